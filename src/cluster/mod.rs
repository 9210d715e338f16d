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
//! [`ClusterRenderer`]'s [`run_frame`](crate::frame::Render::run_frame) is that function: a
//! rank's renderer is driven through [`crate::frame::Render`] as one process's is, every rank
//! calling the same methods in the same order (they are collectives). Samples are exact: a
//! sample depends only on (pixel, sample index, seed), a pixel's owner keeps its sample count
//! and tells the rank that traces it, and a pixel gets at most one sample an iteration, which
//! its owner adds as the one-process renderer does. N ranks therefore give the accumulation of
//! one process bit for bit, whatever the deal — the tests compare them.
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
//! tests ([`exchange::InProcess`]), MPI with the `cluster` feature (`mpi`).
//!
//! Files by job: `collective.rs` ([`Cluster`]: the collectives and their deadlines),
//! `codec.rs` (what crosses the link, as bytes: [`FrameControl`], masks, samples, sums),
//! `engine.rs` (a rank's renderer set up, [`ClusterSetup`], and where its owned pixels lie),
//! `steps.rs` (the frame's steps 1–4 and what changes between frames), `samples.rs` (step 5,
//! the samples' exchange), `gpu_rank.rs` (a rank tracing on its GPU), `gather.rs` (what rank 0
//! reads of the owners' sums); and the modules [`mod@deal`] (blocks and the deal), [`owners`]
//! (the tile map and the `--tile-owners` file), [`handshake`] (the start-up check),
//! [`exchange`] (the transport), [`picture`] (each owner's tiles, filtered where they are
//! owned).

mod codec;
mod collective;
pub mod deal;
mod engine;
pub mod exchange;
mod gather;
mod gpu_rank;
pub mod handshake;
#[cfg(feature = "cluster")]
pub mod mpi;
pub mod owners;
pub mod picture;
mod samples;
mod steps;

use std::sync::Arc;

use crate::frame::{FrameError, FrameStats, GuideConfig};
use crate::roi::dgi::{Roi, Surface};
use crate::schedule::ScheduleError;
use crate::trace::pack::PackedScene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;
use deal::{BlockList, CostTable};
use exchange::{ExchangeError, Traffic};
use gpu_rank::GpuRank;
use owners::BlockOwners;
use samples::InFlight;

pub use codec::{FrameControl, PIXEL_BYTES, f32_bytes};
pub use collective::{Cluster, binomial_tree};
pub use engine::ClusterSetup;
pub use gather::{CONSOLE_PIXELS, reduction_for};
pub use steps::split_dgi;

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

/// A rank's frame as one process's reads: rank 0's stages in the viewer's panel, with the
/// exchange that waits for the slowest rank counted with the trace.
impl From<ClusterFrameStats> for FrameStats {
    fn from(s: ClusterFrameStats) -> Self {
        Self {
            iteration: s.iteration,
            dgi_recomputed: s.dgi_recomputed,
            pixels: u32::try_from(s.pixels).ok(),
            ms_dgi: s.dgi_recomputed.then_some(s.ms_dgi),
            ms_schedule: Some(s.ms_schedule),
            ms_trace: Some(s.ms_trace + s.ms_exchange),
            gpu_timestamps: false,
            rays: Some(s.rays),
        }
    }
}

/// Where the ROI is aimed and how it steers sampling.
struct Guidance {
    config: GuideConfig,
    surface: Surface,
    pitch_m: f64,
}

/// One rank's part of a progressive render across ranks: the schedule, sample counts and DGI
/// of the whole image, the sums of the blocks this rank owns. It holds the rank's handle on the
/// job for as long as it renders: its frames and reads ([`crate::frame::Render`]) are
/// collectives, which every rank calls in the same order.
pub struct ClusterRenderer<'c> {
    /// The job: the transport and the deadlines of every wait.
    link: &'c mut Cluster,
    pub packed: PackedScene,
    pub settings: TraceSettings,
    /// Seconds spent building the BVH and packing the scene.
    pub build_seconds: f64,
    wall: Option<WallCamera>,
    guidance: Option<Guidance>,
    dgi_mode: DgiMode,
    /// This rank and the job's ranks (the link's, kept at hand).
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

#[cfg(test)]
mod tests;
