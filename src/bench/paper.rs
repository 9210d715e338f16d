//! The paper's setup (DESIGN.md §9), defined once for every benchmark: the HORNET wall, a viewer
//! 1 m in front of its centre pointing straight at it with a square ray-gun cone of 10°–60°,
//! the exact metric with the default falloff, the scene's own camera (or the automatic one),
//! 3840 × 2160 pixels.

use crate::trace::wall::WallCamera;
use glam::DVec3;

use crate::display::DisplayModel;
use crate::frame::{FrameError, GuideConfig, Render, Renderer};
use crate::gpu::Backend;
use crate::roi::cone::{Cone, ConeError};
use crate::roi::dgi::{
    DgiParams, Falloff, Guide, GuideError, Metric, Roi, Surface, compute_cpu, roi_radius_m,
};
use crate::scene::Scene;
use crate::trace::camera::{CameraError, RenderCamera};
use crate::trace::path::TraceSettings;

/// The paper's image size.
pub const SIZE: [u32; 2] = [3840, 2160];
/// The paper's FOVs (degrees, square cones).
pub const FOVS_DEG: [f64; 6] = [10.0, 20.0, 30.0, 40.0, 50.0, 60.0];
/// The viewer's position (room frame, metres): 1 m in front of the wall centre.
pub const ORIGIN: [f64; 3] = [0.0, 0.0, 1.0];
/// Where the viewer points: straight at the wall.
pub const DIR: [f64; 3] = [0.0, 0.0, -1.0];

/// What a measurement in the paper's setup renders: `scene` (named `name` in the reports) on
/// `backend`, for `display`'s wall.
#[derive(Clone, Copy)]
pub struct Subject<'a> {
    pub backend: &'a Backend,
    pub display: &'a DisplayModel,
    pub name: &'a str,
    pub scene: &'a Scene,
}

/// A guided render in the paper's setup: the image `size`, the square cone's `fov` (degrees),
/// how many guided `iterations`, and the `seed`.
#[derive(Clone, Copy, Debug)]
pub struct Shot {
    pub size: [u32; 2],
    pub fov: f64,
    pub iterations: u32,
    pub seed: u32,
}

/// A square cone of `fov_deg` from `origin` along `dir` (up +Y).
pub fn cone_from(origin: [f64; 3], dir: [f64; 3], fov_deg: f64) -> Result<Cone, ConeError> {
    Cone::from_pose(
        DVec3::from_array(origin),
        DVec3::from_array(dir),
        DVec3::Y,
        fov_deg,
        fov_deg,
    )
}

/// The ROI of a square cone of `fov_deg` from `origin` along `dir`.
pub fn roi_from(origin: [f64; 3], dir: [f64; 3], fov_deg: f64) -> Result<Roi, ConeError> {
    cone_from(origin, dir, fov_deg).map(Roi::Cone)
}

/// The paper's ROI: a square cone of `fov_deg` from [`ORIGIN`] along [`DIR`].
pub fn roi(fov_deg: f64) -> Result<Roi, ConeError> {
    roi_from(ORIGIN, DIR, fov_deg)
}

/// The DGI of `roi` on `surface` at `width × height` (exact metric, `falloff`), on the CPU
/// twin: the input the scheduling and filter benchmarks take.
pub fn dgi(
    surface: &Surface,
    width: u32,
    height: u32,
    roi: &Roi,
    falloff: Falloff,
) -> Result<Vec<f32>, GuideError> {
    let length = falloff.length_px(roi_radius_m(surface, roi), surface.pitch_m);
    let guide = Guide::new(surface, roi, Metric::Exact)?;
    let params = DgiParams {
        width,
        height,
        falloff_px: Some(length),
    };
    Ok(compute_cpu(surface, &guide, &params))
}

/// What every benchmark renders with: `scene`'s camera (or the automatic one) for `size`.
pub fn settings(
    scene: &Scene,
    size: [u32; 2],
    seed: u32,
    max_depth: u32,
) -> Result<TraceSettings, CameraError> {
    let [width, height] = size;
    Ok(TraceSettings {
        width,
        height,
        seed,
        max_depth,
        camera: RenderCamera::choose(scene, None, width, height)?,
    })
}

/// A guided renderer of the paper's setup with `roi` set (its DGI is computed by the first
/// frame).
pub fn guided<'a>(
    backend: &'a Backend,
    scene: &Scene,
    settings: TraceSettings,
    display: &DisplayModel,
    config: GuideConfig,
    roi: Roi,
) -> Result<Renderer<'a>, FrameError> {
    guided_wall(backend, scene, settings, display, config, roi, None)
}

/// [`guided`] through the wall camera `wall` when given (DESIGN.md §11).
pub fn guided_wall<'a>(
    backend: &'a Backend,
    scene: &Scene,
    settings: TraceSettings,
    display: &DisplayModel,
    config: GuideConfig,
    roi: Roi,
    wall: Option<&WallCamera>,
) -> Result<Renderer<'a>, FrameError> {
    let mut r = Renderer::guided_wall(backend, scene, settings, display, config, wall.cloned())?;
    r.set_roi(Some(roi))?;
    Ok(r)
}

/// A converged full-frame image of `scene` (`spp` samples per pixel, submitted 64 frames at a
/// time): the reference the error tables measure against.
pub fn reference_image(
    backend: &Backend,
    scene: &Scene,
    settings: TraceSettings,
    spp: u32,
) -> Result<Vec<glam::Vec3>, FrameError> {
    reference_image_wall(backend, scene, settings, spp, None, &mut |_| {})
}

/// [`reference_image`] through the wall camera `wall` when given (its unshown pixels black);
/// `frames_done` hears each batch of frames as it finishes (a progress report).
pub fn reference_image_wall(
    backend: &Backend,
    scene: &Scene,
    settings: TraceSettings,
    spp: u32,
    wall: Option<&WallCamera>,
    frames_done: &mut dyn FnMut(u32),
) -> Result<Vec<glam::Vec3>, FrameError> {
    let mut r = match wall {
        Some(w) => Renderer::full_wall(backend, scene, settings, w.clone())?,
        None => Renderer::full(backend, scene, settings)?,
    };
    let mut left = spp;
    while left > 0 {
        let n = left.min(64);
        r.iterate(n)?;
        frames_done(n);
        left -= n;
    }
    Ok(r.accumulation()?.mean_image())
}
