//! Tracking: the live UDP listener, VRPN, the shipped replays and the tracked head.

mod head_tracking;
mod tracking_replays;
mod tracking_udp;
mod tracking_vrpn;

// The helpers of tests/support/ that the files above use, each compiled once here.
#[path = "../support/cli.rs"]
mod support;
#[path = "../support/walls.rs"]
mod walls;
