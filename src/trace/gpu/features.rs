//! Dispatch of `shaders/trace/features.wgsl` ([`FeaturesKernel`]): the denoiser's feature
//! buffers ([`GpuFeatures`]) for the rows of one band, the GPU twin of
//! [`crate::trace::features::features_cpu`].

use wgpu::util::DeviceExt;

use super::params::wall_table_buffer;
use super::{FEATURES_WGSL, GpuScene, GpuTraceParams, TraceKernel, entry};
use crate::gpu::{Band, GpuContext, GpuError};
use crate::trace::features::{FEATURE_SEED, FeatureBuffers};
use crate::trace::pack::PackedScene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

/// Threads per workgroup of the features kernel (`@workgroup_size` in features.wgsl).
const FEATURES_WORKGROUP: u32 = 64;

/// Workgroups in one dimension of a dispatch at most (wgpu's default limit).
const MAX_GROUPS_X: u32 = 65_535;

/// Bytes a pixel of the feature buffers: albedo and normal/depth, a vec4 each.
pub const FEATURE_BYTES_PER_PIXEL: u64 = 32;

/// The scene arrays the features kernel reads (bindings of bind group 0: BVH nodes and
/// primitives, shading data, materials, textures, the environment map).
const SCENE_BINDINGS: [u32; 6] = [0, 1, 2, 3, 4, 7];

/// The scene arrays the primary-hit kernel reads (no environment: a miss records its
/// direction).
const HIT_SCENE_BINDINGS: [u32; 5] = [0, 1, 2, 3, 4];

/// What a features pass looks at: the scene (packed, and uploaded for `trace`, the trace
/// kernel) and the settings whose camera it sees through (their seed and depth are not used).
#[derive(Clone, Copy)]
pub struct FeatureInputs<'a> {
    pub trace: &'a TraceKernel,
    pub scene_gpu: &'a GpuScene,
    pub scene: &'a PackedScene,
    pub settings: &'a TraceSettings,
    /// The wall camera whose rays the features look along, when the frames trace through one.
    pub wall: Option<&'a WallCamera>,
}

/// The compiled features kernel.
#[derive(Clone)]
pub struct FeaturesKernel {
    pipeline: wgpu::ComputePipeline,
    /// `primary_hits`: motion reuse's primary-hit records ([`GpuHits`]).
    hits: wgpu::ComputePipeline,
}

/// Bytes a pixel of the primary-hit records (two vec4s, [`crate::trace::reuse`]).
pub const HIT_BYTES_PER_PIXEL: u64 = 32;

/// The primary-hit records of one band of rows: two vec4s a pixel, row-major from `band.row0`.
pub struct GpuHits {
    pub width: u32,
    pub band: Band,
    pub records: wgpu::Buffer,
}

impl GpuHits {
    /// A buffer for `width × band.rows` pixels; a clear error where it exceeds the adapter's
    /// binding limit.
    pub fn new(ctx: &GpuContext, width: u32, band: Band) -> Result<Self, GpuError> {
        let bytes = u64::from(width) * u64::from(band.rows) * HIT_BYTES_PER_PIXEL;
        ctx.check_binding("primary-hit records", bytes)?;
        Ok(Self {
            width,
            band,
            records: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("primary-hit records"),
                size: bytes.max(32),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        })
    }

    /// The records read back, one `[[f32; 4]; 2]` a pixel.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<[[f32; 4]; 2]>, GpuError> {
        let mut r: Vec<[[f32; 4]; 2]> = ctx.read_buffer(&self.records)?;
        r.truncate((self.width * self.band.rows) as usize);
        Ok(r)
    }
}

/// The feature buffers of one band of rows: `albedo` (`[r, g, b, 0]`) and `normal_depth`
/// (`[n.x, n.y, n.z, depth]`), `width × band.rows` vec4s each, row-major from `band.row0`.
pub struct GpuFeatures {
    pub width: u32,
    pub band: Band,
    pub albedo: wgpu::Buffer,
    pub normal_depth: wgpu::Buffer,
}

impl GpuFeatures {
    /// Buffers for `width × band.rows` pixels; a clear error where one exceeds the adapter's
    /// binding limit.
    pub fn new(ctx: &GpuContext, width: u32, band: Band) -> Result<Self, GpuError> {
        let bytes = u64::from(width) * u64::from(band.rows) * FEATURE_BYTES_PER_PIXEL / 2;
        ctx.check_binding("feature albedo", bytes)?;
        ctx.check_binding("feature normal/depth", bytes)?;
        let make = |label| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        Ok(Self {
            width,
            band,
            albedo: make("feature albedo"),
            normal_depth: make("feature normal/depth"),
        })
    }

    /// The buffers read back.
    pub fn read(&self, ctx: &GpuContext) -> Result<FeatureBuffers, GpuError> {
        let n = (self.width * self.band.rows) as usize;
        let mut a: Vec<[f32; 4]> = ctx.read_buffer(&self.albedo)?;
        let mut nd: Vec<[f32; 4]> = ctx.read_buffer(&self.normal_depth)?;
        a.truncate(n);
        nd.truncate(n);
        Ok(FeatureBuffers {
            albedo: a,
            normal_depth: nd,
        })
    }
}

impl FeaturesKernel {
    /// The kernel, compiled once a device.
    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        ctx.kept("features kernel", || {
            let module = ctx.shader_module("trace/features", FEATURES_WGSL);
            Self {
                pipeline: ctx.compute_pipeline_in(&module, "trace/features", "features"),
                hits: ctx.compute_pipeline_in(&module, "trace/primary_hits", "primary_hits"),
            }
        })
    }

    /// Records the features of `out`'s band as `inputs` see them.
    pub fn record(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        inputs: FeatureInputs<'_>,
        out: &GpuFeatures,
    ) {
        let outputs = [entry(7, &out.albedo), entry(8, &out.normal_depth)];
        let kernel = (&self.pipeline, "trace/features", &SCENE_BINDINGS[..]);
        Self::dispatch(ctx, enc, inputs, kernel, out.band, &outputs);
    }

    /// Records the primary-hit records of `out`'s band as `inputs` see them.
    pub fn record_hits(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        inputs: FeatureInputs<'_>,
        out: &GpuHits,
    ) {
        let outputs = [entry(9, &out.records)];
        let kernel = (&self.hits, "trace/primary_hits", &HIT_SCENE_BINDINGS[..]);
        Self::dispatch(ctx, enc, inputs, kernel, out.band, &outputs);
    }

    /// One thread a pixel of `band` in `pipeline` (with its label and the scene arrays it
    /// reads), writing `outputs`.
    fn dispatch(
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        inputs: FeatureInputs<'_>,
        (pipeline, label, scene_bindings): (&wgpu::ComputePipeline, &str, &[u32]),
        band: Band,
        outputs: &[wgpu::BindGroupEntry<'_>],
    ) {
        let FeatureInputs {
            trace,
            scene_gpu,
            scene,
            settings,
            wall,
        } = inputs;
        let mut params = GpuTraceParams::for_band(trace, scene, settings, wall, false, band);
        params.seed = FEATURE_SEED;
        let params = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("features params"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let wall_table = wall_table_buffer(ctx, "features wall tiles", wall);
        let scene_entries: Vec<_> = scene_bindings
            .iter()
            .map(|&b| entry(b, &scene_gpu.buffers[b as usize]))
            .collect();
        let scene_bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("features scene"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &scene_entries,
        });
        let mut entries = vec![entry(0, &params), entry(6, &wall_table)];
        entries.extend(outputs.iter().cloned());
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("features frame"),
            layout: &pipeline.get_bind_group_layout(1),
            entries: &entries,
        });
        let groups = (settings.width * band.rows).div_ceil(FEATURES_WORKGROUP);
        let gx = groups.clamp(1, MAX_GROUPS_X);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &scene_bind, &[]);
        pass.set_bind_group(1, &bind, &[]);
        pass.dispatch_workgroups(gx, groups.div_ceil(gx).max(1), 1);
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec4;

    use super::*;
    use crate::scene::{Material, MaterialExt, Scene};
    use crate::trace::camera::RenderCamera;
    use crate::trace::features::features_cpu;

    /// The lit Cornell box with its first material made a mirror and its second glass: the GPU kernel's
    /// features are the CPU twin's, pixel by pixel, in two bands.
    #[test]
    fn gpu_features_are_the_cpu_twins() {
        let ctx = GpuContext::for_tests();
        let plain = Scene::builtin("cornell-light").unwrap();
        let mut scene = plain.clone();
        // Make one material a mirror and another glass, so the chains are exercised.
        scene.materials[0] = Material {
            metallic: 1.0,
            roughness: 0.0,
            ..scene.materials[0].clone()
        };
        if scene.materials.len() > 1 {
            scene.material_ext = vec![MaterialExt::default(); scene.materials.len()];
            scene.material_ext[1].transmission = 1.0;
            scene.materials[1].roughness = 0.0;
            scene.materials[1].metallic = 0.0;
        }
        let packed = PackedScene::new(&scene);
        let (w, h) = (24u32, 18u32);
        let cam = RenderCamera::choose(&scene, None, w, h).unwrap();
        let s = TraceSettings {
            width: w,
            height: h,
            seed: 3,
            max_depth: 8,
            camera: cam,
        };
        let cpu = features_cpu(&packed, &s, None);
        // The test means something: most pixels hit, and the mirror and the glass change what
        // some pixels see (their chains are followed).
        let hits = cpu.normal_depth.iter().filter(|nd| nd[3] > 0.0).count();
        assert!(hits > (w * h / 2) as usize, "{hits} hits");
        let before = features_cpu(&PackedScene::new(&plain), &s, None);
        let changed = (0..(w * h) as usize)
            .filter(|&p| before.albedo[p] != cpu.albedo[p])
            .count();
        assert!(
            changed > 0,
            "the specular materials change no pixel's features"
        );
        let trace = TraceKernel::new(&ctx);
        let kernel = FeaturesKernel::new(&ctx);
        let gs = GpuScene::upload(&ctx, &trace, &packed).unwrap();
        let mut close = 0usize;
        for band in [Band { row0: 0, rows: 7 }, Band { row0: 7, rows: 11 }] {
            let out = GpuFeatures::new(&ctx, w, band).unwrap();
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            let inputs = FeatureInputs {
                trace: &trace,
                scene_gpu: &gs,
                scene: &packed,
                settings: &s,
                wall: None,
            };
            kernel.record(&ctx, &mut enc, inputs, &out);
            ctx.queue.submit([enc.finish()]);
            let got = out.read(&ctx).unwrap();
            let (a, nd) = (got.albedo, got.normal_depth);
            assert_eq!(a.len(), (w * band.rows) as usize);
            for (i, (a, nd)) in a.iter().zip(&nd).enumerate() {
                let p = (band.row0 * w) as usize + i;
                let (ca, cn) = (Vec4::from(cpu.albedo[p]), Vec4::from(cpu.normal_depth[p]));
                let (ga, gn) = (Vec4::from(*a), Vec4::from(*nd));
                let tol = 1e-3 * cn.w.abs().max(1.0);
                if (ca - ga).abs().max_element() <= 1e-3 && (cn - gn).abs().max_element() <= tol {
                    close += 1;
                }
            }
        }
        assert!(
            close as f64 >= 0.98 * f64::from(w * h),
            "{close} of {} pixels agree",
            w * h
        );
    }
}
