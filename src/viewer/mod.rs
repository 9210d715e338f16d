//! `raygun view`: an egui window (eframe, wgpu backend) showing the guided render as it
//! converges, steered by mouse clicks, a replay or live tracking.
//!
//! * [`core`]: the panel's settings and the renderer kept in step with them, without a screen.
//! * [`timeline`]: a replay collected ahead of time for play / pause / scrub.
//! * [`live`]: live DTrack / OSC on a listener thread.
//! * `app`: the eframe front end (with the `viewer` feature, on by default).

#[cfg(feature = "viewer")]
pub mod app;
pub mod core;
pub mod live;
pub mod timeline;
