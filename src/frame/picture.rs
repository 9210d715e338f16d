//! The accumulation and the DGI as the callers read them, and step 4: the picture, filtered
//! from them when one is wanted.

use glam::Vec3;

use super::{Engine, FrameError, GpuBand, Renderer};
use crate::filter::{Filter, FilterParams};
use crate::gpu::{GpuContext, GpuError};
use crate::trace::accum::Accumulation;

impl Renderer<'_> {
    /// The accumulation so far (a read-back on the GPU).
    pub fn accumulation(&self) -> Result<Accumulation, FrameError> {
        Ok(match &self.engine {
            Engine::Gpu { ctx, bands, .. } => read_bands(ctx, bands)?,
            Engine::Cpu { accum, .. } => accum.clone(),
        })
    }

    /// The DGI the last frame used (a read-back on the GPU; 0 everywhere for a full frame).
    pub fn dgi(&self) -> Result<Vec<f32>, FrameError> {
        let n = self.settings.width as usize * self.settings.height as usize;
        Ok(match &self.engine {
            Engine::Gpu {
                ctx,
                bands,
                dgi_kernel: Some(_),
                ..
            } => {
                // The first band's read-back is the vector (a one-band frame's whole DGI).
                let mut parts = bands.iter().filter_map(|b| b.guide.as_ref());
                let mut dgi = match parts.next() {
                    Some(g) => ctx.read_buffer::<f32>(&g.dgi)?,
                    None => Vec::new(),
                };
                dgi.reserve(n.saturating_sub(dgi.len()));
                for g in parts {
                    dgi.extend(ctx.read_buffer::<f32>(&g.dgi)?);
                }
                dgi
            }
            Engine::Cpu { guide: Some(g), .. } => g.dgi.clone(),
            Engine::Gpu {
                dgi_kernel: None, ..
            }
            | Engine::Cpu { guide: None, .. } => vec![0.0; n],
        })
    }

    /// Step 4, when a picture is wanted: the mean image filtered by `params` with the DGI
    /// (linear RGB, row-major), on this renderer's backend.
    pub fn picture(&self, params: &FilterParams) -> Result<Vec<Vec3>, FrameError> {
        let acc = self.accumulation()?;
        let dgi = self.dgi()?;
        self.picture_of(params, &acc, &dgi)
    }

    /// The picture of an accumulation and DGI read back already (see [`Self::picture`]).
    pub fn picture_of(
        &self,
        params: &FilterParams,
        acc: &Accumulation,
        dgi: &[f32],
    ) -> Result<Vec<Vec3>, FrameError> {
        let filter = self.filter.get_or_init(|| Filter::new(self.backend));
        let mut image = filter.image(params, acc, dgi)?;
        if let Some(w) = &self.wall {
            w.blank_unshown(&mut image);
        }
        Ok(image)
    }

    /// The accumulation and the DGI the last frame used, ending the render (moved out on the
    /// CPU, read back on the GPU).
    pub fn finish(self) -> Result<(Accumulation, Vec<f32>), FrameError> {
        let dgi = self.dgi()?;
        Ok(match self.engine {
            Engine::Gpu { ctx, bands, .. } => (read_bands(ctx, &bands)?, dgi),
            Engine::Cpu { accum, .. } => (accum, dgi),
        })
    }
}

/// The bands' accumulations read back and joined into the whole frame's (one band: its own,
/// with no second copy).
fn read_bands(ctx: &GpuContext, bands: &[GpuBand]) -> Result<Accumulation, GpuError> {
    if let [one] = bands {
        return one.accum.read(ctx);
    }
    let (w, h) = (
        bands[0].accum.width,
        bands.iter().map(|b| b.band.rows).sum(),
    );
    let mut acc = Accumulation {
        width: w,
        height: h,
        sum: Vec::with_capacity(w as usize * h as usize),
        count: Vec::with_capacity(w as usize * h as usize),
    };
    for b in bands {
        let part = b.accum.read(ctx)?;
        acc.sum.extend(part.sum);
        acc.count.extend(part.count);
    }
    Ok(acc)
}
