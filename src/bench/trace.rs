//! `raygun bench trace`: full-frame path tracing speed — ms per frame at one sample per pixel,
//! ms per megasample and rays per second — for the paper's two scenes, beside the paper's
//! figures (DESIGN.md §9) and raygun's targets (the report's Targets table).

use serde::Serialize;

use super::median;

use crate::frame::Renderer;
use crate::gpu::{Backend, GpuError};
use crate::scene::Scene;
use crate::trace::camera::CameraError;

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
    pub triangles: usize,
    pub bvh_nodes: usize,
    /// BVH build and packing, seconds (CPU, once per scene).
    pub build_s: f64,
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

/// Measures each scene; `progress` is told the scene name before it starts.
pub fn run(
    backend: &Backend,
    scenes: &[(String, Scene)],
    cfg: &TraceBenchConfig,
    mut progress: impl FnMut(&str),
) -> Result<Vec<TraceBenchRow>, TraceBenchError> {
    let mut rows = Vec::new();
    for (name, scene) in scenes {
        progress(name);
        let [w, h] = cfg.size;
        let settings =
            super::paper::settings(scene, cfg.size, cfg.seed, cfg.max_depth).map_err(|source| {
                TraceBenchError::Camera {
                    scene: name.clone(),
                    source,
                }
            })?;
        let mut r = Renderer::full(backend, scene, settings)?;
        r.iterate(cfg.warmup)?;
        let timed = r.timed_iterations(cfg.frames.max(1))?;
        let med = median(timed.ms.clone());
        let ms_min = timed.ms.iter().copied().fold(f64::NAN, f64::min);
        let megasamples = f64::from(w) * f64::from(h) / 1e6;
        let (paper, target) = reference(name);
        rows.push(TraceBenchRow {
            scene: name.clone(),
            triangles: scene.triangles.len(),
            bvh_nodes: r.packed.bvh.cwbvh.nodes.len(),
            build_s: r.build_seconds,
            size: cfg.size,
            ms_per_frame_median: med,
            ms_per_frame_min: ms_min,
            ms_per_megasample: med / megasamples,
            rays_per_second: timed.rays_per_iteration / (med * 1e-3),
            rays_per_pixel: timed.rays_per_iteration / (megasamples * 1e6),
            gpu_timestamps: timed.gpu_timestamps,
            paper_ms_per_frame: paper,
            target_ms_per_frame: target,
        });
    }
    Ok(rows)
}

/// The rows as a Markdown table.
#[must_use]
pub fn markdown(rows: &[TraceBenchRow], device: &str) -> String {
    let mut s = format!(
        "Device: {device}\n\n| scene | triangles | size | ms/frame (median) | ms/megasample | Mrays/s | rays/pixel | paper ms/frame (3840×2160, GTX 980) | target ms/frame (3840×2160, H100) |\n|---|---|---|---|---|---|---|---|---|\n"
    );
    let opt = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.0}"));
    for r in rows {
        s += &format!(
            "| {} | {} | {}×{} | {:.2} | {:.2} | {:.1} | {:.2} | {} | {} |\n",
            r.scene,
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
    }
    s
}
