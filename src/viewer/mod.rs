//! `raygun view`: an egui window (eframe, wgpu backend) showing the guided render as it
//! converges, steered by mouse clicks, a replay or live tracking.
//!
//! * [`core`]: the panel's settings and the renderer kept in step with them, without a screen.

//! * `app`: the eframe front end (with the `viewer` feature, on by default).

#[cfg(feature = "viewer")]
pub mod app;
pub mod core;
