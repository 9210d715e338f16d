//! The accumulation on the GPU ([`GpuAccum`]): the buffers the trace kernel adds its samples to.

use crate::gpu::{GpuContext, GpuError};
use crate::trace::accum::Accumulation;

/// The accumulation on the GPU (layout: [`crate::trace::accum`]), and the tracer's statistics.
pub struct GpuAccum {
    pub width: u32,
    pub height: u32,
    pub accum: wgpu::Buffer,
    pub counts: wgpu::Buffer,
    /// `[rays traced]` since the last [`GpuAccum::clear_stats`].
    pub stats: wgpu::Buffer,
}

impl GpuAccum {
    /// Zeroed buffers for a `width × height` image.
    pub fn new(ctx: &GpuContext, width: u32, height: u32) -> Result<Self, GpuError> {
        let n = u64::from(width) * u64::from(height);
        ctx.check_binding("accumulation (16 bytes per pixel)", n * 16)?;
        let make = |label, size| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        Ok(Self {
            width,
            height,
            accum: make("trace accum", n * 16),
            counts: make("trace counts", n * 4),
            stats: make("trace stats", 16),
        })
    }

    /// Records zeroing the statistics.
    pub fn clear_stats(&self, enc: &mut wgpu::CommandEncoder) {
        enc.clear_buffer(&self.stats, 0, None);
    }

    /// Rays traced since the statistics were last cleared (a read-back: for benchmarks).
    pub fn rays(&self, ctx: &GpuContext) -> Result<u64, GpuError> {
        Ok(u64::from(ctx.read_buffer::<u32>(&self.stats)?[0]))
    }

    /// Records clearing both buffers (a new render).
    pub fn clear(&self, enc: &mut wgpu::CommandEncoder) {
        enc.clear_buffer(&self.accum, 0, None);
        enc.clear_buffer(&self.counts, 0, None);
        enc.clear_buffer(&self.stats, 0, None);
    }

    /// Reads the accumulation back.
    pub fn read(&self, ctx: &GpuContext) -> Result<Accumulation, GpuError> {
        Ok(Accumulation {
            width: self.width,
            height: self.height,
            sum: ctx.read_buffer::<[f32; 4]>(&self.accum)?,
            count: ctx.read_buffer::<u32>(&self.counts)?,
        })
    }
}
