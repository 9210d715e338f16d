//! `raygun bench guided`: the paper's benchmark (DESIGN.md §9). HORNET wall, viewer
//! 1 m in front of the wall centre pointing at it, FOV 10°…60°: per FOV the share of pixels
//! sampled, ms per iteration, ms per megasample, the speed-up over a full-frame 1-spp
//! iteration, and the RMSE inside the ROI against a converged reference after equal time for
//! guided and full-frame rendering; and a plot like the paper's Figure 5.

use std::path::Path;

use glam::Vec3;
use serde::Serialize;

use super::median;

use super::paper;
use crate::display::DisplayModel;
use crate::frame::{FrameError, GuideConfig, Render, Renderer};
use crate::gpu::{Backend, GpuError};
use crate::roi::cone::ConeError;
use crate::scene::Scene;
use crate::schedule::Order;
use crate::trace::camera::CameraError;
use crate::trace::path::TraceSettings;
use crate::trace::wall::{WallCamera, WallCameraError, WallSpec};

/// What to measure.
#[derive(Clone, Debug, Serialize)]
pub struct GuidedBenchConfig {
    pub size: [u32; 2],
    pub fovs_deg: Vec<f64>,
    /// Guided iterations per FOV (the paper: 100).
    pub iterations: u32,
    /// Full-frame frames timed for the baseline.
    pub full_frames: u32,
    /// Samples per pixel of the converged reference.
    pub reference_spp: u32,
    pub p_min: f32,
    pub orders: Vec<Order>,
    pub origin: [f64; 3],
    pub dir: [f64; 3],
    pub max_depth: u32,
    pub seed: u32,
}

impl Default for GuidedBenchConfig {
    fn default() -> Self {
        Self {
            size: [3840, 2160],
            fovs_deg: vec![10.0, 20.0, 30.0, 40.0, 50.0, 60.0],
            iterations: 100,
            full_frames: 20,
            reference_spp: 1024,
            p_min: 0.0,
            orders: vec![Order::Coherent],
            origin: [0.0, 0.0, 1.0],
            dir: [0.0, 0.0, -1.0],
            max_depth: crate::trace::path::DEFAULT_MAX_DEPTH,
            seed: 1,
        }
    }
}

/// The full-frame baseline of a scene.
#[derive(Clone, Debug, Serialize)]
pub struct FullFrameRow {
    pub scene: String,
    pub ms_per_frame: f64,
    pub ms_per_megasample: f64,
    /// Rays traced per sample (closest-hit and shadow rays), where the backend counts them.
    pub rays_per_sample: Option<f64>,
}

/// One scene × FOV × list order.
#[derive(Clone, Debug, Serialize)]
pub struct GuidedBenchRow {
    pub scene: String,
    pub fov_deg: f64,
    pub order: Order,
    /// Mean share of the pixels traced per iteration.
    pub share_sampled: f64,
    /// Median of scheduling + tracing per iteration (ms).
    pub ms_per_iteration: f64,
    pub ms_schedule: Option<f64>,
    pub ms_trace: Option<f64>,
    /// DGI time of the frame that recomputed it (ms).
    pub ms_dgi: Option<f64>,
    pub ms_per_megasample: f64,
    /// ms per megasample ÷ the full frame's (the target on a GPU: at most 1.5×).
    pub ms_per_megasample_vs_full: f64,
    /// Rays traced per sample over the guided iterations (closest-hit and shadow rays), where
    /// the backend counts them: against the full frame's, whether the ROI's paths are longer.
    pub rays_per_sample: Option<f64>,
    /// ms per ray traced ÷ the full frame's, where both count rays: the ms-per-megasample
    /// ratio with the paths' lengths divided out — what the list's launch and its pixels'
    /// coherence cost beyond the ROI's longer (or shorter) paths.
    pub ms_per_ray_vs_full: Option<f64>,
    /// Full-frame ms per frame ÷ guided ms per iteration.
    pub speedup: f64,
    /// Time of the guided iterations at their median rate plus the DGI's:
    /// `iterations × ms_per_iteration + ms_dgi` (ms). The full-frame render gets the same time
    /// at its own median rate, so one slow frame on a shared machine moves neither side.
    pub guided_total_ms: f64,
    /// Full-frame samples per pixel that fit in the same time (at least 1).
    pub equal_time_full_spp: u32,
    /// Pixels inside the ROI (d = 0).
    pub roi_pixels: usize,
    /// RMSE (linear RGB) inside the ROI against the reference, and relative to the
    /// reference's mean there.
    pub rmse_roi_guided: f64,
    pub rmse_roi_full: f64,
    pub rel_rmse_roi_guided: f64,
    pub rel_rmse_roi_full: f64,
    pub gpu_timestamps: bool,
}

/// All rows.
#[derive(Clone, Debug, Serialize)]
pub struct GuidedBenchReport {
    pub device: String,
    pub config: GuidedBenchConfig,
    pub full_frame: Vec<FullFrameRow>,
    pub rows: Vec<GuidedBenchRow>,
}

#[derive(Debug, thiserror::Error)]
pub enum GuidedBenchError {
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
    #[error("scene '{scene}': --camera wall: {source}")]
    Wall {
        scene: String,
        #[source]
        source: WallCameraError,
    },
    #[error("plot {path}: {reason}")]
    Plot { path: String, reason: String },
}

/// RMSE over the masked pixels (linear RGB) and the reference's mean there.
fn rmse(image: &[Vec3], reference: &[Vec3], mask: &[bool]) -> (f64, f64) {
    let (mut se, mut sum, mut n) = (0f64, 0f64, 0usize);
    for ((a, b), &m) in image.iter().zip(reference).zip(mask) {
        if m {
            let d = (*a - *b).as_dvec3();
            se += d.length_squared() / 3.0;
            sum += b.as_dvec3().element_sum() / 3.0;
            n += 1;
        }
    }
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    ((se / n as f64).sqrt(), sum / n as f64)
}

/// The reference's samples per pixel where none are asked for: 16 × `iterations`, from 64 to
/// 1024. The renders it judges have at most `iterations` samples a pixel, so its own noise adds
/// at most 1/16 to their mean squared error (3 % to an RMSE), and it takes a time that fits the
/// run (`bench guided --iterations 8` at 320×180 renders 128 spp, not 1024).
#[must_use]
pub fn default_reference_spp(iterations: u32) -> u32 {
    iterations.saturating_mul(16).clamp(64, 1024)
}

/// The frames [`run`] renders before the equal-time full frames, whose number the run measures
/// (a frame: one full-frame sample of every pixel, or one guided iteration): per scene the
/// full frame's warm-up and timed frames, the reference, and every FOV's iterations.
#[must_use]
pub fn planned_frames(cfg: &GuidedBenchConfig, scenes: usize) -> u64 {
    let per_fov = u64::from(cfg.iterations.max(1)) * cfg.orders.len() as u64;
    scenes as u64
        * (2 + u64::from(cfg.full_frames.max(1))
            + u64::from(cfg.reference_spp)
            + per_fov * cfg.fovs_deg.len() as u64)
}

/// Runs the benchmark; `progress` hears what is being measured and how many frames have been
/// rendered since it last heard (0 at a step's start; [`planned_frames`] in all, plus the
/// equal-time full frames).
pub fn run(
    backend: &Backend,
    display: &DisplayModel,
    scenes: &[(String, Scene)],
    cfg: &GuidedBenchConfig,
    wall: Option<&WallSpec>,
    mut progress: impl FnMut(&str, u32),
) -> Result<GuidedBenchReport, GuidedBenchError> {
    let [w, h] = cfg.size;
    let megapixels = f64::from(w) * f64::from(h) / 1e6;
    let mut full_frame = Vec::new();
    let mut rows = Vec::new();
    for (name, scene) in scenes {
        let base = paper::settings(scene, cfg.size, cfg.seed, cfg.max_depth).map_err(|source| {
            GuidedBenchError::Camera {
                scene: name.clone(),
                source,
            }
        })?;
        let settings = |seed: u32| TraceSettings { seed, ..base };
        let wc = wall
            .map(|spec| spec.camera(cfg.size, &base.camera))
            .transpose()
            .map_err(|source| GuidedBenchError::Wall {
                scene: name.clone(),
                source,
            })?;
        let full_row = full_frame_baseline(
            backend,
            name,
            scene,
            cfg,
            settings(cfg.seed),
            wc.as_ref(),
            &mut progress,
        )?;
        let ms_full = full_row.ms_per_frame;
        let step = format!("{name}: reference ({} spp)", cfg.reference_spp);
        progress(&step, 0);
        let reference = paper::reference_image_wall(
            backend,
            scene,
            settings(cfg.seed ^ 0x5eed),
            cfg.reference_spp,
            wc.as_ref(),
            &mut |n| progress(&step, n),
        )?;
        for &fov in &cfg.fovs_deg {
            for &order in &cfg.orders {
                let step = format!("{name}: {fov}° ({order:?})");
                progress(&step, 0);
                let roi = paper::roi_from(cfg.origin, cfg.dir, fov)?;
                let config = GuideConfig {
                    p_min: cfg.p_min,
                    order,
                    ..Default::default()
                };
                let mut g = paper::guided_wall(
                    backend,
                    scene,
                    settings(cfg.seed.wrapping_add(1)),
                    display,
                    config,
                    roi,
                    wc.as_ref(),
                )?;
                let (mut per_iter, mut sched, mut trace) = (Vec::new(), Vec::new(), Vec::new());
                let (mut pixels, mut ms_dgi, mut stamps) = (0u64, None, false);
                let mut rays = Some(0u64);
                for _ in 0..cfg.iterations.max(1) {
                    let s = g.run_frame(true)?;
                    pixels += u64::from(s.pixels.unwrap_or(0));
                    rays = rays.zip(s.rays).map(|(a, b)| a + b);
                    if s.dgi_recomputed {
                        ms_dgi = s.ms_dgi;
                    }
                    stamps = s.ms_schedule.is_some() && backend_is_gpu(backend);
                    per_iter.push(s.ms_schedule.unwrap_or(0.0) + s.ms_trace.unwrap_or(0.0));
                    progress(&step, 1);
                    sched.extend(s.ms_schedule);
                    trace.extend(s.ms_trace);
                }
                let n = f64::from(cfg.iterations.max(1));
                let share = pixels as f64 / n / (megapixels * 1e6);
                let ms_iter = median(per_iter);
                let total = n * ms_iter + ms_dgi.unwrap_or(0.0);
                let dgi = g.dgi()?;
                // ROI pixels (a wall camera's unshown ones are black in every image: left out).
                let mask: Vec<bool> = dgi
                    .iter()
                    .enumerate()
                    .map(|(p, &d)| d == 0.0 && wc.as_ref().is_none_or(|c| c.is_shown(p as u32)))
                    .collect();
                let guided_image = g.accumulation()?.mean_image();
                drop(g);
                let spp_eq = ((total / ms_full).floor() as u32).max(1);
                let step = format!("{name}: {fov}°, the full frame in equal time ({spp_eq} spp)");
                let full_image = paper::reference_image_wall(
                    backend,
                    scene,
                    settings(cfg.seed.wrapping_add(2)),
                    spp_eq,
                    wc.as_ref(),
                    &mut |n| progress(&step, n),
                )?;
                let (rg, mean_ref) = rmse(&guided_image, &reference, &mask);
                let (rf, _) = rmse(&full_image, &reference, &mask);
                let ms_per_megasample = ms_iter / (share * megapixels);
                let vs_full = ms_per_megasample / full_row.ms_per_megasample;
                let rays_per_sample = rays
                    .filter(|_| pixels > 0)
                    .map(|r| r as f64 / pixels as f64);
                rows.push(GuidedBenchRow {
                    scene: name.clone(),
                    fov_deg: fov,
                    order,
                    share_sampled: share,
                    ms_per_iteration: ms_iter,
                    ms_schedule: (!sched.is_empty()).then(|| median(sched)),
                    ms_trace: (!trace.is_empty()).then(|| median(trace)),
                    ms_dgi,
                    ms_per_megasample,
                    ms_per_megasample_vs_full: vs_full,
                    rays_per_sample,
                    ms_per_ray_vs_full: rays_per_sample
                        .zip(full_row.rays_per_sample)
                        .map(|(g, f)| vs_full * f / g),
                    speedup: ms_full / ms_iter,
                    guided_total_ms: total,
                    equal_time_full_spp: spp_eq,
                    roi_pixels: mask.iter().filter(|&&m| m).count(),
                    rmse_roi_guided: rg,
                    rmse_roi_full: rf,
                    rel_rmse_roi_guided: rg / mean_ref,
                    rel_rmse_roi_full: rf / mean_ref,
                    gpu_timestamps: stamps,
                });
            }
        }
        full_frame.push(full_row);
    }
    Ok(GuidedBenchReport {
        device: super::device(backend),
        config: cfg.clone(),
        full_frame,
        rows,
    })
}

/// The full frame's time on `scene` (`cfg.full_frames` frames timed after two of warm-up),
/// rendered with `settings` (through the wall camera `wc` where there is one).
fn full_frame_baseline(
    backend: &Backend,
    name: &str,
    scene: &Scene,
    cfg: &GuidedBenchConfig,
    settings: TraceSettings,
    wc: Option<&WallCamera>,
    progress: &mut impl FnMut(&str, u32),
) -> Result<FullFrameRow, GuidedBenchError> {
    let megapixels = f64::from(cfg.size[0]) * f64::from(cfg.size[1]) / 1e6;
    progress(&format!("{name}: full-frame baseline"), 0);
    let mut full = match wc {
        Some(c) => Renderer::full_wall(backend, scene, settings, c.clone())?,
        None => Renderer::full(backend, scene, settings)?,
    };
    full.iterate(2)?;
    let timed = full.timed_iterations(cfg.full_frames.max(1))?;
    progress(
        &format!("{name}: full-frame baseline"),
        2 + cfg.full_frames.max(1),
    );
    let ms_full = median(timed.ms.clone());
    Ok(FullFrameRow {
        scene: name.to_owned(),
        ms_per_frame: ms_full,
        ms_per_megasample: ms_full / megapixels,
        rays_per_sample: (timed.rays_per_iteration > 0.0)
            .then(|| timed.rays_per_iteration / (megapixels * 1e6)),
    })
}

fn backend_is_gpu(b: &Backend) -> bool {
    matches!(b, Backend::Gpu(ctx) if ctx.timestamps)
}

/// The report as Markdown: the full-frame baselines, one row per FOV, and the paper's figures.
#[must_use]
pub fn markdown(r: &GuidedBenchReport) -> String {
    let c = &r.config;
    let mut s = format!(
        "Device: {}\n\nSetup: {}×{}, viewer at {:?} pointing {:?}, {} iterations per FOV, p_min {}, reference {} spp.\n\n| scene | full frame ms | ms/megasample | rays/sample |\n|---|---|---|---|\n",
        r.device, c.size[0], c.size[1], c.origin, c.dir, c.iterations, c.p_min, c.reference_spp
    );
    let rays = |v: Option<f64>| v.map_or("–".into(), |v| format!("{v:.2}"));
    for f in &r.full_frame {
        s += &format!(
            "| {} | {:.2} | {:.2} | {} |\n",
            f.scene,
            f.ms_per_frame,
            f.ms_per_megasample,
            rays(f.rays_per_sample)
        );
    }
    s += "\n| scene | FOV | order | share sampled | ms/iteration | schedule ms | trace ms | DGI ms | ms/megasample | ÷ full frame's | speed-up | equal-time full spp | ROI px | ROI rel. RMSE guided | ROI rel. RMSE full frame | rays/sample | ms per ray ÷ full frame's |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    let o = |v: Option<f64>| v.map_or("–".into(), |v| format!("{v:.3}"));
    let times = |v: Option<f64>| v.map_or("–".into(), |v| format!("{v:.2}×"));
    for row in &r.rows {
        s += &format!(
            "| {} | {}° | {:?} | {:.2} % | {:.3} | {} | {} | {} | {:.2} | {:.2}× | {:.2}× | {} | {} | {:.4} | {:.4} | {} | {} |\n",
            row.scene,
            row.fov_deg,
            row.order,
            100.0 * row.share_sampled,
            row.ms_per_iteration,
            o(row.ms_schedule),
            o(row.ms_trace),
            o(row.ms_dgi),
            row.ms_per_megasample,
            row.ms_per_megasample_vs_full,
            row.speedup,
            row.equal_time_full_spp,
            row.roi_pixels,
            row.rel_rmse_roi_guided,
            row.rel_rmse_roi_full,
            rays(row.rays_per_sample),
            times(row.ms_per_ray_vs_full),
        );
    }
    s += "\n*÷ full frame's*: ms per megasample over the full frame's (the target on a GPU: at most 1.5×); *ms per ray ÷ full frame's*: the same with the rays each sample cast divided out — a ROI whose paths are longer costs more per sample but not per ray.\n";
    s += "\nThe paper (GTX 980, OptiX, Cornell box, 3840×2160): full frame 460 ms (55.46 ms/megasample); 10° 12.29 ms per iteration (37.43×); 60° 188 ms (2.44×).\n";
    s
}

/// Figure 5 of the paper: share of pixels sampled and ms per megasample against FOV, one
/// line per scene (and order), as a PNG.
pub fn plot(r: &GuidedBenchReport, path: &Path) -> Result<(), GuidedBenchError> {
    use plotters::prelude::*;
    let err = |e: String| GuidedBenchError::Plot {
        path: path.display().to_string(),
        reason: e,
    };
    crate::bench::font::register().map_err(|e| err(e.to_string()))?;
    let root = BitMapBackend::new(path, (1200, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
    let (left, right) = root.split_horizontally(600);
    let fovs: Vec<f64> = r.config.fovs_deg.clone();
    let (fmin, fmax) = (
        fovs.iter().copied().fold(f64::INFINITY, f64::min) - 2.0,
        fovs.iter().copied().fold(f64::NEG_INFINITY, f64::max) + 2.0,
    );
    // (label, [(FOV, share %, ms per megasample)])
    type Series = (String, Vec<(f64, f64, f64)>);
    let mut series: Vec<Series> = Vec::new();
    for row in &r.rows {
        let key = if r.config.orders.len() > 1 {
            format!("{} ({:?})", row.scene, row.order)
        } else {
            row.scene.clone()
        };
        let point = (
            row.fov_deg,
            100.0 * row.share_sampled,
            row.ms_per_megasample,
        );
        match series.iter_mut().find(|(k, _)| *k == key) {
            Some((_, v)) => v.push(point),
            None => series.push((key, vec![point])),
        }
    }
    let colours = [RED, BLUE, GREEN, MAGENTA, CYAN, BLACK];
    for (area, title, pick, label) in [
        (
            &left,
            "Pixels sampled per iteration",
            1usize,
            "share sampled (%)",
        ),
        (&right, "Time per megasample", 2usize, "ms per megasample"),
    ] {
        let ymax = series
            .iter()
            .flat_map(|(_, v)| v.iter().map(|p| if pick == 1 { p.1 } else { p.2 }))
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max)
            * 1.1
            + 1e-9;
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(fmin..fmax, 0.0..ymax)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("field of view (degrees)")
            .y_desc(label)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for (i, (key, pts)) in series.iter().enumerate() {
            let colour = colours[i % colours.len()];
            let data: Vec<(f64, f64)> = pts
                .iter()
                .map(|p| (p.0, if pick == 1 { p.1 } else { p.2 }))
                .collect();
            chart
                .draw_series(LineSeries::new(data.clone(), colour.stroke_width(2)))
                .map_err(|e| err(e.to_string()))?
                .label(key.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            chart
                .draw_series(data.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                .map_err(|e| err(e.to_string()))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
    }
    root.present().map_err(|e| err(e.to_string()))?;
    Ok(())
}

/// A guided render of `subject.scene` in the paper's setup (viewer 1 m in front of the wall
/// centre, square cone of `shot.fov` degrees, p_min 0), for the filter benchmark's error table:
/// `shot.iterations` guided iterations and a full-frame reference of `reference_spp` samples
/// per pixel.
pub fn filter_input(
    subject: &paper::Subject,
    shot: paper::Shot,
    reference_spp: u32,
) -> Result<crate::bench::filter::FilterBenchInput, GuidedBenchError> {
    let paper::Subject {
        backend,
        display,
        name,
        scene,
    } = *subject;
    let paper::Shot {
        size,
        fov,
        iterations,
        seed,
    } = shot;
    let base = paper::settings(scene, size, seed, crate::trace::path::DEFAULT_MAX_DEPTH).map_err(
        |source| GuidedBenchError::Camera {
            scene: name.to_string(),
            source,
        },
    )?;
    let settings = |seed: u32| TraceSettings { seed, ..base };
    let mut g = paper::guided(
        backend,
        scene,
        settings(seed),
        display,
        GuideConfig::default(),
        paper::roi(fov)?,
    )?;
    for _ in 0..iterations.max(1) {
        g.run_frame(false)?;
    }
    let accumulation = g.accumulation()?;
    let dgi = g.dgi()?;
    drop(g);
    let reference = paper::reference_image(
        backend,
        scene,
        settings(seed ^ 0x5eed),
        reference_spp.max(1),
    )?;
    let roi_mask = dgi.iter().map(|&d| d == 0.0).collect();
    Ok(crate::bench::filter::FilterBenchInput {
        label: format!(
            "guided render of {name}, {iterations} iterations; reference {reference_spp} spp full frame"
        ),
        reference,
        accumulation,
        dgi,
        roi_mask,
    })
}
