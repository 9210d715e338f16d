//! `raygun bench denoise`: the denoisers measured against a reference (DESIGN.md §8).
//!
//! A guided render of one scene in the paper's setup (viewer 1 m in front of the wall centre,
//! square cones, p_min 0; [`super::paper`]) at each ROI field of view, looked at after each of a
//! list of iteration counts, and a full-frame reference of the same scene and view. Each picture
//! is made four ways ([`METHODS`]):
//!
//! * `off`: the accumulation's per-pixel mean, unsampled pixels black;
//! * `filter`: the paper's filter ([`crate::filter::Filter`], [`crate::filter::FilterParams::default`]), as
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

mod crops;
mod methods;
mod report;

use std::path::Path;
use std::time::Instant;

use glam::Vec3;
use serde::Serialize;

use super::paper;
use crate::display::DisplayModel;
use crate::filter::denoise::DenoiseInputError;
use crate::filter::denoise::gpu::DenoiseGpuError;
use crate::filter::{gpu::FilterGpuError, oidn};
use crate::frame::{FrameError, GuideConfig, Render};
use crate::gpu::{Backend, GpuError};
use crate::roi::cone::ConeError;
use crate::scene::Scene;
use crate::trace::camera::CameraError;
use crate::trace::path::TraceSettings;

use crops::write_crops;
pub use crops::{CropColumn, CropsGeometry, crop_geometry, crops_png_size, write_crop_columns};
use methods::{Measured, Methods, Pictures, time_interactive, time_oidn};
pub use report::markdown;
use report::targets;

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

/// Opens OIDN as `render --denoise oidn` does: the library and its device (the CUDA device
/// beside an NVIDIA adapter, else the CPU's); `Err` says why not.
pub fn open_oidn(backend: &Backend) -> Result<oidn::Device, oidn::OidnError> {
    oidn::Oidn::load()?.device(oidn::DeviceChoice::Auto {
        nvidia: backend.is_nvidia(),
    })
}

/// The reference picture, linear and as shown (8-bit sRGB), and its size.
struct Reference {
    image: Vec<Vec3>,
    srgb8: Vec<u8>,
    size: [u32; 2],
}

impl Reference {
    /// Each method's time row, its error rows in both regions, and its
    /// [relMSE ROI, periphery, ꟻLIP ROI, periphery] (`None` for a method not run).
    fn judge(
        &self,
        (fov, n, render_ms): (f64, u32, f64),
        pictures: &Pictures,
        dgi: &[f32],
    ) -> (Vec<TimeRow>, Vec<ErrorRow>, [Option<[f64; 4]>; 4]) {
        let roi: Vec<bool> = dgi.iter().map(|&d| d == 0.0).collect();
        let periphery: Vec<bool> = roi.iter().map(|r| !r).collect();
        let (mut times, mut errors, mut figures) = (Vec::new(), Vec::new(), [None; 4]);
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
            let [w, h] = self.size;
            let shown = crate::output::srgb8::display_rgb(image, 0.0);
            let flip = flip_map(&self.srgb8, &shown, w, h);
            let mut f = [0.0; 4];
            for (r, (region, mask)) in REGIONS.into_iter().zip([&roi, &periphery]).enumerate() {
                let row = ErrorRow {
                    fov_deg: fov,
                    iterations: n,
                    method,
                    region,
                    pixels: mask.iter().filter(|&&v| v).count(),
                    rel_mse: rel_mse(image, &self.image, mask),
                    flip: masked_mean(&flip, mask),
                };
                (f[r], f[2 + r]) = (row.rel_mse, row.flip);
                errors.push(row);
            }
            figures[k] = Some(f);
        }
        (times, errors, figures)
    }
}

/// A guided frame's time (ms): its stage times (the DGI where it was recomputed) where the
/// backend reports them, else the wall clock around it.
fn frame_ms(s: &crate::frame::FrameStats, wall_ms: f64) -> f64 {
    match s.ms_trace {
        Some(trace) => {
            let dgi = if s.dgi_recomputed {
                s.ms_dgi.unwrap_or(0.0)
            } else {
                0.0
            };
            trace + s.ms_schedule.unwrap_or(0.0) + dgi
        }
        None => wall_ms,
    }
}

/// The equal-time rows of one FOV: for each listed count's render time as the budget, each
/// method at the largest count whose render, own and (for the two that read them) feature
/// time fits.
fn equal_time_rows(fov: f64, measured: &[Measured], features_ms: f64) -> Vec<EqualTimeRow> {
    let mut rows = Vec::new();
    for &(budget_n, budget, _, _) in measured {
        for (k, method) in METHODS.into_iter().enumerate() {
            let extra = if k >= 2 { features_ms } else { 0.0 };
            let fit = measured
                .iter()
                .rfind(|(_, r, f, ms)| f[k].is_some() && r + ms[k] + extra <= budget);
            let f = fit.and_then(|(_, _, f, _)| f[k]);
            rows.push(EqualTimeRow {
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
    rows
}

/// The synthetic timings at the bench size and each `--timing-sizes` size.
fn size_timings(
    backend: &Backend,
    m: &Methods<'_>,
    cfg: &DenoiseBenchConfig,
    progress: &mut impl FnMut(&str, u32),
) -> Result<Vec<SizeTiming>, DenoiseBenchError> {
    let mut timings = Vec::new();
    let mut sizes = vec![cfg.size];
    sizes.extend(cfg.timing_sizes.iter().copied());
    for (i, &[tw, th]) in sizes.iter().enumerate() {
        progress(&format!("timing {tw}×{th}"), 0);
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
    Ok(timings)
}

/// The crops' pictures: FOV, iteration count, each method's picture, the DGI.
type CropSet = (f64, u32, Vec<Option<Vec<Vec3>>>, Vec<f32>);

/// What the FOVs' renders gave: the rows, and the crops' pictures (FOV, count, pictures, DGI).
#[derive(Default)]
struct Rendered {
    errors: Vec<ErrorRow>,
    times: Vec<TimeRow>,
    equal_time: Vec<EqualTimeRow>,
    crop_set: Option<CropSet>,
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
    let image = paper::reference_image_wall(
        backend,
        scene,
        settings(cfg.seed ^ 0x5eed),
        cfg.reference_spp,
        None,
        &mut |n| progress(&step, n),
    )?;
    let reference_ms = t.elapsed().as_secs_f64() * 1e3;
    let reference = Reference {
        srgb8: crate::output::srgb8::display_rgb(&image, 0.0),
        image,
        size: cfg.size,
    };
    let (mut methods, mut features_ms) = (None::<Methods>, 0.0);
    let mut out = Rendered::default();
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
            let (m, ms) = Methods::new(backend, &g, oidn_device.take());
            (methods, features_ms) = (Some(m), ms);
        }
        let m = methods.as_ref().expect("made above");
        let (mut done, mut render_ms) = (0u32, 0f64);
        let mut measured: Vec<Measured> = Vec::new();
        for &n in &cfg.iterations {
            while done < n {
                let t = Instant::now();
                let s = g.run_frame(true)?;
                render_ms += frame_ms(&s, t.elapsed().as_secs_f64() * 1e3);
                done += 1;
                progress(&step, 1);
            }
            let (acc, dgi) = (g.accumulation()?, g.dgi()?);
            let pictures = m.pictures(&acc, &dgi)?;
            let (times, errors, figures) = reference.judge((fov, n, render_ms), &pictures, &dgi);
            out.times.extend(times);
            out.errors.extend(errors);
            measured.push((n, render_ms, figures, pictures.ms));
            if crops.is_some() && out.crop_set.is_none() && n == cfg.crops_iterations {
                out.crop_set = Some((fov, n, pictures.images, dgi));
            }
        }
        out.equal_time
            .extend(equal_time_rows(fov, &measured, features_ms));
    }
    let m = methods.expect("at least one FOV (validated)");
    let timings = size_timings(backend, &m, cfg, &mut progress)?;
    let targets = targets(&out.errors, &timings);
    let crops = match (crops, out.crop_set) {
        (Some(path), Some((fov, n, images, dgi))) => Some(write_crops(
            path,
            cfg.size,
            &reference.image,
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
        errors: out.errors,
        times: out.times,
        equal_time: out.equal_time,
        timings,
        targets,
        crops,
    })
}

#[cfg(test)]
mod tests;
