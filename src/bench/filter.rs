//! `raygun bench filter`: time of the exact and fast filters, and the error of each variant
//! against a converged reference inside and outside the ROI, in the paper's setup (HORNET,
//! viewer 1 m in front of the wall centre pointing at it, square cones).
//!
//! Until the guided renderer exists the renders are synthetic ([`FilterBenchInput::synthetic`]):
//! a known reference image sampled with the paper's schedule, p = 1 − d, for N rounds with
//! path-tracer-like noise. [`FilterBenchInput`] is the seam: a real guided render and its
//! converged reference go through the same error table.

use std::time::Instant;

use glam::{DVec3, Vec3};
use serde::Serialize;

use crate::filter::gpu::{FilterGpuError, FilterKernels, UploadedInputs};
use crate::filter::{self, Blend, Filter, FilterInputError, FilterKind, FilterParams, synth};
use crate::gpu::{Backend, GpuContext, PassTimer};
use crate::roi::dgi::{Falloff, Surface};
use crate::trace::accum::{Accumulation, luminance};

/// One render to judge: what the filter sees and what it should converge to.
#[derive(Clone, Debug)]
pub struct FilterBenchInput {
    /// Where it came from (e.g. "synthetic edges, 16 rounds").
    pub label: String,
    /// The converged image, row-major linear RGB.
    pub reference: Vec<Vec3>,
    pub accumulation: Accumulation,
    pub dgi: Vec<f32>,
    /// Pixels inside the ROI (d = 0).
    pub roi_mask: Vec<bool>,
}

impl FilterBenchInput {
    /// A synthetic render: `pattern` sampled with p = 1 − d for `rounds` rounds (the paper's
    /// schedule, p_min = 0), one exponential-noise sample per scheduled pixel and round.
    #[must_use]
    pub fn synthetic(
        pattern: synth::Pattern,
        dgi: Vec<f32>,
        width: u32,
        height: u32,
        rounds: u32,
        seed: u32,
    ) -> Self {
        let reference = synth::reference(pattern, width, height);
        let accumulation =
            synth::accumulate(&reference, width, height, |i| 1.0 - dgi[i], rounds, seed);
        let roi_mask = dgi.iter().map(|&d| d == 0.0).collect();
        Self {
            label: format!("synthetic {pattern:?}, {rounds} rounds of p = 1 − d"),
            reference,
            accumulation,
            dgi,
            roi_mask,
        }
    }
}

/// What to measure.
#[derive(Clone, Debug, Serialize)]
pub struct FilterBenchConfig {
    pub size: [u32; 2],
    pub fovs_deg: Vec<f64>,
    /// k_max values timed.
    pub k_maxes: Vec<f32>,
    /// Repetitions per timing (median reported).
    pub reps: u32,
    /// Rounds of the synthetic render (equal time for every variant: they share it).
    pub rounds: u32,
    pub pattern: synth::Pattern,
    /// Filter settings of the error table (its k_max, c and τ; kind and blend vary per row).
    pub error_params: FilterParams,
    pub seed: u32,
}

impl Default for FilterBenchConfig {
    fn default() -> Self {
        Self {
            size: [3840, 2160],
            fovs_deg: vec![10.0, 60.0],
            k_maxes: vec![8.0, 16.0, 32.0],
            reps: 20,
            rounds: 16,
            pattern: synth::Pattern::Edges,
            error_params: FilterParams::default(),
            seed: 1,
        }
    }
}

/// One timing.
#[derive(Clone, Debug, Serialize)]
pub struct TimingRow {
    pub fov_deg: f64,
    pub kind: FilterKind,
    pub k_max: f32,
    /// "gpu" or "cpu".
    pub backend: &'static str,
    pub ms_median: f64,
    pub ms_min: f64,
    /// Whether the GPU figures come from timestamp queries (else submit-to-done wall time).
    pub gpu_timestamps: bool,
}

/// One variant's error against the reference.
#[derive(Clone, Debug, Serialize)]
pub struct ErrorRow {
    pub fov_deg: f64,
    /// "unfiltered", "paper (exact)", "fast", "variance (fast)".
    pub variant: &'static str,
    pub rmse_roi: f64,
    pub rmse_outside: f64,
    /// Mean luminance of the result over the region against the reference's, relative
    /// (signed: negative is too dark).
    pub brightness_err_roi: f64,
    pub brightness_err_outside: f64,
    /// The falloff band (outside the ROI, d < 1): the pixels the schedule samples at all.
    pub rmse_band: f64,
    pub brightness_err_band: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct FilterBenchReport {
    pub display: String,
    pub adapter: Option<String>,
    pub cpu: String,
    pub input: String,
    pub config: FilterBenchConfig,
    /// Per FOV: the shares of pixels with at least one sample, inside the ROI, in the band.
    pub coverage: Vec<(f64, f64, f64, f64)>,
    pub timings: Vec<TimingRow>,
    pub errors: Vec<ErrorRow>,
}

#[derive(Debug, thiserror::Error)]
pub enum FilterBenchError {
    #[error(transparent)]
    Gpu(#[from] FilterGpuError),
    #[error(transparent)]
    Input(#[from] FilterInputError),
    #[error(transparent)]
    Guide(#[from] crate::roi::dgi::GuideError),
    #[error(transparent)]
    Cone(#[from] crate::roi::cone::ConeError),
    /// Making a rendered input failed.
    #[error("rendering the filter's input: {0}")]
    Render(String),
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The paper's DGI for a square cone of `fov` degrees (exact metric, default falloff).
pub fn paper_dgi(
    surface: &Surface,
    width: u32,
    height: u32,
    fov: f64,
) -> Result<Vec<f32>, FilterBenchError> {
    let roi = super::paper::roi(fov)?;
    Ok(super::paper::dgi(
        surface,
        width,
        height,
        &roi,
        Falloff::default(),
    )?)
}

/// Times `reps` runs of the filter on the GPU (one timestamp pair around all its dispatches).
fn time_gpu(
    ctx: &GpuContext,
    kernels: &FilterKernels,
    params: &FilterParams,
    uploaded: &UploadedInputs,
    reps: u32,
) -> Result<(Vec<f64>, bool), FilterBenchError> {
    let run = kernels.prepare(ctx, params, &uploaded.inputs())?;
    let submit = |timer: Option<(&PassTimer, u32)>| {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        run.record(&mut enc, timer);
        if let Some((t, _)) = timer {
            t.resolve(&mut enc);
        }
        ctx.queue.submit([enc.finish()]);
    };
    // Warm-up: the first dispatch pays for pipeline compilation on some drivers.
    submit(None);
    ctx.wait().map_err(FilterGpuError::from)?;
    let mut times = Vec::new();
    let timer = PassTimer::new(ctx, 1);
    for _ in 0..reps {
        let t = Instant::now();
        submit(timer.as_ref().map(|t| (t, 0)));
        ctx.wait().map_err(FilterGpuError::from)?;
        let wall = t.elapsed().as_secs_f64() * 1e3;
        times.push(match &timer {
            Some(t) => t.read_ms(ctx).map_err(FilterGpuError::from)?[0],
            None => wall,
        });
    }
    Ok((times, timer.is_some()))
}

/// RMSE (over RGB) and relative mean-luminance error of `out` against `reference` over the
/// pixels `region(i)` selects.
fn region_error(
    out: &[DVec3],
    input: &FilterBenchInput,
    region: impl Fn(usize) -> bool,
) -> (f64, f64) {
    let (mut se, mut lo, mut lr, mut n) = (0.0, 0.0, 0.0, 0usize);
    for (i, (o, r)) in out.iter().zip(&input.reference).enumerate() {
        if !region(i) {
            continue;
        }
        let r = r.as_dvec3();
        se += (*o - r).length_squared() / 3.0;
        lo += f64::from(luminance(o.as_vec3()));
        lr += f64::from(luminance(r.as_vec3()));
        n += 1;
    }
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    ((se / n as f64).sqrt(), (lo - lr) / lr)
}

/// The error table for one input (the four variants: exact and fast, each with the count and the variance blend).
pub fn error_rows(
    filter_stage: &Filter,
    base: &FilterParams,
    fov_deg: f64,
    input: &FilterBenchInput,
) -> Result<Vec<ErrorRow>, FilterBenchError> {
    let variants: [(&'static str, FilterKind, Blend); 4] = [
        ("unfiltered", FilterKind::Off, Blend::Count),
        ("paper (exact)", FilterKind::Exact, Blend::Count),
        ("fast", FilterKind::Fast, Blend::Count),
        ("variance (fast)", FilterKind::Fast, Blend::Variance),
    ];
    let mut rows = Vec::new();
    for (variant, kind, blend) in variants {
        let params = FilterParams {
            kind,
            blend,
            ..*base
        };
        let out = filter_stage.apply(&params, &input.accumulation, &input.dgi)?;
        let roi = |i: usize| input.roi_mask[i];
        let (rmse_roi, brightness_err_roi) = region_error(&out, input, roi);
        let (rmse_outside, brightness_err_outside) = region_error(&out, input, |i| !roi(i));
        let (rmse_band, brightness_err_band) =
            region_error(&out, input, |i| !roi(i) && input.dgi[i] < 1.0);
        rows.push(ErrorRow {
            fov_deg,
            variant,
            rmse_roi,
            rmse_outside,
            brightness_err_roi,
            brightness_err_outside,
            rmse_band,
            brightness_err_band,
        });
    }
    Ok(rows)
}

/// Runs the benchmark; `progress` is told each step as it starts.
pub fn run(
    surface: &Surface,
    display_name: &str,
    backend: &Backend,
    config: &FilterBenchConfig,
    progress: impl FnMut(&str),
) -> Result<FilterBenchReport, FilterBenchError> {
    run_with_inputs(
        surface,
        display_name,
        backend,
        config,
        progress,
        |_fov, dgi| {
            let [w, h] = config.size;
            Ok(FilterBenchInput::synthetic(
                config.pattern,
                dgi,
                w,
                h,
                config.rounds,
                config.seed,
            ))
        },
    )
}

/// [`run`] with the renders to judge made by `input(fov, paper_dgi)` — e.g. guided renders of
/// a scene (`raygun bench filter --scene …`).
pub fn run_with_inputs(
    surface: &Surface,
    display_name: &str,
    backend: &Backend,
    config: &FilterBenchConfig,
    mut progress: impl FnMut(&str),
    mut input: impl FnMut(f64, Vec<f32>) -> Result<FilterBenchInput, FilterBenchError>,
) -> Result<FilterBenchReport, FilterBenchError> {
    config
        .error_params
        .validate()
        .map_err(FilterInputError::from)?;
    let [w, h] = config.size;
    let filter_stage = Filter::new(backend);
    let mut report = FilterBenchReport {
        display: display_name.to_owned(),
        adapter: backend.adapter(),
        cpu: super::cpu_threads(),
        input: String::new(),
        config: config.clone(),
        coverage: Vec::new(),
        timings: Vec::new(),
        errors: Vec::new(),
    };
    for &fov in &config.fovs_deg {
        progress(&format!("{fov}°: DGI and the render to filter"));
        let dgi = paper_dgi(surface, w, h, fov)?;
        let input = input(fov, dgi)?;
        report.input.clone_from(&input.label);
        let n = input.dgi.len() as f64;
        let sampled = input.accumulation.count.iter().filter(|&&c| c > 0).count() as f64;
        let roi = input.roi_mask.iter().filter(|&&m| m).count() as f64;
        let band = (0..input.dgi.len())
            .filter(|&i| !input.roi_mask[i] && input.dgi[i] < 1.0)
            .count() as f64;
        report.coverage.push((fov, sampled / n, roi / n, band / n));
        let uploaded = match backend {
            Backend::Gpu(ctx) => Some(
                UploadedInputs::new(ctx, &input.accumulation, &input.dgi)
                    .map_err(FilterGpuError::from)?,
            ),
            Backend::Cpu => None,
        };
        for &k_max in &config.k_maxes {
            for kind in [FilterKind::Exact, FilterKind::Fast] {
                progress(&format!("{fov}°: time {kind:?} k_max {k_max}"));
                let params = FilterParams {
                    kind,
                    k_max,
                    ..config.error_params
                };
                let (times, stamped, name) = match (&filter_stage, &uploaded) {
                    (Filter::Gpu { ctx, kernels }, Some(up)) => {
                        let (t, s) = time_gpu(ctx, kernels, &params, up, config.reps.max(1))?;
                        (t, s, "gpu")
                    }
                    _ => {
                        let mut t = Vec::new();
                        for _ in 0..config.reps.clamp(1, 3) {
                            let start = Instant::now();
                            let out = filter::filter_cpu(&params, &input.accumulation, &input.dgi)?;
                            t.push(start.elapsed().as_secs_f64() * 1e3);
                            std::hint::black_box(out);
                        }
                        (t, false, "cpu")
                    }
                };
                report.timings.push(TimingRow {
                    fov_deg: fov,
                    kind,
                    k_max,
                    backend: name,
                    ms_median: median(times.clone()),
                    ms_min: times.iter().copied().fold(f64::INFINITY, f64::min),
                    gpu_timestamps: stamped,
                });
            }
        }
        progress(&format!("{fov}°: error table"));
        report.errors.extend(error_rows(
            &filter_stage,
            &config.error_params,
            fov,
            &input,
        )?);
    }
    Ok(report)
}

impl FilterBenchReport {
    /// The tables as Markdown.
    #[must_use]
    pub fn to_markdown(&self) -> String {
        let c = &self.config;
        let mut s = format!(
            "Filter benchmark — display {}, {}×{}; GPU: {}; CPU: {}\n\n",
            self.display,
            c.size[0],
            c.size[1],
            self.adapter.as_deref().unwrap_or("none (CPU twins)"),
            self.cpu
        );
        s.push_str("| FOV | filter | k_max | backend | ms (median) | ms (min) |\n");
        s.push_str("|---|---|---|---|---|---|\n");
        for r in &self.timings {
            s.push_str(&format!(
                "| {}° | {:?} | {} | {}{} | {:.3} | {:.3} |\n",
                r.fov_deg,
                r.kind,
                r.k_max,
                r.backend,
                if r.gpu_timestamps {
                    " (timestamps)"
                } else {
                    ""
                },
                r.ms_median,
                r.ms_min
            ));
        }
        s.push_str(&format!(
            "\nError against the reference ({}), k_max {}, c {}, τ {:e}:\n\n",
            self.input, c.error_params.k_max, c.error_params.c, c.error_params.variance_threshold
        ));
        for (fov, sampled, roi, band) in &self.coverage {
            s.push_str(&format!(
                "- {fov}°: {:.1} % of pixels sampled at least once, {:.1} % inside the ROI, \
                 {:.1} % in the band\n",
                100.0 * sampled,
                100.0 * roi,
                100.0 * band
            ));
        }
        s.push_str(
            "\nOutside = every pixel outside the ROI; band = outside the ROI with d < 1 (p > 0: \
             the pixels the paper's schedule samples at all).\n\n\
             | FOV | variant | RMSE in ROI | RMSE outside | RMSE band | brightness err in ROI | \
             brightness err outside | brightness err band |\n",
        );
        s.push_str("|---|---|---|---|---|---|---|---|\n");
        // A region with no pixels at this image size (a tiny ROI) has no error to report.
        let rmse = |v: f64| {
            if v.is_nan() {
                "– (no pixels)".to_string()
            } else {
                format!("{v:.4}")
            }
        };
        let pct = |v: f64| {
            if v.is_nan() {
                "– (no pixels)".to_string()
            } else {
                format!("{:+.2} %", 100.0 * v)
            }
        };
        for r in &self.errors {
            s.push_str(&format!(
                "| {}° | {} | {} | {} | {} | {} | {} | {} |\n",
                r.fov_deg,
                r.variant,
                rmse(r.rmse_roi),
                rmse(r.rmse_outside),
                rmse(r.rmse_band),
                pct(r.brightness_err_roi),
                pct(r.brightness_err_outside),
                pct(r.brightness_err_band)
            ));
        }
        s
    }
}
