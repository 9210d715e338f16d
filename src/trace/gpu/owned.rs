//! A cluster rank's owned sums on its GPU ([`OwnedSums`], DESIGN.md §12):
//! `shaders/trace/accum.wgsl` adds the samples of the rank's own blocks and the other ranks'.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::{ACCUM_WGSL, entry};
use crate::gpu::{GpuContext, GpuError};

/// The parameters of `shaders/trace/accum.wgsl` (mirrors `OwnedParams`, 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuOwnedParams {
    pub own: u32,
    pub foreign: u32,
    pub segments: u32,
    pub _pad: u32,
}

/// Threads per workgroup of `accum.wgsl`'s entry points.
pub(super) const ACCUM_WORKGROUP: u32 = 256;

/// A cluster rank's owned sums on its GPU (DESIGN.md §12): `BLOCK_PIXELS` entries per owned
/// block (RGB sum, Σ lum²), as the rank's CPU lays them out. The samples of its own blocks that
/// it traced stay on the GPU from the trace ([`Self::keep`]) and are added with the other
/// ranks' samples when the frame is collected ([`Self::add`]), so only other owners' samples
/// are read back. CPU twins: `accumulate_sums` and `block_rays` (src/trace/accum.rs).
pub struct OwnedSums {
    add: wgpu::ComputePipeline,
    rays: wgpu::ComputePipeline,
    /// The owned sums.
    pub sums: wgpu::Buffer,
    /// The kept samples, oldest first: each traced frame's own blocks' samples, in the order
    /// of their blocks, with their count, until its frame is collected (with the exchange
    /// overlapped, the next frame keeps its own before the last one's are added).
    kept: std::collections::VecDeque<(wgpu::Buffer, u32)>,
    /// Kept buffers added already, for the next frames to reuse.
    free: Vec<wgpu::Buffer>,
    /// Owned pixels.
    entries: u64,
}

fn storage_init(ctx: &GpuContext, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    // A binding may not be empty: one zero word where there is nothing.
    let bytes = if bytes.is_empty() {
        &[0u8; 4][..]
    } else {
        bytes
    };
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytes,
            usage: wgpu::BufferUsages::STORAGE,
        })
}

impl OwnedSums {
    /// Zeroed sums for `entries` owned pixels (`None` where they exceed one binding: the rank
    /// adds on its CPU then).
    pub fn new(ctx: &GpuContext, entries: u64) -> Option<Self> {
        if entries * 16 > ctx.max_binding() {
            return None;
        }
        let module = ctx.shader_module("trace/accum.wgsl", ACCUM_WGSL);
        Some(Self {
            add: ctx.compute_pipeline_in(&module, "trace/accum add", "add"),
            rays: ctx.compute_pipeline_in(&module, "trace/accum block_rays", "block_rays"),
            sums: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("owned sums"),
                size: (entries * 16).max(16),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            kept: std::collections::VecDeque::new(),
            free: Vec::new(),
            entries,
        })
    }

    /// Every owned sum back to zero (a restart; the frames in flight are collected as stale:
    /// [`Self::drop_kept`]).
    pub fn clear(&mut self, ctx: &GpuContext) {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        enc.clear_buffer(&self.sums, 0, None);
        ctx.queue.submit([enc.finish()]);
    }

    /// Drops the oldest kept samples unadded (their frame was collected after a restart).
    pub fn drop_kept(&mut self) {
        if let Some((b, _)) = self.kept.pop_front() {
            self.free.push(b);
        }
    }

    /// Keeps entries `from..from + len` of `out` (the last list's samples: own blocks' samples
    /// after the others; `None` where the list was empty) until [`Self::add`], and returns the rays of each run `segments`
    /// gives ((first, length) in the kept samples).
    pub fn keep(
        &mut self,
        ctx: &GpuContext,
        out: Option<&wgpu::Buffer>,
        from: u64,
        len: u32,
        segments: &[[u32; 2]],
    ) -> Result<Vec<u32>, GpuError> {
        let bytes = 16 * u64::from(len.max(1));
        ctx.check_binding("a rank's own samples (16 bytes each)", bytes)?;
        let buffer = match self.free.iter().position(|b| b.size() >= bytes) {
            Some(i) => self.free.swap_remove(i),
            None => ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("owned samples kept"),
                size: bytes.next_power_of_two(),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        };
        self.kept.push_back((buffer, len));
        let kept = &self.kept.back().expect("pushed above").0;
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        if len > 0 {
            let out = out.expect("samples to keep come from a traced list");
            enc.copy_buffer_to_buffer(out, 16 * from, kept, 0, 16 * u64::from(len));
        }
        if segments.is_empty() {
            ctx.queue.submit([enc.finish()]);
            return Ok(Vec::new());
        }
        let n = u32::try_from(segments.len()).expect("blocks of a u32 list");
        let params = self.params(ctx, 0, 0, n);
        let seg = storage_init(ctx, "owned segments", bytemuck::cast_slice(segments));
        let rays = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("owned block rays"),
            size: 4 * u64::from(n),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("owned block rays"),
            layout: &self.rays.get_bind_group_layout(0),
            entries: &[
                entry(0, &params),
                entry(2, kept),
                entry(6, &seg),
                entry(7, &rays),
            ],
        });
        let [gx, gy] = ctx.grid_2d(n);
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.rays);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        ctx.queue.submit([enc.finish()]);
        ctx.read_buffer(&rays)
    }

    fn params(&self, ctx: &GpuContext, own: u32, foreign: u32, segments: u32) -> wgpu::Buffer {
        ctx.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("owned params"),
                contents: bytemuck::bytes_of(&GpuOwnedParams {
                    own,
                    foreign,
                    segments,
                    _pad: 0,
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    /// Adds the kept samples to the sums at `own_dst` (one entry each, in kept order; `None`:
    /// the kept samples are dropped, as a restarted accumulation drops them) and the samples
    /// `foreign` (RGB triples) at `foreign_dst`. No two of them may be one pixel (a pixel gets
    /// at most one sample a frame).
    pub fn add(
        &mut self,
        ctx: &GpuContext,
        own_dst: Option<&[u32]>,
        foreign: &[f32],
        foreign_dst: &[u32],
    ) -> Result<(), GpuError> {
        assert_eq!(
            foreign.len(),
            3 * foreign_dst.len(),
            "an RGB triple per destination"
        );
        let kept = match own_dst {
            Some(d) => {
                let (b, len) = self.kept.pop_front().expect("samples kept for this frame");
                assert_eq!(d.len(), len as usize, "a destination per kept sample");
                Some((b, len))
            }
            None => None,
        };
        let own = kept.as_ref().map_or(0, |k| k.1);
        let foreign_n = u32::try_from(foreign_dst.len()).expect("a u32 list");
        let total = own + foreign_n;
        if total == 0 {
            self.free.extend(kept.map(|k| k.0));
            return Ok(());
        }
        ctx.check_binding(
            "other ranks' samples (12 bytes each)",
            12 * u64::from(foreign_n),
        )?;
        let params = self.params(ctx, own, foreign_n, 0);
        let own_dst = storage_init(
            ctx,
            "owned destinations",
            bytemuck::cast_slice(own_dst.unwrap_or(&[])),
        );
        let foreign_buf = storage_init(ctx, "other ranks' samples", bytemuck::cast_slice(foreign));
        let foreign_dst = storage_init(
            ctx,
            "other ranks' destinations",
            bytemuck::cast_slice(foreign_dst),
        );
        let empty;
        let kept_buffer = match &kept {
            Some(k) => &k.0,
            None => {
                empty = storage_init(ctx, "no kept samples", &[0u8; 16]);
                &empty
            }
        };
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("owned add"),
            layout: &self.add.get_bind_group_layout(0),
            entries: &[
                entry(0, &params),
                entry(1, &self.sums),
                entry(2, kept_buffer),
                entry(3, &own_dst),
                entry(4, &foreign_buf),
                entry(5, &foreign_dst),
            ],
        });
        let [gx, gy] = ctx.grid_2d(total.div_ceil(ACCUM_WORKGROUP));
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.add);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        ctx.queue.submit([enc.finish()]);
        // Reused only by a later submit, which the queue orders after this one.
        self.free.extend(kept.map(|k| k.0));
        Ok(())
    }

    /// The owned sums, read back.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<[f32; 4]>, GpuError> {
        ctx.read_prefix(&self.sums, 16 * self.entries)
    }
}
