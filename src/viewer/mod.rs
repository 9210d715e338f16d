//! `raygun view`: an egui window (eframe, wgpu backend) showing the guided render as it
//! converges, steered by mouse clicks, a replay or live tracking.
//!
//! * [`state`]: the panel's settings and what they mean for the renderer;
//! * [`core`]: the renderer kept in step with them and the picture it composes, without a
//!   screen;
//! * [`diagnostics`]: the images that explain a render (ROI outline, heat map, noise);
//! * [`orbit`]: the desktop user's orbit, pan and dolly of the eye or the pinhole camera;
//! * [`save`]: the picture and its data written to files;
//! * `app`: the eframe front end (with the `viewer` feature, on by default);
//! * `tiles`: the window of an owner's own tiles (`view --cluster --show-tiles`).

#[cfg(feature = "viewer")]
pub mod app;
pub mod core;
pub mod diagnostics;
pub mod orbit;
pub mod save;
pub mod state;
pub mod texture;
#[cfg(feature = "viewer")]
pub mod tiles;

use std::path::PathBuf;

/// Why the viewer's renderer or a saved picture failed.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    #[error(transparent)]
    Schedule(#[from] crate::schedule::ScheduleError),
    #[error(transparent)]
    Falloff(#[from] crate::roi::dgi::FalloffError),
    #[error(transparent)]
    Frame(#[from] crate::frame::FrameError),
    #[error(transparent)]
    Cluster(#[from] crate::cluster::ClusterError),
    #[error("max path depth must be at least 1")]
    MaxDepth,
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    #[error(transparent)]
    File(#[from] crate::output::FileError),
    #[error("{}: cannot create the directory: {error}", dir.display())]
    CreateDir { dir: PathBuf, error: std::io::Error },
    #[error("{}: {error}", path.display())]
    Png {
        path: PathBuf,
        error: image::ImageError,
    },
    #[error("picture size mismatch")]
    PictureSize,
}
