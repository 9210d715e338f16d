//! One frame across ranks, steps 1–4 (DESIGN.md §12): the DGI of a changed ROI, the schedule,
//! the deal, the counts of the pixels each rank traces and the trace; and what changes between
//! frames (the ROI, the eye, the camera, a restart). Step 5, the samples' exchange, is in
//! `samples.rs`.

use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;

use super::codec::{decode_masks, encode_masks, f32_bytes, f32s};
use super::deal::{BlockList, deal};
use super::exchange::ExchangeError;
use super::samples::Traced;
use super::{Cluster, ClusterError, ClusterFrameStats, ClusterRenderer, DgiMode, owners};
use crate::frame::stop::RoiProgress;
use crate::frame::{EyeFollow, FrameError, GuideConfig, Render, dgi_cpu};
use crate::roi::dgi::{Roi, Surface};
use crate::schedule::{DrawInput, Order, schedule_cpu_block_masks, schedule_cpu_shown};
use crate::trace::accum::{Accumulation, block_rays};
use crate::trace::camera::RenderCamera;
use crate::trace::gpu::SampleRun;
use crate::trace::path::{TraceSettings, samples_cpu};
use crate::trace::wall::WallCamera;

impl Render for ClusterRenderer<'_> {
    type Error = ClusterError;
    type Stats = ClusterFrameStats;

    fn settings(&self) -> &TraceSettings {
        &self.settings
    }

    fn guide_config(&self) -> Option<&GuideConfig> {
        self.guidance.as_ref().map(|g| &g.config)
    }

    fn wall(&self) -> Option<&WallCamera> {
        self.wall.as_ref()
    }

    /// The ROI set last.
    fn roi(&self) -> Option<&Roi> {
        self.roi.as_ref()
    }

    fn iteration(&self) -> u32 {
        self.iteration
    }

    fn set_roi(&mut self, roi: Option<Roi>) -> Result<(), ClusterError> {
        if self.guidance.is_none() {
            return Err(FrameError::NotGuided.into());
        }
        self.pending = Some(roi);
        self.roi = roi;
        Ok(())
    }

    /// A restart sets this rank's owned sums and counts back to zero. Every rank applies the
    /// same eyes in the same frames, so they stay in step: rank 0 decides, the others
    /// [`move_eye`](ClusterRenderer::move_eye) where it restarted.
    fn follow_eye(&mut self, eye: DVec3, threshold_m: f64) -> Result<EyeFollow, ClusterError> {
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

    fn set_camera(&mut self, camera: RenderCamera) -> Result<(), ClusterError> {
        self.settings.camera = camera;
        if let Some(g) = &self.gpu {
            g.run.set_settings(&g.ctx, &self.packed, &self.settings);
        }
        self.restart();
        Ok(())
    }

    /// One frame on this rank, in step with the others: the DGI of a changed ROI, the
    /// schedule, the deal, this rank's samples, and the exchange that brings every owner the
    /// samples of its blocks. Every step is timed by this rank's clock, `timed` or not:
    /// nothing waits for it.
    fn run_frame(&mut self, _timed: bool) -> Result<ClusterFrameStats, ClusterError> {
        let before = self.link.traffic();
        let mut stats = ClusterFrameStats {
            iteration: self.iteration,
            ..Default::default()
        };
        self.install_dgi(&mut stats)?;
        let mut list = self.schedule(&mut stats)?;
        let tracer = deal(&list, &self.costs, self.ranks);
        if let Some(l) = Arc::get_mut(&mut list) {
            // A list from masks: expand this rank's share, the blocks it traces or owns.
            let (me, owner) = (self.rank, &self.owners.owner);
            l.hold(|i, b| tracer[i] as usize == me || owner[b as usize] as usize == me);
        }
        stats.pixels_held = list.held_len() as u64;
        let counts = self.counts_to_trace(&list, &tracer, &mut stats)?;
        let samples = self.trace(&list, &tracer, &counts, &mut stats)?;
        let t0 = Instant::now();
        // The last frame's samples, which travelled while this one was traced; then this
        // frame's, posted (and, without overlap, collected at once).
        self.collect()?;
        stats.pixels = list.len();
        self.post(list, tracer, samples)?;
        if !self.overlap {
            self.collect()?;
        }
        stats.ms_exchange = t0.elapsed().as_secs_f64() * 1e3;
        stats.traffic = self.link.traffic().since(&before);
        self.iteration += 1;
        Ok(stats)
    }

    fn roi_progress(&mut self) -> Result<Option<RoiProgress>, ClusterError> {
        self.progress()
    }

    /// Every owner sends rank 0 its sums and counts.
    fn gather(&mut self) -> Result<Option<(Accumulation, Vec<f32>)>, ClusterError> {
        self.gather_every(1)
    }
}

impl ClusterRenderer<'_> {
    /// Moves the eye to `eye` and restarts, unconditionally: what the other ranks do with an
    /// eye rank 0's [`Render::follow_eye`] restarted at.
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

    /// This rank's owned sums and counts back to zero.
    pub(super) fn restart(&mut self) {
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

    /// Step 1: the DGI of a changed ROI, computed here or received from rank 0.
    fn install_dgi(&mut self, stats: &mut ClusterFrameStats) -> Result<(), ClusterError> {
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
            DgiMode::Split => split_dgi(
                self.link,
                &g.surface,
                g.pitch_m,
                &g.config,
                roi.as_ref(),
                size,
            )?,
            DgiMode::Broadcast => {
                let mine = if self.link.is_root() {
                    f32_bytes(&compute()?)
                } else {
                    Vec::new()
                };
                let got = self.link.broadcast("the DGI", mine)?;
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
    fn schedule(&mut self, stats: &mut ClusterFrameStats) -> Result<Arc<BlockList>, ClusterError> {
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
                let input = DrawInput {
                    dgi: &self.dgi,
                    shown,
                    width: size[0],
                    height: size[1],
                    p_min: cfg.p_min,
                    iteration: self.iteration,
                    seed: self.settings.seed,
                };
                let masks = schedule_cpu_block_masks(&input, &mine)?;
                let part = encode_masks(&masks);
                let what = format!("the schedule of iteration {}", self.iteration);
                let got = self.link.all_to_all(&what, vec![part; self.ranks])?;
                let mut all = vec![[0u32; 32]; n as usize];
                for (src, bytes) in got.iter().enumerate() {
                    let theirs: Vec<u32> = (src as u32..n).step_by(self.ranks).collect();
                    let masks = decode_masks(bytes, theirs.len()).map_err(|e| {
                        ExchangeError::Malformed {
                            rank: src,
                            what: what.clone(),
                            reason: e.to_string(),
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
                let input = DrawInput {
                    dgi: &self.dgi,
                    shown,
                    width: size[0],
                    height: size[1],
                    p_min: c.p_min,
                    iteration: self.iteration,
                    seed: self.settings.seed,
                };
                let list = schedule_cpu_shown(&input, c.order)?;
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
            got = self.link.all_to_all(&what, parts)?;
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
