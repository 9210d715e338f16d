//! `raygun bench native`: a guided iteration at the display canvas's own resolution (HORNET:
//! 13519×5457, 73.8 MP) — what a wall driven pixel for pixel costs per iteration, which share of
//! it is sampled, and the memory each stage holds, stated ([`Budget`]) and measured (the
//! process's resident set).
//!
//! Per field of view the paper's ROI is set, the first frame computes the DGI (timed on its
//! own), and the next `iterations` frames are timed (schedule + trace; the picture is not made:
//! the filter's cost at this size is `bench filter`'s). The memory is checked against the
//! machine before anything is allocated, as every command does.

use std::time::Instant;

use crate::bench::{median, paper};
use crate::display::DisplayModel;
use crate::filter::FilterKind;
use crate::frame::{FrameError, GuideConfig, Render};
use crate::gpu::Backend;
use crate::memory::{Budget, MemoryError, Work};
use crate::output::tiles::canvas_pixel_size;
use crate::scene::Scene;
use crate::trace::wall::{WallCameraError, WallSpec};

/// What to measure.
#[derive(Clone, Debug, serde::Serialize)]
pub struct NativeBenchConfig {
    pub fovs_deg: Vec<f64>,
    /// Timed iterations per field of view (after the DGI's frame).
    pub iterations: u32,
    pub max_depth: u32,
    pub seed: u32,
    pub p_min: f32,
}

impl Default for NativeBenchConfig {
    fn default() -> Self {
        Self {
            fovs_deg: vec![10.0, 60.0],
            iterations: 5,
            max_depth: crate::trace::path::DEFAULT_MAX_DEPTH,
            seed: 1,
            p_min: 0.0,
        }
    }
}

/// One field of view.
#[derive(Clone, Debug, serde::Serialize)]
pub struct NativeBenchRow {
    pub scene: String,
    pub fov_deg: f64,
    /// The first frame's DGI (ms).
    pub ms_dgi: f64,
    /// Median of the timed iterations: the whole frame (wall clock around `run_frame`, which
    /// waits for a GPU's frame when timed), and its schedule and trace steps.
    pub ms_per_iteration: f64,
    pub ms_schedule: f64,
    pub ms_trace: f64,
    pub iterations_per_second: f64,
    /// Scheduled pixels per iteration over the canvas's pixels (median).
    pub share_sampled: f64,
    /// Megasamples per second of the trace step.
    pub megasamples_per_second: f64,
    /// The process's resident set at the end of the field of view (bytes; Linux only).
    pub resident_bytes: Option<u64>,
}

/// The report: the size, the stated budget by stage and the rows.
#[derive(Clone, Debug, serde::Serialize)]
pub struct NativeBenchReport {
    pub display: String,
    pub size: [u32; 2],
    pub megapixels: f64,
    /// (stage, bytes) on the host and on the GPU ([`Budget::of`]: a guided render without the
    /// picture's filter).
    pub host_budget: Vec<(&'static str, u64)>,
    pub device_budget: Vec<(&'static str, u64)>,
    /// The process's peak resident set over the run (bytes; Linux only).
    pub peak_resident_bytes: Option<u64>,
    /// On the GPU: the bands of rows the frame's buffers are split into to fit the adapter's
    /// storage bindings (1: unsplit), and that binding limit in bytes.
    pub gpu_bands: Option<(usize, u64)>,
    pub rows: Vec<NativeBenchRow>,
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum NativeBenchError {
    #[error(transparent)]
    Memory(#[from] MemoryError),
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error("scene {scene}: {source}")]
    Camera {
        scene: String,
        #[source]
        source: crate::trace::camera::CameraError,
    },
    #[error("scene {scene}: {source}")]
    Wall {
        scene: String,
        #[source]
        source: WallCameraError,
    },
    #[error("{fov}° ROI: {source}")]
    Roi {
        fov: f64,
        #[source]
        source: crate::roi::cone::ConeError,
    },
}

/// The guided render's budget at `size` on `backend`, the filter left out.
#[must_use]
pub fn budget(backend: &Backend, size: [u32; 2]) -> Budget {
    Budget::of(
        Work::Render {
            gpu: backend.is_gpu(),
            filter: FilterKind::Off,
        },
        size,
    )
}

/// Runs the benchmark on `display`'s canvas at its own pixel size, through the wall camera of
/// `wall` when given (its pixels off the tiles never traced).
pub fn run(
    backend: &Backend,
    display: &DisplayModel,
    scenes: &[(String, Scene)],
    cfg: &NativeBenchConfig,
    wall: Option<&WallSpec>,
    mut progress: impl FnMut(&str),
) -> Result<NativeBenchReport, NativeBenchError> {
    let size = canvas_pixel_size(display);
    let budget = budget(backend, size);
    budget.check(crate::memory::available_host_bytes(), backend.max_binding())?;
    let pixels = budget.pixels() as f64;
    let mut rows = Vec::new();
    let mut gpu_bands = None;
    for (name, scene) in scenes {
        let settings = paper::settings(scene, size, cfg.seed, cfg.max_depth).map_err(|source| {
            NativeBenchError::Camera {
                scene: name.clone(),
                source,
            }
        })?;
        let wc = wall
            .map(|spec| spec.camera(size, &settings.camera))
            .transpose()
            .map_err(|source| NativeBenchError::Wall {
                scene: name.clone(),
                source,
            })?;
        for &fov in &cfg.fovs_deg {
            progress(&format!("{name}: {fov}° at {}×{}", size[0], size[1]));
            let roi = paper::roi(fov).map_err(|source| NativeBenchError::Roi { fov, source })?;
            let config = GuideConfig {
                p_min: cfg.p_min,
                ..GuideConfig::default()
            };
            let mut renderer =
                paper::guided_wall(backend, scene, settings, display, config, roi, wc.as_ref())?;
            gpu_bands = renderer.gpu_bands().zip(backend.max_binding());
            let first = renderer.run_frame(true)?;
            let (mut whole, mut schedule, mut trace, mut share) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for _ in 0..cfg.iterations.max(1) {
                let t = Instant::now();
                let stats = renderer.run_frame(true)?;
                whole.push(t.elapsed().as_secs_f64() * 1e3);
                schedule.push(stats.ms_schedule.unwrap_or(f64::NAN));
                trace.push(stats.ms_trace.unwrap_or(f64::NAN));
                share.push(f64::from(stats.pixels.unwrap_or(0)) / pixels);
            }
            let (ms, ms_trace) = (median(whole), median(trace));
            let share_sampled = median(share);
            rows.push(NativeBenchRow {
                scene: name.clone(),
                fov_deg: fov,
                ms_dgi: first.ms_dgi.unwrap_or(f64::NAN),
                ms_per_iteration: ms,
                ms_schedule: median(schedule),
                ms_trace,
                iterations_per_second: 1e3 / ms,
                share_sampled,
                megasamples_per_second: share_sampled * pixels / 1e6 / (ms_trace / 1e3),
                resident_bytes: proc_status_bytes("VmRSS:"),
            });
        }
    }
    Ok(NativeBenchReport {
        display: display.name().to_string(),
        size,
        megapixels: pixels / 1e6,
        host_budget: budget.host.clone(),
        device_budget: budget.device.clone(),
        peak_resident_bytes: proc_status_bytes("VmHWM:"),
        gpu_bands,
        rows,
    })
}

/// A `/proc/self/status` line in bytes ("VmRSS:", "VmHWM:"), where there is one.
fn proc_status_bytes(key: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    let kb: u64 = line[key.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb * 1024)
}

/// The report as Markdown.
#[must_use]
pub fn markdown(r: &NativeBenchReport, device: &str) -> String {
    use crate::memory::bytes;
    use std::fmt::Write as _;
    let mut s = format!(
        "Device: {device}\n\n{} at its native {}×{} ({:.1} MP)\n\n",
        r.display, r.size[0], r.size[1], r.megapixels
    );
    s.push_str(
        "| scene | FOV | DGI ms | ms/iteration | schedule ms | trace ms | it/s | share sampled | Msamples/s | resident |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
    );
    for row in &r.rows {
        let _ = writeln!(
            s,
            "| {} | {}° | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} | {:.2} % | {:.2} | {} |",
            row.scene,
            row.fov_deg,
            row.ms_dgi,
            row.ms_per_iteration,
            row.ms_schedule,
            row.ms_trace,
            row.iterations_per_second,
            100.0 * row.share_sampled,
            row.megasamples_per_second,
            row.resident_bytes.map_or("–".into(), bytes),
        );
    }
    let stages = |v: &[(&str, u64)]| {
        v.iter()
            .map(|(stage, b)| format!("{stage} {}", bytes(*b)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let _ = writeln!(
        s,
        "\nStated memory (host): {}; total {}",
        stages(&r.host_budget),
        bytes(r.host_budget.iter().map(|b| b.1).sum())
    );
    if !r.device_budget.is_empty() {
        let _ = writeln!(s, "Stated memory (GPU): {}", stages(&r.device_budget));
    }
    if let Some((bands, max)) = r.gpu_bands {
        let _ = writeln!(
            s,
            "GPU buffers: {bands} band{} of rows (the adapter's storage binding: {})",
            if bands == 1 { "" } else { "s" },
            bytes(max)
        );
    }
    if let Some(peak) = r.peak_resident_bytes {
        let _ = writeln!(
            s,
            "Peak resident (process, scene and BVH included): {}",
            bytes(peak)
        );
    }
    s
}
