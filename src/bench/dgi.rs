//! `raygun bench dgi`: DGI time per metric and backend, and each cheaper metric's error against
//! the exact one, in the paper's setup (viewer 1 m in front of the wall centre, pointing at it).

use std::time::Instant;

use serde::Serialize;

use crate::gpu::{Backend, GpuContext, GpuError, PassTimer};
use crate::roi::dgi::{
    DgiParams, Falloff, Guide, GuideError, Metric, Surface, compute_cpu, roi_radius_m,
};
use crate::roi::gpu::DgiKernel;

/// What to measure.
#[derive(Clone, Debug, Serialize)]
pub struct DgiBenchConfig {
    pub size: [u32; 2],
    pub fovs_deg: Vec<f64>,
    /// Repetitions per GPU measurement (the median is reported).
    pub gpu_reps: u32,
    /// Repetitions per CPU measurement.
    pub cpu_reps: u32,
    /// Viewer position and pointing direction.
    pub origin: [f64; 3],
    pub dir: [f64; 3],
    pub falloff: Falloff,
}

impl Default for DgiBenchConfig {
    fn default() -> Self {
        Self {
            size: [3840, 2160],
            fovs_deg: vec![10.0, 30.0, 60.0],
            gpu_reps: 50,
            cpu_reps: 3,
            origin: [0.0, 0.0, 1.0],
            dir: [0.0, 0.0, -1.0],
            falloff: Falloff::default(),
        }
    }
}

/// One measured configuration.
#[derive(Clone, Debug, Serialize)]
pub struct DgiBenchRow {
    pub fov_deg: f64,
    pub metric: Metric,
    /// "gpu" or "cpu".
    pub backend: &'static str,
    /// Median time of one DGI (GPU: kernel time from timestamp queries where available, else
    /// submit-to-done wall time).
    pub ms_median: f64,
    pub ms_min: f64,
    /// Whether `ms_*` came from GPU timestamps.
    pub gpu_timestamps: bool,
    /// CPU time to build the guide (once per ROI change, before either backend runs).
    pub guide_ms: f64,
    /// Share of pixels that p = 1 − d would sample per iteration.
    pub share_sampled: f64,
    /// Error of this metric's raw distance against the exact metric's (f64, canvas px), over
    /// the pixels the falloff reaches (exact d_raw < L); 0 for the exact metric itself.
    pub err_max_px: f64,
    pub err_mean_px: f64,
    /// This backend's result against the CPU twin's (normalised d), max abs difference.
    pub backend_max_abs_d: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct DgiBenchReport {
    pub display: String,
    pub adapter: Option<String>,
    pub cpu: String,
    pub config: DgiBenchConfig,
    pub rows: Vec<DgiBenchRow>,
}

#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Guide(#[from] GuideError),
    #[error(transparent)]
    Cone(#[from] crate::roi::cone::ConeError),
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Times `reps` dispatches of the prepared DGI (GPU timestamps where available).
fn time_gpu(
    ctx: &GpuContext,
    kernel: &DgiKernel,
    surface: &Surface,
    guide: &Guide,
    params: &DgiParams,
    reps: u32,
) -> Result<(Vec<f64>, bool), BenchError> {
    let run = kernel.prepare(ctx, surface, guide, params)?;
    // Warm-up: the first dispatch pays for pipeline compilation on some drivers.
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    run.record(&mut enc, None);
    ctx.queue.submit([enc.finish()]);
    ctx.wait()?;
    if let Some(timer) = PassTimer::new(ctx, reps) {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        for i in 0..reps {
            run.record(&mut enc, Some((&timer, i)));
        }
        timer.resolve(&mut enc);
        ctx.queue.submit([enc.finish()]);
        return Ok((timer.read_ms(ctx)?, true));
    }
    let mut times = Vec::new();
    for _ in 0..reps {
        let t = Instant::now();
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        run.record(&mut enc, None);
        ctx.queue.submit([enc.finish()]);
        ctx.wait()?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    Ok((times, false))
}

/// Runs the benchmark; `progress` is told each configuration as it starts.
pub fn run(
    surface: &Surface,
    display_name: &str,
    backend: &Backend,
    config: &DgiBenchConfig,
    mut progress: impl FnMut(&str),
) -> Result<DgiBenchReport, BenchError> {
    let [w, h] = config.size;
    let kernel = match backend {
        Backend::Gpu(ctx) => Some((ctx.as_ref(), DgiKernel::new(ctx))),
        Backend::Cpu => None,
    };
    let mut rows = Vec::new();
    for &fov in &config.fovs_deg {
        let roi = super::paper::roi_from(config.origin, config.dir, fov)?;
        let length_px = config
            .falloff
            .length_px(roi_radius_m(surface, &roi), surface.pitch_m);
        let norm = DgiParams {
            width: w,
            height: h,
            falloff_px: Some(length_px),
        };
        let raw = DgiParams {
            falloff_px: None,
            ..norm
        };
        // The exact metric's raw distances (f64 twin) are the reference for the others.
        let exact_guide = Guide::new(surface, &roi, Metric::Exact)?;
        let exact_raw = compute_cpu(surface, &exact_guide, &raw);
        for metric in [Metric::Exact, Metric::Ellipse, Metric::Angular] {
            progress(&format!("{fov}° {metric:?}"));
            let t = Instant::now();
            let guide = Guide::new(surface, &roi, metric)?;
            let guide_ms = t.elapsed().as_secs_f64() * 1e3;
            let metric_raw = if metric == Metric::Exact {
                exact_raw.clone()
            } else {
                compute_cpu(surface, &guide, &raw)
            };
            let (mut err_max, mut err_sum, mut n) = (0f64, 0f64, 0usize);
            for (e, m) in exact_raw.iter().zip(&metric_raw) {
                if f64::from(*e) < length_px {
                    let err = (f64::from(*e) - f64::from(*m)).abs();
                    err_max = err_max.max(err);
                    err_sum += err;
                    n += 1;
                }
            }
            let err_mean = if n > 0 { err_sum / n as f64 } else { 0.0 };
            // CPU timing (and the normalised reference for the GPU comparison).
            let mut cpu_times = Vec::new();
            let mut cpu_d = Vec::new();
            for _ in 0..config.cpu_reps.max(1) {
                let t = Instant::now();
                cpu_d = compute_cpu(surface, &guide, &norm);
                cpu_times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            let share = cpu_d.iter().map(|&d| 1.0 - f64::from(d)).sum::<f64>() / cpu_d.len() as f64;
            rows.push(DgiBenchRow {
                fov_deg: fov,
                metric,
                backend: "cpu",
                ms_median: median(cpu_times.clone()),
                ms_min: cpu_times.iter().copied().fold(f64::INFINITY, f64::min),
                gpu_timestamps: false,
                guide_ms,
                share_sampled: share,
                err_max_px: err_max,
                err_mean_px: err_mean,
                backend_max_abs_d: 0.0,
            });
            if let Some((ctx, kernel)) = &kernel {
                let gpu_d = kernel.compute(ctx, surface, &guide, &norm)?;
                let diff = gpu_d
                    .iter()
                    .zip(&cpu_d)
                    .map(|(g, c)| (f64::from(*g) - f64::from(*c)).abs())
                    .fold(0.0, f64::max);
                let (times, stamped) =
                    time_gpu(ctx, kernel, surface, &guide, &norm, config.gpu_reps)?;
                rows.push(DgiBenchRow {
                    backend: "gpu",
                    ms_median: median(times.clone()),
                    ms_min: times.iter().copied().fold(f64::INFINITY, f64::min),
                    gpu_timestamps: stamped,
                    backend_max_abs_d: diff,
                    ..rows.last().expect("CPU row pushed above").clone()
                });
            }
        }
    }
    Ok(DgiBenchReport {
        display: display_name.to_owned(),
        adapter: backend.adapter(),
        cpu: super::cpu_threads(),
        config: config.clone(),
        rows,
    })
}

impl DgiBenchReport {
    /// The table as Markdown.
    #[must_use]
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "DGI benchmark — display {}, {}×{}; GPU: {}; CPU: {}\n\n",
            self.display,
            self.config.size[0],
            self.config.size[1],
            self.adapter.as_deref().unwrap_or("none"),
            self.cpu
        );
        s.push_str(
            "| FOV | metric | backend | ms (median) | ms (min) | guide ms | share sampled | err max px | err mean px | max difference in d from the CPU twin |\n",
        );
        s.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
        for r in &self.rows {
            s.push_str(&format!(
                "| {}° | {} | {}{} | {:.3} | {:.3} | {:.3} | {:.2} % | {:.3} | {:.4} | {} |\n",
                r.fov_deg,
                r.metric.name(),
                r.backend,
                if r.gpu_timestamps {
                    " (timestamps)"
                } else {
                    ""
                },
                r.ms_median,
                r.ms_min,
                r.guide_ms,
                100.0 * r.share_sampled,
                r.err_max_px,
                r.err_mean_px,
                // The CPU twin is the reference itself.
                if r.backend == "cpu" {
                    "—".to_owned()
                } else {
                    format!("{:.1e}", r.backend_max_abs_d)
                }
            ));
        }
        s
    }
}
