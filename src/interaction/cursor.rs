//! Smoothing of the drawn ray-gun cursor: a 1€ filter (Casiez, Roussel, Vogel, "1€ Filter: A
//! Simple Speed-based Low-pass Filter for Noisy Input in Interactive Systems", CHI 2012) on the
//! canvas point the device aims at, driven by the events' timestamps, and what to draw at the
//! display's frame time.
//!
//! Only the drawn cursor is smoothed. A trigger press still freezes the raw pose into the ROI
//! cone (DESIGN.md §4): the shot goes where the stick pointed at the press, not where a lagging
//! filter thought it was, so replays give the same ROIs whatever the cursor settings.
//!
//! The filter is a first-order low-pass whose cutoff rises with speed:
//! `fc = min_cutoff_hz + beta · |v̂|` with v̂ the speed low-passed at `d_cutoff_hz`; each step
//! blends `x̂ ← x̂ + α (x − x̂)` with `α = 1 / (1 + 1 / (2π fc Δt))`. At rest the cutoff is low
//! (tremor and tracker noise are removed), in a fast move it is high (little lag). Both canvas
//! axes share the cutoff (the speed is the vector's length), so the cursor does not drift off
//! the path of a diagonal move.
//!
//! Between samples the cursor is extrapolated along the smoothed point's own velocity for at
//! most `max_extrapolation_s`, then held. With no sample for `stale_after_s` (the stream
//! stopped) or after a sample saying the device is untracked or aims off the wall, the cursor
//! is [`CursorMark::Stale`] (drawn grey where it was last seen). Time that repeats or runs
//! back is ignored; a gap of more than `stale_after_s` or a jump back of more than that (a new
//! stream, a scrubbed replay) restarts the filter at the new sample.

use glam::DVec2;
use serde::{Deserialize, Serialize};

/// The cursor's parameters (`"cursor"` in the interaction JSON config; every field optional).
///
/// Defaults, for canvas pixels of about 0.5 mm (HORNET: 1886 px/m) and tracking at 60 Hz:
/// `min_cutoff_hz` 1.0 and `d_cutoff_hz` 1.0 (the paper's suggested start), `beta` 0.005 per
/// canvas px/s (a 2000 px/s sweep raises the cutoff to 11 Hz), `max_extrapolation_s` 0.02 (a
/// bit more than one 60 Hz frame), `stale_after_s` 0.25.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CursorConfig {
    /// Smooth the cursor at all (off: the latest raw aim, held).
    pub smooth: bool,
    /// Cutoff at rest, Hz.
    pub min_cutoff_hz: f64,
    /// Cutoff increase per canvas pixel per second of speed, Hz·s/px.
    pub beta: f64,
    /// Cutoff of the speed estimate, Hz.
    pub d_cutoff_hz: f64,
    /// Longest extrapolation past the last sample, seconds (0: hold).
    pub max_extrapolation_s: f64,
    /// After this long without a sample the cursor is stale; a longer gap restarts the filter.
    pub stale_after_s: f64,
}

impl Default for CursorConfig {
    fn default() -> Self {
        Self {
            smooth: true,
            min_cutoff_hz: 1.0,
            beta: 0.005,
            d_cutoff_hz: 1.0,
            max_extrapolation_s: 0.02,
            stale_after_s: 0.25,
        }
    }
}

impl CursorConfig {
    /// Checks that every parameter is a finite value in its range; the error names the field
    /// (as in the JSON config).
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let positive = [
            ("cursor.min_cutoff_hz", self.min_cutoff_hz),
            ("cursor.d_cutoff_hz", self.d_cutoff_hz),
            ("cursor.stale_after_s", self.stale_after_s),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err((field, format!("{v} is not a positive number")));
            }
        }
        for (field, v) in [
            ("cursor.beta", self.beta),
            ("cursor.max_extrapolation_s", self.max_extrapolation_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err((field, format!("{v} is not a non-negative number")));
            }
        }
        Ok(())
    }
}

/// What to draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CursorMark {
    /// Tracked and recent: the smoothed aim.
    Live(DVec2),
    /// Untracked, off the wall or no recent sample: where the cursor was last, drawn grey.
    Stale(DVec2),
}

impl CursorMark {
    #[must_use]
    pub fn position(self) -> DVec2 {
        match self {
            Self::Live(p) | Self::Stale(p) => p,
        }
    }
}

/// The filter's state after the last accepted sample.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Filtered {
    t: f64,
    /// Smoothed position and the low-passed raw velocity (1€'s x̂ and dx̂).
    x: DVec2,
    dx: DVec2,
    /// Velocity of the smoothed position over the last step (for extrapolation).
    v_out: DVec2,
}

/// The smoothed cursor of one device.
#[derive(Clone, Debug, PartialEq)]
pub struct CursorSmoother {
    pub config: CursorConfig,
    state: Option<Filtered>,
    /// The last sample said untracked / off the wall (at this time).
    lost_at: Option<f64>,
    /// The latest raw aim on the wall (for `smooth = false`).
    raw: Option<DVec2>,
    /// Samples ignored for repeated or backward time, or non-finite values.
    pub ignored: u64,
}

/// 1€'s smoothing factor for cutoff `fc` over `dt`.
fn alpha(fc: f64, dt: f64) -> f64 {
    let tau = 1.0 / (2.0 * std::f64::consts::PI * fc);
    1.0 / (1.0 + tau / dt)
}

impl CursorSmoother {
    #[must_use]
    pub fn new(config: CursorConfig) -> Self {
        Self {
            config,
            state: None,
            lost_at: None,
            raw: None,
            ignored: 0,
        }
    }

    /// Forgets everything (a scrubbed replay starts over).
    pub fn reset(&mut self) {
        *self = Self::new(self.config.clone());
    }

    fn last_t(&self) -> Option<f64> {
        match (self.state.map(|s| s.t), self.lost_at) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        }
    }

    /// Feeds the sample of time `t` (seconds, any origin): the canvas point the device aims at,
    /// or `None` while it is untracked or aims off the wall.
    pub fn observe(&mut self, t: f64, aim: Option<DVec2>) {
        if !t.is_finite() || aim.is_some_and(|p| !p.is_finite()) {
            self.ignored += 1;
            return;
        }
        if let Some(last) = self.last_t() {
            if t < last - self.config.stale_after_s {
                // A new stream or a replay scrubbed back: start over.
                self.reset_keeping_count();
            } else if t <= last {
                self.ignored += 1;
                return;
            }
        }
        let Some(x) = aim else {
            self.lost_at = Some(t);
            return;
        };
        self.raw = Some(x);
        let restart = self.lost_at.is_some()
            || self
                .state
                .is_none_or(|s| t - s.t > self.config.stale_after_s);
        self.lost_at = None;
        if restart {
            self.state = Some(Filtered {
                t,
                x,
                dx: DVec2::ZERO,
                v_out: DVec2::ZERO,
            });
            return;
        }
        let Some(s) = self.state else { return };
        let c = &self.config;
        let dt = t - s.t;
        let dx = s.dx + alpha(c.d_cutoff_hz, dt) * ((x - s.x) / dt - s.dx);
        let fc = c.min_cutoff_hz + c.beta * dx.length();
        let new_x = s.x + alpha(fc, dt) * (x - s.x);
        self.state = Some(Filtered {
            t,
            x: new_x,
            dx,
            v_out: (new_x - s.x) / dt,
        });
    }

    fn reset_keeping_count(&mut self) {
        let ignored = self.ignored;
        self.reset();
        self.ignored = ignored;
    }

    /// What to draw at display time `t` (the events' time axis); `None` before the first
    /// tracked sample.
    #[must_use]
    pub fn at(&self, t: f64) -> Option<CursorMark> {
        let s = self.state?;
        if !self.config.smooth {
            let r = self.raw.unwrap_or(s.x);
            let live = self.lost_at.is_none() && !(t - s.t > self.config.stale_after_s);
            return Some(if live {
                CursorMark::Live(r)
            } else {
                CursorMark::Stale(r)
            });
        }
        let age = if t.is_finite() { t - s.t } else { 0.0 };
        let ahead = age.clamp(0.0, self.config.max_extrapolation_s);
        let p = s.x + s.v_out * ahead;
        if self.lost_at.is_some() {
            return Some(CursorMark::Stale(s.x));
        }
        Some(if age > self.config.stale_after_s {
            CursorMark::Stale(p)
        } else {
            CursorMark::Live(p)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 60 Hz tracking.
    const DT: f64 = 1.0 / 60.0;

    /// A deterministic standard normal (Box–Muller on a fixed LCG).
    struct Normal(u64);
    impl Normal {
        fn unit(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn next(&mut self) -> f64 {
            let (u, v) = (self.unit(), self.unit());
            (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
        }
    }

    #[test]
    fn tremor_and_noise_at_rest_are_reduced_fivefold() {
        // A stick held still at (5000, 2000) with a 10 Hz physiological tremor of 8 px
        // amplitude on both axes (about 4 mm on HORNET) and tracker noise of σ = 3 px.
        let centre = DVec2::new(5000.0, 2000.0);
        let mut rng = Normal(7);
        let mut f = CursorSmoother::new(CursorConfig::default());
        let (mut raw_sq, mut out_sq, mut n) = (0.0, 0.0, 0);
        for i in 0..600 {
            let t = f64::from(i) * DT;
            let w = 2.0 * std::f64::consts::PI * 10.0 * t;
            let x = centre
                + 8.0 * DVec2::new(w.sin(), (w + 1.0).sin())
                + 3.0 * DVec2::new(rng.next(), rng.next());
            f.observe(t, Some(x));
            // Judge after a 1 s warm-up, at the sample times.
            if t >= 1.0 {
                let p = f.at(t).unwrap();
                assert!(matches!(p, CursorMark::Live(_)));
                raw_sq += (x - centre).length_squared();
                out_sq += (p.position() - centre).length_squared();
                n += 1;
            }
        }
        let (raw, out) = ((raw_sq / n as f64).sqrt(), (out_sq / n as f64).sqrt());
        assert!(
            out * 5.0 < raw,
            "RMS jitter {raw:.2} px raw, {out:.2} px smoothed"
        );
    }

    #[test]
    fn a_large_step_is_followed_within_50_ms() {
        // At rest, then the aim jumps 500 px (a flick across a panel, 27 cm on HORNET).
        let (a, b) = (DVec2::new(1000.0, 1000.0), DVec2::new(1500.0, 1000.0));
        let mut f = CursorSmoother::new(CursorConfig::default());
        for i in 0..60 {
            f.observe(f64::from(i) * DT, Some(a));
        }
        let t_step = 60.0 * DT;
        let mut reached = None;
        for i in 60..120 {
            let t = f64::from(i) * DT;
            f.observe(t, Some(b));
            let p = f.at(t).unwrap().position();
            // No overshoot past the target, along or across the step.
            assert!(p.x <= b.x + 1e-9 && (p.y - b.y).abs() < 1e-9, "{p}");
            if reached.is_none() && (p - b).length() <= 0.05 * (b - a).length() {
                reached = Some(t - t_step);
            }
        }
        let lag = reached.expect("reaches the target");
        assert!(
            lag <= 0.05 + 1e-9,
            "within 5 % of a 500 px step after {lag} s"
        );
        // A plain 1 Hz low-pass (beta = 0) takes far longer: the speed term is what helps.
        let mut slow = CursorSmoother::new(CursorConfig {
            beta: 0.0,
            ..CursorConfig::default()
        });
        for i in 0..60 {
            slow.observe(f64::from(i) * DT, Some(a));
        }
        for i in 60..66 {
            slow.observe(f64::from(i) * DT, Some(b));
        }
        let p = slow.at(65.0 * DT).unwrap().position();
        assert!((p - b).length() > 0.5 * (b - a).length(), "{p}");
    }

    #[test]
    fn extrapolation_is_bounded_and_the_cursor_goes_stale() {
        let c = CursorConfig::default();
        let mut f = CursorSmoother::new(c.clone());
        // A steady sweep at 600 px/s.
        for i in 0..120 {
            let t = f64::from(i) * DT;
            f.observe(t, Some(DVec2::new(600.0 * t, 0.0)));
        }
        let t_last = 119.0 * DT;
        let at = |dt: f64| f.at(t_last + dt).unwrap();
        let held = at(c.max_extrapolation_s).position();
        // Moves on between samples, at most for max_extrapolation_s, then holds.
        assert!(at(0.01).position().x > at(0.0).position().x);
        assert_eq!(at(0.2).position(), held);
        assert!(matches!(at(0.2), CursorMark::Live(_)));
        // The extrapolation is at most the sweep's speed times the bound.
        assert!(held.x - at(0.0).position().x <= 600.0 * c.max_extrapolation_s * 1.01);
        // No sample for longer than stale_after_s: grey, held in place, even much later.
        assert_eq!(at(c.stale_after_s + 0.01), CursorMark::Stale(held));
        assert_eq!(at(1e6), CursorMark::Stale(held));
        assert!(matches!(at(f64::NAN), CursorMark::Live(_)));
    }

    #[test]
    fn dropouts_repeats_and_time_going_back_give_no_nan() {
        let mut f = CursorSmoother::new(CursorConfig::default());
        assert_eq!(f.at(0.0), None, "nothing drawn before the first sample");
        f.observe(0.0, None);
        assert_eq!(f.at(0.0), None);
        let p = DVec2::new(100.0, 50.0);
        f.observe(0.1, Some(p));
        assert_eq!(f.at(0.1), Some(CursorMark::Live(p)));
        // Repeated timestamps (with another position) and a small step back are ignored.
        f.observe(0.1, Some(p + 1000.0));
        f.observe(0.05, Some(p - 1000.0));
        assert_eq!(f.at(0.1), Some(CursorMark::Live(p)));
        assert_eq!(f.ignored, 2);
        // Non-finite input is ignored too.
        f.observe(f64::NAN, Some(p));
        f.observe(0.2, Some(DVec2::new(f64::INFINITY, 0.0)));
        f.observe(f64::INFINITY, None);
        assert_eq!(f.ignored, 5);
        // Untracked: grey where it was; the next tracked sample starts afresh there.
        f.observe(0.3, None);
        assert_eq!(f.at(0.3), Some(CursorMark::Stale(p)));
        let q = DVec2::new(3000.0, 900.0);
        f.observe(0.31, Some(q));
        assert_eq!(f.at(0.31), Some(CursorMark::Live(q)));
        // A long jump back (scrubbed replay) restarts at the new sample.
        f.observe(-5.0, Some(p));
        assert_eq!(f.at(-5.0), Some(CursorMark::Live(p)));
        // A random-ish stream with every kind of trouble stays finite.
        let mut rng = Normal(3);
        let mut t = 0.0;
        for i in 0..5000 {
            let r = rng.next();
            t += match i % 7 {
                0 => 0.0,
                1 => -0.01,
                2 => 1e-12,
                3 => 0.5,
                _ => DT * (1.0 + 0.2 * r),
            };
            let aim = (i % 11 != 0).then(|| DVec2::new(1e4 * r, 1e3 * r.sin()));
            f.observe(t, aim);
            if let Some(m) = f.at(t + 0.01 * r) {
                assert!(m.position().is_finite(), "step {i}: {m:?}");
            }
        }
    }

    #[test]
    fn unsmoothed_shows_the_latest_raw_aim() {
        let mut f = CursorSmoother::new(CursorConfig {
            smooth: false,
            ..CursorConfig::default()
        });
        f.observe(0.0, Some(DVec2::ZERO));
        f.observe(DT, Some(DVec2::new(500.0, 0.0)));
        assert_eq!(f.at(DT), Some(CursorMark::Live(DVec2::new(500.0, 0.0))));
        f.observe(2.0 * DT, None);
        assert_eq!(
            f.at(2.0 * DT),
            Some(CursorMark::Stale(DVec2::new(500.0, 0.0)))
        );
    }

    #[test]
    fn invalid_parameters_name_their_field() {
        let bad = [
            (
                CursorConfig {
                    min_cutoff_hz: 0.0,
                    ..CursorConfig::default()
                },
                "cursor.min_cutoff_hz",
            ),
            (
                CursorConfig {
                    beta: f64::NAN,
                    ..CursorConfig::default()
                },
                "cursor.beta",
            ),
            (
                CursorConfig {
                    max_extrapolation_s: -1.0,
                    ..CursorConfig::default()
                },
                "cursor.max_extrapolation_s",
            ),
        ];
        for (c, field) in bad {
            assert_eq!(c.validate().unwrap_err().0, field);
        }
        CursorConfig::default().validate().unwrap();
    }
}
