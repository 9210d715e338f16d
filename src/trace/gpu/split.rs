//! The wavefront split of full frames (a `+split` variant: [`TraceVariant::split`]): the
//! paths' start, their closest hits and the rest of each bounce as three kernels
//! (`split_start`, `split_extend`, `split_shade` in `shaders/trace/path.wgsl`), a bounce apart,
//! over chunks of paths (Laine et al. 2013).

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::params::MAX_GROUPS_X;
use super::{TraceVariant, entry, full_frame_launch};
use crate::gpu::GpuContext;

/// The wavefront split's three entry points (`split_start`, `split_extend`, `split_shade` in
/// path.wgsl), sharing `trace`'s bind groups 0 and 1 (one explicit layout for all four).
#[derive(Clone)]
pub(super) struct SplitKernels {
    pub(super) start: wgpu::ComputePipeline,
    pub(super) extend: wgpu::ComputePipeline,
    pub(super) shade: wgpu::ComputePipeline,
    /// Bind group 2: a chunk's path states, closest hits, [`GpuSplitParams`], and its two
    /// queues of live paths with their lengths.
    pub(super) chunk_layout: wgpu::BindGroupLayout,
}

/// Mirrors `SplitParams` in shaders/trace/path.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuSplitParams {
    pub first_job: u32,
    pub jobs: u32,
    pub groups_x: u32,
    /// 0: the first bounce (the chunk's paths, the live ones queued in queue 1); 1: queue 1
    /// to queue 0; 2: queue 0 to queue 1.
    pub phase: u32,
}

/// GPU bytes a path of the wavefront split holds while its chunk is traced: its state
/// (`PathState`, 64), its closest hit (`Hit`, 16) and its place in the two queues (4 each).
pub const SPLIT_PATH_BYTES: u64 = 88;

/// The paths a chunk of `variant`'s wavefront split holds for a full frame of `jobs` threads:
/// the variant's chunk, at most what one binding of `max_binding` bytes holds of path states
/// (64 bytes each), at most the frame's jobs (rounded up to 64), at least 64.
#[must_use]
pub fn split_chunk(variant: TraceVariant, jobs: u32, max_binding: u64) -> u32 {
    let most = (max_binding / 64).min(u64::from(u32::MAX)) as u32 / 64 * 64;
    variant
        .split
        .min(most)
        .min(jobs.next_multiple_of(64))
        .max(64)
}

/// GPU bytes the wavefront split of `variant` holds for a full frame of `width × rows`
/// ([`SPLIT_PATH_BYTES`] a path of a chunk, [`split_chunk`]); 0 for a kernel without it.
#[must_use]
pub fn split_bytes(variant: TraceVariant, width: u32, rows: u32, max_binding: u64) -> u64 {
    if variant.split == 0 {
        return 0;
    }
    let (jobs, _, _) = full_frame_launch(width, rows, variant);
    SPLIT_PATH_BYTES * u64::from(split_chunk(variant, jobs, max_binding))
}

/// A compute-stage bind group layout of `entries`: `(binding, type)`.
fn bind_layout(
    ctx: &GpuContext,
    label: &str,
    entries: &[(u32, wgpu::BufferBindingType)],
) -> wgpu::BindGroupLayout {
    let entries: Vec<_> = entries
        .iter()
        .map(|&(binding, ty)| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect();
    ctx.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &entries,
        })
}

/// The explicit bind group layouts the split's kernels share with `trace`: a layout derived
/// from one pipeline serves that pipeline alone, and the split's kernels take the bind groups
/// made for `trace` (groups 0 and 1) beside a chunk's (group 2).
pub(super) struct SplitLayouts {
    scene: wgpu::BindGroupLayout,
    frame: wgpu::BindGroupLayout,
    /// Bind group 2: a chunk's path states, closest hits, [`GpuSplitParams`], and its two
    /// queues of live paths with their lengths.
    pub(super) chunk: wgpu::BindGroupLayout,
}

impl SplitLayouts {
    pub(super) fn new(ctx: &GpuContext) -> Self {
        use wgpu::BufferBindingType as B;
        let read = B::Storage { read_only: true };
        let write = B::Storage { read_only: false };
        Self {
            scene: bind_layout(
                ctx,
                "trace scene",
                &[0, 1, 2, 3, 4, 5, 6, 7].map(|b| (b, read)),
            ),
            frame: bind_layout(
                ctx,
                "trace frame",
                &[
                    (0, B::Uniform),
                    (1, write),
                    (2, write),
                    (3, read),
                    (4, read),
                    (5, write),
                    (6, read),
                ],
            ),
            chunk: bind_layout(
                ctx,
                "trace split chunk",
                &[
                    (0, write),
                    (1, write),
                    (2, B::Uniform),
                    (3, write),
                    (4, write),
                ],
            ),
        }
    }

    /// The pipeline layout of `trace` (the scene and the frame), or of the split's kernels
    /// where `chunk` (and a chunk's group).
    pub(super) fn pipeline(
        &self,
        ctx: &GpuContext,
        label: &str,
        chunk: bool,
    ) -> wgpu::PipelineLayout {
        let groups = [Some(&self.scene), Some(&self.frame), Some(&self.chunk)];
        ctx.device
            .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &groups[..if chunk { 3 } else { 2 }],
                immediate_size: 0,
            })
    }
}

/// A full frame in the wavefront split: the kernels, and each chunk's bind groups (one a
/// phase: its parameters over the path states, hits and queues all chunks share, traced one
/// after the other) and grid.
pub(super) struct SplitRun {
    start: wgpu::ComputePipeline,
    extend: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
    chunks: Vec<([wgpu::BindGroup; 3], [u32; 2])>,
    /// Bounces a chunk runs: the settings' maximum depth.
    pub(super) max_depth: std::cell::Cell<u32>,
}

impl SplitRun {
    /// `jobs` full-frame jobs (threads of the one-kernel frame) in chunks of at most `chunk`
    /// paths — fewer where one binding holds fewer path states.
    pub(super) fn new(
        ctx: &GpuContext,
        kernels: &SplitKernels,
        variant: TraceVariant,
        jobs: u32,
        max_depth: u32,
    ) -> Self {
        let chunk = split_chunk(variant, jobs, ctx.max_binding());
        let buffer = |label, bytes: u64| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        let states = buffer("trace split states", 64 * u64::from(chunk));
        let hits = buffer("trace split hits", 16 * u64::from(chunk));
        let queues = buffer("trace split queues", 8 * u64::from(chunk));
        let lengths = buffer("trace split queue lengths", 8);
        let chunks = (0..jobs)
            .step_by(chunk as usize)
            .map(|first_job| {
                let n = chunk.min(jobs - first_job);
                let groups = n.div_ceil(variant.workgroup);
                let gx = groups.min(MAX_GROUPS_X);
                let phase = |phase: u32| {
                    let params = ctx
                        .device
                        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                            label: Some("trace split chunk"),
                            contents: bytemuck::bytes_of(&GpuSplitParams {
                                first_job,
                                // The queues are `jobs` apart: the chunk's size, the last
                                // chunk's too.
                                jobs: n,
                                groups_x: gx,
                                phase,
                            }),
                            usage: wgpu::BufferUsages::UNIFORM,
                        });
                    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("trace split chunk"),
                        layout: &kernels.chunk_layout,
                        entries: &[
                            entry(0, &states),
                            entry(1, &hits),
                            entry(2, &params),
                            entry(3, &queues),
                            entry(4, &lengths),
                        ],
                    })
                };
                ([phase(0), phase(1), phase(2)], [gx, groups.div_ceil(gx)])
            })
            .collect();
        Self {
            start: kernels.start.clone(),
            extend: kernels.extend.clone(),
            shade: kernels.shade.clone(),
            chunks,
            max_depth: std::cell::Cell::new(max_depth),
        }
    }

    /// Each chunk in turn: its paths started, then closest hits and shading alternating, a
    /// bounce each (the first over the chunk's paths, then from one queue of live paths into
    /// the other and back), in a pass whose bind groups 0 and 1 are set.
    pub(super) fn record(&self, pass: &mut wgpu::ComputePass<'_>) {
        for (phases, [gx, gy]) in &self.chunks {
            pass.set_bind_group(2, &phases[0], &[]);
            pass.set_pipeline(&self.start);
            pass.dispatch_workgroups(*gx, *gy, 1);
            for bounce in 0..self.max_depth.get() {
                let phase = match bounce {
                    0 => 0,
                    b if b % 2 == 1 => 1,
                    _ => 2,
                };
                pass.set_bind_group(2, &phases[phase], &[]);
                pass.set_pipeline(&self.extend);
                pass.dispatch_workgroups(*gx, *gy, 1);
                pass.set_pipeline(&self.shade);
                pass.dispatch_workgroups(*gx, *gy, 1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::wgsl::{assert_same_layout, struct_size, validated};

    #[test]
    fn the_split_params_and_path_bytes_match_the_kernel() {
        let module = validated("path.wgsl", super::super::TRACE_WGSL);
        assert_same_layout(
            &module,
            "SplitParams",
            &crate::rust_layout!(GpuSplitParams; first_job, jobs, groups_x, phase),
        );
        // The split's buffers: a path's state, its closest hit and its two queue entries.
        assert_eq!(
            (struct_size(&module, "PathState") + struct_size(&module, "Hit") + 8) as u64,
            SPLIT_PATH_BYTES
        );
        assert_eq!(struct_size(&module, "PathState"), 64);
    }
}
