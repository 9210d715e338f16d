//! Where the ROI comes from (DESIGN.md §1, §10, §4): the layer between the parsers and the
//! frame. It owns everything with a clock, a socket or a file position — live listeners, the
//! VRPN connection, replays played against a display, the render loop that follows them —
//! while `tracking` below it only parses and `frame` above the stages only renders.
//!
//! ```text
//! udp::UdpSource / vrpn::VrpnSource ─┐
//! replay::ReplayPlan (a recording) ──┼─► pipeline::Pipeline (Ingest ─► Interaction) ─► ROI changes
//!                                    │        ├─► live::LiveTracking (viewer, own thread)
//!                                    │        ├─► timeline::Timeline (viewer: play / scrub)
//!                                    │        └─► guide::GuideSource ─► render::run_guided
//! calibrate (presses for `raygun calibrate`)
//! ```
//!
//! A tracked head (`crate::tracking::head`) rides along every path: replay plans name it
//! (`ReplayPlan::head`), the guide source and the timeline carry its eyes, live tracking reports
//! them, and the render loop moves the wall camera's eye under the restart rule.
//!
//! Modules: [`pipeline`] (raw input to ROI changes), [`udp`] (DTrack / OSC listeners and the
//! recorder), [`vrpn`] (the VRPN client), [`live`] (live tracking for the viewer), [`replay`]
//! (replay plans and their ROI changes), [`timeline`] (a replay collected for the viewer),
//! [`guide`] (a guided render's ROI over its iterations), [`render`] (the shared render loop),
//! [`calibrate`] (calibration presses), [`viewer_setup`] (the viewer's display, mapping,
//! timeline, wall camera and live source, built step by step).

pub mod calibrate;
pub mod cluster;
pub mod guide;
pub mod live;
pub mod pipeline;
pub mod render;
pub mod replay;
pub mod timeline;
pub mod udp;
pub mod viewer_setup;
pub mod vrpn;
