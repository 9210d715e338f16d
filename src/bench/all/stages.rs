//! Per-stage times of a guided iteration (DESIGN.md §1): DGI (on the iteration after an ROI change,
//! and spread over the run), mask + compaction, tracing, the fast filter and display, each
//! measured inside the iteration's own wall-clock interval so that their sum can be checked
//! against it.
//!
//! *Display* is what the viewer does to show the filtered image: exposure scaling, the sRGB
//! transfer function and 8-bit RGBA packing — the bytes it hands to egui as a texture. Filter
//! and display run every iteration here, as if each iteration were shown (the viewer shows one
//! picture per UI frame). A row's *picture* says which way: **host** — the accumulation and the
//! DGI read back, the filter on a copy (its time the kernels', the copies *filter transfers*),
//! the conversion on the CPU ([`display_rgba`]; a test checks it against the viewer's
//! picture); **GPU** — the filter on the renderer's own buffers and the display kernel, the
//! 8-bit picture read back ([`Renderer::shown_picture`]); **texture** — the same kernels, the
//! picture copied into a texture on the GPU and nothing read back
//! ([`Renderer::shown_picture_into`], the window's picture where it draws with the renderer's
//! device). `bench all` measures the three on a GPU.

use std::time::Instant;

use serde::Serialize;

use crate::filter::{Filter, FilterParams};
use crate::frame::{GuideConfig, Render, Renderer};
use crate::gpu::Backend;
use crate::output::srgb8::display_rgba;

use super::AllBenchError;
use crate::bench::paper::{Shot, Subject};

/// One FOV's stage times (ms). Stage columns are means over the iterations, so that they add
/// up: the mean of the per-iteration sums is the sum of the means.
#[derive(Clone, Debug, Serialize)]
pub struct StageRow {
    pub fov_deg: f64,
    pub size: [u32; 2],
    pub iterations: u32,
    /// Mean share of the pixels traced per iteration.
    pub share_sampled: f64,
    /// The DGI of the iteration after the ROI change (None: the adapter has no timestamps).
    pub dgi_ms_per_change: Option<f64>,
    /// That DGI spread over the `iterations` (one change per run).
    pub dgi_ms_amortised: f64,
    /// Mask + compaction (+ indirect arguments).
    pub schedule_ms: f64,
    pub trace_ms: f64,
    pub filter_ms: f64,
    pub display_ms: f64,
    /// DGI amortised + schedule + trace + filter + display.
    pub stage_sum_ms: f64,
    /// Wall clock of whole iterations (ROI change, frame, read-backs, filter, display).
    pub iteration_ms_mean: f64,
    pub iteration_ms_median: f64,
    pub iteration_ms_min: f64,
    /// The accumulation's and the DGI's read-back (GPU; the CPU twin clones them).
    pub readback_ms: f64,
    /// The filter's wall clock beyond its kernels: its inputs' upload, its preparation and its
    /// picture's read-back (GPU; about 0 on the CPU, where the filter's time is its wall clock).
    pub filter_transfer_ms: f64,
    /// iteration_ms_mean − stage_sum_ms − readback_ms − filter_transfer_ms: the frame's
    /// submission and waits, bookkeeping.
    pub other_ms: f64,
    /// The target iteration on the iteration with an ROI change: DGI + schedule +
    /// trace + fast filter (display excluded).
    pub target_iteration_ms: f64,
    /// Whether the GPU stages came from timestamps (else wall clock).
    pub gpu_timestamps: bool,
    /// How the picture was made: `host` (read back, filter a copy, convert on the CPU), `gpu`
    /// (filtered and converted on the GPU, 8 bits read back: `Renderer::shown_picture`) or
    /// `texture` (the same, into a texture there: `Renderer::shown_picture_into`).
    pub picture: PicturePath,
}

/// The ways a GPU renderer's picture reaches the window (the CPU twin has the first).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PicturePath {
    /// The accumulation and DGI read back, the filter on a copy, the conversion on the CPU.
    Host,
    /// The filter on the renderer's own buffers and the conversion on the GPU; 4 bytes a pixel
    /// read back ([`Renderer::shown_picture`]).
    Gpu,
    /// As `Gpu`, but written into a texture on the GPU and nothing read back
    /// ([`Renderer::shown_picture_into`]: the window that draws with the renderer's device).
    Texture,
}

impl PicturePath {
    /// The way's name in the tables: host, GPU or texture.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            PicturePath::Host => "host",
            PicturePath::Gpu => "GPU",
            PicturePath::Texture => "texture",
        }
    }
}

/// Measures `shot.iterations` guided iterations of `subject.scene` in the paper's setup
/// (viewer at (0, 0, 1) m pointing at the wall centre, square cone of `shot.fov` degrees) with
/// the ROI set on the first, filtering with `filter` and converting for display with
/// `exposure` every one, the picture made the `picture` way (a GPU renderer whose frame is one
/// band; else the host way, and the row says so).
pub fn measure(
    subject: &Subject,
    shot: Shot,
    filter: &FilterParams,
    exposure: f32,
    picture: PicturePath,
) -> Result<StageRow, AllBenchError> {
    let Subject {
        backend,
        display,
        name,
        scene,
    } = *subject;
    let Shot {
        size,
        fov,
        iterations,
        seed,
    } = shot;
    let [w, h] = size;
    let settings =
        crate::bench::paper::settings(scene, size, seed, crate::trace::path::DEFAULT_MAX_DEPTH)
            .map_err(|source| AllBenchError::Camera {
                scene: name.to_string(),
                source,
            })?;
    let roi = crate::bench::paper::roi(fov)?;
    let mut g = Renderer::guided(backend, scene, settings, display, GuideConfig::default())?;
    let filter_stage = Filter::new(backend);
    let resident = picture != PicturePath::Host && g.shows_on_gpu(filter);
    let texture = match (backend, resident && picture == PicturePath::Texture) {
        (Backend::Gpu(ctx), true) => Some(ctx.picture_texture(
            "stages picture",
            [w, h],
            wgpu::TextureFormat::Rgba8Unorm,
            wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        )),
        _ => None,
    };
    let n = iterations.max(1);
    let (mut dgi_change, mut stamps) = (None, matches!(backend, Backend::Cpu));
    let (mut sched, mut trace, mut filt, mut disp) = (0f64, 0f64, 0f64, 0f64);
    let (mut readback, mut transfer) = (0f64, 0f64);
    let (mut walls, mut pixels) = (Vec::new(), 0u64);
    for i in 0..n {
        let t0 = Instant::now();
        if i == 0 {
            // The CPU twin computes the DGI here (its time comes back in the frame's stats);
            // the GPU records it into the frame.
            g.set_roi(Some(roi))?;
        }
        let s = g.run_frame(true)?;
        let (ms_readback, ms_filter, ms_transfer, ms_display, stamped) = if resident {
            // Filtered and converted on the GPU; the 8-bit picture read back, or written into
            // the window's texture there.
            let t = Instant::now();
            let st = match &texture {
                Some(texture) => g.shown_picture_into_timed(filter, exposure, false, texture)?,
                None => {
                    let shown = g.shown_picture(filter, exposure, false, true)?;
                    std::hint::black_box(&shown.rgba);
                    shown.times.expect("timed")
                }
            };
            let wall = t.elapsed().as_secs_f64() * 1e3;
            let transfer = (wall - st.filter_ms - st.display_ms).max(0.0);
            (
                0.0,
                st.filter_ms,
                transfer,
                st.display_ms,
                st.gpu_timestamps,
            )
        } else {
            let t = Instant::now();
            let acc = g.accumulation()?;
            let dgi = g.dgi()?;
            let ms_readback = t.elapsed().as_secs_f64() * 1e3;
            let t = Instant::now();
            let (image, ms_filter, stamped) = filter_stage.timed_image(filter, &acc, &dgi)?;
            // The kernels' time is at most the call's wall clock (timestamps lie inside it).
            let ms_transfer = (t.elapsed().as_secs_f64() * 1e3 - ms_filter).max(0.0);
            let t = Instant::now();
            let rgba = display_rgba(&image, exposure);
            std::hint::black_box(&rgba);
            let ms_display = t.elapsed().as_secs_f64() * 1e3;
            (ms_readback, ms_filter, ms_transfer, ms_display, stamped)
        };
        walls.push(t0.elapsed().as_secs_f64() * 1e3);
        if s.dgi_recomputed {
            dgi_change = s.ms_dgi;
        }
        if backend.is_gpu() {
            stamps = stamped;
        }
        pixels += u64::from(s.pixels.unwrap_or(0));
        sched += s.ms_schedule.unwrap_or(0.0);
        trace += s.ms_trace.unwrap_or(0.0);
        filt += ms_filter;
        disp += ms_display;
        readback += ms_readback;
        transfer += ms_transfer;
    }
    let k = f64::from(n);
    let (sched, trace, filt, disp) = (sched / k, trace / k, filt / k, disp / k);
    let (readback, transfer) = (readback / k, transfer / k);
    let dgi_amortised = dgi_change.unwrap_or(0.0) / k;
    let stage_sum = dgi_amortised + sched + trace + filt + disp;
    let mean = walls.iter().sum::<f64>() / k;
    Ok(StageRow {
        fov_deg: fov,
        size,
        iterations: n,
        share_sampled: pixels as f64 / k / (f64::from(w) * f64::from(h)),
        dgi_ms_per_change: dgi_change,
        dgi_ms_amortised: dgi_amortised,
        schedule_ms: sched,
        trace_ms: trace,
        filter_ms: filt,
        display_ms: disp,
        stage_sum_ms: stage_sum,
        iteration_ms_median: crate::bench::median(walls.clone()),
        iteration_ms_min: walls.iter().copied().fold(f64::INFINITY, f64::min),
        iteration_ms_mean: mean,
        readback_ms: readback,
        filter_transfer_ms: transfer,
        other_ms: mean - stage_sum - readback - transfer,
        target_iteration_ms: dgi_change.unwrap_or(0.0) + sched + trace + filt,
        gpu_timestamps: stamps,
        picture: if resident { picture } else { PicturePath::Host },
    })
}

/// The stage table as Markdown.
#[must_use]
pub fn markdown(rows: &[StageRow], device: &str) -> String {
    let mut s = format!(
        "Device: {device}. Means over the iterations (ms), so the stages add up; the wall clock of whole iterations is given as mean, median and min. *Display* = the viewer's conversion of the filtered image to the 8-bit sRGB RGBA texture it uploads (CPU); *read-back* = the accumulation's and the DGI's read-back (a copy on the CPU); *filter transfers* = the filter's wall clock beyond its kernels (its inputs' upload, preparation, its picture's read-back; about 0 on the CPU); *other* = the rest of the wall clock (the frame's submission and waits, bookkeeping). Filter and display run every iteration here. The *target iteration* is DGI on a change + mask/compaction + trace + fast filter. *Picture*: host = the accumulation and DGI read back, filtered as a copy, converted on the CPU (the columns above); GPU = filtered on the renderer's own buffers and converted by the display kernel, 4 bytes a pixel read back (`Renderer::shown_picture`): its *display* is that kernel, its *filter transfers* the 8-bit read-back and the waits, its *read-back* 0; texture = the same kernels, the picture copied into a texture on the GPU and nothing read back (`Renderer::shown_picture_into`, what the window does when it draws with the renderer's device): its *filter transfers* the copy, the submission and the wait.\n\n| FOV | size | iterations | share sampled | DGI per change | DGI amortised | mask+compaction | trace | filter | display | sum of stages | other | iteration (mean / median / min) | target iteration | read-back | filter transfers | picture |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    );
    for r in rows {
        s += &format!(
            "| {}° | {}×{} | {} | {:.2} % | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} / {:.3} / {:.3} | {:.3} | {:.3} | {:.3} | {} |\n",
            r.fov_deg,
            r.size[0],
            r.size[1],
            r.iterations,
            100.0 * r.share_sampled,
            r.dgi_ms_per_change
                .map_or("– (no timestamps)".into(), |v| format!("{v:.3}")),
            r.dgi_ms_amortised,
            r.schedule_ms,
            r.trace_ms,
            r.filter_ms,
            r.display_ms,
            r.stage_sum_ms,
            r.other_ms,
            r.iteration_ms_mean,
            r.iteration_ms_median,
            r.iteration_ms_min,
            r.target_iteration_ms,
            r.readback_ms,
            r.filter_transfer_ms,
            r.picture.name(),
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::display::DisplayModel;
    use crate::scene::Scene;
    use crate::trace::camera::RenderCamera;
    use crate::trace::path::TraceSettings;
    use crate::viewer::core::ViewerCore;
    use crate::viewer::state::{RoiSource, ViewerState};

    /// The display stage converts exactly as the viewer's picture does.
    #[test]
    fn display_rgba_is_the_viewers_picture() {
        let model = DisplayModel::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/display-models/hornet.json"
        ))
        .unwrap();
        let scene = Scene::open("builtin:cornell").unwrap();
        let (w, h) = (32, 18);
        let base = TraceSettings {
            width: w,
            height: h,
            seed: 5,
            max_depth: 3,
            camera: RenderCamera::choose(&scene, None, w, h).unwrap(),
        };
        let backend = Backend::Cpu;
        let mut state = ViewerState::new(RoiSource::Mouse, 3);
        state.roi_outline = false;
        state.exposure = 0.75;
        state.click(&model, glam::DVec2::new(16.0, 9.0), [w, h]);
        let mut core = ViewerCore::new(&backend, &scene, &model, base, state).unwrap();
        for _ in 0..3 {
            core.step(std::time::Duration::ZERO).unwrap();
        }
        let pic = core.picture().unwrap();
        assert!(
            pic.rgba.iter().any(|&v| v != 0 && v != 255),
            "a flat picture proves nothing"
        );
        assert_eq!(display_rgba(&pic.image, 0.75), pic.rgba);
        assert_ne!(
            display_rgba(&pic.image, 0.0),
            pic.rgba,
            "exposure is applied"
        );
    }
}
