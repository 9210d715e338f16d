//! `raygun bench guided --cluster`: the paper's guided setup across ranks (DESIGN.md §12).
//!
//! * **Strong scaling**, measured: the same guided iterations (HORNET, viewer 1 m in front of
//!   the centre, 10° and 60°) on the ranks of the job it runs in — under `mpirun -np N` with
//!   the `cluster` feature, or as threads of one process (`--cluster-threads N`, the in-memory
//!   exchange), each rank on its GPU or CPU twin (`--backend`). Per rank: ms per iteration, of it
//!   tracing and exchanging, bytes sent and received per iteration; and the DGI's two ways
//!   to reach the ranks, each rank computing it against rank 0 broadcasting it; and a picture
//!   of the wall made both ways, every owner filtering its own tiles against rank 0 gathering
//!   and filtering the whole image.
//! * **Exchange**, counted exactly: for larger images (default 3840×2160 and HORNET's native
//!   13519×5457) the real schedule, deal and default tile map of one iteration, without
//!   tracing — the bytes each rank sends and receives for 1 to 35 ranks (the deal's weights
//!   taken equal: a real run weights by measured rays, which moves blocks, not bytes' total),
//!   and per picture the owners' margins against the gather to rank 0.
//! * **Model**: from those bytes and a stated link speed, the per-GPU trace rate at which the
//!   exchange takes as long as the tracing, for 1–35 ranks, and the iterations per second at a
//!   measured rate (the ranks' backend's: the CPU twin's here, a GPU rank's on a GPU machine).

use std::time::Instant;

use serde::Serialize;

use super::{median, paper};
use crate::cluster::deal::{BlockList, CostTable, deal};
use crate::cluster::owners::{BlockOwners, TileOwners};
use crate::cluster::{
    Cluster, ClusterError, ClusterFrameStats, ClusterRenderer, ClusterSetup, DgiMode, f32_bytes,
};
use crate::display::DisplayModel;
use crate::frame::{FrameError, GuideConfig, Render, dgi_cpu};
use crate::roi::cone::ConeError;
use crate::roi::dgi::Surface;
use crate::scene::Scene;
use crate::schedule::{Order, ScheduleError, schedule_cpu};
use crate::trace::camera::CameraError;

/// Bytes of one sample on the link (linear RGB, f32), of its count on the way to its tracer
/// (u32), and of one block's rays.
pub const SAMPLE_BYTES: u64 = 12;
pub const COUNT_BYTES: u64 = 4;
pub const BLOCK_RAYS_BYTES: u64 = 4;
/// The split schedule's bytes per block drawn (its flag) and per non-empty block (its mask).
pub const MASK_FLAG_BYTES: u64 = 1;
pub const MASK_BYTES: u64 = 128;
/// A control message with an ROI change (6 bytes of header, a cone's 14 f64s).
pub const CONTROL_BYTES: u64 = 6 + 14 * 8;

#[derive(Debug, thiserror::Error)]
pub enum ClusterBenchError {
    #[error(transparent)]
    Cluster(#[from] ClusterError),
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error(transparent)]
    Cone(#[from] ConeError),
    #[error(transparent)]
    Schedule(#[from] ScheduleError),
    #[error(transparent)]
    Camera(#[from] CameraError),
}

/// What to measure and model.
#[derive(Clone, Debug, Serialize)]
pub struct ClusterBenchConfig {
    pub scene: String,
    pub size: [u32; 2],
    pub fovs_deg: Vec<f64>,
    pub iterations: u32,
    pub max_depth: u32,
    /// Sizes of the exchange count and the model.
    pub model_sizes: Vec<[u32; 2]>,
    /// Largest rank count of the exchange count.
    pub model_ranks: usize,
    /// The stated link speed of the model, Gbit/s.
    pub link_gbps: f64,
}

/// One FOV's measured run on one rank.
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize)]
pub struct RankRun {
    pub rank: usize,
    /// With each frame's samples travelling while the next frame is traced (the default).
    pub ms_per_iteration: f64,
    /// The same iterations with each frame's samples collected within it, run after them.
    #[serde(default)]
    pub ms_per_iteration_sync: f64,
    pub ms_trace: f64,
    /// Of `ms_trace`, the tracer's call (GPU: the list's upload, the kernel, the samples'
    /// read-back; CPU: the tracing); the rest is the host's work around it.
    #[serde(default)]
    pub ms_trace_call: f64,
    pub ms_schedule: f64,
    /// The counts of the pixels this rank traces for other owners (received before the trace).
    #[serde(default)]
    pub ms_counts: f64,
    pub ms_exchange: f64,
    pub samples_traced_per_iteration: f64,
    pub bytes_sent_per_iteration: f64,
    pub bytes_received_per_iteration: f64,
    /// The DGI computed on this rank (ms): on its GPU for a GPU rank, as the renderer does.
    pub ms_dgi_compute: f64,
    /// The DGI broadcast from rank 0, received (or sent) here (ms).
    pub ms_dgi_broadcast: f64,
    /// The DGI split on the CPU twins: this rank's bands computed, then every rank's bands
    /// exchanged (ms). A GPU rank splits no work (it computes the whole DGI on its GPU, the
    /// compute column, and only exchanges the bands).
    pub ms_dgi_split: f64,
    /// After the iterations, the picture of the tiles this rank owns: the margins' exchange
    /// and the filter of its own tiles (ms; every owner at once).
    pub ms_tile_pictures: f64,
    /// The bytes that exchange sent and received here.
    pub tile_pictures_bytes_sent: u64,
    pub tile_pictures_bytes_received: u64,
    /// Rank 0 only: the whole picture the other way, the owners' sums gathered to rank 0 and
    /// the whole image filtered there (ms; on its GPU when it traces on one).
    pub ms_gather_and_filter: f64,
    /// Rank 0 only: the picture `view --cluster` shows on its console, every k-th pixel of
    /// every k-th row ([`crate::cluster::reduction_for`] at
    /// [`crate::cluster::CONSOLE_PIXELS`]; k = 1: the whole one above), gathered and
    /// filtered (ms), and the bytes rank 0 received for it.
    pub console_every: u32,
    pub ms_console_picture: f64,
    pub console_bytes_received: u64,
}

/// One FOV's measured run on all ranks.
#[derive(Clone, Debug, Serialize)]
pub struct ScalingRow {
    pub fov_deg: f64,
    pub ranks: usize,
    /// Samples per iteration on all ranks, as a share of the image.
    pub share_sampled: f64,
    pub samples_per_iteration: f64,
    pub per_rank: Vec<RankRun>,
}

impl ScalingRow {
    /// Rank 0's ms per iteration (the job's pace: every rank waits for the slowest each
    /// iteration).
    #[must_use]
    pub fn ms_per_iteration(&self) -> f64 {
        self.per_rank[0].ms_per_iteration
    }

    /// Rank 0's ms per iteration with the exchange not overlapped.
    #[must_use]
    pub fn ms_per_iteration_sync(&self) -> f64 {
        self.per_rank[0].ms_per_iteration_sync
    }
}

/// One size × FOV × rank count of the exchange count.
#[derive(Clone, Debug, Serialize)]
pub struct ExchangeRow {
    /// `columns` (the default map: whole columns dealt evenly) or `tiles` (tile i to rank
    /// i mod N, which spreads the ROI's tiles).
    pub tile_map: &'static str,
    pub size: [u32; 2],
    pub fov_deg: f64,
    pub ranks: usize,
    pub samples_per_iteration: u64,
    pub bytes_sent_max: u64,
    pub bytes_sent_mean: f64,
    pub bytes_received_max: u64,
    /// Per rank, the larger of its sent and received bytes before the trace (the split
    /// schedule's masks, the counts, the control) and after it (the samples and the blocks'
    /// rays, which travel during the next trace when the exchange is overlapped).
    pub link_bytes_now: Vec<u64>,
    pub link_bytes_later: Vec<u64>,
    /// The bytes the DGI's broadcast moves per ROI change over all links (every rank but 0
    /// receives 4 bytes a pixel; down the binomial tree rank 0 sends ⌈log₂ N⌉ of those copies).
    pub dgi_broadcast_bytes: u64,
    /// Per picture of the whole wall (not per iteration): the most any rank sends and receives
    /// for its tiles' margins (the default fast filter, k_max 16; 20 bytes a pixel), against the
    /// whole accumulation rank 0 receives when it assembles the picture instead.
    pub margin_sent_max: u64,
    pub margin_received_max: u64,
    pub gather_received: u64,
    /// Per picture of `view --cluster`'s console: what rank 0 receives for every k-th pixel
    /// of every k-th row ([`crate::cluster::reduction_for`] at
    /// [`crate::cluster::CONSOLE_PIXELS`]), and that k.
    pub console_every: u32,
    pub console_received: u64,
}

impl ExchangeRow {
    /// Seconds the busiest rank's link needs per iteration at `gbps` (sending and receiving
    /// overlap on a full-duplex link: the larger of the two).
    #[must_use]
    pub fn link_seconds(&self, gbps: f64) -> f64 {
        self.bytes_sent_max.max(self.bytes_received_max) as f64 * 8.0 / (gbps * 1e9)
    }

    /// Seconds per iteration with the exchange overlapped, each rank tracing at `rate`
    /// samples/s over a `gbps` link: the slowest rank's before-the-trace bytes plus the longer
    /// of its trace and its after-the-trace bytes (which travel during the next trace).
    #[must_use]
    pub fn overlapped_seconds(&self, gbps: f64, rate: f64) -> f64 {
        let trace = self.samples_per_iteration as f64 / self.ranks as f64 / rate;
        let secs = |b: u64| b as f64 * 8.0 / (gbps * 1e9);
        self.link_bytes_now
            .iter()
            .zip(&self.link_bytes_later)
            .map(|(&now, &later)| secs(now) + trace.max(secs(later)))
            .fold(trace, f64::max)
    }

    /// The per-rank trace rate (samples/s) at which tracing a rank's share takes as long as its
    /// exchange: above it, the link dominates.
    #[must_use]
    pub fn break_even_rate(&self, gbps: f64) -> f64 {
        let t = self.link_seconds(gbps);
        if t == 0.0 {
            f64::INFINITY
        } else {
            self.samples_per_iteration as f64 / self.ranks as f64 / t
        }
    }
}

/// Everything.
#[derive(Clone, Debug, Serialize)]
pub struct ClusterBenchReport {
    pub device: String,
    pub config: ClusterBenchConfig,
    pub scaling: Vec<ScalingRow>,
    pub exchange: Vec<ExchangeRow>,
}

/// The measured guided run on this job's ranks (rank 0 gets the rows).
///
/// One function of some 180 lines on purpose: each FOV's measurements are collectives that
/// every rank must reach in the same order (frames, the DGI's broadcast and split, the owners'
/// pictures, the gathers, the numbers to rank 0); read top to bottom, the function is that
/// order.
// Long: the collectives every rank must reach in one order, top to bottom (see above).
pub fn scaling(
    c: &mut Cluster,
    scene: &Scene,
    display: &DisplayModel,
    cfg: &ClusterBenchConfig,
    gpu: Option<std::sync::Arc<crate::gpu::GpuContext>>,
) -> Result<Option<Vec<ScalingRow>>, ClusterBenchError> {
    let (rank, ranks) = (c.rank(), c.ranks());
    let owners = BlockOwners::of_display(display, &TileOwners::columns(display, ranks), cfg.size);
    let mut rows = Vec::new();
    for &fov in &cfg.fovs_deg {
        let settings = paper::settings(scene, cfg.size, 1, cfg.max_depth)?;
        let roi = paper::roi(fov)?;
        let config = GuideConfig::default();
        let setup = ClusterSetup {
            settings,
            guide: Some((display, config)),
            wall: None,
            owners: owners.clone(),
            dgi_mode: DgiMode::Compute,
        };
        let mut r = ClusterRenderer::new(c, scene, setup)?;
        if let Some(ctx) = &gpu {
            r.trace_on_gpu(ctx.clone())?;
        }
        r.set_roi(Some(roi))?;
        // The broadcast alternative: rank 0's DGI, computed before the first frame so that the
        // timed broadcast right after it (the frame's exchange leaves the ranks in step) is the
        // transfer alone.
        let surface = Surface::from_model(display);
        let dgi = if r.cluster().is_root() {
            f32_bytes(&dgi_cpu(
                &surface,
                display.pitch_m(),
                &config,
                Some(&roi),
                cfg.size,
            )?)
        } else {
            Vec::new()
        };
        // The first frame computes the DGI on every rank.
        let first = r.run_frame(false)?;
        // Its samples delivered, so that the timed iterations' bytes are theirs alone.
        r.finish()?;
        let t0 = Instant::now();
        r.cluster_mut()
            .broadcast("the DGI (timed)", dgi)
            .map_err(ClusterError::from)?;
        let ms_dgi_broadcast = t0.elapsed().as_secs_f64() * 1e3;
        let t0 = Instant::now();
        crate::cluster::split_dgi(
            r.cluster_mut(),
            &surface,
            display.pitch_m(),
            &config,
            Some(&roi),
            cfg.size,
        )?;
        let ms_dgi_split = t0.elapsed().as_secs_f64() * 1e3;
        let mut frames: Vec<(f64, ClusterFrameStats)> = Vec::new();
        let before = r.cluster().traffic();
        for _ in 0..cfg.iterations.max(1) {
            let t = Instant::now();
            let s = r.run_frame(false)?;
            frames.push((t.elapsed().as_secs_f64() * 1e3, s));
        }
        // The last frame's samples, still in flight, reach their owners before the pictures.
        r.finish()?;
        // The iterations' bytes, each frame's samples counted with it (a frame's own stats
        // count the samples it collected, the frame's before).
        let moved = r.cluster().traffic().since(&before);
        // The same iterations with each frame's samples collected within the frame (the
        // exchange not overlapped with the next trace), for the side-by-side column.
        r.set_overlap(false);
        let mut sync = Vec::new();
        for _ in 0..cfg.iterations.max(1) {
            let t = Instant::now();
            r.run_frame(false)?;
            sync.push(t.elapsed().as_secs_f64() * 1e3);
        }
        r.set_overlap(true);
        let n = frames.len() as f64;
        let med = |f: &dyn Fn(&ClusterFrameStats) -> f64| {
            median(frames.iter().map(|(_, s)| f(s)).collect())
        };
        let mine = RankRun {
            rank,
            ms_per_iteration: median(frames.iter().map(|(ms, _)| *ms).collect()),
            ms_per_iteration_sync: median(sync),
            ms_trace: med(&|s| s.ms_trace),
            ms_trace_call: med(&|s| s.ms_trace_call),
            ms_schedule: med(&|s| s.ms_schedule),
            ms_counts: med(&|s| s.ms_counts),
            ms_exchange: med(&|s| s.ms_exchange),
            samples_traced_per_iteration: frames
                .iter()
                .map(|(_, s)| s.pixels_traced as f64)
                .sum::<f64>()
                / n,
            bytes_sent_per_iteration: moved.bytes_sent as f64 / n,
            bytes_received_per_iteration: moved.bytes_received as f64 / n,
            ms_dgi_compute: first.ms_dgi,
            ms_dgi_broadcast,
            ms_dgi_split,
            ..RankRun::default()
        };
        // The picture, both ways: every owner its own tiles, and rank 0 the whole image.
        let params = crate::filter::FilterParams::default();
        let tile_map = TileOwners::columns(display, ranks);
        let before = r.cluster().traffic();
        let t = Instant::now();
        r.tile_pictures(display, &tile_map, &params, None)?;
        let ms_tile_pictures = t.elapsed().as_secs_f64() * 1e3;
        let moved = r.cluster().traffic();
        // Rank 0 filters where it traces, as `render --cluster` and `view --cluster` do.
        let filter_backend = match r.gpu() {
            Some(ctx) => crate::gpu::Backend::Gpu(Box::new(ctx.clone())),
            None => crate::gpu::Backend::Cpu,
        };
        let filter = crate::filter::Filter::new(&filter_backend);
        let t = Instant::now();
        if let Some((acc, dgi)) = r.gather()? {
            filter
                .image(&params, &acc, &dgi)
                .map_err(ClusterError::from)?;
        }
        let ms_gather_and_filter = if r.cluster().is_root() {
            t.elapsed().as_secs_f64() * 1e3
        } else {
            0.0
        };
        let console_every = crate::cluster::reduction_for(cfg.size, crate::cluster::CONSOLE_PIXELS);
        let console_before = r.cluster().traffic();
        let t = Instant::now();
        if let Some((acc, dgi)) = r.gather_every(console_every)? {
            filter
                .image(&params, &acc, &dgi)
                .map_err(ClusterError::from)?;
        }
        let (ms_console_picture, console_bytes_received) = if r.cluster().is_root() {
            (
                t.elapsed().as_secs_f64() * 1e3,
                r.cluster().traffic().since(&console_before).bytes_received,
            )
        } else {
            (0.0, 0)
        };
        let mine = RankRun {
            ms_tile_pictures,
            tile_pictures_bytes_sent: moved.bytes_sent - before.bytes_sent,
            tile_pictures_bytes_received: moved.bytes_received - before.bytes_received,
            ms_gather_and_filter,
            console_every,
            ms_console_picture,
            console_bytes_received,
            ..mine
        };
        let samples = frames.iter().map(|(_, s)| s.pixels as f64).sum::<f64>() / n;
        let gathered = r
            .cluster_mut()
            .gather(
                "the benchmark's numbers",
                serde_json::to_vec(&mine).expect("numbers serialise"),
            )
            .map_err(ClusterError::from)?;
        if let Some(all) = gathered {
            let per_rank = all
                .iter()
                .map(|b| serde_json::from_slice(b).unwrap_or_default())
                .collect();
            rows.push(ScalingRow {
                fov_deg: fov,
                ranks,
                share_sampled: samples / (f64::from(cfg.size[0]) * f64::from(cfg.size[1])),
                samples_per_iteration: samples,
                per_rank,
            });
        }
    }
    Ok(c.is_root().then_some(rows))
}

/// What each rank sends and receives in one frame of `list` dealt as `tracer` says, owned as
/// `owners` says, on `ranks` ranks (the control message left out): the split schedule's
/// masks (coherent order), every block's rays to every other rank, and for blocks traced away
/// from their owner the owner's counts to the tracer and the samples back. `(sent, received)`
/// per rank; the cluster's frame moves these bytes exactly (tested).
#[must_use]
pub fn frame_traffic(
    list: &BlockList,
    tracer: &[u32],
    owners: &BlockOwners,
    ranks: usize,
) -> Vec<(u64, u64)> {
    frame_traffic_lanes(list, tracer, owners, ranks, true)
        .into_iter()
        .map(|l| (l.now.0 + l.later.0, l.now.1 + l.later.1))
        .collect()
}

/// One rank's bytes of a frame by the exchange's lane: `(sent, received)` before the trace
/// (the split schedule's masks, the counts) and after it (the samples and the blocks' rays,
/// which travel during the next frame's trace when the exchange is overlapped).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LaneBytes {
    pub now: (u64, u64),
    pub later: (u64, u64),
}

/// [`frame_traffic`] by lane; `masks`: the split schedule's masks cross the link (CPU ranks;
/// GPU ranks draw the whole schedule and send none).
#[must_use]
pub fn frame_traffic_lanes(
    list: &BlockList,
    tracer: &[u32],
    owners: &BlockOwners,
    ranks: usize,
    masks: bool,
) -> Vec<LaneBytes> {
    let mut out = vec![LaneBytes::default(); ranks];
    let n = ranks as u64;
    let nblocks = owners.owner.len();
    if ranks > 1 && masks {
        let mut listed = vec![false; nblocks];
        for &b in &list.blocks {
            listed[b as usize] = true;
        }
        let part: Vec<u64> = (0..ranks)
            .map(|r| {
                (r..nblocks)
                    .step_by(ranks)
                    .map(|b| MASK_FLAG_BYTES + MASK_BYTES * u64::from(listed[b]))
                    .sum()
            })
            .collect();
        let total: u64 = part.iter().sum();
        for (r, o) in out.iter_mut().enumerate() {
            o.now.0 += part[r] * (n - 1);
            o.now.1 += total - part[r];
        }
    }
    for (i, &t) in tracer.iter().enumerate() {
        let t = t as usize;
        let o = owners.owner[list.blocks[i] as usize] as usize;
        // Its rays to every other rank.
        out[t].later.0 += BLOCK_RAYS_BYTES * (n - 1);
        for (r, l) in out.iter_mut().enumerate() {
            if r != t {
                l.later.1 += BLOCK_RAYS_BYTES;
            }
        }
        if t != o {
            // The owner's counts to the tracer, the tracer's samples back.
            let len = u64::from(list.len_of(i));
            out[o].now.0 += COUNT_BYTES * len;
            out[t].now.1 += COUNT_BYTES * len;
            out[t].later.0 += SAMPLE_BYTES * len;
            out[o].later.1 += SAMPLE_BYTES * len;
        }
    }
    out
}

/// The bytes rank 0 receives for the console's picture of a `size` image owned as `owners`
/// says ([`ClusterRenderer::gather_every`] at `every`): [`crate::cluster::PIXEL_BYTES`] for
/// each pixel on the grid of every `every`-th column and row in a block another rank owns.
#[must_use]
pub fn console_received(owners: &BlockOwners, size: [u32; 2], every: u32) -> u64 {
    let [tx, _] = owners.tiles;
    // The grid's columns (or rows) in [lo, lo + 32) of a side n long.
    let on_grid = |lo: u32, n: u32| {
        let hi = (lo + crate::schedule::TILE_EDGE).min(n);
        u64::from(hi.div_ceil(every) - lo.div_ceil(every))
    };
    (0..owners.owner.len() as u32)
        .filter(|&b| owners.owner[b as usize] != 0)
        .map(|b| {
            let (x, y) = (b % tx, b / tx);
            on_grid(x * crate::schedule::TILE_EDGE, size[0])
                * on_grid(y * crate::schedule::TILE_EDGE, size[1])
        })
        .sum::<u64>()
        * crate::cluster::PIXEL_BYTES as u64
}

/// The exact exchange of one iteration (the first: iteration 0, seed 1) of the paper's setup
/// for each size, FOV and rank count 1..=`max_ranks`, from the real schedule and the deal with
/// equal weights, for the default tile map (whole columns) and for tiles dealt round-robin.
pub fn exchange(
    display: &DisplayModel,
    sizes: &[[u32; 2]],
    fovs: &[f64],
    max_ranks: usize,
    gpu_ranks: bool,
    mut progress: impl FnMut(&str),
) -> Result<Vec<ExchangeRow>, ClusterBenchError> {
    let surface = Surface::from_model(display);
    let halo = crate::filter::halo(&crate::filter::FilterParams::default());
    let mut rows = Vec::new();
    for &size in sizes {
        let console_every = crate::cluster::reduction_for(size, crate::cluster::CONSOLE_PIXELS);
        // The margins do not depend on the FOV.
        let mut margins = std::collections::HashMap::new();
        for &fov in fovs {
            progress(&format!("exchange: {}×{}, {fov}°", size[0], size[1]));
            let roi = paper::roi(fov)?;
            let dgi = dgi_cpu(
                &surface,
                display.pitch_m(),
                &GuideConfig::default(),
                Some(&roi),
                size,
            )?;
            let list = schedule_cpu(&dgi, size[0], size[1], 0.0, 0, 1, Order::Coherent)?;
            drop(dgi);
            let list = BlockList::group(&list, size);
            let nblocks = (size[0].div_ceil(32) * size[1].div_ceil(32)) as usize;
            let costs = CostTable::new(nblocks);
            for (tile_map, ranks) in ["columns", "tiles"]
                .into_iter()
                .flat_map(|m| (1..=max_ranks).map(move |n| (m, n)))
            {
                let map = if tile_map == "columns" {
                    TileOwners::columns(display, ranks)
                } else {
                    TileOwners {
                        ranks: (0..display.tiles().len()).map(|t| t % ranks).collect(),
                    }
                };
                let owners = BlockOwners::of_display(display, &map, size);
                let (margin_sent_max, margin_received_max) =
                    *margins.entry((tile_map, ranks)).or_insert_with(|| {
                        let m = crate::cluster::picture::margin_traffic(
                            display, &map, &owners, halo, ranks,
                        );
                        (
                            m.iter().map(|t| t.0).max().unwrap_or(0),
                            m.iter().map(|t| t.1).max().unwrap_or(0),
                        )
                    });
                let tracer = deal(&list, &costs, ranks);
                let n = ranks as u64;
                let mut lanes = frame_traffic_lanes(&list, &tracer, &owners, ranks, !gpu_ranks);
                // The control (with an ROI change: the largest) from rank 0, before the trace.
                lanes[0].now.0 += CONTROL_BYTES * (n - 1);
                for l in lanes.iter_mut().skip(1) {
                    l.now.1 += CONTROL_BYTES;
                }
                let (sent, got): (Vec<u64>, Vec<u64>) = lanes
                    .iter()
                    .map(|l| (l.now.0 + l.later.0, l.now.1 + l.later.1))
                    .unzip();
                rows.push(ExchangeRow {
                    tile_map,
                    size,
                    fov_deg: fov,
                    ranks,
                    samples_per_iteration: list.len(),
                    bytes_sent_max: sent.iter().copied().max().unwrap_or(0),
                    bytes_sent_mean: sent.iter().sum::<u64>() as f64 / ranks as f64,
                    bytes_received_max: got.iter().copied().max().unwrap_or(0),
                    link_bytes_now: lanes.iter().map(|l| l.now.0.max(l.now.1)).collect(),
                    link_bytes_later: lanes.iter().map(|l| l.later.0.max(l.later.1)).collect(),
                    dgi_broadcast_bytes: 4 * u64::from(size[0]) * u64::from(size[1]) * (n - 1),
                    margin_sent_max,
                    margin_received_max,
                    // Every rank but 0 sends its owned sums and counts.
                    gather_received: crate::cluster::PIXEL_BYTES as u64
                        * (0..owners.owner.len() as u32)
                            .filter(|&b| owners.owner[b as usize] != 0)
                            .map(|b| {
                                let [tx, _] = owners.tiles;
                                let side = |i: u32, n: u32| u64::from((n - i * 32).min(32));
                                side(b % tx, size[0]) * side(b / tx, size[1])
                            })
                            .sum::<u64>(),
                    console_every,
                    console_received: console_received(&owners, size, console_every),
                });
            }
        }
    }
    Ok(rows)
}

fn mb(bytes: f64) -> String {
    format!("{:.2}", bytes / 1e6)
}

/// The report as Markdown.
#[must_use]
pub fn markdown(r: &ClusterBenchReport) -> String {
    let c = &r.config;
    let mut s = format!(
        "Device: {}\n\n## Strong scaling (measured)\n\n{} at {}×{}, max depth {}, HORNET, viewer 1 m in front of the centre, {} timed iterations per FOV after the DGI's.\n\n| FOV | ranks | share sampled | ms/iteration (rank 0), exchange overlapped / not | rank | ms trace (of which the tracer's call) | ms schedule | ms counts | ms exchange | samples traced/it | bytes sent/it | bytes received/it | DGI computed ms | DGI broadcast ms | DGI split ms | own tiles' picture ms (bytes sent / received) | rank 0: gather + whole filter ms | rank 0: console picture (every k-th pixel) ms, bytes received |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
        r.device, c.scene, c.size[0], c.size[1], c.max_depth, c.iterations
    );
    for row in &r.scaling {
        for (k, p) in row.per_rank.iter().enumerate() {
            let head = if k == 0 {
                format!(
                    "| {}° | {} | {:.3} | {:.1} / {:.1} ",
                    row.fov_deg,
                    row.ranks,
                    row.share_sampled,
                    row.ms_per_iteration(),
                    row.ms_per_iteration_sync()
                )
            } else {
                "| | | | ".to_owned()
            };
            let (gather, console) = if k == 0 {
                (
                    format!("{:.1}", p.ms_gather_and_filter),
                    format!(
                        "{:.1} (k = {}), {}",
                        p.ms_console_picture, p.console_every, p.console_bytes_received
                    ),
                )
            } else {
                (String::new(), String::new())
            };
            s += &format!(
                "{head}| {} | {:.1} ({:.1}) | {:.1} | {:.1} | {:.1} | {:.0} | {:.0} | {:.0} | {:.1} | {:.1} | {:.1} | {:.1} ({} / {}) | {gather} | {console} |\n",
                p.rank,
                p.ms_trace,
                p.ms_trace_call,
                p.ms_schedule,
                p.ms_counts,
                p.ms_exchange,
                p.samples_traced_per_iteration,
                p.bytes_sent_per_iteration,
                p.bytes_received_per_iteration,
                p.ms_dgi_compute,
                p.ms_dgi_broadcast,
                p.ms_dgi_split,
                p.ms_tile_pictures,
                p.tile_pictures_bytes_sent,
                p.tile_pictures_bytes_received,
            );
        }
    }
    // A rank's trace rate (its backend's), measured above: the model's one measured rate.
    let rate = r
        .scaling
        .iter()
        .flat_map(|row| &row.per_rank)
        .filter(|p| p.ms_trace > 0.0)
        .map(|p| p.samples_traced_per_iteration / (p.ms_trace / 1e3))
        .fold(f64::NAN, f64::max);
    s += &format!(
        "\n## Exchange per iteration (counted from the real schedule and deal)\n\nBytes per iteration: 12 per sample traced for another rank's tile and 4 (its count) from that tile's owner to the rank that traces it, 4 per block traced to every other rank, the split schedule (1 per block and 128 per non-empty block, from the rank that drew it to every other), the control message ({CONTROL_BYTES} bytes with an ROI change). The DGI's broadcast ({}) is per ROI change, not per iteration.\n\n| tile map | size | FOV | ranks | samples/it | max sent MB/it | mean sent MB/it | max received MB/it | DGI broadcast MB | link ms/it at {} Gb/s | break-even rate per rank (Msamples/s) | iterations/s at the measured rate, exchange not overlapped / overlapped | picture: margins max sent / received MB | picture: gathered to rank 0 MB | console picture: every k-th pixel, MB to rank 0 |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
        "4 bytes a pixel to every other rank, down a binomial tree; the column sums all links",
        c.link_gbps
    );
    for e in &r.exchange {
        if !(e.ranks <= 4 || e.ranks % 5 == 0 || e.ranks == c.model_ranks) {
            continue;
        }
        let link = e.link_seconds(c.link_gbps);
        let trace = e.samples_per_iteration as f64 / e.ranks as f64 / rate;
        s += &format!(
            "| {} | {}×{} | {}° | {} | {} | {} | {} | {} | {} | {:.3} | {:.0} | {:.2} / {:.2} | {} / {} | {} | k = {}: {} |\n",
            e.tile_map,
            e.size[0],
            e.size[1],
            e.fov_deg,
            e.ranks,
            e.samples_per_iteration,
            mb(e.bytes_sent_max as f64),
            mb(e.bytes_sent_mean),
            mb(e.bytes_received_max as f64),
            mb(e.dgi_broadcast_bytes as f64),
            link * 1e3,
            e.break_even_rate(c.link_gbps) / 1e6,
            1.0 / (trace + link),
            1.0 / e.overlapped_seconds(c.link_gbps, rate),
            mb(e.margin_sent_max as f64),
            mb(e.margin_received_max as f64),
            mb(e.gather_received as f64),
            e.console_every,
            mb(e.console_received as f64),
        );
    }
    s += &format!(
        "\nThe measured rate: {:.3} Msamples/s per rank ({}, best of the rows above: the trace step alone, its upload and read-back on a GPU included). Iterations/s, the schedule and the DGI left out: not overlapped, 1 / (samples/(ranks × rate) + link time); overlapped (the default: a frame's samples and rays travel while the next frame is traced), 1 / (the slowest rank's bytes before the trace + the longer of its trace and its bytes after it) — the counts, the control and the split schedule's masks come before a trace and do not overlap. A rank whose trace rate exceeds the break-even rate spends longer on the link than on tracing. The picture's columns are per picture shown or saved, not per iteration: each owner's tiles' margins (the default fast filter) against the whole accumulation gathered to rank 0, and against `view --cluster`'s console picture: every k-th pixel of every k-th row, the least k that fits a 4K monitor.\n",
        rate / 1e6,
        r.device
    );
    s
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;
    use crate::cluster::exchange::InProcess;

    /// The model's bytes are the bytes a frame moves: 3 in-process ranks, a guided first frame
    /// (equal costs: the deal the model makes), each rank's traffic against [`frame_traffic`];
    /// and the console's pictures after it against [`console_received`].
    #[test]
    fn overlapped_iterations_hide_the_shorter_of_trace_and_samples() {
        let row = |now: Vec<u64>, later: Vec<u64>| ExchangeRow {
            tile_map: "columns",
            size: [8, 8],
            fov_deg: 10.0,
            ranks: 2,
            samples_per_iteration: 2_000,
            bytes_sent_max: 0,
            bytes_sent_mean: 0.0,
            bytes_received_max: 0,
            link_bytes_now: now,
            link_bytes_later: later,
            dgi_broadcast_bytes: 0,
            margin_sent_max: 0,
            margin_received_max: 0,
            gather_received: 0,
            console_every: 1,
            console_received: 0,
        };
        // 1 Gb/s: 125 000 bytes a millisecond; 1 000 samples a rank at 1 M/s: 1 ms of trace.
        let (gbps, rate) = (1.0, 1e6);
        let ms = |r: &ExchangeRow| r.overlapped_seconds(gbps, rate) * 1e3;
        assert!((ms(&row(vec![0, 0], vec![0, 0])) - 1.0).abs() < 1e-12);
        // Samples shorter than the trace: hidden; the counts before it are not.
        assert!((ms(&row(vec![125_000, 0], vec![62_500, 0])) - 2.0).abs() < 1e-12);
        // Samples longer than the trace on the slowest rank: they set the pace.
        assert!((ms(&row(vec![0, 125_000], vec![0, 375_000])) - 4.0).abs() < 1e-12);
    }

    #[test]
    fn the_models_frame_bytes_are_the_bytes_a_frame_moves() {
        let display = DisplayModel::open("hornet").unwrap().0;
        let scene = Scene::builtin("cornell").unwrap();
        let size = [160, 72];
        let ranks = 3;
        let roi = paper::roi(30.0).unwrap();
        let config = GuideConfig {
            p_min: 0.02,
            ..GuideConfig::default()
        };
        let owners = BlockOwners::of_display(&display, &TileOwners::columns(&display, ranks), size);
        let settings = paper::settings(&scene, size, 1, 2).unwrap();
        let measured: Vec<((u64, u64), LaneBytes)> = std::thread::scope(|s| {
            let handles: Vec<_> = InProcess::job(ranks)
                .into_iter()
                .map(|end| {
                    let (scene, display, owners) = (&scene, &display, &owners);
                    s.spawn(move || {
                        let rank = crate::cluster::exchange::Exchange::rank(&end);
                        let mut c = Cluster::new(Box::new(end), Duration::from_secs(30));
                        let setup = || ClusterSetup {
                            settings,
                            guide: Some((display, config)),
                            wall: None,
                            owners: owners.clone(),
                            dgi_mode: DgiMode::Compute,
                        };
                        let mut r = ClusterRenderer::new(&mut c, scene, setup()).unwrap();
                        r.set_roi(Some(roi)).unwrap();
                        // The frame's own bytes: its samples collected within it (overlapped,
                        // they would be received during the next frame).
                        r.set_overlap(false);
                        let t = r.run_frame(false).unwrap().traffic;
                        // The console's picture, at several reductions: rank 0's bytes.
                        let console = [1, 3, 7].map(|every| {
                            let before = r.cluster().traffic();
                            r.gather_every(every).unwrap();
                            (every, r.cluster().traffic().since(&before).bytes_received)
                        });
                        if rank == 0 {
                            for (every, got) in console {
                                assert_eq!(
                                    got,
                                    console_received(owners, size, every),
                                    "every {every}"
                                );
                                assert!(got > 0);
                            }
                        }
                        // The same frame overlapped: it sends everything and receives what
                        // comes before the trace; the rest arrives when it is collected.
                        drop(r);
                        let mut r = ClusterRenderer::new(&mut c, scene, setup()).unwrap();
                        r.set_roi(Some(roi)).unwrap();
                        let o = r.run_frame(false).unwrap().traffic;
                        let before = r.cluster().traffic();
                        r.finish().unwrap();
                        let later = r.cluster().traffic().since(&before);
                        let lanes = LaneBytes {
                            now: (o.bytes_sent, o.bytes_received),
                            later: (later.bytes_sent, later.bytes_received),
                        };
                        ((t.bytes_sent, t.bytes_received), lanes)
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        let dgi = dgi_cpu(
            &Surface::from_model(&display),
            display.pitch_m(),
            &config,
            Some(&roi),
            size,
        )
        .unwrap();
        let list = schedule_cpu(&dgi, size[0], size[1], 0.02, 0, 1, Order::Coherent).unwrap();
        let list = BlockList::group(&list, size);
        let tracer = deal(&list, &CostTable::new(owners.owner.len()), ranks);
        assert!(
            tracer.iter().any(|&t| t != 0),
            "the deal spreads the blocks"
        );
        let whole: Vec<(u64, u64)> = measured.iter().map(|m| m.0).collect();
        assert_eq!(whole, frame_traffic(&list, &tracer, &owners, ranks));
        // Overlapped: the frame sent both lanes (posted) and received the first; collecting
        // brought the second.
        let lanes = frame_traffic_lanes(&list, &tracer, &owners, ranks, true);
        for (rank, (m, l)) in measured.iter().zip(&lanes).enumerate() {
            let (got, want) = (m.1, l);
            assert_eq!(got.now.0, want.now.0 + want.later.0, "rank {rank}: sent");
            assert_eq!(got.now.1, want.now.1, "rank {rank}: received in the frame");
            assert_eq!(got.later, (0, want.later.1), "rank {rank}: collected after");
            assert!(
                want.later.1 > 0 && want.now.1 > 0,
                "rank {rank}: both lanes move bytes"
            );
        }
    }
}
