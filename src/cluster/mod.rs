//! One wall rendered by several ranks (DESIGN.md §12): the frame of [`crate::frame`] with its
//! samples computed across ranks and accumulated by the ranks that own the wall's tiles.
//!
//! ```text
//! rank 0: ROI, iteration ──broadcast (binomial tree)──► every rank
//! every rank: install the DGI (computed, or broadcast by rank 0) ──► schedule (the whole
//!     list: the same on every rank) ──► deal its 32×32 blocks, weighted by measured cost
//!     ──► trace the blocks dealt to this rank (its GPU, or the CPU twin) ──all-to-all──►
//!     each block's samples to the owner of its tile, which accumulates them
//! rank 0, when asked (save, report): gathers the owners' sums ──► filter ──► picture
//! every owner, for its display tiles: the margins' sums from their owners ──► filter ──► tiles
//! ```
//!
//! A frame's samples travel while the next frame is traced ([`ClusterRenderer::set_overlap`],
//! on by default): an owner counts its pixels' samples when they are dealt (a pixel's count is
//! its next sample's index, which the next frame needs) and adds their sums when they arrive,
//! during the next frame or before anything reads the accumulation
//! ([`ClusterRenderer::finish`]); the messages wait on their own lane
//! ([`exchange::Lane::Later`]) while that frame's rounds pass.
//!
//! [`ClusterRenderer::run_frame`] is that function. Samples are exact: a sample depends only
//! on (pixel, sample index, seed), a pixel's owner keeps its sample count and tells the rank
//! that traces it, and a pixel gets at most one sample an iteration, which its owner adds as the
//! one-process renderer does. N ranks therefore give the accumulation of one process bit for
//! bit, whatever the deal — the tests compare them.
//!
//! A rank's own work and memory are its share of the image: it keeps the sums and counts of
//! the blocks it owns, knows every listed block's length (the deal's input: a population
//! count of the block's mask in coherent order) and expands only the pixels of the blocks it
//! traces or owns. Nothing per pixel of the whole image is done on every rank each iteration
//! but the schedule of scattered order and of a single rank (the whole draw), and the DGI of a
//! new ROI (`--cluster-dgi`). A GPU rank draws the whole coherent schedule on its GPU, as every
//! block's slot mask (128 bytes a block read back: 9 MB at 73.8 MP), so no masks cross the link
//! between GPU ranks; and it keeps its owned sums on its GPU (`OwnedSums`): the samples of its
//! own blocks never leave the GPU, the other ranks' are uploaded and added there, and the
//! CPU's copy is read back only when something reads it.
//!
//! What crosses the link each iteration, per rank: the control message from rank 0 (tens of
//! bytes), 4 bytes (the count, u32) per sample an owner has traced elsewhere, to the rank that
//! traces it, before the trace; 12 bytes (linear RGB, f32) per such sample back to its owner —
//! the sum of squared luminance and the count follow from it exactly — and 4 bytes per block
//! traced (its rays, the deal's weights) to every other rank. On an ROI change the DGI is computed by every
//! rank ([`DgiMode::Compute`]: no traffic) or by rank 0 and broadcast ([`DgiMode::Broadcast`]:
//! 4 bytes a pixel); `raygun bench guided --cluster` measures both.
//!
//! Every wait has a deadline ([`Cluster`]): a rank that stops answering ends the job with an
//! error naming it. The transport is [`exchange::Exchange`]: threads in one process for the
//! tests ([`exchange::InProcess`]), MPI with the `cluster` feature (`mpi`). Modules: [`mod@deal`]
//! (blocks and the deal), [`owners`] (the tile map and the `--tile-owners` file), [`handshake`]
//! (the start-up check), [`exchange`], [`picture`] (each owner's tiles, filtered where they are
//! owned).

pub mod deal;
pub mod exchange;
pub mod handshake;
#[cfg(feature = "cluster")]
pub mod mpi;
pub mod owners;
pub mod picture;

use std::sync::Arc;

use rayon::prelude::*;
use std::time::{Duration, Instant};

use glam::{DVec2, DVec3, Vec3};

use crate::display::DisplayModel;
use crate::frame::stop::RoiProgress;
use crate::frame::{EyeFollow, FrameError, GuideConfig, dgi_cpu, prepare_dgi};
use crate::gpu::GpuContext;
use crate::roi::cone::Cone;
use crate::roi::dgi::{Roi, Surface};
use crate::roi::gpu::DgiKernel;
use crate::scene::Scene;
use crate::schedule::gpu::BlockMasksRun;
use crate::schedule::{
    BLOCK_PIXELS, Order, ScheduleError, TILE_EDGE, schedule_cpu_block_masks, schedule_cpu_shown,
};
use crate::trace::accum::{Accumulation, accumulate_sums, block_rays, every, every_size};
use crate::trace::gpu::{GpuScene, OwnedSums, SampleRun, TraceKernel};
use crate::trace::pack::PackedScene;
use crate::trace::path::{TraceSettings, samples_cpu};
use crate::trace::wall::WallCamera;
use deal::{BlockList, CostTable, deal};
use exchange::{Exchange, ExchangeError, Lane, Traffic};
use owners::{BlockOwners, block_grid, block_of, block_pixels, block_pixels_every};

/// Why a cluster frame (or the job's start) failed.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    #[error(transparent)]
    Exchange(#[from] ExchangeError),
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error(transparent)]
    Schedule(#[from] ScheduleError),
    #[error(transparent)]
    Filter(#[from] crate::filter::FilterGpuError),
    #[error("this rank's GPU: {0}")]
    Gpu(#[from] crate::gpu::GpuError),
    #[error("the start-up check rejected the job: {0}")]
    Rejected(String),
    #[error("the block map is for a {map:?} image, the render's is {image:?}")]
    MapSize { map: [u32; 2], image: [u32; 2] },
}

/// How the DGI of a new ROI reaches every rank.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DgiMode {
    /// Every rank computes it (no traffic; each rank spends the DGI's time).
    #[default]
    Compute,
    /// Rank 0 computes it and broadcasts it (4 bytes a pixel to every rank).
    Broadcast,
    /// Every rank computes every N-th band of 16 rows and sends it to the others (each rank
    /// receives 4 bytes a pixel of the others' bands): a 1/N share of the work each. GPU ranks
    /// compute instead, as with `compute`: a GPU makes the whole DGI in one dispatch, and the
    /// bands' exchange would bring nothing it has not computed.
    Split,
}

/// A rank's handle on the job: the transport, and the deadline rule for every wait.
///
/// A wait may last the timeout plus twice the time this rank spent on its own since its last
/// round (a peer doing the same step may take three times as long as this rank did), doubled
/// on ranks other than 0 so that rank 0, which holds the user's terminal, is the one that
/// reports a rank that stopped answering.
pub struct Cluster {
    x: Box<dyn Exchange>,
    timeout: Duration,
    last: Instant,
}

impl Cluster {
    #[must_use]
    pub fn new(x: Box<dyn Exchange>, timeout: Duration) -> Self {
        Self {
            x,
            timeout,
            last: Instant::now(),
        }
    }

    #[must_use]
    pub fn rank(&self) -> usize {
        self.x.rank()
    }

    #[must_use]
    pub fn ranks(&self) -> usize {
        self.x.ranks()
    }

    #[must_use]
    pub fn is_root(&self) -> bool {
        self.rank() == 0
    }

    /// What this rank has exchanged so far.
    #[must_use]
    pub fn traffic(&self) -> Traffic {
        self.x.traffic()
    }

    /// Ends the whole job now (after an error this rank printed).
    pub fn abort(&self, code: i32) -> ! {
        self.x.abort(code)
    }

    fn wait(&self) -> Duration {
        let local = self.last.elapsed();
        if self.is_root() {
            self.timeout + 2 * local
        } else {
            2 * self.timeout + 3 * local
        }
    }

    fn round(
        &mut self,
        sends: Vec<(usize, Vec<u8>)>,
        from: &[usize],
        what: &str,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        let wait = self.wait();
        self.round_within(sends, from, what, wait)
    }

    fn round_within(
        &mut self,
        sends: Vec<(usize, Vec<u8>)>,
        from: &[usize],
        what: &str,
        wait: Duration,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        let got = self.x.round(sends, from, what, wait);
        self.last = Instant::now();
        got
    }

    /// Rank 0's `data` on every rank (other ranks' `data` is ignored), down a binomial tree as
    /// MPI_Bcast sends it: rank r receives from r with its lowest set bit cleared and passes the
    /// data on to r + 2^k for each 2^k below that bit, so no rank sends more than ⌈log₂ N⌉
    /// copies (a DGI of 295 MB to 34 ranks: 6 copies from rank 0 instead of 34).
    pub fn broadcast(&mut self, what: &str, data: Vec<u8>) -> Result<Vec<u8>, ExchangeError> {
        let wait = self.wait();
        self.broadcast_within(what, data, wait)
    }

    /// [`Self::broadcast`] where the other ranks wait for rank 0 as long as it takes (a day):
    /// the viewer's next step, which comes when its user acts or its window draws again, and
    /// not at all while the window is minimised. A rank 0 that dies still ends the job (mpirun
    /// ends every rank), and rank 0's own waits keep their deadlines.
    pub fn broadcast_patiently(
        &mut self,
        what: &str,
        data: Vec<u8>,
    ) -> Result<Vec<u8>, ExchangeError> {
        self.broadcast_within(what, data, Duration::from_secs(24 * 3600))
    }

    fn broadcast_within(
        &mut self,
        what: &str,
        data: Vec<u8>,
        wait: Duration,
    ) -> Result<Vec<u8>, ExchangeError> {
        let (me, n) = (self.rank(), self.ranks());
        let (parent, children) = binomial_tree(me, n);
        let data = match parent {
            Some(p) => self.round_within(vec![], &[p], what, wait)?.remove(0),
            None => data,
        };
        if !children.is_empty() {
            let sends = children.into_iter().map(|c| (c, data.clone())).collect();
            self.round(sends, &[], what)?;
        }
        Ok(data)
    }

    /// Every rank's `data` on rank 0, by rank (`None` on the other ranks).
    pub fn gather(
        &mut self,
        what: &str,
        data: Vec<u8>,
    ) -> Result<Option<Vec<Vec<u8>>>, ExchangeError> {
        let n = self.ranks();
        if self.is_root() {
            let from: Vec<usize> = (1..n).collect();
            let mut all = vec![data];
            all.extend(self.round(vec![], &from, what)?);
            Ok(Some(all))
        } else {
            self.round(vec![(0, data)], &[], what)?;
            Ok(None)
        }
    }

    /// `parts[r]` to rank `r`; returns what each rank sent this one (its own part at its own
    /// index).
    pub fn all_to_all(
        &mut self,
        what: &str,
        parts: Vec<Vec<u8>>,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        let (own, sends) = self.split_parts(parts);
        let mut got = self.round(sends, &self.others(), what)?;
        got.insert(self.rank(), own);
        Ok(got)
    }

    /// `parts` (one per rank) as this rank's own and the sends to the others.
    fn split_parts(&self, mut parts: Vec<Vec<u8>>) -> (Vec<u8>, Vec<(usize, Vec<u8>)>) {
        let me = self.rank();
        assert_eq!(parts.len(), self.ranks(), "one part per rank");
        let own = std::mem::take(&mut parts[me]);
        let sends = parts
            .into_iter()
            .enumerate()
            .filter(|(r, _)| *r != me)
            .collect();
        (own, sends)
    }

    /// Every rank but this one, ascending.
    fn others(&self) -> Vec<usize> {
        (0..self.ranks()).filter(|&r| r != self.rank()).collect()
    }
}

impl Cluster {
    /// The first half of an all-to-all whose messages travel while this rank works on:
    /// `parts[r]` posted to rank `r` on [`Lane::Later`]; returns this rank's own part, for
    /// [`Self::all_to_all_collect`].
    pub fn all_to_all_post(
        &mut self,
        what: &str,
        parts: Vec<Vec<u8>>,
    ) -> Result<Vec<u8>, ExchangeError> {
        let (own, sends) = self.split_parts(parts);
        self.x.post(sends, Lane::Later, what)?;
        Ok(own)
    }

    /// The second half: what each rank posted this one (`own` at this rank's index), and this
    /// rank's posted sends taken.
    pub fn all_to_all_collect(
        &mut self,
        what: &str,
        own: Vec<u8>,
    ) -> Result<Vec<Vec<u8>>, ExchangeError> {
        let wait = self.wait();
        let mut got = self.x.collect(&self.others(), Lane::Later, what, wait);
        self.last = Instant::now();
        if let Ok(got) = &mut got {
            got.insert(self.rank(), own);
        }
        got
    }
}

/// Rank `me`'s parent (`None` for rank 0) and children, in sending order, in the binomial tree
/// of `n` ranks rooted at 0.
#[must_use]
pub fn binomial_tree(me: usize, n: usize) -> (Option<usize>, Vec<usize>) {
    let low = if me == 0 {
        n.next_power_of_two()
    } else {
        1 << me.trailing_zeros()
    };
    let parent = (me != 0).then(|| me - low);
    let mut children = Vec::new();
    let mut step = low >> 1;
    while step > 0 {
        if me + step < n {
            children.push(me + step);
        }
        step >>= 1;
    }
    (parent, children)
}

/// What rank 0 tells every rank before a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameControl {
    pub iteration: u32,
    /// No frame: the render ends here.
    pub stop: bool,
    /// After this frame, the owners send rank 0 the sums of the ROI's pixels
    /// ([`ClusterRenderer::roi_progress`]: a stop condition on the ROI's progress).
    pub measure: bool,
    /// `Some`: the ROI changed to this (`Some(None)`: no ROI, sample everything).
    pub roi: Option<Option<Roi>>,
    /// `Some`: rank 0's tracked head moved the wall camera's eye here (room frame) and
    /// restarted the accumulation (DESIGN.md §11); every other rank does the same before
    /// this frame.
    pub eye: Option<DVec3>,
}

impl FrameControl {
    /// Little-endian bytes: iteration, flags, ROI kind, then the ROI's and the eye's f64s.
    #[must_use]
    pub fn encode(&self) -> Vec<u8> {
        let mut b = self.iteration.to_le_bytes().to_vec();
        let flags = u8::from(self.stop) | u8::from(self.roi.is_some()) << 1;
        let flags = flags | u8::from(self.eye.is_some()) << 2 | u8::from(self.measure) << 3;
        b.push(flags);
        let mut f = Vec::new();
        let kind = match self.roi {
            Some(Some(Roi::Cone(c))) => {
                for v in [c.apex, c.axis, c.right, c.up] {
                    f.extend(v.to_array());
                }
                f.extend([c.tan_h, c.tan_v]);
                1
            }
            Some(Some(Roi::CanvasEllipse { center, semi_axes })) => {
                f.extend([center.x, center.y, semi_axes.x, semi_axes.y]);
                2
            }
            _ => 0,
        };
        b.push(kind);
        if let Some(e) = self.eye {
            f.extend(e.to_array());
        }
        for v in f {
            b.extend(v.to_le_bytes());
        }
        b
    }

    /// The inverse of [`Self::encode`]; `None` for bytes it does not produce.
    #[must_use]
    pub fn decode(b: &[u8]) -> Option<Self> {
        let iteration = u32::from_le_bytes(b.get(..4)?.try_into().ok()?);
        let (flags, kind) = (*b.get(4)?, *b.get(5)?);
        let f: Vec<f64> = b
            .get(6..)?
            .chunks(8)
            .map(|c| c.try_into().ok().map(f64::from_le_bytes))
            .collect::<Option<_>>()?;
        let roi_len = [0, 14, 4][usize::from(kind.min(2))];
        let eye_len = if flags & 4 != 0 { 3 } else { 0 };
        if kind > 2 || f.len() != roi_len + eye_len || flags > 15 {
            return None;
        }
        let v3 = |i: usize| DVec3::new(f[i], f[i + 1], f[i + 2]);
        let roi = match kind {
            1 => Some(Roi::Cone(Cone {
                apex: v3(0),
                axis: v3(3),
                right: v3(6),
                up: v3(9),
                tan_h: f[12],
                tan_v: f[13],
            })),
            2 => Some(Roi::CanvasEllipse {
                center: DVec2::new(f[0], f[1]),
                semi_axes: DVec2::new(f[2], f[3]),
            }),
            _ => None,
        };
        Some(Self {
            iteration,
            stop: flags & 1 != 0,
            measure: flags & 8 != 0,
            roi: (flags & 2 != 0).then_some(roi),
            eye: (eye_len > 0).then(|| v3(roi_len)),
        })
    }
}

/// What one cluster frame did on this rank.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct ClusterFrameStats {
    pub iteration: u32,
    pub dgi_recomputed: bool,
    /// Pixels scheduled on all ranks together.
    pub pixels: u64,
    /// Of those, the ones this rank traced.
    pub pixels_traced: u64,
    /// Of those, the ones this rank expanded from the schedule (those it traces or owns; every
    /// one where the list is drawn whole on every rank: scattered order, a single rank).
    pub pixels_held: u64,
    /// Rays this rank traced.
    pub rays: u64,
    /// Wall-clock ms of each step on this rank.
    pub ms_dgi: f64,
    pub ms_schedule: f64,
    /// Sending, waiting for and taking in the counts of the pixels this rank traces for other
    /// owners.
    pub ms_counts: f64,
    pub ms_trace: f64,
    /// Of `ms_trace`, the tracer's call: on a GPU the list's upload, the kernel and the
    /// samples' read-back; on the CPU twin the tracing. The rest is the host's work around it
    /// (the list put together, the rays per block).
    pub ms_trace_call: f64,
    /// Taking in and adding the samples in flight (the previous frame's, overlapped; this
    /// frame's, not overlapped) and posting this frame's.
    pub ms_exchange: f64,
    /// What this rank sent and received in this frame (the DGI's broadcast included; with the
    /// exchange overlapped, the samples received are the previous frame's).
    pub traffic: Traffic,
}

/// Where the ROI is aimed and how it steers sampling.
struct Guidance {
    config: GuideConfig,
    surface: Surface,
    pitch_m: f64,
}

/// One rank's part of a progressive render across ranks: the schedule, sample counts and DGI
/// of the whole image, the sums of the blocks this rank owns.
pub struct ClusterRenderer {
    pub packed: PackedScene,
    pub settings: TraceSettings,
    /// Seconds spent building the BVH and packing the scene.
    pub build_seconds: f64,
    wall: Option<WallCamera>,
    guidance: Option<Guidance>,
    dgi_mode: DgiMode,
    rank: usize,
    ranks: usize,
    iteration: u32,
    /// The DGI in use (guided renders; empty for a full frame).
    dgi: Vec<f32>,
    /// A new ROI for the next frame to install.
    pending: Option<Option<Roi>>,
    roi: Option<Roi>,
    /// Pixels of the whole image.
    pixels: usize,
    /// Samples taken so far over the whole image (every rank knows every block's length).
    total: u64,
    /// `BLOCK_PIXELS` sample counts per owned block, laid out as `sums`.
    counts: Vec<u32>,
    owners: BlockOwners,
    /// Per block: its index among this rank's blocks, or `u32::MAX`.
    slot: Vec<u32>,
    /// `BLOCK_PIXELS` sums per owned block, row-major inside the block (on a GPU rank whose
    /// owned sums live on its GPU, their copy as of the last [`Self::sync_sums`]).
    sums: Vec<[f32; 4]>,
    /// Whether the GPU's owned sums changed since `sums` was read back.
    sums_stale: bool,
    costs: CostTable,
    /// A full frame's list (every shown pixel), made once.
    full_list: Option<Arc<BlockList>>,
    /// Where this rank traces its samples: the CPU twin (`None`) or its GPU.
    gpu: Option<Box<GpuRank>>,
    /// Whether a frame's samples travel while the next frame is traced (the default), or
    /// reach their owners before `run_frame` returns.
    overlap: bool,
    /// The last frame's samples, posted to their owners and not yet collected.
    in_flight: Option<InFlight>,
}

/// A frame's exchange between its post and its collect.
struct InFlight {
    iteration: u32,
    list: Arc<BlockList>,
    tracer: Vec<u32>,
    mine: Traced,
    /// This rank's own part of the all-to-all (empty).
    own: Vec<u8>,
    /// The accumulation restarted since (a moved eye or camera): the samples are collected
    /// (they are on their way) and not added.
    stale: bool,
}

/// A rank's GPU, with the scene on it and the kernel's compact mode ([`SampleRun`]).
struct GpuRank {
    ctx: Arc<GpuContext>,
    scene: GpuScene,
    run: SampleRun,
    /// The DGI's kernel: a GPU rank computes the DGI as one GPU process does (the CPU twin's
    /// f64 solves agree with it only to rounding).
    dgi: DgiKernel,
    /// A guided render in coherent order: each iteration's whole schedule drawn on this GPU as
    /// every block's slot mask, instead of a 1/N share on the CPU and the rest from the link
    /// (`None`: a full frame, scattered order, or an image whose DGI is over one binding of
    /// this adapter: the CPU's split draw).
    masks: Option<BlockMasksRun>,
    /// The owned sums on this GPU: the samples of this rank's own blocks that it traces
    /// never leave the GPU (`None`: more owned pixels than one binding holds; the CPU adds).
    owned: Option<OwnedSums>,
}

impl GpuRank {
    /// The DGI of `roi` (`None`: 0 everywhere) on this rank's GPU: what a one-process GPU
    /// renderer installs, value for value.
    fn dgi(
        &self,
        g: &Guidance,
        roi: Option<&Roi>,
        size: [u32; 2],
    ) -> Result<Vec<f32>, ClusterError> {
        Ok(match roi {
            Some(r) => {
                let (guide, params) = prepare_dgi(&g.surface, g.pitch_m, &g.config, r, size)?;
                self.dgi.compute(&self.ctx, &g.surface, &guide, &params)?
            }
            None => vec![0.0; size[0] as usize * size[1] as usize],
        })
    }
}

impl ClusterRenderer {
    /// Rank `rank` of `ranks`: a render of `scene` (guided when `guide` gives the display and
    /// how the ROI steers; a full frame otherwise), through `wall` when given, with the blocks
    /// owned as `owners` says.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        scene: &Scene,
        settings: TraceSettings,
        guide: Option<(&DisplayModel, GuideConfig)>,
        wall: Option<WallCamera>,
        owners: BlockOwners,
        dgi_mode: DgiMode,
        rank: usize,
        ranks: usize,
    ) -> Result<Self, ClusterError> {
        let size = [settings.width, settings.height];
        if [owners.width, owners.height] != size {
            return Err(ClusterError::MapSize {
                map: [owners.width, owners.height],
                image: size,
            });
        }
        if let Some(wc) = &wall
            && [wc.width, wc.height] != size
        {
            return Err(FrameError::WallSize {
                wall: [wc.width, wc.height],
                image: size,
            }
            .into());
        }
        let guidance = match guide {
            Some((model, config)) => {
                crate::schedule::validate_p_min(config.p_min)?;
                Some(Guidance {
                    config,
                    surface: Surface::from_model(model),
                    pitch_m: model.pitch_m(),
                })
            }
            None => None,
        };
        let t0 = Instant::now();
        let packed = PackedScene::new(scene);
        let build_seconds = t0.elapsed().as_secs_f64();
        let n = size[0] as usize * size[1] as usize;
        let mine = owners.owned_by(rank);
        let mut slot = vec![u32::MAX; owners.owner.len()];
        for (i, &b) in mine.iter().enumerate() {
            slot[b as usize] = i as u32;
        }
        Ok(Self {
            packed,
            settings,
            build_seconds,
            wall,
            dgi: if guidance.is_some() {
                vec![0.0; n]
            } else {
                Vec::new()
            },
            guidance,
            dgi_mode,
            rank,
            ranks,
            iteration: 0,
            pending: None,
            roi: None,
            pixels: n,
            total: 0,
            counts: vec![0; mine.len() * BLOCK_PIXELS as usize],
            costs: CostTable::new(owners.owner.len()),
            sums: vec![[0.0; 4]; mine.len() * BLOCK_PIXELS as usize],
            sums_stale: false,
            owners,
            slot,
            full_list: None,
            gpu: None,
            overlap: true,
            in_flight: None,
        })
    }

    /// Traces this rank's samples on `ctx`'s GPU from now on, the scene uploaded to it (the
    /// kernel's compact mode: the samples come back to this rank, which sends them to their
    /// owners as the CPU twin's). Every rank should trace on the same kind of adapter: the
    /// GPU's samples equal the CPU twin's only to rounding, so a job that mixes them is
    /// bit-identical to neither (the start-up check compares the backends).
    pub fn trace_on_gpu(&mut self, ctx: Arc<GpuContext>) -> Result<(), ClusterError> {
        let kernel = TraceKernel::new(&ctx);
        let scene = GpuScene::upload(&ctx, &kernel, &self.packed)?;
        let run = SampleRun::new(
            &ctx,
            &kernel,
            &self.packed,
            &self.settings,
            self.wall.as_ref(),
        );
        let dgi = DgiKernel::new(&ctx);
        let masks = match &self.guidance {
            Some(g) if g.config.order == Order::Coherent => {
                let shown = self.wall.as_ref().map(WallCamera::shown_mask);
                let (w, h) = (self.settings.width, self.settings.height);
                match BlockMasksRun::new(&ctx, w, h, g.config.p_min, shown) {
                    Ok(m) => {
                        m.set_dgi(&ctx, &self.dgi);
                        Some(m)
                    }
                    // Over the adapter's binding: the CPU draws (every rank of a job has the
                    // same adapter, the start-up check, so every rank decides alike).
                    Err(ScheduleError::Gpu(crate::gpu::GpuError::TooLarge { .. })) => None,
                    Err(e) => return Err(e.into()),
                }
            }
            _ => None,
        };
        let owned = OwnedSums::new(&ctx, self.sums.len() as u64);
        // The owned sums start from the CPU's (zero before the first frame).
        if let Some(o) = &owned {
            ctx.queue
                .write_buffer(&o.sums, 0, bytemuck::cast_slice(&self.sums));
        }
        self.gpu = Some(Box::new(GpuRank {
            ctx,
            scene,
            run,
            dgi,
            masks,
            owned,
        }));
        Ok(())
    }

    /// How the ROI steers sampling (`None`: a full frame).
    #[must_use]
    pub fn guide_config(&self) -> Option<&GuideConfig> {
        self.guidance.as_ref().map(|g| &g.config)
    }

    /// The GPU this rank traces on (`None`: the CPU twin).
    #[must_use]
    pub fn gpu(&self) -> Option<&GpuContext> {
        self.gpu.as_deref().map(|g| &*g.ctx)
    }

    /// Samples taken so far, over the whole image (every rank knows every block's length).
    #[must_use]
    pub fn samples(&self) -> u64 {
        self.total
    }

    /// Iterations run so far.
    #[must_use]
    pub fn iteration(&self) -> u32 {
        self.iteration
    }

    /// The ROI set last (`None` also for a full frame).
    #[must_use]
    pub fn roi(&self) -> Option<&Roi> {
        self.roi.as_ref()
    }

    /// The wall camera, if the frames trace through one.
    #[must_use]
    pub fn wall(&self) -> Option<&WallCamera> {
        self.wall.as_ref()
    }

    /// The restart rule of a moving eye, as [`crate::frame::Renderer::follow_eye`] applies it:
    /// past `threshold_m` from the eye the accumulation started with, the wall camera moves
    /// there and this rank's owned sums and counts restart (the ROI and its DGI
    /// kept); otherwise nothing changes. Every rank applies the same eyes in the same frames,
    /// so they stay in step.
    pub fn follow_eye(&mut self, eye: DVec3, threshold_m: f64) -> Result<EyeFollow, ClusterError> {
        let wall = self.wall.as_ref().ok_or(FrameError::NoWall)?;
        if !wall.eye_moved(eye, threshold_m) {
            return Ok(EyeFollow::Kept);
        }
        match wall.with_eye(eye) {
            Ok(moved) => {
                self.restart_with(moved);
                Ok(EyeFollow::Restarted)
            }
            Err(e) => Ok(EyeFollow::Refused(e)),
        }
    }

    /// Moves the eye to `eye` and restarts, unconditionally: what the other ranks do with an
    /// eye rank 0's [`Self::follow_eye`] restarted at.
    pub fn move_eye(&mut self, eye: DVec3) -> Result<(), ClusterError> {
        let wall = self.wall.as_ref().ok_or(FrameError::NoWall)?;
        let moved = wall.with_eye(eye).map_err(FrameError::Wall)?;
        self.restart_with(moved);
        Ok(())
    }

    /// The wall camera `wall` from now on, and this rank's owned sums and counts back to zero
    /// (the one-process renderer's restart).
    fn restart_with(&mut self, wall: WallCamera) {
        if let Some(g) = &mut self.gpu {
            let moved = g.run.set_wall(&g.ctx, &self.packed, &self.settings, &wall);
            debug_assert!(moved, "the same display's wall camera");
        }
        self.wall = Some(wall);
        self.restart();
    }

    /// The pinhole camera `camera` from now on, and the accumulation restarted (the
    /// one-process renderer's [`crate::frame::Renderer::set_camera`]).
    pub fn set_camera(&mut self, camera: crate::trace::camera::RenderCamera) {
        self.settings.camera = camera;
        if let Some(g) = &self.gpu {
            g.run.set_settings(&g.ctx, &self.packed, &self.settings);
        }
        self.restart();
    }

    /// This rank's owned sums and counts back to zero.
    fn restart(&mut self) {
        if let Some(f) = &mut self.in_flight {
            f.stale = true;
        }
        self.total = 0;
        self.counts.fill(0);
        self.sums.fill([0.0; 4]);
        if let Some(g) = &mut self.gpu
            && let Some(o) = &mut g.owned
        {
            o.clear(&g.ctx);
        }
        self.sums_stale = false;
        self.iteration = 0;
    }

    /// Sets the ROI; the next frame installs its DGI. The accumulation is kept.
    pub fn set_roi(&mut self, roi: Option<Roi>) -> Result<(), ClusterError> {
        if self.guidance.is_none() {
            return Err(FrameError::NotGuided.into());
        }
        self.pending = Some(roi);
        self.roi = roi;
        Ok(())
    }

    /// One frame on this rank, in step with the others: the DGI of a changed ROI, the
    /// schedule, the deal, this rank's samples, and the exchange that brings every owner the
    /// samples of its blocks.
    pub fn run_frame(&mut self, c: &mut Cluster) -> Result<ClusterFrameStats, ClusterError> {
        let before = c.traffic();
        let mut stats = ClusterFrameStats {
            iteration: self.iteration,
            ..Default::default()
        };
        self.install_dgi(c, &mut stats)?;
        let mut list = self.schedule(c, &mut stats)?;
        let tracer = deal(&list, &self.costs, self.ranks);
        if let Some(l) = Arc::get_mut(&mut list) {
            // A list from masks: expand this rank's share, the blocks it traces or owns.
            let (me, owner) = (self.rank, &self.owners.owner);
            l.hold(|i, b| tracer[i] as usize == me || owner[b as usize] as usize == me);
        }
        stats.pixels_held = list.held_len() as u64;
        let counts = self.counts_to_trace(c, &list, &tracer, &mut stats)?;
        let samples = self.trace(&list, &tracer, &counts, &mut stats)?;
        let t0 = Instant::now();
        // The last frame's samples, which travelled while this one was traced; then this
        // frame's, posted (and, without overlap, collected at once).
        self.collect(c)?;
        stats.pixels = list.len();
        self.post(c, list, tracer, samples)?;
        if !self.overlap {
            self.collect(c)?;
        }
        stats.ms_exchange = t0.elapsed().as_secs_f64() * 1e3;
        stats.traffic = c.traffic().since(&before);
        self.iteration += 1;
        Ok(stats)
    }

    /// Step 1: the DGI of a changed ROI, computed here or received from rank 0.
    fn install_dgi(
        &mut self,
        c: &mut Cluster,
        stats: &mut ClusterFrameStats,
    ) -> Result<(), ClusterError> {
        let (Some(roi), Some(g)) = (self.pending.take(), &self.guidance) else {
            return Ok(());
        };
        let t0 = Instant::now();
        let size = [self.settings.width, self.settings.height];
        // On this rank's GPU when it traces on one (as one GPU process computes it), else on
        // the CPU twin.
        let gpu = self.gpu.as_deref();
        let compute = || match gpu {
            Some(gr) => gr.dgi(g, roi.as_ref(), size),
            None => Ok(dgi_cpu(
                &g.surface,
                g.pitch_m,
                &g.config,
                roi.as_ref(),
                size,
            )?),
        };
        self.dgi = match self.dgi_mode {
            // GPU ranks compute the whole DGI in either mode: a band computed on a GPU costs
            // what the whole does there (one dispatch), and the others' bands would only be
            // the values this rank computed already — so no exchange (every rank of a job is
            // on the same backend: the start-up check).
            DgiMode::Compute => compute()?,
            DgiMode::Split if gpu.is_some() => compute()?,
            DgiMode::Split => split_dgi(c, &g.surface, g.pitch_m, &g.config, roi.as_ref(), size)?,
            DgiMode::Broadcast => {
                let mine = if c.is_root() {
                    f32_bytes(&compute()?)
                } else {
                    Vec::new()
                };
                let got = c.broadcast("the DGI", mine)?;
                let dgi = f32s(&got, 1);
                if dgi.len() != self.pixels {
                    return Err(ExchangeError::Length {
                        rank: 0,
                        what: "the DGI".into(),
                        got: got.len(),
                        expected: self.pixels * 4,
                    }
                    .into());
                }
                dgi
            }
        };
        if let Some(gr) = self.gpu.as_deref()
            && let Some(m) = &gr.masks
        {
            m.set_dgi(&gr.ctx, &self.dgi);
        }
        stats.dgi_recomputed = true;
        stats.ms_dgi = t0.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// Step 2: the whole iteration's list, grouped by block (the same on every rank). In
    /// coherent order each rank draws every N-th block and sends the others its blocks'
    /// selected slots (a flag byte a block, 128 bytes a non-empty one): the draw is split N
    /// ways instead of repeated on every rank.
    fn schedule(
        &mut self,
        c: &mut Cluster,
        stats: &mut ClusterFrameStats,
    ) -> Result<Arc<BlockList>, ClusterError> {
        let t0 = Instant::now();
        let size = [self.settings.width, self.settings.height];
        let shown = self.wall.as_ref().map(WallCamera::shown_mask);
        let gpu_masks = self
            .gpu
            .as_deref()
            .and_then(|gr| gr.masks.as_ref().map(|m| (&gr.ctx, m)));
        let list = match (&self.guidance, gpu_masks) {
            // A GPU rank draws the whole iteration on its GPU: no masks cross the link.
            (Some(_), Some((ctx, m))) => {
                let all = m.masks(ctx, self.iteration, self.settings.seed)?;
                Arc::new(BlockList::from_masks(size, &all))
            }
            (Some(g), None) if g.config.order == Order::Coherent && self.ranks > 1 => {
                let cfg = &g.config;
                let [tx, ty] = owners::block_grid(size);
                let n = tx * ty;
                let mine: Vec<u32> = (self.rank as u32..n).step_by(self.ranks).collect();
                let masks = schedule_cpu_block_masks(
                    &self.dgi,
                    shown,
                    size[0],
                    size[1],
                    cfg.p_min,
                    self.iteration,
                    self.settings.seed,
                    &mine,
                )?;
                let part = encode_masks(&masks);
                let what = format!("the schedule of iteration {}", self.iteration);
                let got = c.all_to_all(&what, vec![part; self.ranks])?;
                let mut all = vec![[0u32; 32]; n as usize];
                for (src, bytes) in got.iter().enumerate() {
                    let theirs: Vec<u32> = (src as u32..n).step_by(self.ranks).collect();
                    let masks = decode_masks(bytes, theirs.len()).map_err(|reason| {
                        ExchangeError::Malformed {
                            rank: src,
                            what: what.clone(),
                            reason,
                        }
                    })?;
                    for (b, m) in theirs.into_iter().zip(masks) {
                        all[b as usize] = m;
                    }
                }
                Arc::new(BlockList::from_masks(size, &all))
            }
            (Some(g), None) => {
                let c = &g.config;
                let list = schedule_cpu_shown(
                    &self.dgi,
                    shown,
                    size[0],
                    size[1],
                    c.p_min,
                    self.iteration,
                    self.settings.seed,
                    c.order,
                )?;
                Arc::new(BlockList::group(&list, size))
            }
            (None, _) => Arc::clone(
                self.full_list
                    .get_or_insert_with(|| Arc::new(BlockList::every(size, shown))),
            ),
        };
        stats.ms_schedule = t0.elapsed().as_secs_f64() * 1e3;
        Ok(list)
    }

    /// Step 3: the sample counts of the pixels this rank traces, in block order: its own
    /// blocks' from its counts, the others' from their owners, who send each tracer the counts
    /// of their blocks it was dealt (4 bytes a pixel, blocks ascending).
    fn counts_to_trace(
        &mut self,
        c: &mut Cluster,
        list: &BlockList,
        tracer: &[u32],
        stats: &mut ClusterFrameStats,
    ) -> Result<Vec<u32>, ClusterError> {
        let t0 = Instant::now();
        let (me, n) = (self.rank, self.ranks);
        let owner = |i: usize| self.owners.owner[list.blocks[i] as usize] as usize;
        let mut got = vec![Vec::new(); n];
        if n > 1 {
            let mut bytes = vec![0usize; n];
            for (i, &t) in tracer.iter().enumerate() {
                if t as usize != me && owner(i) == me {
                    bytes[t as usize] += 4 * list.len_of(i) as usize;
                }
            }
            let mut parts: Vec<Vec<u8>> = bytes.iter().map(|&b| Vec::with_capacity(b)).collect();
            for (i, &t) in tracer.iter().enumerate() {
                let t = t as usize;
                if t != me && owner(i) == me {
                    let base = self.own_base(list.blocks[i]).expect("a block of this rank");
                    for &p in list.pixels_of(i) {
                        let c = self.counts[base + self.local(p)];
                        parts[t].extend_from_slice(&c.to_le_bytes());
                    }
                }
            }
            let what = format!("the counts of iteration {}", self.iteration);
            got = c.all_to_all(&what, parts)?;
            for (src, bytes) in got.iter().enumerate().filter(|(s, _)| *s != me) {
                let expected: usize = (0..list.blocks.len())
                    .filter(|&i| tracer[i] as usize == me && owner(i) == src)
                    .map(|i| 4 * list.len_of(i) as usize)
                    .sum();
                if bytes.len() != expected {
                    return Err(ExchangeError::Length {
                        rank: src,
                        what,
                        got: bytes.len(),
                        expected,
                    }
                    .into());
                }
            }
        }
        let mut at = vec![0usize; n];
        let mut counts = Vec::new();
        for i in (0..list.blocks.len()).filter(|&i| tracer[i] as usize == me) {
            let o = owner(i);
            if o == me {
                let base = self.own_base(list.blocks[i]).expect("a block of this rank");
                counts.extend(
                    list.pixels_of(i)
                        .iter()
                        .map(|&p| self.counts[base + self.local(p)]),
                );
            } else {
                let len = list.len_of(i) as usize;
                let bytes = &got[o][4 * at[o]..4 * (at[o] + len)];
                counts.extend(
                    bytes
                        .chunks_exact(4)
                        .map(|b| u32::from_le_bytes(b.try_into().expect("4"))),
                );
                at[o] += len;
            }
        }
        stats.ms_counts = t0.elapsed().as_secs_f64() * 1e3;
        Ok(counts)
    }

    /// Step 4: one sample for each pixel of the blocks dealt to this rank, in block order (the
    /// pixels' counts, `counts`, in the same order), and the rays each block took, on this
    /// rank's GPU or CPU twin.
    fn trace(
        &mut self,
        list: &BlockList,
        tracer: &[u32],
        counts: &[u32],
        stats: &mut ClusterFrameStats,
    ) -> Result<Traced, ClusterError> {
        let t0 = Instant::now();
        let mine: Vec<usize> = (0..list.blocks.len())
            .filter(|&i| tracer[i] as usize == self.rank)
            .collect();
        let lens: Vec<u32> = mine.iter().map(|&i| list.len_of(i)).collect();
        let total: usize = lens.iter().map(|&n| n as usize).sum();
        let owned_here =
            |k: usize| self.owners.owner[list.blocks[mine[k]] as usize] as usize == self.rank;
        // A GPU rank with its owned sums on its GPU traces the other owners' blocks first and
        // its own after them, reads back the others' samples only and keeps its own there.
        let keep = self
            .gpu
            .as_deref()
            .is_some_and(|g| g.owned.is_some() && SampleRun::fits_one_binding(&g.ctx, total));
        let order: Vec<usize> = if keep {
            let (own, others): (Vec<usize>, Vec<usize>) =
                (0..mine.len()).partition(|&k| owned_here(k));
            others.into_iter().chain(own).collect()
        } else {
            (0..mine.len()).collect()
        };
        let mut first = Vec::with_capacity(mine.len() + 1);
        first.push(0usize);
        for &n in &lens {
            first.push(first.last().expect("starts at 0") + n as usize);
        }
        let mut pixels = Vec::with_capacity(total);
        let mut ordered_counts = Vec::with_capacity(total);
        for &k in &order {
            pixels.extend_from_slice(list.pixels_of(mine[k]));
            ordered_counts.extend_from_slice(&counts[first[k]..first[k + 1]]);
        }
        debug_assert_eq!(counts.len(), pixels.len());
        let read = if keep {
            order
                .iter()
                .filter(|&&k| !owned_here(k))
                .map(|&k| lens[k] as usize)
                .sum()
        } else {
            total
        };
        // Where each block's samples are: in `samples` (read back) or kept on the GPU, in
        // `order`'s order (own blocks ascending, after the others).
        let mut at = vec![None; mine.len()];
        let mut segments = Vec::new();
        let mut kept = Vec::new();
        let mut pos = 0usize;
        for &k in &order {
            if keep && owned_here(k) {
                segments.push([(pos - read) as u32, lens[k]]);
                kept.push(k);
            } else {
                at[k] = Some(pos);
            }
            pos += lens[k] as usize;
        }
        let (sc, s, wall) = (&self.packed, &self.settings, self.wall.as_ref());
        let t_call = Instant::now();
        let (samples, kept_rays) = match &mut self.gpu {
            Some(g) if keep => {
                let samples =
                    g.run
                        .samples_prefix(&g.ctx, &g.scene, &pixels, &ordered_counts, read)?;
                let out = g.run.out();
                let owned = g.owned.as_mut().expect("checked above");
                let rays =
                    owned.keep(&g.ctx, out, read as u64, (total - read) as u32, &segments)?;
                (samples, rays)
            }
            Some(g) => (
                g.run
                    .samples_raw(&g.ctx, &g.scene, &pixels, &ordered_counts)?,
                Vec::new(),
            ),
            None => (
                samples_cpu(sc, s, wall, &pixels, &ordered_counts)
                    .into_iter()
                    .map(|(c, r)| [c.x, c.y, c.z, f32::from_bits(r)])
                    .collect(),
                Vec::new(),
            ),
        };
        stats.ms_trace_call = t_call.elapsed().as_secs_f64() * 1e3;
        let read_blocks: Vec<(usize, [u32; 2])> = (0..mine.len())
            .filter_map(|k| at[k].map(|a| (k, [a as u32, lens[k]])))
            .collect();
        let read_segments: Vec<[u32; 2]> = read_blocks.iter().map(|&(_, seg)| seg).collect();
        let mut rays = vec![0u32; mine.len()];
        for (&(k, _), r) in read_blocks.iter().zip(block_rays(&samples, &read_segments)) {
            rays[k] = r;
        }
        for (&k, r) in kept.iter().zip(kept_rays) {
            rays[k] = r;
        }
        stats.pixels_traced = total as u64;
        stats.rays = rays.iter().map(|&r| u64::from(r)).sum();
        stats.ms_trace = t0.elapsed().as_secs_f64() * 1e3;
        Ok(Traced {
            blocks: mine,
            samples,
            at,
            kept,
            kept_on_gpu: keep,
            rays,
        })
    }

    /// Step 5, first half: every rank's samples posted to the owners of their blocks, and every
    /// block's rays to every rank (the deal's weights). An owner counts the samples of its
    /// pixels now — a pixel's count is its sample index, which the next frame's counts need,
    /// and a sample counts whatever its value — and adds their sums when they arrive
    /// ([`Self::collect`]).
    fn post(
        &mut self,
        c: &mut Cluster,
        list: Arc<BlockList>,
        tracer: Vec<u32>,
        mine: Traced,
    ) -> Result<(), ClusterError> {
        debug_assert!(self.in_flight.is_none(), "one frame's samples in flight");
        let n = self.ranks;
        let rays: Vec<u8> = mine.rays.iter().flat_map(|r| r.to_le_bytes()).collect();
        // Each other owner's share: the rays, then 12 bytes a sample of its blocks.
        let owner_of = |i: usize| self.owners.owner[list.blocks[i] as usize] as usize;
        let mut bytes = vec![0usize; n];
        for &i in &mine.blocks {
            bytes[owner_of(i)] += 12 * list.len_of(i) as usize;
        }
        let mut parts: Vec<Vec<u8>> = (0..n)
            .map(|r| {
                if r == self.rank {
                    Vec::new()
                } else {
                    let mut part = Vec::with_capacity(rays.len() + bytes[r]);
                    part.extend_from_slice(&rays);
                    part
                }
            })
            .collect();
        for (k, &i) in mine.blocks.iter().enumerate() {
            let len = list.len_of(i) as usize;
            let owner = owner_of(i);
            if owner != self.rank {
                // Other owners' samples are always read back.
                let at = mine.at[k].expect("another owner's block is read back");
                let part = &mut parts[owner];
                for s in &mine.samples[at..at + len] {
                    part.extend_from_slice(&rgb_bytes(s));
                }
            }
        }
        // Each owned block's pixels counted in its own slot: the blocks on all cores.
        let mut jobs: Vec<Option<&[u32]>> = vec![None; self.slots()];
        for i in 0..list.blocks.len() {
            if let Some(base) = self.own_base(list.blocks[i]) {
                jobs[base / BLOCK_PIXELS as usize] = Some(list.pixels_of(i));
            }
        }
        let width = self.settings.width;
        self.counts
            .par_chunks_mut(BLOCK_PIXELS as usize)
            .zip(jobs.par_iter())
            .for_each(|(counts, job)| {
                for &p in job.unwrap_or_default() {
                    counts[local_in_block(p, width)] += 1;
                }
            });
        self.total += list.len();
        let what = format!("the samples of iteration {}", self.iteration);
        let own = c.all_to_all_post(&what, parts)?;
        self.in_flight = Some(InFlight {
            iteration: self.iteration,
            list,
            tracer,
            mine,
            own,
            stale: false,
        });
        Ok(())
    }

    /// Step 5, second half: the posted frame's samples (if one is in flight) received, and
    /// their sums added by the owners of their blocks — unless the accumulation restarted
    /// since — and every block's rays recorded for the next deals.
    fn collect(&mut self, c: &mut Cluster) -> Result<(), ClusterError> {
        let Some(f) = self.in_flight.take() else {
            return Ok(());
        };
        let (list, tracer, mine) = (&f.list, &f.tracer, &f.mine);
        let what = format!("the samples of iteration {}", f.iteration);
        let got = c.all_to_all_collect(&what, f.own)?;
        // Own blocks first (no bytes), then each other rank's, by the same layout: each owned
        // block's samples found (at most one rank traced it), then added — on this rank's GPU
        // where its owned sums are there, else on all cores, a block's pixels in its own slot.
        let mut jobs: Vec<Option<(&[u32], BlockSamples)>> = vec![None; self.slots()];
        for (k, &i) in mine.blocks.iter().enumerate() {
            let len = list.len_of(i) as usize;
            let b = list.blocks[i];
            if let (Some(base), Some(at)) = (self.own_base(b), mine.at[k]) {
                let samples = BlockSamples::Own(&mine.samples[at..at + len]);
                jobs[base / BLOCK_PIXELS as usize] = Some((list.pixels_of(i), samples));
            }
            self.costs.record(b, mine.rays[k], len as u32);
        }
        for (src, bytes) in got.iter().enumerate() {
            if src == self.rank {
                continue;
            }
            let theirs: Vec<usize> = (0..list.blocks.len())
                .filter(|&i| tracer[i] as usize == src)
                .collect();
            let owned: Vec<bool> = theirs
                .iter()
                .map(|&i| self.owners.owner[list.blocks[i] as usize] as usize == self.rank)
                .collect();
            let samples: usize = theirs
                .iter()
                .zip(&owned)
                .filter(|(_, o)| **o)
                .map(|(&i, _)| list.len_of(i) as usize)
                .sum();
            let expected = 4 * theirs.len() + 12 * samples;
            if bytes.len() != expected {
                return Err(ExchangeError::Length {
                    rank: src,
                    what,
                    got: bytes.len(),
                    expected,
                }
                .into());
            }
            let (ray_bytes, rgb) = bytes.split_at(4 * theirs.len());
            let mut off = 0;
            for (k, &i) in theirs.iter().enumerate() {
                let b = list.blocks[i];
                let len = list.len_of(i) as usize;
                let r = u32::from_le_bytes(ray_bytes[4 * k..4 * k + 4].try_into().expect("4"));
                self.costs.record(b, r, len as u32);
                if owned[k] {
                    let base = self.own_base(b).expect("a block of this rank");
                    let samples = BlockSamples::Wire(&rgb[12 * off..12 * (off + len)]);
                    jobs[base / BLOCK_PIXELS as usize] = Some((list.pixels_of(i), samples));
                    off += len;
                }
            }
        }
        let width = self.settings.width;
        if let Some(g) = self.gpu.as_deref_mut()
            && let Some(owned) = g.owned.as_mut()
        {
            // The kept samples' destinations in kept order, then every other sample's.
            let mut own_dst = Vec::new();
            for &k in &mine.kept {
                let i = mine.blocks[k];
                let base = own_base_of(&self.slot, list.blocks[i]).expect("a block of this rank");
                own_dst.extend(
                    list.pixels_of(i)
                        .iter()
                        .map(|&p| (base + local_in_block(p, width)) as u32),
                );
            }
            let (mut rgb, mut dst) = (Vec::new(), Vec::new());
            for (slot, job) in jobs.iter().enumerate() {
                let Some((pixels, samples)) = job else {
                    continue;
                };
                let base = slot * BLOCK_PIXELS as usize;
                dst.extend(
                    pixels
                        .iter()
                        .map(|&p| (base + local_in_block(p, width)) as u32),
                );
                match samples {
                    BlockSamples::Own(v) => {
                        for s in *v {
                            rgb.extend_from_slice(&s[..3]);
                        }
                    }
                    BlockSamples::Wire(bytes) => {
                        for c in bytes.chunks_exact(12) {
                            rgb.extend_from_slice(&rgb_of(c).to_array());
                        }
                    }
                }
            }
            if f.stale {
                // Restarted since: the kept samples go, nothing is added.
                if mine.kept_on_gpu {
                    owned.drop_kept();
                }
            } else {
                owned.add(&g.ctx, mine.kept_on_gpu.then_some(&own_dst[..]), &rgb, &dst)?;
                self.sums_stale = true;
            }
        } else if !f.stale {
            self.sums
                .par_chunks_mut(BLOCK_PIXELS as usize)
                .zip(jobs.par_iter())
                .for_each(|(sums, job)| match job {
                    Some((pixels, BlockSamples::Own(samples))) => {
                        for (&p, s) in pixels.iter().zip(*samples) {
                            let v = Vec3::new(s[0], s[1], s[2]);
                            accumulate_sums(&mut sums[local_in_block(p, width)], v);
                        }
                    }
                    Some((pixels, BlockSamples::Wire(bytes))) => {
                        for (&p, c) in pixels.iter().zip(bytes.chunks_exact(12)) {
                            accumulate_sums(&mut sums[local_in_block(p, width)], rgb_of(c));
                        }
                    }
                    None => {}
                });
        }
        Ok(())
    }

    /// The owned sums as the readers need them: on a GPU rank whose owned sums live on its
    /// GPU, read back when they changed since the last time.
    fn sync_sums(&mut self) -> Result<(), ClusterError> {
        if !self.sums_stale {
            return Ok(());
        }
        if let Some(g) = self.gpu.as_deref()
            && let Some(owned) = &g.owned
        {
            let n = self.sums.len();
            let mut sums = owned.read(&g.ctx)?;
            sums.truncate(n);
            self.sums = sums;
        }
        self.sums_stale = false;
        Ok(())
    }

    /// Brings every owner the samples still in flight: before the accumulation is read
    /// (gathers, pictures, the ROI's progress) and at the end of a render. Every rank calls it
    /// at the same point (it is a collective when samples are in flight).
    pub fn finish(&mut self, c: &mut Cluster) -> Result<(), ClusterError> {
        self.collect(c)
    }

    /// Whether a frame's samples travel while the next frame is traced (`true`, the default)
    /// or reach their owners within the frame. The results are the same bit for bit; only
    /// when the exchange's time is spent differs (and the deal's weights lag a frame behind).
    pub fn set_overlap(&mut self, overlap: bool) {
        self.overlap = overlap;
    }

    /// Where pixel `p`'s sums and count are in `sums` and `counts`, if its block is this
    /// rank's.
    fn own_index(&self, p: u32) -> Option<usize> {
        let b = block_of(p, self.settings.width, self.owners.tiles[0]);
        self.own_base(b).map(|base| base + self.local(p))
    }

    /// Where block `b`'s pixels begin in `sums` and `counts`, if the block is this rank's (the
    /// loops over a block's pixels look it up once, not per pixel).
    fn own_base(&self, b: u32) -> Option<usize> {
        own_base_of(&self.slot, b)
    }

    /// Pixel `p`'s place inside its block (row-major).
    fn local(&self, p: u32) -> usize {
        local_in_block(p, self.settings.width)
    }

    /// The owned blocks' slots (`BLOCK_PIXELS` entries of `sums` and `counts` each).
    fn slots(&self) -> usize {
        self.counts.len() / BLOCK_PIXELS as usize
    }

    /// An owned pixel's sums and count as they travel: 16 bytes of sums (f32), 4 of count.
    fn own_bytes(&self, p: u32, out: &mut Vec<u8>) {
        let k = self.own_index(p).expect("a pixel of this rank");
        out.extend(f32_bytes(&self.sums[k]));
        out.extend(self.counts[k].to_le_bytes());
    }

    /// How far the ROI has come, on rank 0 (`Some(None)` without ROI pixels; `None` on the
    /// other ranks): every owner sends rank 0 the sums and counts of its pixels inside the ROI
    /// (d = 0), [`PIXEL_BYTES`] each, and rank 0 measures them as one process does.
    pub fn roi_progress(
        &mut self,
        c: &mut Cluster,
    ) -> Result<Option<Option<RoiProgress>>, ClusterError> {
        self.collect(c)?;
        self.sync_sums()?;
        let size = [self.settings.width, self.settings.height];
        let tiles_x = self.owners.tiles[0];
        let in_roi = |p: &u32| self.dgi.get(*p as usize) == Some(&0.0);
        let mut mine = Vec::new();
        for b in self.owners.owned_by(self.rank) {
            for p in block_pixels(b, size, tiles_x).filter(in_roi) {
                self.own_bytes(p, &mut mine);
            }
        }
        let Some(all) = c.gather("the ROI's sums", mine)? else {
            return Ok(None);
        };
        let (mut sum, mut count) = (Vec::new(), Vec::new());
        for (src, bytes) in all.iter().enumerate() {
            let pixels: Vec<u32> = self
                .owners
                .owned_by(src)
                .into_iter()
                .flat_map(|b| block_pixels(b, size, tiles_x).filter(in_roi))
                .collect();
            let pixels =
                sums_and_counts(bytes, pixels.len()).ok_or_else(|| ExchangeError::Length {
                    rank: src,
                    what: "the ROI's sums".into(),
                    got: bytes.len(),
                    expected: PIXEL_BYTES * pixels.len(),
                })?;
            for (s, n) in pixels {
                sum.push(s);
                count.push(n);
            }
        }
        let n = sum.len();
        let acc = Accumulation {
            width: n as u32,
            height: 1,
            sum,
            count,
        };
        Ok(Some(RoiProgress::measure(&acc, &vec![0.0; n])))
    }

    /// The whole accumulation and the DGI the last frame used, on rank 0 (`None` on the
    /// others): every owner sends rank 0 its sums and counts.
    pub fn gather(
        &mut self,
        c: &mut Cluster,
    ) -> Result<Option<(Accumulation, Vec<f32>)>, ClusterError> {
        self.gather_every(c, 1)
    }

    /// [`Self::gather`] of the pixels at every `step`-th column of every `step`-th row only,
    /// as an image of ⌈W / step⌉ × ⌈H / step⌉: [`Accumulation::every`] of the whole
    /// accumulation (and the DGI's pixels there), for a picture smaller than the wall — rank
    /// 0's console. Each owner sends those of its pixels ([`PIXEL_BYTES`] each): 1/step² of
    /// the whole gather's bytes.
    pub fn gather_every(
        &mut self,
        c: &mut Cluster,
        step: u32,
    ) -> Result<Option<(Accumulation, Vec<f32>)>, ClusterError> {
        self.collect(c)?;
        self.sync_sums()?;
        let size = [self.settings.width, self.settings.height];
        let pixels_of = |rank: usize| {
            let tiles_x = self.owners.tiles[0];
            self.owners
                .owned_by(rank)
                .into_iter()
                .flat_map(move |b| block_pixels_every(b, size, tiles_x, step))
        };
        let mut mine = Vec::new();
        for p in pixels_of(self.rank) {
            self.own_bytes(p, &mut mine);
        }
        let Some(all) = c.gather("the owners' sums", mine)? else {
            return Ok(None);
        };
        let [w, h] = every_size(size, step);
        let mut acc = Accumulation::new(w, h);
        for (src, bytes) in all.iter().enumerate() {
            let pixels: Vec<u32> = pixels_of(src).collect();
            let values =
                sums_and_counts(bytes, pixels.len()).ok_or_else(|| ExchangeError::Length {
                    rank: src,
                    what: "the owners' sums".into(),
                    got: bytes.len(),
                    expected: PIXEL_BYTES * pixels.len(),
                })?;
            for (p, (s, n)) in pixels.into_iter().zip(values) {
                let o = ((p / size[0]) / step * w + (p % size[0]) / step) as usize;
                acc.sum[o] = s;
                acc.count[o] = n;
            }
        }
        let dgi = if self.guidance.is_some() {
            every(&self.dgi, size, step)
        } else {
            vec![0.0; w as usize * h as usize]
        };
        Ok(Some((acc, dgi)))
    }

    /// The blocks per row and column of the image.
    #[must_use]
    pub fn block_grid(&self) -> [u32; 2] {
        block_grid([self.settings.width, self.settings.height])
    }
}

/// The samples this rank traced in a frame.
struct Traced {
    /// Indices into the frame's [`BlockList`], ascending.
    blocks: Vec<usize>,
    /// The samples read back: RGB, then the sample's rays as the bits of the fourth float
    /// (the GPU's read-back as it comes).
    samples: Vec<[f32; 4]>,
    /// Per block: where its samples begin in `samples`, or `None` where they stayed on the
    /// GPU (an owned block of a GPU rank whose owned sums are there).
    at: Vec<Option<usize>>,
    /// The blocks (positions in `blocks`) whose samples stayed on the GPU, in the order the
    /// GPU keeps them: ascending.
    kept: Vec<usize>,
    /// Whether the GPU kept this frame's own samples (even none): its collect takes them.
    kept_on_gpu: bool,
    /// Rays per block.
    rays: Vec<u32>,
}

/// Where block `b`'s pixels begin in a rank's sums and counts, by its `slot` table.
fn own_base_of(slot: &[u32], b: u32) -> Option<usize> {
    let slot = slot[b as usize];
    if slot == u32::MAX {
        None
    } else {
        Some((slot * BLOCK_PIXELS) as usize)
    }
}

/// Pixel `p`'s place inside its block (row-major) in an image `width` pixels wide.
fn local_in_block(p: u32, width: u32) -> usize {
    let (x, y) = (p % width, p / width);
    ((y % TILE_EDGE) * TILE_EDGE + x % TILE_EDGE) as usize
}

/// The samples an owned block receives in one frame: its own (as traced here) or another
/// rank's (as they travelled).
#[derive(Clone, Copy)]
enum BlockSamples<'a> {
    Own(&'a [[f32; 4]]),
    Wire(&'a [u8]),
}

/// A sample's RGB as it travels: three f32, little-endian.
fn rgb_bytes(s: &[f32; 4]) -> [u8; 12] {
    let mut b = [0u8; 12];
    for (c, v) in b.chunks_exact_mut(4).zip(&s[..3]) {
        c.copy_from_slice(&v.to_le_bytes());
    }
    b
}

/// The RGB of a sample's 12 travelling bytes.
fn rgb_of(b: &[u8]) -> Vec3 {
    let f = |k: usize| f32::from_le_bytes(b[4 * k..4 * k + 4].try_into().expect("4 bytes"));
    Vec3::new(f(0), f(1), f(2))
}

/// The DGI computed by the ranks together ([`DgiMode::Split`]): rank k of N computes the bands
/// of 16 rows k, k + N, … ([`crate::frame::dgi_cpu_bands`], each bit for bit the whole
/// image's), and every rank sends its bands to every other; every rank ends with the whole DGI.
pub fn split_dgi(
    c: &mut Cluster,
    surface: &Surface,
    pitch_m: f64,
    config: &GuideConfig,
    roi: Option<&Roi>,
    size: [u32; 2],
) -> Result<Vec<f32>, ClusterError> {
    let (me, n) = (c.rank(), c.ranks());
    let mut dgi = crate::frame::dgi_cpu_bands(surface, pitch_m, config, roi, size, (me, n))?;
    let (w, h, band) = (size[0] as usize, size[1] as usize, crate::roi::dgi::BLOCK);
    let rows = |b: usize| b * band * w..((b + 1) * band).min(h) * w;
    let bands_of = |r: usize| (r..h.div_ceil(band)).step_by(n);
    let mut mine = Vec::new();
    for b in bands_of(me) {
        mine.extend_from_slice(&f32_bytes(&dgi[rows(b)]));
    }
    let what = "the DGI's bands";
    let got = c.all_to_all(what, vec![mine; n])?;
    for (src, bytes) in got.iter().enumerate() {
        if src == me {
            continue;
        }
        let expected: usize = bands_of(src).map(|b| 4 * rows(b).len()).sum();
        if bytes.len() != expected {
            return Err(ExchangeError::Length {
                rank: src,
                what: what.into(),
                got: bytes.len(),
                expected,
            }
            .into());
        }
        let mut at = 0;
        for b in bands_of(src) {
            let r = rows(b);
            let len = 4 * r.len();
            for (v, c) in dgi[r].iter_mut().zip(bytes[at..at + len].chunks_exact(4)) {
                *v = f32::from_le_bytes(c.try_into().expect("4 bytes"));
            }
            at += len;
        }
    }
    Ok(dgi)
}

/// Blocks' selected slots as bytes: per block a flag byte (0: none), then its mask's 128
/// bytes when the flag is 1.
fn encode_masks(masks: &[crate::schedule::SlotMask]) -> Vec<u8> {
    let mut b = Vec::new();
    for m in masks {
        if m.iter().all(|&w| w == 0) {
            b.push(0);
        } else {
            b.push(1);
            for w in m {
                b.extend(w.to_le_bytes());
            }
        }
    }
    b
}

/// The inverse of [`encode_masks`] for `blocks` blocks, or what is wrong with the bytes.
fn decode_masks(b: &[u8], blocks: usize) -> Result<Vec<crate::schedule::SlotMask>, String> {
    let mut out = Vec::with_capacity(blocks);
    let mut at = 0;
    for k in 0..blocks {
        match b.get(at) {
            Some(0) => {
                out.push([0; 32]);
                at += 1;
            }
            Some(1) => {
                let words = b
                    .get(at + 1..at + 129)
                    .ok_or_else(|| format!("block {k} of {blocks}: its mask is cut short"))?;
                let mut m = [0u32; 32];
                for (w, c) in m.iter_mut().zip(words.chunks_exact(4)) {
                    *w = u32::from_le_bytes(c.try_into().expect("4 bytes"));
                }
                out.push(m);
                at += 129;
            }
            Some(f) => return Err(format!("block {k} of {blocks}: flag {f}, not 0 or 1")),
            None => return Err(format!("{} bytes for {blocks} blocks", b.len())),
        }
    }
    if at != b.len() {
        return Err(format!(
            "{} bytes for {blocks} blocks, {} past them",
            b.len(),
            b.len() - at
        ));
    }
    Ok(out)
}

/// f32s as little-endian bytes.
#[must_use]
pub fn f32_bytes(v: &[f32]) -> Vec<u8> {
    if cfg!(target_endian = "little") {
        // The bytes as they lie: a copy, not a value at a time (a DGI is tens of MB).
        bytemuck::cast_slice(v).to_vec()
    } else {
        let mut b = Vec::with_capacity(4 * v.len());
        for x in v {
            b.extend_from_slice(&x.to_le_bytes());
        }
        b
    }
}

/// The most pixels of the picture rank 0's console window shows across ranks (`view
/// --cluster`): a 4K monitor's (the window asks for no more than it shows). A larger wall's picture is reduced to every k-th pixel of every
/// k-th row (`viewer::core::ViewerCore::console_every`), so that the owners send rank 0 those pixels only —
/// 20 bytes each, where HORNET's 73.8 megapixels whole are 1.5 GB a picture — and rank 0
/// filters and draws only what its window can show. Saving takes the whole picture.
pub const CONSOLE_PIXELS: u64 = 3840 * 2160;

/// The least k for which every k-th pixel of every k-th row of a `size` image is at most
/// `max` pixels (at least one).
#[must_use]
pub fn reduction_for(size: [u32; 2], max: u64) -> u32 {
    (1..=size[0].max(size[1]).max(1))
        .find(|&k| {
            let [w, h] = every_size(size, k);
            u64::from(w) * u64::from(h) <= max.max(1)
        })
        .unwrap_or(1)
}

/// Little-endian bytes as f32s (a multiple of `group` values; a shorter tail is dropped, and
/// the callers check lengths first).
/// Bytes a pixel's sums and count take on the link: 16 of sums (f32), 4 of count (u32).
pub const PIXEL_BYTES: usize = 20;

/// `pixels` pairs of sums and count from `b` ([`PIXEL_BYTES`] each), or `None` if `b` is not
/// that long.
fn sums_and_counts(b: &[u8], pixels: usize) -> Option<Vec<([f32; 4], u32)>> {
    (b.len() == PIXEL_BYTES * pixels).then(|| {
        b.chunks_exact(PIXEL_BYTES)
            .map(|c| {
                let f = |k: usize| f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().expect("4"));
                let n = u32::from_le_bytes(c[16..20].try_into().expect("4"));
                ([f(0), f(1), f(2), f(3)], n)
            })
            .collect()
    })
}

fn f32s(b: &[u8], group: usize) -> Vec<f32> {
    let whole = b.len() / (4 * group) * 4 * group;
    b[..whole]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect()
}

#[cfg(test)]
mod tests;
