//! Normalised tracking events (DESIGN.md §10): what every source (DTrack, OSC, VMC, mouse,
//! replay file) is turned into before the interaction state machine sees it.
//!
//! Units and frames are fixed here so that nothing downstream has to know the source: time in
//! seconds (f64), positions in room metres, orientations as unit quaternions in the room frame
//! of DESIGN.md §2 (right-handed, +Y up, +Z from the wall towards the viewer).

use std::fmt;
use std::str::FromStr;

use glam::{DQuat, DVec2, DVec3};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// What kind of source a device comes from; DTrack bodies and FlySticks have separate id spaces,
/// so the kind is part of the identity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DeviceKind {
    /// A DTrack standard body (`6d` line).
    Body,
    /// A DTrack FlyStick (`6df2` line).
    Flystick,
    /// A device of raygun's own OSC address space (`/raygun/<id>/...`).
    Osc,
    /// A VMC controller; id 0 is the right hand, 1 the left hand.
    Vmc,
    /// A desktop mouse; its position is a canvas point, not a pose.
    Mouse,
}

impl DeviceKind {
    const NAMES: [(DeviceKind, &'static str); 5] = [
        (DeviceKind::Body, "body"),
        (DeviceKind::Flystick, "flystick"),
        (DeviceKind::Osc, "osc"),
        (DeviceKind::Vmc, "vmc"),
        (DeviceKind::Mouse, "mouse"),
    ];

    /// The lower-case name used in `kind:id` device strings.
    #[must_use]
    pub fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(k, _)| *k == self)
            .map_or("?", |(_, n)| n)
    }
}

/// A device identity, written `kind:id` (e.g. `flystick:0`) in JSON files and on the command
/// line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct DeviceId {
    pub kind: DeviceKind,
    pub id: u32,
}

impl DeviceId {
    #[must_use]
    pub const fn new(kind: DeviceKind, id: u32) -> Self {
        Self { kind, id }
    }
}

impl fmt::Display for DeviceId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.kind.name(), self.id)
    }
}

/// Why a `kind:id` string is not a device id.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "device id {text:?} is not of the form kind:number with kind one of body, flystick, osc, vmc, mouse"
)]
pub struct DeviceIdError {
    pub text: String,
}

impl FromStr for DeviceId {
    type Err = DeviceIdError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = || DeviceIdError { text: s.to_owned() };
        let (kind, id) = s.split_once(':').ok_or_else(err)?;
        let kind = DeviceKind::NAMES
            .iter()
            .find(|(_, n)| *n == kind)
            .map(|(k, _)| *k)
            .ok_or_else(err)?;
        let id = id.parse::<u32>().map_err(|_| err())?;
        Ok(Self { kind, id })
    }
}

impl Serialize for DeviceId {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for DeviceId {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

/// A tracked pose in the room frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Metres, room frame.
    pub position: DVec3,
    /// Unit quaternion, room frame (device frame → room frame).
    pub orientation: DQuat,
}

impl Pose {
    /// Whether every component is finite and the quaternion has unit length (within 1e-6): the
    /// invariant every parser establishes before it emits a pose.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.position.is_finite()
            && self.orientation.is_finite()
            && (self.orientation.length() - 1.0).abs() < 1e-6
    }
}

/// What an event says about a device's pose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Tracking {
    /// The device was tracked at this pose.
    Tracked(Pose),
    /// The tracker reported the device as not tracked (DTrack quality −1); no pose exists.
    Lost,
}

/// One normalised event: the state of one device at one time. Fields that are `None` were not
/// part of the message (an OSC `buttons` message says nothing about the pose), so consumers
/// keep their previous value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackingEvent {
    /// Seconds; the origin depends on the source (tracker clock or receive clock) but is the
    /// same for every event of one source, which is all the state machine needs.
    pub t: f64,
    pub device: DeviceId,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<Tracking>,
    /// Button bitmask, bit i = button i pressed (FlyStick2: bit 0 is the trigger).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub buttons: Option<u32>,
    /// Analog axes in [−1, 1] (FlyStick2: x, y of the stick; FlyStick2+: a third, the wheel).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axes: Option<Vec<f64>>,
    /// A pointer position in canvas pixels (mouse on a desktop display).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub canvas: Option<DVec2>,
    /// A requested field of view, degrees (horizontal, vertical), from OSC `/raygun/<id>/fov`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_deg: Option<[f64; 2]>,
}

impl TrackingEvent {
    /// An event that carries nothing but its time and device; sources fill in what they know.
    #[must_use]
    pub fn empty(t: f64, device: DeviceId) -> Self {
        Self {
            t,
            device,
            pose: None,
            buttons: None,
            axes: None,
            canvas: None,
            fov_deg: None,
        }
    }

    /// Whether every number in the event is finite and every pose valid: events that fail this
    /// never reach the interaction state machine (replay files can hold anything).
    #[must_use]
    pub fn is_valid(&self) -> bool {
        let pose_ok = match &self.pose {
            Some(Tracking::Tracked(p)) => p.is_valid(),
            _ => true,
        };
        self.t.is_finite()
            && pose_ok
            && self
                .axes
                .as_ref()
                .is_none_or(|a| a.len() <= MAX_AXES && a.iter().all(|v| v.is_finite()))
            && self.canvas.is_none_or(|c| c.is_finite())
            && self
                .fov_deg
                .is_none_or(|f| f.iter().all(|v| v.is_finite() && *v > 0.0 && *v < 180.0))
    }
}

/// Most analog axes any source may report; DTrack's own limit for FlySticks is 8.
pub const MAX_AXES: usize = 8;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_id_round_trips_through_its_string_form() {
        for kind in DeviceKind::NAMES.map(|(k, _)| k) {
            let d = DeviceId::new(kind, 7);
            assert_eq!(d.to_string().parse::<DeviceId>().unwrap(), d);
        }
    }

    #[test]
    fn device_id_rejects_unknown_kind_and_bad_number() {
        assert!("wand:1".parse::<DeviceId>().is_err());
        assert!("flystick:-1".parse::<DeviceId>().is_err());
        assert!("flystick".parse::<DeviceId>().is_err());
    }

    #[test]
    fn event_json_round_trip_keeps_every_field() {
        let e = TrackingEvent {
            t: 1.25,
            device: DeviceId::new(DeviceKind::Flystick, 2),
            pose: Some(Tracking::Tracked(Pose {
                position: DVec3::new(0.1, 1.5, 1.0),
                orientation: DQuat::from_rotation_y(0.3),
            })),
            buttons: Some(0b101),
            axes: Some(vec![0.5, -1.0]),
            canvas: None,
            fov_deg: Some([10.0, 20.0]),
        };
        let json = serde_json::to_string(&e).unwrap();
        assert_eq!(serde_json::from_str::<TrackingEvent>(&json).unwrap(), e);
        let lost = TrackingEvent {
            pose: Some(Tracking::Lost),
            ..TrackingEvent::empty(0.0, e.device)
        };
        let json = serde_json::to_string(&lost).unwrap();
        assert_eq!(serde_json::from_str::<TrackingEvent>(&json).unwrap(), lost);
    }

    #[test]
    fn non_finite_and_non_unit_values_make_an_event_invalid() {
        let d = DeviceId::new(DeviceKind::Osc, 0);
        let mut e = TrackingEvent::empty(0.0, d);
        assert!(e.is_valid());
        e.axes = Some(vec![f64::NAN]);
        assert!(!e.is_valid());
        let mut e = TrackingEvent::empty(0.0, d);
        e.pose = Some(Tracking::Tracked(Pose {
            position: DVec3::ZERO,
            orientation: DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0),
        }));
        assert!(!e.is_valid());
        let mut e = TrackingEvent::empty(f64::INFINITY, d);
        assert!(!e.is_valid());
        e.t = 0.0;
        e.fov_deg = Some([0.0, 10.0]);
        assert!(!e.is_valid());
    }
}
