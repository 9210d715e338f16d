//! The render loop of a guided render (`render --guide`, `demo`): frames with the ROI — and a
//! tracked head's eye — from a [`GuideSource`] until a stop rule says so, then the picture.
//!
//! [`run_guided`] drives any [`Render`]; [`Steering`] is what it decides each iteration from the
//! guide, which rank 0 of a render across ranks decides the same way and sends the others
//! (`super::cluster::run_cluster`).

use std::path::Path;
use std::time::Instant;

use glam::{DVec3, Vec3};

use super::guide::GuideSource;
use crate::display::DisplayModel;
use crate::filter::{Denoiser, Filter, FilterParams};
use crate::frame::denoise_picture;
use crate::frame::stop::{RoiProgress, StopCondition, StopReason, reached};
use crate::frame::{EyeFollow, EyeMove, FrameError, GuideConfig, Render, Renderer};
use crate::gpu::Backend;
use crate::output::OutputError;
use crate::roi::dgi::Roi;
use crate::scene::Scene;
use crate::trace::path::TraceSettings;
use crate::trace::reuse::ReuseStats;
use crate::trace::wall::WallCamera;

/// When a guided render stops.
#[derive(Clone, Debug, Default)]
pub struct Stopping {
    /// At most this many iterations (`None`: until a condition is reached).
    pub iterations: Option<u32>,
    pub until: Vec<StopCondition>,
}

/// How often the ROI's progress is measured for a stop condition (on a GPU renderer of one
/// band a submit and 208 bytes back, `Renderer::roi_stats`; elsewhere a read-back; across ranks
/// a gather of the ROI's sums on rank 0).
pub const PROGRESS_INTERVAL_S: f64 = 0.5;

/// What the guide asks of a render iteration by iteration: the ROI when it changes, and the
/// tracked head's eye under the restart rule (DESIGN.md §11), with what became of the eyes.
pub struct Steering<'s> {
    source: &'s GuideSource,
    /// The iterations the guide's time axis is spread over.
    spread: u32,
    /// The ROI given last.
    current: Option<Roi>,
    /// (iteration, eye): where the eye restarted the accumulation.
    pub eye_restarts: Vec<(u32, DVec3)>,
    /// (iteration, eye, what it carried): where the eye moved and the accumulation was
    /// carried over ([`crate::frame::EyeMove::Reuse`]).
    pub eye_reuses: Vec<(u32, DVec3, ReuseStats)>,
    /// Eyes refused (on or behind a tile's plane: the eye stayed where it was).
    pub eyes_refused: u32,
}

impl<'s> Steering<'s> {
    /// `source` spread over `stopping`'s iterations (over one without a number).
    #[must_use]
    pub fn new(source: &'s GuideSource, stopping: &Stopping) -> Self {
        Self {
            source,
            spread: stopping.iterations.unwrap_or(1),
            current: None,
            eye_restarts: Vec::new(),
            eye_reuses: Vec::new(),
            eyes_refused: 0,
        }
    }

    /// The ROI of iteration `k` where it differs from the one given last (always at 0).
    pub fn roi_change(&mut self, k: u32) -> Option<Option<Roi>> {
        let roi = self.source.roi_at(k, self.spread);
        (k == 0 || roi != self.current).then(|| {
            self.current = roi;
            roi
        })
    }

    /// The tracked head's eye of iteration `k` applied to `r` under the restart rule (a wall
    /// camera's only): `Some(eye)` where the accumulation restarted there.
    pub fn follow_eye<R: Render>(&mut self, r: &mut R, k: u32) -> Result<Option<DVec3>, R::Error> {
        if r.wall().is_none() {
            return Ok(None);
        }
        let Some(eye) = self.source.eye_at(k, self.spread) else {
            return Ok(None);
        };
        Ok(match r.follow_eye(eye, self.source.eye_threshold_m())? {
            EyeFollow::Kept => None,
            EyeFollow::Restarted => {
                self.eye_restarts.push((k, eye));
                Some(eye)
            }
            EyeFollow::Reused(stats) => {
                self.eye_reuses.push((k, eye, stats));
                Some(eye)
            }
            EyeFollow::Refused(_) => {
                self.eyes_refused += 1;
                None
            }
        })
    }
}

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
    /// The accumulation's sums (RGB and Σ luminance²) where [`GuidedRender::keep_sums`] asked
    /// for them (with `counts`, the whole accumulation), else empty.
    pub sums: Vec<[f32; 4]>,
    /// Wall-clock seconds of the iterations (read-back and filter excluded), from the first
    /// frame on: the build and the upload before it are one-time work.
    pub seconds: f64,
    /// Seconds spent packing the scene and building its BVH ([`Renderer::build_seconds`]).
    pub build_seconds: f64,
    /// Seconds spent preparing the backend before the first frame
    /// ([`Renderer::upload_seconds`]).
    pub upload_seconds: f64,
    pub stop: StopReason,
    /// The ROI's last measured progress (with stop conditions only).
    pub progress: Option<RoiProgress>,
    /// Iterations in the accumulation the picture shows (since the last restart of a moving
    /// eye; `iterations` without one).
    pub accumulated: u32,
    /// (iteration, eye): where a tracked head's eye restarted the accumulation (the wall
    /// camera only; the ROI and its DGI are kept).
    pub eye_restarts: Vec<(u32, glam::DVec3)>,
    /// (iteration, eye, what it carried): where a tracked head's eye moved and the
    /// accumulation was carried over.
    pub eye_reuses: Vec<(u32, glam::DVec3, ReuseStats)>,
    /// Head eyes refused (on or behind a tile's plane: the eye stayed where it was).
    pub eyes_refused: u32,
    /// Pixels the denoiser dropped for a NaN or infinite sum (DESIGN.md §8).
    pub denoise_dropped: u64,
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

/// What the render loop did; the renderer holds the accumulation.
#[derive(Clone, Debug)]
pub struct Steered {
    pub iterations: u32,
    /// Wall-clock seconds of the iterations.
    pub seconds: f64,
    pub stop: StopReason,
    /// The ROI's last measured progress (with stop conditions only).
    pub progress: Option<RoiProgress>,
    /// (iteration, eye): where a tracked head's eye restarted the accumulation.
    pub eye_restarts: Vec<(u32, DVec3)>,
    /// (iteration, eye, what it carried): where it moved and the accumulation was carried.
    pub eye_reuses: Vec<(u32, DVec3, ReuseStats)>,
    /// Head eyes refused (on or behind a tile's plane).
    pub eyes_refused: u32,
}

/// The render loop: frames of `r` with the ROI from `source` until `stopping` says so. A
/// replay with a tracked head moves a wall camera's eye along with the ROI (its eyes spread
/// over the iterations on the same time axis), under the restart rule: an eye past the
/// threshold from the one the accumulation started with restarts it, the ROI kept.
/// `on_iteration` is called after each frame with the number done and the ROI's progress when
/// it was measured.
pub fn run_guided<R: Render>(
    r: &mut R,
    source: &GuideSource,
    stopping: &Stopping,
    mut on_iteration: impl FnMut(u32, Option<&RoiProgress>),
) -> Result<Steered, R::Error> {
    let t0 = Instant::now();
    let needs_progress = stopping.until.iter().any(StopCondition::needs_progress);
    let mut steering = Steering::new(source, stopping);
    let mut last_check = f64::NEG_INFINITY;
    let mut progress = None;
    let mut k = 0;
    let stop = loop {
        if stopping.iterations.is_some_and(|n| k >= n) {
            break StopReason::Iterations(k);
        }
        if let Some(roi) = steering.roi_change(k) {
            r.set_roi(roi)?;
        }
        steering.follow_eye(r, k)?;
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
    Ok(Steered {
        iterations: k,
        seconds: t0.elapsed().as_secs_f64(),
        stop,
        progress,
        eye_restarts: steering.eye_restarts,
        eye_reuses: steering.eye_reuses,
        eyes_refused: steering.eyes_refused,
    })
}

/// A guided render as [`render_guided`] makes it: what the frames trace and how the picture is
/// filtered.
#[derive(Clone, Debug)]
pub struct GuidedRender<'a> {
    pub settings: TraceSettings,
    /// The display the ROI is aimed at.
    pub model: &'a DisplayModel,
    /// The wall camera the frames trace through (DESIGN.md §11): only the pixels its display
    /// shows are scheduled and traced, and the others come out black.
    pub wall: Option<WallCamera>,
    pub config: GuideConfig,
    pub filter: FilterParams,
    /// What denoises the filtered picture (`--denoise`; DESIGN.md §8), steered by the view's
    /// features.
    pub denoise: Option<Denoiser<'a>>,
    /// Whether the result keeps the accumulation's sums (the demo's side-by-side crops).
    pub keep_sums: bool,
    /// What a tracked head's move does to the accumulation (`--on-eye-move`).
    pub on_eye_move: EyeMove,
}

/// One process's guided render of `scene` on `backend`: the render loop ([`run_guided`]), then
/// the accumulation read back and filtered.
pub fn render_guided(
    backend: &Backend,
    scene: &Scene,
    job: GuidedRender<'_>,
    source: &GuideSource,
    stopping: &Stopping,
    on_iteration: impl FnMut(u32, Option<&RoiProgress>),
) -> Result<GuidedResult, FrameError> {
    let [w, h] = [job.settings.width, job.settings.height];
    let mut r = Renderer::guided_wall(
        backend,
        scene,
        job.settings,
        job.model,
        job.config,
        job.wall,
    )?;
    r.set_on_eye_move(job.on_eye_move);
    let (build_seconds, upload_seconds) = (r.build_seconds, r.upload_seconds);
    let run = run_guided(&mut r, source, stopping, on_iteration)?;
    let accumulated = r.iteration();
    let wall = r.wall().cloned();
    // The features depend on the view alone: taken before the accumulation leaves the renderer.
    let features = job.denoise.map(|_| r.take_features()).transpose()?;
    let (acc, dgi) = r.finish()?;
    let mut image = Filter::new(backend).image(&job.filter, &acc, &dgi)?;
    let mut dropped = 0;
    if let (Some(denoiser), Some(features)) = (job.denoise, &features) {
        (image, dropped) =
            denoise_picture(backend, denoiser, &acc, features, &image, wall.as_ref())?;
    }
    if let Some(wc) = &wall {
        wc.blank_unshown(&mut image);
    }
    Ok(GuidedResult {
        size: [w, h],
        iterations: run.iterations,
        image,
        dgi,
        counts: acc.count,
        sums: if job.keep_sums { acc.sum } else { Vec::new() },
        seconds: run.seconds,
        build_seconds,
        upload_seconds,
        stop: run.stop,
        progress: run.progress,
        accumulated,
        eye_restarts: run.eye_restarts,
        eye_reuses: run.eye_reuses,
        eyes_refused: run.eyes_refused,
        denoise_dropped: dropped,
    })
}
