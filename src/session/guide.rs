//! Where a guided render's ROI comes from: a fixed ROI, or a replay's ROI changes spread
//! evenly over the iterations — and, where the replay has a tracked head, its eyes on the same
//! time axis, which move the wall camera under the restart rule.

use std::path::{Path, PathBuf};

use glam::DVec3;

use super::replay::{ReplayPlan, replay_changes_with};
use crate::roi::dgi::Roi;
use crate::tracking::replay::ReplayError;

/// Why a replay gives no guide.
#[derive(Debug, thiserror::Error)]
pub enum GuideSourceError {
    #[error(transparent)]
    Replay(#[from] ReplayError),
    #[error(
        "{}: no shot of the replay hits the display ({display}): it gives no ROI (`raygun replay` lists its shots and misses)",
        file.display()
    )]
    NoShot { file: PathBuf, display: String },
}

/// Where the ROI comes from.
#[derive(Clone, Debug)]
pub enum GuideSource {
    /// A fixed ROI for every iteration.
    Fixed(Roi),
    /// A replay's ROI changes, (seconds since the first, ROI) in time order, spread evenly
    /// over the iterations.
    Replay {
        changes: Vec<(f64, Option<Roi>)>,
        duration: f64,
        /// The tracked head's eyes (seconds on the same axis, room frame), in time order;
        /// empty without a head.
        eyes: Vec<(f64, DVec3)>,
        /// The head's restart threshold, metres.
        eye_threshold_m: f64,
    },
}

impl GuideSource {
    /// The ROI changes of a replay, timed from its first event of the followed device.
    pub fn from_replay(plan: &ReplayPlan, file: &Path) -> Result<Self, GuideSourceError> {
        let mut changes = Vec::new();
        let mut eyes = Vec::new();
        let mut first = None;
        let mut last = 0.0f64;
        replay_changes_with(
            plan,
            file,
            |t_event| {
                first.get_or_insert(t_event);
                last = last.max(t_event);
            },
            |c| {
                changes.push((c.t, c.roi.to_roi().ok().flatten()));
            },
            |t, eye| eyes.push((t, eye)),
        )?;
        if !changes.iter().any(|(_, r)| r.is_some()) {
            return Err(GuideSourceError::NoShot {
                file: file.to_owned(),
                display: plan.display_origin.clone(),
            });
        }
        let t0 = first.unwrap_or(0.0);
        let changes: Vec<(f64, Option<Roi>)> =
            changes.into_iter().map(|(t, r)| (t - t0, r)).collect();
        let eyes = eyes.into_iter().map(|(t, e)| (t - t0, e)).collect();
        Ok(Self::Replay {
            changes,
            duration: (last - t0).max(0.0),
            eyes,
            eye_threshold_m: plan
                .head
                .map_or(crate::tracking::head::DEFAULT_EYE_THRESHOLD_M, |h| {
                    h.eye_threshold_m
                }),
        })
    }

    /// The replay's time, seconds since its first event, that iteration `k` of `n` shows: the
    /// end of its even share of the session, `duration · (k + 1) / n`, so that the last
    /// iteration shows the session's end and the first already shows what happened in its share.
    #[must_use]
    pub fn time_of(duration: f64, k: u32, n: u32) -> f64 {
        duration * (f64::from(k) + 1.0) / f64::from(n.max(1))
    }

    /// The tracked head's eye for iteration `k` of `n` (the last at or before its time, else
    /// the first); `None` without a head.
    #[must_use]
    pub fn eye_at(&self, k: u32, n: u32) -> Option<DVec3> {
        match self {
            Self::Fixed(_) => None,
            Self::Replay { eyes, duration, .. } => {
                let t = Self::time_of(*duration, k, n);
                let i = eyes.partition_point(|(te, _)| *te <= t);
                eyes.get(i.saturating_sub(1)).map(|(_, e)| *e)
            }
        }
    }

    /// The restart threshold of the head's eyes, metres.
    #[must_use]
    pub fn eye_threshold_m(&self) -> f64 {
        match self {
            Self::Replay {
                eye_threshold_m, ..
            } => *eye_threshold_m,
            Self::Fixed(_) => crate::tracking::head::DEFAULT_EYE_THRESHOLD_M,
        }
    }

    /// The first eye of the tracked head, if any.
    #[must_use]
    pub fn first_eye(&self) -> Option<DVec3> {
        match self {
            Self::Fixed(_) => None,
            Self::Replay { eyes, .. } => eyes.first().map(|(_, e)| *e),
        }
    }

    /// The ROI for iteration `k` of `n`: the last change at or before [`Self::time_of`].
    #[must_use]
    pub fn roi_at(&self, k: u32, n: u32) -> Option<Roi> {
        match self {
            Self::Fixed(r) => Some(*r),
            Self::Replay {
                changes, duration, ..
            } => {
                let t = Self::time_of(*duration, k, n);
                changes
                    .iter()
                    .rev()
                    .find(|(tc, _)| *tc <= t)
                    .and_then(|(_, r)| *r)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::roi::dgi::Roi;

    fn roi(x: f64) -> Roi {
        Roi::CanvasEllipse {
            center: glam::DVec2::new(x, 0.0),
            semi_axes: glam::DVec2::new(10.0, 10.0),
        }
    }

    #[test]
    fn the_iterations_share_the_session_evenly_and_the_last_shows_its_end() {
        // Shots at 0, 4 and 7 s of an 8 s session; eyes at 1 and 8 s.
        let source = GuideSource::Replay {
            changes: vec![
                (0.0, Some(roi(0.0))),
                (4.0, Some(roi(4.0))),
                (7.0, Some(roi(7.0))),
            ],
            duration: 8.0,
            eyes: vec![(1.0, DVec3::X), (8.0, DVec3::Y)],
            eye_threshold_m: 0.01,
        };
        // Two iterations: the first half, then the whole session.
        assert_eq!(source.roi_at(0, 2), Some(roi(4.0)));
        assert_eq!(source.roi_at(1, 2), Some(roi(7.0)));
        assert_eq!(source.eye_at(1, 2), Some(DVec3::Y));
        // Eight: one second each.
        let rois: Vec<_> = (0..8).map(|k| source.roi_at(k, 8)).collect();
        let xs: Vec<f64> = rois
            .iter()
            .map(|r| match r {
                Some(Roi::CanvasEllipse { center, .. }) => center.x,
                _ => f64::NAN,
            })
            .collect();
        assert_eq!(xs, [0.0, 0.0, 0.0, 4.0, 4.0, 4.0, 7.0, 7.0]);
        assert_eq!(source.eye_at(0, 8), Some(DVec3::X));
        assert_eq!(source.eye_at(6, 8), Some(DVec3::X));
        assert_eq!(source.eye_at(7, 8), Some(DVec3::Y));
        // One iteration shows the end.
        assert_eq!(source.roi_at(0, 1), Some(roi(7.0)));
    }
}
