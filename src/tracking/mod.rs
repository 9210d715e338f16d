//! Tracking ingest (DESIGN.md §10): sources of pointing input turned into normalised events.
//!
//! ```text
//! UDP datagram ─► dtrack::DtrackDecoder ─┐
//!              └► osc::OscDecoder ───────┤
//! VRPN read    ─► vrpn::VrpnDecoder ─────┼─► TrackingEvent ─► interaction::Interaction ─► ROI
//! replay line  ─► replay::ReplayReader ──┘    (events of a replay go straight through)
//! ```
//!
//! Raw datagrams from a replay file and from a live socket take the same path (the session
//! layer's `Pipeline`: these decoders, validation, then the interaction), so a recorded
//! session reproduces exactly what the live run did; `tests/tracking/tracking_replays.rs` checks that
//! for every shipped replay. This layer only parses and validates: sockets, threads and
//! replays played against a display belong to `session`.
//!
//! Modules: [`event`] (normalised events), [`dtrack`] and [`osc`] (parsers), [`vrpn`] (VRPN
//! wire format and decoder), [`calibration`] (the tracker→room transform of every source),
//! [`head`] (the tracked head that moves the wall camera's eye, and the restart rule),
//! [`ingest`] (every decoder behind one call), [`replay`] (JSON Lines files), [`problems`]
//! (bad-input counters).

pub mod calibration;
pub mod dtrack;
pub mod event;
pub mod head;
pub mod ingest;
pub mod osc;
pub mod problems;
pub mod replay;
pub mod vrpn;
