//! The viewer without a screen: the panel's settings ([`ViewerState`]), what they mean for the
//! renderer, and [`ViewerCore`], which keeps a [`Renderer`] in step with them and
//! composes the picture the window shows. The egui front end (`app.rs`) only maps widgets and
//! clicks onto these; tests drive them directly.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use glam::{DVec2, Vec3};

use crate::display::DisplayModel;
use crate::filter::{FilterKind, FilterParams};
use crate::frame::{FrameStats, GuideConfig, Renderer};
use crate::gpu::Backend;
use crate::interaction::{CursorMark, CursorSmoother, RoiState};
use crate::output::tiles::wall_view;
use crate::roi::dgi::{Falloff, Metric, Roi};
use crate::scene::Scene;
use crate::schedule::Order;
use crate::trace::accum::Accumulation;
use crate::trace::path::TraceSettings;

use crate::session::timeline::Timeline;

/// Where the ROI comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RoiSource {
    /// A click on the image; its size from the panel.
    Mouse,
    /// A replay, played / paused / scrubbed in the panel.
    Replay,
    /// Live DTrack or OSC traffic.
    Live,
}

/// What the image shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Overlay {
    /// The (filtered) render.
    Image,
    /// The distance-guide image, d in [0, 1] as grey.
    Dgi,
    /// Samples per pixel as a heat map (0 black … most samples white).
    Counts,
    /// The standard error of each pixel's mean luminance ([`noise_image`]) as grey, scaled so
    /// the 99th percentile is white; pixels with fewer than two samples (undefined) dark blue.
    Noise,
}

/// Every setting of the panel.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewerState {
    pub source: RoiSource,
    /// Centre of the mouse ROI, canvas pixels.
    pub mouse_centre: Option<DVec2>,
    /// Radius of the (circular) mouse ROI, canvas pixels.
    pub mouse_radius_px: f64,
    pub falloff_base_m: f64,
    pub falloff_scale: f64,
    pub p_min: f32,
    pub metric: Metric,
    pub order: Order,
    pub filter: FilterParams,
    pub max_depth: u32,
    pub overlay: Overlay,
    pub roi_outline: bool,
    /// Show the canvas as the wall shows it (pixels behind bezels black).
    pub wall_view: bool,
    pub exposure: f32,
    /// A full opening angle (degrees, both axes) replacing the tracked ROI's own (the stick's).
    pub fov_override_deg: Option<f64>,
    /// Replay clock, seconds, and whether it runs.
    pub replay_t: f64,
    pub playing: bool,
    /// The latest tracked ROI (replay or live) and the ray gun's raw aim, canvas pixels.
    pub tracked: Option<RoiState>,
    pub aim: Option<DVec2>,
    /// The drawn cursor: the aim smoothed over the events' times (the ROI keeps the raw pose
    /// of the trigger press), and the replay time up to which it has been fed.
    pub cursor: CursorSmoother,
    cursor_fed_t: Option<f64>,
    /// Set by the "reset accumulation" button; cleared when the renderer has been rebuilt.
    pub reset: bool,
    /// The ROI's target standard error (`view --target-se`): the panel shows the time to it.
    pub target_se: Option<f64>,
}

impl ViewerState {
    /// The defaults of `render` (guide and filter) with a mouse ROI of 600 canvas pixels
    /// (about 32 cm on HORNET) not yet placed.
    #[must_use]
    pub fn new(source: RoiSource, max_depth: u32) -> Self {
        let falloff = Falloff::default();
        Self {
            source,
            mouse_centre: None,
            mouse_radius_px: 600.0,
            falloff_base_m: falloff.base_m,
            falloff_scale: falloff.scale,
            p_min: 0.0,
            metric: Metric::Exact,
            order: Order::Coherent,
            filter: FilterParams::default(),
            max_depth,
            overlay: Overlay::Image,
            roi_outline: true,
            wall_view: false,
            exposure: 0.0,
            fov_override_deg: None,
            replay_t: 0.0,
            playing: true,
            tracked: None,
            aim: None,
            cursor: CursorSmoother::new(crate::interaction::CursorConfig::default()),
            cursor_fed_t: None,
            reset: false,
            target_se: None,
        }
    }

    /// A click at image pixel `image_px` (centres at `i + 0.5`) of a `size` image: centres the
    /// mouse ROI there (canvas coordinates) and makes the mouse the ROI source.
    pub fn click(&mut self, model: &DisplayModel, image_px: DVec2, size: [u32; 2]) {
        self.mouse_centre = Some(model.image_to_canvas(image_px, size));
        self.source = RoiSource::Mouse;
    }

    /// The ROI the renderer should use.
    #[must_use]
    pub fn roi(&self) -> Option<Roi> {
        match self.source {
            RoiSource::Mouse => self.mouse_centre.map(|c| Roi::CanvasEllipse {
                center: c,
                semi_axes: DVec2::splat(self.mouse_radius_px),
            }),
            RoiSource::Replay | RoiSource::Live => {
                let mut r = self.tracked.clone()?;
                if let Some(f) = self.fov_override_deg {
                    r.fov_deg = [f, f];
                }
                r.to_roi().ok().flatten()
            }
        }
    }

    /// The guide configuration the renderer gets (errors name the bad setting).
    pub fn guide_config(&self) -> Result<GuideConfig, ViewerError> {
        crate::schedule::validate_p_min(self.p_min)?;
        Ok(GuideConfig {
            metric: self.metric,
            falloff: Falloff::new(self.falloff_base_m, self.falloff_scale)?,
            p_min: self.p_min,
            order: self.order,
        })
    }

    /// The filter the picture uses: the panel's, off while a tracked device has toggled the
    /// filter off.
    #[must_use]
    pub fn filter_params(&self) -> FilterParams {
        let tracked_off =
            self.source != RoiSource::Mouse && self.tracked.as_ref().is_some_and(|r| !r.filter);
        FilterParams {
            kind: if tracked_off {
                FilterKind::Off
            } else {
                self.filter.kind
            },
            ..self.filter
        }
    }

    /// Takes live tracking's news: the ROI when it changed, the aim samples into the cursor
    /// and the latest aim.
    pub fn apply_live(&mut self, update: crate::session::live::LiveUpdate) {
        if let Some(roi) = update.roi {
            self.tracked = roi;
        }
        for &(t, aim) in &update.aim {
            self.cursor.observe(t, aim);
        }
        if let Some(&(_, aim)) = update.aim.last() {
            self.aim = aim;
        }
    }

    /// Advances the replay clock by `dt` seconds while playing (stops at the end).
    pub fn advance(&mut self, dt: f64, timeline: &Timeline) {
        if self.playing {
            self.replay_t = (self.replay_t + dt).min(timeline.duration);
            if self.replay_t >= timeline.duration {
                self.playing = false;
            }
        }
        self.tracked = timeline.roi_at(self.replay_t).cloned();
        self.aim = timeline.aim_at(self.replay_t);
        self.feed_cursor(timeline);
    }

    /// Feeds the cursor the replay's aim samples up to the replay clock: those since the last
    /// call, or, after a scrub back or a jump ahead, the [`CURSOR_WARM_UP_S`] before the clock
    /// into a fresh filter.
    fn feed_cursor(&mut self, timeline: &Timeline) {
        let t = self.replay_t;
        let from = match self.cursor_fed_t {
            Some(fed) if fed <= t && t - fed <= self.cursor.config.stale_after_s => fed,
            _ => {
                self.cursor.reset();
                t - CURSOR_WARM_UP_S
            }
        };
        for &(ts, aim) in timeline.aim_after(from, t) {
            self.cursor.observe(ts, aim);
        }
        self.cursor_fed_t = Some(t);
    }

    /// The cursor to draw at display time `t` (replay: the replay clock; live: the events'
    /// clock now); `None` before the device was first seen on the wall.
    #[must_use]
    pub fn cursor_mark(&self, t: f64) -> Option<CursorMark> {
        self.cursor.at(t)
    }
}

/// How much of a replay a scrubbed cursor replays to settle its filter, seconds (several time
/// constants of the 1 Hz resting cutoff: 1/(2π·1 Hz) = 0.16 s).
pub const CURSOR_WARM_UP_S: f64 = 1.0;

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
    /// Samples in the ROI (pixels with d = 0) and the mean per ROI pixel.
    pub roi_samples: u64,
    pub roi_pixels: u64,
    /// Median standard error of the mean luminance ([`noise_image`]) over the ROI's noisy
    /// pixels and the periphery's ([`NoiseContrast`]); `None` without an ROI or such pixels.
    pub roi_noise: Option<f32>,
    pub periphery_noise: Option<f32>,
    /// The ROI's progress as `render --until` measures it (median SE over every ROI pixel,
    /// fewest samples), and the seconds the current ROI has been sampled for.
    pub roi_progress: Option<crate::frame::stop::RoiProgress>,
    pub seconds_on_roi: f64,
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
    config: GuideConfigKey,
    max_depth: u32,
}

/// [`GuideConfig`] compared field by field.
#[derive(Clone, Copy, Debug, PartialEq)]
struct GuideConfigKey {
    metric: Metric,
    falloff: Falloff,
    p_min: f32,
    order: Order,
}

impl From<GuideConfig> for GuideConfigKey {
    fn from(c: GuideConfig) -> Self {
        Self {
            metric: c.metric,
            falloff: c.falloff,
            p_min: c.p_min,
            order: c.order,
        }
    }
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

/// The renderer kept in step with a [`ViewerState`].
pub struct ViewerCore<'a> {
    backend: &'a Backend,
    scene: &'a Scene,
    pub model: &'a DisplayModel,
    base: TraceSettings,
    pub state: ViewerState,
    renderer: Renderer<'a>,
    built: Built,
    /// Frames since the renderer was built, and when (for iterations per second).
    window: (u32, Instant),
    /// When the ROI last changed (or the accumulation restarted).
    roi_since: Instant,
    pub stats: Stats,
}

/// Why the viewer's renderer or a saved picture failed.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    #[error(transparent)]
    Schedule(#[from] crate::schedule::ScheduleError),
    #[error(transparent)]
    Falloff(#[from] crate::roi::dgi::FalloffError),
    #[error(transparent)]
    Frame(#[from] crate::frame::FrameError),
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
        let config = state.guide_config()?;
        let settings = TraceSettings {
            max_depth: state.max_depth,
            ..base
        };
        let renderer = Renderer::guided(backend, scene, settings, model, config)?;
        Ok(Self {
            backend,
            scene,
            model,
            base,
            built: Built {
                config: config.into(),
                max_depth: state.max_depth,
            },
            state,
            renderer,
            window: (0, Instant::now()),
            roi_since: Instant::now(),
            stats: Stats::default(),
        })
    }

    #[must_use]
    pub fn size(&self) -> [u32; 2] {
        [self.base.width, self.base.height]
    }

    /// The backend in words.
    #[must_use]
    pub fn backend_name(&self) -> String {
        self.backend.describe()
    }

    /// The renderer as it stands (settings it received, iterations, ROI).
    #[must_use]
    pub fn renderer(&self) -> &Renderer<'a> {
        &self.renderer
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
            config: config.into(),
            max_depth: self.state.max_depth,
        };
        if want != self.built || self.state.reset {
            let settings = TraceSettings {
                max_depth: self.state.max_depth,
                ..self.base
            };
            self.renderer =
                Renderer::guided(self.backend, self.scene, settings, self.model, config)?;
            self.built = want;
            self.state.reset = false;
            self.window = (0, Instant::now());
            self.roi_since = Instant::now();
            self.stats = Stats::default();
        }
        let roi = self.state.roi();
        let changed = self.renderer.roi() != roi.as_ref();
        if changed {
            let t0 = Instant::now();
            self.roi_since = t0;
            self.renderer.set_roi(roi)?;
            // The CPU twin computes the DGI right here; the GPU records it into the next frame
            // (timed by its timestamps).
            if matches!(self.backend, Backend::Cpu) {
                self.stats.ms_dgi = Some(t0.elapsed().as_secs_f64() * 1e3);
            }
        }
        Ok(changed)
    }

    /// Syncs, then runs frames for about `budget` (at least one).
    pub fn step(&mut self, budget: Duration) -> Result<(), ViewerError> {
        let mut roi_changed = self.sync()?;
        let t0 = Instant::now();
        loop {
            let timed = roi_changed || self.renderer.iteration().is_multiple_of(TIMED_EVERY);
            roi_changed = false;
            let s = self.renderer.run_frame(timed)?;
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
        self.stats.iterations = self.renderer.iteration();
        let secs = self.window.1.elapsed().as_secs_f64();
        if secs > 0.0 {
            self.stats.iterations_per_s = f64::from(self.window.0) / secs;
        }
        Ok(())
    }

    /// Reads the accumulation and the DGI back, filters, and composes the picture for the
    /// state's overlay (with the ROI outline and the wall view as asked).
    pub fn picture(&mut self) -> Result<Picture, ViewerError> {
        let acc = self.renderer.accumulation()?;
        let dgi = self.renderer.dgi()?;
        let image = self
            .renderer
            .picture_of(&self.state.filter_params(), &acc, &dgi)?;
        let (roi_samples, roi_pixels) = roi_samples(&acc, &dgi, self.renderer.roi().is_some());
        self.stats.roi_samples = roi_samples;
        self.stats.roi_pixels = roi_pixels;
        let noise = noise_image(&acc);
        let contrast = self.renderer.roi().and_then(|_| {
            let regions = NoiseRegions {
                dgi: &dgi,
                p_min: self.renderer.guide_config().map_or(0.0, |c| c.p_min),
            };
            NoiseContrast::measure(&noise, &regions)
        });
        self.stats.roi_noise = contrast.map(|c| c.roi);
        self.stats.periphery_noise = contrast.map(|c| c.periphery);
        self.stats.roi_progress = self
            .renderer
            .roi()
            .and_then(|_| crate::frame::stop::RoiProgress::measure(&acc, &dgi));
        self.stats.seconds_on_roi = self.roi_since.elapsed().as_secs_f64();
        let size = self.size();
        let mut rgba = match self.state.overlay {
            Overlay::Image => {
                let scale = self.state.exposure.exp2();
                image
                    .iter()
                    .flat_map(|p| {
                        let s = |v: f32| {
                            crate::output::unit_to_u8(crate::output::linear_to_srgb(v * scale))
                        };
                        [s(p.x), s(p.y), s(p.z), 255]
                    })
                    .collect()
            }
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
        if self.state.roi_outline && self.renderer.roi().is_some() {
            for i in roi_outline(&dgi, size) {
                rgba[4 * i..4 * i + 4].copy_from_slice(&OUTLINE);
            }
        }
        if self.state.wall_view {
            let px: Vec<[u8; 4]> = rgba
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect();
            rgba = wall_view(self.model, &px, size, [0, 0, 0, 255]).concat();
        }
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

/// The ROI outline colour (opaque yellow).
pub const OUTLINE: [u8; 4] = [255, 220, 0, 255];

/// Pixels inside the ROI (d = 0) with a 4-neighbour outside it: the ROI's outline on the wall,
/// whatever the ROI's kind.
#[must_use]
pub fn roi_outline(dgi: &[f32], size: [u32; 2]) -> Vec<usize> {
    let (w, h) = (size[0] as usize, size[1] as usize);
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if dgi[i] != 0.0 {
                continue;
            }
            let outside = |j: usize| dgi[j] > 0.0;
            if (x > 0 && outside(i - 1))
                || (x + 1 < w && outside(i + 1))
                || (y > 0 && outside(i - w))
                || (y + 1 < h && outside(i + w))
            {
                out.push(i);
            }
        }
    }
    out
}

/// Samples per pixel as RGBA: black (0) through red and yellow to white (the most).
#[must_use]
pub fn heat_map(counts: &[u32]) -> Vec<u8> {
    let max = counts.iter().copied().max().unwrap_or(0).max(1) as f32;
    counts
        .iter()
        .flat_map(|&c| {
            let t = c as f32 / max * 3.0;
            let ch = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
            [ch(t), ch(t - 1.0), ch(t - 2.0), 255]
        })
        .collect()
}

/// Undefined noise (fewer than two samples) in the noise overlay: dark blue.
pub const NOISE_UNDEFINED: [u8; 4] = [0, 0, 110, 255];

/// The standard error of each pixel's mean luminance, √(s²/n) with the unbiased sample variance
/// s² of the luminances (from the accumulation's Σ luminance², its RGB sum and count; see
/// [`Accumulation::luminance_variance_of_mean`]). Pixels with fewer than two samples have no
/// estimate: NaN there.
#[must_use]
pub fn noise_image(acc: &Accumulation) -> Vec<f32> {
    (0..acc.count.len())
        .map(|i| {
            acc.luminance_variance_of_mean(i)
                .map_or(f32::NAN, f32::sqrt)
        })
        .collect()
}

/// The median of the finite values; `None` when there is none.
#[must_use]
pub fn median_finite(values: impl IntoIterator<Item = f32>) -> Option<f32> {
    let mut v: Vec<f32> = values.into_iter().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    // Selection, not a sort: this runs on every displayed frame over every pixel.
    let n = v.len();
    let (lower, &mut upper, _) = v.select_nth_unstable_by(n / 2, f32::total_cmp);
    Some(if n % 2 == 1 {
        upper
    } else {
        let below = lower.iter().copied().max_by(f32::total_cmp).expect("n ≥ 2");
        0.5 * (below + upper)
    })
}

/// The two regions the noise is compared over: the ROI (d = 0, sampled every iteration) and the
/// periphery (pixels whose sampling probability max(p_min, 1 − d) is the floor p_min, i.e.
/// d ≥ 1 − p_min).
#[derive(Clone, Copy, Debug)]
pub struct NoiseRegions<'a> {
    pub dgi: &'a [f32],
    pub p_min: f32,
}

impl NoiseRegions<'_> {
    /// `values` at the ROI's pixels.
    #[must_use]
    pub fn roi(&self, values: &[f32]) -> Vec<f32> {
        self.select(values, |d| d == 0.0)
    }

    /// `values` at the periphery's pixels (none while p_min = 1: every pixel is the ROI's).
    #[must_use]
    pub fn periphery(&self, values: &[f32]) -> Vec<f32> {
        let floor = 1.0 - self.p_min;
        self.select(values, |d| d > 0.0 && d >= floor)
    }

    fn select(&self, values: &[f32], keep: impl Fn(f32) -> bool) -> Vec<f32> {
        values
            .iter()
            .zip(self.dgi)
            .filter(|(_, d)| keep(**d))
            .map(|(v, _)| *v)
            .collect()
    }
}

/// The ROI's noise against the periphery's: the median standard error of the mean luminance
/// over each region's noisy pixels, and how many there are.
///
/// Absolute SE, not SE relative to the mean: dividing by the mean brings in how bright each
/// region is, which has nothing to do with the sampler. Measured on the Cornell box (124×50, 64
/// iterations, every pixel sampled alike): the ROI/periphery ratio of the absolute SE was
/// 1.02–1.07 over three ROI placements, of the relative SE 0.86–1.44; the absolute ratio
/// isolates the sampler. Pixels whose samples all agree (SE 0: a constant
/// background or an emitter seen directly) have no noise however they are sampled and are left
/// out, as are pixels without an estimate (fewer than two samples).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseContrast {
    pub roi: f32,
    pub periphery: f32,
    pub roi_pixels: usize,
    pub periphery_pixels: usize,
}

impl NoiseContrast {
    /// Measures `noise` (SE of the mean luminance) over `regions`; `None` when a region has no
    /// noisy pixel.
    #[must_use]
    pub fn measure(noise: &[f32], regions: &NoiseRegions<'_>) -> Option<Self> {
        let noisy = |v: Vec<f32>| -> Vec<f32> {
            v.into_iter()
                .filter(|x| x.is_finite() && *x > 0.0)
                .collect()
        };
        let (roi, far) = (noisy(regions.roi(noise)), noisy(regions.periphery(noise)));
        Some(Self {
            roi_pixels: roi.len(),
            periphery_pixels: far.len(),
            roi: median_finite(roi)?,
            periphery: median_finite(far)?,
        })
    }

    /// ROI noise over periphery noise.
    #[must_use]
    pub fn ratio(&self) -> f32 {
        self.roi / self.periphery
    }
}

/// The ratio of standard errors the guide predicts between the ROI (sampled every iteration)
/// and the periphery (sampled with probability p_min): SE ∝ 1/√n and n_roi / n_periphery =
/// 1 / p_min, so √p_min for pixels whose samples spread alike.
#[must_use]
pub fn predicted_noise_ratio(p_min: f32) -> f32 {
    p_min.sqrt()
}

/// The noise overlay: SE as grey scaled by its 99th percentile, undefined pixels
/// [`NOISE_UNDEFINED`].
#[must_use]
pub fn noise_map(noise: &[f32]) -> Vec<u8> {
    let mut finite: Vec<f32> = noise.iter().copied().filter(|v| v.is_finite()).collect();
    let rank = (finite.len().saturating_sub(1) * 99) / 100;
    let top = if finite.is_empty() {
        None
    } else {
        Some(*finite.select_nth_unstable_by(rank, f32::total_cmp).1)
    }
    .filter(|v| *v > 0.0)
    .unwrap_or(1.0);
    noise
        .iter()
        .flat_map(|&v| {
            if v.is_finite() {
                let g = crate::output::unit_to_u8((v / top).clamp(0.0, 1.0));
                [g, g, g, 255]
            } else {
                NOISE_UNDEFINED
            }
        })
        .collect()
}

/// Samples taken in the ROI (pixels with d = 0) and how many pixels it covers; (0, 0) without
/// an ROI.
#[must_use]
pub fn roi_samples(acc: &Accumulation, dgi: &[f32], has_roi: bool) -> (u64, u64) {
    if !has_roi {
        return (0, 0);
    }
    dgi.iter()
        .zip(&acc.count)
        .filter(|(d, _)| **d == 0.0)
        .fold((0, 0), |(s, n), (_, &c)| (s + u64::from(c), n + 1))
}

/// Writes the picture's image (`<stem>.exr` linear, `<stem>.png` as shown with the exposure),
/// the DGI (`<stem>.dgi.png`), the counts (`<stem>.counts.exr`), the noise
/// (`<stem>.noise.exr`: channel `se`, the standard error of the mean luminance, NaN below two
/// samples) and the window's picture with its overlay (`<stem>.view.png`) into `dir`; returns
/// the paths.
pub fn save_picture(
    dir: &Path,
    stem: &str,
    p: &Picture,
    exposure: f32,
) -> Result<Vec<PathBuf>, ViewerError> {
    std::fs::create_dir_all(dir).map_err(|error| ViewerError::CreateDir {
        dir: dir.to_owned(),
        error,
    })?;
    let [w, h] = p.size;
    let mut files = Vec::new();
    for ext in ["exr", "png"] {
        let path = dir.join(format!("{stem}.{ext}"));
        crate::output::write_rgb(&path, w, h, &p.image, exposure)?;
        files.push(path);
    }
    let dgi = dir.join(format!("{stem}.dgi.png"));
    crate::output::write_gray(&dgi, w, h, &p.dgi, "d")?;
    let counts = dir.join(format!("{stem}.counts.exr"));
    let c: Vec<f32> = p.counts.iter().map(|&c| c as f32).collect();
    crate::output::write_gray(&counts, w, h, &c, "samples")?;
    let noise = dir.join(format!("{stem}.noise.exr"));
    crate::output::write_gray(&noise, w, h, &p.noise, "se")?;
    let view = dir.join(format!("{stem}.view.png"));
    save_view_png(&view, p)?;
    files.extend([dgi, counts, noise, view]);
    Ok(files)
}

/// Writes the picture as shown (RGBA8 PNG).
pub fn save_view_png(path: &Path, p: &Picture) -> Result<(), ViewerError> {
    let [w, h] = p.size;
    let img = image::RgbaImage::from_raw(w, h, p.rgba.clone()).ok_or(ViewerError::PictureSize)?;
    crate::output::replace_with(path, |tmp| {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|error| ViewerError::Png {
                path: path.to_owned(),
                error,
            })
    })
}
