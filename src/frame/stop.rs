//! When a progressive guided render stops: after a number of iterations, or when the region of
//! interest has converged far enough (`--until roi-se:X`), has enough samples in every pixel
//! (`--until roi-spp:N`) or a time budget is spent (`--until time:S`) — the halt conditions
//! users of progressive renderers ask for, with a sample target that counts only the region's
//! pixels. The first condition reached wins.

use std::fmt;
use std::str::FromStr;

/// One halt condition.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StopCondition {
    /// The median standard error of the ROI pixels' mean luminance is at or below this.
    RoiSe(f64),
    /// Every ROI pixel has at least this many samples.
    RoiSpp(u32),
    /// This many seconds of rendering have passed.
    Time(f64),
}

/// Why a `--until` stop condition did not parse.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StopConditionError {
    #[error("{text:?}: a stop condition is roi-se:X, roi-spp:N or time:SECONDS")]
    NoColon { text: String },
    #[error("{text:?}: {value:?} is not a positive number")]
    NotPositive { text: String, value: String },
    #[error("{text:?}: {value:?} is not a whole number of samples ≥ 1")]
    NotSamples { text: String, value: String },
    #[error("{text:?}: unknown stop condition {kind:?} (roi-se:X, roi-spp:N or time:SECONDS)")]
    Unknown { text: String, kind: String },
}

impl FromStr for StopCondition {
    type Err = StopConditionError;

    fn from_str(s: &str) -> Result<Self, StopConditionError> {
        let (kind, value) = s
            .split_once(':')
            .ok_or_else(|| StopConditionError::NoColon { text: s.to_owned() })?;
        let number = || {
            value
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v > 0.0)
                .ok_or_else(|| StopConditionError::NotPositive {
                    text: s.to_owned(),
                    value: value.to_owned(),
                })
        };
        match kind {
            "roi-se" => Ok(Self::RoiSe(number()?)),
            "time" => Ok(Self::Time(number()?)),
            "roi-spp" => value
                .trim()
                .parse::<u32>()
                .ok()
                .filter(|n| *n > 0)
                .map(Self::RoiSpp)
                .ok_or_else(|| StopConditionError::NotSamples {
                    text: s.to_owned(),
                    value: value.to_owned(),
                }),
            _ => Err(StopConditionError::Unknown {
                text: s.to_owned(),
                kind: kind.to_owned(),
            }),
        }
    }
}

impl fmt::Display for StopCondition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::RoiSe(v) => write!(f, "roi-se:{v}"),
            Self::RoiSpp(n) => write!(f, "roi-spp:{n}"),
            Self::Time(s) => write!(f, "time:{s}"),
        }
    }
}

impl StopCondition {
    /// Whether the condition needs the accumulation's statistics (`Renderer::roi_progress`).
    #[must_use]
    pub fn needs_progress(&self) -> bool {
        !matches!(self, Self::Time(_))
    }
}

/// How far the ROI has come: defined with the ROI's statistics (the output stage's, so that
/// the GPU measures the same).
pub use crate::output::stats::RoiProgress;

/// Why a render stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StopReason {
    /// All `--iterations` ran.
    Iterations(u32),
    /// This condition was reached.
    Reached(StopCondition),
}

impl fmt::Display for StopReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Iterations(n) => write!(
                f,
                "{} done",
                crate::messages::count(*n as usize, "iteration")
            ),
            Self::Reached(c) => write!(f, "{c} reached"),
        }
    }
}

/// The first condition of `conditions` that `progress` (the ROI, if measured) and `elapsed`
/// seconds satisfy.
#[must_use]
pub fn reached(
    conditions: &[StopCondition],
    progress: Option<&RoiProgress>,
    elapsed: f64,
) -> Option<StopCondition> {
    conditions.iter().copied().find(|c| match *c {
        StopCondition::Time(s) => elapsed >= s,
        StopCondition::RoiSe(x) => progress.is_some_and(|p| f64::from(p.median_se) <= x),
        StopCondition::RoiSpp(n) => progress.is_some_and(|p| p.min_samples >= n),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::accum::Accumulation;
    use glam::Vec3;

    #[test]
    fn conditions_parse_and_bad_ones_say_what_is_wrong() {
        assert_eq!("roi-se:0.01".parse(), Ok(StopCondition::RoiSe(0.01)));
        assert_eq!("roi-spp:64".parse(), Ok(StopCondition::RoiSpp(64)));
        assert_eq!("time:2.5".parse(), Ok(StopCondition::Time(2.5)));
        for bad in [
            "roi-se",
            "roi-se:-1",
            "roi-se:nan",
            "roi-spp:1.5",
            "time:0",
            "spp:4",
        ] {
            let e = bad.parse::<StopCondition>().unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
    }

    #[test]
    fn progress_counts_only_roi_pixels_and_undefined_noise_is_infinite() {
        let mut acc = Accumulation::new(3, 1);
        for k in 0..4 {
            acc.add(0, Vec3::splat(if k % 2 == 0 { 1.0 } else { 0.0 }));
            acc.add(1, Vec3::splat(0.5));
        }
        acc.add(2, Vec3::ONE);
        // Pixel 2 is outside the ROI.
        let p = RoiProgress::measure(&acc, &[0.0, 0.0, 0.5]).unwrap();
        assert_eq!((p.pixels, p.min_samples), (2, 4));
        // Pixel 0: luminance 1, 0, 1, 0: s² = 1/3, SE = √(1/12); pixel 1: SE 0. Median of two is
        // the upper one.
        assert!((p.median_se - (1.0f32 / 12.0).sqrt()).abs() < 1e-6, "{p:?}");
        let only_one_sample = RoiProgress::measure(&acc, &[1.0, 1.0, 0.0]).unwrap();
        assert_eq!(only_one_sample.median_se, f32::INFINITY);
        assert!(RoiProgress::measure(&acc, &[1.0, 1.0, 1.0]).is_none());
    }

    #[test]
    fn the_first_condition_reached_wins() {
        let p = RoiProgress {
            pixels: 10,
            min_samples: 8,
            median_se: 0.02,
        };
        let c = [StopCondition::RoiSe(0.01), StopCondition::RoiSpp(8)];
        assert_eq!(reached(&c, Some(&p), 1.0), Some(StopCondition::RoiSpp(8)));
        assert_eq!(reached(&c[..1], Some(&p), 1.0), None);
        assert_eq!(
            reached(&[StopCondition::Time(2.0)], None, 2.0),
            Some(StopCondition::Time(2.0))
        );
        assert_eq!(reached(&c, None, 100.0), None);
    }

    #[test]
    fn the_time_estimate_follows_one_over_root_n() {
        let p = RoiProgress {
            pixels: 1,
            min_samples: 4,
            median_se: 0.02,
        };
        // Halving the SE takes four times the samples: three more of the time spent.
        // (median_se is an f32: 0.02 is 0.0199999996…)
        assert!((p.seconds_to_se(0.01, 2.0).unwrap() - 6.0).abs() < 1e-5);
        assert_eq!(p.seconds_to_se(0.05, 2.0), Some(0.0));
    }
}
