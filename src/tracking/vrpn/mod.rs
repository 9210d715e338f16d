//! VRPN (Virtual-Reality Peripheral Network): the protocol most VR labs already run between
//! their trackers and applications (A.R.T. via `vrpn_Tracker_DTrack`, Vicon's built-in
//! server, Unreal nDisplay). No maintained Rust implementation exists, so this is raygun's
//! own client, written from the wire format of VRPN 07.38 and checked on its bytes
//! (`tests/data/vrpn/`).
//!
//! ```text
//! session::vrpn::VrpnSource::poll ─► raw read (TCP piece | UDP datagram | end) ─┬─► replay line (vrpn_*_hex)
//!                                                               └─► Ingest ─► VrpnDecoder ─► TrackingEvent
//! replay line ─► ReplayReader ─► the same Ingest / VrpnDecoder
//! ```
//!
//! * [`wire`]: cookie, 24-byte big-endian headers, 8-byte padding, payloads of Pos_Quat,
//!   Velocity, Acceleration, Button Change / States and Analog Channel; an encoder for test
//!   servers.
//! * [`decoder`]: reassembles TCP reads, matches the peer's sender and type ids by name
//!   (ids differ per side), and turns the device's messages into normalised events
//!   (DESIGN.md §10) through the tracker→room calibration ([`VrpnConfig`]).
//! * [`config`]: `DEVICE@HOST[:PORT]` addresses and the sensor / button / analog mapping.
//!
//! The connection itself (TCP, or VRPN's classic UDP set-up, reconnection with back-off, live
//! runs and recording) is the session layer's (`session::vrpn`): this module only parses.
//!
//! Bad input of every kind (wrong cookie or major version, lengths below 24 or above
//! [`wire::MAX_MESSAGE_LEN`], truncated messages, unknown or redefined ids, NaN, infinite or
//! non-unit poses, a silent or flooding server) is counted per kind in a
//! [`ProblemLog`](crate::tracking::problems::ProblemLog) and logged once; nothing panics, and
//! every buffer is bounded (one partial message per connection, one read at a time).

pub mod config;
pub mod decoder;
pub mod wire;

pub use config::{
    AnalogGroup, ButtonGroup, Transport, VrpnAddress, VrpnAddressError, VrpnConfig,
    VrpnConfigError, VrpnHeader,
};
pub use decoder::{Channel, VrpnDecoder, VrpnMessage, VrpnStats};
