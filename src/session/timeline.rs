//! A tracking replay collected ahead of time for the viewer's play / pause / scrub: every ROI
//! change and the ray gun's aim (where its pointing ray meets the wall) over the session, and a
//! tracked head's eye where the replay has one.

use glam::{DVec2, DVec3};

use super::replay::{ReplayOptions, ReplayPlan, ReplayPlanError};
use crate::interaction::RaySurface;
use crate::interaction::RoiState;
use crate::tracking::event::Tracking;
use crate::tracking::replay::{ReplayPayload, play};

/// A session on one time axis: seconds since its first event.
#[derive(Clone, Debug, Default)]
pub struct Timeline {
    /// (t, the ROI state after the change), in time order.
    pub changes: Vec<(f64, RoiState)>,
    /// (t, canvas pixel the device points at; `None` while untracked or aiming off the wall).
    pub aim: Vec<(f64, Option<DVec2>)>,
    /// (t, the tracked head's eye, room frame), in time order; empty without a head.
    pub eyes: Vec<(f64, DVec3)>,
    pub duration: f64,
}

impl Timeline {
    /// Plays `args` through the live parsers and the interaction state machine, as fast as
    /// possible, keeping the followed device's aim and every ROI change.
    pub fn collect(args: &ReplayOptions) -> Result<Self, ReplayPlanError> {
        let (plan, reader) = ReplayPlan::new(args)?;
        let mut pipeline = plan.pipeline();
        let device = plan.interaction.device;
        let (pointing, _, _) = plan.interaction.axes();
        let mut changes = Vec::new();
        let mut aim = Vec::new();
        let mut eyes = Vec::new();
        let head = plan.head;
        let surface = &plan.surface;
        let note = |e: &crate::tracking::event::TrackingEvent,
                    aim: &mut Vec<(f64, Option<DVec2>)>| {
            if e.device != device {
                return;
            }
            match e.pose {
                Some(Tracking::Tracked(p)) => aim.push((
                    e.t,
                    surface
                        .hit(p.position, p.orientation * pointing)
                        .map(|h| h.canvas_px),
                )),
                Some(Tracking::Lost) => aim.push((e.t, None)),
                None => {}
            }
        };
        let mut problems = play(
            reader,
            crate::tracking::replay::Playback::AsFastAsPossible,
            |item| {
                let new = match &item.payload {
                    ReplayPayload::Datagram(protocol, bytes) => {
                        let (events, new) = pipeline.datagram(*protocol, bytes, item.t, surface);
                        for e in events {
                            note(e, &mut aim);
                            eyes.extend(head.and_then(|h| h.eye_of(e)).map(|eye| (e.t, eye)));
                        }
                        new
                    }
                    ReplayPayload::Event(e) => {
                        if e.is_valid() {
                            note(e, &mut aim);
                            eyes.extend(head.and_then(|h| h.eye_of(e)).map(|eye| (e.t, eye)));
                        }
                        pipeline.event(e.clone(), surface)
                    }
                };
                changes.extend(new.iter().map(|c| (c.t, c.roi.clone())));
            },
        );
        problems.merge(&pipeline.ingest.problems);
        if problems.total() > 0 {
            eprintln!(
                "raygun view: {}: {} input problems (see `raygun replay` for details)",
                args.file.display(),
                problems.total()
            );
        }
        let t0 = aim
            .first()
            .map(|a| a.0)
            .into_iter()
            .chain(changes.first().map(|c| c.0))
            .fold(f64::INFINITY, f64::min);
        let t0 = if t0.is_finite() { t0 } else { 0.0 };
        for c in &mut changes {
            c.0 -= t0;
        }
        for a in &mut aim {
            a.0 -= t0;
        }
        for e in &mut eyes {
            e.0 -= t0;
        }
        let duration = aim
            .last()
            .map(|a| a.0)
            .into_iter()
            .chain(changes.last().map(|c| c.0))
            .fold(0.0, f64::max);
        Ok(Self {
            changes,
            aim,
            eyes,
            duration,
        })
    }

    /// The ROI state at time `t` (the last change at or before it).
    #[must_use]
    pub fn roi_at(&self, t: f64) -> Option<&RoiState> {
        let i = self.changes.partition_point(|c| c.0 <= t);
        i.checked_sub(1).map(|i| &self.changes[i].1)
    }

    /// The aim samples with `t0 < t ≤ t1`, in time order.
    #[must_use]
    pub fn aim_after(&self, t0: f64, t1: f64) -> &[(f64, Option<DVec2>)] {
        let a = self.aim.partition_point(|a| a.0 <= t0);
        let b = self.aim.partition_point(|a| a.0 <= t1).max(a);
        &self.aim[a..b]
    }

    /// The tracked head's eye at time `t` (the last at or before it, else the first); `None`
    /// without a head.
    #[must_use]
    pub fn eye_at(&self, t: f64) -> Option<DVec3> {
        let i = self.eyes.partition_point(|e| e.0 <= t);
        self.eyes.get(i.saturating_sub(1)).map(|e| e.1)
    }

    /// Where the device points at time `t`.
    #[must_use]
    pub fn aim_at(&self, t: f64) -> Option<DVec2> {
        let i = self.aim.partition_point(|a| a.0 <= t);
        i.checked_sub(1).and_then(|i| self.aim[i].1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bundled_replay_has_shots_and_aim_in_time_order() {
        let root = env!("CARGO_MANIFEST_DIR");
        let t = Timeline::collect(&ReplayOptions {
            file: format!("{root}/tracking-replays/flystick-1-centre-sweeps.dtrack.jsonl").into(),
            display: Some(format!("{root}/display-models/hornet.json")),
            config: None,
            device: None,
            calibration: None,
            realtime: false,
            head: Default::default(),
        })
        .unwrap();
        // The session is 20 s long (its header says so).
        assert!((t.duration - 20.0).abs() < 0.1, "{}", t.duration);
        assert!(t.changes.windows(2).all(|w| w[0].0 <= w[1].0));
        assert!(t.changes.iter().any(|c| c.1.centre.is_some()));
        // Before the first change there is no ROI; at the end there is the last one.
        assert!(t.roi_at(-1.0).is_none());
        assert_eq!(t.roi_at(t.duration), Some(&t.changes.last().unwrap().1));
        // The sweeps about the wall centre aim at the canvas most of the time.
        let on = t.aim.iter().filter(|a| a.1.is_some()).count();
        assert!(on * 2 > t.aim.len(), "{on} of {}", t.aim.len());
    }
}
