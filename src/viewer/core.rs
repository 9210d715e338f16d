//! The viewer without a screen: the panel's settings ([`ViewerState`]), what they mean for the
//! renderer, and [`ViewerCore`], which keeps the renderer in step with them — one process's
//! [`Renderer`], or rank 0's part of a render across ranks, read through [`Render`] — and
//! composes the picture the window shows. The egui front end (`app.rs`) only maps widgets and
//! clicks onto these; tests drive them directly.
//!
//! The panel's settings are in `state.rs`, the images that explain a render (ROI outline, sample
//! heat map, noise map and its regions) in `diagnostics.rs`.

use std::time::{Duration, Instant};

use glam::{DVec3, Vec3};

use crate::cluster::{CONSOLE_PIXELS, reduction_for};
use crate::display::DisplayModel;
use crate::filter::{Denoiser, Filter};
use crate::frame::{EyeFollow, FrameStats, GuideConfig, Render, Renderer};
use crate::gpu::Backend;
use crate::output::stats::RoiStats;
use crate::output::tiles::wall_view;
use crate::roi::dgi::Roi;
use crate::scene::Scene;
use crate::session::cluster::{Applied, ClusterView, ViewStep};
use crate::trace::accum::Accumulation;
use crate::trace::camera::RenderCamera;
use crate::trace::features::pixel_features;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

use super::ViewerError;
use super::diagnostics::{heat_map, noise_image, noise_map, roi_outline};
use super::orbit::{camera_moved, camera_orbit, eye_orbit};
use super::state::{Overlay, ViewerState};
use crate::output::srgb8::paint_outline;

/// Live statistics.
#[derive(Clone, Copy, Debug, Default)]
pub struct Stats {
    pub iterations: u32,
    pub iterations_per_s: f64,
    /// Share of pixels the last timed frame traced.
    pub sampled_share: Option<f64>,
    pub last_timed: Option<FrameStats>,
    /// The DGI stage's time when it last ran in a timed frame (the frame after an ROI change
    /// is always timed).
    pub ms_dgi: Option<f64>,
    /// The picture's reduction: every `console_every`-th pixel of every such row of the
    /// image (1: every pixel; more only across ranks, for an image larger than rank 0's
    /// console shows: [`ViewerCore::console_pixels`]). The statistics below are over the
    /// picture's pixels.
    pub console_every: u32,
    /// Samples in the ROI (pixels with d = 0) and the mean per ROI pixel.
    pub roi_samples: u64,
    pub roi_pixels: u64,
    /// Median standard error of the mean luminance ([`noise_image`]) over the ROI's noisy
    /// pixels and the periphery's ([`NoiseContrast`](crate::output::stats::NoiseContrast));
    /// `None` without an ROI or such pixels.
    pub roi_noise: Option<f32>,
    pub periphery_noise: Option<f32>,
    /// The ROI's progress as `render --until` measures it (median SE over every ROI pixel,
    /// fewest samples), and the seconds the current ROI has been sampled for.
    pub roi_progress: Option<crate::frame::stop::RoiProgress>,
    pub seconds_on_roi: f64,
    /// The denoiser of the last picture with the image (`None`: none).
    pub denoised_by: Option<ShownDenoiser>,
    /// Pixels with a NaN or infinite sum raygun's denoiser dropped from the last picture.
    pub denoise_dropped: u64,
}

impl Stats {
    /// Seconds until the ROI's median SE reaches `target` at the rate it has fallen so far
    /// (`Some(0.0)`: reached); `None` while it cannot be told.
    #[must_use]
    pub fn seconds_to_target(&self, target: f64) -> Option<f64> {
        self.roi_progress?
            .seconds_to_se(target, self.seconds_on_roi)
    }
}

/// What the renderer was built with: a change rebuilds it (and restarts the accumulation).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Built {
    config: GuideConfig,
    max_depth: u32,
}

/// The picture the window shows: RGBA8, row-major, `size`.
#[derive(Clone, Debug)]
pub struct Picture {
    pub size: [u32; 2],
    pub rgba: Vec<u8>,
    /// The filtered image (linear RGB), the DGI and the counts it was made from.
    pub image: Vec<Vec3>,
    pub dgi: Vec<f32>,
    pub counts: Vec<u32>,
    /// The standard error of each pixel's mean luminance ([`noise_image`]; NaN below two
    /// samples), of the unfiltered accumulation.
    pub noise: Vec<f32>,
}

/// What the viewer renders with. Across ranks every change goes to every rank as a
/// [`ViewStep`] the moment the viewer makes it, so rank 0's renderer is always the one the
/// others have.
enum Engine<'a> {
    Local(Box<Renderer<'a>>),
    Cluster(Box<ClusterView<'a>>),
}

/// `$body` with `$r` the renderer the viewer reads, through [`Render`]: one process's, or rank
/// 0's part of the job (every rank applies the same steps, so it stands for every rank's).
macro_rules! read {
    ($engine:expr, |$r:ident| $body:expr) => {
        match $engine {
            Engine::Local(local) => {
                let $r: &Renderer<'_> = local;
                $body
            }
            Engine::Cluster(view) => {
                let $r = view.renderer();
                $body
            }
        }
    };
}

impl Engine<'_> {
    fn set_roi(&mut self, roi: Option<Roi>) -> Result<(), ViewerError> {
        match self {
            Self::Local(r) => r.set_roi(roi)?,
            Self::Cluster(v) => {
                v.send(ViewStep::Roi(roi))?;
            }
        }
        Ok(())
    }

    /// The restart rule of a moving eye (across ranks rank 0 decides; every rank moves).
    fn follow_eye(&mut self, eye: DVec3, threshold_m: f64) -> Result<EyeFollow, ViewerError> {
        Ok(match self {
            Self::Local(r) => r.follow_eye(eye, threshold_m)?,
            Self::Cluster(v) => v.follow_eye(eye, threshold_m)?,
        })
    }

    /// What the last move carried over (across ranks: every move restarts).
    fn last_reuse(&self) -> Option<crate::trace::reuse::ReuseStats> {
        match self {
            Self::Local(r) => r.last_reuse(),
            Self::Cluster(_) => None,
        }
    }

    fn set_camera(&mut self, camera: RenderCamera) -> Result<(), ViewerError> {
        match self {
            Self::Local(r) => r.set_camera(camera)?,
            Self::Cluster(v) => {
                v.send(ViewStep::Camera(camera))?;
            }
        }
        Ok(())
    }

    fn run_frame(&mut self, timed: bool) -> Result<FrameStats, ViewerError> {
        match self {
            Self::Local(r) => Ok(r.run_frame(timed)?),
            Self::Cluster(v) => match v.send(ViewStep::Frame)? {
                // Rank 0's stages, the exchange that waits for the slowest rank with the trace.
                Applied::Frame(s) => Ok(s.into()),
                _ => unreachable!("a frame step gives a frame"),
            },
        }
    }

    /// The accumulation and the DGI at every `every`-th pixel of every `every`-th row (across
    /// ranks: gathered from the owners; one process's is whole: `every` is 1 there).
    fn accumulation(&mut self, every: u32) -> Result<(Accumulation, Vec<f32>), ViewerError> {
        match self {
            Self::Local(r) => {
                assert_eq!(every, 1, "one process's picture is whole");
                Ok(r.gather()?.expect("one process holds its whole picture"))
            }
            Self::Cluster(v) => match v.send(ViewStep::Gather { every })? {
                Applied::Gathered(Some(g)) => Ok(g),
                _ => unreachable!("rank 0 gathers"),
            },
        }
    }
}

/// The renderer kept in step with a [`ViewerState`].
pub struct ViewerCore<'a> {
    backend: &'a Backend,
    pub model: &'a DisplayModel,
    base: TraceSettings,
    pub state: ViewerState,
    engine: Engine<'a>,
    built: Built,
    /// Frames since the renderer was built, and when (for iterations per second).
    window: (u32, Instant),
    /// When the ROI last changed (or the accumulation restarted).
    roi_since: Instant,
    pub stats: Stats,
    /// Why the last eye the state asked for was refused (on or behind a tile's plane).
    pub eye_refused: Option<String>,
    /// Accumulation restarts since the start because the eye or the camera moved.
    pub restarts: u32,
    /// Moves of the eye or the camera that carried the accumulation over.
    pub moves_reused: u32,
    /// What the last move carried over (`None`: it restarted, or none yet).
    pub last_reuse: Option<crate::trace::reuse::ReuseStats>,
    /// Across ranks, the filter of rank 0's pictures (on `backend`), made once.
    filter: std::cell::OnceCell<Filter<'a>>,
    /// The most pixels of the window's picture across ranks ([`CONSOLE_PIXELS`] unless set;
    /// the window sets the pixels it shows the picture on).
    pub console_pixels: u64,
    /// When a picture that stays on the GPU last measured the statistics
    /// ([`Self::window_picture`]; `None`: measure on the next one).
    stats_at: Option<Instant>,
    /// When the last window picture was done, what it took, and the look it showed
    /// ([`Self::picture_due`]).
    last_picture: Option<(Instant, Duration, Look)>,
    /// Intel Open Image Denoise, where it was opened (`view --denoise oidn`): the picture once
    /// the ROI and the eye are still.
    oidn: Option<crate::filter::oidn::Device>,
}

/// What a window picture shows besides the accumulation: a change is shown at once.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Look {
    overlay: Overlay,
    exposure: f32,
    filter: crate::filter::FilterParams,
    /// The denoiser the picture gets (`None`: off).
    denoiser: Option<ShownDenoiser>,
    roi_outline: bool,
    wall_view: bool,
}

/// Which denoiser made a shown picture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShownDenoiser {
    /// raygun's interactive denoiser.
    Interactive,
    /// Intel Open Image Denoise (the ROI and the eye still).
    Oidn,
}

/// What the window shows: RGBA8, row-major, `size` (see [`ViewerCore::window_picture`]).
#[derive(Clone, Debug)]
pub struct WindowPicture {
    pub size: [u32; 2],
    pub rgba: Vec<u8>,
    /// Whether the picture stayed on the GPU (filtered and converted there).
    pub resident: bool,
}

/// How often a window picture that stays on the GPU measures the statistics (on a GPU a
/// measurement is one submit and 208 bytes read back, [`Renderer::roi_stats`]; the period keeps
/// the numbers readable).
pub const STATS_PERIOD: Duration = Duration::from_millis(500);

/// Every this many frames one is timed (stage times, pixel count), which makes the GPU wait.
pub const TIMED_EVERY: u32 = 8;

impl<'a> ViewerCore<'a> {
    pub fn new(
        backend: &'a Backend,
        scene: &'a Scene,
        model: &'a DisplayModel,
        base: TraceSettings,
        state: ViewerState,
    ) -> Result<Self, ViewerError> {
        Self::with_wall(backend, scene, model, base, state, None)
    }

    /// [`Self::new`] through the wall camera `wall` when given (`view --camera wall`): its eye
    /// follows [`ViewerState::wanted_eye`] under the restart rule.
    pub fn with_wall(
        backend: &'a Backend,
        scene: &'a Scene,
        model: &'a DisplayModel,
        base: TraceSettings,
        mut state: ViewerState,
        wall: Option<WallCamera>,
    ) -> Result<Self, ViewerError> {
        let config = state.guide_config()?;
        let settings = TraceSettings {
            max_depth: state.max_depth,
            ..base
        };
        if state.view.is_none() {
            state.view = match &wall {
                Some(w) => eye_orbit(model, w.eye_room),
                None => camera_orbit(&base.camera, focus_distance(scene, &base)),
            };
        }
        let mut renderer = Renderer::guided_wall(backend, scene, settings, model, config, wall)?;
        renderer.set_on_eye_move(state.on_eye_move);
        Ok(Self::with_engine(
            backend,
            model,
            base,
            state,
            Engine::Local(Box::new(renderer)),
        ))
    }

    /// [`Self::new`] as rank 0 of a render across ranks (`view --cluster`, DESIGN.md §12):
    /// `view` renders (the other ranks follow it), and every change of the state goes to every
    /// rank. `backend` filters the picture: rank 0's own (its GPU when its rank traces on
    /// one, sharing the device: the one-process GPU viewer's filter), else the CPU twin.
    pub fn over_cluster(
        backend: &'a Backend,
        scene: &'a Scene,
        model: &'a DisplayModel,
        base: TraceSettings,
        mut state: ViewerState,
        view: ClusterView<'a>,
    ) -> Result<Self, ViewerError> {
        state.guide_config()?;
        if state.view.is_none() {
            state.view = match view.renderer().wall() {
                Some(w) => eye_orbit(model, w.eye_room),
                None => camera_orbit(&base.camera, focus_distance(scene, &base)),
            };
        }
        Ok(Self::with_engine(
            backend,
            model,
            base,
            state,
            Engine::Cluster(Box::new(view)),
        ))
    }

    fn with_engine(
        backend: &'a Backend,
        model: &'a DisplayModel,
        base: TraceSettings,
        state: ViewerState,
        engine: Engine<'a>,
    ) -> Self {
        let built = read!(&engine, |r| Built {
            config: *r.guide_config().expect("the viewer's render is guided"),
            max_depth: r.settings().max_depth,
        });
        Self {
            backend,
            model,
            base,
            built,
            state,
            engine,
            window: (0, Instant::now()),
            roi_since: Instant::now(),
            stats: Stats::default(),
            eye_refused: None,
            restarts: 0,
            moves_reused: 0,
            last_reuse: None,
            filter: std::cell::OnceCell::new(),
            console_pixels: CONSOLE_PIXELS,
            stats_at: None,
            last_picture: None,
            oidn: None,
        }
    }

    /// The denoiser `by` names, with the filter's variance threshold from `params`.
    fn denoiser(&self, by: ShownDenoiser, params: &crate::filter::FilterParams) -> Denoiser<'_> {
        match (by, &self.oidn) {
            (ShownDenoiser::Oidn, Some(device)) => {
                Denoiser::Oidn(device, crate::filter::oidn::Quality::Fast)
            }
            _ => Denoiser::Interactive(crate::filter::denoise::DenoiseParams {
                variance_threshold: params.variance_threshold,
                ..Default::default()
            }),
        }
    }

    /// Hands the viewer an OIDN device for `denoise` = `oidn` (DESIGN.md §8).
    pub fn set_oidn(&mut self, device: crate::filter::oidn::Device) {
        self.oidn = Some(device);
    }

    /// Whether OIDN was opened (the panel offers it then).
    #[must_use]
    pub fn has_oidn(&self) -> bool {
        self.oidn.is_some()
    }

    /// The denoiser the next picture gets: none when off; OIDN where asked for and opened once
    /// the ROI and the eye have been still for [`STILL_SECONDS`](super::state::STILL_SECONDS);
    /// otherwise raygun's interactive denoiser. Across ranks rank 0 denoises its gathered
    /// picture with its own copy of the scene's features, and the owners their tiles.
    #[must_use]
    pub fn shown_denoiser(&self) -> Option<ShownDenoiser> {
        use crate::filter::DenoiseKind;
        match self.state.denoise {
            DenoiseKind::Off => None,
            DenoiseKind::Oidn
                if self.oidn.is_some()
                    && self.roi_since.elapsed().as_secs_f64() >= super::state::STILL_SECONDS =>
            {
                Some(ShownDenoiser::Oidn)
            }
            DenoiseKind::Interactive | DenoiseKind::Oidn => Some(ShownDenoiser::Interactive),
        }
    }

    /// The wall camera's eye (room frame), the one the accumulation started with.
    #[must_use]
    pub fn eye(&self) -> Option<DVec3> {
        self.wall().map(|w| w.eye_room)
    }

    #[must_use]
    pub fn size(&self) -> [u32; 2] {
        [self.base.width, self.base.height]
    }

    /// The one-process renderer's one-time work before its first frame, in seconds: the BVH's
    /// build and the upload ([`Renderer::build_seconds`], [`Renderer::upload_seconds`]);
    /// `None` across ranks.
    #[must_use]
    pub fn set_up_seconds(&self) -> Option<(f64, f64)> {
        match &self.engine {
            Engine::Local(r) => Some((r.build_seconds, r.upload_seconds)),
            Engine::Cluster(_) => None,
        }
    }

    /// The backend in words.
    #[must_use]
    pub fn backend_name(&self) -> String {
        match &self.engine {
            Engine::Local(_) => self.backend.describe(),
            Engine::Cluster(v) => v.describe(),
        }
    }

    /// Iterations in the renderer's accumulation (since it last restarted).
    #[must_use]
    pub fn iteration(&self) -> u32 {
        read!(&self.engine, |r| r.iteration())
    }

    /// The ROI the renderer has.
    #[must_use]
    pub fn roi(&self) -> Option<&Roi> {
        read!(&self.engine, |r| r.roi())
    }

    /// The settings the renderer traces with (the panel's path depth, the camera as moved).
    #[must_use]
    pub fn settings(&self) -> &TraceSettings {
        read!(&self.engine, |r| r.settings())
    }

    /// How the ROI steers the renderer's sampling.
    #[must_use]
    pub fn guide_config(&self) -> Option<&GuideConfig> {
        read!(&self.engine, |r| r.guide_config())
    }

    /// The wall camera, if the renderer traces through one.
    #[must_use]
    pub fn wall(&self) -> Option<&WallCamera> {
        read!(&self.engine, |r| r.wall())
    }

    /// Brings the renderer in line with the state: rebuilds it when the guide settings or the
    /// path depth changed or a reset was asked for, and hands it a changed ROI. Returns whether
    /// the ROI changed.
    pub fn sync(&mut self) -> Result<bool, ViewerError> {
        if self.state.max_depth == 0 {
            return Err(ViewerError::MaxDepth);
        }
        let config = self.state.guide_config()?;
        let want = Built {
            config,
            max_depth: self.state.max_depth,
        };
        if want != self.built || self.state.reset {
            let max_depth = self.state.max_depth;
            match &mut self.engine {
                Engine::Local(r) => {
                    let settings = TraceSettings {
                        max_depth,
                        camera: r.settings.camera,
                        ..self.base
                    };
                    let wall = r.wall().cloned();
                    **r = r.rebuilt_guided(settings, self.model, config, wall)?;
                }
                Engine::Cluster(v) => {
                    v.send(ViewStep::Rebuild { config, max_depth })?;
                }
            }
            self.built = want;
            self.state.reset = false;
            self.restarted();
        }
        self.follow_viewpoint()?;
        let roi = self.state.roi();
        let changed = self.roi() != roi.as_ref();
        if changed {
            let t0 = Instant::now();
            self.roi_since = t0;
            self.engine.set_roi(roi)?;
            // The CPU twin computes the DGI right here; the GPU records it into the next frame
            // (timed by its timestamps), and so do ranks.
            if matches!(self.backend, Backend::Cpu) && matches!(self.engine, Engine::Local(_)) {
                self.stats.ms_dgi = Some(t0.elapsed().as_secs_f64() * 1e3);
            }
        }
        Ok(changed)
    }

    /// What a move of the eye or the camera does from now on (one process: across ranks every
    /// move restarts).
    pub fn set_on_eye_move(&mut self, policy: crate::frame::EyeMove) {
        self.state.on_eye_move = policy;
        if let Engine::Local(r) = &mut self.engine {
            r.set_on_eye_move(policy);
        }
    }

    /// Whether one process renders (not ranks across a cluster).
    #[must_use]
    pub fn is_local(&self) -> bool {
        matches!(self.engine, Engine::Local(_))
    }

    /// The frame counter and the statistics start again (the accumulation did).
    fn restarted(&mut self) {
        self.window = (0, Instant::now());
        self.roi_since = Instant::now();
        self.stats = Stats::default();
        self.stats_at = None;
    }

    /// Moves the wall camera's eye to the one the state asks for, or the pinhole camera to the
    /// desktop viewpoint, under the restart rule: past the threshold from where the
    /// accumulation started, it restarts (the ROI kept); within it, nothing changes. A
    /// refused eye leaves the camera as it was and puts the desktop viewpoint back there.
    fn follow_viewpoint(&mut self) -> Result<(), ViewerError> {
        let threshold = self.state.eye_threshold_m;
        if self.wall().is_some() {
            // While the head leads, the desktop viewpoint follows it, so a drag starts there.
            if self.state.follow_head
                && let (Some(h), Some(v)) = (self.state.head, &mut self.state.view)
            {
                v.set_position(h);
            }
            let Some(eye) = self.state.wanted_eye() else {
                return Ok(());
            };
            match self.engine.follow_eye(eye, threshold)? {
                EyeFollow::Kept => {}
                EyeFollow::Restarted => {
                    self.eye_refused = None;
                    self.restarts += 1;
                    self.last_reuse = None;
                    self.restarted();
                }
                EyeFollow::Reused(stats) => {
                    self.eye_refused = None;
                    self.moves_reused += 1;
                    self.last_reuse = Some(stats);
                }
                EyeFollow::Refused(e) => {
                    self.eye_refused = Some(e.to_string());
                    let at = self.eye();
                    if let (Some(v), Some(at)) = (&mut self.state.view, at) {
                        v.set_position(at);
                    }
                }
            }
        } else if let Some(v) = &self.state.view {
            let now = self.settings().camera;
            let camera = v.camera(&now);
            if camera_moved(&now, &camera, threshold) {
                self.engine.set_camera(camera)?;
                self.last_reuse = self.engine.last_reuse();
                if self.last_reuse.is_some() {
                    self.moves_reused += 1;
                } else {
                    self.restarts += 1;
                    self.restarted();
                }
            }
        }
        Ok(())
    }

    /// Syncs, then runs frames for about `budget` (at least one).
    pub fn step(&mut self, budget: Duration) -> Result<(), ViewerError> {
        let mut roi_changed = self.sync()?;
        let t0 = Instant::now();
        loop {
            let timed = roi_changed || self.iteration().is_multiple_of(TIMED_EVERY);
            roi_changed = false;
            let s = self.engine.run_frame(timed)?;
            if timed {
                self.stats.last_timed = Some(s);
                if s.ms_dgi.is_some() {
                    self.stats.ms_dgi = s.ms_dgi;
                }
                let n = f64::from(self.base.width) * f64::from(self.base.height);
                self.stats.sampled_share = s.pixels.map(|p| f64::from(p) / n);
            }
            self.window.0 += 1;
            if t0.elapsed() >= budget {
                break;
            }
        }
        self.stats.iterations = self.iteration();
        let secs = self.window.1.elapsed().as_secs_f64();
        if secs > 0.0 {
            self.stats.iterations_per_s = f64::from(self.window.0) / secs;
        }
        Ok(())
    }

    /// The reduction of the window's picture: 1 in one process (its picture is whole); across
    /// ranks, the least k for which every k-th pixel of every k-th row fits
    /// [`Self::console_pixels`] ([`reduction_for`]).
    #[must_use]
    pub fn console_every(&self) -> u32 {
        match self.engine {
            Engine::Local(_) => 1,
            Engine::Cluster(_) => reduction_for(self.size(), self.console_pixels),
        }
    }

    /// The picture with its data (image, DGI, counts, noise) at the window's reduction:
    /// [`Self::picture_every`] at [`Self::console_every`]. The window itself shows
    /// [`Self::window_picture`], the same bytes.
    pub fn picture(&mut self) -> Result<Picture, ViewerError> {
        self.picture_every(self.console_every())
    }

    /// The whole picture, every pixel (saves).
    pub fn whole_picture(&mut self) -> Result<Picture, ViewerError> {
        self.picture_every(1)
    }

    /// The picture the window shows this UI frame. With one process on a GPU, the image
    /// overlay and a frame of one band, it stays on the GPU ([`Renderer::shown_picture`]: the
    /// filter reads the renderer's buffers, the display kernel converts, 4 bytes a pixel come
    /// back; the ROI outline painted there from the DGI) and the statistics are measured every
    /// [`STATS_PERIOD`] where the accumulation lives ([`Renderer::roi_stats`]: a guided
    /// renderer's on the GPU, nothing read back without an ROI). Otherwise it is
    /// [`Self::picture`]'s (without the filtered image the DGI, count and noise overlays do
    /// not show). Either way the same bytes as [`Self::picture`] (tested); files take
    /// [`Self::whole_picture`].
    pub fn window_picture(&mut self) -> Result<WindowPicture, ViewerError> {
        let t0 = Instant::now();
        let picture = self.make_window_picture()?;
        self.last_picture = Some((Instant::now(), t0.elapsed(), self.look()));
        Ok(picture)
    }

    /// The GPU the renderer runs on, where it is one process's renderer on a GPU: a window that
    /// draws with this device can be handed the picture on it ([`Self::window_picture_into`]).
    #[must_use]
    pub fn gpu(&self) -> Option<&crate::gpu::GpuContext> {
        match (&self.engine, self.backend) {
            (Engine::Local(_), Backend::Gpu(ctx)) => Some(ctx),
            _ => None,
        }
    }

    /// [`Self::window_picture`] written into `texture` on the GPU instead of read back
    /// ([`Renderer::shown_picture_into`]: the window's texture, `Rgba8Unorm`, on the renderer's
    /// device, the picture's size, `COPY_DST`), where the picture stays there: one process on
    /// a GPU, the image overlay, a filter that fits one binding and not the wall view (which
    /// rearranges the bytes on the CPU). `Ok(false)`: not here, nothing written — take
    /// [`Self::window_picture`]. The statistics are measured on the GPU as there.
    pub fn window_picture_into(&mut self, texture: &wgpu::Texture) -> Result<bool, ViewerError> {
        let t0 = Instant::now();
        let params = self.state.filter_params();
        // The wall view rearranges the bytes on the CPU.
        if !self.picture_stays_on_gpu(&params) || self.state.wall_view {
            return Ok(false);
        }
        self.refresh_gpu_stats()?;
        let Engine::Local(r) = &self.engine else {
            unreachable!("checked above");
        };
        r.shown_picture_into(
            &params,
            self.state.exposure,
            self.state.roi_outline,
            texture,
        )?;
        // Waited for, so that what it took is the kernels' time ([`Self::picture_due`]: on a
        // slow device pictures still take at most half of the time).
        if let Some(ctx) = self.gpu() {
            ctx.wait().map_err(crate::frame::FrameError::from)?;
        }
        self.last_picture = Some((Instant::now(), t0.elapsed(), self.look()));
        Ok(true)
    }

    /// Whether the window's picture with `params` is made where the accumulation lives: one
    /// process's renderer that keeps its picture on the GPU ([`Renderer::shows_on_gpu`]) under
    /// the image overlay (the others show no filtered picture).
    fn picture_stays_on_gpu(&self, params: &crate::filter::FilterParams) -> bool {
        match &self.engine {
            // A denoised picture takes the host path (the features and the denoiser's buffers
            // are not bound to the renderer's).
            Engine::Local(r) => {
                self.state.overlay == Overlay::Image
                    && self.shown_denoiser().is_none()
                    && r.shows_on_gpu(params)
            }
            Engine::Cluster(_) => false,
        }
    }

    /// Every [`STATS_PERIOD`], the statistics measured where a GPU renderer's accumulation
    /// lives (a few dozen bytes back, nothing read back but them).
    fn refresh_gpu_stats(&mut self) -> Result<(), ViewerError> {
        let Engine::Local(r) = &self.engine else {
            return Ok(());
        };
        if self.stats_at.is_none_or(|t| t.elapsed() >= STATS_PERIOD) {
            let measured = r.roi_stats()?;
            self.set_stats(measured, 1);
            self.stats_at = Some(Instant::now());
        }
        self.stats.seconds_on_roi = self.roi_since.elapsed().as_secs_f64();
        Ok(())
    }

    /// Whether the window should make a new picture this UI frame (it shows its last one
    /// otherwise): when it has none, when the look changed (overlay, exposure, filter, outline,
    /// wall view), or when at least as long as the last picture took has passed since it was
    /// done — so that a picture that costs more than the rendering between pictures (the CPU
    /// twin's filter: 170 ms at 960×540, against 30 ms of rendering a UI frame) takes at most
    /// half of the time, and a picture that stays on the GPU (a few ms) comes every UI frame.
    #[must_use]
    pub fn picture_due(&self) -> bool {
        self.last_picture
            .is_none_or(|(done, took, look)| look != self.look() || done.elapsed() >= took)
    }

    /// What the last window picture took.
    #[must_use]
    pub fn picture_took(&self) -> Option<Duration> {
        self.last_picture.map(|(_, took, _)| took)
    }

    fn look(&self) -> Look {
        let s = &self.state;
        Look {
            overlay: s.overlay,
            exposure: s.exposure,
            filter: s.filter_params(),
            denoiser: self.shown_denoiser(),
            roi_outline: s.roi_outline,
            wall_view: s.wall_view,
        }
    }

    fn make_window_picture(&mut self) -> Result<WindowPicture, ViewerError> {
        let params = self.state.filter_params();
        if !self.picture_stays_on_gpu(&params) {
            // Another overlay than the image shows no filtered picture: none is made.
            let with_image = self.state.overlay == Overlay::Image;
            let p = self.compose(self.console_every(), with_image)?;
            return Ok(WindowPicture {
                size: p.size,
                rgba: p.rgba,
                resident: false,
            });
        }
        // Measured where the accumulation lives (a GPU renderer of one band), not read back.
        self.refresh_gpu_stats()?;
        let Engine::Local(r) = &self.engine else {
            unreachable!("checked above");
        };
        // The outline painted by the display kernel from the DGI on the GPU.
        let shown = r.shown_picture(&params, self.state.exposure, self.state.roi_outline, false)?;
        let (size, rgba) = (shown.size, shown.rgba);
        Ok(WindowPicture {
            size,
            rgba: self.wall_view(rgba, size),
            resident: true,
        })
    }

    /// The statistics measured over a picture's accumulation and DGI (every `every`-th pixel
    /// of every such row of the image) and its noise image.
    fn measure_stats(&mut self, acc: &Accumulation, dgi: &[f32], noise: &[f32], every: u32) {
        let full_width = self.size()[0] as usize;
        let width = acc.width as usize;
        let step = every as usize;
        let pixel = |i: usize| ((i / width * step) * full_width + (i % width) * step) as u32;
        let measured = if self.roi().is_some() {
            let wall = self.wall();
            let shown = |i: usize| wall.is_none_or(|w| w.is_shown(pixel(i)));
            let p_min = self.guide_config().map_or(0.0, |c| c.p_min);
            RoiStats::measure_with_noise(acc, dgi, noise, p_min, shown)
        } else {
            RoiStats::default()
        };
        self.set_stats(measured, every);
    }

    /// Shows `measured`, taken over every `every`-th pixel of every such row.
    fn set_stats(&mut self, measured: RoiStats, every: u32) {
        self.stats.console_every = every;
        self.stats.roi_samples = measured.roi_samples;
        self.stats.roi_pixels = measured.roi_pixels;
        self.stats.roi_noise = measured.contrast.map(|c| c.roi);
        self.stats.periphery_noise = measured.contrast.map(|c| c.periphery);
        self.stats.roi_progress = measured.progress;
        self.stats.seconds_on_roi = self.roi_since.elapsed().as_secs_f64();
    }

    /// The picture as the wall shows it when the state asks for the wall view, else as it is.
    fn wall_view(&self, rgba: Vec<u8>, size: [u32; 2]) -> Vec<u8> {
        if !self.state.wall_view {
            return rgba;
        }
        let px: Vec<[u8; 4]> = rgba
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect();
        wall_view(self.model, &px, size, [0, 0, 0, 255]).concat()
    }

    /// Reads the accumulation and the DGI back at every `every`-th pixel of every `every`-th
    /// row (1: whole), filters, and composes the picture for the state's overlay (with the ROI
    /// outline and the wall view as asked); the statistics are measured over its pixels.
    pub fn picture_every(&mut self, every: u32) -> Result<Picture, ViewerError> {
        self.compose(every, true)
    }

    /// [`Self::picture_every`]; without `with_image` the filtered image is not made (its
    /// `image` is empty): the DGI, count and noise overlays do not show it, and the filter is
    /// most of a picture's cost on the CPU twin and its round trip most of the bytes on a GPU.
    fn compose(&mut self, every: u32, with_image: bool) -> Result<Picture, ViewerError> {
        let (acc, dgi) = self.engine.accumulation(every)?;
        let full_width = self.size()[0] as usize;
        let width = acc.width as usize;
        let step = every as usize;
        // The image pixel a picture pixel is.
        let pixel = |i: usize| ((i / width * step) * full_width + (i % width) * step) as u32;
        if let Engine::Cluster(v) = &mut self.engine
            && v.shows_tiles()
        {
            // Every owner shows its own tiles' pictures (`view --show-tiles`); rank 0's
            // window shows the whole picture, so its own tiles' go unused here.
            v.send(ViewStep::Tiles {
                filter: self.state.filter_params(),
                exposure: self.state.exposure,
                denoise: self.state.denoise != crate::filter::DenoiseKind::Off,
            })?;
        }
        let wall = self.wall();
        let shown = |i: usize| wall.is_none_or(|w| w.is_shown(pixel(i)));
        let params = self.state.filter_params();
        let denoised_by = self.shown_denoiser().filter(|_| with_image);
        let mut dropped = 0;
        let image = match &self.engine {
            _ if !with_image => Vec::new(),
            Engine::Local(r) => match denoised_by {
                None => r.picture_of(&params, &acc, &dgi)?,
                Some(by) => {
                    let denoiser = self.denoiser(by, &params);
                    let image;
                    (image, dropped) =
                        r.denoised_picture_of(&params, denoiser, &acc, &dgi, every)?;
                    image
                }
            },
            Engine::Cluster(_) => {
                // Across ranks on rank 0's backend (a reduced picture at its own size), the
                // wall camera's unshown pixels black.
                let filter = self.filter.get_or_init(|| Filter::new(self.backend));
                let mut image = filter
                    .image(&params, &acc, &dgi)
                    .map_err(crate::frame::FrameError::from)?;
                for (i, v) in image.iter_mut().enumerate() {
                    if !shown(i) {
                        *v = Vec3::ZERO;
                    }
                }
                if let (Some(by), Engine::Cluster(v)) = (denoised_by, &self.engine) {
                    // The features of the picture's pixels, from rank 0's copy of the scene.
                    let r = v.renderer();
                    let (albedo, normal_depth) = (0..image.len())
                        .map(|i| pixel_features(&r.packed, &r.settings, r.wall(), pixel(i)))
                        .unzip();
                    let features = crate::filter::denoise::Features {
                        width: acc.width,
                        height: acc.height,
                        albedo,
                        normal_depth,
                    };
                    let denoiser = self.denoiser(by, &params);
                    (image, dropped) = crate::frame::denoise_picture(
                        self.backend,
                        denoiser,
                        &acc,
                        &features,
                        &image,
                        None,
                    )?;
                    for (i, v) in image.iter_mut().enumerate() {
                        if !shown(i) {
                            *v = Vec3::ZERO;
                        }
                    }
                }
                image
            }
        };
        let noise = noise_image(&acc);
        self.measure_stats(&acc, &dgi, &noise, every);
        if with_image {
            self.stats.denoised_by = denoised_by;
            self.stats.denoise_dropped = dropped;
        }
        let size = [acc.width, acc.height];
        let mut rgba = match self.state.overlay {
            Overlay::Image => crate::output::srgb8::display_rgba(&image, self.state.exposure),
            Overlay::Dgi => dgi
                .iter()
                .flat_map(|&d| {
                    let g = crate::output::unit_to_u8(d);
                    [g, g, g, 255]
                })
                .collect(),
            Overlay::Counts => heat_map(&acc.count),
            Overlay::Noise => noise_map(&noise),
        };
        if self.state.roi_outline && self.roi().is_some() {
            paint_outline(&mut rgba, &roi_outline(&dgi, size));
        }
        let rgba = self.wall_view(rgba, size);
        Ok(Picture {
            size,
            rgba,
            image,
            dgi,
            counts: acc.count,
            noise,
        })
    }
}

/// How far in front of the pinhole its orbit's target lies: to the scene's centre along the
/// view (at least a tenth of the scene's size), or 1 without triangles.
fn focus_distance(scene: &Scene, base: &TraceSettings) -> f64 {
    let Some(b) = scene.bounds() else {
        return 1.0;
    };
    let c = base.camera;
    let along = (b.center() - c.position).dot(c.forward);
    f64::from(along.max(0.1 * b.size().length()).max(1e-3))
}
