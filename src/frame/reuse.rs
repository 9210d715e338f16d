//! A moving eye keeps its picture (DESIGN.md §11): with [`EyeMove::Reuse`], a new wall-camera
//! eye or pinhole camera carries each pixel's accumulation over from the old pixel that saw
//! the same surface ([`crate::trace::reuse`]) instead of restarting every pixel.
//!
//! The primary-hit records of the current view are made at the first move (one ray a pixel,
//! the features kernel's `primary_hits` on the GPU or its CPU twin) and kept until the next:
//! each move makes the new view's records, carries the accumulation, and keeps the new
//! records (with the carried pixels' anchors) for the move after it. On the GPU a frame in one
//! band is carried by the reuse kernel; a frame in several bands (larger than one storage
//! binding) is read back, carried by the CPU twin and written back.

use super::{Engine, FrameError, Renderer};
use crate::gpu::{Band, GpuContext};
use crate::trace::accum::Accumulation;
use crate::trace::camera::RenderCamera;
use crate::trace::features::hit_records_cpu;
use crate::trace::gpu::ReuseInputs;
use crate::trace::gpu::{FeatureInputs, FeaturesKernel, GpuAccum, GpuHits, HIT_BYTES_PER_PIXEL};
use crate::trace::gpu::{ReuseKernel, TraceKernel};
use crate::trace::reuse::{ReuseStats, View, reuse_cpu};
use crate::trace::wall::WallCamera;

/// What a renderer does with its accumulation when the eye or the camera moves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum EyeMove {
    /// Every pixel starts again (the ROI and its DGI kept).
    #[default]
    Restart,
    /// Each pixel keeps the old accumulation of the surface it still sees, where it may.
    Reuse,
}

impl std::str::FromStr for EyeMove {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "restart" => Ok(Self::Restart),
            "reuse" => Ok(Self::Reuse),
            _ => Err(format!("'{s}': expected reuse or restart")),
        }
    }
}

/// The primary-hit records of a view, on the renderer's backend.
pub(super) enum Hits {
    Cpu(Vec<[[f32; 4]; 2]>),
    /// One buffer a band of the frame.
    Gpu(Vec<GpuHits>),
}

/// A view the records were made in, owned.
#[derive(Clone)]
enum ViewOf {
    Wall(WallCamera),
    Pinhole(RenderCamera),
}

impl Renderer<'_> {
    /// What the renderer does when the eye or the camera moves (default: restart).
    pub fn set_on_eye_move(&mut self, policy: EyeMove) {
        self.on_eye_move = policy;
        if policy == EyeMove::Restart {
            self.hits = None;
        }
    }

    /// What the last move of the eye or the camera carried over (`None` before any, or when
    /// it restarted).
    #[must_use]
    pub fn last_reuse(&self) -> Option<ReuseStats> {
        self.last_reuse
    }

    /// The view the records are made in now.
    fn view_now(&self) -> ViewOf {
        match &self.wall {
            Some(w) => ViewOf::Wall(w.clone()),
            None => ViewOf::Pinhole(self.settings.camera),
        }
    }

    fn view<'v>(&self, v: &'v ViewOf) -> View<'v> {
        match v {
            ViewOf::Wall(w) => View::Wall(w),
            ViewOf::Pinhole(c) => View::Pinhole {
                camera: *c,
                width: self.settings.width,
                height: self.settings.height,
            },
        }
    }

    /// Moves the view by `apply` (which installs the new wall camera or camera): with
    /// [`EyeMove::Reuse`], carrying the accumulation over; else restarting it.
    pub(super) fn move_view(
        &mut self,
        apply: impl FnOnce(&mut Self),
    ) -> Result<Option<ReuseStats>, FrameError> {
        if self.on_eye_move == EyeMove::Restart {
            apply(self);
            self.restart();
            self.last_reuse = None;
            return Ok(None);
        }
        let old_view = self.view_now();
        let old = match self.hits.take() {
            Some(h) => h,
            None => self.compute_hits()?,
        };
        apply(self);
        let new_view = self.view_now();
        let mut new = self.compute_hits()?;
        let (ov, nv) = (self.view(&old_view), self.view(&new_view));
        let stats = match (&mut self.engine, &old, &mut new) {
            (Engine::Cpu { accum, .. }, Hits::Cpu(old), Hits::Cpu(new)) => {
                let (carried, stats) = reuse_cpu(&nv, &ov, new, old, accum);
                *accum = carried;
                stats
            }
            (Engine::Gpu { ctx, bands, .. }, Hits::Gpu(old), Hits::Gpu(new))
                if bands.len() == 1 && old.len() == 1 && new.len() == 1 =>
            {
                let accum = &bands[0].accum;
                let old_accum = copy_accum(ctx, accum)?;
                ReuseKernel::new(ctx).run(
                    ctx,
                    &ReuseInputs {
                        old_view: ov,
                        new_view: nv,
                        new_hits: &new[0],
                        old_hits: &old[0],
                        old_accum: &old_accum,
                        accum,
                    },
                )?
            }
            (Engine::Gpu { ctx, bands, .. }, Hits::Gpu(old), Hits::Gpu(new)) => {
                // Bands: the old pixel may lie in any band; the CPU twin carries the whole frame.
                let read = |hits: &[GpuHits]| -> Result<Vec<_>, FrameError> {
                    let mut all = Vec::new();
                    for h in hits {
                        all.extend(h.read(ctx)?);
                    }
                    Ok(all)
                };
                let (old_r, mut new_r) = (read(old)?, read(new)?);
                let (w, h) = (self.settings.width, self.settings.height);
                let mut acc = Accumulation::new(w, h);
                acc.sum.clear();
                acc.count.clear();
                for b in bands.iter() {
                    let part = b.accum.read(ctx)?;
                    acc.sum.extend(part.sum);
                    acc.count.extend(part.count);
                }
                let (carried, stats) = reuse_cpu(&nv, &ov, &mut new_r, &old_r, &acc);
                let rows = |b: Band| (b.row0 * w) as usize..((b.row0 + b.rows) * w) as usize;
                let q = &ctx.queue;
                for b in bands.iter() {
                    let range = rows(b.band);
                    q.write_buffer(
                        &b.accum.accum,
                        0,
                        bytemuck::cast_slice(&carried.sum[range.clone()]),
                    );
                    q.write_buffer(
                        &b.accum.counts,
                        0,
                        bytemuck::cast_slice(&carried.count[range]),
                    );
                }
                for hits in new.iter() {
                    q.write_buffer(
                        &hits.records,
                        0,
                        bytemuck::cast_slice(&new_r[rows(hits.band)]),
                    );
                }
                stats
            }
            _ => unreachable!("records are made on the renderer's backend"),
        };
        self.hits = Some(new);
        // The view changed: its features are made again.
        self.features = std::cell::OnceCell::new();
        self.last_reuse = Some(stats);
        Ok(Some(stats))
    }

    /// The primary-hit records of the current view on this renderer's backend.
    fn compute_hits(&self) -> Result<Hits, FrameError> {
        match &self.engine {
            Engine::Gpu { ctx, scene, .. } => {
                let trace = TraceKernel::new(ctx);
                let kernel = FeaturesKernel::new(ctx);
                let (w, h) = (self.settings.width, self.settings.height);
                // Bands of their own: a record is twice an accumulation pixel's bytes.
                let rows = (ctx.max_binding() / (u64::from(w) * HIT_BYTES_PER_PIXEL)).max(1);
                let rows = rows.min(u64::from(h)) as u32;
                let mut out = Vec::new();
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                for row0 in (0..h).step_by(rows as usize) {
                    let band = Band {
                        row0,
                        rows: rows.min(h - row0),
                    };
                    let hits = GpuHits::new(ctx, w, band)?;
                    let inputs = FeatureInputs {
                        trace: &trace,
                        scene_gpu: scene,
                        scene: &self.packed,
                        settings: &self.settings,
                        wall: self.wall.as_ref(),
                    };
                    kernel.record_hits(ctx, &mut enc, inputs, &hits);
                    out.push(hits);
                }
                ctx.queue.submit([enc.finish()]);
                Ok(Hits::Gpu(out))
            }
            Engine::Cpu { .. } => Ok(Hits::Cpu(hit_records_cpu(
                &self.packed,
                &self.settings,
                self.wall.as_ref(),
            ))),
        }
    }
}

/// A copy of `accum` (its sums and counts) on the GPU.
fn copy_accum(ctx: &GpuContext, accum: &GpuAccum) -> Result<GpuAccum, FrameError> {
    let copy = GpuAccum::new(ctx, accum.width, accum.height)?;
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(&accum.accum, 0, &copy.accum, 0, accum.accum.size());
    enc.copy_buffer_to_buffer(&accum.counts, 0, &copy.counts, 0, accum.counts.size());
    ctx.queue.submit([enc.finish()]);
    Ok(copy)
}
