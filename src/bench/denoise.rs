//! `raygun bench denoise`: the denoisers measured against a reference (DESIGN.md §8).
//!
//! A guided render of one scene in the paper's setup (viewer 1 m in front of the wall centre,
//! square cones, p_min 0; [`super::paper`]) at each ROI field of view, looked at after each of a
//! list of iteration counts, and a full-frame reference of the same scene and view. Each picture
//! is made four ways ([`METHODS`]):
//!
//! * `off`: the accumulation's per-pixel mean, unsampled pixels black;
//! * `filter`: the paper's filter ([`crate::filter::Filter`], [`FilterParams::default`]), as
//!   `render` shows it;
//! * `interactive`: raygun's à-trous denoiser ([`crate::filter::denoise`], default settings)
//!   with the view's features ([`crate::trace::features::features_cpu`]): the GPU kernels on a
//!   GPU backend, the CPU twin otherwise (timed on both where there is a GPU);
//! * `oidn`: Intel Open Image Denoise's `RT` filter at quality `high` on the colour `render`
//!   gives it ([`oidn::colour_input`]: each pixel's own mean, the filter's picture where it has
//!   none) plus the features' albedo and normal. Its time includes the filter's, which makes
//!   its colour input. Without the library the report says why and has the other methods.
//!
//! **Errors**, per picture, inside the ROI (pixels whose DGI distance is 0, as `bench guided`
//! separates them) and outside it (the periphery):
//!
//! * relative MSE ([`rel_mse`]): the mean over the region's pixels and the three channels of
//!   (x − r)² / (r² + 0.01), linear RGB;
//! * ꟻLIP (Andersson et al. 2020, LDR; [`flip_map`]): NVIDIA's reference implementation (the
//!   `nv-flip` crate builds its C++) on both pictures as `--output x.png` shows them (8-bit
//!   sRGB at exposure 0), at its default 67 pixels per degree; the mean of its per-pixel
//!   error over the region, in [0, 1].
//!
//! **Equal iterations**: every method on the same accumulation. **Equal time**: a budget is
//! the render's time up to one of the listed iteration counts; each method gets the largest
//! listed count whose render time plus its own time (the features' too, for the two methods
//! that read them) fits the budget ([`EqualTimeRow`]).
//!
//! **Timings**: ms per picture of `interactive` (CPU twin; the kernels on a GPU backend) and
//! `oidn` on the synthetic scene ([`crate::filter::denoise::synth_scene`], one round at p = ½)
//! at the bench size and each `--timing-sizes` size; the median of the runs, after one warm-up
//! run at the first size (threads, pipelines and OIDN's weights are warm for the others). OIDN
//! builds its filter for every picture, as `render` calls it.

use std::path::Path;
use std::time::Instant;

use glam::Vec3;
use serde::Serialize;

use super::{median, paper};
use crate::display::DisplayModel;
use crate::filter::denoise::gpu::{DenoiseGpuError, DenoiseKernels, UploadedDenoiseInputs};
use crate::filter::denoise::{self, DenoiseInput, DenoiseInputError, DenoiseParams, Features};
use crate::filter::{Filter, FilterParams, gpu::FilterGpuError, oidn};
use crate::frame::{FrameError, GuideConfig, Render};
use crate::gpu::{Backend, GpuContext, GpuError, PassTimer};
use crate::roi::cone::ConeError;
use crate::scene::Scene;
use crate::trace::accum::Accumulation;
use crate::trace::camera::CameraError;
use crate::trace::path::TraceSettings;

/// The methods, in the order of every table.
pub const METHODS: [&str; 4] = ["off", "filter", "interactive", "oidn"];
/// The regions of every error row.
pub const REGIONS: [&str; 2] = ["roi", "periphery"];
/// The most iterations a picture may be looked at after.
pub const MAX_ITERATIONS: u32 = 256;
/// The most samples per pixel of the reference.
pub const MAX_REFERENCE_SPP: u32 = 16_384;
/// The most pixels of the rendered pictures (`--size`) and of a timed one (`--timing-sizes`):
/// 3840 × 2160.
pub const MAX_PIXELS: u64 = 3840 * 2160;
/// The fewest pixels along either side of the rendered pictures (the crops need room).
pub const MIN_SIDE: u32 = 16;
/// The most timed runs per size.
pub const MAX_TIMING_RUNS: u32 = 20;
/// The offset of relative MSE's denominator: (x − r)² / (r² + this).
pub const REL_MSE_EPSILON: f64 = 1e-2;
/// The crops' largest side (pixels of the picture), their shown size at least, the gap between
/// them and the height of the label row (pixels of the PNG).
pub const CROP_SIDE: u32 = 64;
pub const CROP_SHOWN: u32 = 128;
pub const CROP_GAP: u32 = 4;
pub const CROP_LABEL: u32 = 22;

/// What to measure.
#[derive(Clone, Debug, Serialize)]
pub struct DenoiseBenchConfig {
    pub scene: String,
    pub size: [u32; 2],
    pub fovs_deg: Vec<f64>,
    /// Iteration counts the pictures are made after, ascending.
    pub iterations: Vec<u32>,
    pub reference_spp: u32,
    /// Sizes of the synthetic timings beside the bench size.
    pub timing_sizes: Vec<[u32; 2]>,
    pub timing_runs: u32,
    /// The iteration count of the crops (one of `iterations`); the first FOV's pictures.
    pub crops_iterations: u32,
    pub seed: u32,
    pub max_depth: u32,
}

impl Default for DenoiseBenchConfig {
    fn default() -> Self {
        Self {
            scene: "builtin:cornell".into(),
            size: [320, 180],
            fovs_deg: vec![10.0, 60.0],
            iterations: vec![1, 4, 16, 64],
            reference_spp: 1024,
            timing_sizes: vec![[1920, 1080], [3840, 2160]],
            timing_runs: 1,
            crops_iterations: 4,
            seed: 1,
            max_depth: crate::trace::path::DEFAULT_MAX_DEPTH,
        }
    }
}

impl DenoiseBenchConfig {
    /// Checks every setting; the error names the flag.
    pub fn validate(&self) -> Result<(), DenoiseBenchError> {
        let flag = |flag: &'static str, value: String, reason: &str| {
            Err(DenoiseBenchError::Flag {
                flag,
                value,
                reason: reason.to_owned(),
            })
        };
        let sized = |[w, h]: [u32; 2], min: u32| {
            w >= min && h >= min && u64::from(w) * u64::from(h) <= MAX_PIXELS
        };
        let [w, h] = self.size;
        if !sized(self.size, MIN_SIDE) {
            return flag(
                "--size",
                format!("{w},{h}"),
                "expected at least 16 pixels a side and at most 3840 × 2160 pixels",
            );
        }
        if self.fovs_deg.is_empty() {
            return flag(
                "--fov",
                String::new(),
                "expected at least one field of view",
            );
        }
        if let Some(f) = self
            .fovs_deg
            .iter()
            .find(|f| !(f.is_finite() && **f > 0.0 && **f <= 120.0))
        {
            return flag(
                "--fov",
                f.to_string(),
                "expected degrees above 0, at most 120",
            );
        }
        if self.iterations.is_empty() {
            return flag("--iterations", String::new(), "expected at least one count");
        }
        if let Some(n) = self
            .iterations
            .iter()
            .find(|&&n| n == 0 || n > MAX_ITERATIONS)
        {
            return flag("--iterations", n.to_string(), "expected 1 to 256");
        }
        if !self.iterations.windows(2).all(|p| p[0] < p[1]) {
            return flag(
                "--iterations",
                format!("{:?}", self.iterations),
                "expected counts in ascending order, each once",
            );
        }
        if self.reference_spp == 0 || self.reference_spp > MAX_REFERENCE_SPP {
            return flag(
                "--reference-spp",
                self.reference_spp.to_string(),
                "expected 1 to 16384",
            );
        }
        if let Some([tw, th]) = self.timing_sizes.iter().find(|s| !sized(**s, 1)) {
            return flag(
                "--timing-sizes",
                format!("{tw}x{th}"),
                "expected at most 3840 × 2160 pixels",
            );
        }
        if self.timing_runs == 0 || self.timing_runs > MAX_TIMING_RUNS {
            return flag(
                "--timing-runs",
                self.timing_runs.to_string(),
                "expected 1 to 20",
            );
        }
        if !self.iterations.contains(&self.crops_iterations) {
            return flag(
                "--crops-iterations",
                self.crops_iterations.to_string(),
                "expected one of --iterations",
            );
        }
        Ok(())
    }
}

/// One method's error in one region of one picture.
#[derive(Clone, Debug, Serialize)]
pub struct ErrorRow {
    pub fov_deg: f64,
    pub iterations: u32,
    pub method: &'static str,
    pub region: &'static str,
    pub pixels: usize,
    pub rel_mse: f64,
    pub flip: f64,
}

/// One method's time for one picture.
#[derive(Clone, Debug, Serialize)]
pub struct TimeRow {
    pub fov_deg: f64,
    pub iterations: u32,
    pub method: &'static str,
    /// The guided render's time up to this picture (ms): DGI, scheduling and tracing.
    pub render_ms: f64,
    /// The method's own time (ms): 0 for `off`; the filter's; the denoiser's (its kernels on a
    /// GPU backend); OIDN's plus the filter's that makes its colour input.
    pub ms: f64,
    /// `interactive` on a GPU backend: its CPU twin's time on the same picture.
    pub ms_cpu_twin: Option<f64>,
}

/// A method's error at equal time: within `budget_ms` (the render's time up to
/// `budget_iterations`), the largest listed iteration count whose render time plus the
/// method's own time (and the features' where it reads them) fits.
#[derive(Clone, Debug, Serialize)]
pub struct EqualTimeRow {
    pub fov_deg: f64,
    pub budget_iterations: u32,
    pub budget_ms: f64,
    pub method: &'static str,
    /// `None`: not even the first listed count fits.
    pub iterations: Option<u32>,
    pub cost_ms: Option<f64>,
    pub rel_mse_roi: Option<f64>,
    pub rel_mse_periphery: Option<f64>,
    pub flip_roi: Option<f64>,
    pub flip_periphery: Option<f64>,
}

/// ms per picture on the synthetic scene at one size.
#[derive(Clone, Debug, Serialize)]
pub struct SizeTiming {
    pub width: u32,
    pub height: u32,
    pub interactive_cpu_ms: f64,
    pub interactive_gpu_ms: Option<f64>,
    pub gpu_timestamps: bool,
    pub oidn_ms: Option<f64>,
    /// The CPU twin's time over OIDN's.
    pub interactive_cpu_over_oidn: Option<f64>,
    /// The kernels' time over OIDN's.
    pub interactive_gpu_over_oidn: Option<f64>,
}

/// The targets (DESIGN.md §8), as measured: the worst ratio over every FOV, iteration count
/// and timed size, and whether it meets the target.
#[derive(Clone, Debug, Serialize)]
pub struct Targets {
    /// Periphery relMSE of `interactive` over `off`'s (target ≤ 0.5).
    pub periphery_interactive_over_off: f64,
    pub periphery_interactive_over_off_met: bool,
    /// Periphery relMSE of `interactive` over `oidn`'s (target ≤ 1.5; `None` without OIDN).
    pub periphery_interactive_over_oidn: Option<f64>,
    pub periphery_interactive_over_oidn_met: Option<bool>,
    /// The CPU twin's time over OIDN's on the CPU (target ≤ 0.1).
    pub time_interactive_cpu_over_oidn: Option<f64>,
    pub time_interactive_cpu_over_oidn_met: Option<bool>,
    /// ROI relMSE of `interactive` over `off`'s (target ≤ 1: never worse).
    pub roi_interactive_over_off: f64,
    pub roi_interactive_over_off_met: bool,
}

/// Where the crops went.
#[derive(Clone, Debug, Serialize)]
pub struct CropsInfo {
    pub path: String,
    pub width: u32,
    pub height: u32,
    /// The crops' side in the picture's pixels, and how many PNG pixels show one.
    pub side: u32,
    pub scale: u32,
    pub fov_deg: f64,
    pub iterations: u32,
    /// Top-left corners of the two crops in the picture: the ROI's edge (first row) and the
    /// periphery (second row).
    pub roi_edge_at: [u32; 2],
    pub periphery_at: [u32; 2],
    /// The columns, left to right.
    pub columns: Vec<String>,
}

/// Everything measured.
#[derive(Clone, Debug, Serialize)]
pub struct DenoiseBenchReport {
    pub device: String,
    /// "Intel Open Image Denoise 2.5.1 on its CPU device", or why it is missing.
    pub oidn: String,
    pub oidn_loaded: bool,
    pub config: DenoiseBenchConfig,
    /// The features' time (once per view, ms; the CPU twin).
    pub features_ms: f64,
    pub reference_ms: f64,
    pub errors: Vec<ErrorRow>,
    pub times: Vec<TimeRow>,
    pub equal_time: Vec<EqualTimeRow>,
    pub timings: Vec<SizeTiming>,
    pub targets: Targets,
    pub crops: Option<CropsInfo>,
}

#[derive(Debug, thiserror::Error)]
pub enum DenoiseBenchError {
    #[error("{flag} {value}: {reason}")]
    Flag {
        flag: &'static str,
        value: String,
        reason: String,
    },
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error(transparent)]
    Cone(#[from] ConeError),
    #[error("scene '{scene}': {source}")]
    Camera {
        scene: String,
        #[source]
        source: CameraError,
    },
    #[error(transparent)]
    Input(#[from] DenoiseInputError),
    #[error(transparent)]
    DenoiseGpu(#[from] DenoiseGpuError),
    #[error(transparent)]
    Filter(#[from] FilterGpuError),
    #[error(transparent)]
    Oidn(#[from] oidn::OidnError),
    #[error("--crops {path}: {reason}")]
    Crops { path: String, reason: String },
    #[error(transparent)]
    File(#[from] crate::output::FileError),
}

/// Relative MSE of `image` against `reference` over the pixels where `mask` holds: the mean
/// over those pixels and the three channels of (x − r)² / (r² + [`REL_MSE_EPSILON`]), in f64.
/// NaN over no pixels.
#[must_use]
pub fn rel_mse(image: &[Vec3], reference: &[Vec3], mask: &[bool]) -> f64 {
    let (mut sum, mut n) = (0f64, 0usize);
    for ((x, r), _) in image.iter().zip(reference).zip(mask).filter(|(_, m)| **m) {
        for c in 0..3 {
            let (x, r) = (f64::from(x[c]), f64::from(r[c]));
            sum += (x - r) * (x - r) / (r * r + REL_MSE_EPSILON);
        }
        n += 3;
    }
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// ꟻLIP's per-pixel error (LDR, NVIDIA's implementation at its default 67.0 pixels per
/// degree) between two 8-bit sRGB pictures (`width × height`, RGB, row-major): each in [0, 1].
#[must_use]
pub fn flip_map(reference: &[u8], test: &[u8], width: u32, height: u32) -> Vec<f32> {
    let r = nv_flip::FlipImageRgb8::with_data(width, height, reference);
    let t = nv_flip::FlipImageRgb8::with_data(width, height, test);
    nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE).to_vec()
}

/// The mean of `values` where `mask` holds (NaN over no pixels).
#[must_use]
pub fn masked_mean(values: &[f32], mask: &[bool]) -> f64 {
    let (mut s, mut n) = (0f64, 0usize);
    for (v, _) in values.iter().zip(mask).filter(|(_, m)| **m) {
        s += f64::from(*v);
        n += 1;
    }
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// The frames [`run`] renders: the reference and each FOV's iterations.
#[must_use]
pub fn planned_frames(cfg: &DenoiseBenchConfig) -> u64 {
    u64::from(cfg.reference_spp)
        + cfg.fovs_deg.len() as u64 * u64::from(cfg.iterations.last().copied().unwrap_or(0))
}

/// OIDN's albedo and normal inputs from the features: three floats a pixel each.
fn oidn_features(f: &Features) -> (Vec<f32>, Vec<f32>) {
    let three = |v: &[[f32; 4]]| v.iter().flat_map(|p| [p[0], p[1], p[2]]).collect();
    (three(&f.albedo), three(&f.normal_depth))
}

/// The denoiser's kernels on one picture: the picture and the kernels' time (timestamps where
/// the adapter has them, else the wall clock around submit-and-wait; a picture larger than one
/// binding is denoised in bands, timed by the wall clock around them all).
fn interactive_gpu(
    ctx: &GpuContext,
    kernels: &DenoiseKernels,
    params: &DenoiseParams,
    input: &DenoiseInput<'_>,
) -> Result<(Vec<Vec3>, f64), DenoiseBenchError> {
    let to_rgb = |image: &[[f32; 4]]| image.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
    if !denoise::gpu::fits_one_binding(ctx, [input.width, input.height]) {
        let t = Instant::now();
        let d = kernels.denoise_banded(ctx, params, input)?;
        return Ok((to_rgb(&d.image), t.elapsed().as_secs_f64() * 1e3));
    }
    let uploaded = UploadedDenoiseInputs::new(ctx, input)?;
    let run = kernels.prepare(ctx, params, &uploaded.inputs(), [0, input.height])?;
    let timer = PassTimer::new(ctx, 1);
    let t = Instant::now();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    run.record(&mut enc, timer.as_ref().map(|t| (t, 0)));
    if let Some(timer) = &timer {
        timer.resolve(&mut enc);
    }
    ctx.queue.submit([enc.finish()]);
    ctx.wait()?;
    let wall = t.elapsed().as_secs_f64() * 1e3;
    let ms = match &timer {
        Some(timer) => timer.read_ms(ctx)?[0],
        None => wall,
    };
    let out = run.read(ctx)?;
    Ok((to_rgb(&out.image), ms))
}

/// One listed iteration count of one FOV: the count, the render's time to it, each method's
/// [relMSE ROI, periphery, ꟻLIP ROI, periphery] (`None` for a method not run) and time.
type Measured = (u32, f64, [Option<[f64; 4]>; 4], [f64; 4]);

/// The four pictures of one accumulation, and each method's time.
struct Pictures {
    images: Vec<Option<Vec<Vec3>>>,
    ms: [f64; 4],
    ms_cpu_twin: Option<f64>,
}

struct Methods<'a> {
    backend: &'a Backend,
    filter: Filter<'a>,
    kernels: Option<DenoiseKernels>,
    oidn: Option<oidn::Device>,
    features: Features,
    albedo3: Vec<f32>,
    normal3: Vec<f32>,
}

impl Methods<'_> {
    fn pictures(&self, acc: &Accumulation, dgi: &[f32]) -> Result<Pictures, DenoiseBenchError> {
        let off = acc.mean_image();
        let (filtered, filter_ms, _) =
            self.filter
                .timed_image(&FilterParams::default(), acc, dgi)?;
        let params = DenoiseParams::default();
        let input = DenoiseInput::new(acc, &self.features)?;
        let t = Instant::now();
        let cpu = denoise::denoise_cpu(&params, &input)?;
        let cpu_ms = t.elapsed().as_secs_f64() * 1e3;
        let (interactive, interactive_ms, twin) = match (self.backend, &self.kernels) {
            (Backend::Gpu(ctx), Some(k)) => {
                let (image, ms) = interactive_gpu(ctx, k, &params, &input)?;
                (image, ms, Some(cpu_ms))
            }
            _ => (
                cpu.image
                    .iter()
                    .map(|p| Vec3::new(p[0], p[1], p[2]))
                    .collect(),
                cpu_ms,
                None,
            ),
        };
        let (oidn_image, oidn_ms) = match &self.oidn {
            Some(device) => {
                let (colour, _) = oidn::colour_input(acc, &filtered);
                let t = Instant::now();
                let out = device.denoise(
                    oidn::Images {
                        size: [acc.width, acc.height],
                        color: &colour,
                        albedo: Some(&self.albedo3),
                        normal: Some(&self.normal3),
                    },
                    oidn::Quality::High,
                )?;
                let ms = t.elapsed().as_secs_f64() * 1e3 + filter_ms;
                let image = out
                    .chunks_exact(3)
                    .map(|c| Vec3::new(c[0], c[1], c[2]))
                    .collect();
                (Some(image), ms)
            }
            None => (None, f64::NAN),
        };
        Ok(Pictures {
            images: vec![Some(off), Some(filtered), Some(interactive), oidn_image],
            ms: [0.0, filter_ms, interactive_ms, oidn_ms],
            ms_cpu_twin: twin,
        })
    }
}

/// Opens OIDN as `render --denoise oidn` does: the library and its device (the CUDA device
/// beside an NVIDIA adapter, else the CPU's); `Err` says why not.
pub fn open_oidn(backend: &Backend) -> Result<oidn::Device, oidn::OidnError> {
    oidn::Oidn::load()?.device(oidn::DeviceChoice::Auto {
        nvidia: backend.is_nvidia(),
    })
}

/// Runs the benchmark on `scene` (named `cfg.scene`); `progress` hears the step and the frames
/// rendered since it last heard ([`planned_frames`] in all). `oidn` is the device or why there
/// is none. The crops go to `crops` when given.
pub fn run(
    backend: &Backend,
    display: &DisplayModel,
    scene: &Scene,
    cfg: &DenoiseBenchConfig,
    oidn: Result<oidn::Device, oidn::OidnError>,
    crops: Option<&Path>,
    mut progress: impl FnMut(&str, u32),
) -> Result<DenoiseBenchReport, DenoiseBenchError> {
    cfg.validate()?;
    let [w, h] = cfg.size;
    let name = cfg.scene.as_str();
    let base = paper::settings(scene, cfg.size, cfg.seed, cfg.max_depth).map_err(|source| {
        DenoiseBenchError::Camera {
            scene: name.to_owned(),
            source,
        }
    })?;
    let settings = |seed: u32| TraceSettings { seed, ..base };
    let (oidn_text, mut oidn_device) = match oidn {
        Ok(d) => (d.describe(), Some(d)),
        Err(e) => (format!("not used: {e}"), None),
    };
    let step = format!("{name}: reference ({} spp)", cfg.reference_spp);
    progress(&step, 0);
    let t = Instant::now();
    let reference = paper::reference_image_wall(
        backend,
        scene,
        settings(cfg.seed ^ 0x5eed),
        cfg.reference_spp,
        None,
        &mut |n| progress(&step, n),
    )?;
    let reference_ms = t.elapsed().as_secs_f64() * 1e3;
    let reference8 = crate::output::srgb8::display_rgb(&reference, 0.0);
    let mut methods: Option<Methods> = None;
    let mut features_ms = 0.0;
    let (mut errors, mut times, mut equal_time) = (Vec::new(), Vec::new(), Vec::new());
    let mut crop_set = None;
    for &fov in &cfg.fovs_deg {
        let step = format!("{name}: {fov}°");
        progress(&step, 0);
        let mut g = paper::guided(
            backend,
            scene,
            settings(cfg.seed.wrapping_add(1)),
            display,
            GuideConfig::default(),
            paper::roi(fov)?,
        )?;
        if methods.is_none() {
            // One view: the same features serve every FOV.
            let t = Instant::now();
            let f = crate::trace::features::features_cpu(&g.packed, &g.settings);
            features_ms = t.elapsed().as_secs_f64() * 1e3;
            let features = Features {
                width: w,
                height: h,
                albedo: f.albedo,
                normal_depth: f.normal_depth,
            };
            let (albedo3, normal3) = oidn_features(&features);
            methods = Some(Methods {
                backend,
                filter: Filter::new(backend),
                kernels: match backend {
                    Backend::Gpu(ctx) => Some(DenoiseKernels::new(ctx)),
                    Backend::Cpu => None,
                },
                oidn: oidn_device.take(),
                features,
                albedo3,
                normal3,
            });
        }
        let m = methods.as_ref().expect("made above");
        let (mut done, mut render_ms) = (0u32, 0f64);
        // Per listed count: [relMSE roi, periphery, FLIP roi, periphery] per method, and times.
        let mut measured: Vec<Measured> = Vec::new();
        for &n in &cfg.iterations {
            while done < n {
                let t = Instant::now();
                let s = g.run_frame(true)?;
                let wall = t.elapsed().as_secs_f64() * 1e3;
                render_ms += match s.ms_trace {
                    Some(trace) => {
                        trace
                            + s.ms_schedule.unwrap_or(0.0)
                            + if s.dgi_recomputed {
                                s.ms_dgi.unwrap_or(0.0)
                            } else {
                                0.0
                            }
                    }
                    None => wall,
                };
                done += 1;
                progress(&step, 1);
            }
            let acc = g.accumulation()?;
            let dgi = g.dgi()?;
            let roi: Vec<bool> = dgi.iter().map(|&d| d == 0.0).collect();
            let periphery: Vec<bool> = roi.iter().map(|r| !r).collect();
            let pictures = m.pictures(&acc, &dgi)?;
            let mut figures = [None; 4];
            for (k, method) in METHODS.into_iter().enumerate() {
                times.push(TimeRow {
                    fov_deg: fov,
                    iterations: n,
                    method,
                    render_ms,
                    ms: pictures.ms[k],
                    ms_cpu_twin: if k == 2 { pictures.ms_cpu_twin } else { None },
                });
                let Some(image) = &pictures.images[k] else {
                    continue;
                };
                let flip = flip_map(
                    &reference8,
                    &crate::output::srgb8::display_rgb(image, 0.0),
                    w,
                    h,
                );
                let mut f = [0.0; 4];
                for (r, (region, mask)) in REGIONS.into_iter().zip([&roi, &periphery]).enumerate() {
                    let row = ErrorRow {
                        fov_deg: fov,
                        iterations: n,
                        method,
                        region,
                        pixels: mask.iter().filter(|&&v| v).count(),
                        rel_mse: rel_mse(image, &reference, mask),
                        flip: masked_mean(&flip, mask),
                    };
                    (f[r], f[2 + r]) = (row.rel_mse, row.flip);
                    errors.push(row);
                }
                figures[k] = Some(f);
            }
            measured.push((n, render_ms, figures, pictures.ms));
            if crops.is_some() && crop_set.is_none() && n == cfg.crops_iterations {
                crop_set = Some((fov, n, pictures.images, dgi));
            }
        }
        drop(g);
        for &(budget_n, budget, _, _) in &measured {
            for (k, method) in METHODS.into_iter().enumerate() {
                let extra = if k >= 2 { features_ms } else { 0.0 };
                let fit = measured
                    .iter()
                    .rfind(|(_, r, f, ms)| f[k].is_some() && r + ms[k] + extra <= budget);
                let f = fit.and_then(|(_, _, f, _)| f[k]);
                equal_time.push(EqualTimeRow {
                    fov_deg: fov,
                    budget_iterations: budget_n,
                    budget_ms: budget,
                    method,
                    iterations: fit.map(|x| x.0),
                    cost_ms: fit.map(|(_, r, _, ms)| r + ms[k] + extra),
                    rel_mse_roi: f.map(|f| f[0]),
                    rel_mse_periphery: f.map(|f| f[1]),
                    flip_roi: f.map(|f| f[2]),
                    flip_periphery: f.map(|f| f[3]),
                });
            }
        }
    }
    let m = methods.expect("at least one FOV (validated)");
    let mut timings = Vec::new();
    let mut sizes = vec![cfg.size];
    sizes.extend(cfg.timing_sizes.iter().copied());
    for (i, &[tw, th]) in sizes.iter().enumerate() {
        let step = format!("timing {tw}×{th}");
        progress(&step, 0);
        let t = time_interactive(backend, m.kernels.as_ref(), tw, th, cfg.timing_runs, i == 0)?;
        let oidn_ms = match &m.oidn {
            Some(device) => Some(time_oidn(device, tw, th, cfg.timing_runs, i == 0)?),
            None => None,
        };
        timings.push(SizeTiming {
            width: tw,
            height: th,
            interactive_cpu_ms: t.cpu_ms,
            interactive_gpu_ms: t.gpu_ms,
            gpu_timestamps: t.gpu_timestamps,
            oidn_ms,
            interactive_cpu_over_oidn: oidn_ms.map(|o| t.cpu_ms / o),
            interactive_gpu_over_oidn: oidn_ms.zip(t.gpu_ms).map(|(o, g)| g / o),
        });
    }
    let targets = targets(&errors, &timings);
    let crops = match (crops, crop_set) {
        (Some(path), Some((fov, n, images, dgi))) => Some(write_crops(
            path,
            cfg.size,
            &reference,
            &images,
            &dgi,
            (fov, n),
        )?),
        _ => None,
    };
    Ok(DenoiseBenchReport {
        device: super::device(backend),
        oidn_loaded: m.oidn.is_some(),
        oidn: oidn_text,
        config: cfg.clone(),
        features_ms,
        reference_ms,
        errors,
        times,
        equal_time,
        timings,
        targets,
        crops,
    })
}

/// What [`time_interactive`] measured.
struct InteractiveTiming {
    cpu_ms: f64,
    gpu_ms: Option<f64>,
    gpu_timestamps: bool,
}

/// The denoiser's ms per picture on the synthetic scene at `width × height`: the CPU twin's
/// wall clock and, on a GPU backend, the kernels' time ([`interactive_gpu`]); medians of `runs`
/// after a warm-up run of each when `warm_up` (the first size: later ones find the threads and
/// pipelines warm).
fn time_interactive(
    backend: &Backend,
    kernels: Option<&DenoiseKernels>,
    width: u32,
    height: u32,
    runs: u32,
    warm_up: bool,
) -> Result<InteractiveTiming, DenoiseBenchError> {
    let s = denoise::synth_scene(width, height, 1, 0.5, 1);
    let input = DenoiseInput::new(&s.acc, &s.features)?;
    let params = DenoiseParams::default();
    let skip = u32::from(warm_up);
    let mut cpu = Vec::new();
    for r in 0..runs + skip {
        let t = Instant::now();
        std::hint::black_box(denoise::denoise_cpu(&params, &input)?);
        if r >= skip {
            cpu.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let (mut gpu_ms, mut gpu_timestamps) = (None, false);
    if let (Backend::Gpu(ctx), Some(k)) = (backend, kernels) {
        let mut gpu = Vec::new();
        for r in 0..runs + skip {
            let (_, ms) = interactive_gpu(ctx, k, &params, &input)?;
            if r >= skip {
                gpu.push(ms);
            }
        }
        gpu_ms = Some(median(gpu));
        gpu_timestamps = ctx.timestamps && denoise::gpu::fits_one_binding(ctx, [width, height]);
    }
    Ok(InteractiveTiming {
        cpu_ms: median(cpu),
        gpu_ms,
        gpu_timestamps,
    })
}

/// OIDN's ms per picture on the synthetic scene at `width × height` (colour: each pixel's
/// mean, black where unsampled; the scene's albedo and normal), median of `runs` after a
/// warm-up run when `warm_up`.
fn time_oidn(
    device: &oidn::Device,
    width: u32,
    height: u32,
    runs: u32,
    warm_up: bool,
) -> Result<f64, DenoiseBenchError> {
    let s = denoise::synth_scene(width, height, 1, 0.5, 1);
    let (colour, _) = oidn::colour_input(&s.acc, &s.acc.mean_image());
    let (albedo, normal) = oidn_features(&s.features);
    let images = oidn::Images {
        size: [width, height],
        color: &colour,
        albedo: Some(&albedo),
        normal: Some(&normal),
    };
    let mut ms = Vec::new();
    for r in 0..runs + u32::from(warm_up) {
        let t = Instant::now();
        std::hint::black_box(device.denoise(images, oidn::Quality::High)?);
        if r >= u32::from(warm_up) {
            ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    Ok(median(ms))
}

fn figure(errors: &[ErrorRow], fov: f64, n: u32, method: &str, region: &str) -> Option<f64> {
    errors
        .iter()
        .find(|e| e.fov_deg == fov && e.iterations == n && e.method == method && e.region == region)
        .map(|e| e.rel_mse)
}

/// The worst ratios over the measured pictures and sizes (NaN-free: a region without pixels
/// is left out).
fn targets(errors: &[ErrorRow], timings: &[SizeTiming]) -> Targets {
    let (mut vs_off, mut vs_oidn, mut roi) = (0f64, None::<f64>, 0f64);
    for e in errors.iter().filter(|e| e.method == "interactive") {
        let (fov, n) = (e.fov_deg, e.iterations);
        let ratio = |other: &str| {
            figure(errors, fov, n, other, e.region)
                .map(|o| e.rel_mse / o)
                .filter(|r| r.is_finite())
        };
        match e.region {
            "periphery" => {
                if let Some(r) = ratio("off") {
                    vs_off = vs_off.max(r);
                }
                if let Some(r) = ratio("oidn") {
                    vs_oidn = Some(vs_oidn.map_or(r, |v| v.max(r)));
                }
            }
            _ => {
                if let Some(r) = ratio("off") {
                    roi = roi.max(r);
                }
            }
        }
    }
    let time = timings
        .iter()
        .filter_map(|t| t.interactive_cpu_over_oidn)
        .reduce(f64::max);
    Targets {
        periphery_interactive_over_off: vs_off,
        periphery_interactive_over_off_met: vs_off <= 0.5,
        periphery_interactive_over_oidn: vs_oidn,
        periphery_interactive_over_oidn_met: vs_oidn.map(|v| v <= 1.5),
        time_interactive_cpu_over_oidn: time,
        time_interactive_cpu_over_oidn_met: time.map(|v| v <= 0.1),
        roi_interactive_over_off: roi,
        roi_interactive_over_off_met: roi <= 1.0,
    }
}

/// The crops' side (picture pixels) and scale (PNG pixels a picture pixel) for `size`.
#[must_use]
pub fn crop_geometry([w, h]: [u32; 2]) -> (u32, u32) {
    let side = CROP_SIDE.min(w / 3).min(h / 2).max(1);
    (side, CROP_SHOWN.div_ceil(side).max(1))
}

/// The PNG's size for `size`: five columns and two rows of crops, a label row on top.
#[must_use]
pub fn crops_png_size(size: [u32; 2]) -> [u32; 2] {
    let (side, scale) = crop_geometry(size);
    let cell = side * scale;
    [
        5 * cell + 6 * CROP_GAP,
        CROP_LABEL + 2 * cell + 3 * CROP_GAP,
    ]
}

/// Top-left corners of the ROI-edge crop (centred on the ROI outline's leftmost pixel nearest
/// the middle row; the picture's centre without an outline) and the periphery crop (of the
/// picture's four corners and the middles of its left and right sides, the window farthest
/// from the ROI by mean DGI).
fn crop_corners(dgi: &[f32], [w, h]: [u32; 2], side: u32) -> ([u32; 2], [u32; 2]) {
    let clamp = |c: [i64; 2]| {
        [
            (c[0] - i64::from(side / 2)).clamp(0, i64::from(w - side)) as u32,
            (c[1] - i64::from(side / 2)).clamp(0, i64::from(h - side)) as u32,
        ]
    };
    let outline = crate::output::srgb8::roi_outline(dgi, [w, h]);
    let edge = outline
        .iter()
        .map(|&p| (p as u32 % w, p as u32 / w))
        .min_by_key(|&(x, y)| (x, y.abs_diff(h / 2)))
        .map_or([i64::from(w / 2), i64::from(h / 2)], |(x, y)| {
            [i64::from(x), i64::from(y)]
        });
    let window_dgi = |[x0, y0]: [u32; 2]| {
        let mut s = 0f64;
        for y in y0..y0 + side {
            for x in x0..x0 + side {
                s += f64::from(dgi[(y * w + x) as usize]);
            }
        }
        s
    };
    let (r, b) = (w - side, h - side);
    let periphery = [[0, 0], [r, 0], [0, b], [r, b], [0, b / 2], [r, b / 2]]
        .into_iter()
        .max_by(|a, c| window_dgi(*a).total_cmp(&window_dgi(*c)))
        .expect("six candidates");
    (clamp(edge), periphery)
}

/// Writes the crops PNG: columns reference, off, filter, interactive, oidn (grey where OIDN
/// was not loaded), rows the ROI's edge and the periphery, each crop scaled up by whole pixels.
fn write_crops(
    path: &Path,
    size: [u32; 2],
    reference: &[Vec3],
    images: &[Option<Vec<Vec3>>],
    dgi: &[f32],
    (fov, iterations): (f64, u32),
) -> Result<CropsInfo, DenoiseBenchError> {
    use plotters::prelude::*;
    let err = |reason: String| DenoiseBenchError::Crops {
        path: path.display().to_string(),
        reason,
    };
    let [w, _] = size;
    let (side, scale) = crop_geometry(size);
    let cell = side * scale;
    let [pw, ph] = crops_png_size(size);
    let (edge, periphery) = crop_corners(dgi, size, side);
    let mut columns: Vec<(String, Option<Vec<u8>>)> = vec![(
        "reference".into(),
        Some(crate::output::srgb8::display_rgb(reference, 0.0)),
    )];
    for (k, method) in METHODS.into_iter().enumerate() {
        let label = match &images[k] {
            Some(_) => method.to_owned(),
            None => format!("{method} (not loaded)"),
        };
        let bytes = images[k]
            .as_ref()
            .map(|i| crate::output::srgb8::display_rgb(i, 0.0));
        columns.push((label, bytes));
    }
    let mut png = vec![255u8; (pw * ph * 3) as usize];
    for (c, (_, bytes)) in columns.iter().enumerate() {
        let x0 = CROP_GAP + c as u32 * (cell + CROP_GAP);
        for (row, [cx, cy]) in [edge, periphery].into_iter().enumerate() {
            let y0 = CROP_LABEL + CROP_GAP + row as u32 * (cell + CROP_GAP);
            for y in 0..cell {
                for x in 0..cell {
                    let o = (((y0 + y) * pw + x0 + x) * 3) as usize;
                    let rgb = match bytes {
                        Some(b) => {
                            let s = (((cy + y / scale) * w + cx + x / scale) * 3) as usize;
                            [b[s], b[s + 1], b[s + 2]]
                        }
                        None => [128; 3],
                    };
                    png[o..o + 3].copy_from_slice(&rgb);
                }
            }
        }
    }
    crate::bench::font::register().map_err(|e| err(e.to_string()))?;
    {
        let root = BitMapBackend::with_buffer(&mut png, (pw, ph)).into_drawing_area();
        let font_px = (CROP_LABEL as f64 * 0.65)
            .min(f64::from(cell) / 7.0)
            .max(8.0);
        for (c, (label, _)) in columns.iter().enumerate() {
            let x0 = CROP_GAP + c as u32 * (cell + CROP_GAP);
            root.draw(&Text::new(
                label.clone(),
                (x0 as i32, 4),
                (crate::bench::font::FAMILY, font_px)
                    .into_font()
                    .color(&BLACK),
            ))
            .map_err(|e| err(e.to_string()))?;
        }
        root.present().map_err(|e| err(e.to_string()))?;
    }
    let img = image::RgbImage::from_raw(pw, ph, png).expect("sized above");
    crate::output::replace_with(path, |tmp| {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|e| err(e.to_string()))
    })?;
    Ok(CropsInfo {
        path: path.display().to_string(),
        width: pw,
        height: ph,
        side,
        scale,
        fov_deg: fov,
        iterations,
        roi_edge_at: edge,
        periphery_at: periphery,
        columns: columns.into_iter().map(|(l, _)| l).collect(),
    })
}

fn cell(v: Option<f64>, digits: usize) -> String {
    v.filter(|v| v.is_finite())
        .map_or("–".into(), |v| format!("{v:.digits$}"))
}

/// The report as Markdown: the errors at equal iterations and at equal time, the timings and
/// the targets.
#[must_use]
pub fn markdown(r: &DenoiseBenchReport) -> String {
    let c = &r.config;
    let mut s = format!(
        "Device: {}\nOIDN: {}\n\nSetup: {}, {}×{}, guided (paper's setup, p_min 0), reference {} spp ({:.0} ms); features {:.1} ms once per view.\n\n",
        r.device,
        r.oidn,
        c.scene,
        c.size[0],
        c.size[1],
        c.reference_spp,
        r.reference_ms,
        r.features_ms
    );
    s += "Equal iterations (relMSE; ꟻLIP):\n\n| FOV | iterations | method | render ms | method ms | relMSE ROI | relMSE periphery | FLIP ROI | FLIP periphery |\n|---|---|---|---|---|---|---|---|---|\n";
    for t in &r.times {
        let get = |region: &str| {
            r.errors.iter().find(|e| {
                e.fov_deg == t.fov_deg
                    && e.iterations == t.iterations
                    && e.method == t.method
                    && e.region == region
            })
        };
        let (roi, per) = (get("roi"), get("periphery"));
        let ms = match t.ms_cpu_twin {
            Some(twin) => format!("{} (CPU twin {twin:.2})", cell(Some(t.ms), 2)),
            None => cell(Some(t.ms), 2),
        };
        s += &format!(
            "| {}° | {} | {} | {:.1} | {} | {} | {} | {} | {} |\n",
            t.fov_deg,
            t.iterations,
            t.method,
            t.render_ms,
            ms,
            cell(roi.map(|e| e.rel_mse), 4),
            cell(per.map(|e| e.rel_mse), 4),
            cell(roi.map(|e| e.flip), 4),
            cell(per.map(|e| e.flip), 4),
        );
    }
    s += "\nEqual time (each method at the largest listed iteration count whose render, method and feature time fits the render's time up to the budget's count):\n\n| FOV | budget (iterations, ms) | method | iterations | cost ms | relMSE ROI | relMSE periphery | FLIP ROI | FLIP periphery |\n|---|---|---|---|---|---|---|---|---|\n";
    for e in &r.equal_time {
        s += &format!(
            "| {}° | {}, {:.1} | {} | {} | {} | {} | {} | {} | {} |\n",
            e.fov_deg,
            e.budget_iterations,
            e.budget_ms,
            e.method,
            e.iterations.map_or("–".into(), |n| n.to_string()),
            cell(e.cost_ms, 1),
            cell(e.rel_mse_roi, 4),
            cell(e.rel_mse_periphery, 4),
            cell(e.flip_roi, 4),
            cell(e.flip_periphery, 4),
        );
    }
    s += "\nTime per picture (synthetic scene, median):\n\n| size | interactive CPU twin ms | interactive GPU ms | OIDN ms | CPU twin ÷ OIDN | GPU ÷ OIDN |\n|---|---|---|---|---|---|\n";
    for t in &r.timings {
        s += &format!(
            "| {}×{} | {:.1} | {} | {} | {} | {} |\n",
            t.width,
            t.height,
            t.interactive_cpu_ms,
            cell(t.interactive_gpu_ms, 2),
            cell(t.oidn_ms, 1),
            cell(t.interactive_cpu_over_oidn, 3),
            cell(t.interactive_gpu_over_oidn, 3),
        );
    }
    let t = &r.targets;
    let met = |m: Option<bool>| match m {
        Some(true) => "met",
        Some(false) => "missed",
        None => "not measured",
    };
    s += &format!(
        "\nTargets (worst case over the pictures and sizes):\n\n* periphery relMSE interactive ÷ off ≤ 0.5: {:.3} ({})\n* periphery relMSE interactive ÷ OIDN ≤ 1.5: {} ({})\n* time interactive (CPU twin) ÷ OIDN (CPU) ≤ 0.1: {} ({})\n* ROI relMSE interactive ÷ off ≤ 1: {:.3} ({})\n",
        t.periphery_interactive_over_off,
        met(Some(t.periphery_interactive_over_off_met)),
        cell(t.periphery_interactive_over_oidn, 3),
        met(t.periphery_interactive_over_oidn_met),
        cell(t.time_interactive_cpu_over_oidn, 3),
        met(t.time_interactive_cpu_over_oidn_met),
        t.roi_interactive_over_off,
        met(Some(t.roi_interactive_over_off_met)),
    );
    if let Some(c) = &r.crops {
        s += &format!(
            "\nCrops: {} ({}×{}; {}° at {} iterations; rows: ROI edge at {:?}, periphery at {:?}).\n",
            c.path, c.width, c.height, c.fov_deg, c.iterations, c.roi_edge_at, c.periphery_at
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// relMSE in closed form: a uniform offset δ on a uniform reference r gives
    /// δ² / (r² + 0.01) in every channel; the mask picks the pixels.
    #[test]
    fn rel_mse_closed_form_and_mask() {
        let r = Vec3::new(0.5, 0.2, 1.0);
        let reference = vec![r; 6];
        let mut image = vec![r + Vec3::splat(0.1); 6];
        image[5] = Vec3::splat(100.0);
        let mask = [true, true, true, true, true, false];
        let want = [0.5f64, 0.2, 1.0]
            .iter()
            .map(|r| 0.01 / (r * r + 0.01))
            .sum::<f64>()
            / 3.0;
        let got = rel_mse(&image, &reference, &mask);
        assert!((got - want).abs() < 1e-6 * want, "{got} vs {want}");
        assert_eq!(rel_mse(&reference, &reference, &mask), 0.0);
        assert!(rel_mse(&image, &reference, &[false; 6]).is_nan());
        // Black reference: the offset keeps it finite.
        let black = vec![Vec3::ZERO; 2];
        let one = vec![Vec3::splat(0.1); 2];
        assert!((rel_mse(&one, &black, &[true; 2]) - 1.0).abs() < 1e-6);
    }

    fn noisy(base: u8, amplitude: i32, n: usize, seed: u32) -> Vec<u8> {
        let mut state = seed;
        (0..n)
            .map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let u = (state >> 8) as i32 % (2 * amplitude + 1) - amplitude;
                (i32::from(base) + u).clamp(0, 255) as u8
            })
            .collect()
    }

    /// ꟻLIP's analytic cases: a picture against itself is 0 everywhere; black against white is
    /// the same at every pixel, NVIDIA's implementation's 0.9674 (its colour term alone, as a
    /// uniform picture has no edges or points); more noise is more error.
    #[test]
    fn flip_analytic_cases() {
        let (w, h) = (32u32, 24u32);
        let n = (w * h * 3) as usize;
        let grey = vec![118u8; n];
        assert!(flip_map(&grey, &grey, w, h).iter().all(|&v| v == 0.0));
        let noise = noisy(118, 40, n, 7);
        assert!(flip_map(&noise, &noise, w, h).iter().all(|&v| v == 0.0));
        let bw = flip_map(&vec![0; n], &vec![255; n], w, h);
        assert_eq!(bw.len(), (w * h) as usize);
        for v in &bw {
            assert!((v - 0.9674).abs() < 1e-3, "black vs white: {v}");
        }
        let all = vec![true; (w * h) as usize];
        let mut last = 0.0;
        for amplitude in [2, 8, 24, 64] {
            let m = masked_mean(&flip_map(&grey, &noisy(118, amplitude, n, 3), w, h), &all);
            assert!(m > last && m <= 1.0, "noise ±{amplitude}: {m} after {last}");
            last = m;
        }
    }

    #[test]
    fn bad_settings_name_their_flag() {
        let bad = [
            (
                DenoiseBenchConfig {
                    size: [8, 8],
                    ..Default::default()
                },
                "--size",
            ),
            (
                DenoiseBenchConfig {
                    iterations: vec![1, 512],
                    ..Default::default()
                },
                "--iterations",
            ),
            (
                DenoiseBenchConfig {
                    iterations: vec![4, 1],
                    ..Default::default()
                },
                "--iterations",
            ),
            (
                DenoiseBenchConfig {
                    timing_sizes: vec![[7680, 4320]],
                    ..Default::default()
                },
                "--timing-sizes",
            ),
            (
                DenoiseBenchConfig {
                    crops_iterations: 3,
                    ..Default::default()
                },
                "--crops-iterations",
            ),
            (
                DenoiseBenchConfig {
                    reference_spp: 0,
                    ..Default::default()
                },
                "--reference-spp",
            ),
            (
                DenoiseBenchConfig {
                    fovs_deg: vec![f64::NAN],
                    ..Default::default()
                },
                "--fov",
            ),
        ];
        for (cfg, flag) in bad {
            let e = cfg.validate().unwrap_err().to_string();
            assert!(e.starts_with(flag), "{e}");
        }
        DenoiseBenchConfig::default().validate().unwrap();
    }

    #[test]
    fn crops_fit_the_picture() {
        for size in [[48, 27], [320, 180], [16, 16]] {
            let (side, scale) = crop_geometry(size);
            assert!(side <= size[0] && side <= size[1] && side * scale >= CROP_SHOWN);
            let dgi: Vec<f32> = (0..size[0] * size[1])
                .map(|p| if p % size[0] > size[0] / 2 { 0.0 } else { 0.5 })
                .collect();
            let (e, p) = crop_corners(&dgi, size, side);
            for [x, y] in [e, p] {
                assert!(x + side <= size[0] && y + side <= size[1]);
            }
        }
    }
}
