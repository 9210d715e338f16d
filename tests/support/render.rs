//! Rendering a scene on either backend for the tests, and the statistical test of two
//! renders (tests/render/trace.rs, tests/scene/gltf_features.rs, tests/twins/trace.rs).

#![allow(dead_code)]

use raygun::gpu::GpuContext;
use raygun::scene::Scene;
use raygun::trace::accum::{Accumulation, luminance};
use raygun::trace::camera::RenderCamera;
use raygun::trace::gpu::{GpuAccum, GpuScene, TraceKernel, TraceRun};
use raygun::trace::pack::PackedScene;
use raygun::trace::path::{TraceSettings, render_cpu};

/// The bound on |z| of [`renders_agree`]'s per-block Welch test: two-sided p = 5.7e-7 per
/// block, under 1e-3 family-wise over the 256 blocks of a 32 × 32 image (Bonferroni).
pub const BLOCK_Z: f32 = 5.0;

/// Two backends' first samples with the same seed "agree" when every channel differs by at
/// most this share of the brighter channel (or 1e-3 absolute below 1): float rounding, as the
/// two compute the same operations in a different order (FMA contraction, `sqrt`/`pow`
/// implementations).
pub const SAME_SEED_REL: f32 = 1e-3;

pub fn settings(scene: &Scene, w: u32, h: u32, seed: u32, max_depth: u32) -> TraceSettings {
    TraceSettings {
        width: w,
        height: h,
        seed,
        max_depth,
        camera: RenderCamera::choose(scene, None, w, h).unwrap(),
    }
}

pub fn render_gpu(ctx: &GpuContext, scene: &Scene, s: &TraceSettings, spp: u32) -> Accumulation {
    let packed = PackedScene::new(scene);
    let kernel = TraceKernel::new(ctx);
    let gs = GpuScene::upload(ctx, &kernel, &packed).unwrap();
    let acc = GpuAccum::new(ctx, s.width, s.height).unwrap();
    let run = TraceRun::new(ctx, &kernel, &packed, s, &acc, None);
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    acc.clear(&mut enc);
    for _ in 0..spp {
        run.record(&mut enc, &gs, None);
    }
    ctx.queue.submit([enc.finish()]);
    acc.read(ctx).unwrap()
}

pub fn render_on_cpu(scene: &Scene, s: &TraceSettings, spp: u32) -> Accumulation {
    let packed = PackedScene::new(scene);
    let mut acc = Accumulation::new(s.width, s.height);
    for _ in 0..spp {
        render_cpu(&packed, s, &mut acc, None);
    }
    acc
}

/// Welch Z-test of two independent renders' mean luminance, per 2 × 2 block (pooled so each
/// mean rests on 4 × spp samples). |z| < [`BLOCK_Z`] per block: two-sided p = 5.7e-7 each, under 1e-3
/// family-wise over the blocks (Bonferroni).
pub fn renders_agree(a: &Accumulation, b: &Accumulation, label: &str) -> Result<(), String> {
    let (a, b) = (a.pooled(2), b.pooled(2));
    for i in 0..a.count.len() {
        let (ma, mb) = (luminance(a.mean(i)), luminance(b.mean(i)));
        let v = a.luminance_variance_of_mean(i).unwrap() + b.luminance_variance_of_mean(i).unwrap();
        let z = (ma - mb) / v.sqrt().max(1e-6);
        if z.is_nan() || z.abs() >= BLOCK_Z {
            return Err(format!("{label}: block {i}: means {ma} vs {mb}, z = {z}"));
        }
    }
    Ok(())
}

/// The share of pixels whose one-sample means agree to [`SAME_SEED_REL`] (see there).
pub fn same_seed_share(a: &Accumulation, b: &Accumulation) -> f64 {
    let close = (0..a.count.len())
        .filter(|&i| {
            (a.mean(i) - b.mean(i)).abs().max_element()
                <= SAME_SEED_REL * a.mean(i).abs().max_element().max(1.0)
        })
        .count();
    close as f64 / a.count.len() as f64
}
