//! The ROI's statistics of the frame as it is ([`Renderer::roi_stats`]): what the window shows
//! under the picture and what the stop conditions judge.
//!
//! On a GPU renderer of one band they are measured where the accumulation lives
//! ([`StatsKernel`]: the totals and five order statistics come back, 208 bytes); otherwise from
//! the accumulation and the DGI read back (24 bytes a pixel on a GPU: about 200 MB at
//! 3840×2160, which the window would read twice a second) by the CPU twin
//! [`RoiStats::measure`].

use super::{Engine, FrameError, Render, Renderer};
use crate::frame::stop::RoiProgress;
use crate::output::gpu::{GpuStatsInputs, StatsKernel, StatsRun};
use crate::output::stats::RoiStats;
use crate::trace::accum::Accumulation;

impl Renderer<'_> {
    /// Whether [`Self::roi_stats`] measures on the GPU: a guided GPU renderer whose frame is
    /// one band.
    #[must_use]
    pub fn measures_stats_on_gpu(&self) -> bool {
        match &self.engine {
            Engine::Gpu { bands, .. } => bands.len() == 1 && bands[0].guide.is_some(),
            Engine::Cpu { .. } => false,
        }
    }

    /// The ROI's statistics now (a wall camera's: over the pixels its display shows): its
    /// samples and pixels, its noise against the periphery's and its progress. Without an ROI
    /// nothing is measured or read ([`RoiStats::default`]).
    pub fn roi_stats(&self) -> Result<RoiStats, FrameError> {
        if self.roi().is_none() {
            return Ok(RoiStats::default());
        }
        self.measured_stats()
    }

    /// How far the pixels of d = 0 have come ([`Render::roi_progress`]), with a wall camera
    /// over the pixels its display shows: the ROI's, or every pixel's while a guided renderer
    /// has no ROI or a full frame is rendered; `None` without such pixels. On a GPU renderer of
    /// one band measured there ([`Self::roi_stats`]'s measurement); otherwise from the
    /// accumulation (a read-back on the GPU).
    pub(super) fn progress(&self) -> Result<Option<RoiProgress>, FrameError> {
        if self.measures_stats_on_gpu() {
            return Ok(self.measured_stats()?.progress);
        }
        self.on_host(|acc, dgi, shown| RoiProgress::measure_where(acc, dgi, shown))
    }

    /// The statistics of the pixels of d = 0 as they are, ROI or not.
    fn measured_stats(&self) -> Result<RoiStats, FrameError> {
        let p_min = self.guide_config().map_or(0.0, |c| c.p_min);
        let (Engine::Gpu { ctx, bands, .. }, true) = (&self.engine, self.measures_stats_on_gpu())
        else {
            return self.on_host(|acc, dgi, shown| RoiStats::measure(acc, dgi, p_min, shown));
        };
        let run = match self.stats.get() {
            Some(run) => run,
            None => {
                let band = &bands[0];
                let guide = band
                    .guide
                    .as_ref()
                    .expect("measures_stats_on_gpu checked it");
                let run = StatsKernel::new(ctx).prepare(
                    ctx,
                    &GpuStatsInputs {
                        pixels: self.settings.width * self.settings.height,
                        accum: &band.accum.accum,
                        counts: &band.accum.counts,
                        dgi: &guide.dgi,
                        shown: self.wall.as_ref().map(|w| w.shown_mask()),
                    },
                )?;
                self.stats.get_or_init(|| run)
            }
        };
        Ok(run.measure(ctx, p_min)?)
    }

    /// `f` of the accumulation, the DGI and the wall camera's shown pixels on the host: the
    /// CPU twin's own, or read back from the GPU.
    fn on_host<R>(
        &self,
        f: impl FnOnce(&Accumulation, &[f32], &dyn Fn(usize) -> bool) -> R,
    ) -> Result<R, FrameError> {
        let wall = self.wall.as_ref();
        let shown = |i: usize| wall.is_none_or(|w| w.is_shown(i as u32));
        Ok(match &self.engine {
            Engine::Cpu {
                accum,
                guide: Some(g),
            } => f(accum, &g.dgi, &shown),
            _ => f(&self.accumulation()?, &self.dgi()?, &shown),
        })
    }
}

/// Where a renderer keeps its bound measurement.
pub(super) type Stats = std::cell::OnceCell<StatsRun>;
