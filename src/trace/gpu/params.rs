//! The trace kernel's parameters for a frame ([`GpuTraceParams`], `Params` in
//! `shaders/trace/path.wgsl`), the full frame's launch grid, and the wall camera's tile table
//! the kernel reads beside them.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::TraceKernel;
use crate::gpu::{Band, GpuContext};
use crate::trace::pack::PackedScene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

/// Vec4s of the stand-in wall table when there is no wall camera (a binding is never empty).
const TILE_VEC4S_MIN: usize = 4;
/// The most workgroups in one dimension of a dispatch.
pub(super) const MAX_GROUPS_X: u32 = 65_535;

/// Mirrors `Params` in shaders/trace/path.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuTraceParams {
    pub size: [u32; 2],
    pub count: u32,
    pub mode: u32,
    pub seed: u32,
    pub max_depth: u32,
    pub light_count: u32,
    pub groups_x: u32,
    pub env_size: [u32; 2],
    pub env_marginal: u32,
    pub env_conditional: u32,
    pub env_constant: [f32; 3],
    pub env_select: f32,
    pub cam_pos: [f32; 3],
    pub tan_half_y: f32,
    pub cam_fwd: [f32; 3],
    pub aspect: f32,
    pub cam_right: [f32; 3],
    pub node_count: u32,
    pub cam_up: [f32; 3],
    /// The wall camera's tile count (0: pinhole or orthographic).
    pub wall_tiles: u32,
    pub features: u32,
    pub extras_offset: u32,
    pub punctual_count: u32,
    pub punct_select: f32,
    pub ortho_half_y: f32,
    /// The band of rows this dispatch covers ([`Band`]): its buffers hold `size.x × rows`
    /// pixels from image row `row0`.
    pub row0: u32,
    pub rows: u32,
    /// Full frames of a regenerating kernel (the kernel lab's `+regenG`): the threads
    /// launched, each tracing the paths of slots `linear`, `linear + stride`, …; 0: a thread a
    /// path.
    pub stride: u32,
}

/// The full-frame grid: threads (8 × 8 tiles, padded) and a 2D grid of `workgroup`-thread
/// groups within the per-dimension dispatch limit.
#[must_use]
pub fn full_frame_grid(width: u32, height: u32, workgroup: u32) -> (u32, [u32; 2]) {
    let threads = width.div_ceil(8) * height.div_ceil(8) * 64;
    let groups = threads.div_ceil(workgroup);
    let gx = groups.min(MAX_GROUPS_X);
    (threads, [gx, groups.div_ceil(gx)])
}

impl GpuTraceParams {
    /// The parameters for `kernel` with `wall`'s eye and tile count when given.
    #[must_use]
    pub fn with_wall(
        kernel: &TraceKernel,
        scene: &PackedScene,
        s: &TraceSettings,
        wall: Option<&WallCamera>,
        list_mode: bool,
    ) -> Self {
        Self::for_band(kernel, scene, s, wall, list_mode, Band::whole(s.height))
    }

    /// [`Self::with_wall`] for the rows of `band` alone.
    #[must_use]
    pub fn for_band(
        kernel: &TraceKernel,
        scene: &PackedScene,
        s: &TraceSettings,
        wall: Option<&WallCamera>,
        list_mode: bool,
        band: Band,
    ) -> Self {
        let (threads, [gx, _], stride) = kernel.full_frame_launch(s.width, band.rows);
        // A list is dispatched from its count, a thread a path.
        let stride = if list_mode { 0 } else { stride };
        let c = &s.camera;
        Self {
            size: [s.width, s.height],
            count: threads,
            mode: u32::from(list_mode),
            seed: s.seed,
            max_depth: s.max_depth,
            light_count: scene.light_count,
            groups_x: gx,
            env_size: scene.env_size,
            env_marginal: scene.env_marginal,
            env_conditional: scene.env_conditional,
            env_constant: scene.env_constant.to_array(),
            env_select: scene.env_select,
            cam_pos: wall.map_or(c.position, |w| w.eye).to_array(),
            tan_half_y: c.tan_half_y,
            cam_fwd: c.forward.to_array(),
            aspect: c.aspect,
            cam_right: c.right.to_array(),
            node_count: scene.bvh.cwbvh.nodes.len() as u32,
            cam_up: c.up.to_array(),
            wall_tiles: wall.map_or(0, |w| w.tiles.len() as u32),
            features: scene.features,
            extras_offset: scene.extras_offset,
            punctual_count: scene.punctual_count,
            punct_select: scene.punct_select,
            ortho_half_y: c.ortho_half_y,
            row0: band.row0,
            rows: band.rows,
            stride,
        }
    }
}

/// `wall`'s tile table as a storage buffer ([`TILE_VEC4S`](crate::trace::wall::TILE_VEC4S) vec4s a
/// tile), or a stand-in without one (a binding is never empty).
pub(super) fn wall_table_buffer(
    ctx: &GpuContext,
    label: &str,
    wall: Option<&WallCamera>,
) -> wgpu::Buffer {
    let table = wall.map_or_else(|| vec![[0.0f32; 4]; TILE_VEC4S_MIN], WallCamera::gpu_table);
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(&table),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        })
}

/// Writes `wall`'s tile table into `table` and makes it `current`, where `current` is a wall
/// camera with as many tiles (a moved eye); `false`, changing nothing, otherwise.
pub(super) fn replace_wall(
    ctx: &GpuContext,
    table: &wgpu::Buffer,
    current: &mut Option<WallCamera>,
    wall: &WallCamera,
) -> bool {
    match current {
        Some(w) if w.tiles.len() == wall.tiles.len() => {}
        _ => return false,
    }
    ctx.queue
        .write_buffer(table, 0, bytemuck::cast_slice(&wall.gpu_table()));
    *current = Some(wall.clone());
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_frame_grid_stays_within_dispatch_limits() {
        for (w, h) in [(1, 1), (7, 9), (128, 72), (3840, 2160), (7680, 4320)] {
            // Every workgroup size the kernel lab compiles.
            for wg in [32, 64, 128, 256] {
                let (threads, [gx, gy]) = full_frame_grid(w, h, wg);
                assert!(gx <= MAX_GROUPS_X);
                assert!(u64::from(gx) * u64::from(gy) * u64::from(wg) >= u64::from(threads));
                assert!(u64::from(threads) >= u64::from(w) * u64::from(h));
            }
        }
    }
}
