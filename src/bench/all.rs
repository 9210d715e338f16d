//! `raygun bench all`: every benchmark in one run (issue 8) — DGI, full-frame tracing, the
//! paper's guided benchmark and the filter — plus convergence curves: RMSE against a converged
//! reference inside and outside the ROI versus accumulated frame time, guided vs full frame,
//! unfiltered vs the fast filter; the DGI metrics' time against their error and the
//! closest-point solver on the hard-case set; per-stage times per iteration; and the paper's
//! table (DESIGN.md §9) and the issue's targets beside ours. Writes `report.md`, `report.json`
//! (the same figures), `fig5.png`, `dgi_metrics.png` and `convergence.png`.

use std::path::Path;

use glam::{DVec3, Vec3};
use serde::Serialize;

use crate::bench::dgi::{self, DgiBenchConfig, DgiBenchReport};
use crate::bench::filter::{self, FilterBenchConfig, FilterBenchReport};
use crate::bench::guided::{self, GuidedBenchConfig, GuidedBenchReport};
use crate::bench::solver::{self, SolverReport};
use crate::bench::stages::{self, StageRow};
use crate::bench::trace::{self, TraceBenchConfig, TraceBenchRow};
use crate::display::DisplayModel;
use crate::filter::{FilterKind, FilterParams};
use crate::frame::{GuideConfig, Renderer};
use crate::gpu::Backend;
use crate::roi::dgi::{Falloff, Surface};
use crate::scene::Scene;
use crate::trace::accum::Accumulation;
use crate::trace::camera::RenderCamera;
use crate::trace::cpu::TraceSettings;

/// Target of the time-to-quality figure: RMSE inside the ROI ≤ this share of the reference's
/// mean there.
pub const TARGET_REL_RMSE: f64 = 0.01;

/// Every setting of the run.
#[derive(Clone, Debug, Serialize)]
pub struct AllConfig {
    pub quick: bool,
    pub size: [u32; 2],
    pub fovs_deg: Vec<f64>,
    /// Guided iterations of the guided benchmark and of each guided convergence curve.
    pub iterations: u32,
    /// Samples per pixel of the converged references.
    pub reference_spp: u32,
    /// A curve point every this many iterations.
    pub sample_every: u32,
    pub trace_frames: u32,
    pub dgi_gpu_reps: u32,
    pub dgi_cpu_reps: u32,
    pub filter_reps: u32,
    /// Timed passes of the closest-point solvers over the hard-case set.
    pub solver_reps: u32,
    /// Iterations of the per-stage measurement (per FOV).
    pub stage_iterations: u32,
    /// Also time a full frame of `builtin:city` (the paper's second scene) when the report's
    /// scene is not it.
    pub city: bool,
    /// Fast filter settings of the filtered curves and the filter benchmark's error table.
    pub filter: FilterParams,
    pub seed: u32,
}

impl AllConfig {
    /// Settings by `--quick`; `size` overrides the image size (k_max scales with the width).
    #[must_use]
    pub fn new(quick: bool, size: Option<[u32; 2]>) -> Self {
        let size = size.unwrap_or(if quick { [160, 90] } else { [3840, 2160] });
        let k_max = (FilterParams::DEFAULT_K_MAX * size[0] as f32 / 3840.0)
            .clamp(1.0, FilterParams::MAX_K_MAX);
        let filter = FilterParams {
            kind: FilterKind::Fast,
            k_max,
            ..FilterParams::default()
        };
        if quick {
            Self {
                quick,
                size,
                fovs_deg: vec![10.0, 60.0],
                iterations: 128,
                reference_spp: 1024,
                sample_every: 8,
                trace_frames: 5,
                dgi_gpu_reps: 5,
                dgi_cpu_reps: 1,
                filter_reps: 3,
                solver_reps: 3,
                stage_iterations: 16,
                city: true,
                filter,
                seed: 1,
            }
        } else {
            Self {
                quick,
                size,
                fovs_deg: vec![10.0, 20.0, 30.0, 40.0, 50.0, 60.0],
                iterations: 100,
                reference_spp: 1024,
                sample_every: 5,
                trace_frames: 20,
                dgi_gpu_reps: 50,
                dgi_cpu_reps: 3,
                filter_reps: 20,
                solver_reps: 20,
                stage_iterations: 100,
                city: true,
                filter,
                seed: 1,
            }
        }
    }
}

/// Who ran it where, and how to run it again.
#[derive(Clone, Debug, Serialize)]
pub struct Header {
    /// The command line, shell-quoted.
    pub command: String,
    /// The backend in words (adapter and API, or the CPU twins and their threads).
    pub device: String,
    /// The GPU adapter, when the backend is a GPU.
    pub adapter: Option<String>,
    /// Processor model and the threads the CPU work ran on.
    pub cpu: String,
    pub commit: String,
    /// Whether the working tree differed from the commit (`git status --porcelain`).
    pub dirty: bool,
    /// "release" or "debug" (debug builds are several times slower on the CPU).
    pub profile: String,
    /// UTC, YYYY-MM-DD.
    pub date: String,
    pub scene: String,
    pub display: String,
}

/// `args` as one shell command line (single quotes where a word needs them).
#[must_use]
pub fn shell_join(args: impl IntoIterator<Item = String>) -> String {
    args.into_iter()
        .map(|a| {
            let plain = !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_./,:=@+".contains(c));
            if plain {
                a
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// The processor model (from `/proc/cpuinfo` where there is one) and rayon's thread count.
#[must_use]
pub fn cpu_description() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    format!("{model}, {} threads", rayon::current_num_threads())
}

fn git_dirty() -> bool {
    std::process::Command::new("git")
        .args(["status", "--porcelain", "--untracked-files=no"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .is_some_and(|o| !o.stdout.is_empty())
}

impl Header {
    /// The header of a run on `backend` now, from this process's command line.
    #[must_use]
    pub fn now(backend: &Backend, scene: &str, display: &str) -> Self {
        Self {
            command: shell_join(std::env::args()),
            device: backend.describe(),
            adapter: backend.adapter(),
            cpu: cpu_description(),
            commit: commit(),
            dirty: git_dirty(),
            profile: if cfg!(debug_assertions) {
                "debug"
            } else {
                "release"
            }
            .into(),
            date: utc_date(),
            scene: scene.to_string(),
            display: display.to_string(),
        }
    }
}

/// One point of a convergence curve.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct CurvePoint {
    pub iteration: u32,
    /// Accumulated frame time (ms), read-backs and RMSE excluded.
    pub ms: f64,
    pub rmse_roi: f64,
    pub rmse_outside: f64,
    pub rmse_roi_filtered: f64,
    pub rmse_outside_filtered: f64,
}

/// Guided and full-frame curves of one FOV.
#[derive(Clone, Debug, Serialize)]
pub struct Convergence {
    pub fov_deg: f64,
    pub roi_pixels: usize,
    /// The reference's mean inside the ROI; the target is [`TARGET_REL_RMSE`] of it.
    pub reference_mean_roi: f64,
    pub target_rmse_roi: f64,
    pub guided: Vec<CurvePoint>,
    pub full_frame: Vec<CurvePoint>,
    /// Unfiltered ROI RMSE of the full frame at the last point not later than the guided
    /// curve's end (equal time, or the first full-frame point when even that is later).
    pub full_rmse_roi_at_guided_end: f64,
    pub full_ms_at_guided_end: f64,
    pub guided_time_to_target: TimeToTarget,
    pub full_time_to_target: TimeToTarget,
    /// Full-frame ÷ guided time to the target, when both reached it.
    pub speedup_to_target: Option<f64>,
    /// The same ratio from the extrapolated times where a curve did not reach the target.
    pub extrapolated_speedup_to_target: Option<f64>,
}

/// When a curve first reached the target (unfiltered, inside the ROI), or how close it got.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TimeToTarget {
    pub reached: bool,
    /// Time of the first point at or below the target, else of the lowest point.
    pub ms: f64,
    /// RMSE at that point.
    pub rmse_roi: f64,
    /// When not reached: the time at which RMSE ∝ 1/√t through the curve's last point would
    /// reach the target (an extrapolation, not a measurement; it ignores the reference's own
    /// noise).
    pub extrapolated_ms: Option<f64>,
}

/// Everything `bench all` measured.
#[derive(Clone, Debug, Serialize)]
pub struct AllReport {
    pub header: Header,
    pub config: AllConfig,
    pub dgi: DgiBenchReport,
    pub trace: Vec<TraceBenchRow>,
    pub guided: GuidedBenchReport,
    pub filter: FilterBenchReport,
    pub convergence: Vec<Convergence>,
    pub solver: SolverReport,
    pub stages: Vec<StageRow>,
    /// DESIGN.md §9's table, row for row, with ours beside it.
    pub paper: Vec<PaperRow>,
    pub targets: Vec<TargetRow>,
}

/// The paper's image size, at which its figures were measured.
pub const PAPER_SIZE: [u32; 2] = [3840, 2160];

/// One row of the paper's table (DESIGN.md §9) and ours. Times are ms; a range is `[low, high]`
/// (equal bounds for a single figure). "Per megapixel" divides by the image's megapixels: for a
/// full frame at one sample per pixel that is the paper's ms per megasample, and it is the
/// figure to compare where our run is not at 3840×2160 (nothing is scaled).
#[derive(Clone, Debug, Serialize)]
pub struct PaperRow {
    pub measure: String,
    pub paper_ms: [f64; 2],
    pub paper_ms_per_megapixel: [f64; 2],
    pub paper_speedup: Option<f64>,
    pub ours_ms: Option<[f64; 2]>,
    pub ours_ms_per_megapixel: Option<[f64; 2]>,
    pub ours_speedup: Option<f64>,
    pub ours_size: [u32; 2],
    pub ours_device: String,
    /// Where ours comes from, or why it is missing.
    pub note: String,
}

/// Whether a target was met.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TargetStatus {
    Met,
    Missed,
    NotMeasured,
}

/// One of the issue's targets.
#[derive(Clone, Debug, Serialize)]
pub struct TargetRow {
    pub target: String,
    /// Our figure on this run's device and size (None: not run).
    pub measured: Option<f64>,
    pub unit: String,
    pub status: TargetStatus,
    /// What the figure is, and why the status is what it is.
    pub note: String,
}

#[derive(Debug, thiserror::Error)]
pub enum AllBenchError {
    #[error("DGI benchmark: {0}")]
    Dgi(#[from] dgi::BenchError),
    #[error("trace benchmark: {0}")]
    Trace(#[from] trace::TraceBenchError),
    #[error("guided benchmark: {0}")]
    Guided(#[from] guided::GuidedBenchError),
    #[error("filter benchmark: {0}")]
    Filter(#[from] filter::FilterBenchError),
    #[error("closest-point solver benchmark: {0}")]
    Solver(#[from] solver::SolverBenchError),
    #[error("scene '{scene}': {reason}")]
    Scene { scene: String, reason: String },
    #[error("convergence curves: {0}")]
    Frame(#[from] crate::frame::FrameError),
    #[error("convergence curves: {0}")]
    Gpu(#[from] crate::gpu::GpuError),
    #[error("convergence curves: {0}")]
    FilterInput(#[from] crate::filter::FilterInputError),
    #[error("convergence curves: {0}")]
    Cone(#[from] crate::roi::cone::ConeError),
    #[error("convergence curves: scene '{scene}': {source}")]
    Camera {
        scene: String,
        #[source]
        source: crate::trace::camera::CameraError,
    },
    #[error("writing {path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("writing {path}: {reason}")]
    Output { path: String, reason: String },
}

/// The commit of the working directory (`git rev-parse HEAD`), or "unknown".
#[must_use]
pub fn commit() -> String {
    std::process::Command::new("git")
        .args(["rev-parse", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".into())
}

/// Today's UTC date as YYYY-MM-DD (civil-from-days, proleptic Gregorian).
#[must_use]
pub fn utc_date() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let z = (secs / 86_400) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

/// RMSE (linear RGB) over the pixels where `mask` is `inside`; NaN when there are none.
fn rmse(image: &[DVec3], reference: &[Vec3], mask: &[bool], inside: bool) -> f64 {
    let (mut se, mut n) = (0f64, 0usize);
    for ((a, b), &m) in image.iter().zip(reference).zip(mask) {
        if m == inside {
            se += (*a - b.as_dvec3()).length_squared() / 3.0;
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        (se / n as f64).sqrt()
    }
}

fn point(
    iteration: u32,
    ms: f64,
    acc: &Accumulation,
    dgi: &[f32],
    reference: &[Vec3],
    mask: &[bool],
    params: &FilterParams,
) -> Result<CurvePoint, AllBenchError> {
    let raw = crate::filter::unfiltered_cpu(acc);
    let filtered = crate::filter::filter_cpu(params, acc, dgi)?;
    Ok(CurvePoint {
        iteration,
        ms,
        rmse_roi: rmse(&raw, reference, mask, true),
        rmse_outside: rmse(&raw, reference, mask, false),
        rmse_roi_filtered: rmse(&filtered, reference, mask, true),
        rmse_outside_filtered: rmse(&filtered, reference, mask, false),
    })
}

fn time_to_target(curve: &[CurvePoint], target: f64) -> TimeToTarget {
    if let Some(p) = curve.iter().find(|p| p.rmse_roi <= target) {
        return TimeToTarget {
            reached: true,
            ms: p.ms,
            rmse_roi: p.rmse_roi,
            extrapolated_ms: None,
        };
    }
    let extrapolated_ms = curve
        .last()
        .filter(|p| p.rmse_roi.is_finite() && target > 0.0)
        .map(|p| p.ms * (p.rmse_roi / target).powi(2));
    let best = curve
        .iter()
        .min_by(|a, b| a.rmse_roi.total_cmp(&b.rmse_roi))
        .copied();
    TimeToTarget {
        reached: false,
        ms: best.map_or(f64::NAN, |p| p.ms),
        rmse_roi: best.map_or(f64::NAN, |p| p.rmse_roi),
        extrapolated_ms,
    }
}

/// The convergence curves of one scene at each FOV of `fovs`: a guided render of
/// `cfg.iterations` iterations, then a full-frame render until its accumulated time reaches the
/// guided one's (at least two iterations). Time is the frames' own (GPU timestamps where the
/// adapter has them, else wall clock); the filtered curves use the fast filter's CPU twin.
#[allow(clippy::too_many_arguments)]
pub fn convergence(
    backend: &Backend,
    display: &DisplayModel,
    name: &str,
    scene: &Scene,
    fovs: &[f64],
    cfg: &AllConfig,
    mut progress: impl FnMut(&str),
) -> Result<Vec<Convergence>, AllBenchError> {
    let [w, h] = cfg.size;
    let camera =
        RenderCamera::choose(scene, None, w, h).map_err(|source| AllBenchError::Camera {
            scene: name.to_string(),
            source,
        })?;
    let settings = |seed: u32| TraceSettings {
        width: w,
        height: h,
        seed,
        max_depth: crate::trace::cpu::DEFAULT_MAX_DEPTH,
        camera,
    };
    progress(&format!(
        "convergence: reference ({} spp)",
        cfg.reference_spp
    ));
    let reference = {
        let mut r = Renderer::full(backend, scene, settings(cfg.seed ^ 0xc0_5eed))?;
        let mut left = cfg.reference_spp.max(1);
        while left > 0 {
            let n = left.min(64);
            r.iterate(n)?;
            left -= n;
        }
        r.accumulation()?.mean_image()
    };
    let every = cfg.sample_every.max(1);
    let mut out = Vec::new();
    for &fov in fovs {
        progress(&format!("convergence: {fov}° guided"));
        let roi = super::paper_roi(fov)?;
        let mut g = Renderer::guided(
            backend,
            scene,
            settings(cfg.seed.wrapping_add(11)),
            display,
            GuideConfig::default(),
        )?;
        g.set_roi(Some(roi))?;
        let n = cfg.iterations.max(1);
        let (mut ms, mut guided_curve) = (0.0, Vec::new());
        let (mut dgi, mut mask) = (Vec::new(), Vec::new());
        for i in 1..=n {
            let s = g.run_frame(true)?;
            ms +=
                s.ms_dgi.unwrap_or(0.0) + s.ms_schedule.unwrap_or(0.0) + s.ms_trace.unwrap_or(0.0);
            if i == 1 {
                dgi = g.dgi()?;
                mask = dgi.iter().map(|&d| d == 0.0).collect();
            }
            if i % every == 0 || i == n {
                let acc = g.accumulation()?;
                guided_curve.push(point(i, ms, &acc, &dgi, &reference, &mask, &cfg.filter)?);
            }
        }
        drop(g);
        let guided_ms = ms;
        progress(&format!("convergence: {fov}° full frame"));
        let mut full = Renderer::full(backend, scene, settings(cfg.seed.wrapping_add(12)))?;
        let (mut ms, mut full_curve, mut i) = (0.0, Vec::new(), 0u32);
        let mut stride = 1u32;
        loop {
            ms += full.timed_iterations(1)?.ms[0];
            i += 1;
            if i == 1 {
                // Aim for about as many points as the guided curve.
                let estimate = (guided_ms / ms).ceil().max(1.0) as u32;
                stride = (estimate / (n / every).max(1)).max(1);
            }
            let done = i >= 2 && ms >= guided_ms;
            if i % stride == 0 || done {
                let acc = full.accumulation()?;
                full_curve.push(point(i, ms, &acc, &dgi, &reference, &mask, &cfg.filter)?);
            }
            if done {
                break;
            }
        }
        drop(full);
        let at_end = full_curve
            .iter()
            .rev()
            .find(|p| p.ms <= guided_ms)
            .unwrap_or(&full_curve[0]);
        let mean = {
            let (mut s, mut k) = (0f64, 0usize);
            for (r, &m) in reference.iter().zip(&mask) {
                if m {
                    s += r.as_dvec3().element_sum() / 3.0;
                    k += 1;
                }
            }
            if k == 0 { f64::NAN } else { s / k as f64 }
        };
        let target = TARGET_REL_RMSE * mean;
        let gt = time_to_target(&guided_curve, target);
        let ft = time_to_target(&full_curve, target);
        out.push(Convergence {
            fov_deg: fov,
            roi_pixels: mask.iter().filter(|&&m| m).count(),
            reference_mean_roi: mean,
            target_rmse_roi: target,
            full_rmse_roi_at_guided_end: at_end.rmse_roi,
            full_ms_at_guided_end: at_end.ms,
            guided: guided_curve,
            full_frame: full_curve,
            speedup_to_target: (gt.reached && ft.reached).then(|| ft.ms / gt.ms),
            extrapolated_speedup_to_target: match (
                gt.extrapolated_ms.or(gt.reached.then_some(gt.ms)),
                ft.extrapolated_ms.or(ft.reached.then_some(ft.ms)),
            ) {
                (Some(g), Some(f)) if !(gt.reached && ft.reached) => Some(f / g),
                _ => None,
            },
            guided_time_to_target: gt,
            full_time_to_target: ft,
        });
    }
    Ok(out)
}

/// The FOVs of the filter, convergence and per-stage sections: the first and last of the list.
fn end_fovs(cfg: &AllConfig) -> Vec<f64> {
    match (cfg.fovs_deg.first(), cfg.fovs_deg.last()) {
        (Some(&a), Some(&b)) if a != b => vec![a, b],
        (Some(&a), _) => vec![a],
        _ => Vec::new(),
    }
}

/// Whether `name` is the paper's city scene (the full-frame table's second row).
fn is_city(name: &str) -> bool {
    name.contains("city")
}

/// How many times [`run`] calls its `progress` (for a progress bar's length).
#[must_use]
pub fn progress_steps(cfg: &AllConfig, name: &str, gpu: bool) -> u64 {
    let fovs = cfg.fovs_deg.len() as u64;
    let ends = end_fovs(cfg).len() as u64;
    let scenes = 1 + u64::from(cfg.city && !is_city(name));
    (1 + 3 * fovs) // DGI
        + (1 + scenes) // trace
        + (1 + 2 + fovs) // guided
        + (1 + 4 * ends) // filter (one k_max: exact and fast)
        + (1 + 2 * ends) // convergence
        + (2 + u64::from(gpu)) // solver
        + ends // stages
}

/// Runs every benchmark on `scene` (named `name`): DGI, full-frame tracing (plus `builtin:city`
/// when `cfg.city`), the guided benchmark, the filter, the convergence curves and per-stage times
/// at the first and last of `cfg.fovs_deg`, and the closest-point solver; then lays the paper's
/// table and the issue's targets beside them.
pub fn run(
    backend: &Backend,
    display: &DisplayModel,
    display_name: &str,
    name: &str,
    scene: &Scene,
    cfg: &AllConfig,
    mut progress: impl FnMut(&str),
) -> Result<AllReport, AllBenchError> {
    let header = Header::now(backend, name, display_name);
    let surface = Surface::from_model(display);
    progress("DGI");
    let dgi = dgi::run(
        &surface,
        display.name(),
        backend,
        &DgiBenchConfig {
            size: cfg.size,
            fovs_deg: cfg.fovs_deg.clone(),
            gpu_reps: cfg.dgi_gpu_reps.max(1),
            cpu_reps: cfg.dgi_cpu_reps.max(1),
            falloff: Falloff::default(),
            ..DgiBenchConfig::default()
        },
        &mut progress,
    )?;
    progress("trace");
    let scenes = vec![(name.to_string(), scene.clone())];
    let mut trace_scenes = scenes.clone();
    if cfg.city && !is_city(name) {
        let city = Scene::open("builtin:city").map_err(|e| AllBenchError::Scene {
            scene: "builtin:city".into(),
            reason: e.to_string(),
        })?;
        trace_scenes.push(("city".to_string(), city));
    }
    let trace = trace::run(
        backend,
        &trace_scenes,
        &TraceBenchConfig {
            size: cfg.size,
            frames: cfg.trace_frames.max(1),
            seed: cfg.seed,
            ..TraceBenchConfig::default()
        },
        &mut progress,
    )?;
    drop(trace_scenes);
    progress("guided");
    let guided = guided::run(
        backend,
        display,
        &scenes,
        &GuidedBenchConfig {
            size: cfg.size,
            fovs_deg: cfg.fovs_deg.clone(),
            iterations: cfg.iterations.max(1),
            full_frames: cfg.trace_frames.max(1),
            reference_spp: cfg.reference_spp.max(1),
            seed: cfg.seed,
            ..GuidedBenchConfig::default()
        },
        &mut progress,
    )?;
    progress("filter");
    let fovs = end_fovs(cfg);
    let fcfg = FilterBenchConfig {
        size: cfg.size,
        fovs_deg: fovs.clone(),
        k_maxes: vec![cfg.filter.k_max],
        reps: cfg.filter_reps.max(1),
        rounds: cfg.iterations.max(1),
        error_params: cfg.filter,
        seed: cfg.seed,
        ..FilterBenchConfig::default()
    };
    let filter = filter::run_with_inputs(
        &surface,
        display_name,
        backend,
        &fcfg,
        &mut progress,
        |fov, _| {
            guided::filter_input(
                backend,
                display,
                name,
                scene,
                cfg.size,
                fov,
                cfg.iterations.max(1),
                cfg.reference_spp.max(1),
                cfg.seed,
            )
            .map_err(|e| filter::FilterBenchError::Render(e.to_string()))
        },
    )?;
    let convergence = convergence(backend, display, name, scene, &fovs, cfg, &mut progress)?;
    let solver = solver::run(backend, cfg.solver_reps, &mut progress)?;
    let mut stage_rows = Vec::new();
    for &fov in &fovs {
        progress(&format!("per-stage times: {fov}°"));
        stage_rows.push(stages::measure(
            backend,
            display,
            name,
            scene,
            cfg.size,
            fov,
            cfg.stage_iterations,
            &cfg.filter,
            0.0,
            cfg.seed.wrapping_add(21),
        )?);
    }
    let mut report = AllReport {
        header,
        config: cfg.clone(),
        dgi,
        trace,
        guided,
        filter,
        convergence,
        solver,
        stages: stage_rows,
        paper: Vec::new(),
        targets: Vec::new(),
    };
    report.paper = paper_rows(&report);
    report.targets = target_rows(&report, datacenter_gpu(backend));
    Ok(report)
}

/// Adapter names of datacenter GPUs (the targets' class of device).
const DATACENTER_GPUS: [&str; 12] = [
    "H100", "H200", "H800", "GH200", "A100", "A800", "B100", "B200", "GB200", "L40", "MI300",
    "MI250",
];

/// The adapter's name when the backend is a datacenter GPU.
#[must_use]
pub fn datacenter_gpu(backend: &Backend) -> Option<String> {
    match backend {
        Backend::Gpu(ctx)
            if ctx.info.device_type != wgpu::DeviceType::Cpu
                && DATACENTER_GPUS.iter().any(|g| ctx.info.name.contains(g)) =>
        {
            Some(ctx.info.name.clone())
        }
        _ => None,
    }
}

fn megapixels(size: [u32; 2]) -> f64 {
    f64::from(size[0]) * f64::from(size[1]) / 1e6
}

fn same(v: f64) -> [f64; 2] {
    [v, v]
}

/// DESIGN.md §9's rows with ours beside them.
#[must_use]
pub fn paper_rows(r: &AllReport) -> Vec<PaperRow> {
    let size = r.config.size;
    let mp = megapixels(size);
    let paper_mp = megapixels(PAPER_SIZE);
    let size_note = if size == PAPER_SIZE {
        String::new()
    } else {
        format!(
            "; ours at {}×{}, not 3840×2160: compare per megapixel (nothing scaled)",
            size[0], size[1]
        )
    };
    let mut rows = Vec::new();
    // DGI: the exact metric on the GPU when there is one, else on the CPU twin; min–max over FOVs.
    let backend = if r.dgi.adapter.is_some() {
        "gpu"
    } else {
        "cpu"
    };
    let dgi_ms: Vec<f64> = r
        .dgi
        .rows
        .iter()
        .filter(|d| d.metric == crate::roi::dgi::Metric::Exact && d.backend == backend)
        .map(|d| d.ms_median)
        .collect();
    let dgi_range = (!dgi_ms.is_empty()).then(|| {
        [
            dgi_ms.iter().copied().fold(f64::INFINITY, f64::min),
            dgi_ms.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ]
    });
    rows.push(PaperRow {
        measure: "DGI generation, 3840×2160".into(),
        paper_ms: [2.0, 3.0],
        paper_ms_per_megapixel: [2.0 / paper_mp, 3.0 / paper_mp],
        paper_speedup: None,
        ours_ms: dgi_range,
        ours_ms_per_megapixel: dgi_range.map(|[a, b]| [a / mp, b / mp]),
        ours_speedup: None,
        ours_size: size,
        ours_device: match (&r.dgi.adapter, backend) {
            (Some(a), "gpu") => a.clone(),
            _ => format!("CPU twin (f64), {}", r.dgi.cpu),
        },
        note: format!(
            "exact metric, median per FOV, min–max over FOVs {:?}°{size_note}",
            r.config.fovs_deg
        ),
    });
    for (label, key, paper) in [
        ("full frame, 1 spp, Cornell box", "cornell", 460.0),
        ("full frame, 1 spp, city (~350k triangles)", "city", 750.0),
    ] {
        let row = r.trace.iter().find(|t| t.scene.contains(key));
        rows.push(PaperRow {
            measure: label.into(),
            paper_ms: same(paper),
            paper_ms_per_megapixel: same(paper / paper_mp),
            paper_speedup: None,
            ours_ms: row.map(|t| same(t.ms_per_frame_median)),
            ours_ms_per_megapixel: row.map(|t| same(t.ms_per_megasample)),
            ours_speedup: None,
            ours_size: size,
            ours_device: r.header.device.clone(),
            note: match row {
                Some(t) => format!(
                    "scene '{}' ({} triangles), median of {} frames{size_note}",
                    t.scene, t.triangles, r.config.trace_frames
                ),
                None => format!("not run: no '{key}' scene in this report"),
            },
        });
    }
    for (fov, paper, speedup) in [(10.0, 12.29, 37.43), (60.0, 188.0, 2.44)] {
        let row = r
            .guided
            .rows
            .iter()
            .find(|g| g.fov_deg == fov && g.scene == r.header.scene);
        rows.push(PaperRow {
            measure: format!("{fov}° FOV iteration, Cornell box"),
            paper_ms: same(paper),
            paper_ms_per_megapixel: same(paper / paper_mp),
            paper_speedup: Some(speedup),
            ours_ms: row.map(|g| same(g.ms_per_iteration)),
            ours_ms_per_megapixel: row.map(|g| same(g.ms_per_iteration / mp)),
            ours_speedup: row.map(|g| g.speedup),
            ours_size: size,
            ours_device: r.guided.device.clone(),
            note: match row {
                Some(g) => format!(
                    "scene '{}', schedule + trace, median of {} iterations, {:.2} % of the pixels per iteration; speed-up over our full frame on the same device{size_note}",
                    g.scene,
                    r.config.iterations,
                    100.0 * g.share_sampled
                ),
                None => format!("not run: {fov}° is not among the FOVs {:?}", r.config.fovs_deg),
            },
        });
    }
    rows
}

/// The issue's targets, judged only on a datacenter GPU at 3840×2160.
#[must_use]
pub fn target_rows(r: &AllReport, datacenter: Option<String>) -> Vec<TargetRow> {
    let size = r.config.size;
    let why_not = match (&datacenter, size == PAPER_SIZE) {
        (Some(_), true) => None,
        (None, _) => Some(format!(
            "device is not a datacenter GPU ({})",
            r.header.device
        )),
        (Some(_), false) => Some(format!("run at {}×{}, not 3840×2160", size[0], size[1])),
    };
    let judge = |value: Option<f64>, ok: &dyn Fn(f64) -> bool| match (&why_not, value) {
        (None, Some(v)) if v.is_finite() => {
            if ok(v) {
                TargetStatus::Met
            } else {
                TargetStatus::Missed
            }
        }
        _ => TargetStatus::NotMeasured,
    };
    let cv10 = r.convergence.iter().find(|c| c.fov_deg == 10.0);
    let (speedup, how) = match cv10 {
        Some(c) => match (c.speedup_to_target, c.extrapolated_speedup_to_target) {
            (Some(x), _) => (Some(x), "both curves reached the target".to_string()),
            (None, Some(x)) => (
                Some(x),
                "extrapolated (RMSE ∝ 1/√t) where a curve did not reach the target".to_string(),
            ),
            (None, None) => (None, "no time to target".to_string()),
        },
        None => (None, "10° not among the FOVs".to_string()),
    };
    let st10 = r.stages.iter().find(|s| s.fov_deg == 10.0);
    let iteration = st10.map(|s| s.target_iteration_ms);
    let reason = |s: &TargetStatus| match (s, &why_not) {
        (TargetStatus::NotMeasured, Some(w)) => format!("; not judged: {w}"),
        _ => String::new(),
    };
    let s1 = judge(speedup, &|v| v >= 30.0);
    let s2 = judge(iteration, &|v| v <= 8.0);
    vec![
        TargetRow {
            target: "guided reaches the ROI target RMSE (1 % of the reference mean) ≥ 30× sooner than full frame at 10° FOV".into(),
            measured: speedup,
            unit: "×".into(),
            status: s1,
            note: format!("full-frame ÷ guided time to target, {how}{}", reason(&s1)),
        },
        TargetRow {
            target: "3840×2160 guided iteration at 10° FOV incl. DGI-if-changed, scheduling, tracing and the fast filter ≤ 8 ms (≥ 120 iterations/s)".into(),
            measured: iteration,
            unit: "ms".into(),
            status: s2,
            note: format!(
                "the per-stage table's target iteration (the iteration with an ROI change) at {}×{}{}",
                size[0],
                size[1],
                reason(&s2)
            ),
        },
    ]
}

fn fmt_ttt(t: &TimeToTarget) -> String {
    if t.reached {
        format!("{:.1} ms (RMSE {:.4})", t.ms, t.rmse_roi)
    } else {
        format!(
            "not reached (closest: RMSE {:.4} at {:.1} ms; extrapolated {} ms)",
            t.rmse_roi,
            t.ms,
            t.extrapolated_ms.map_or("–".into(), |x| format!("{x:.0}"))
        )
    }
}

/// The report as Markdown: header, settings, each benchmark's own tables and the convergence
/// figures.
#[must_use]
pub fn markdown(r: &AllReport) -> String {
    let h = &r.header;
    let c = &r.config;
    let mut s = format!(
        "# raygun benchmark report\n\n- Command: `{}`\n- Commit: {}{}\n- Build: {}\n- Date: {} (UTC)\n- Device: {}\n- Adapter: {}\n- CPU: {}\n- Scene: {}; display: {}\n- Mode: {}\n- Settings: {}×{}, FOVs {:?}°, {} guided iterations, reference {} spp, curve point every {} iterations, {} trace frames{}, DGI reps {} GPU / {} CPU, filter reps {}, filter {:?} k_max {:.2} c {}, solver reps {}, per-stage iterations {}, seed {}\n\n",
        h.command,
        h.commit,
        if h.dirty {
            " (working tree modified)"
        } else {
            ""
        },
        h.profile,
        h.date,
        h.device,
        h.adapter.as_deref().unwrap_or("none (CPU twins)"),
        h.cpu,
        h.scene,
        h.display,
        if c.quick { "quick" } else { "full" },
        c.size[0],
        c.size[1],
        c.fovs_deg,
        c.iterations,
        c.reference_spp,
        c.sample_every,
        c.trace_frames,
        if c.city { " (plus builtin:city)" } else { "" },
        c.dgi_gpu_reps,
        c.dgi_cpu_reps,
        c.filter_reps,
        c.filter.kind,
        c.filter.k_max,
        c.filter.c,
        c.solver_reps,
        c.stage_iterations,
        c.seed,
    );
    s += &paper_markdown(&r.paper);
    s += "\n## Targets\n\n";
    s += &targets_markdown(&r.targets);
    s += "\n";
    s += "## DGI\n\n";
    s += &r.dgi.to_markdown();
    s += "\n\n## DGI metrics: time vs error\n\n![DGI metrics](dgi_metrics.png)\n\n";
    s += &dgi_metrics_markdown(&r.dgi);
    s += "\n## Closest-point solver\n\n";
    s += &solver::markdown(&r.solver);
    s += "\n\n## Full-frame path tracing\n\n";
    s += &trace::markdown(&r.trace, &h.device);
    s += "\n\n## Guided vs full frame (the paper's benchmark)\n\n![Figure 5](fig5.png)\n\n";
    s += &guided::markdown(&r.guided);
    s += "\n\n## Filter\n\n";
    s += &r.filter.to_markdown();
    s += &format!(
        "\n\n## Convergence\n\n![convergence](convergence.png)\n\nRMSE (linear RGB) against a converged reference ({} spp full frame) versus accumulated frame time (RMSE and read-backs excluded); filtered = the fast filter's CPU twin. Target: ROI RMSE ≤ {} % of the reference's mean in the ROI; where a curve did not reach it, the time is extrapolated with RMSE ∝ 1/√t through its last point (not measured).\n\n| FOV | ROI px | target RMSE | guided: time to target | full frame: time to target | speed-up to target | guided end ms | guided ROI RMSE at end | full-frame ROI RMSE at equal time (ms) | guided outside RMSE at end (unfiltered / filtered) | full-frame outside RMSE at equal time (unfiltered / filtered) |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
        c.reference_spp,
        100.0 * TARGET_REL_RMSE
    );
    for cv in &r.convergence {
        let (Some(g), Some(f)) = (cv.guided.last(), equal_time_point(cv)) else {
            continue;
        };
        s += &format!(
            "| {}° | {} | {:.4} | {} | {} | {} | {:.1} | {:.4} | {:.4} ({:.1}) | {:.4} / {:.4} | {:.4} / {:.4} |\n",
            cv.fov_deg,
            cv.roi_pixels,
            cv.target_rmse_roi,
            fmt_ttt(&cv.guided_time_to_target),
            fmt_ttt(&cv.full_time_to_target),
            match (cv.speedup_to_target, cv.extrapolated_speedup_to_target) {
                (Some(x), _) => format!("{x:.2}×"),
                (None, Some(x)) => format!("{x:.2}× (extrapolated)"),
                (None, None) => "–".into(),
            },
            g.ms,
            g.rmse_roi,
            cv.full_rmse_roi_at_guided_end,
            cv.full_ms_at_guided_end,
            g.rmse_outside,
            g.rmse_outside_filtered,
            f.rmse_outside,
            f.rmse_outside_filtered,
        );
    }
    s += "\n## Per-stage times per iteration\n\n";
    s += &stages::markdown(&r.stages, &h.device);
    s
}

fn fmt_range(v: [f64; 2], digits: usize) -> String {
    if v[0] == v[1] {
        format!("{:.*}", digits, v[0])
    } else {
        format!("{:.*}–{:.*}", digits, v[0], digits, v[1])
    }
}

/// The paper's table with ours beside it.
#[must_use]
pub fn paper_markdown(rows: &[PaperRow]) -> String {
    let mut s = String::from(
        "## The paper's table beside ours\n\nThe paper (Roth et al., ISVC 2015): HORNET, viewer 1 m in front of the wall centre, 3840×2160, GTX 980 with OptiX. Per megapixel = ms ÷ the image's megapixels (for a 1-spp full frame the paper's ms per megasample); where our size is not 3840×2160 it is the comparable figure, and nothing is scaled. Speed-up = full frame ÷ guided iteration on the same device.\n\n| measure | paper ms | paper ms/megapixel | paper speed-up | ours ms | ours ms/megapixel | ours speed-up | our size | our device | note |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let sp = |v: Option<f64>| v.map_or("–".into(), |v| format!("{v:.2}×"));
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {}×{} | {} | {} |\n",
            r.measure,
            fmt_range(r.paper_ms, 2),
            fmt_range(r.paper_ms_per_megapixel, 3),
            sp(r.paper_speedup),
            r.ours_ms.map_or("not run".into(), |v| fmt_range(v, 3)),
            r.ours_ms_per_megapixel
                .map_or("–".into(), |v| fmt_range(v, 3)),
            sp(r.ours_speedup),
            r.ours_size[0],
            r.ours_size[1],
            r.ours_device,
            r.note,
        );
    }
    s
}

/// The targets table.
#[must_use]
pub fn targets_markdown(rows: &[TargetRow]) -> String {
    let mut s = String::from("| target | measured | status | note |\n|---|---|---|---|\n");
    for t in rows {
        s += &format!(
            "| {} | {} | {} | {} |\n",
            t.target,
            t.measured
                .map_or("not run".into(), |v| format!("{v:.3} {}", t.unit)),
            match t.status {
                TargetStatus::Met => "**met**",
                TargetStatus::Missed => "**missed**",
                TargetStatus::NotMeasured => "not measured",
            },
            t.note
        );
    }
    s
}

/// The DGI metrics' time against their error (the plot's points as a table).
#[must_use]
pub fn dgi_metrics_markdown(r: &DgiBenchReport) -> String {
    let mut s = String::from(
        "Each cheaper metric's raw distance against the exact metric's (f64, canvas px) over the pixels the falloff reaches; time = median DGI time on each backend.\n\n| FOV | metric | backend | ms (median) | mean error px | max error px |\n|---|---|---|---|---|---|\n",
    );
    for d in &r.rows {
        s += &format!(
            "| {}° | {:?} | {} | {:.3} | {:.4} | {:.3} |\n",
            d.fov_deg, d.metric, d.backend, d.ms_median, d.err_mean_px, d.err_max_px
        );
    }
    s
}

/// DGI metrics as a PNG: time (x) against mean and max error (y, canvas px), one point per
/// metric, FOV and backend (filled: GPU, hollow: CPU), labelled with the FOV.
pub fn plot_dgi_metrics(r: &DgiBenchReport, path: &Path) -> Result<(), AllBenchError> {
    use crate::roi::dgi::Metric;
    use plotters::prelude::*;
    let err = |e: String| AllBenchError::Output {
        path: path.display().to_string(),
        reason: e,
    };
    let root = BitMapBackend::new(path, (1200, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
    let (left, right) = root.split_horizontally(600);
    let xmax = r.rows.iter().map(|d| d.ms_median).fold(0.0, f64::max) * 1.15 + 1e-9;
    type Pick = fn(&crate::bench::dgi::DgiBenchRow) -> f64;
    let panels: [(&DrawingArea<BitMapBackend, _>, &str, Pick); 2] = [
        (&left, "mean error (canvas px)", |d| d.err_mean_px),
        (&right, "max error (canvas px)", |d| d.err_max_px),
    ];
    for (area, label, pick) in panels {
        let ymax = r.rows.iter().map(pick).fold(0.0, f64::max) * 1.15 + 1e-3;
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("DGI metrics: time vs {label}; filled GPU, hollow CPU"),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..xmax, 0.0..ymax)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("DGI time (ms, median)")
            .y_desc(label)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for (metric, colour) in [
            (Metric::Exact, BLACK),
            (Metric::Ellipse, BLUE),
            (Metric::Angular, RED),
        ] {
            let pts: Vec<_> = r.rows.iter().filter(|d| d.metric == metric).collect();
            if pts.is_empty() {
                continue;
            }
            chart
                .draw_series(pts.iter().map(|d| {
                    let style = if d.backend == "gpu" {
                        colour.filled()
                    } else {
                        colour.stroke_width(2)
                    };
                    Circle::new((d.ms_median, pick(d)), 5, style)
                }))
                .map_err(|e| err(e.to_string()))?
                .label(format!("{metric:?}"))
                .legend(move |(x, y)| Circle::new((x + 10, y), 5, colour.filled()));
            chart
                .draw_series(pts.iter().map(|d| {
                    Text::new(
                        format!("{}°", d.fov_deg),
                        (d.ms_median, pick(d)),
                        ("sans-serif", 12).into_font().color(&colour),
                    )
                }))
                .map_err(|e| err(e.to_string()))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperMiddle)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
    }
    root.present().map_err(|e| err(e.to_string()))?;
    Ok(())
}

fn equal_time_point(cv: &Convergence) -> Option<&CurvePoint> {
    let end = cv.guided.last()?.ms;
    cv.full_frame
        .iter()
        .rev()
        .find(|p| p.ms <= end)
        .or(cv.full_frame.first())
}

/// The convergence curves as a PNG: one panel per FOV, RMSE (log scale) against time, guided
/// and full frame, inside and outside the ROI, unfiltered (solid) and filtered (dashed).
pub fn plot_convergence(r: &AllReport, path: &Path) -> Result<(), AllBenchError> {
    use plotters::prelude::*;
    let err = |e: String| AllBenchError::Output {
        path: path.display().to_string(),
        reason: e,
    };
    let n = r.convergence.len().max(1);
    let root = BitMapBackend::new(path, (600 * n as u32, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
    let panels = root.split_evenly((1, n));
    for (area, cv) in panels.iter().zip(&r.convergence) {
        let all = cv.guided.iter().chain(&cv.full_frame);
        let xmax = all.clone().map(|p| p.ms).fold(0.0, f64::max) * 1.05 + 1e-9;
        let ys = all
            .flat_map(|p| {
                [
                    p.rmse_roi,
                    p.rmse_outside,
                    p.rmse_roi_filtered,
                    p.rmse_outside_filtered,
                ]
            })
            .chain([cv.target_rmse_roi])
            .filter(|v| v.is_finite() && *v > 0.0);
        let (ymin, ymax) = ys.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        let (ymin, ymax) = if ymin.is_finite() {
            (ymin * 0.8, ymax * 1.25)
        } else {
            (1e-3, 1.0)
        };
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("Convergence, FOV {}°", cv.fov_deg),
                ("sans-serif", 22),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..xmax, (ymin..ymax).log_scale())
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("accumulated frame time (ms)")
            .y_desc("RMSE vs reference")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        type Pick = fn(&CurvePoint) -> f64;
        let lines: [(&str, &[CurvePoint], Pick, RGBColor, bool); 8] = [
            ("guided ROI", &cv.guided, |p| p.rmse_roi, RED, false),
            (
                "guided ROI filtered",
                &cv.guided,
                |p| p.rmse_roi_filtered,
                RED,
                true,
            ),
            (
                "guided outside",
                &cv.guided,
                |p| p.rmse_outside,
                MAGENTA,
                false,
            ),
            (
                "guided outside filtered",
                &cv.guided,
                |p| p.rmse_outside_filtered,
                MAGENTA,
                true,
            ),
            ("full ROI", &cv.full_frame, |p| p.rmse_roi, BLUE, false),
            (
                "full ROI filtered",
                &cv.full_frame,
                |p| p.rmse_roi_filtered,
                BLUE,
                true,
            ),
            (
                "full outside",
                &cv.full_frame,
                |p| p.rmse_outside,
                CYAN,
                false,
            ),
            (
                "full outside filtered",
                &cv.full_frame,
                |p| p.rmse_outside_filtered,
                CYAN,
                true,
            ),
        ];
        for (label, pts, pick, colour, dashed) in lines {
            let data: Vec<(f64, f64)> = pts
                .iter()
                .map(|p| (p.ms, pick(p)))
                .filter(|p| p.1.is_finite() && p.1 > 0.0)
                .collect();
            if data.is_empty() {
                continue;
            }
            let style = colour.stroke_width(2);
            if dashed {
                chart
                    .draw_series(DashedLineSeries::new(data, 6, 4, style))
                    .map_err(|e| err(e.to_string()))?
                    .label(format!("{label} (dashed)"))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            } else {
                chart
                    .draw_series(LineSeries::new(data, style))
                    .map_err(|e| err(e.to_string()))?
                    .label(label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            }
        }
        chart
            .draw_series(LineSeries::new(
                [(0.0, cv.target_rmse_roi), (xmax, cv.target_rmse_roi)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| err(e.to_string()))?
            .label(format!("target ({} %)", 100.0 * TARGET_REL_RMSE))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(|e| err(e.to_string()))?;
    }
    root.present().map_err(|e| err(e.to_string()))?;
    Ok(())
}

impl From<crate::output::FileError> for AllBenchError {
    fn from(e: crate::output::FileError) -> Self {
        Self::Output {
            path: String::new(),
            reason: e.to_string(),
        }
    }
}

/// Writes `report.md`, `report.json`, `fig5.png`, `dgi_metrics.png` and `convergence.png` into
/// `dir` (created).
pub fn write(r: &AllReport, dir: &Path) -> Result<(), AllBenchError> {
    let io = |p: &Path| {
        let path = p.display().to_string();
        move |source| AllBenchError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let file = |e: crate::output::FileError| AllBenchError::Output {
        path: dir.display().to_string(),
        reason: e.to_string(),
    };
    let md = dir.join("report.md");
    crate::output::write_bytes(&md, markdown(r).as_bytes()).map_err(file)?;
    let json = dir.join("report.json");
    let text = serde_json::to_string_pretty(r).map_err(|e| AllBenchError::Output {
        path: json.display().to_string(),
        reason: e.to_string(),
    })?;
    crate::output::write_bytes(&json, text.as_bytes()).map_err(file)?;
    let plot = |name: &str, draw: &dyn Fn(&Path) -> Result<(), AllBenchError>| {
        let path = dir.join(name);
        crate::output::replace_with(&path, |tmp| draw(tmp))
    };
    plot("fig5.png", &|p| Ok(guided::plot(&r.guided, p)?))?;
    plot("dgi_metrics.png", &|p| plot_dgi_metrics(&r.dgi, p))?;
    plot("convergence.png", &|p| plot_convergence(r, p))
}
