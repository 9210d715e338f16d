//! Tracking ingest (DESIGN.md §10): sources of pointing input turned into normalised events.
//!
//! ```text
//! UDP datagram ─► dtrack::DtrackDecoder ─┐
//!              └► osc::OscDecoder ───────┼─► TrackingEvent ─► interaction::Interaction ─► ROI
//! replay line  ─► replay::ReplayReader ──┘    (events of a replay go straight through)
//! ```
//!
//! Raw datagrams from a replay file and from a live socket take the same path
//! ([`ingest::Ingest`]), so a recorded session reproduces exactly what the live run did.

pub mod bench;
pub mod dtrack;
pub mod event;
pub mod ingest;
pub mod osc;
pub mod problems;
pub mod replay;
pub mod synth;
pub mod udp;
