//! Dispatch of `shaders/trace/reuse.wgsl` ([`ReuseKernel`]): motion reuse on the GPU over
//! whole-image buffers, the twin of [`crate::trace::reuse::reuse_cpu`].

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::params::wall_table_buffer;
use super::{GpuAccum, GpuHits, REUSE_WGSL, entry};
use crate::gpu::{GpuContext, GpuError};
use crate::trace::reuse::{ReuseStats, View};

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

#[cfg(test)]
mod tests {
    use glam::{DVec3, Vec3};

    use super::*;
    use crate::display::DisplayModel;
    use crate::gpu::Band;
    use crate::scene::Scene;
    use crate::trace::accum::Accumulation;
    use crate::trace::camera::RenderCamera;
    use crate::trace::features::hit_records_cpu;
    use crate::trace::gpu::{FeatureInputs, FeaturesKernel, GpuScene, TraceKernel};
    use crate::trace::pack::PackedScene;
    use crate::trace::path::TraceSettings;
    use crate::trace::reuse::reuse_cpu;
    use crate::trace::wall::{WallCamera, WorldFromRoom};

    /// The GPU's records of `s` (through `wall`), read back.
    fn gpu_hits(
        ctx: &GpuContext,
        packed: &PackedScene,
        gs: &GpuScene,
        s: &TraceSettings,
        wall: Option<&WallCamera>,
    ) -> GpuHits {
        let hits = GpuHits::new(
            ctx,
            s.width,
            Band {
                row0: 0,
                rows: s.height,
            },
        )
        .unwrap();
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let inputs = FeatureInputs {
            trace: &TraceKernel::new(ctx),
            scene_gpu: gs,
            scene: packed,
            settings: s,
            wall,
        };
        FeaturesKernel::new(ctx).record_hits(ctx, &mut enc, inputs, &hits);
        ctx.queue.submit([enc.finish()]);
        hits
    }

    /// Through HORNET's wall camera on the Cornell box, an eye moving 3 cm: the GPU's records
    /// are the CPU twin's (anchors within 1e-4 of the depth, normals within 1e-4, the same
    /// words: ≥ 99 % of pixels), and the reuse kernel carries the same pixels from the same
    /// sources with the same sums as the twin (≥ 99 % of pixels; the rest sit where a pixel
    /// boundary or a tolerance is met to the last bit).
    #[test]
    fn gpu_reuse_is_the_cpu_twins() {
        let ctx = GpuContext::for_tests();
        let scene = Scene::builtin("cornell-light").unwrap();
        let packed = PackedScene::new(&scene);
        let model = DisplayModel::open("hornet").unwrap().0;
        let (w, h) = (160u32, 64u32);
        let cam = RenderCamera::choose(&scene, None, w, h).unwrap();
        let s = TraceSettings {
            width: w,
            height: h,
            seed: 1,
            max_depth: 4,
            camera: cam,
        };
        let dv = |v: Vec3| DVec3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z));
        let old_wall = WallCamera::new(
            &model,
            [w, h],
            DVec3::new(0.0, 0.0, 1.5),
            &WorldFromRoom::Auto,
            (dv(cam.position), dv(cam.forward), dv(cam.up)),
        )
        .unwrap();
        let new_wall = old_wall.with_eye(DVec3::new(0.03, 0.01, 1.5)).unwrap();
        let trace = TraceKernel::new(&ctx);
        let gs = GpuScene::upload(&ctx, &trace, &packed).unwrap();
        let old_cpu = hit_records_cpu(&packed, &s, Some(&old_wall));
        let mut new_cpu = hit_records_cpu(&packed, &s, Some(&new_wall));
        let old_gpu = gpu_hits(&ctx, &packed, &gs, &s, Some(&old_wall));
        let new_gpu = gpu_hits(&ctx, &packed, &gs, &s, Some(&new_wall));
        let n = (w * h) as usize;
        let same_record = |a: &[[f32; 4]; 2], b: &[[f32; 4]; 2]| {
            let tol = 1e-4 * Vec3::from_slice(&a[0][..3]).length().max(1.0);
            a[1][3].to_bits() == b[1][3].to_bits()
                && (0..3).all(|c| (a[0][c] - b[0][c]).abs() <= tol)
                && (0..3).all(|c| (a[1][c] - b[1][c]).abs() <= 1e-4)
        };
        let got = old_gpu.read(&ctx).unwrap();
        let agree = (0..n)
            .filter(|&p| same_record(&old_cpu[p], &got[p]))
            .count();
        assert!(agree * 100 >= n * 99, "records: {agree} of {n} agree");
        // An accumulation to carry: pixel p holds p + 1 samples of a tagged sum.
        let mut acc = Accumulation::new(w, h);
        for p in 0..n {
            acc.sum[p] = [p as f32, 1.0, 2.0, 3.0];
            acc.count[p] = p as u32 % 50 + 1;
        }
        let old_accum = GpuAccum::new(&ctx, w, h).unwrap();
        ctx.queue
            .write_buffer(&old_accum.accum, 0, bytemuck::cast_slice(&acc.sum));
        ctx.queue
            .write_buffer(&old_accum.counts, 0, bytemuck::cast_slice(&acc.count));
        let accum = GpuAccum::new(&ctx, w, h).unwrap();
        let (ov, nv) = (View::Wall(&old_wall), View::Wall(&new_wall));
        // The twin on the GPU's records, so that only the reuse step is compared.
        let mut new_twin = new_gpu.read(&ctx).unwrap();
        let (want, want_stats) = reuse_cpu(&nv, &ov, &mut new_twin, &got, &acc);
        let stats = ReuseKernel::new(&ctx)
            .run(
                &ctx,
                &ReuseInputs {
                    old_view: ov,
                    new_view: nv,
                    new_hits: &new_gpu,
                    old_hits: &old_gpu,
                    old_accum: &old_accum,
                    accum: &accum,
                },
            )
            .unwrap();
        assert_eq!(stats.shown, want_stats.shown);
        assert!(want_stats.share() > 0.8, "{want_stats:?}");
        let carried = accum.read(&ctx).unwrap();
        let new_records = new_gpu.read(&ctx).unwrap();
        // Records compare by bits: a miss's word is a NaN.
        let bits = |r: &[[f32; 4]; 2]| r.map(|v| v.map(f32::to_bits));
        let same = (0..n)
            .filter(|&p| {
                carried.count[p] == want.count[p]
                    && carried.sum[p] == want.sum[p]
                    && bits(&new_records[p]) == bits(&new_twin[p])
            })
            .count();
        assert!(same * 100 >= n * 99, "reuse: {same} of {n} pixels agree");
        assert!(stats.carried.abs_diff(want_stats.carried) * 100 <= want_stats.carried);
        // And the twin's own records carry as many.
        let (_, cpu_stats) = reuse_cpu(&nv, &ov, &mut new_cpu, &old_cpu, &acc);
        assert!(cpu_stats.carried.abs_diff(want_stats.carried) * 100 <= want_stats.carried);
    }
}
