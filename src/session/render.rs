//! The render loop that `render --guide`, `demo` and the benchmarks share: guided frames with
//! the ROI from a [`GuideSource`] until a stop rule says so, then the picture.

use std::path::Path;
use std::time::Instant;

use glam::Vec3;

use super::guide::GuideSource;
use crate::display::DisplayModel;
use crate::filter::{Filter, FilterParams};
use crate::frame::stop::{RoiProgress, StopCondition, StopReason, reached};
use crate::frame::{EyeFollow, FrameError, GuideConfig, Renderer};
use crate::gpu::Backend;
use crate::output::OutputError;
use crate::roi::dgi::Roi;
use crate::scene::Scene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

/// When a guided render stops.
#[derive(Clone, Debug, Default)]
pub struct Stopping {
    /// At most this many iterations (`None`: until a condition is reached).
    pub iterations: Option<u32>,
    pub until: Vec<StopCondition>,
}

/// How often the ROI's progress is measured for a stop condition (on a GPU renderer of one
/// band a submit and 208 bytes back, `Renderer::roi_stats`; elsewhere a read-back).
const PROGRESS_INTERVAL_S: f64 = 0.5;

/// What a guided render produced.
pub struct GuidedResult {
    pub size: [u32; 2],
    pub iterations: u32,
    /// The filtered mean image (linear RGB, row-major).
    pub image: Vec<Vec3>,
    /// The DGI of the last iteration.
    pub dgi: Vec<f32>,
    /// Samples per pixel.
    pub counts: Vec<u32>,
    /// Wall-clock seconds of the iterations (read-back and filter excluded).
    pub seconds: f64,
    pub stop: StopReason,
    /// The ROI's last measured progress (with stop conditions only).
    pub progress: Option<RoiProgress>,
    /// Iterations in the accumulation the picture shows (since the last restart of a moving
    /// eye; `iterations` without one).
    pub accumulated: u32,
    /// (iteration, eye): where a tracked head's eye restarted the accumulation (the wall
    /// camera only; the ROI and its DGI are kept).
    pub eye_restarts: Vec<(u32, glam::DVec3)>,
    /// Head eyes refused (on or behind a tile's plane: the eye stayed where it was).
    pub eyes_refused: u32,
}

impl GuidedResult {
    /// Samples taken in all.
    #[must_use]
    pub fn samples(&self) -> u64 {
        self.counts.iter().map(|&c| u64::from(c)).sum()
    }

    /// Samples as a share of full frames over the accumulated iterations.
    #[must_use]
    pub fn sample_share(&self) -> f64 {
        self.samples() as f64
            / (f64::from(self.size[0]) * f64::from(self.size[1]) * f64::from(self.accumulated))
    }

    /// Writes the DGI and the sample counts where given (EXR or PNG by extension).
    pub fn write_guides(
        &self,
        dgi_out: Option<&Path>,
        counts_out: Option<&Path>,
    ) -> Result<(), OutputError> {
        let [w, h] = self.size;
        if let Some(p) = dgi_out {
            crate::output::write_gray(p, w, h, &self.dgi, crate::output::DGI_CHANNEL)?;
        }
        if let Some(p) = counts_out {
            let counts: Vec<f32> = self.counts.iter().map(|&c| c as f32).collect();
            crate::output::write_gray(p, w, h, &counts, "samples")?;
        }
        Ok(())
    }
}

/// Runs guided frames with the ROI from `source` until `stopping` says so, then reads back and
/// filters. `on_iteration` is called after each frame with the number done and the ROI's
/// progress when it was measured.
#[allow(clippy::too_many_arguments)]
pub fn render_guided(
    backend: &Backend,
    scene: &Scene,
    settings: TraceSettings,
    model: &DisplayModel,
    config: GuideConfig,
    filter: &FilterParams,
    source: &GuideSource,
    stopping: &Stopping,
    on_iteration: impl FnMut(u32, Option<&RoiProgress>),
) -> Result<GuidedResult, FrameError> {
    render_guided_wall(
        backend,
        scene,
        settings,
        model,
        None,
        config,
        filter,
        source,
        stopping,
        on_iteration,
    )
}

/// [`render_guided`] through the wall camera `wall` when given (DESIGN.md §11): only the pixels
/// its display shows are scheduled and traced, and the others come out black. A replay with a
/// tracked head moves the wall camera's eye along with the ROI (its eyes spread over the
/// iterations on the same time axis), under the restart rule: an eye past the threshold from
/// the one the accumulation started with restarts it, the ROI kept.
#[allow(clippy::too_many_arguments)]
pub fn render_guided_wall(
    backend: &Backend,
    scene: &Scene,
    settings: TraceSettings,
    model: &DisplayModel,
    wall: Option<WallCamera>,
    config: GuideConfig,
    filter: &FilterParams,
    source: &GuideSource,
    stopping: &Stopping,
    mut on_iteration: impl FnMut(u32, Option<&RoiProgress>),
) -> Result<GuidedResult, FrameError> {
    let mut r = Renderer::guided_wall(backend, scene, settings, model, config, wall)?;
    let t0 = Instant::now();
    let needs_progress = stopping.until.iter().any(StopCondition::needs_progress);
    let spread = stopping.iterations.unwrap_or(1);
    let mut current: Option<Roi> = None;
    let mut last_check = f64::NEG_INFINITY;
    let mut progress = None;
    let mut eye_restarts = Vec::new();
    let mut eyes_refused = 0;
    let threshold = source.eye_threshold_m();
    let mut k = 0;
    let stop = loop {
        if stopping.iterations.is_some_and(|n| k >= n) {
            break StopReason::Iterations(k);
        }
        let roi = source.roi_at(k, spread);
        if k == 0 || roi != current {
            r.set_roi(roi)?;
            current = roi;
        }
        if r.wall().is_some()
            && let Some(eye) = source.eye_at(k, spread)
        {
            match r.follow_eye(eye, threshold)? {
                EyeFollow::Kept => {}
                EyeFollow::Restarted => eye_restarts.push((k, eye)),
                EyeFollow::Refused(_) => eyes_refused += 1,
            }
        }
        r.run_frame(false)?;
        k += 1;
        let elapsed = t0.elapsed().as_secs_f64();
        let mut measured = false;
        if needs_progress && elapsed - last_check >= PROGRESS_INTERVAL_S {
            last_check = elapsed;
            progress = r.roi_progress()?;
            measured = true;
        }
        on_iteration(k, progress.as_ref().filter(|_| measured));
        if let Some(c) = reached(&stopping.until, progress.as_ref(), elapsed) {
            break StopReason::Reached(c);
        }
    };
    let seconds = t0.elapsed().as_secs_f64();
    let accumulated = r.iteration();
    let wall = r.wall().cloned();
    let (acc, dgi) = r.finish()?;
    let mut image = Filter::new(backend).image(filter, &acc, &dgi)?;
    if let Some(w) = &wall {
        w.blank_unshown(&mut image);
    }
    Ok(GuidedResult {
        size: [settings.width, settings.height],
        iterations: k,
        image,
        dgi,
        counts: acc.count,
        seconds,
        stop,
        progress,
        accumulated,
        eye_restarts,
        eyes_refused,
    })
}
