//! `raygun bench all`: every benchmark in one run (issue 8) — DGI, full-frame tracing, the
//! paper's guided benchmark and the filter — plus convergence curves: RMSE against a converged
//! reference inside and outside the ROI versus accumulated frame time, guided vs full frame,
//! unfiltered vs the fast filter. Writes `report.md`, `report.json` (the same figures),
//! `fig5.png` and `convergence.png`.

use std::path::Path;

use glam::{DVec3, Vec3};
use serde::Serialize;

use crate::bench::dgi::{self, DgiBenchConfig, DgiBenchReport};
use crate::bench::filter::{self, FilterBenchConfig, FilterBenchReport};
use crate::bench::guided::{self, GuidedBenchConfig, GuidedBenchReport};
use crate::bench::trace::{self, TraceBenchConfig, TraceBenchRow};
use crate::display::DisplayModel;
use crate::filter::{FilterKind, FilterParams};
use crate::frame::{GuideConfig, GuidedRenderer};
use crate::gpu::Backend;
use crate::roi::cone::Cone;
use crate::roi::dgi::{Falloff, Roi, Surface};
use crate::scene::Scene;
use crate::trace::accum::Accumulation;
use crate::trace::camera::RenderCamera;
use crate::trace::cpu::TraceSettings;
use crate::trace::render::Renderer;

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
                filter,
                seed: 1,
            }
        }
    }
}

/// Who ran it where.
#[derive(Clone, Debug, Serialize)]
pub struct Header {
    pub device: String,
    pub commit: String,
    /// UTC, YYYY-MM-DD.
    pub date: String,
    pub scene: String,
    pub display: String,
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
        let mut r = Renderer::new(backend, scene, settings(cfg.seed ^ 0xc0_5eed))?;
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
        let roi = Roi::Cone(Cone::from_pose(
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::NEG_Z,
            DVec3::Y,
            fov,
            fov,
        )?);
        let mut g = GuidedRenderer::new(
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
        let mut full = Renderer::new(backend, scene, settings(cfg.seed.wrapping_add(12)))?;
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

/// Runs every benchmark on `scene` (named `name`) and the convergence curves at the first and
/// last of `cfg.fovs_deg`.
pub fn run(
    backend: &Backend,
    display: &DisplayModel,
    display_name: &str,
    name: &str,
    scene: &Scene,
    cfg: &AllConfig,
    mut progress: impl FnMut(&str),
) -> Result<AllReport, AllBenchError> {
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
    let trace = trace::run(
        backend,
        &scenes,
        &TraceBenchConfig {
            size: cfg.size,
            frames: cfg.trace_frames.max(1),
            seed: cfg.seed,
            ..TraceBenchConfig::default()
        },
        &mut progress,
    )?;
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
    let fovs = match (cfg.fovs_deg.first(), cfg.fovs_deg.last()) {
        (Some(&a), Some(&b)) if a != b => vec![a, b],
        (Some(&a), _) => vec![a],
        _ => Vec::new(),
    };
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
    Ok(AllReport {
        header: Header {
            device: backend.describe(),
            commit: commit(),
            date: utc_date(),
            scene: name.to_string(),
            display: display_name.to_string(),
        },
        config: cfg.clone(),
        dgi,
        trace,
        guided,
        filter,
        convergence,
    })
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
        "# raygun benchmark report\n\n- Device: {}\n- Commit: {}\n- Date: {}\n- Scene: {}; display: {}\n- Mode: {}\n- Settings: {}×{}, FOVs {:?}°, {} guided iterations, reference {} spp, curve point every {} iterations, {} trace frames, DGI reps {} GPU / {} CPU, filter reps {}, filter {:?} k_max {:.2} c {}, seed {}\n\n",
        h.device,
        h.commit,
        h.date,
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
        c.dgi_gpu_reps,
        c.dgi_cpu_reps,
        c.filter_reps,
        c.filter.kind,
        c.filter.k_max,
        c.filter.c,
        c.seed,
    );
    s += "## DGI\n\n";
    s += &r.dgi.to_markdown();
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
    s
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

/// Writes `report.md`, `report.json`, `fig5.png` and `convergence.png` into `dir` (created).
pub fn write(r: &AllReport, dir: &Path) -> Result<(), AllBenchError> {
    let io = |p: &Path| {
        let path = p.display().to_string();
        move |source| AllBenchError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let md = dir.join("report.md");
    std::fs::write(&md, markdown(r)).map_err(io(&md))?;
    let json = dir.join("report.json");
    let text = serde_json::to_string_pretty(r).map_err(|e| AllBenchError::Output {
        path: json.display().to_string(),
        reason: e.to_string(),
    })?;
    std::fs::write(&json, text).map_err(io(&json))?;
    guided::plot(&r.guided, &dir.join("fig5.png"))?;
    plot_convergence(r, &dir.join("convergence.png"))
}
