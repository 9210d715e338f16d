//! Tracking ingest (DESIGN.md §10): sources of pointing input turned into normalised events.
//!
//! ```text
//! UDP datagram ─► dtrack::DtrackDecoder ─┐
//!              └► osc::OscDecoder ───────┤
//! VRPN read    ─► vrpn::VrpnDecoder ─────┼─► TrackingEvent ─► interaction::Interaction ─► ROI
//! replay line  ─► replay::ReplayReader ──┘    (events of a replay go straight through)
//! ```
//!
//! Raw datagrams from a replay file and from a live socket take the same path
//! ([`ingest::Pipeline`]: decoders, validation, interaction), so a recorded session reproduces
//! exactly what the live run did; `tests/tracking_replays.rs` checks that for every shipped
//! replay.
//!
//! Modules: [`event`] (normalised events), [`dtrack`] and [`osc`] (parsers), [`vrpn`] (VRPN
//! client and decoder), [`calibration`] (the tracker→room transform of every source),
//! [`replay`] (JSON Lines files), [`udp`] (listeners, recorder), [`problems`] (bad-input counters),
//! [`synth`] (synthetic sessions), [`bench`] (ingest benchmark).

pub mod bench;
pub mod calibration;
pub mod dtrack;
pub mod event;
pub mod ingest;
pub mod osc;
pub mod problems;
pub mod replay;
pub mod synth;
pub mod udp;
pub mod vrpn;
