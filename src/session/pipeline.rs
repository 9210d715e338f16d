//! Decoder and state machine together: raw input in, ROI changes out (DESIGN.md §10, §4).

use crate::interaction::{Interaction, InteractionConfig, RaySurface, RoiChange};
use crate::tracking::dtrack::{DtrackConfig, TimeSource};
use crate::tracking::event::{DeviceId, TrackingEvent};
use crate::tracking::ingest::{Ingest, Protocol};
use crate::tracking::osc::OscConfig;

/// Decoder and state machine together: raw input in, ROI changes out. Live listeners and
/// replays both drive this, so a replay reproduces what the live run did.
#[derive(Clone, Debug)]
pub struct Pipeline {
    pub ingest: Ingest,
    pub interaction: Interaction,
    changes: Vec<RoiChange>,
}

impl Pipeline {
    #[must_use]
    pub fn new(ingest: Ingest, interaction: Interaction) -> Self {
        Self {
            ingest,
            interaction,
            changes: Vec::new(),
        }
    }

    /// A pipeline for live traffic with the default parsers and mapping, stamped with receive
    /// times, following `device`, with problems counted but not logged (load and loopback runs,
    /// where a logged line per bad datagram would be noise).
    #[must_use]
    pub fn quiet_live(device: DeviceId) -> Self {
        let mut ingest = Ingest::new(
            DtrackConfig::default(),
            OscConfig::default(),
            TimeSource::Receive,
        );
        ingest.problems.quiet = true;
        let interaction = Interaction::new(InteractionConfig {
            device,
            ..InteractionConfig::default()
        });
        Self::new(ingest, interaction)
    }

    /// One raw datagram: its events and the ROI changes they caused.
    pub fn datagram(
        &mut self,
        protocol: Protocol,
        data: &[u8],
        receive_t: f64,
        surface: &dyn RaySurface,
    ) -> (&[TrackingEvent], &[RoiChange]) {
        self.changes.clear();
        let events = self.ingest.datagram(protocol, data, receive_t);
        for e in events {
            self.interaction.handle(e, surface, &mut self.changes);
        }
        (events, &self.changes)
    }

    /// Nothing arrived up to `receive_t` (a live poll timed out): the VRPN decoder may lose
    /// the sensors of a silent server (see [`Ingest::idle`]).
    pub fn idle(
        &mut self,
        receive_t: f64,
        surface: &dyn RaySurface,
    ) -> (&[TrackingEvent], &[RoiChange]) {
        self.changes.clear();
        let events = self.ingest.idle(receive_t);
        for e in events {
            self.interaction.handle(e, surface, &mut self.changes);
        }
        (events, &self.changes)
    }

    /// One normalised event (validated first).
    pub fn event(&mut self, event: TrackingEvent, surface: &dyn RaySurface) -> &[RoiChange] {
        self.changes.clear();
        if let Some(e) = self.ingest.event(event) {
            self.interaction.handle(&e, surface, &mut self.changes);
        }
        &self.changes
    }
}
