//! A cluster rank's samples ([`SampleRun`], DESIGN.md §12): the trace kernel's compact mode,
//! each listed pixel's sample returned rather than accumulated.

use wgpu::util::DeviceExt;

use super::params::{replace_wall, wall_table_buffer};
use super::{GpuScene, GpuTraceParams, TraceKernel, entry};
use crate::gpu::{GpuContext, GpuError};
use crate::trace::pack::PackedScene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

/// Samples returned rather than accumulated: a cluster rank's trace (DESIGN.md §12), whose
/// samples go to the owners of their tiles. The kernel's compact mode: entry i of the list
/// traces pixel `pixels[i]` with sample index `counts[i]` (the rank has each pixel's count
/// on its CPU, from the pixel's owner) and writes the sample's RGB and its ray count into entry i, which is read back.
/// CPU twin: [`crate::trace::path::samples_cpu`].
///
/// Per sample the link to the GPU carries 8 bytes up (pixel, sample index) and 16 down; the
/// buffers grow with the longest list so far.
pub struct SampleRun {
    /// The kernel (its pipeline, its workgroup's size, whether its launches regenerate).
    kernel: TraceKernel,
    params: wgpu::Buffer,
    wall_table: wgpu::Buffer,
    wall: Option<WallCamera>,
    buffers: Option<SampleBuffers>,
}

/// A [`SampleRun`]'s list-sized buffers and the frame bind group over them.
struct SampleBuffers {
    capacity: u32,
    list: wgpu::Buffer,
    counts: wgpu::Buffer,
    out: wgpu::Buffer,
    args: wgpu::Buffer,
    bind: wgpu::BindGroup,
}

impl SampleRun {
    /// For `scene` with `settings`, through `wall`'s primary rays when given.
    #[must_use]
    pub fn new(
        ctx: &GpuContext,
        kernel: &TraceKernel,
        scene: &PackedScene,
        settings: &TraceSettings,
        wall: Option<&WallCamera>,
    ) -> Self {
        let params = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("samples params"),
                contents: bytemuck::bytes_of(&Self::params_of(kernel, scene, settings, wall)),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
        let wall_table = wall_table_buffer(ctx, "samples wall tiles", wall);
        Self {
            kernel: kernel.clone(),
            params,
            wall_table,
            wall: wall.cloned(),
            buffers: None,
        }
    }

    fn params_of(
        kernel: &TraceKernel,
        scene: &PackedScene,
        settings: &TraceSettings,
        wall: Option<&WallCamera>,
    ) -> GpuTraceParams {
        GpuTraceParams {
            mode: 2,
            ..GpuTraceParams::with_wall(kernel, scene, settings, wall, true)
        }
    }

    /// The wall camera `wall` from now on (a moved eye: the same display and tile count).
    /// Returns `false`, changing nothing, where this run has no wall camera or `wall` has
    /// another tile count.
    pub fn set_wall(
        &mut self,
        ctx: &GpuContext,
        scene: &PackedScene,
        settings: &TraceSettings,
        wall: &WallCamera,
    ) -> bool {
        if !replace_wall(ctx, &self.wall_table, &mut self.wall, wall) {
            return false;
        }
        self.set_settings(ctx, scene, settings);
        true
    }

    /// Rewrites the parameters (a new camera or depth) before the next list.
    pub fn set_settings(&self, ctx: &GpuContext, scene: &PackedScene, settings: &TraceSettings) {
        let p = Self::params_of(&self.kernel, scene, settings, self.wall.as_ref());
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&p));
    }

    /// Buffers for at least `len` entries (grown by doubling).
    fn buffers(&mut self, ctx: &GpuContext, len: u32) -> Result<&SampleBuffers, GpuError> {
        if self.buffers.as_ref().is_none_or(|b| b.capacity < len) {
            // Doubling, within what one binding holds (`samples` keeps `len` below it).
            let most = u32::try_from(ctx.max_binding() / 16).unwrap_or(u32::MAX);
            let capacity = len.max(1).next_power_of_two().max(1024).min(most).max(len);
            ctx.check_binding("a rank's samples (16 bytes each)", u64::from(capacity) * 16)?;
            let make = |label, bytes: u64, usage| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes,
                    usage,
                    mapped_at_creation: false,
                })
            };
            use wgpu::BufferUsages as U;
            let n = u64::from(capacity);
            let list = make("samples pixels", 4 * n, U::STORAGE | U::COPY_DST);
            let counts = make("samples indices", 4 * n, U::STORAGE | U::COPY_DST);
            let out = make(
                "samples out",
                16 * n,
                U::STORAGE | U::COPY_SRC | U::COPY_DST,
            );
            let args = make("samples args", 16, U::STORAGE | U::COPY_DST);
            let stats = make("samples stats", 16, U::STORAGE);
            let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("samples frame"),
                layout: &self.kernel.pipeline.get_bind_group_layout(1),
                entries: &[
                    entry(0, &self.params),
                    entry(1, &out),
                    entry(2, &counts),
                    entry(3, &list),
                    entry(4, &args),
                    entry(5, &stats),
                    entry(6, &self.wall_table),
                ],
            });
            self.buffers = Some(SampleBuffers {
                capacity,
                list,
                counts,
                out,
                args,
                bind,
            });
        }
        Ok(self.buffers.as_ref().expect("made above"))
    }

    /// One sample for each of `pixels` (sample index `counts[i]` for `pixels[i]`): its RGB and
    /// the rays it took, in list order; a pixel the wall camera does not show gives black and
    /// no rays. A list longer than one binding holds (16 bytes an entry) goes in pieces.
    pub fn samples(
        &mut self,
        ctx: &GpuContext,
        scene: &GpuScene,
        pixels: &[u32],
        counts: &[u32],
    ) -> Result<Vec<(glam::Vec3, u32)>, GpuError> {
        Ok(self
            .samples_raw(ctx, scene, pixels, counts)?
            .iter()
            .map(|v| (glam::Vec3::new(v[0], v[1], v[2]), v[3].to_bits()))
            .collect())
    }

    /// [`Self::samples`] as the kernel writes them: RGB, then the rays as the bits of the
    /// fourth float — the read-back itself, not a converted copy (a GPU rank's list is
    /// millions of samples).
    pub fn samples_raw(
        &mut self,
        ctx: &GpuContext,
        scene: &GpuScene,
        pixels: &[u32],
        counts: &[u32],
    ) -> Result<Vec<[f32; 4]>, GpuError> {
        assert_eq!(pixels.len(), counts.len(), "a sample index for each pixel");
        if Self::fits_one_binding(ctx, pixels.len()) {
            return self.samples_prefix(ctx, scene, pixels, counts, pixels.len());
        }
        let piece = Self::piece(ctx);
        let mut out = Vec::with_capacity(pixels.len());
        for (p, c) in pixels.chunks(piece).zip(counts.chunks(piece)) {
            out.extend(self.samples_prefix(ctx, scene, p, c, p.len())?);
        }
        Ok(out)
    }

    /// The most samples one dispatch takes: one binding of 16 bytes each.
    fn piece(ctx: &GpuContext) -> usize {
        (ctx.max_binding() / 16).clamp(1, 1 << 30) as usize
    }

    /// Traces `pixels` (a list one binding holds: [`Self::fits_one_binding`]) and reads back
    /// the first `read` samples only; the others stay in [`Self::out`] until the next list (a
    /// cluster rank keeps the samples of its own blocks on its GPU: [`super::OwnedSums::keep`]).
    pub fn samples_prefix(
        &mut self,
        ctx: &GpuContext,
        scene: &GpuScene,
        pixels: &[u32],
        counts: &[u32],
        read: usize,
    ) -> Result<Vec<[f32; 4]>, GpuError> {
        assert_eq!(pixels.len(), counts.len(), "a sample index for each pixel");
        assert!(read <= pixels.len(), "{read} of {} samples", pixels.len());
        if pixels.is_empty() {
            return Ok(Vec::new());
        }
        let len = u32::try_from(pixels.len()).expect("a list of u32 pixel indices");
        // The scheduler's grid for this kernel (capped where it regenerates).
        let [gx, gy, _] = crate::schedule::indirect_grid(
            len,
            self.kernel.workgroup(),
            self.kernel.max_list_groups(),
            ctx.limits.max_compute_workgroups_per_dimension,
        );
        let pipeline = self.kernel.pipeline.clone();
        let b = self.buffers(ctx, len)?;
        ctx.queue
            .write_buffer(&b.list, 0, bytemuck::cast_slice(pixels));
        ctx.queue
            .write_buffer(&b.counts, 0, bytemuck::cast_slice(counts));
        ctx.queue
            .write_buffer(&b.args, 0, bytemuck::cast_slice(&[gx, gy, 1, len]));
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("trace/samples"),
            });
        enc.clear_buffer(&b.out, 0, Some(16 * u64::from(len)));
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("trace/samples"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &scene.bind, &[]);
            pass.set_bind_group(1, &b.bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        ctx.queue.submit([enc.finish()]);
        ctx.read_prefix(&b.out, 16 * read as u64)
    }

    /// Whether a list of `len` samples is traced in one dispatch (16 bytes a sample in one
    /// binding), so [`Self::samples_prefix`] can take it.
    #[must_use]
    pub fn fits_one_binding(ctx: &GpuContext, len: usize) -> bool {
        len <= Self::piece(ctx)
    }

    /// The last list's samples (RGB, rays as bits), entry i for its pixel i.
    #[must_use]
    pub fn out(&self) -> Option<&wgpu::Buffer> {
        self.buffers.as_ref().map(|b| &b.out)
    }
}
