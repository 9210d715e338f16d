//! One path from raw input to validated events, shared by live sockets and replay files.

use serde::{Deserialize, Serialize};

use super::dtrack::{DtrackConfig, DtrackDecoder, TimeSource};
use super::event::DeviceId;
use super::event::TrackingEvent;
use super::osc::{OscConfig, OscDecoder};
use super::problems::ProblemLog;
use crate::interaction::{Interaction, InteractionConfig, RaySurface, RoiChange};

/// The protocol of a raw datagram.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Protocol {
    Dtrack,
    Osc,
}

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

    /// One normalised event (validated first).
    pub fn event(&mut self, event: TrackingEvent, surface: &dyn RaySurface) -> &[RoiChange] {
        self.changes.clear();
        if let Some(e) = self.ingest.event(event) {
            self.interaction.handle(&e, surface, &mut self.changes);
        }
        &self.changes
    }
}

/// Decoders for both protocols plus the problem counters.
#[derive(Clone, Debug)]
pub struct Ingest {
    dtrack: DtrackDecoder,
    osc: OscDecoder,
    pub problems: ProblemLog,
    events: Vec<TrackingEvent>,
    /// Datagrams that decoded (frames delivered).
    pub accepted: u64,
}

impl Ingest {
    #[must_use]
    pub fn new(dtrack: DtrackConfig, osc: OscConfig, time_source: TimeSource) -> Self {
        let osc = OscConfig { time_source, ..osc };
        Self {
            dtrack: DtrackDecoder::new(dtrack, time_source),
            osc: OscDecoder::new(osc),
            problems: ProblemLog::default(),
            events: Vec::new(),
            accepted: 0,
        }
    }

    /// Applies a tracker→room calibration to both decoders (their other settings stay).
    pub fn calibrate(&mut self, calibration: &super::calibration::Calibration) {
        let mut dtrack = self.dtrack.config().clone();
        let mut osc = self.osc.config().clone();
        calibration.apply(&mut dtrack, &mut osc);
        self.dtrack.set_config(dtrack);
        self.osc.set_config(osc);
    }

    /// Decodes one datagram; a bad one is counted and yields no events.
    pub fn datagram(
        &mut self,
        protocol: Protocol,
        data: &[u8],
        receive_t: f64,
    ) -> &[TrackingEvent] {
        self.events.clear();
        let result = match protocol {
            Protocol::Dtrack => self
                .dtrack
                .decode_into(data, receive_t, &mut self.events)
                .map(|_| ())
                .map_err(|e| (e.kind.name(), e.to_string())),
            Protocol::Osc => self
                .osc
                .decode_into(data, receive_t, &mut self.events)
                .map_err(|e| (e.name(), e.to_string())),
        };
        match result {
            Ok(()) => {
                self.accepted += 1;
                // Parsers establish validity; this guards the invariant, never the normal path.
                let before = self.events.len();
                self.events.retain(TrackingEvent::is_valid);
                if self.events.len() != before {
                    self.problems
                        .report("invalid_event", "a decoded event failed validation");
                }
            }
            Err((kind, detail)) => {
                self.events.clear();
                self.problems.report(kind, detail);
            }
        }
        &self.events
    }

    /// Passes a normalised event (from a replay file) through the same validation.
    #[must_use]
    pub fn event(&mut self, event: TrackingEvent) -> Option<TrackingEvent> {
        if event.is_valid() {
            self.accepted += 1;
            Some(event)
        } else {
            self.problems.report(
                "invalid_event",
                format_args!(
                    "event at t = {} has non-finite or out-of-range values",
                    event.t
                ),
            );
            None
        }
    }
}
