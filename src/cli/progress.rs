//! Progress of a long command: a bar on a terminal; off a terminal (a log file, CI, a pipe)
//! where a bar draws nothing, a line at the first step and then one every [`LINE_INTERVAL`], so
//! a render that takes minutes is never silent.
//!
//! The time left is estimated from the pace after the first step (a render's first frame):
//! the one-time work before it — loading the scene, building the BVH, uploading to the GPU,
//! the first frame's own warm-up — says nothing about how long the remaining steps take
//! ([`seconds_left`]).

use std::io::IsTerminal;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// How often a progress line is printed when standard error is not a terminal.
pub const LINE_INTERVAL: Duration = Duration::from_secs(10);

/// A progress report over `len` units (or an open-ended one).
pub struct Progress {
    bar: Option<ProgressBar>,
    lines: Option<Lines>,
    /// When the first step was reported done, and how many units it brought.
    first: Option<(Instant, u64)>,
}

/// Seconds left for `len` units at the pace measured since the first step: `first` is when
/// the first step ended and the units done by then, `now` the time of `done` units (seconds on
/// any one clock). What came before the first step's end (one-time work) does not count. `None`
/// until a step after the first has ended, and once the work is done.
#[must_use]
pub fn seconds_left(first: (f64, u64), now: f64, done: u64, len: u64) -> Option<f64> {
    let per_unit = seconds_per_unit(first, now, done)?;
    (len > done).then(|| per_unit * (len - done) as f64)
}

/// The seconds `done` units take at the pace measured since the first step (see
/// [`seconds_left`]): the time spent sampling, one-time work left out. `None` until a step
/// after the first has ended.
#[must_use]
pub fn sampling_seconds(first: (f64, u64), now: f64, done: u64) -> Option<f64> {
    Some(seconds_per_unit(first, now, done)? * done as f64)
}

/// The one-time work before a render's first frame, reported on a line of its own: the
/// sampling times (the `… ms per megasample` figure, the time left) start at the first frame
/// and leave it out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OneTime {
    /// Reading and decoding the scene (or generating a built-in), with `--env`'s image.
    pub load_seconds: f64,
    /// Packing the scene and building its BVH.
    pub build_seconds: f64,
    /// Preparing the backend: on a GPU compiling the kernels, uploading the scene and making
    /// the first buffers; on the CPU allocating the accumulation.
    pub upload_seconds: f64,
}

impl std::fmt::Display for OneTime {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "one-time work (not in the sampling time): scene load {:.2} s, BVH build {:.2} s, upload {:.2} s",
            self.load_seconds, self.build_seconds, self.upload_seconds
        )
    }
}

fn seconds_per_unit((at, first_done): (f64, u64), now: f64, done: u64) -> Option<f64> {
    (done > first_done && now >= at).then(|| (now - at) / (done - first_done) as f64)
}

struct Lines {
    what: String,
    unit: String,
    len: Option<u64>,
    start: Instant,
    /// When the last line was printed (`None`: none yet, the first `set` prints one).
    last: Option<Instant>,
    message: String,
}

impl Progress {
    /// `what` names the work ("rendering"), `unit` the counted steps ("spp"); `len` `None` for
    /// an open-ended run (a stop condition decides). Nothing at all with `quiet`.
    #[must_use]
    pub fn new(quiet: bool, what: &str, len: Option<u64>, unit: &str) -> Self {
        if quiet {
            return Self {
                bar: None,
                lines: None,
                first: None,
            };
        }
        if std::io::stderr().is_terminal() {
            let bar = match len {
                Some(n) => ProgressBar::new(n).with_style(
                    ProgressStyle::with_template(&format!(
                        "{{msg}} [{{bar:40}}] {{pos}}/{{len}} {unit}, {{elapsed}} (eta {{eta}})"
                    ))
                    .expect("static template")
                    .progress_chars("=> "),
                ),
                None => ProgressBar::new_spinner().with_style(
                    ProgressStyle::with_template(&format!("{{msg}} {{pos}} {unit}, {{elapsed}}"))
                        .expect("static template"),
                ),
            };
            bar.set_message(what.to_owned());
            return Self {
                bar: Some(bar),
                lines: None,
                first: None,
            };
        }
        let now = Instant::now();
        Self {
            bar: None,
            lines: Some(Lines {
                what: what.to_owned(),
                unit: unit.to_owned(),
                len,
                start: now,
                last: None,
                message: String::new(),
            }),
            first: None,
        }
    }

    /// `done` units so far. The first call marks the end of the first step: the estimate of
    /// the time left starts there.
    pub fn set(&mut self, done: u64) {
        let is_first = self.first.is_none();
        let first = *self.first.get_or_insert_with(|| (Instant::now(), done));
        if let Some(bar) = &self.bar {
            bar.set_position(done);
            if is_first {
                // The bar's own estimate, too, from the pace after the first step.
                bar.reset_eta();
            }
        }
        if let Some(l) = &mut self.lines
            && l.last.is_none_or(|t| t.elapsed() >= LINE_INTERVAL)
        {
            l.last = Some(Instant::now());
            let elapsed = l.start.elapsed().as_secs_f64();
            let of = l.len.map_or(String::new(), |n| format!("/{n}"));
            let first_at = first.0.duration_since(l.start).as_secs_f64();
            let eta = l
                .len
                .and_then(|n| seconds_left((first_at, first.1), elapsed, done, n))
                .map_or(String::new(), |s| format!(", about {s:.0} s left"));
            let extra = if l.message.is_empty() {
                String::new()
            } else {
                format!(" ({})", l.message)
            };
            eprintln!(
                "raygun: {} {done}{of} {}, {elapsed:.0} s{eta}{extra}",
                l.what, l.unit
            );
        }
    }

    /// The seconds `done` units take at the pace since the first step ([`sampling_seconds`]);
    /// `None` before a second step has ended.
    #[must_use]
    pub fn sampling_seconds(&self, done: u64) -> Option<f64> {
        let (at, first_done) = self.first?;
        sampling_seconds((0.0, first_done), at.elapsed().as_secs_f64(), done)
    }

    /// Lengthens the run to `len` units where it turns out longer than first said.
    pub fn lengthen(&mut self, len: u64) {
        if let Some(bar) = &self.bar
            && bar.length().is_some_and(|n| n < len)
        {
            bar.set_length(len);
        }
        if let Some(l) = &mut self.lines
            && l.len.is_some_and(|n| n < len)
        {
            l.len = Some(len);
        }
    }

    /// A note shown beside the count (e.g. the ROI's current noise).
    pub fn note(&mut self, text: &str) {
        if let Some(bar) = &self.bar {
            bar.set_message(text.to_owned());
        }
        if let Some(l) = &mut self.lines {
            text.clone_into(&mut l.message);
        }
    }

    /// Clears the bar.
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

/// A progress bar over `len` units (hidden when `quiet`), for the benchmarks.
#[must_use]
pub fn bar(quiet: bool, len: u64, unit: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    ProgressBar::new(len).with_style(
        ProgressStyle::with_template(&format!(
            "{{msg}} [{{bar:40}}] {{pos}}/{{len}} {unit}, {{elapsed}} (eta {{eta}})"
        ))
        .expect("static template")
        .progress_chars("=> "),
    )
}

/// A progress bar over a benchmark's `steps` — hidden with `--json`, and (by indicatif) when
/// standard error is not a terminal — and the callback that advances it, showing each step's
/// name. A step beyond the count lengthens the bar rather than overrunning it.
pub fn bench_progress(json: bool, steps: u64) -> (indicatif::ProgressBar, impl FnMut(&str)) {
    let bar = bar(json, steps, "steps");
    let b = bar.clone();
    let advance = move |what: &str| {
        if b.position() >= b.length().unwrap_or(0) {
            b.inc_length(1);
        }
        b.set_message(what.to_string());
        b.inc(1);
    };
    (bar, advance)
}

/// Prints a benchmark's text and, with `--out`, also writes it to that file.
pub fn print_and_save(text: &str, out: Option<&std::path::Path>) -> anyhow::Result<()> {
    crate::cli::print_out(&text)?;
    if let Some(path) = out {
        crate::output::write_bytes(path, text.as_bytes())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{sampling_seconds, seconds_left};

    /// A render whose one-time work took 250 s and whose steps take 1 s each: the time before
    /// the first step's end does not enter the estimate.
    #[test]
    fn the_estimate_ignores_the_time_before_the_first_step() {
        // First step (1 spp of 256) done at 251 s; 10 s later 11 spp are done.
        let first = (251.0, 1);
        assert_eq!(seconds_left(first, 261.0, 11, 256), Some(245.0));
        assert_eq!(sampling_seconds(first, 261.0, 11), Some(11.0));
        // One step from the end: about a second, not the 255 s that counting the one-time work
        // as sampling would give.
        assert_eq!(seconds_left(first, 505.0, 255, 256), Some(1.0));
        // Only the first step so far: no pace yet.
        assert_eq!(seconds_left(first, 251.0, 1, 256), None);
        assert_eq!(sampling_seconds(first, 251.0, 1), None);
        // Done: nothing left to estimate.
        assert_eq!(seconds_left(first, 506.0, 256, 256), None);
        // A first step of several units (a batch) counts from its end too.
        assert_eq!(seconds_left((5.0, 4), 9.0, 8, 16), Some(8.0));
    }
}
