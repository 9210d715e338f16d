//! The scene on the GPU ([`GpuScene`]): its packed arrays uploaded once, bind group 0 of every
//! trace kernel.

use wgpu::util::DeviceExt;

use super::{STACK_ENTRIES, TraceKernel, entry};
use crate::gpu::{GpuContext, GpuError};
use crate::trace::pack::PackedScene;

/// The scene on the GPU.
pub struct GpuScene {
    pub(super) bind: wgpu::BindGroup,
    /// The arrays, in binding order (other kernels over the scene bind what they use).
    pub(super) buffers: Vec<wgpu::Buffer>,
    /// Bytes uploaded (for reports).
    pub bytes: u64,
}

impl GpuScene {
    /// Uploads `scene`; fails with a clear error when an array exceeds the adapter's limits or
    /// the scene's tree needs more than the kernel's traversal stack holds.
    pub fn upload(
        ctx: &GpuContext,
        kernel: &TraceKernel,
        scene: &PackedScene,
    ) -> Result<Self, GpuError> {
        // A walk whose stack is full drops what it would push: that geometry would be missed.
        let needs = scene.bvh.stack_entries();
        if needs > STACK_ENTRIES {
            return Err(GpuError::TraceStack {
                needs,
                holds: STACK_ENTRIES,
            });
        }
        let nodes: &[u8] = if scene.bvh.cwbvh.nodes.is_empty() {
            &[0u8; 80]
        } else {
            bytemuck::cast_slice(&scene.bvh.cwbvh.nodes)
        };
        let arrays: [(&'static str, &[u8]); 8] = [
            ("BVH nodes", nodes),
            ("BVH primitives", bytemuck::cast_slice(&scene.bvh.prims)),
            ("triangle shading data", bytemuck::cast_slice(&scene.shade)),
            ("materials", bytemuck::cast_slice(&scene.materials)),
            ("textures", bytemuck::cast_slice(&scene.texels)),
            ("emissive triangles", bytemuck::cast_slice(&scene.lights)),
            ("sampling distributions", bytemuck::cast_slice(&scene.dist)),
            ("environment map", bytemuck::cast_slice(&scene.env)),
        ];
        let mut bytes = 0;
        let mut buffers = Vec::with_capacity(arrays.len());
        for (what, data) in arrays {
            ctx.check_binding(what, data.len() as u64)?;
            bytes += data.len() as u64;
            buffers.push(
                ctx.device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some(what),
                        contents: data,
                        usage: wgpu::BufferUsages::STORAGE,
                    }),
            );
        }
        let entries: Vec<_> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| entry(i as u32, b))
            .collect();
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace scene"),
            layout: &kernel.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        Ok(Self {
            bind,
            buffers,
            bytes,
        })
    }
}
