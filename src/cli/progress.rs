//! Progress of a long command: a bar on a terminal; off a terminal (a log file, CI, a pipe)
//! where a bar draws nothing, a line at the first step and then one every [`LINE_INTERVAL`], so
//! a render that takes minutes is never silent.

use std::io::IsTerminal;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// How often a progress line is printed when standard error is not a terminal.
pub const LINE_INTERVAL: Duration = Duration::from_secs(10);

/// A progress report over `len` units (or an open-ended one).
pub struct Progress {
    bar: Option<ProgressBar>,
    lines: Option<Lines>,
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
        }
    }

    /// `done` units so far.
    pub fn set(&mut self, done: u64) {
        if let Some(bar) = &self.bar {
            bar.set_position(done);
        }
        if let Some(l) = &mut self.lines
            && l.last.is_none_or(|t| t.elapsed() >= LINE_INTERVAL)
        {
            l.last = Some(Instant::now());
            let elapsed = l.start.elapsed().as_secs_f64();
            let of = l.len.map_or(String::new(), |n| format!("/{n}"));
            let eta = match l.len {
                Some(n) if done > 0 && n > done => format!(
                    ", about {:.0} s left",
                    elapsed * (n - done) as f64 / done as f64
                ),
                _ => String::new(),
            };
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
