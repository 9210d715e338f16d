//! The path tracer: furnace tests with analytic answers on both backends, and the GPU kernel
//! against its CPU twin.

use glam::{Vec2, Vec3, Vec4};
use raygun::gpu::GpuContext;
use raygun::scene::{Camera, Environment, Material, Scene, Triangle};
use raygun::trace::accum::{Accumulation, luminance};
use raygun::trace::camera::RenderCamera;
use raygun::trace::gpu::{GpuAccum, GpuScene, TraceKernel, TraceRun};
use raygun::trace::pack::PackedScene;
use raygun::trace::path::{TraceSettings, render_cpu};

/// A pure Lambertian reflector (KHR_materials_specular factor 0) of albedo `rho`.
fn lambert(rho: f32, emission: Vec3) -> Material {
    Material {
        name: "lambert".into(),
        base_color: Vec4::new(rho, rho, rho, 1.0),
        base_color_texture: None,
        metallic: 0.0,
        roughness: 1.0,
        specular: 0.0,
        emission,
        double_sided: true,
    }
}

fn flat(p: [Vec3; 3], material: u32) -> Triangle {
    let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
    Triangle {
        p,
        n: [n; 3],
        uv: [Vec2::ZERO; 3],
        material,
    }
}

/// An icosahedron of circumradius `r` at `c` with outward faces: convex, so a ray leaving a
/// face never meets the object again.
fn icosahedron(c: Vec3, r: f32, material: u32) -> Vec<Triangle> {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let v: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| c + Vec3::new(x, y, z).normalize() * r)
    .collect();
    let f = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    f.iter()
        .map(|t| {
            let mut tri = flat([v[t[0]], v[t[1]], v[t[2]]], material);
            if tri.n[0].dot(v[t[0]] - c) < 0.0 {
                tri = flat([v[t[0]], v[t[2]], v[t[1]]], material);
            }
            tri
        })
        .collect()
}

/// The inside of a sphere: an icosahedron subdivided `levels` times, faces pointing inwards.
fn sphere_inside(c: Vec3, r: f32, levels: u32, material: u32) -> Vec<Triangle> {
    let mut faces: Vec<[Vec3; 3]> = icosahedron(Vec3::ZERO, 1.0, 0)
        .iter()
        .map(|t| t.p)
        .collect();
    for _ in 0..levels {
        faces = faces
            .iter()
            .flat_map(|&[a, b, d]| {
                let (ab, bd, da) = (
                    (a + b).normalize(),
                    (b + d).normalize(),
                    (d + a).normalize(),
                );
                [[a, ab, da], [ab, b, bd], [da, bd, d], [ab, bd, da]]
            })
            .collect();
    }
    faces
        .iter()
        .map(|f| flat([c + f[0] * r, c + f[2] * r, c + f[1] * r], material))
        .collect()
}

/// The inside of an axis-aligned box (faces pointing inwards).
fn box_inside(lo: Vec3, hi: Vec3, material: u32) -> Vec<Triangle> {
    let c =
        |x: usize, y: usize, z: usize| Vec3::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z]);
    let quads = [
        [c(0, 0, 0), c(1, 0, 0), c(1, 1, 0), c(0, 1, 0)],
        [c(0, 0, 1), c(0, 1, 1), c(1, 1, 1), c(1, 0, 1)],
        [c(0, 0, 0), c(0, 1, 0), c(0, 1, 1), c(0, 0, 1)],
        [c(1, 0, 0), c(1, 0, 1), c(1, 1, 1), c(1, 1, 0)],
        [c(0, 0, 0), c(0, 0, 1), c(1, 0, 1), c(1, 0, 0)],
        [c(0, 1, 0), c(1, 1, 0), c(1, 1, 1), c(0, 1, 1)],
    ];
    let centre = (lo + hi) * 0.5;
    quads
        .iter()
        .flat_map(|q| {
            let mut a = flat([q[0], q[1], q[2]], material);
            let mut b = flat([q[0], q[2], q[3]], material);
            if a.n[0].dot(centre - q[0]) < 0.0 {
                a = flat([q[0], q[2], q[1]], material);
                b = flat([q[0], q[3], q[2]], material);
            }
            [a, b]
        })
        .collect()
}

fn camera(position: Vec3, target: Vec3, yfov_deg: f32) -> Camera {
    Camera {
        name: "test".into(),
        position,
        forward: (target - position).normalize(),
        up: Vec3::Y,
        yfov: yfov_deg.to_radians(),
    }
}

fn settings(scene: &Scene, w: u32, h: u32, seed: u32, max_depth: u32) -> TraceSettings {
    TraceSettings {
        width: w,
        height: h,
        seed,
        max_depth,
        camera: RenderCamera::choose(scene, None, w, h).unwrap(),
    }
}

fn render_gpu(ctx: &GpuContext, scene: &Scene, s: &TraceSettings, spp: u32) -> Accumulation {
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

fn render_on_cpu(scene: &Scene, s: &TraceSettings, spp: u32) -> Accumulation {
    let packed = PackedScene::new(scene);
    let mut acc = Accumulation::new(s.width, s.height);
    for _ in 0..spp {
        render_cpu(&packed, s, &mut acc, None);
    }
    acc
}

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

fn material(name: &str, rgb: Vec3, metallic: f32, roughness: f32, emission: Vec3) -> Material {
    Material {
        name: name.into(),
        base_color: rgb.extend(1.0),
        base_color_texture: None,
        metallic,
        roughness,
        specular: 1.0,
        emission,
        double_sided: true,
    }
}

/// A Cornell-like room built here (open front, a ceiling light, an environment, a diffuse
/// block and a glossy metal icosahedron) so the twin test covers both BSDF lobes, both light
/// kinds and MIS.
fn twin_scene() -> Scene {
    let mut tris = Vec::new();
    // Room interior without its front (+Z) face: five walls, 10 triangles.
    let room = box_inside(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0), 0);
    for (k, t) in room.into_iter().enumerate() {
        let face = k / 2;
        if face == 1 {
            continue; // the open front
        }
        let m = match face {
            2 => 1, // left, red
            3 => 2, // right, green
            _ => 0,
        };
        tris.push(Triangle { material: m, ..t });
    }
    // Ceiling light, facing down.
    let (a, b, c, d) = (
        Vec3::new(-0.3, 1.99, -0.3),
        Vec3::new(0.3, 1.99, -0.3),
        Vec3::new(0.3, 1.99, 0.3),
        Vec3::new(-0.3, 1.99, 0.3),
    );
    tris.push(flat([a, b, c], 3));
    tris.push(flat([a, c, d], 3));
    // A diffuse block (its outside) and a metal icosahedron.
    for t in box_inside(Vec3::new(-0.7, 0.0, -0.6), Vec3::new(-0.1, 1.2, 0.0), 0) {
        tris.push(flat([t.p[0], t.p[2], t.p[1]], 0));
    }
    tris.extend(icosahedron(Vec3::new(0.45, 0.4, 0.2), 0.4, 4));
    Scene {
        triangles: tris,
        materials: vec![
            material("white", Vec3::splat(0.73), 0.0, 1.0, Vec3::ZERO),
            material("red", Vec3::new(0.65, 0.05, 0.05), 0.0, 1.0, Vec3::ZERO),
            material("green", Vec3::new(0.12, 0.45, 0.15), 0.0, 1.0, Vec3::ZERO),
            // One-sided, as a ceiling lamp is: the twins must agree on that path too.
            Material {
                double_sided: false,
                ..material(
                    "light",
                    Vec3::splat(0.78),
                    0.0,
                    1.0,
                    Vec3::new(17.0, 12.0, 4.0),
                )
            },
            material("gold", Vec3::new(1.0, 0.77, 0.34), 1.0, 0.3, Vec3::ZERO),
        ],
        cameras: vec![camera(
            Vec3::new(0.0, 1.0, 3.4),
            Vec3::new(0.0, 1.0, 0.0),
            40.0,
        )],
        environment: Environment::Constant(Vec3::splat(0.5)),
        ..Default::default()
    }
}

/// Welch Z-test of two independent renders' mean luminance, per 2 × 2 block (pooled so each
/// mean rests on 4 × spp samples). |z| < 5 per block: two-sided p = 5.7e-7 each, under 1e-3
/// family-wise over the blocks (Bonferroni).
fn renders_agree(a: &Accumulation, b: &Accumulation, label: &str) -> Result<(), String> {
    let (a, b) = (a.pooled(2), b.pooled(2));
    for i in 0..a.count.len() {
        let (ma, mb) = (luminance(a.mean(i)), luminance(b.mean(i)));
        let v = a.luminance_variance_of_mean(i).unwrap() + b.luminance_variance_of_mean(i).unwrap();
        let z = (ma - mb) / v.sqrt().max(1e-6);
        if z.is_nan() || z.abs() >= 5.0 {
            return Err(format!("{label}: block {i}: means {ma} vs {mb}, z = {z}"));
        }
    }
    Ok(())
}

#[test]
fn gpu_and_cpu_twin_converge_to_the_same_image() {
    let ctx = GpuContext::for_tests();
    let scene = twin_scene();
    let spp = 64;
    let cpu = render_on_cpu(&scene, &settings(&scene, 32, 32, 11, 8), spp);
    let gpu = render_gpu(&ctx, &scene, &settings(&scene, 32, 32, 12, 8), spp);
    renders_agree(&gpu, &cpu, "GPU (seed 12) vs CPU (seed 11)").unwrap();
    // The test has power: a 10 % brighter image is told apart.
    let mut brighter = cpu.clone();
    for s in &mut brighter.sum {
        for v in &mut s[..3] {
            *v *= 1.1;
        }
        s[3] *= 1.21;
    }
    assert!(renders_agree(&gpu, &brighter, "GPU vs CPU × 1.1").is_err());
    // Nothing non-finite, and the room is lit.
    assert!(gpu.sum.iter().all(|s| s.iter().all(|v| v.is_finite())));
    assert!(gpu.mean_image().iter().map(|c| luminance(*c)).sum::<f32>() > 0.0);
}

/// With the same seed both backends trace the same paths: most pixels' first samples agree to
/// float rounding (a few paths diverge where rounding flips a Russian-roulette or lobe choice).
#[test]
fn same_seed_gives_the_same_samples_on_both_backends() {
    let ctx = GpuContext::for_tests();
    let scene = twin_scene();
    let s = settings(&scene, 32, 32, 5, 8);
    let cpu = render_on_cpu(&scene, &s, 1);
    let gpu = render_gpu(&ctx, &scene, &s, 1);
    let close = (0..cpu.count.len())
        .filter(|&i| {
            let (a, b) = (cpu.mean(i), gpu.mean(i));
            (a - b).abs().max_element() <= 1e-3 * a.abs().max_element().max(1.0)
        })
        .count();
    let share = close as f64 / cpu.count.len() as f64;
    assert!(
        share >= 0.95,
        "only {:.1} % of the pixels agree",
        100.0 * share
    );
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

/// Textures, many materials and a 3 900-triangle BVH: the small city agrees on both backends,
/// under a non-uniform environment map with a sun.
#[test]
fn gpu_and_cpu_agree_on_the_textured_city_under_an_environment_map() {
    use raygun::scene::EnvironmentMap;
    let mut scene = Scene::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/scenes/city-small.glb"
    ))
    .unwrap();
    assert!(!scene.textures.is_empty(), "the small city has textures");
    let (w, h) = (32u32, 16u32);
    scene.environment = Environment::Map(EnvironmentMap {
        name: "sun".into(),
        width: w,
        height: h,
        texels: (0..w * h)
            .map(|i| {
                if i == 3 * w + 20 {
                    Vec3::splat(300.0)
                } else {
                    Vec3::new(0.3, 0.4, 0.6)
                }
            })
            .collect(),
    });
    let ctx = GpuContext::for_tests();
    let cpu = render_on_cpu(&scene, &settings(&scene, 32, 32, 21, 5), 48);
    let gpu = render_gpu(&ctx, &scene, &settings(&scene, 32, 32, 22, 5), 48);
    renders_agree(&gpu, &cpu, "city: GPU (seed 22) vs CPU (seed 21)").unwrap();
    let same = render_gpu(&ctx, &scene, &settings(&scene, 32, 32, 21, 5), 1);
    let cpu1 = render_on_cpu(&scene, &settings(&scene, 32, 32, 21, 5), 1);
    let close = (0..cpu1.count.len())
        .filter(|&i| {
            (cpu1.mean(i) - same.mean(i)).abs().max_element()
                <= 1e-3 * cpu1.mean(i).max_element().max(1.0)
        })
        .count();
    assert!(
        close * 100 >= 95 * cpu1.count.len(),
        "same seed: {close} of {} pixels agree",
        cpu1.count.len()
    );
}

/// The paper's scene itself: the generated Cornell box (open front, environment light) and its
/// ceiling-light variant converge to the same image on both backends.
#[test]
fn gpu_and_cpu_agree_on_the_cornell_box() {
    let ctx = GpuContext::for_tests();
    for file in ["cornell.glb", "cornell-light.glb"] {
        let path = format!("{}/tests/data/scenes/{file}", env!("CARGO_MANIFEST_DIR"));
        let scene = Scene::load(&path).unwrap();
        let cpu = render_on_cpu(&scene, &settings(&scene, 32, 32, 31, 8), 64);
        let gpu = render_gpu(&ctx, &scene, &settings(&scene, 32, 32, 32, 8), 64);
        renders_agree(&gpu, &cpu, &format!("{file}: GPU vs CPU")).unwrap();
        assert!(gpu.sum.iter().all(|s| s.iter().all(|v| v.is_finite())));
    }
}
