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

pub mod roi_stats;
pub mod shown;
pub mod stop;

use std::cell::OnceCell;
use std::time::Instant;

use glam::Vec3;

use crate::display::DisplayModel;
use crate::filter::{Filter, FilterGpuError, FilterParams};
use crate::gpu::{Backend, Band, GpuContext, GpuError, PassTimer};
use crate::roi::dgi::{
    DgiParams, Falloff, Guide, GuideError, Metric, Roi, Surface, compute_cpu, roi_radius_m,
};
use crate::roi::gpu::{DgiKernel, DgiRun};
use crate::scene::Scene;
use crate::schedule::gpu::{ScheduleConfig, ScheduleKernel, ScheduleRun};
use crate::schedule::{Order, ScheduleError, schedule_cpu_shown};
use crate::trace::accum::Accumulation;
use crate::trace::camera::RenderCamera;
use crate::trace::gpu::{GpuAccum, GpuScene, TraceKernel, TraceRun};
use crate::trace::pack::PackedScene;
use crate::trace::path::{TraceSettings, render_cpu_with};
use crate::trace::wall::{WallCamera, WallCameraError};

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

/// What [`Renderer::follow_eye`] did with an eye.
#[derive(Debug)]
pub enum EyeFollow {
    /// Within the threshold of the eye the accumulation started with: nothing changed.
    Kept,
    /// Moved past the threshold: the wall camera was rebuilt at the new eye and the
    /// accumulation restarted (the ROI and its DGI kept).
    Restarted,
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

/// Timer slots of a frame's passes.
const PASS_DGI: u32 = 0;
const PASS_SCHEDULE: u32 = 1;
const PASS_TRACE: u32 = 2;

/// A frame being assembled by the steps of [`Renderer::run_frame`].
struct FrameInProgress {
    timed: bool,
    stats: FrameStats,
    /// GPU: the encoder every step records into.
    encoder: Option<wgpu::CommandEncoder>,
    /// CPU: the pixels the schedule step chose (`None`: every pixel).
    list: Option<Vec<u32>>,
    /// When the frame started (the GPU's wall-clock fallback).
    started: Instant,
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
}

impl<'a> Renderer<'a> {
    /// A full-frame render of `scene`: one path per pixel per frame.
    pub fn full(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
    ) -> Result<Self, FrameError> {
        Self::new(backend, scene, settings, None, None)
    }

    /// A full-frame render through the wall camera `wall`: every pixel its display shows, every
    /// frame; the others are never traced.
    pub fn full_wall(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
        wall: WallCamera,
    ) -> Result<Self, FrameError> {
        Self::new(backend, scene, settings, None, Some(wall))
    }

    /// A render of `settings.width × settings.height` pixels covering `display`'s canvas,
    /// steered by the ROI set with [`Self::set_roi`] (none yet: the whole frame is sampled).
    pub fn guided(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
        display: &DisplayModel,
        config: GuideConfig,
    ) -> Result<Self, FrameError> {
        Self::guided_wall(backend, scene, settings, display, config, None)
    }

    /// [`Self::guided`] through the wall camera `wall` when given: the schedule never lists a
    /// pixel its display does not show.
    pub fn guided_wall(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
        display: &DisplayModel,
        config: GuideConfig,
        wall: Option<WallCamera>,
    ) -> Result<Self, FrameError> {
        let guidance = Guidance::new(display, config)?;
        Self::new(backend, scene, settings, Some(guidance), wall)
    }

    /// A guided renderer of this one's scene with other settings, guide or wall camera
    /// ([`Self::guided_wall`]'s arguments less the scene), starting from nothing: the scene
    /// is not packed and its BVH not built again (the viewer's rebuild when its settings
    /// change or a reset is asked for: seconds for a large scene).
    pub fn rebuilt_guided(
        &self,
        settings: TraceSettings,
        display: &DisplayModel,
        config: GuideConfig,
        wall: Option<WallCamera>,
    ) -> Result<Renderer<'a>, FrameError> {
        Self::check_wall(&settings, wall.as_ref())?;
        let guidance = Guidance::new(display, config)?;
        Renderer::with_packed(
            self.backend,
            std::sync::Arc::clone(&self.packed),
            self.build_seconds,
            settings,
            Some(guidance),
            wall,
        )
    }

    /// Packs the scene, builds its BVH and prepares every stage (on the GPU: uploads and
    /// clears).
    fn new(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
        guidance: Option<Guidance>,
        wall: Option<WallCamera>,
    ) -> Result<Self, FrameError> {
        Self::check_wall(&settings, wall.as_ref())?;
        let t0 = Instant::now();
        let packed = std::sync::Arc::new(PackedScene::new(scene));
        if !backend.is_gpu() {
            // The CPU twin's own tree is one-time work: here, not in the first frame's time.
            packed.bvh.prepare_cpu();
        }
        let build_seconds = t0.elapsed().as_secs_f64();
        Self::with_packed(backend, packed, build_seconds, settings, guidance, wall)
    }

    /// A wall camera's image must be the render's.
    fn check_wall(settings: &TraceSettings, wall: Option<&WallCamera>) -> Result<(), FrameError> {
        match wall {
            Some(wc) if [wc.width, wc.height] != [settings.width, settings.height] => {
                Err(FrameError::WallSize {
                    wall: [wc.width, wc.height],
                    image: [settings.width, settings.height],
                })
            }
            _ => Ok(()),
        }
    }

    /// Prepares every stage for the packed scene `packed` (on the GPU: uploads and clears);
    /// the callers have checked the wall camera ([`Self::check_wall`]).
    fn with_packed(
        backend: &'a Backend,
        packed: std::sync::Arc<PackedScene>,
        build_seconds: f64,
        settings: TraceSettings,
        guidance: Option<Guidance>,
        wall: Option<WallCamera>,
    ) -> Result<Self, FrameError> {
        let (w, h) = (settings.width, settings.height);
        let n = w as usize * h as usize;
        let engine = match backend {
            Backend::Gpu(ctx) => {
                let ctx: &GpuContext = ctx;
                let kernel = TraceKernel::new(ctx);
                let gscene = GpuScene::upload(ctx, &kernel, &packed)?;
                let schedule_kernel = guidance.as_ref().map(|_| ScheduleKernel::new(ctx));
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                let mut bands = Vec::new();
                for band in frame_bands(ctx, w, h)? {
                    let accum = GpuAccum::new(ctx, w, band.rows)?;
                    let guide = match (&guidance, &schedule_kernel) {
                        (Some(g), Some(k)) => Some(gpu_guide(
                            ctx,
                            k,
                            w,
                            band,
                            &g.config,
                            wall.as_ref().map(WallCamera::shown_mask),
                            &kernel,
                        )?),
                        _ => None,
                    };
                    let trace = TraceRun::for_band(
                        ctx,
                        &kernel,
                        &packed,
                        &settings,
                        wall.as_ref(),
                        &accum,
                        guide
                            .as_ref()
                            .map(|g| (g.schedule.list(), g.schedule.args())),
                        band,
                    );
                    accum.clear(&mut enc);
                    if let Some(g) = &guide {
                        enc.clear_buffer(&g.dgi, 0, None);
                    }
                    bands.push(GpuBand {
                        band,
                        accum,
                        trace,
                        guide,
                    });
                }
                ctx.queue.submit([enc.finish()]);
                Engine::Gpu {
                    ctx,
                    scene: gscene,
                    bands,
                    dgi_kernel: guidance.as_ref().map(|_| DgiKernel::new(ctx)),
                    timer: PassTimer::new(ctx, 3),
                }
            }
            Backend::Cpu => Engine::Cpu {
                accum: Accumulation::new(w, h),
                guide: guidance.as_ref().map(|_| CpuGuide {
                    dgi: vec![0.0; n],
                    pending: None,
                }),
            },
        };
        Ok(Self {
            packed,
            settings,
            build_seconds,
            backend,
            guidance,
            engine,
            iteration: 0,
            filter: OnceCell::new(),
            display: OnceCell::new(),
            resident: std::cell::RefCell::new(None),
            stats: roi_stats::Stats::new(),
            wall,
        })
    }

    /// Iterations run so far.
    #[must_use]
    pub fn iteration(&self) -> u32 {
        self.iteration
    }

    /// The current ROI (`None` also for a full-frame render).
    #[must_use]
    pub fn roi(&self) -> Option<&Roi> {
        self.guidance.as_ref().and_then(|g| g.roi.as_ref())
    }

    /// How the ROI steers sampling (`None` for a full-frame render).
    #[must_use]
    pub fn guide_config(&self) -> Option<&GuideConfig> {
        self.guidance.as_ref().map(|g| &g.config)
    }

    /// The backend the frames run on.
    #[must_use]
    pub fn backend(&self) -> &'a Backend {
        self.backend
    }

    /// Sets the ROI; its DGI is computed by the next frame (`None`: sample the whole frame).
    /// The accumulation is kept: samples taken under the old ROI still count.
    pub fn set_roi(&mut self, roi: Option<Roi>) -> Result<(), FrameError> {
        let (w, h) = (self.settings.width, self.settings.height);
        let g = self.guidance.as_mut().ok_or(FrameError::NotGuided)?;
        let prepared = match &roi {
            Some(r) => Some(prepare_dgi(&g.surface, g.pitch_m, &g.config, r, [w, h])?),
            None => None,
        };
        match &mut self.engine {
            Engine::Gpu {
                ctx,
                bands,
                dgi_kernel: Some(kernel),
                ..
            } => {
                for b in bands.iter_mut() {
                    let gg = b.guide.as_mut().ok_or(FrameError::NotGuided)?;
                    gg.pending = Some(match &prepared {
                        Some((guide, params)) => PendingDgi::Run(kernel.prepare_band(
                            ctx,
                            &g.surface,
                            guide,
                            params,
                            b.band.row0,
                            b.band.rows,
                        )?),
                        None => PendingDgi::Zero,
                    });
                }
            }
            Engine::Cpu {
                guide: Some(cg), ..
            } => {
                let t0 = Instant::now();
                let dgi = match prepared {
                    Some((guide, params)) => compute_cpu(&g.surface, &guide, &params),
                    None => vec![0.0; w as usize * h as usize],
                };
                cg.pending = Some((dgi, t0.elapsed().as_secs_f64() * 1e3));
            }
            // A guided renderer always has its guided stages.
            Engine::Gpu {
                dgi_kernel: None, ..
            }
            | Engine::Cpu { guide: None, .. } => {
                return Err(FrameError::NotGuided);
            }
        }
        g.roi = roi;
        Ok(())
    }

    /// Runs one frame: the DGI if the ROI changed, the schedule, and one path for each
    /// scheduled pixel. With `timed`, stage times are measured (GPU timestamps where the
    /// adapter has them) and the pixel and ray counts are read back — for benchmarks; an
    /// interactive loop leaves it off so nothing waits on the GPU.
    pub fn run_frame(&mut self, timed: bool) -> Result<FrameStats, FrameError> {
        let mut frame = self.begin(timed);
        self.install_dgi(&mut frame);
        self.schedule(&mut frame)?;
        self.trace(&mut frame);
        self.submit(frame)
    }

    /// Starts a frame: on the GPU, the command encoder the steps record into (and, timed, the
    /// cleared ray counter).
    fn begin(&self, timed: bool) -> FrameInProgress {
        let encoder = match &self.engine {
            Engine::Gpu { ctx, bands, .. } => {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                if timed {
                    bands.iter().for_each(|b| b.accum.clear_stats(&mut enc));
                }
                Some(enc)
            }
            Engine::Cpu { .. } => None,
        };
        FrameInProgress {
            timed,
            stats: FrameStats {
                iteration: self.iteration,
                ..FrameStats::default()
            },
            encoder,
            list: None,
            started: Instant::now(),
        }
    }

    /// Step 1: installs the DGI of a changed ROI (recorded on the GPU; computed already by
    /// [`Self::set_roi`] on the CPU). Nothing for a full frame or an unchanged ROI.
    fn install_dgi(&mut self, frame: &mut FrameInProgress) {
        match &mut self.engine {
            Engine::Gpu { bands, timer, .. } => {
                let timer = timer.as_ref().filter(|_| frame.timed);
                let enc = frame.encoder.as_mut().expect("a GPU frame has an encoder");
                let last = bands.len() - 1;
                for (i, g) in bands.iter_mut().enumerate() {
                    let Some(g) = g.guide.as_mut() else { continue };
                    match g.pending.take() {
                        Some(PendingDgi::Run(run)) => {
                            run.record_with(
                                enc,
                                timer.and_then(|t| t.writes_part(PASS_DGI, i == 0, i == last)),
                            );
                            enc.copy_buffer_to_buffer(&run.output, 0, &g.dgi, 0, g.dgi.size());
                            frame.stats.dgi_recomputed = true;
                        }
                        Some(PendingDgi::Zero) => {
                            enc.clear_buffer(&g.dgi, 0, None);
                            frame.stats.dgi_recomputed = true;
                        }
                        None => {}
                    }
                }
            }
            Engine::Cpu { guide: Some(g), .. } => {
                if let Some((new, ms)) = g.pending.take() {
                    g.dgi = new;
                    frame.stats.dgi_recomputed = true;
                    if frame.timed {
                        frame.stats.ms_dgi = Some(ms);
                    }
                }
            }
            Engine::Cpu { guide: None, .. } => {}
        }
    }

    /// Step 2: chooses the pixels to trace from the DGI (p = max(p_min, 1 − d), Bernoulli,
    /// compaction into a list). A full frame traces every pixel: nothing to choose.
    fn schedule(&mut self, frame: &mut FrameInProgress) -> Result<(), FrameError> {
        let (w, h, seed) = (
            self.settings.width,
            self.settings.height,
            self.settings.seed,
        );
        let iteration = self.iteration;
        match (&mut self.engine, &self.guidance) {
            (Engine::Gpu { bands, timer, .. }, Some(_)) => {
                let timer = timer.as_ref().filter(|_| frame.timed);
                let enc = frame.encoder.as_mut().expect("a GPU frame has an encoder");
                let last = bands.len() - 1;
                for (i, b) in bands.iter().enumerate() {
                    if let Some(g) = &b.guide {
                        g.schedule.record_with(
                            enc,
                            iteration,
                            seed,
                            timer.and_then(|t| t.writes_part(PASS_SCHEDULE, i == 0, i == last)),
                        );
                    }
                }
            }
            (Engine::Cpu { guide: Some(g), .. }, Some(guidance)) => {
                let t0 = Instant::now();
                let c = &guidance.config;
                let shown = self.wall.as_ref().map(WallCamera::shown_mask);
                frame.list = Some(schedule_cpu_shown(
                    &g.dgi, shown, w, h, c.p_min, iteration, seed, c.order,
                )?);
                if frame.timed {
                    frame.stats.ms_schedule = Some(t0.elapsed().as_secs_f64() * 1e3);
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// Step 3: one path for each scheduled pixel (every pixel of a full frame), added to the
    /// accumulation.
    fn trace(&mut self, frame: &mut FrameInProgress) {
        match &mut self.engine {
            Engine::Gpu {
                scene,
                bands,
                timer,
                ..
            } => {
                let timer = timer.as_ref().filter(|_| frame.timed);
                let enc = frame.encoder.as_mut().expect("a GPU frame has an encoder");
                let last = bands.len() - 1;
                for (i, b) in bands.iter().enumerate() {
                    b.trace.record_with(
                        enc,
                        scene,
                        timer.and_then(|t| t.writes_part(PASS_TRACE, i == 0, i == last)),
                    );
                }
            }
            Engine::Cpu { accum, .. } => {
                let t0 = Instant::now();
                let list = frame.list.as_deref();
                let rays = render_cpu_with(
                    &self.packed,
                    &self.settings,
                    self.wall.as_ref(),
                    accum,
                    list,
                );
                let pixels = list.map_or_else(|| self.full_frame_pixels(), |l| l.len() as u32);
                frame.stats.pixels = Some(pixels);
                frame.stats.rays = Some(rays);
                if frame.timed {
                    frame.stats.ms_trace = Some(t0.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
    }

    /// Ends the frame: on the GPU, submits the steps' work once (and, timed, waits and reads
    /// the timestamps and counts back).
    fn submit(&mut self, frame: FrameInProgress) -> Result<FrameStats, FrameError> {
        let FrameInProgress {
            timed,
            mut stats,
            encoder,
            started,
            ..
        } = frame;
        if let Engine::Gpu {
            ctx,
            bands,
            dgi_kernel,
            timer,
            ..
        } = &self.engine
        {
            let guided = dgi_kernel.is_some();
            let timer = timer.as_ref().filter(|_| timed);
            let mut enc = encoder.expect("a GPU frame has an encoder");
            if let Some(t) = timer {
                t.resolve(&mut enc);
            }
            ctx.queue.submit([enc.finish()]);
            if !guided {
                stats.pixels = Some(self.full_frame_pixels());
            }
            if timed {
                ctx.wait()?;
                let wall = started.elapsed().as_secs_f64() * 1e3;
                if guided {
                    let mut pixels = 0;
                    for g in bands.iter().filter_map(|b| b.guide.as_ref()) {
                        pixels += g.schedule.read_args(ctx)?[3];
                    }
                    stats.pixels = Some(pixels);
                }
                match timer {
                    Some(t) => {
                        let ms = t.read_ms(ctx)?;
                        stats.ms_dgi = stats.dgi_recomputed.then_some(ms[PASS_DGI as usize]);
                        if guided {
                            stats.ms_schedule = Some(ms[PASS_SCHEDULE as usize]);
                        }
                        stats.ms_trace = Some(ms[PASS_TRACE as usize]);
                        stats.gpu_timestamps = true;
                    }
                    // Without timestamps only the whole frame can be timed.
                    None => stats.ms_trace = Some(wall),
                }
                let mut rays = 0;
                for b in bands {
                    rays += b.accum.rays(ctx)?;
                }
                stats.rays = Some(rays);
            }
        }
        self.iteration += 1;
        Ok(stats)
    }

    /// Pixels a full frame traces: every pixel, or those the wall camera's display shows.
    fn full_frame_pixels(&self) -> u32 {
        self.wall
            .as_ref()
            .map_or(self.settings.width * self.settings.height, |w| {
                w.shown_count() as u32
            })
    }

    /// The bands of rows a GPU frame is split into to fit the adapter's storage bindings
    /// (1: unsplit); `None` on the CPU backend.
    #[must_use]
    pub fn gpu_bands(&self) -> Option<usize> {
        match &self.engine {
            Engine::Gpu { bands, .. } => Some(bands.len()),
            Engine::Cpu { .. } => None,
        }
    }

    /// The wall camera, if the frames trace through one.
    #[must_use]
    pub fn wall(&self) -> Option<&WallCamera> {
        self.wall.as_ref()
    }

    /// Restarts the accumulation: every pixel's sum and count back to zero and the iteration
    /// counter to 0 (the schedule draws as a fresh renderer's do). The ROI, its DGI (installed
    /// or pending) and the scene stay.
    pub fn restart(&mut self) {
        match &mut self.engine {
            Engine::Gpu { ctx, bands, .. } => {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                bands.iter().for_each(|b| b.accum.clear(&mut enc));
                ctx.queue.submit([enc.finish()]);
            }
            Engine::Cpu { accum, .. } => {
                accum.sum.fill([0.0; 4]);
                accum.count.fill(0);
            }
        }
        self.iteration = 0;
    }

    /// Moves the wall camera's eye to `eye` (room frame; the room's placement in the scene
    /// kept, [`WallCamera::with_eye`]) and restarts the accumulation ([`Self::restart`]).
    pub fn set_wall_eye(&mut self, eye: glam::DVec3) -> Result<(), FrameError> {
        let wall = self
            .wall
            .as_ref()
            .ok_or(FrameError::NoWall)?
            .with_eye(eye)?;
        if let Engine::Gpu { ctx, bands, .. } = &mut self.engine {
            for b in bands.iter_mut() {
                let done = b.trace.set_wall(ctx, &self.packed, &self.settings, &wall);
                debug_assert!(done, "a moved wall camera keeps its tiles");
            }
        }
        self.wall = Some(wall);
        self.restart();
        Ok(())
    }

    /// The restart rule of a moving eye (a tracked head, a desktop user's orbit): when `eye`
    /// lies more than `threshold_m` from the eye the accumulation started with, the wall camera
    /// moves there and the accumulation restarts, the ROI kept; otherwise nothing changes.
    pub fn follow_eye(
        &mut self,
        eye: glam::DVec3,
        threshold_m: f64,
    ) -> Result<EyeFollow, FrameError> {
        let wall = self.wall.as_ref().ok_or(FrameError::NoWall)?;
        if !wall.eye_moved(eye, threshold_m) {
            return Ok(EyeFollow::Kept);
        }
        match self.set_wall_eye(eye) {
            Ok(()) => Ok(EyeFollow::Restarted),
            Err(FrameError::Wall(e)) => Ok(EyeFollow::Refused(e)),
            Err(e) => Err(e),
        }
    }

    /// Replaces the pinhole (or orthographic) camera and restarts the accumulation
    /// ([`Self::restart`]); the ROI stays. (With a wall camera the primary rays come from its
    /// eye: move that with [`Self::set_wall_eye`].)
    pub fn set_camera(&mut self, camera: RenderCamera) {
        self.settings.camera = camera;
        if let Engine::Gpu { ctx, bands, .. } = &self.engine {
            for b in bands {
                b.trace.set_settings(ctx, &self.packed, &self.settings);
            }
        }
        self.restart();
    }

    /// Runs `n` frames and waits for them.
    pub fn iterate(&mut self, n: u32) -> Result<(), FrameError> {
        for _ in 0..n {
            self.run_frame(false)?;
        }
        self.wait()
    }

    /// Waits until the submitted frames are done (nothing to wait for on the CPU).
    pub fn wait(&self) -> Result<(), FrameError> {
        match &self.engine {
            Engine::Gpu { ctx, .. } => Ok(ctx.wait()?),
            Engine::Cpu { .. } => Ok(()),
        }
    }

    /// Runs `n` frames one at a time and times the trace step of each (for benchmarks).
    pub fn timed_iterations(&mut self, n: u32) -> Result<TimedIterations, FrameError> {
        let mut ms = Vec::with_capacity(n as usize);
        let mut rays = 0u64;
        let mut stamps = false;
        for _ in 0..n {
            let s = self.run_frame(true)?;
            ms.push(s.ms_trace.unwrap_or(f64::NAN));
            rays += s.rays.unwrap_or(0);
            stamps = s.gpu_timestamps;
        }
        Ok(TimedIterations {
            ms,
            rays_per_iteration: rays as f64 / f64::from(n.max(1)),
            gpu_timestamps: stamps,
        })
    }

    /// The accumulation so far (a read-back on the GPU).
    pub fn accumulation(&self) -> Result<Accumulation, FrameError> {
        Ok(match &self.engine {
            Engine::Gpu { ctx, bands, .. } => read_bands(ctx, bands)?,
            Engine::Cpu { accum, .. } => accum.clone(),
        })
    }

    /// The DGI the last frame used (a read-back on the GPU; 0 everywhere for a full frame).
    pub fn dgi(&self) -> Result<Vec<f32>, FrameError> {
        let n = self.settings.width as usize * self.settings.height as usize;
        Ok(match &self.engine {
            Engine::Gpu {
                ctx,
                bands,
                dgi_kernel: Some(_),
                ..
            } => {
                // The first band's read-back is the vector (a one-band frame's whole DGI).
                let mut parts = bands.iter().filter_map(|b| b.guide.as_ref());
                let mut dgi = match parts.next() {
                    Some(g) => ctx.read_buffer::<f32>(&g.dgi)?,
                    None => Vec::new(),
                };
                dgi.reserve(n.saturating_sub(dgi.len()));
                for g in parts {
                    dgi.extend(ctx.read_buffer::<f32>(&g.dgi)?);
                }
                dgi
            }
            Engine::Cpu { guide: Some(g), .. } => g.dgi.clone(),
            Engine::Gpu {
                dgi_kernel: None, ..
            }
            | Engine::Cpu { guide: None, .. } => vec![0.0; n],
        })
    }

    /// Step 4, when a picture is wanted: the mean image filtered by `params` with the DGI
    /// (linear RGB, row-major), on this renderer's backend.
    pub fn picture(&self, params: &FilterParams) -> Result<Vec<Vec3>, FrameError> {
        let acc = self.accumulation()?;
        let dgi = self.dgi()?;
        self.picture_of(params, &acc, &dgi)
    }

    /// The picture of an accumulation and DGI read back already (see [`Self::picture`]).
    pub fn picture_of(
        &self,
        params: &FilterParams,
        acc: &Accumulation,
        dgi: &[f32],
    ) -> Result<Vec<Vec3>, FrameError> {
        let filter = self.filter.get_or_init(|| Filter::new(self.backend));
        let mut image = filter.image(params, acc, dgi)?;
        if let Some(w) = &self.wall {
            w.blank_unshown(&mut image);
        }
        Ok(image)
    }

    /// The accumulation and the DGI the last frame used, ending the render (moved out on the
    /// CPU, read back on the GPU).
    pub fn finish(self) -> Result<(Accumulation, Vec<f32>), FrameError> {
        let dgi = self.dgi()?;
        Ok(match self.engine {
            Engine::Gpu { ctx, bands, .. } => (read_bands(ctx, &bands)?, dgi),
            Engine::Cpu { accum, .. } => (accum, dgi),
        })
    }
}

/// The DGI job of `roi` for a `size` image on `surface` (pitch `pitch_m` metres per canvas
/// pixel): the guide and the parameters with the falloff `config` gives that ROI's radius.
pub fn prepare_dgi(
    surface: &Surface,
    pitch_m: f64,
    config: &GuideConfig,
    roi: &Roi,
    [width, height]: [u32; 2],
) -> Result<(Guide, DgiParams), FrameError> {
    let guide = Guide::new(surface, roi, config.metric)?;
    let length = config
        .falloff
        .length_px(roi_radius_m(surface, roi), pitch_m);
    Ok((
        guide,
        DgiParams {
            width,
            height,
            falloff_px: Some(length),
        },
    ))
}

/// The DGI of `roi` (`None`: 0 everywhere) computed by the CPU twin: what a CPU renderer's
/// [`Renderer::set_roi`] installs, value for value.
pub fn dgi_cpu(
    surface: &Surface,
    pitch_m: f64,
    config: &GuideConfig,
    roi: Option<&Roi>,
    size: [u32; 2],
) -> Result<Vec<f32>, FrameError> {
    Ok(match roi {
        Some(r) => {
            let (guide, params) = prepare_dgi(surface, pitch_m, config, r, size)?;
            compute_cpu(surface, &guide, &params)
        }
        None => vec![0.0; size[0] as usize * size[1] as usize],
    })
}

/// [`dgi_cpu`] of the bands of [`crate::roi::dgi::BLOCK`] rows `k`, `k + n`, … alone (0
/// elsewhere), each bit for bit the whole image's: the share of rank `k` of `n` when the ranks
/// split the DGI.
pub fn dgi_cpu_bands(
    surface: &Surface,
    pitch_m: f64,
    config: &GuideConfig,
    roi: Option<&Roi>,
    size: [u32; 2],
    (k, n): (usize, usize),
) -> Result<Vec<f32>, FrameError> {
    Ok(match roi {
        Some(r) => {
            let (guide, params) = prepare_dgi(surface, pitch_m, config, r, size)?;
            crate::roi::dgi::compute_cpu_bands(surface, &guide, &params, k, n)
        }
        None => vec![0.0; size[0] as usize * size[1] as usize],
    })
}

/// The bands of a `w × h` frame on this adapter: one where every buffer fits a storage
/// binding, else as few bands of rows as fit (the accumulation's 16 bytes a pixel is the
/// largest buffer).
fn frame_bands(ctx: &GpuContext, w: u32, h: u32) -> Result<Vec<Band>, FrameError> {
    let max = ctx.max_binding();
    Band::split(w, h, ACCUM_BYTES_PER_PIXEL, max).ok_or_else(|| {
        GpuError::TooLarge {
            what: "one row of the accumulation (16 bytes per pixel)",
            bytes: u64::from(w) * ACCUM_BYTES_PER_PIXEL,
            max,
        }
        .into()
    })
}

/// Bytes per pixel of the largest per-pixel GPU buffer, the accumulation's RGB sum and
/// Σ luminance².
const ACCUM_BYTES_PER_PIXEL: u64 = 16;

/// The bands' accumulations read back and joined into the whole frame's (one band: its own,
/// with no second copy).
fn read_bands(ctx: &GpuContext, bands: &[GpuBand]) -> Result<Accumulation, GpuError> {
    if let [one] = bands {
        return one.accum.read(ctx);
    }
    let (w, h) = (
        bands[0].accum.width,
        bands.iter().map(|b| b.band.rows).sum(),
    );
    let mut acc = Accumulation {
        width: w,
        height: h,
        sum: Vec::with_capacity(w as usize * h as usize),
        count: Vec::with_capacity(w as usize * h as usize),
    };
    for b in bands {
        let part = b.accum.read(ctx)?;
        acc.sum.extend(part.sum);
        acc.count.extend(part.count);
    }
    Ok(acc)
}

/// The bits of `shown` (bit `p % 32` of word `p / 32` for image pixel `p`) for the `n` pixels
/// from `base`, as a mask of their own.
fn band_mask(shown: &[u32], base: u32, n: u32) -> Vec<u32> {
    let words = n.div_ceil(32) as usize;
    if base.is_multiple_of(32) {
        // Word-aligned (a one-band frame's band, say): the words as they are. Bits past the
        // band's last pixel may belong to the next band; the kernel never reads them.
        let first = (base / 32) as usize;
        return shown[first..first + words].to_vec();
    }
    let bit = |p: u32| (shown[(p / 32) as usize] >> (p % 32)) & 1;
    let mut out = vec![0u32; words];
    for p in 0..n {
        out[(p / 32) as usize] |= bit(base + p) << (p % 32);
    }
    out
}

/// The guided stages on the GPU for one `band` of a `w`-wide frame, with a cleared DGI.
fn gpu_guide(
    ctx: &GpuContext,
    kernel: &ScheduleKernel,
    w: u32,
    band: Band,
    config: &GuideConfig,
    shown: Option<&[u32]>,
    trace: &TraceKernel,
) -> Result<GpuGuide, FrameError> {
    let dgi = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("frame dgi"),
        size: u64::from(w) * u64::from(band.rows) * 4,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let base = band.pixel_base(w);
    let mask = shown.map(|m| band_mask(m, base, w * band.rows));
    let schedule = kernel.prepare_band(
        ctx,
        &dgi,
        mask.as_deref(),
        &ScheduleConfig {
            width: w,
            height: band.rows,
            p_min: config.p_min,
            order: config.order,
            trace_workgroup_size: trace.workgroup(),
            trace_max_groups: trace.max_list_groups(),
        },
        base,
    )?;
    Ok(GpuGuide {
        dgi,
        schedule,
        pending: None,
    })
}
