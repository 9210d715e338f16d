//! The render loop across ranks (DESIGN.md §12): rank 0 follows the guide source and the stop
//! rule and broadcasts each frame's control (iteration, stop, ROI change); every rank runs the
//! cluster frame; at the end rank 0 gathers the owners' sums.

use std::time::Instant;

use super::guide::GuideSource;
use super::render::Stopping;
use crate::cluster::exchange::ExchangeError;
use crate::cluster::{Cluster, ClusterError, ClusterFrameStats, ClusterRenderer, FrameControl};
use crate::frame::EyeFollow;
use crate::frame::stop::{RoiProgress, StopCondition, StopReason, reached};
use crate::roi::dgi::Roi;
use crate::trace::accum::Accumulation;

/// A fault a test injects (`--cluster-fault`): that rank ends, or stops answering, at the
/// start of that iteration — what the other ranks' deadlines are for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    Exit { rank: usize, iteration: u32 },
    Hang { rank: usize, iteration: u32 },
}

impl Fault {
    /// Acts if the fault is this rank's at iteration `k`.
    fn strike(&self, rank: usize, k: u32) {
        match *self {
            Self::Exit { rank: r, iteration } if r == rank && iteration == k => {
                eprintln!("raygun: rank {rank}: --cluster-fault: ending at iteration {k}");
                std::process::exit(9);
            }
            Self::Hang { rank: r, iteration } if r == rank && iteration == k => {
                eprintln!(
                    "raygun: rank {rank}: --cluster-fault: no longer answering at iteration {k}"
                );
                loop {
                    std::thread::sleep(std::time::Duration::from_secs(3600));
                }
            }
            _ => {}
        }
    }
}

/// What a render across ranks did on this rank.
pub struct ClusterRun {
    pub iterations: u32,
    /// Wall-clock seconds of the iterations on this rank (the gather excluded).
    pub seconds: f64,
    pub stop: StopReason,
    /// This rank's frames.
    pub frames: Vec<ClusterFrameStats>,
    /// Rank 0: the whole accumulation and the DGI of the last frame (`None` elsewhere, and
    /// when not asked for).
    pub gathered: Option<(Accumulation, Vec<f32>)>,
    /// Rank 0: the ROI's last measured progress (with stop conditions on it only).
    pub progress: Option<RoiProgress>,
    /// Iterations in the accumulation at the end (since the last restart of a moving eye).
    pub accumulated: u32,
    /// Rank 0: (iteration, eye) where the guide's tracked head restarted the accumulation.
    pub eye_restarts: Vec<(u32, glam::DVec3)>,
    /// Rank 0: head eyes refused (on or behind a tile's plane).
    pub eyes_refused: u32,
}

/// How often rank 0 measures the ROI's progress for a stop condition (the one-process loop's
/// interval): a gather of the ROI pixels' sums.
const PROGRESS_INTERVAL_S: f64 = 0.5;

/// Runs frames on every rank until rank 0's stop rule says so; then, with `gather`, rank 0
/// assembles the whole accumulation (every rank must pass the same `gather`). `source` steers a guided render
/// (read on rank 0 only; `None`: a full frame). `--until time:S` is rank 0's clock; a condition
/// on the ROI's progress is measured every half second from the owners' ROI sums
/// ([`ClusterRenderer::roi_progress`]). `fault` is a test's. `on_iteration` hears each finished
/// frame on this rank, and rank 0's progress when it was measured.
pub fn run_cluster(
    c: &mut Cluster,
    r: &mut ClusterRenderer,
    source: Option<&GuideSource>,
    stopping: &Stopping,
    fault: Option<Fault>,
    gather: bool,
    mut on_iteration: impl FnMut(&ClusterFrameStats, Option<&RoiProgress>),
) -> Result<ClusterRun, ClusterError> {
    let t0 = Instant::now();
    let needs_progress = stopping.until.iter().any(StopCondition::needs_progress);
    let mut last_check = f64::NEG_INFINITY;
    let mut progress: Option<RoiProgress> = None;
    let spread = stopping.iterations.unwrap_or(1);
    let mut current: Option<Roi> = None;
    let mut frames = Vec::new();
    let mut k = 0u32;
    let (mut eye_restarts, mut eyes_refused) = (Vec::new(), 0);
    let stop = loop {
        if let Some(f) = &fault {
            f.strike(c.rank(), k);
        }
        let control = if c.is_root() {
            let elapsed = t0.elapsed().as_secs_f64();
            let stop = match stopping.iterations {
                Some(n) if k >= n => Some(StopReason::Iterations(k)),
                _ => reached(&stopping.until, progress.as_ref(), elapsed).map(StopReason::Reached),
            };
            let measure = needs_progress && elapsed - last_check >= PROGRESS_INTERVAL_S;
            if measure {
                last_check = elapsed;
            }
            let roi = source.map(|s| s.roi_at(k, spread));
            let changed = roi.filter(|&roi| k == 0 || roi != current);
            if let Some(roi) = changed {
                current = roi;
            }
            // The tracked head (a wall camera only): rank 0 applies the restart rule, and an
            // eye it restarted at goes to the other ranks with this frame's control.
            let mut moved = None;
            if r.wall().is_some()
                && let Some(s) = source
                && let Some(e) = s.eye_at(k, spread)
            {
                match r.follow_eye(e, s.eye_threshold_m())? {
                    EyeFollow::Kept => {}
                    EyeFollow::Restarted => {
                        eye_restarts.push((k, e));
                        moved = Some(e);
                    }
                    EyeFollow::Refused(_) => eyes_refused += 1,
                }
            }
            FrameControl {
                iteration: k,
                stop: stop.is_some(),
                measure,
                roi: changed,
                eye: moved,
            }
        } else {
            FrameControl {
                iteration: k,
                stop: false,
                measure: false,
                roi: None,
                eye: None,
            }
        };
        let bytes = c.broadcast(&format!("the control of iteration {k}"), control.encode())?;
        let got = FrameControl::decode(&bytes).ok_or_else(|| ExchangeError::Malformed {
            rank: 0,
            what: format!("the control of iteration {k}"),
            reason: format!("{} bytes that are no control message", bytes.len()),
        })?;
        if got.iteration != k {
            return Err(ExchangeError::Malformed {
                rank: 0,
                what: format!("the control of iteration {k}"),
                reason: format!("iteration {}, this rank is at iteration {k}", got.iteration),
            }
            .into());
        }
        if !c.is_root()
            && let Some(e) = got.eye
        {
            r.move_eye(e)?;
        }
        if got.stop {
            let elapsed = t0.elapsed().as_secs_f64();
            break match (stopping.iterations, c.is_root()) {
                (Some(n), _) if k >= n => StopReason::Iterations(k),
                (_, true) => reached(&stopping.until, progress.as_ref(), elapsed)
                    .map_or(StopReason::Iterations(k), StopReason::Reached),
                // Only rank 0 knows which condition it was.
                (_, false) => StopReason::Iterations(k),
            };
        }
        if let Some(roi) = got.roi {
            r.set_roi(roi)?;
        }
        let stats = r.run_frame(c)?;
        let measured = if got.measure {
            if let Some(p) = r.roi_progress(c)? {
                progress = p;
            }
            c.is_root()
        } else {
            false
        };
        on_iteration(&stats, progress.as_ref().filter(|_| measured));
        frames.push(stats);
        k += 1;
    };
    let seconds = t0.elapsed().as_secs_f64();
    let accumulated = r.iteration();
    let gathered = if gather { r.gather(c)? } else { None };
    Ok(ClusterRun {
        iterations: k,
        seconds,
        stop,
        frames,
        gathered,
        progress,
        accumulated,
        eye_restarts,
        eyes_refused,
    })
}
