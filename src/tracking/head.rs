//! Head tracking (DESIGN.md §11): the wall camera's eye follows a tracked body.
//!
//! The head is a device like the ray gun — a DTrack `6d` body (`body:N`), a body of raygun's
//! OSC address space (`osc:N`, `/raygun/N/pose`) or a VRPN tracker sensor (the device the VRPN
//! mapping gives it; `vrpn_Tracker_DTrack`'s sensor 0 is `body:0`) — so its poses reach the
//! room frame through the same decoders and the same tracker→room calibration as the ray gun's.
//! The eye sits at a fixed offset in the body's own frame (metres):
//! `eye = position + orientation · offset`.
//!
//! A recording carries the head's stream like every other device's (the raw datagrams hold
//! every body), and its header names the head ([`HeadConfig`], the replay header's `head`), so
//! a replay moves the eye as the live session did.
//!
//! The restart rule lives here, where the parsers' consumers and the renderers both reach it:
//! [`eye_moved`] says whether an eye lies more than the threshold
//! ([`DEFAULT_EYE_THRESHOLD_M`], 1 cm, unless given) from the eye the accumulation started
//! with; the wall camera applies it to its own eye, and [`EyeRule`] to a stream of eyes (a
//! replay's, before any renderer exists).

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::event::{DeviceId, DeviceKind, Tracking, TrackingEvent};

/// How far (metres) the eye may move from the eye the accumulation started with before the
/// accumulation restarts, when no threshold is given (`--eye-threshold`, a replay header's
/// `eye_threshold_m`).
pub const DEFAULT_EYE_THRESHOLD_M: f64 = 0.01;

/// The restart rule of a moving eye: whether `eye` lies more than `threshold_m` from `started`
/// (the eye the accumulation started with). A non-finite eye never restarts (it is refused
/// where it is used).
#[must_use]
pub fn eye_moved(started: DVec3, eye: DVec3, threshold_m: f64) -> bool {
    eye.is_finite() && eye.distance(started) > threshold_m
}

fn default_threshold() -> f64 {
    DEFAULT_EYE_THRESHOLD_M
}

fn is_zero(v: &[f64; 3]) -> bool {
    *v == [0.0; 3]
}

/// Which tracked device is the viewer's head and where the eye sits on it (the replay header's
/// `head`; `--head KIND:N --eye-offset X,Y,Z --eye-threshold M` on the command line).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeadConfig {
    pub device: DeviceId,
    /// The eye in the body's own frame, metres (from the body's origin to the point between
    /// the eyes).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub eye_offset_m: [f64; 3],
    /// The accumulation restarts when the eye moves more than this from where it started.
    #[serde(default = "default_threshold")]
    pub eye_threshold_m: f64,
}

/// Why a head configuration cannot be used; names the flag.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HeadError {
    #[error("--head {0}: a mouse is a canvas pointer, not a tracked pose")]
    Mouse(DeviceId),
    #[error("--eye-offset: {0:?} must be three finite numbers (metres, the body's frame)")]
    Offset([f64; 3]),
    #[error("--eye-threshold: {0} must be a finite number of metres, 0 or more")]
    Threshold(f64),
}

impl HeadConfig {
    /// The head `device` with the eye at its origin and the default threshold.
    #[must_use]
    pub fn new(device: DeviceId) -> Self {
        Self {
            device,
            eye_offset_m: [0.0; 3],
            eye_threshold_m: DEFAULT_EYE_THRESHOLD_M,
        }
    }

    pub fn validate(&self) -> Result<(), HeadError> {
        if self.device.kind == DeviceKind::Mouse {
            return Err(HeadError::Mouse(self.device));
        }
        if !self.eye_offset_m.iter().all(|v| v.is_finite()) {
            return Err(HeadError::Offset(self.eye_offset_m));
        }
        if !(self.eye_threshold_m.is_finite() && self.eye_threshold_m >= 0.0) {
            return Err(HeadError::Threshold(self.eye_threshold_m));
        }
        Ok(())
    }

    /// The eye of an event of the head that carries a tracked pose (room frame); `None` for
    /// other devices, untracked or pose-less events and invalid ones.
    #[must_use]
    pub fn eye_of(&self, e: &TrackingEvent) -> Option<DVec3> {
        if e.device != self.device || !e.is_valid() {
            return None;
        }
        match e.pose {
            Some(Tracking::Tracked(p)) => {
                Some(p.position + p.orientation * DVec3::from_array(self.eye_offset_m))
            }
            _ => None,
        }
    }
}

/// What the command line changes of a head (`--head`, `--eye-offset`, `--eye-threshold`),
/// over the one a replay's header names.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HeadOverride {
    pub device: Option<DeviceId>,
    pub eye_offset_m: Option<[f64; 3]>,
    pub eye_threshold_m: Option<f64>,
}

impl HeadOverride {
    /// The head `base` (a header's) with these changes; a device given here makes a head
    /// where `base` has none.
    #[must_use]
    pub fn apply(&self, base: Option<HeadConfig>) -> Option<HeadConfig> {
        let mut h = match (self.device, base) {
            (Some(d), Some(b)) => HeadConfig { device: d, ..b },
            (Some(d), None) => HeadConfig::new(d),
            (None, b) => b?,
        };
        if let Some(o) = self.eye_offset_m {
            h.eye_offset_m = o;
        }
        if let Some(t) = self.eye_threshold_m {
            h.eye_threshold_m = t;
        }
        Some(h)
    }
}

/// The restart rule on a stream of eyes: [`Self::offer`] says whether an eye restarts the
/// accumulation (the first eye always starts one).
#[derive(Clone, Debug, PartialEq)]
pub struct EyeRule {
    pub threshold_m: f64,
    started: Option<DVec3>,
}

impl EyeRule {
    #[must_use]
    pub fn new(threshold_m: f64) -> Self {
        Self {
            threshold_m,
            started: None,
        }
    }

    /// Whether `eye` starts a new accumulation: the first one, and any more than the threshold
    /// from the eye the current one started with (which it then becomes).
    pub fn offer(&mut self, eye: DVec3) -> bool {
        let restart = match self.started {
            None => eye.is_finite(),
            Some(s) => eye_moved(s, eye, self.threshold_m),
        };
        if restart {
            self.started = Some(eye);
        }
        restart
    }

    /// The eye the current accumulation started with.
    #[must_use]
    pub fn started(&self) -> Option<DVec3> {
        self.started
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::event::Pose;
    use glam::DQuat;

    #[test]
    fn the_eye_is_the_body_pose_times_the_offset() {
        let head = HeadConfig {
            eye_offset_m: [0.0, 0.0, -0.1],
            ..HeadConfig::new(DeviceId::new(DeviceKind::Body, 3))
        };
        let pose = Pose {
            position: DVec3::new(1.0, 2.0, 3.0),
            // Turned 90° left: the body's −Z (forward) is the room's −X.
            orientation: DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2),
        };
        let e = TrackingEvent {
            pose: Some(Tracking::Tracked(pose)),
            ..TrackingEvent::empty(0.0, head.device)
        };
        let eye = head.eye_of(&e).unwrap();
        assert!(eye.abs_diff_eq(DVec3::new(0.9, 2.0, 3.0), 1e-12), "{eye}");
        let other = TrackingEvent {
            device: DeviceId::new(DeviceKind::Body, 4),
            ..e.clone()
        };
        assert!(head.eye_of(&other).is_none());
        let lost = TrackingEvent {
            pose: Some(Tracking::Lost),
            ..e
        };
        assert!(head.eye_of(&lost).is_none());
    }

    #[test]
    fn the_rule_restarts_past_the_threshold_from_where_it_started() {
        let mut r = EyeRule::new(0.01);
        let a = DVec3::new(0.0, 0.0, 1.0);
        assert!(r.offer(a));
        assert!(!r.offer(a + DVec3::X * 0.006));
        // 12 mm from the start, 6 mm from the last eye.
        assert!(r.offer(a + DVec3::X * 0.012));
        assert_eq!(r.started(), Some(a + DVec3::X * 0.012));
        assert!(!r.offer(DVec3::NAN));
    }

    #[test]
    fn overrides_change_what_they_name() {
        let base = HeadConfig {
            eye_offset_m: [0.0, 0.1, 0.0],
            ..HeadConfig::new(DeviceId::new(DeviceKind::Body, 3))
        };
        assert_eq!(HeadOverride::default().apply(Some(base)), Some(base));
        assert_eq!(HeadOverride::default().apply(None), None);
        let o = HeadOverride {
            eye_threshold_m: Some(0.05),
            ..HeadOverride::default()
        };
        assert_eq!(o.apply(Some(base)).unwrap().eye_threshold_m, 0.05);
        assert_eq!(o.apply(None), None);
        let d = DeviceId::new(DeviceKind::Osc, 2);
        let o = HeadOverride {
            device: Some(d),
            ..HeadOverride::default()
        };
        assert_eq!(o.apply(None), Some(HeadConfig::new(d)));
        assert_eq!(o.apply(Some(base)).unwrap().eye_offset_m, [0.0, 0.1, 0.0]);
    }

    #[test]
    fn bad_configurations_name_their_flag() {
        let mut h = HeadConfig::new(DeviceId::new(DeviceKind::Mouse, 0));
        assert!(h.validate().unwrap_err().to_string().contains("--head"));
        h.device = DeviceId::new(DeviceKind::Osc, 1);
        h.eye_offset_m[1] = f64::NAN;
        assert!(
            h.validate()
                .unwrap_err()
                .to_string()
                .contains("--eye-offset")
        );
        h.eye_offset_m[1] = 0.0;
        h.eye_threshold_m = -1.0;
        assert!(
            h.validate()
                .unwrap_err()
                .to_string()
                .contains("--eye-threshold")
        );
        let json = r#"{"device":"body:3","eye_offset_m":[0,0.05,-0.08]}"#;
        let h: HeadConfig = serde_json::from_str(json).unwrap();
        assert_eq!(h.eye_threshold_m, DEFAULT_EYE_THRESHOLD_M);
        assert!(serde_json::from_str::<HeadConfig>(r#"{"device":"body:3","x":1}"#).is_err());
    }
}
