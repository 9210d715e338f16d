//! One path from raw input to validated events, shared by live sockets and replay files (the
//! session layer's `Pipeline` adds the interaction state machine on top).

use serde::{Deserialize, Serialize};

use super::dtrack::{DtrackConfig, DtrackDecoder, TimeSource};
use super::event::TrackingEvent;
use super::osc::{OscConfig, OscDecoder};
use super::problems::ProblemLog;
use super::vrpn::{Channel, VrpnConfig, VrpnConfigError, VrpnDecoder};

/// The protocol of a raw datagram.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Protocol {
    Dtrack,
    Osc,
    /// Bytes of one read from a VRPN TCP connection (any piece of the stream; empty: the
    /// connection ended).
    VrpnTcp,
    /// One VRPN UDP datagram (whole messages).
    VrpnUdp,
}

impl std::fmt::Display for Protocol {
    /// The protocol's own name, as its makers write it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Dtrack => "DTrack",
            Self::Osc => "OSC",
            Self::VrpnTcp => "VRPN over TCP",
            Self::VrpnUdp => "VRPN over UDP",
        })
    }
}

/// Decoders for every protocol plus the problem counters. VRPN needs a device name and a
/// mapping, so its decoder exists only once [`Ingest::with_vrpn`] configured it.
#[derive(Clone, Debug)]
pub struct Ingest {
    dtrack: DtrackDecoder,
    osc: OscDecoder,
    vrpn: Option<VrpnDecoder>,
    time_source: TimeSource,
    pub problems: ProblemLog,
    events: Vec<TrackingEvent>,
    /// Datagrams that decoded (frames delivered).
    pub accepted: u64,
}

impl Ingest {
    /// An ingest that decodes only VRPN, for `device` with `config` (live loops that do not
    /// come from a replay header).
    pub fn vrpn_only(
        device: &str,
        config: VrpnConfig,
        time_source: TimeSource,
    ) -> Result<Ingest, VrpnConfigError> {
        Self::new(DtrackConfig::default(), OscConfig::default(), time_source)
            .with_vrpn(device, config)
    }

    #[must_use]
    pub fn new(dtrack: DtrackConfig, osc: OscConfig, time_source: TimeSource) -> Self {
        let osc = OscConfig { time_source, ..osc };
        Self {
            dtrack: DtrackDecoder::new(dtrack, time_source),
            osc: OscDecoder::new(osc),
            vrpn: None,
            time_source,
            problems: ProblemLog::default(),
            events: Vec::new(),
            accepted: 0,
        }
    }

    /// Applies a tracker→room calibration to every decoder (their other settings stay; VRPN
    /// sends metres). Meant for before the first datagram: a VRPN decoder starts afresh.
    pub fn calibrate(&mut self, calibration: &super::calibration::Calibration) {
        let mut dtrack = self.dtrack.config().clone();
        let mut osc = self.osc.config().clone();
        calibration.apply(&mut dtrack, &mut osc);
        self.dtrack.set_config(dtrack);
        self.osc.set_config(osc);
        if let Some(v) = &self.vrpn {
            let mut config = v.config().clone();
            config.tracker_to_room = calibration.tracker_to_room(1.0);
            let device = v.device().to_owned();
            // The configuration validated before; only the transform changed, and a
            // calibration's transform is valid.
            if let Ok(d) = VrpnDecoder::new(&device, config, self.time_source) {
                self.vrpn = Some(d);
            }
        }
    }

    /// Adds the VRPN decoder for `device` (the DEVICE of DEVICE@HOST) with `config`
    /// (validated), using this ingest's time source.
    pub fn with_vrpn(mut self, device: &str, config: VrpnConfig) -> Result<Self, VrpnConfigError> {
        self.vrpn = Some(VrpnDecoder::new(device, config, self.time_source)?);
        Ok(self)
    }

    /// The VRPN decoder, if configured.
    #[must_use]
    pub fn vrpn(&self) -> Option<&VrpnDecoder> {
        self.vrpn.as_ref()
    }

    /// The VRPN decoder, if configured (e.g. to keep its decoded messages).
    pub fn vrpn_mut(&mut self) -> Option<&mut VrpnDecoder> {
        self.vrpn.as_mut()
    }

    /// Whether the VRPN stream broke since the last call (see
    /// [`VrpnDecoder::take_reconnect`]); live loops then drop the connection.
    pub fn take_vrpn_reconnect(&mut self) -> bool {
        self.vrpn.as_mut().is_some_and(VrpnDecoder::take_reconnect)
    }

    /// Nothing arrived up to `receive_t`: events the silence implies (VRPN: sensors lost
    /// after [`VrpnConfig::silence_s`]).
    pub fn idle(&mut self, receive_t: f64) -> &[TrackingEvent] {
        self.events.clear();
        if let Some(v) = &mut self.vrpn {
            v.idle(receive_t, &mut self.events);
        }
        &self.events
    }

    /// Decodes one datagram; a bad one is counted and yields no events. A VRPN read holds any
    /// number of messages: bad ones are counted one by one and the good ones still decode.
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
            Protocol::VrpnTcp | Protocol::VrpnUdp => {
                let channel = if protocol == Protocol::VrpnTcp {
                    Channel::Tcp
                } else {
                    Channel::Udp
                };
                match &mut self.vrpn {
                    Some(v) => {
                        v.decode(channel, data, receive_t, &mut self.events, &mut self.problems);
                        Ok(())
                    }
                    None => Err((
                        "vrpn_not_configured",
                        "a VRPN read arrived but no VRPN device is configured (replay header `vrpn`)"
                            .to_owned(),
                    )),
                }
            }
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
