//! Step 5 of a frame across ranks (DESIGN.md §12): the samples' exchange. Every rank posts its
//! samples to the owners of their blocks and every block's rays to every rank; an owner counts
//! its pixels' samples when they are dealt and adds their sums when they arrive — while the next
//! frame is traced, or before anything reads the sums.

use std::sync::Arc;

use glam::Vec3;
use rayon::prelude::*;

use super::codec::{rgb_bytes, rgb_of};
use super::deal::BlockList;
use super::engine::{local_in_block, own_base_of};
use super::exchange::ExchangeError;
use super::{ClusterError, ClusterRenderer};
use crate::schedule::BLOCK_PIXELS;
use crate::trace::accum::accumulate_sums;

/// A frame's exchange between its post and its collect.
pub(super) struct InFlight {
    pub(super) iteration: u32,
    pub(super) list: Arc<BlockList>,
    pub(super) tracer: Vec<u32>,
    pub(super) mine: Traced,
    /// This rank's own part of the all-to-all (empty).
    pub(super) own: Vec<u8>,
    /// The accumulation restarted since (a moved eye or camera): the samples are collected
    /// (they are on their way) and not added.
    pub(super) stale: bool,
}

/// The samples this rank traced in a frame.
pub(super) struct Traced {
    /// Indices into the frame's [`BlockList`], ascending.
    pub(super) blocks: Vec<usize>,
    /// The samples read back: RGB, then the sample's rays as the bits of the fourth float
    /// (the GPU's read-back as it comes).
    pub(super) samples: Vec<[f32; 4]>,
    /// Per block: where its samples begin in `samples`, or `None` where they stayed on the
    /// GPU (an owned block of a GPU rank whose owned sums are there).
    pub(super) at: Vec<Option<usize>>,
    /// The blocks (positions in `blocks`) whose samples stayed on the GPU, in the order the
    /// GPU keeps them: ascending.
    pub(super) kept: Vec<usize>,
    /// Whether the GPU kept this frame's own samples (even none): its collect takes them.
    pub(super) kept_on_gpu: bool,
    /// Rays per block.
    pub(super) rays: Vec<u32>,
}

/// The samples an owned block receives in one frame: its own (as traced here) or another
/// rank's (as they travelled).
#[derive(Clone, Copy)]
enum BlockSamples<'a> {
    Own(&'a [[f32; 4]]),
    Wire(&'a [u8]),
}

impl ClusterRenderer<'_> {
    /// Step 5, first half: every rank's samples posted to the owners of their blocks, and every
    /// block's rays to every rank (the deal's weights). An owner counts the samples of its
    /// pixels now — a pixel's count is its sample index, which the next frame's counts need,
    /// and a sample counts whatever its value — and adds their sums when they arrive
    /// ([`Self::collect`]).
    pub(super) fn post(
        &mut self,
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
        let own = self.link.all_to_all_post(&what, parts)?;
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
    pub(super) fn collect(&mut self) -> Result<(), ClusterError> {
        let Some(f) = self.in_flight.take() else {
            return Ok(());
        };
        let (list, tracer, mine) = (&f.list, &f.tracer, &f.mine);
        let what = format!("the samples of iteration {}", f.iteration);
        let got = self.link.all_to_all_collect(&what, f.own)?;
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
    pub(super) fn sync_sums(&mut self) -> Result<(), ClusterError> {
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
    pub fn finish(&mut self) -> Result<(), ClusterError> {
        self.collect()
    }

    /// Whether a frame's samples travel while the next frame is traced (`true`, the default)
    /// or reach their owners within the frame. The results are the same bit for bit; only
    /// when the exchange's time is spent differs (and the deal's weights lag a frame behind).
    pub fn set_overlap(&mut self, overlap: bool) {
        self.overlap = overlap;
    }
}
