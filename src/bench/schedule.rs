//! `raygun bench schedule`: the time of one scheduling iteration (Bernoulli mask, compaction and
//! the tracer's indirect arguments) for the DGIs of the paper's setup (HORNET, viewer 1 m in
//! front of the wall centre pointing at it, FOV 10°–60°; DESIGN.md §9), on the GPU and on the
//! CPU twin, with the share of pixels selected. The target: ≤ 0.1 ms at 3840 × 2160 on a
//! datacenter GPU.
//!
//! Both list orders are timed; the scattered one costs more here (uncoalesced DGI reads and the
//! permutation), but what coherence buys is the tracer's time over the list, which the guided
//! render benchmark measures once the tracer exists ([`Order`] selects the order).

use std::time::Instant;

use serde::Serialize;
use wgpu::util::DeviceExt;

use crate::gpu::{Backend, GpuContext, PassTimer};
use crate::roi::dgi::{Falloff, Surface};
use crate::schedule::gpu::{ScheduleConfig, ScheduleKernel};
use crate::schedule::{Order, probability, schedule_cpu};

/// Why the scheduling benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum ScheduleBenchError {
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    #[error(transparent)]
    Schedule(#[from] crate::schedule::ScheduleError),
    #[error(transparent)]
    Cone(#[from] crate::roi::cone::ConeError),
    #[error(transparent)]
    Guide(#[from] crate::roi::dgi::GuideError),
}

/// What to measure.
#[derive(Clone, Debug, Serialize)]
pub struct ScheduleBenchConfig {
    pub size: [u32; 2],
    pub fovs_deg: Vec<f64>,
    pub p_min: f32,
    pub orders: Vec<Order>,
    pub gpu_reps: u32,
    pub cpu_reps: u32,
    pub seed: u32,
    /// The tracer workgroup size the indirect arguments are computed for.
    pub trace_workgroup_size: u32,
    pub origin: [f64; 3],
    pub dir: [f64; 3],
    pub falloff: Falloff,
}

impl Default for ScheduleBenchConfig {
    fn default() -> Self {
        Self {
            size: [3840, 2160],
            fovs_deg: vec![10.0, 20.0, 30.0, 40.0, 50.0, 60.0],
            p_min: 0.0,
            orders: vec![Order::Coherent, Order::Scattered],
            gpu_reps: 50,
            cpu_reps: 5,
            seed: 1,
            trace_workgroup_size: 64,
            origin: [0.0, 0.0, 1.0],
            dir: [0.0, 0.0, -1.0],
            falloff: Falloff::default(),
        }
    }
}

/// One measured configuration.
#[derive(Clone, Debug, Serialize)]
pub struct ScheduleBenchRow {
    pub fov_deg: f64,
    /// "gpu" or "cpu".
    pub backend: &'static str,
    pub order: Order,
    /// Mean of p over the image: the expected share of pixels selected per iteration.
    pub expected_share: f64,
    /// Share selected in the first measured iteration.
    pub share_selected: f64,
    /// Median time of one iteration (GPU: the schedule pass from timestamp queries where
    /// available, else submit-to-done wall time; CPU: `schedule_cpu`, list included).
    pub ms_median: f64,
    pub ms_min: f64,
    pub gpu_timestamps: bool,
    /// GPU rows: whether the GPU's count equals the twin's for the same iteration and seed.
    pub count_matches_cpu: Option<bool>,
}

#[derive(Clone, Debug, Serialize)]
pub struct ScheduleBenchReport {
    pub display: String,
    pub adapter: Option<String>,
    pub cpu: String,
    pub config: ScheduleBenchConfig,
    pub rows: Vec<ScheduleBenchRow>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

/// GPU times of `reps` iterations (and the first iteration's count).
fn time_gpu(
    ctx: &GpuContext,
    kernel: &ScheduleKernel,
    dgi: &wgpu::Buffer,
    config: &ScheduleBenchConfig,
    order: Order,
) -> Result<(Vec<f64>, bool, u32), ScheduleBenchError> {
    let [width, height] = config.size;
    let run = kernel.prepare(
        ctx,
        dgi,
        &ScheduleConfig {
            width,
            height,
            p_min: config.p_min,
            order,
            trace_workgroup_size: config.trace_workgroup_size,
            trace_max_groups: 0,
        },
    )?;
    // Iteration 0 doubles as the warm-up (pipeline compilation on some drivers).
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    run.record(&mut enc, 0, config.seed, None);
    ctx.queue.submit([enc.finish()]);
    let count = run.read_args(ctx)?[3];
    let reps = config.gpu_reps.max(1);
    if let Some(timer) = PassTimer::new(ctx, reps) {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        for i in 0..reps {
            run.record(&mut enc, i + 1, config.seed, Some((&timer, i)));
        }
        timer.resolve(&mut enc);
        ctx.queue.submit([enc.finish()]);
        return Ok((timer.read_ms(ctx)?, true, count));
    }
    let mut times = Vec::new();
    for i in 0..reps {
        let t = Instant::now();
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        run.record(&mut enc, i + 1, config.seed, None);
        ctx.queue.submit([enc.finish()]);
        ctx.wait()?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    Ok((times, false, count))
}

/// Runs the benchmark; `progress` is told each configuration as it starts.
pub fn run(
    surface: &Surface,
    display_name: &str,
    backend: &Backend,
    config: &ScheduleBenchConfig,
    mut progress: impl FnMut(&str),
) -> Result<ScheduleBenchReport, ScheduleBenchError> {
    let [w, h] = config.size;
    let pixels = f64::from(w) * f64::from(h);
    let gpu = match backend {
        Backend::Gpu(ctx) => Some((ctx.as_ref(), ScheduleKernel::new(ctx))),
        Backend::Cpu => None,
    };
    let mut rows = Vec::new();
    for &fov in &config.fovs_deg {
        progress(&format!("{fov}°: DGI (exact metric, CPU twin)"));
        let roi = super::paper::roi_from(config.origin, config.dir, fov)?;
        let dgi = super::paper::dgi(surface, w, h, &roi, config.falloff)?;
        let expected_share = dgi
            .iter()
            .map(|&d| f64::from(probability(d, config.p_min)).min(1.0))
            .sum::<f64>()
            / pixels;
        let dgi_buf = gpu.as_ref().map(|(ctx, _)| {
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("bench schedule dgi"),
                    contents: bytemuck::cast_slice(&dgi),
                    usage: wgpu::BufferUsages::STORAGE,
                })
        });
        for &order in &config.orders {
            progress(&format!("{fov}° {order:?}: CPU twin"));
            let mut times = Vec::new();
            let mut first_count = 0;
            for i in 0..config.cpu_reps.max(1) {
                let t = Instant::now();
                let list = schedule_cpu(&dgi, w, h, config.p_min, i, config.seed, order)?;
                times.push(t.elapsed().as_secs_f64() * 1e3);
                if i == 0 {
                    first_count = list.len();
                }
            }
            rows.push(ScheduleBenchRow {
                fov_deg: fov,
                backend: "cpu",
                order,
                expected_share,
                share_selected: first_count as f64 / pixels,
                ms_median: median(times.clone()),
                ms_min: min(&times),
                gpu_timestamps: false,
                count_matches_cpu: None,
            });
            if let (Some((ctx, kernel)), Some(buf)) = (&gpu, &dgi_buf) {
                progress(&format!("{fov}° {order:?}: GPU"));
                let (times, stamped, count) = time_gpu(ctx, kernel, buf, config, order)?;
                rows.push(ScheduleBenchRow {
                    backend: "gpu",
                    share_selected: f64::from(count) / pixels,
                    ms_median: median(times.clone()),
                    ms_min: min(&times),
                    gpu_timestamps: stamped,
                    count_matches_cpu: Some(count as usize == first_count),
                    ..rows.last().expect("CPU row pushed above").clone()
                });
            }
        }
    }
    Ok(ScheduleBenchReport {
        display: display_name.to_owned(),
        adapter: backend.adapter(),
        cpu: super::cpu_threads(),
        config: config.clone(),
        rows,
    })
}

impl ScheduleBenchReport {
    /// The table as Markdown.
    #[must_use]
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "Schedule benchmark (mask + compaction + indirect args) — display {}, {}×{}, \
             p_min {}; GPU: {}; CPU: {}\n\n",
            self.display,
            self.config.size[0],
            self.config.size[1],
            self.config.p_min,
            self.adapter.as_deref().unwrap_or("none"),
            self.cpu
        );
        s.push_str(
            "| FOV | backend | order | share selected | expected share | ms (median) | ms (min) | GPU count = CPU |\n",
        );
        s.push_str("|---|---|---|---|---|---|---|---|\n");
        for r in &self.rows {
            s.push_str(&format!(
                "| {}° | {}{} | {:?} | {:.2} % | {:.2} % | {:.3} | {:.3} | {} |\n",
                r.fov_deg,
                r.backend,
                if r.gpu_timestamps {
                    " (timestamps)"
                } else {
                    ""
                },
                r.order,
                100.0 * r.share_selected,
                100.0 * r.expected_share,
                r.ms_median,
                r.ms_min,
                match r.count_matches_cpu {
                    Some(true) => "yes",
                    Some(false) => "NO",
                    None => "–",
                }
            ));
        }
        s
    }
}
