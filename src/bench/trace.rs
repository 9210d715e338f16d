//! `raygun bench trace`: full-frame path tracing speed — ms per frame at one sample per pixel,
//! ms per megasample and rays per second — for the paper's two scenes, beside the paper's
//! figures (DESIGN.md §9) and raygun's targets (the report's Targets table).
//!
//! With a wall camera (DESIGN.md §11) each scene is measured twice in the same run, the pinhole
//! and the wall camera's frames interleaved (pinhole, wall, pinhole, …) so that both see the
//! same machine state; the wall camera traces only the pixels a tile shows, so its rows compare
//! by ms per megasample of traced pixels.

use serde::Serialize;

use super::median;

use crate::frame::{Render, Renderer};
#[cfg(feature = "kernel-lab")]
use crate::gpu::variant::TraceVariant;
use crate::gpu::{Backend, GpuError};
use crate::scene::Scene;
use crate::trace::camera::CameraError;
use crate::trace::wall::{WallCameraError, WallSpec};

/// What to measure.
#[derive(Clone, Debug, Serialize)]
pub struct TraceBenchConfig {
    pub size: [u32; 2],
    /// Timed frames per scene (one sample per pixel each; the median is reported).
    pub frames: u32,
    /// Untimed frames first (pipeline compilation, caches).
    pub warmup: u32,
    pub max_depth: u32,
    pub seed: u32,
}

impl Default for TraceBenchConfig {
    fn default() -> Self {
        Self {
            size: [3840, 2160],
            frames: 20,
            warmup: 2,
            max_depth: crate::trace::path::DEFAULT_MAX_DEPTH,
            seed: 1,
        }
    }
}

/// One scene's figures.
#[derive(Clone, Debug, Serialize)]
pub struct TraceBenchRow {
    pub scene: String,
    /// "pinhole" (the scene's camera) or "wall" (the wall camera).
    pub camera: &'static str,
    /// The GPU trace kernel's name (`GpuContext::trace_kernel_name`: `private`, or a kernel
    /// lab's variant); none on the CPU.
    pub kernel: Option<String>,
    /// Pixels traced per frame (the wall camera skips those no tile shows).
    pub pixels: u64,
    pub triangles: usize,
    pub bvh_nodes: usize,
    /// BVH build and packing, seconds (CPU, once per scene).
    pub build_s: f64,
    /// Preparing the backend for the scene, seconds (once per renderer, before its first
    /// frame: on a GPU the kernels' compilation, the scene's upload and the first buffers).
    pub upload_s: f64,
    pub size: [u32; 2],
    pub ms_per_frame_median: f64,
    pub ms_per_frame_min: f64,
    /// Median frame time divided by the frame's megasamples (W·H / 10⁶).
    pub ms_per_megasample: f64,
    /// Closest-hit and shadow rays per second at the median frame time.
    pub rays_per_second: f64,
    pub rays_per_pixel: f64,
    pub gpu_timestamps: bool,
    /// The paper's full-frame time at 3840×2160 (GTX 980, OptiX), where it reported one.
    pub paper_ms_per_frame: Option<f64>,
    /// Our target on an H100-class GPU at 3840×2160.
    pub target_ms_per_frame: Option<f64>,
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum TraceBenchError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Frame(#[from] crate::frame::FrameError),
    #[error("scene '{scene}': {source}")]
    Camera {
        scene: String,
        #[source]
        source: CameraError,
    },
    #[error("scene '{scene}': --camera wall: {source}")]
    Wall {
        scene: String,
        #[source]
        source: WallCameraError,
    },
    #[cfg(feature = "kernel-lab")]
    #[error("--trace-kernel: the trace kernel's variants are GPU kernels; use --backend gpu")]
    KernelsNeedGpu,
}

/// The paper's full-frame figure and our target for a scene name ("cornell…", "city…").
fn reference(scene: &str) -> (Option<f64>, Option<f64>) {
    if scene.contains("cornell") {
        (Some(460.0), Some(10.0))
    } else if scene.contains("city") {
        (Some(750.0), Some(20.0))
    } else {
        (None, None)
    }
}

/// Measures each scene (with `wall`, the pinhole and the wall camera interleaved, one frame
/// of each in turn, so that both see the same machine state); `progress` is told the scene
/// name before it starts.
pub fn run(
    backend: &Backend,
    scenes: &[(String, Scene)],
    cfg: &TraceBenchConfig,
    wall: Option<&WallSpec>,
    progress: impl FnMut(&str),
) -> Result<Vec<TraceBenchRow>, TraceBenchError> {
    measure(&[backend], scenes, cfg, wall, progress)
}

/// [`run`] for each of the kernel lab's trace kernels `kernels` on `backend`'s GPU,
/// interleaved too (one frame of each in turn, so that every variant sees the same GPU state).
#[cfg(feature = "kernel-lab")]
pub fn run_kernels(
    backend: &Backend,
    scenes: &[(String, Scene)],
    cfg: &TraceBenchConfig,
    wall: Option<&WallSpec>,
    kernels: &[TraceVariant],
    progress: impl FnMut(&str),
) -> Result<Vec<TraceBenchRow>, TraceBenchError> {
    let variants: Vec<Backend> = match backend {
        Backend::Gpu(ctx) => kernels
            .iter()
            .map(|&v| Ok(Backend::Gpu(Box::new(ctx.with_trace_variant(v)?))))
            .collect::<Result<_, GpuError>>()?,
        Backend::Cpu if kernels.is_empty() => Vec::new(),
        Backend::Cpu => return Err(TraceBenchError::KernelsNeedGpu),
    };
    if variants.is_empty() {
        return run(backend, scenes, cfg, wall, progress);
    }
    let engines: Vec<&Backend> = variants.iter().collect();
    measure(&engines, scenes, cfg, wall, progress)
}

/// Each scene on each of `engines`, their frames interleaved.
fn measure(
    engines: &[&Backend],
    scenes: &[(String, Scene)],
    cfg: &TraceBenchConfig,
    wall: Option<&WallSpec>,
    mut progress: impl FnMut(&str),
) -> Result<Vec<TraceBenchRow>, TraceBenchError> {
    let kernel_of = |b: &Backend| match b {
        Backend::Gpu(ctx) => Some(ctx.trace_kernel_name()),
        Backend::Cpu => None,
    };
    let mut rows = Vec::new();
    for (name, scene) in scenes {
        progress(name);
        let settings =
            super::paper::settings(scene, cfg.size, cfg.seed, cfg.max_depth).map_err(|source| {
                TraceBenchError::Camera {
                    scene: name.clone(),
                    source,
                }
            })?;
        let wall_camera = wall
            .map(|spec| spec.camera(cfg.size, &settings.camera))
            .transpose()
            .map_err(|source| TraceBenchError::Wall {
                scene: name.clone(),
                source,
            })?;
        let mut renderers = Vec::new();
        for &engine in engines {
            let kernel = kernel_of(engine);
            renderers.push((
                "pinhole",
                kernel.clone(),
                Renderer::full(engine, scene, settings)?,
            ));
            if let Some(wc) = &wall_camera {
                let r = Renderer::full_wall(engine, scene, settings, wc.clone())?;
                renderers.push(("wall", kernel, r));
            }
        }
        for (_, _, r) in &mut renderers {
            r.iterate(cfg.warmup)?;
        }
        let mut ms = vec![Vec::new(); renderers.len()];
        let mut rays = vec![0u64; renderers.len()];
        let mut pixels = vec![0u64; renderers.len()];
        let mut stamps = false;
        for _ in 0..cfg.frames.max(1) {
            for (k, (_, _, r)) in renderers.iter_mut().enumerate() {
                let s = r.run_frame(true)?;
                ms[k].push(s.ms_trace.unwrap_or(f64::NAN));
                rays[k] += s.rays.unwrap_or(0);
                pixels[k] = u64::from(s.pixels.unwrap_or(0));
                stamps = s.gpu_timestamps;
            }
        }
        let frames = f64::from(cfg.frames.max(1));
        for (k, (camera, kernel, r)) in renderers.iter().enumerate() {
            let med = median(ms[k].clone());
            let ms_min = ms[k].iter().copied().fold(f64::NAN, f64::min);
            let megasamples = pixels[k] as f64 / 1e6;
            let rays_per_frame = rays[k] as f64 / frames;
            let (paper, target) = reference(name);
            rows.push(TraceBenchRow {
                scene: name.clone(),
                camera,
                kernel: kernel.clone(),
                pixels: pixels[k],
                triangles: scene.triangles.len(),
                bvh_nodes: r.packed.bvh.cwbvh.nodes.len(),
                build_s: r.build_seconds,
                upload_s: r.upload_seconds,
                size: cfg.size,
                ms_per_frame_median: med,
                ms_per_frame_min: ms_min,
                ms_per_megasample: med / megasamples,
                rays_per_second: rays_per_frame / (med * 1e-3),
                rays_per_pixel: rays_per_frame / (megasamples * 1e6),
                gpu_timestamps: stamps,
                paper_ms_per_frame: paper,
                target_ms_per_frame: target,
            });
        }
    }
    Ok(rows)
}

/// The rows as a Markdown table; where several trace kernels were measured, each row's
/// median frame time also as a ratio to the first kernel's on the same scene and camera.
#[must_use]
pub fn markdown(rows: &[TraceBenchRow], device: &str) -> String {
    let first_kernel = rows.first().and_then(|r| r.kernel.clone());
    let several = rows.iter().any(|r| r.kernel != first_kernel);
    let (ratio_head, ratio_rule) = if several {
        (
            format!(" ÷ {} |", first_kernel.as_deref().unwrap_or("–")),
            "---|",
        )
    } else {
        (String::new(), "")
    };
    let mut s = format!(
        "Device: {device}\n\n| scene | camera | trace kernel | pixels traced | triangles | size | ms/frame (median) | ms/megasample | Mrays/s | rays/pixel | paper ms/frame (3840×2160, GTX 980) | target ms/frame (3840×2160, H100) |{ratio_head}\n|---|---|---|---|---|---|---|---|---|---|---|---|{ratio_rule}\n"
    );
    let opt = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.0}"));
    for r in rows {
        s += &format!(
            "| {} | {} | {} | {} | {} | {}×{} | {:.2} | {:.2} | {:.1} | {:.2} | {} | {} |",
            r.scene,
            r.camera,
            r.kernel.as_deref().unwrap_or("– (CPU)"),
            r.pixels,
            r.triangles,
            r.size[0],
            r.size[1],
            r.ms_per_frame_median,
            r.ms_per_megasample,
            r.rays_per_second / 1e6,
            r.rays_per_pixel,
            opt(r.paper_ms_per_frame),
            opt(r.target_ms_per_frame),
        );
        if several {
            let base = rows
                .iter()
                .find(|b| b.scene == r.scene && b.camera == r.camera && b.kernel == first_kernel);
            s += &match base {
                Some(b) => format!(" ×{:.3} |", r.ms_per_frame_median / b.ms_per_frame_median),
                None => " – |".to_string(),
            };
        }
        s += "\n";
    }
    s
}
