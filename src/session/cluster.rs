//! The render loop across ranks (DESIGN.md §12): rank 0 follows the guide source and the stop
//! rule and broadcasts each frame's control (iteration, stop, ROI change, a restarted eye);
//! every rank runs the cluster frame; at the end rank 0 gathers the owners' sums. For `view
//! --cluster`, rank 0's viewer sends each of its steps instead ([`ViewStep`], [`ClusterView`])
//! and the other ranks follow them until the window closes.

use std::time::Instant;

use glam::DVec3;

use super::guide::GuideSource;
use super::render::{PROGRESS_INTERVAL_S, Steering, Stopping};
use crate::cluster::exchange::ExchangeError;
use crate::cluster::owners::TileOwners;
use crate::cluster::picture::TilePicture;
use crate::cluster::{ClusterError, ClusterFrameStats, ClusterRenderer, FrameControl};
use crate::display::DisplayModel;
use crate::filter::{Blend, FilterKind, FilterParams};
use crate::frame::stop::{RoiProgress, StopCondition, StopReason, reached};
use crate::frame::{EyeFollow, FrameError, GuideConfig, Render};
use crate::gpu::GpuContext;
use crate::roi::dgi::{Falloff, Metric, Roi};
use crate::schedule::Order;
use crate::trace::accum::Accumulation;
use crate::trace::camera::RenderCamera;
use crate::trace::path::TraceSettings;

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

/// Runs frames on every rank until rank 0's stop rule says so; then, with `gather`, rank 0
/// assembles the whole accumulation (every rank must pass the same `gather`). `source` steers a
/// guided render (read on rank 0 only, as [`run_guided`](super::render::run_guided) reads it:
/// [`Steering`]; `None`: a full frame). `--until time:S` is rank 0's clock; a condition on the
/// ROI's progress is measured every half second from the owners' ROI sums
/// ([`Render::roi_progress`]). `fault` is a test's. `on_iteration` hears each finished frame on
/// this rank, and rank 0's progress when it was measured.
pub fn run_cluster(
    r: &mut ClusterRenderer<'_>,
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
    let (rank, root) = (r.cluster().rank(), r.cluster().is_root());
    // Rank 0 decides what the guide asks; the others hear it in each frame's control.
    let mut steering = source.filter(|_| root).map(|s| Steering::new(s, stopping));
    let mut frames = Vec::new();
    let mut k = 0u32;
    let stop = loop {
        if let Some(f) = &fault {
            f.strike(rank, k);
        }
        let control = if root {
            let elapsed = t0.elapsed().as_secs_f64();
            let stop = match stopping.iterations {
                Some(n) if k >= n => Some(StopReason::Iterations(k)),
                _ => reached(&stopping.until, progress.as_ref(), elapsed).map(StopReason::Reached),
            };
            let measure = needs_progress && elapsed - last_check >= PROGRESS_INTERVAL_S;
            if measure {
                last_check = elapsed;
            }
            // The ROI's change and the tracked head (a wall camera only): rank 0 applies the
            // restart rule, and an eye it restarted at goes to the other ranks with this
            // frame's control.
            let (roi, eye) = match &mut steering {
                Some(s) => (s.roi_change(k), s.follow_eye(r, k)?),
                None => (None, None),
            };
            FrameControl {
                iteration: k,
                stop: stop.is_some(),
                measure,
                roi,
                eye,
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
        let what = format!("the control of iteration {k}");
        let bytes = r.cluster_mut().broadcast(&what, control.encode())?;
        let got = FrameControl::decode(&bytes).ok_or_else(|| ExchangeError::Malformed {
            rank: 0,
            what: what.clone(),
            reason: format!("{} bytes that are no control message", bytes.len()),
        })?;
        if got.iteration != k {
            return Err(ExchangeError::Malformed {
                rank: 0,
                what,
                reason: format!("iteration {}, this rank is at iteration {k}", got.iteration),
            }
            .into());
        }
        if !root && let Some(e) = got.eye {
            r.move_eye(e)?;
        }
        if got.stop {
            let elapsed = t0.elapsed().as_secs_f64();
            break match (stopping.iterations, root) {
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
        let stats = r.run_frame(false)?;
        let measured = got.measure && {
            // Rank 0 gets the measurement; the others send their sums.
            progress = r.roi_progress()?;
            root
        };
        on_iteration(&stats, progress.as_ref().filter(|_| measured));
        frames.push(stats);
        k += 1;
    };
    // The last frame's samples reach their owners (counted in the run's time: they are part
    // of it).
    r.finish()?;
    let seconds = t0.elapsed().as_secs_f64();
    let accumulated = r.iteration();
    let gathered = if gather { r.gather()? } else { None };
    let (eye_restarts, eyes_refused) =
        steering.map_or((Vec::new(), 0), |s| (s.eye_restarts, s.eyes_refused));
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

/// What rank 0's viewer asks of every rank in `view --cluster` (DESIGN.md §12), one message at a
/// time: every rank applies each to its [`ClusterRenderer`] in the same order, so the ranks stay
/// in step whatever the user does between frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ViewStep {
    /// One frame.
    Frame,
    /// The owners' sums to rank 0 at every `every`-th pixel of every `every`-th row
    /// ([`ClusterRenderer::gather_every`]; 1: the whole picture): the picture the window shows
    /// (rank 0's console, reduced to its size) or saves (whole).
    Gather { every: u32 },
    /// A new ROI (`None`: sample every pixel); the accumulation goes on.
    Roi(Option<Roi>),
    /// The wall camera's eye moved past the restart threshold: move it there and restart.
    Eye(glam::DVec3),
    /// The pinhole moved: this camera from now on, the accumulation restarted.
    Camera(RenderCamera),
    /// The guide's settings or the path depth changed: the renderer starts again from nothing
    /// ([`ClusterRenderer::rebuild`]: the accumulation restarts, with no ROI), as the
    /// one-process viewer builds a new one.
    Rebuild { config: GuideConfig, max_depth: u32 },
    /// The window closed: the render ends on every rank.
    Stop,
    /// Every owner makes the pictures of the display tiles it owns, filtered where they are
    /// owned (`view --show-tiles`: each shows its own), at this exposure (stops), and with
    /// `denoise` denoised by the interactive denoiser (the filter's variance threshold).
    Tiles {
        filter: FilterParams,
        exposure: f32,
        denoise: bool,
    },
}

impl ViewStep {
    /// Little-endian bytes: a tag, then the step's numbers.
    #[must_use]
    pub fn encode(&self) -> Vec<u8> {
        let mut b = Vec::new();
        let f64s = |b: &mut Vec<u8>, v: &[f64]| v.iter().for_each(|x| b.extend(x.to_le_bytes()));
        let f32s = |b: &mut Vec<u8>, v: &[f32]| v.iter().for_each(|x| b.extend(x.to_le_bytes()));
        match *self {
            Self::Frame => b.push(0),
            Self::Gather { every } => {
                b.push(1);
                b.extend(every.to_le_bytes());
            }
            Self::Roi(None) => b.push(2),
            Self::Roi(Some(Roi::Cone(c))) => {
                b.push(3);
                for v in [c.apex, c.axis, c.right, c.up] {
                    f64s(&mut b, &v.to_array());
                }
                f64s(&mut b, &[c.tan_h, c.tan_v]);
            }
            Self::Roi(Some(Roi::CanvasEllipse { center, semi_axes })) => {
                b.push(4);
                f64s(&mut b, &[center.x, center.y, semi_axes.x, semi_axes.y]);
            }
            Self::Eye(e) => {
                b.push(5);
                f64s(&mut b, &e.to_array());
            }
            Self::Camera(c) => {
                b.push(6);
                for v in [c.position, c.forward, c.right, c.up] {
                    f32s(&mut b, &v.to_array());
                }
                f32s(&mut b, &[c.tan_half_y, c.aspect, c.ortho_half_y]);
            }
            Self::Rebuild { config, max_depth } => {
                b.push(7);
                b.push(match config.metric {
                    Metric::Exact => 0,
                    Metric::Ellipse => 1,
                    Metric::Angular => 2,
                });
                b.push(match config.order {
                    Order::Coherent => 0,
                    Order::Scattered => 1,
                });
                f64s(&mut b, &[config.falloff.base_m, config.falloff.scale]);
                f32s(&mut b, &[config.p_min]);
                b.extend(max_depth.to_le_bytes());
            }
            Self::Stop => b.push(8),
            Self::Tiles {
                filter,
                exposure,
                denoise,
            } => {
                b.push(9);
                b.push(u8::from(denoise));
                b.push(match filter.kind {
                    FilterKind::Off => 0,
                    FilterKind::Exact => 1,
                    FilterKind::Fast => 2,
                });
                b.push(match filter.blend {
                    Blend::Count => 0,
                    Blend::Variance => 1,
                });
                f32s(
                    &mut b,
                    &[filter.k_max, filter.c, filter.variance_threshold, exposure],
                );
            }
        }
        b
    }

    /// The inverse of [`Self::encode`]; `None` for bytes it does not produce.
    #[must_use]
    pub fn decode(b: &[u8]) -> Option<Self> {
        let (&tag, rest) = b.split_first()?;
        let f64s = |r: &[u8], n: usize| -> Option<Vec<f64>> {
            (r.len() == 8 * n).then(|| {
                r.chunks_exact(8)
                    .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                    .collect()
            })
        };
        let f32s = |r: &[u8], n: usize| -> Option<Vec<f32>> {
            (r.len() == 4 * n).then(|| {
                r.chunks_exact(4)
                    .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
                    .collect()
            })
        };
        let none = |s: Self| rest.is_empty().then_some(s);
        Some(match tag {
            0 => none(Self::Frame)?,
            1 => {
                let every = u32::from_le_bytes(rest.try_into().ok()?);
                (every > 0).then_some(Self::Gather { every })?
            }
            2 => none(Self::Roi(None))?,
            3 => {
                let f = f64s(rest, 14)?;
                let v = |i: usize| glam::DVec3::new(f[i], f[i + 1], f[i + 2]);
                Self::Roi(Some(Roi::Cone(crate::roi::cone::Cone {
                    apex: v(0),
                    axis: v(3),
                    right: v(6),
                    up: v(9),
                    tan_h: f[12],
                    tan_v: f[13],
                })))
            }
            4 => {
                let f = f64s(rest, 4)?;
                Self::Roi(Some(Roi::CanvasEllipse {
                    center: glam::DVec2::new(f[0], f[1]),
                    semi_axes: glam::DVec2::new(f[2], f[3]),
                }))
            }
            5 => {
                let f = f64s(rest, 3)?;
                Self::Eye(glam::DVec3::new(f[0], f[1], f[2]))
            }
            6 => {
                let f = f32s(rest, 15)?;
                let v = |i: usize| glam::Vec3::new(f[i], f[i + 1], f[i + 2]);
                Self::Camera(RenderCamera {
                    position: v(0),
                    forward: v(3),
                    right: v(6),
                    up: v(9),
                    tan_half_y: f[12],
                    aspect: f[13],
                    ortho_half_y: f[14],
                })
            }
            7 => {
                if rest.len() != 2 + 16 + 4 + 4 {
                    return None;
                }
                let metric = match rest[0] {
                    0 => Metric::Exact,
                    1 => Metric::Ellipse,
                    2 => Metric::Angular,
                    _ => return None,
                };
                let order = match rest[1] {
                    0 => Order::Coherent,
                    1 => Order::Scattered,
                    _ => return None,
                };
                let fall = f64s(&rest[2..18], 2)?;
                let p_min = f32s(&rest[18..22], 1)?[0];
                let max_depth = u32::from_le_bytes(rest[22..26].try_into().ok()?);
                Self::Rebuild {
                    config: GuideConfig {
                        metric,
                        falloff: Falloff {
                            base_m: fall[0],
                            scale: fall[1],
                        },
                        p_min,
                        order,
                    },
                    max_depth,
                }
            }
            8 => none(Self::Stop)?,
            9 => {
                let (&denoise, rest) = rest.split_first()?;
                let denoise = match denoise {
                    0 => false,
                    1 => true,
                    _ => return None,
                };
                let (&kind, rest) = rest.split_first()?;
                let (&blend, rest) = rest.split_first()?;
                let f = f32s(rest, 4)?;
                Self::Tiles {
                    filter: FilterParams {
                        kind: match kind {
                            0 => FilterKind::Off,
                            1 => FilterKind::Exact,
                            2 => FilterKind::Fast,
                            _ => return None,
                        },
                        blend: match blend {
                            0 => Blend::Count,
                            1 => Blend::Variance,
                            _ => return None,
                        },
                        k_max: f[0],
                        c: f[1],
                        variance_threshold: f[2],
                    },
                    exposure: f[3],
                    denoise,
                }
            }
            _ => return None,
        })
    }
}

/// What a [`ViewStep`] gave on this rank.
pub enum Applied {
    Frame(ClusterFrameStats),
    /// Rank 0: the whole accumulation and the DGI (`None` elsewhere).
    Gathered(Option<(Accumulation, Vec<f32>)>),
    /// The pictures of this rank's tiles, and the exposure to show them at.
    Tiles(Vec<TilePicture>, f32),
    Done,
}

/// One rank's part of `view --cluster`: this rank's renderer, holding the job, and what the
/// owners' pictures need. Rank 0 [`sends`](Self::send) the viewer's steps (each applied on every
/// rank, this one included); the others [`follow`](Self::follow) them until the window closes.
/// Dropped on rank 0 before the window's last step, it tells the others to stop.
pub struct ClusterView<'a> {
    r: ClusterRenderer<'a>,
    model: &'a DisplayModel,
    /// The tile map, for the owners' pictures ([`ViewStep::Tiles`]).
    tiles: Option<TileOwners>,
    /// A test's fault, struck at the start of a frame.
    fault: Option<Fault>,
    /// Frames run since the start.
    frames: u32,
    stopped: bool,
}

impl<'a> ClusterView<'a> {
    /// This rank's view of the guided render `r` (guided on `model`; traced on its GPU where
    /// [`ClusterRenderer::trace_on_gpu`] was called).
    pub fn new(r: ClusterRenderer<'a>, model: &'a DisplayModel) -> Result<Self, ClusterError> {
        if r.guide_config().is_none() {
            return Err(FrameError::NotGuided.into());
        }
        Ok(Self {
            r,
            model,
            tiles: None,
            fault: None,
            frames: 0,
            stopped: false,
        })
    }

    /// A test's fault (`--cluster-fault`): this rank ends or stops answering at the start of
    /// that frame (counted from the render's start, restarts included).
    #[must_use]
    pub fn with_fault(mut self, fault: Option<Fault>) -> Self {
        self.fault = fault;
        self
    }

    /// The tile map the owners make their tiles' pictures by (`view --show-tiles`; the same
    /// on every rank).
    #[must_use]
    pub fn with_tiles(mut self, tiles: TileOwners) -> Self {
        self.tiles = Some(tiles);
        self
    }

    /// The display model.
    #[must_use]
    pub fn model(&self) -> &DisplayModel {
        self.model
    }

    /// Whether the owners make their tiles' pictures (a tile map was given).
    #[must_use]
    pub fn shows_tiles(&self) -> bool {
        self.tiles.is_some()
    }

    /// This rank.
    #[must_use]
    pub fn rank(&self) -> usize {
        self.r.cluster().rank()
    }

    /// This rank's renderer as it stands.
    #[must_use]
    pub fn renderer(&self) -> &ClusterRenderer<'a> {
        &self.r
    }

    /// The job's ranks.
    #[must_use]
    pub fn ranks(&self) -> usize {
        self.r.cluster().ranks()
    }

    /// The ranks and where this one traces, in words.
    #[must_use]
    pub fn describe(&self) -> String {
        format!(
            "{} rank(s), rank 0 tracing on {}",
            self.ranks(),
            self.r
                .gpu()
                .map_or_else(|| "the CPU twins".to_owned(), GpuContext::describe)
        )
    }

    /// Rank 0: `step` on every rank, this one included; what it gave here.
    pub fn send(&mut self, step: ViewStep) -> Result<Applied, ClusterError> {
        assert!(
            self.r.cluster().is_root(),
            "rank 0 sends the viewer's steps"
        );
        self.r
            .cluster_mut()
            .broadcast("the viewer's next step", step.encode())?;
        self.apply(step)
    }

    /// Rank 0: the restart rule of a moving eye ([`Render::follow_eye`]) decided here, and an
    /// eye the accumulation restarts at sent to every rank ([`ViewStep::Eye`]).
    pub fn follow_eye(&mut self, eye: DVec3, threshold_m: f64) -> Result<EyeFollow, ClusterError> {
        let wall = self.r.wall().ok_or(FrameError::NoWall)?;
        if !wall.eye_moved(eye, threshold_m) {
            return Ok(EyeFollow::Kept);
        }
        if let Err(e) = wall.with_eye(eye) {
            return Ok(EyeFollow::Refused(e));
        }
        self.send(ViewStep::Eye(eye))?;
        Ok(EyeFollow::Restarted)
    }

    fn apply(&mut self, step: ViewStep) -> Result<Applied, ClusterError> {
        match step {
            ViewStep::Frame => {
                if let Some(f) = &self.fault {
                    f.strike(self.rank(), self.frames);
                }
                self.frames += 1;
                return Ok(Applied::Frame(self.r.run_frame(false)?));
            }
            ViewStep::Gather { every } => {
                return Ok(Applied::Gathered(self.r.gather_every(every)?));
            }
            ViewStep::Roi(roi) => self.r.set_roi(roi)?,
            ViewStep::Eye(e) => self.r.move_eye(e)?,
            ViewStep::Camera(camera) => self.r.set_camera(camera)?,
            ViewStep::Rebuild { config, max_depth } => {
                let settings = TraceSettings {
                    max_depth,
                    ..*self.r.settings()
                };
                self.r.rebuild(settings, config)?;
            }
            ViewStep::Stop => {
                self.r.finish()?;
                self.stopped = true;
            }
            ViewStep::Tiles {
                filter,
                exposure,
                denoise,
            } => {
                let tiles = self.tiles.as_ref().ok_or_else(|| {
                    ClusterError::Rejected("the owners' pictures need the tile map".into())
                })?;
                let denoise = denoise.then(|| crate::filter::denoise::DenoiseParams {
                    variance_threshold: filter.variance_threshold,
                    ..Default::default()
                });
                let pictures =
                    self.r
                        .tile_pictures(self.model, tiles, &filter, denoise.as_ref())?;
                return Ok(Applied::Tiles(pictures, exposure));
            }
        }
        Ok(Applied::Done)
    }

    /// Every rank but 0: rank 0's next step, applied here (`None` once the window closed).
    pub fn next_step(&mut self) -> Result<Option<(ViewStep, Applied)>, ClusterError> {
        if self.stopped {
            return Ok(None);
        }
        let what = "the viewer's next step";
        let bytes = self.r.cluster_mut().broadcast_patiently(what, Vec::new())?;
        let step = ViewStep::decode(&bytes).ok_or_else(|| ExchangeError::Malformed {
            rank: 0,
            what: what.into(),
            reason: format!("{} bytes that are no viewer step", bytes.len()),
        })?;
        let applied = self.apply(step)?;
        Ok((!self.stopped).then_some((step, applied)))
    }

    /// Every rank but 0: rank 0's steps until its window closes; the frames this rank ran.
    pub fn follow(&mut self) -> Result<u32, ClusterError> {
        let mut frames = 0;
        while let Some((step, _)) = self.next_step()? {
            frames += u32::from(step == ViewStep::Frame);
        }
        Ok(frames)
    }
}

impl Drop for ClusterView<'_> {
    /// Rank 0's window closed (or its viewer ended on an error): the others stop too.
    fn drop(&mut self) {
        if self.r.cluster().is_root() && !self.stopped {
            let _ = self.send(ViewStep::Stop);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_steps_survive_their_bytes_and_other_bytes_are_refused() {
        let cone = crate::roi::cone::Cone::from_pose(
            glam::DVec3::new(0.1, 0.2, 1.0),
            glam::DVec3::NEG_Z,
            glam::DVec3::Y,
            17.0,
            23.0,
        )
        .unwrap();
        let camera = RenderCamera {
            position: glam::Vec3::new(0.1, -2.0, 3.5),
            forward: glam::Vec3::NEG_Z,
            right: glam::Vec3::X,
            up: glam::Vec3::Y,
            tan_half_y: 0.4,
            aspect: 2.5,
            ortho_half_y: 0.0,
        };
        let config = GuideConfig {
            metric: Metric::Angular,
            falloff: Falloff {
                base_m: 0.125,
                scale: 1.0 / 3.0,
            },
            p_min: 0.1,
            order: Order::Scattered,
        };
        let steps = [
            ViewStep::Frame,
            ViewStep::Gather { every: 1 },
            ViewStep::Gather { every: 7 },
            ViewStep::Roi(None),
            ViewStep::Roi(Some(Roi::Cone(cone))),
            ViewStep::Roi(Some(Roi::CanvasEllipse {
                center: glam::DVec2::new(12.5, -3.0),
                semi_axes: glam::DVec2::new(1e-9, 7.0),
            })),
            ViewStep::Eye(glam::DVec3::new(0.3, -0.1, 1.7)),
            ViewStep::Camera(camera),
            ViewStep::Rebuild {
                config,
                max_depth: 7,
            },
            ViewStep::Stop,
            ViewStep::Tiles {
                filter: FilterParams {
                    kind: FilterKind::Exact,
                    blend: Blend::Variance,
                    k_max: 12.5,
                    c: 3.0,
                    variance_threshold: 1e-5,
                },
                exposure: -1.5,
                denoise: true,
            },
        ];
        for s in steps {
            let b = s.encode();
            assert_eq!(ViewStep::decode(&b), Some(s), "{s:?}");
            // A byte more or less is no step.
            let mut longer = b.clone();
            longer.push(0);
            assert_eq!(ViewStep::decode(&longer), None, "{s:?} + 1 byte");
            assert_eq!(ViewStep::decode(&b[..b.len() - 1]), None, "{s:?} − 1 byte");
        }
        assert_eq!(ViewStep::decode(&[9]), None);
        assert_eq!(ViewStep::decode(&[1, 0, 0, 0, 0]), None, "every 0th pixel");
        let mut bad_metric = ViewStep::Rebuild {
            config,
            max_depth: 7,
        }
        .encode();
        bad_metric[1] = 3;
        assert_eq!(ViewStep::decode(&bad_metric), None);
    }
}
