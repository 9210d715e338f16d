//! The one interface a progressive render is driven through (DESIGN.md §1): the render loop
//! (`session::render`), the viewer and the benchmarks drive one process's [`Renderer`] and one
//! rank's part of a render across MPI ranks (`cluster::ClusterRenderer`, DESIGN.md §12) alike.
//!
//! [`Render`] holds what every caller needs and nothing more: what the render was built with,
//! the ROI and the eye (under the restart rule of a moving eye, DESIGN.md §11), one iteration,
//! and what the callers read back — the ROI's progress and the whole accumulation. What only one
//! renderer has stays its own: the GPU-resident picture and the ROI's statistics of one process,
//! the owners' tiles and the collectives of a rank.

use glam::DVec3;

use super::stop::RoiProgress;
use super::{EyeFollow, FrameStats, GuideConfig};
use crate::roi::dgi::Roi;
use crate::trace::accum::Accumulation;
use crate::trace::camera::RenderCamera;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

#[cfg(doc)]
use super::Renderer;

/// A progressive render, full frame or steered by an ROI on a display wall, run one iteration
/// at a time. Every rank of a job calls the same methods in the same order (a rank's frames and
/// reads are collectives); one process calls them as it likes.
pub trait Render {
    /// Why a call failed.
    type Error: std::error::Error + Send + Sync + 'static;
    /// What one frame did; every caller can read it as one process's [`FrameStats`].
    type Stats: Copy + Into<FrameStats>;

    /// What the frames trace with: the image's size, the seed, the path depth, the camera.
    fn settings(&self) -> &TraceSettings;

    /// How the ROI steers sampling (`None` for a full-frame render).
    fn guide_config(&self) -> Option<&GuideConfig>;

    /// The wall camera, if the frames trace through one.
    fn wall(&self) -> Option<&WallCamera>;

    /// The current ROI (`None` also for a full-frame render).
    fn roi(&self) -> Option<&Roi>;

    /// Iterations in the accumulation (since it last restarted).
    fn iteration(&self) -> u32;

    /// Sets the ROI; its DGI is installed by the next frame (`None`: sample the whole frame).
    /// The accumulation is kept: samples taken under the old ROI still count.
    fn set_roi(&mut self, roi: Option<Roi>) -> Result<(), Self::Error>;

    /// The restart rule of a moving eye (a tracked head, a desktop user's orbit;
    /// [`crate::tracking::head::eye_moved`]): when `eye` lies more than `threshold_m` from the
    /// eye the accumulation started with, the wall camera moves there and the accumulation
    /// restarts, the ROI and its DGI kept; otherwise nothing changes.
    fn follow_eye(&mut self, eye: DVec3, threshold_m: f64) -> Result<EyeFollow, Self::Error>;

    /// Replaces the pinhole (or orthographic) camera and restarts the accumulation (or, where
    /// the renderer reuses it on a move, carries it over); the ROI stays. (With a wall camera
    /// the primary rays come from its eye: [`Self::follow_eye`].)
    fn set_camera(&mut self, camera: RenderCamera) -> Result<(), Self::Error>;

    /// One iteration: the DGI of a changed ROI, the schedule, and one path for each scheduled
    /// pixel. With `timed`, stage times are measured and counts read back where that makes the
    /// renderer wait (one process's GPU: for benchmarks; an interactive loop leaves it off).
    fn run_frame(&mut self, timed: bool) -> Result<Self::Stats, Self::Error>;

    /// How far the pixels of d = 0 have come (with a wall camera, those its display shows):
    /// the ROI's, or every pixel's while there is no ROI. `None` without such pixels, and where
    /// this process does not hold the measurement (a rank other than 0).
    fn roi_progress(&mut self) -> Result<Option<RoiProgress>, Self::Error>;

    /// The whole accumulation and the DGI the last frame used, where this process holds the
    /// picture: one process always, rank 0 of a job (the owners send it their sums); `None` on
    /// the other ranks.
    fn gather(&mut self) -> Result<Option<(Accumulation, Vec<f32>)>, Self::Error>;
}
