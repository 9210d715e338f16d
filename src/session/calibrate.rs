//! Where `raygun calibrate`'s measurements come from: one tracker position per trigger press,
//! read through decoders that leave the tracker's own units and frame.

use glam::DVec3;

use crate::tracking::dtrack::{DtrackConfig, TimeSource, TrackerToRoom};
use crate::tracking::event::{DeviceId, Tracking, TrackingEvent};
use crate::tracking::ingest::Ingest;
use crate::tracking::osc::OscConfig;

/// Collects one tracker position per press of `button` on `device` from a stream of events:
/// the position of the last tracked pose at or before the press.
#[derive(Debug, Default)]
pub struct PressCollector {
    device: Option<DeviceId>,
    button: u32,
    last_position: Option<DVec3>,
    pressed: bool,
    /// Positions at the presses, tracker units.
    pub positions: Vec<DVec3>,
    /// Presses while the device was untracked (not counted).
    pub untracked_presses: u32,
}

impl PressCollector {
    #[must_use]
    pub fn new(device: DeviceId, button: u32) -> Self {
        Self {
            device: Some(device),
            button,
            ..Self::default()
        }
    }

    /// Takes one event; true when it was a counted press.
    pub fn event(&mut self, e: &TrackingEvent) -> bool {
        if Some(e.device) != self.device {
            return false;
        }
        match e.pose {
            Some(Tracking::Tracked(p)) => self.last_position = Some(p.position),
            Some(Tracking::Lost) => self.last_position = None,
            None => {}
        }
        let Some(buttons) = e.buttons else {
            return false;
        };
        let down = buttons & (1 << self.button) != 0;
        let press = down && !self.pressed;
        self.pressed = down;
        if !press {
            return false;
        }
        match self.last_position {
            Some(p) => {
                self.positions.push(p);
                true
            }
            None => {
                self.untracked_presses += 1;
                false
            }
        }
    }
}

/// Decoders that leave positions in the tracker's own units and frame (identity, 1 m per
/// unit), so the solver sees the raw numbers.
pub fn raw_ingest() -> Ingest {
    let raw = TrackerToRoom {
        metres_per_unit: 1.0,
        ..TrackerToRoom::default()
    };
    Ingest::new(
        DtrackConfig {
            tracker_to_room: raw.clone(),
            ..DtrackConfig::default()
        },
        OscConfig {
            tracker_to_room: raw,
            ..OscConfig::default()
        },
        TimeSource::Receive,
    )
}
