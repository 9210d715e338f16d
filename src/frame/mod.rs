//! One frame of the pipeline (DESIGN.md §1), on either backend:
//!
//! ```text
//! install the DGI (if the ROI changed) ──► schedule (p = max(p_min, 1 − d), Bernoulli,
//!     compaction) ──► trace exactly the listed pixels into the accumulation
//!                                        ──► filter and picture (when asked)
//! ```
//!
//! [`Renderer::run_frame`] is that function, one named step per stage, each choosing its
//! backend inside. On the GPU every step records into one command encoder — the DGI only when
//! the ROI changed, then the scheduler, whose pixel count feeds the tracer's indirect dispatch
//! — and the frame submits once: nothing is read back. On the CPU the twins run in the same
//! order on the same data, so both backends take the same decisions. Per-pixel sample counts
//! live in the accumulation and persist across ROI changes. [`Renderer::picture`] filters the
//! accumulation with the DGI when a picture is wanted.
//!
//! On the GPU a frame whose buffers exceed the adapter's largest storage binding runs in bands
//! of rows (`GpuBand`, DESIGN.md §11): every step records one dispatch per band into its pass,
//! and every kernel computes the image pixel's values, so the split changes nothing.
//!
//! A full-frame render ([`Renderer::full`]) is a guided frame without an ROI and without a
//! display: its DGI is 0 everywhere, so every pixel is traced every frame and the scheduling
//! step has nothing to decide (the tracer covers the frame directly). A guided render before
//! its first shot is the same: d = 0 everywhere.
//!
//! [`stop`] holds the halt conditions measured on the accumulation (`--until`).
//!
//! [`Renderer`] is one type in files by job: its set-up (the backends' buffers and kernels, the
//! bands) in `engine.rs`, the frame's steps and what changes between frames in `steps.rs`, the
//! accumulation read back and the picture in `picture.rs`, the features and the denoised
//! picture in `denoise.rs`, an ROI's DGI in `dgi.rs`, the window's picture in [`shown`] and the
//! ROI's statistics in [`roi_stats`].

mod denoise;
mod dgi;
mod engine;
mod picture;
mod render;
mod reuse;
pub mod roi_stats;
pub mod shown;
mod steps;
pub mod stop;

use std::cell::OnceCell;

use crate::display::DisplayModel;
use crate::filter::{Filter, FilterGpuError};
use crate::gpu::{Backend, Band, GpuContext, GpuError, PassTimer};
use crate::roi::dgi::{Falloff, GuideError, Metric, Roi, Surface};
use crate::roi::gpu::{DgiKernel, DgiRun};
use crate::schedule::gpu::ScheduleRun;
use crate::schedule::{Order, ScheduleError};
use crate::trace::accum::Accumulation;
use crate::trace::gpu::{GpuAccum, GpuScene, TraceRun};
use crate::trace::pack::PackedScene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::{WallCamera, WallCameraError};

pub use denoise::{denoise_picture, filled_where_unreached};
pub use dgi::{dgi_cpu, dgi_cpu_bands, prepare_dgi};
pub use render::Render;
pub use reuse::EyeMove;

/// How the ROI steers sampling.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GuideConfig {
    pub metric: Metric,
    pub falloff: Falloff,
    /// Lowest sampling probability (paper preset 0).
    pub p_min: f32,
    pub order: Order,
}

impl Default for GuideConfig {
    fn default() -> Self {
        Self {
            metric: Metric::Exact,
            falloff: Falloff::default(),
            p_min: 0.0,
            order: Order::Coherent,
        }
    }
}

/// Why a frame (or the renderer's set-up) failed.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Schedule(#[from] ScheduleError),
    #[error(transparent)]
    Guide(#[from] GuideError),
    #[error(transparent)]
    Filter(#[from] FilterGpuError),
    #[error(transparent)]
    Denoise(#[from] crate::filter::oidn::OidnError),
    #[error(transparent)]
    DenoiseInput(#[from] crate::filter::denoise::DenoiseInputError),
    #[error(transparent)]
    DenoiseGpu(#[from] crate::filter::denoise::gpu::DenoiseGpuError),
    #[error(
        "a full-frame renderer has no display to aim an ROI at (build it with Renderer::guided)"
    )]
    NotGuided,
    #[error(
        "the wall camera was built for a {}×{} image, the renderer's is {}×{}",
        wall[0], wall[1], image[0], image[1]
    )]
    WallSize { wall: [u32; 2], image: [u32; 2] },
    #[error("this renderer has no wall camera whose eye could move (build it with a wall camera)")]
    NoWall,
    #[error(
        "this renderer's picture does not stay on a GPU (a CPU renderer, a frame in bands or a filter larger than one binding): it cannot be written into a texture"
    )]
    NotResident,
    #[error(
        "a picture of {}×{} cannot be written into a {}×{}×{} {format:?} texture (it needs the picture's size, one layer, Rgba8Unorm or Rgba8UnormSrgb, and COPY_DST usage)",
        picture[0], picture[1], texture[0], texture[1], texture[2]
    )]
    PictureTexture {
        texture: [u32; 3],
        format: wgpu::TextureFormat,
        picture: [u32; 2],
    },
    #[error(transparent)]
    Wall(#[from] WallCameraError),
}

/// What [`Render::follow_eye`] did with an eye.
#[derive(Debug)]
pub enum EyeFollow {
    /// Within the threshold of the eye the accumulation started with: nothing changed.
    Kept,
    /// Moved past the threshold: the wall camera was rebuilt at the new eye and the
    /// accumulation restarted (the ROI and its DGI kept).
    Restarted,
    /// Moved past the threshold: the wall camera was rebuilt at the new eye and the
    /// accumulation carried over where the surfaces allow ([`EyeMove::Reuse`]).
    Reused(crate::trace::reuse::ReuseStats),
    /// Moved past the threshold to where no wall camera can be (on or behind a tile's plane):
    /// nothing changed.
    Refused(WallCameraError),
}

/// What one frame did.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct FrameStats {
    pub iteration: u32,
    /// Whether the DGI was recomputed (the ROI changed).
    pub dgi_recomputed: bool,
    /// Pixels traced (CPU: always; GPU: full frames always, guided ones only with timing,
    /// which reads the count back).
    pub pixels: Option<u32>,
    /// Stage times in ms (GPU timestamps or CPU wall clock), when timing was asked for.
    pub ms_dgi: Option<f64>,
    pub ms_schedule: Option<f64>,
    pub ms_trace: Option<f64>,
    /// Whether `ms_*` come from GPU timestamps (else the CPU's clock).
    #[serde(skip)]
    pub gpu_timestamps: bool,
    /// Rays traced (closest-hit and shadow rays; CPU: always; GPU: with timing).
    #[serde(skip)]
    pub rays: Option<u64>,
}

/// Times of frames run one at a time.
#[derive(Clone, Debug)]
pub struct TimedIterations {
    /// Milliseconds of the trace step per iteration: GPU timestamps where the adapter has them,
    /// else wall clock around submit-and-wait (CPU: wall clock).
    pub ms: Vec<f64>,
    /// Rays traced per iteration (closest-hit and shadow rays), averaged.
    pub rays_per_iteration: f64,
    /// Whether `ms` comes from GPU timestamps.
    pub gpu_timestamps: bool,
}

/// Where the ROI is aimed and how it steers sampling (a guided renderer only).
struct Guidance {
    config: GuideConfig,
    surface: Surface,
    pitch_m: f64,
    roi: Option<Roi>,
}

impl Guidance {
    /// `config` (its p_min checked) on `display`'s surface, no ROI yet.
    fn new(display: &DisplayModel, config: GuideConfig) -> Result<Self, FrameError> {
        crate::schedule::validate_p_min(config.p_min)?;
        Ok(Self {
            config,
            surface: Surface::from_model(display),
            pitch_m: display.pitch_m(),
            roi: None,
        })
    }
}

/// A new DGI for the next frame to install.
enum PendingDgi {
    Run(DgiRun),
    /// No ROI: d = 0 everywhere.
    Zero,
}

/// The guided stages of one band on the GPU: the DGI the scheduler reads (a DGI run's output
/// is copied in on ROI changes), the scheduler, and a DGI change waiting for the next frame.
struct GpuGuide {
    dgi: wgpu::Buffer,
    schedule: ScheduleRun,
    pending: Option<PendingDgi>,
}

/// One band of rows of a GPU frame (DESIGN.md §11): a frame whose buffers fit the adapter's
/// storage bindings is one band; a larger one is split into bands of rows, each with its own
/// accumulation, DGI, schedule and trace dispatch, recorded one after another into the same
/// passes. Every kernel computes the image pixel's values, so the split changes nothing.
struct GpuBand {
    band: Band,
    accum: GpuAccum,
    trace: TraceRun,
    guide: Option<GpuGuide>,
}

/// The guided stages on the CPU: the DGI in use and the next one with the ms it took.
struct CpuGuide {
    dgi: Vec<f32>,
    pending: Option<(Vec<f32>, f64)>,
}

// One engine per renderer: the size difference between the variants does not matter.
#[allow(clippy::large_enum_variant)]
enum Engine<'a> {
    Gpu {
        ctx: &'a GpuContext,
        scene: GpuScene,
        bands: Vec<GpuBand>,
        /// The DGI kernel of a guided renderer.
        dgi_kernel: Option<DgiKernel>,
        timer: Option<PassTimer>,
    },
    Cpu {
        accum: Accumulation,
        guide: Option<CpuGuide>,
    },
}

/// A progressive render, full frame or steered by an ROI on a display wall: the one object
/// every command, the viewer and the benchmarks drive.
pub struct Renderer<'a> {
    /// The packed scene and its BVH, shared with the renderers rebuilt from this one
    /// ([`Self::rebuilt_guided`]).
    pub packed: std::sync::Arc<PackedScene>,
    pub settings: TraceSettings,
    /// Seconds spent building the BVH and packing the scene.
    pub build_seconds: f64,
    /// Seconds spent preparing the backend for the packed scene, once, before the first
    /// frame: on a GPU compiling the kernels, uploading the scene and making and clearing the
    /// first buffers (waited for until the GPU has done them); on the CPU allocating the
    /// accumulation.
    pub upload_seconds: f64,
    backend: &'a Backend,
    guidance: Option<Guidance>,
    engine: Engine<'a>,
    iteration: u32,
    /// The filter stage, made on the first picture (its GPU kernels compile once).
    filter: OnceCell<Filter<'a>>,
    /// The display kernel, made on the first shown picture on the GPU.
    display: OnceCell<crate::output::gpu::DisplayKernel>,
    /// The filter and display kernel bound to this renderer's buffers ([`shown`]).
    resident: std::cell::RefCell<Option<shown::Resident>>,
    /// The ROI's statistics bound to this renderer's buffers ([`roi_stats`]).
    stats: roi_stats::Stats,
    /// The wall camera (DESIGN.md §11): primary rays from its eye through each pixel's wall
    /// point, and only the pixels its display shows are scheduled and traced.
    wall: Option<WallCamera>,
    /// The current view's feature buffers, made on the first denoised picture and dropped when
    /// the view changes ([`Renderer::restart`]).
    features: OnceCell<crate::filter::denoise::Features>,
    /// raygun's denoiser's kernels, made on the first denoised picture on the GPU.
    denoise_kernels: OnceCell<crate::filter::denoise::gpu::DenoiseKernels>,
    /// What a move of the eye or the camera does to the accumulation ([`EyeMove`]).
    on_eye_move: EyeMove,
    /// The current view's primary-hit records (motion reuse): made at the first move.
    hits: Option<reuse::Hits>,
    /// What the last move carried over.
    last_reuse: Option<crate::trace::reuse::ReuseStats>,
}
