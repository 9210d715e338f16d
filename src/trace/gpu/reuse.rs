//! Dispatch of `shaders/trace/reuse.wgsl` ([`ReuseKernel`]): motion reuse on the GPU over
//! whole-image buffers, the twin of [`crate::trace::reuse::reuse_cpu`].

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::params::wall_table_buffer;
use super::{GpuAccum, GpuHits, entry};
use crate::gpu::{GpuContext, GpuError};
use crate::trace::reuse::{ReuseStats, View};

/// The kernel's source.
pub const REUSE_WGSL: &str = include_str!("../../../shaders/trace/reuse.wgsl");

/// Threads per workgroup (`@workgroup_size` in reuse.wgsl).
const REUSE_WORKGROUP: u32 = 64;

/// Workgroups in one dimension of a dispatch at most (wgpu's default limit).
const MAX_GROUPS_X: u32 = 65_535;

/// Mirrors `View` in reuse.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuView {
    pub eye: [f32; 3],
    pub tan_half_y: f32,
    pub fwd: [f32; 3],
    pub aspect: f32,
    pub right: [f32; 3],
    pub tiles: u32,
    pub up: [f32; 3],
    pub pad: u32,
}

impl GpuView {
    /// `view` as the kernel reads it (an orthographic camera: `tan_half_y` 0, nothing
    /// projects).
    #[must_use]
    pub fn of(view: &View<'_>) -> Self {
        match view {
            View::Wall(w) => Self {
                eye: w.eye.to_array(),
                tiles: w.tiles.len() as u32,
                ..Self::default()
            },
            View::Pinhole { camera: c, .. } => Self {
                eye: c.position.to_array(),
                tan_half_y: if c.ortho_half_y > 0.0 {
                    0.0
                } else {
                    c.tan_half_y
                },
                fwd: c.forward.to_array(),
                aspect: c.aspect,
                right: c.right.to_array(),
                tiles: 0,
                up: c.up.to_array(),
                pad: 0,
            },
        }
    }
}

/// Mirrors `ReuseParams` in reuse.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuReuseParams {
    pub size: [u32; 2],
    pub pad: [u32; 2],
    pub old_view: GpuView,
    pub new_view: GpuView,
}

/// The wall camera of `view`, if it is one.
fn wall_of<'a>(view: &View<'a>) -> Option<&'a crate::trace::wall::WallCamera> {
    match *view {
        View::Wall(w) => Some(w),
        View::Pinhole { .. } => None,
    }
}

/// The compiled reuse kernel.
#[derive(Clone)]
pub struct ReuseKernel {
    pipeline: wgpu::ComputePipeline,
}

/// One move's inputs on the GPU: the two views, the new view's records (carried pixels get
/// their source's anchor), the old view's records and accumulation, and the accumulation the
/// new view starts with (every pixel written).
pub struct ReuseInputs<'a> {
    pub old_view: View<'a>,
    pub new_view: View<'a>,
    pub new_hits: &'a GpuHits,
    pub old_hits: &'a GpuHits,
    pub old_accum: &'a GpuAccum,
    pub accum: &'a GpuAccum,
}

impl ReuseKernel {
    /// The kernel, compiled once a device.
    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        ctx.kept("reuse kernel", || {
            let module = ctx.shader_module("trace/reuse", REUSE_WGSL);
            Self {
                pipeline: ctx.compute_pipeline_in(&module, "trace/reuse", "reuse"),
            }
        })
    }

    /// Runs the move and reads back how many pixels it carried.
    pub fn run(&self, ctx: &GpuContext, inputs: &ReuseInputs<'_>) -> Result<ReuseStats, GpuError> {
        let (w, h) = (inputs.accum.width, inputs.accum.height);
        let params = GpuReuseParams {
            size: [w, h],
            pad: [0; 2],
            old_view: GpuView::of(&inputs.old_view),
            new_view: GpuView::of(&inputs.new_view),
        };
        let make = |label, contents: &[u8], usage| {
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage,
                })
        };
        let params = make(
            "reuse params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let stats = make(
            "reuse stats",
            bytemuck::cast_slice(&[0u32; 4]),
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        );
        let old_wall = wall_table_buffer(ctx, "reuse old wall", wall_of(&inputs.old_view));
        let new_wall = wall_table_buffer(ctx, "reuse new wall", wall_of(&inputs.new_view));
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("reuse"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                entry(0, &params),
                entry(1, &old_wall),
                entry(2, &new_wall),
                entry(3, &inputs.new_hits.records),
                entry(4, &inputs.old_hits.records),
                entry(5, &inputs.old_accum.accum),
                entry(6, &inputs.old_accum.counts),
                entry(7, &inputs.accum.accum),
                entry(8, &inputs.accum.counts),
                entry(9, &stats),
            ],
        });
        let groups = (w * h).div_ceil(REUSE_WORKGROUP);
        let gx = groups.clamp(1, MAX_GROUPS_X);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("trace/reuse"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(gx, groups.div_ceil(gx).max(1), 1);
        }
        ctx.queue.submit([enc.finish()]);
        let counted: Vec<u32> = ctx.read_buffer(&stats)?;
        Ok(ReuseStats {
            carried: u64::from(counted[0]),
            shown: u64::from(counted[1]),
        })
    }
}
