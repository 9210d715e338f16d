//! A rank that traces on its GPU (DESIGN.md §12): the scene uploaded there, the trace kernel's
//! compact mode, the DGI computed as one GPU process computes it, the whole schedule drawn there
//! as slot masks, and the owned sums kept there.

use std::sync::Arc;

use super::{ClusterError, ClusterRenderer, Guidance};
use crate::frame::prepare_dgi;
use crate::gpu::GpuContext;
use crate::roi::dgi::Roi;
use crate::roi::gpu::DgiKernel;
use crate::schedule::gpu::BlockMasksRun;
use crate::schedule::{Order, ScheduleError};
use crate::trace::gpu::{GpuScene, OwnedSums, SampleRun, TraceKernel};
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

/// A rank's GPU, with the scene on it and the kernel's compact mode ([`SampleRun`]).
pub(super) struct GpuRank {
    pub(super) ctx: Arc<GpuContext>,
    pub(super) scene: GpuScene,
    pub(super) run: SampleRun,
    /// The DGI's kernel: a GPU rank computes the DGI as one GPU process does (the CPU twin's
    /// f64 solves agree with it only to rounding).
    pub(super) dgi: DgiKernel,
    /// A guided render in coherent order: each iteration's whole schedule drawn on this GPU as
    /// every block's slot mask, instead of a 1/N share on the CPU and the rest from the link
    /// (`None`: a full frame, scattered order, or an image whose DGI is over one binding of
    /// this adapter: the CPU's split draw).
    pub(super) masks: Option<BlockMasksRun>,
    /// The owned sums on this GPU: the samples of this rank's own blocks that it traces
    /// never leave the GPU (`None`: more owned pixels than one binding holds; the CPU adds).
    pub(super) owned: Option<OwnedSums>,
}

impl GpuRank {
    /// The DGI of `roi` (`None`: 0 everywhere) on this rank's GPU: what a one-process GPU
    /// renderer installs, value for value.
    pub(super) fn dgi(
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

impl ClusterRenderer<'_> {
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
        let masks = block_masks(
            &ctx,
            self.guidance.as_ref(),
            self.wall.as_ref(),
            &self.settings,
            &self.dgi,
        )?;
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

    /// The GPU this rank traces on (`None`: the CPU twin).
    #[must_use]
    pub fn gpu(&self) -> Option<&GpuContext> {
        self.gpu.as_deref().map(|g| &*g.ctx)
    }
}

/// The whole coherent schedule drawn on `ctx`'s GPU as every block's slot mask, from the DGI
/// `dgi` (a guided render in coherent order; `None` for a full frame, scattered order, or an
/// image whose DGI is over one binding of this adapter: then the CPU's split draw).
pub(super) fn block_masks(
    ctx: &GpuContext,
    guidance: Option<&Guidance>,
    wall: Option<&WallCamera>,
    settings: &TraceSettings,
    dgi: &[f32],
) -> Result<Option<BlockMasksRun>, ClusterError> {
    let Some(g) = guidance.filter(|g| g.config.order == Order::Coherent) else {
        return Ok(None);
    };
    let shown = wall.map(WallCamera::shown_mask);
    let (w, h) = (settings.width, settings.height);
    match BlockMasksRun::new(ctx, w, h, g.config.p_min, shown) {
        Ok(m) => {
            m.set_dgi(ctx, dgi);
            Ok(Some(m))
        }
        // Over the adapter's binding: the CPU draws (every rank of a job has the same adapter,
        // the start-up check, so every rank decides alike).
        Err(ScheduleError::Gpu(crate::gpu::GpuError::TooLarge { .. })) => Ok(None),
        Err(e) => Err(e.into()),
    }
}
