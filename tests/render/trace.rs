//! The path tracer: furnace tests and other analytic answers on both backends (the GPU kernel
//! against its CPU twin is in tests/twins/trace.rs).

use crate::render;
use crate::scenes;

use glam::{Vec2, Vec3};
use raygun::gpu::GpuContext;
use raygun::scene::{Environment, Material, Scene, Triangle};
use raygun::trace::accum::{Accumulation, luminance};
use raygun::trace::gpu::{GpuAccum, GpuScene, TraceKernel, TraceRun};
use raygun::trace::pack::PackedScene;
use raygun::trace::path::{TraceSettings, render_cpu};
use render::{render_gpu, render_on_cpu, renders_agree, settings};
use scenes::{camera, flat, icosahedron, lambert, sphere_inside, twin_scene};

/// Checks every pixel's mean luminance against `expected(i)`: the whole image's mean error
/// by a Z-test (|z| < 5 with the standard error from the pixels' own sample variances), and
/// each pixel with a Bonferroni-corrected bound (|z| < 5.5, two-sided p ≈ 4e-8 per pixel,
/// far below 1e-3 / pixel count).
fn assert_converges_to(acc: &Accumulation, expected: impl Fn(usize) -> f32, label: &str) {
    if let Err(e) = converges_to(acc, expected, label) {
        panic!("{e}");
    }
}

fn converges_to(
    acc: &Accumulation,
    expected: impl Fn(usize) -> f32,
    label: &str,
) -> Result<(), String> {
    let (mut err_sum, mut var_sum, mut n) = (0f64, 0f64, 0usize);
    for i in 0..acc.count.len() {
        if acc.count[i] < 2 {
            return Err(format!("{label}: pixel {i} has {} samples", acc.count[i]));
        }
        let m = f64::from(luminance(acc.mean(i)));
        if !m.is_finite() {
            return Err(format!("{label}: pixel {i} is not finite"));
        }
        let v = f64::from(acc.luminance_variance_of_mean(i).unwrap());
        let e = f64::from(expected(i));
        let z = (m - e) / v.sqrt().max(1e-6);
        if z.abs() >= 5.5 {
            return Err(format!(
                "{label}: pixel {i} mean {m}, expected {e}, z = {z}"
            ));
        }
        err_sum += m - e;
        var_sum += v;
        n += 1;
    }
    let z = err_sum / var_sum.sqrt().max(1e-9);
    if z.abs() >= 5.0 {
        return Err(format!(
            "{label}: image mean error {} (z = {z})",
            err_sum / n as f64
        ));
    }
    Ok(())
}

fn furnace_scene(rho: f32) -> Scene {
    Scene {
        triangles: icosahedron(Vec3::ZERO, 1.0, 0),
        materials: vec![lambert(rho, Vec3::ZERO)],
        cameras: vec![camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 40.0)],
        environment: Environment::Constant(Vec3::ONE),
        ..Default::default()
    }
}

fn pure_pixels(scene: &Scene, s: &TraceSettings) -> (Vec<bool>, Vec<bool>) {
    let packed = PackedScene::new(scene);
    let corners = [
        (0.0, 0.0),
        (0.999, 0.0),
        (0.0, 0.999),
        (0.999, 0.999),
        (0.5, 0.5),
    ];
    let mut object = Vec::new();
    let mut sky = Vec::new();
    for p in 0..s.width * s.height {
        let (x, y) = ((p % s.width) as f32, (p / s.width) as f32);
        let hits: Vec<bool> = corners
            .iter()
            .map(|&(dx, dy)| {
                let d = s.camera.direction(x + dx, y + dy, s.width, s.height);
                packed
                    .bvh
                    .closest_hit(s.camera.position, d, f32::INFINITY)
                    .is_some()
            })
            .collect();
        object.push(hits.iter().all(|&h| h));
        sky.push(hits.iter().all(|&h| !h));
    }
    (object, sky)
}

/// The furnace check passes for the true albedo and fails for one 5 % off (the test has power).
fn furnace(acc: &Accumulation, scene: &Scene, s: &TraceSettings, rho: f32, label: &str) {
    furnace_against(acc, scene, s, rho, label).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        furnace_against(acc, scene, s, rho * 0.95, label).is_err(),
        "{label}: a 5 % albedo error must be detected"
    );
}

fn furnace_against(
    acc: &Accumulation,
    scene: &Scene,
    s: &TraceSettings,
    rho: f32,
    label: &str,
) -> Result<(), String> {
    let (object, sky) = pure_pixels(scene, s);
    assert!(
        object.iter().filter(|&&o| o).count() > 50,
        "the object must be seen"
    );
    let mut kept = Accumulation::new(0, 0);
    let mut expected = Vec::new();
    for i in 0..acc.count.len() {
        if object[i] || sky[i] {
            kept.sum.push(acc.sum[i]);
            kept.count.push(acc.count[i]);
            expected.push(if object[i] { rho } else { 1.0 });
        }
    }
    converges_to(&kept, |i| expected[i], label)
}

#[test]
fn furnace_cpu_albedo_one_and_half() {
    for rho in [1.0, 0.5] {
        let scene = furnace_scene(rho);
        let s = settings(&scene, 48, 48, 1, 4);
        let acc = render_on_cpu(&scene, &s, 64);
        furnace(&acc, &scene, &s, rho, &format!("CPU furnace, albedo {rho}"));
    }
}

#[test]
fn furnace_gpu_albedo_one_and_half() {
    let ctx = GpuContext::for_tests();
    for rho in [1.0, 0.5] {
        let scene = furnace_scene(rho);
        let s = settings(&scene, 48, 48, 1, 4);
        let acc = render_gpu(&ctx, &scene, &s, 64);
        furnace(&acc, &scene, &s, rho, &format!("GPU furnace, albedo {rho}"));
    }
}

/// A closed room whose walls emit Le and reflect with albedo ρ, seen from inside: every point
/// sees the same radiance Le/(1 − ρ) (the Neumann series Le Σ ρᵏ; 64 bounces leave 2⁻⁶⁴ of
/// it). Pixels are pooled into 8 × 8 blocks (4096 samples each) before the Z-test: with
/// Russian roulette the per-path values are strongly skewed (a rare long path carries many
/// emitter contributions), and 64 samples of one pixel underestimate the variance. Exercises
/// emitter hits, next-event estimation with MIS, Russian roulette and a camera
/// inside geometry. The room is a finely tessellated sphere, not a box: next-event estimation
/// from points near a concave edge has an infinite-variance (1/r²) estimator, so in a box the
/// pixels' sample variances are unreliable for a Z-test; on a sphere the kernel
/// cos θ cos θ' / r² is constant and the estimator well behaved.
fn glowing_room() -> Scene {
    Scene {
        triangles: sphere_inside(Vec3::new(0.0, 0.2, 0.3), 1.5, 3, 0),
        materials: vec![lambert(0.5, Vec3::splat(0.25))],
        cameras: vec![camera(
            Vec3::new(0.0, 0.25, 1.0),
            Vec3::new(0.0, 0.25, -1.0),
            30.0,
        )],
        environment: Environment::Constant(Vec3::ZERO),
        ..Default::default()
    }
}

#[test]
fn glowing_room_converges_to_the_neumann_series_on_both_backends() {
    let scene = glowing_room();
    let s = settings(&scene, 24, 24, 3, 64);
    let expected = 0.25 / (1.0 - 0.5);
    let cpu = render_on_cpu(&scene, &s, 64).pooled(8);
    assert_converges_to(&cpu, |_| expected, "CPU glowing room");
    assert!(converges_to(&cpu, |_| expected * 0.97, "CPU glowing room").is_err());
    let ctx = GpuContext::for_tests();
    let gpu = render_gpu(&ctx, &scene, &s, 64).pooled(8);
    assert_converges_to(&gpu, |_| expected, "GPU glowing room");
}

/// The glowing room with paths of at most `max_depth` vertices: the series stops at ρᴺ, the
/// last term coming from the last vertex's light sample alone (no BSDF ray follows it). A light
/// sample weighted by MIS there would lose the BSDF strategy's share of that term: at depth 1
/// the image would be darker than Le (1 + ρ). No Russian roulette at these depths.
#[test]
fn glowing_room_at_depths_one_to_three_converges_to_the_truncated_series() {
    let scene = glowing_room();
    let ctx = GpuContext::for_tests();
    let (le, rho) = (0.25f32, 0.5f32);
    for n in 1..=3u32 {
        let expected: f32 = (0..=n).map(|k| le * rho.powi(k as i32)).sum();
        let s = settings(&scene, 24, 24, 7 + n, n);
        let cpu = render_on_cpu(&scene, &s, 64).pooled(8);
        assert_converges_to(&cpu, |_| expected, &format!("CPU glowing room, depth {n}"));
        // Power: the next term's worth of error is told apart.
        let off = expected - le * rho.powi(n as i32) * 0.5;
        assert!(converges_to(&cpu, |_| off, "CPU, half the last term").is_err());
        let gpu = render_gpu(&ctx, &scene, &s, 64).pooled(8);
        assert_converges_to(&gpu, |_| expected, &format!("GPU glowing room, depth {n}"));
    }
}

/// A quad at z = 0 with its front towards −z, seen from z = +3 (from behind), in front of a
/// uniform environment; and a diffuse floor below a small quad lamp.
fn quad(z: f32, facing_camera: bool, material: u32) -> Vec<Triangle> {
    let (a, b, c, d) = (
        Vec3::new(-1.0, -1.0, z),
        Vec3::new(1.0, -1.0, z),
        Vec3::new(1.0, 1.0, z),
        Vec3::new(-1.0, 1.0, z),
    );
    // Counter-clockwise seen from +z: the front faces +z.
    if facing_camera {
        vec![flat([a, b, c], material), flat([a, c, d], material)]
    } else {
        vec![flat([a, c, b], material), flat([a, d, c], material)]
    }
}

#[test]
fn a_single_sided_emitter_seen_from_behind_is_not_there() {
    let ctx = GpuContext::for_tests();
    let lamp = |double_sided| Material {
        double_sided,
        ..lambert(0.5, Vec3::splat(5.0))
    };
    let scene = |double_sided| Scene {
        triangles: quad(0.0, false, 0),
        materials: vec![lamp(double_sided)],
        cameras: vec![camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 20.0)],
        environment: Environment::Constant(Vec3::splat(0.3)),
        ..Default::default()
    };
    // The camera sees only the quad's back: one-sided, it sees the environment through it,
    // exactly (every sample is the environment's radiance).
    let one = scene(false);
    let s = settings(&one, 16, 16, 5, 4);
    for (acc, label) in [
        (render_on_cpu(&one, &s, 16), "CPU"),
        (render_gpu(&ctx, &one, &s, 16), "GPU"),
    ] {
        let worst = acc
            .mean_image()
            .iter()
            .map(|c| (luminance(*c) - 0.3).abs())
            .fold(0.0, f32::max);
        assert!(worst < 1e-5, "{label}: one-sided lamp from behind: {worst}");
    }
    // Two-sided, it glows from the back as well.
    let two = scene(true);
    let acc = render_on_cpu(&two, &settings(&two, 16, 16, 5, 4), 8);
    assert!(luminance(acc.mean(8 * 16 + 8)) > 4.0);
}

#[test]
fn a_single_sided_lamp_lights_only_what_its_front_faces() {
    let ctx = GpuContext::for_tests();
    let floor = |m| {
        let (a, b, c, d) = (
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(2.0, 0.0, -2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(-2.0, 0.0, 2.0),
        );
        vec![flat([a, c, b], m), flat([a, d, c], m)]
    };
    // A 0.4 m lamp 1 m above the floor, its front up (away) or down (towards it).
    let lamp = |down: bool| -> Vec<Triangle> {
        let (a, b, c, d) = (
            Vec3::new(-0.2, 1.0, -0.2),
            Vec3::new(0.2, 1.0, -0.2),
            Vec3::new(0.2, 1.0, 0.2),
            Vec3::new(-0.2, 1.0, 0.2),
        );
        if down {
            vec![flat([a, b, c], 1), flat([a, c, d], 1)]
        } else {
            vec![flat([a, c, b], 1), flat([a, d, c], 1)]
        }
    };
    let scene = |down: bool, double_sided: bool| Scene {
        triangles: [floor(0), lamp(down)].concat(),
        materials: vec![
            lambert(0.5, Vec3::ZERO),
            Material {
                double_sided,
                ..lambert(0.0, Vec3::splat(10.0))
            },
        ],
        // Low over the floor, below the lamp: it sees the lamp's underside (its back when it
        // faces up) and the floor around it.
        cameras: vec![camera(
            Vec3::new(0.0, 0.6, 3.0),
            Vec3::new(0.0, 0.3, 0.0),
            40.0,
        )],
        environment: Environment::Constant(Vec3::ZERO),
        ..Default::default()
    };
    // Facing away, one-sided: nothing reaches the floor, exactly.
    let away = scene(false, false);
    let s = settings(&away, 16, 16, 9, 4);
    for (acc, label) in [
        (render_on_cpu(&away, &s, 16), "CPU"),
        (render_gpu(&ctx, &away, &s, 16), "GPU"),
    ] {
        assert!(
            acc.mean_image().iter().all(|c| *c == Vec3::ZERO),
            "{label}: light behind a one-sided lamp"
        );
    }
    // Facing down, one-sided lights the floor as a two-sided lamp does (the floor only sees its
    // front), and the two-sided lamp facing up lights it just the same.
    let down_one = render_on_cpu(&scene(true, false), &s, 64);
    let down_two = render_gpu(&ctx, &scene(true, true), &s, 64);
    let up_two = render_on_cpu(&scene(false, true), &settings(&away, 16, 16, 10, 4), 64);
    let lit: f32 = down_one.mean_image().iter().map(|c| luminance(*c)).sum();
    assert!(lit > 1.0, "the lamp facing down lights the floor: {lit}");
    renders_agree(
        &down_one,
        &down_two,
        "one-sided (CPU) vs two-sided (GPU), facing down",
    )
    .unwrap();
    renders_agree(
        &down_two,
        &up_two,
        "two-sided facing down (GPU) vs up (CPU)",
    )
    .unwrap();
}

/// Robustness: an empty scene shows the environment exactly; degenerate and NaN triangles
/// that reach the tracer give finite pixels; far from the origin (1e4 m) the furnace still
/// holds, so self-intersection is avoided at any magnitude.
#[test]
fn empty_degenerate_and_far_away_scenes_render_correctly_on_both_backends() {
    let ctx = GpuContext::for_tests();
    let sky = Vec3::new(0.25, 0.5, 1.0);
    let empty = Scene {
        environment: Environment::Constant(sky),
        ..Default::default()
    };
    let s = settings(&empty, 16, 8, 1, 4);
    for acc in [
        render_on_cpu(&empty, &s, 2),
        render_gpu(&ctx, &empty, &s, 2),
    ] {
        assert!(
            acc.mean_image().iter().all(|&c| c == sky),
            "an empty scene is the sky"
        );
    }

    let mut broken = furnace_scene(0.5);
    let p = Vec3::new(0.0, 0.0, 0.5);
    broken.triangles.push(Triangle {
        p: [p, p, p],
        ..broken.triangles[0]
    });
    broken.triangles.push(Triangle {
        p: [p, p + Vec3::X, p + 2.0 * Vec3::X],
        ..broken.triangles[0]
    });
    broken.triangles.push(Triangle {
        n: [Vec3::NAN; 3],
        uv: [Vec2::NAN; 3],
        ..broken.triangles[3]
    });
    let s = settings(&broken, 24, 24, 1, 4);
    for acc in [
        render_on_cpu(&broken, &s, 4),
        render_gpu(&ctx, &broken, &s, 4),
    ] {
        assert!(acc.sum.iter().all(|v| v.iter().all(|x| x.is_finite())));
    }

    let offset = Vec3::splat(1e4);
    let mut far = furnace_scene(0.5);
    for t in &mut far.triangles {
        for q in &mut t.p {
            *q += offset;
        }
    }
    far.cameras[0].position += offset;
    let s = settings(&far, 48, 48, 2, 4);
    furnace(
        &render_on_cpu(&far, &s, 64),
        &far,
        &s,
        0.5,
        "CPU furnace at 1e4 m",
    );
    furnace(
        &render_gpu(&ctx, &far, &s, 64),
        &far,
        &s,
        0.5,
        "GPU furnace at 1e4 m",
    );
}

/// List mode (the scheduler's path): only the listed pixels get a sample, launched by an
/// indirect dispatch, and they get the same first sample as the CPU twin's list render.
#[test]
fn list_mode_samples_exactly_the_listed_pixels() {
    use wgpu::util::DeviceExt;
    let ctx = GpuContext::for_tests();
    let scene = twin_scene();
    let s = settings(&scene, 40, 30, 9, 6);
    let list: Vec<u32> = (0..40 * 30).filter(|p| (p * 7919) % 5 < 2).collect();
    let n = list.len() as u32;
    let packed = PackedScene::new(&scene);
    let kernel = TraceKernel::new(&ctx);
    let gs = GpuScene::upload(&ctx, &kernel, &packed).unwrap();
    let acc = GpuAccum::new(&ctx, s.width, s.height).unwrap();
    let list_buf = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("test list"),
            contents: bytemuck::cast_slice(&list),
            usage: wgpu::BufferUsages::STORAGE,
        });
    let args = [n.div_ceil(64), 1, 1, n];
    let args_buf = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("test args"),
            contents: bytemuck::cast_slice(&args),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
        });
    let run = TraceRun::new(
        &ctx,
        &kernel,
        &packed,
        &s,
        &acc,
        Some((&list_buf, &args_buf)),
    );
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    acc.clear(&mut enc);
    run.record(&mut enc, &gs, None);
    ctx.queue.submit([enc.finish()]);
    let gpu = acc.read(&ctx).unwrap();
    let mut cpu = Accumulation::new(s.width, s.height);
    render_cpu(&packed, &s, &mut cpu, Some(&list));
    let listed: std::collections::HashSet<u32> = list.iter().copied().collect();
    let mut close = 0;
    for p in 0..40 * 30u32 {
        let i = p as usize;
        assert_eq!(gpu.count[i], u32::from(listed.contains(&p)), "pixel {p}");
        assert_eq!(cpu.count[i], gpu.count[i]);
        let (a, b) = (cpu.mean(i), gpu.mean(i));
        if (a - b).abs().max_element() <= 1e-3 * a.abs().max_element().max(1.0) {
            close += 1;
        }
    }
    assert!(
        close as f64 >= 0.95 * 1200.0,
        "{close} of 1200 pixels agree"
    );
}

/// An environment map whose texels are all 1 is the white furnace again: map sampling, its
/// density and the MIS weights must agree for the answer to be ρ.
#[test]
fn furnace_under_a_uniform_environment_map_on_both_backends() {
    use raygun::scene::EnvironmentMap;
    let mut scene = furnace_scene(0.5);
    scene.environment = Environment::Map(EnvironmentMap {
        name: "white".into(),
        width: 16,
        height: 8,
        texels: vec![Vec3::ONE; 128],
    });
    let s = settings(&scene, 48, 48, 4, 4);
    furnace(
        &render_on_cpu(&scene, &s, 64),
        &scene,
        &s,
        0.5,
        "CPU furnace, uniform map",
    );
    let ctx = GpuContext::for_tests();
    furnace(
        &render_gpu(&ctx, &scene, &s, 64),
        &scene,
        &s,
        0.5,
        "GPU furnace, uniform map",
    );
}
