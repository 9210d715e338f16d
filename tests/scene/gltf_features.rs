//! glTF features beyond the core material (the materials and meshes exporters write), each in
//! a scene built in code with a known answer, on both backends (GPU against the CPU twin on one
//! scene using all of them: tests/twins/trace.rs).

use crate::gltf_scenes;
use crate::render;

use glam::{Vec2, Vec3, Vec4};
use gltf_scenes::{flat, material, ortho, rect, tex_ref, texture};
use raygun::gpu::GpuContext;
use raygun::scene::{
    AlphaMode, Camera, Environment, LightKind, Material, MaterialExt, PunctualLight, Scene,
    Triangle, VertexExtras,
};
use raygun::trace::accum::{Accumulation, luminance};
use raygun::trace::pack::PackedScene;
use raygun::trace::path::TraceSettings;
use render::{render_gpu, render_on_cpu, settings};

/// Both backends' renders, labelled.
fn both(scene: &Scene, s: &TraceSettings, spp: u32) -> Vec<(Accumulation, &'static str)> {
    let ctx = GpuContext::for_tests();
    vec![
        (render_on_cpu(scene, s, spp), "CPU"),
        (render_gpu(&ctx, scene, s, spp), "GPU"),
    ]
}

/// Z statistic of the mean luminance of `pixels` against `expected` (their pooled samples).
fn z_of(acc: &Accumulation, pixels: &[usize], expected: f64) -> f64 {
    let (mut m, mut v) = (0f64, 0f64);
    for &i in pixels {
        m += f64::from(luminance(acc.mean(i)));
        v += f64::from(acc.luminance_variance_of_mean(i).unwrap());
    }
    let n = pixels.len() as f64;
    (m / n - expected) / (v.sqrt() / n).max(1e-12)
}

/// The mean colour of `pixels`.
fn mean_rgb(acc: &Accumulation, pixels: &[usize]) -> Vec3 {
    pixels.iter().map(|&i| acc.mean(i)).sum::<Vec3>() / pixels.len() as f32
}

/// An emissive texture whose left half is white and right half black, on a black-based quad
/// (exporters write emissiveFactor 1 beside every emissive texture): the left half glows with
/// exactly the factor's radiance, the right half is black, and only the left triangles are
/// lights.
#[test]
fn an_emissive_texture_half_white_half_black_glows_on_one_half_only() {
    let lamp = |tris: &mut Vec<Triangle>, x0, x1| tris.extend(rect(x0, -1.0, x1, 1.0, 0.0, 0));
    let mut tris = Vec::new();
    lamp(&mut tris, -1.0, 0.0);
    lamp(&mut tris, 0.0, 1.0);
    // The halves carry their part of the texture's u range.
    for t in &mut tris {
        for (uv, p) in t.uv.iter_mut().zip(t.p) {
            uv.x = (p.x + 1.0) / 2.0;
        }
    }
    let scene = Scene {
        triangles: tris,
        materials: vec![material(Vec3::ZERO, 0.0, 1.0, 0.0, Vec3::splat(2.0))],
        material_ext: vec![MaterialExt {
            emissive_texture: tex_ref(0),
            ..Default::default()
        }],
        textures: vec![texture(
            "half",
            2,
            1,
            vec![[255, 255, 255, 255], [0, 0, 0, 255]],
            true,
        )],
        orthographic_cameras: vec![ortho(Vec3::new(0.0, 0.0, 2.0), 1.0)],
        environment: Environment::Constant(Vec3::ZERO),
        ..Default::default()
    };
    assert_eq!(
        scene.emissive_triangle_count(),
        2,
        "the black half is no lamp"
    );
    assert_eq!(PackedScene::new(&scene).light_count, 2);
    let s = settings(&scene, 16, 16, 1, 2);
    for (acc, label) in both(&scene, &s, 4) {
        for y in 0..16 {
            for x in 0..16 {
                let l = luminance(acc.mean(y * 16 + x));
                let want = if x < 8 { 2.0 } else { 0.0 };
                assert!(
                    (l - want).abs() < 1e-4,
                    "{label}: pixel ({x}, {y}) = {l}, want {want}"
                );
            }
        }
    }
}

/// A black cut-out quad (alphaMode MASK, cutoff 0.5) whose 4 × 1 alpha texture is opaque in
/// one column, in front of a lamp of radiance 3: the camera sees the lamp through exactly the
/// three transparent quarters; with BLEND and alpha 0.25 everywhere, 75 % of the light
/// passes (stochastic coverage).
#[test]
fn an_alpha_masked_quad_in_front_of_an_emitter_lets_exactly_the_unmasked_area_through() {
    let scene = |alpha: AlphaMode, texels: Vec<[u8; 4]>| Scene {
        triangles: [
            rect(-1.0, -1.0, 1.0, 1.0, 0.0, 0),
            rect(-2.0, -2.0, 2.0, 2.0, -1.0, 1),
        ]
        .concat(),
        materials: vec![
            Material {
                base_color_texture: Some(0),
                ..material(Vec3::ZERO, 0.0, 1.0, 0.0, Vec3::ZERO)
            },
            material(Vec3::ZERO, 0.0, 1.0, 0.0, Vec3::splat(3.0)),
        ],
        material_ext: vec![MaterialExt {
            alpha,
            ..Default::default()
        }],
        textures: vec![texture("alpha", 4, 1, texels, true)],
        orthographic_cameras: vec![ortho(Vec3::new(0.0, 0.0, 2.0), 1.0)],
        environment: Environment::Constant(Vec3::ZERO),
        ..Default::default()
    };
    let mask = scene(
        AlphaMode::Mask(0.5),
        vec![[0, 0, 0, 255], [0, 0, 0, 0], [0, 0, 0, 100], [0, 0, 0, 127]],
    );
    let s = settings(&mask, 16, 16, 3, 3);
    for (acc, label) in both(&mask, &s, 4) {
        let mean: f32 = acc.mean_image().iter().map(|c| luminance(*c)).sum::<f32>() / 256.0;
        assert!(
            (mean - 2.25).abs() < 1e-4,
            "{label}: mean {mean}, want 3 × 3/4"
        );
        for y in 0..16 {
            let l = luminance(acc.mean(y * 16 + 1));
            assert!(
                l.abs() < 1e-6,
                "{label}: the opaque column lets light through: {l}"
            );
        }
    }
    let blend = scene(AlphaMode::Blend, vec![[0, 0, 0, 64]; 4]);
    let alpha = 64.0 / 255.0;
    for (acc, label) in both(&blend, &s, 64) {
        let all: Vec<usize> = (0..256).collect();
        let z = z_of(&acc, &all, 3.0 * (1.0 - alpha));
        assert!(z.abs() < 5.0, "{label}: blended coverage z = {z}");
        assert!(
            z_of(&acc, &all, 3.0 * 0.72).abs() > 5.0,
            "{label}: the test has power"
        );
    }
}

/// The box from `lo` to `hi` turned by `turn` about the origin, of material 0, as a closed mesh
/// with outward faces (counter-clockwise seen from outside).
fn glass_box(lo: Vec3, hi: Vec3, turn: glam::Quat) -> Vec<Triangle> {
    let c = |x: usize, y: usize, z: usize| {
        turn * Vec3::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z])
    };
    let quads = [
        [c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)],
        [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)],
        [c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)],
        [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)],
        [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)],
        [c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)],
    ];
    quads
        .iter()
        .flat_map(|q| {
            [
                flat([q[0], q[1], q[2]], [Vec2::ZERO; 3], 0),
                flat([q[0], q[2], q[3]], [Vec2::ZERO; 3], 0),
            ]
        })
        .collect()
}

/// A smooth glass slab (4 × 4 m, 0.2 m thick, z from −0.2 to 0; a closed box with outward
/// faces) of index `ior` and KHR_materials_volume absorption σ, over a white emitter of
/// radiance 1 at z = −1, seen straight on by an orthographic camera; nothing else lights it.
fn slab_scene(ior: f32, absorption: Vec3) -> Scene {
    let (lo, hi) = (Vec3::new(-2.0, -2.0, -0.2), Vec3::new(2.0, 2.0, 0.0));
    let mut tris = glass_box(lo, hi, glam::Quat::IDENTITY);
    tris.extend(rect(-3.0, -3.0, 3.0, 3.0, -1.0, 1));
    let glass = MaterialExt {
        absorption,
        ..MaterialExt::default()
    };
    glass_before_lamp(tris, ior, glass, ortho(Vec3::new(0.0, 0.0, 1.0), 0.5))
}

/// `triangles` (material 0: smooth white glass of index `ior` with the rest of `glass`;
/// material 1: a lamp of radiance 1) seen by `camera` in a black world.
fn glass_before_lamp(
    triangles: Vec<Triangle>,
    ior: f32,
    glass: MaterialExt,
    camera: raygun::scene::OrthographicCamera,
) -> Scene {
    Scene {
        triangles,
        materials: vec![
            material(Vec3::ONE, 0.0, 0.0, 1.0, Vec3::ZERO),
            material(Vec3::ZERO, 0.0, 1.0, 0.0, Vec3::ONE),
        ],
        material_ext: vec![MaterialExt {
            transmission: 1.0,
            ior,
            ..glass
        }],
        orthographic_cameras: vec![camera],
        environment: Environment::Constant(Vec3::ZERO),
        ..Default::default()
    }
}

/// A smooth glass slab (a closed box) between the camera and a lamp of radiance 1 in a black
/// world: at normal incidence each face transmits 1 − F0 with F0 = ((ior − 1)/(ior + 1))²,
/// so the lamp is seen through it at (1 − F0)² (paths of three vertices: no light bouncing
/// inside the slab yet).
#[test]
fn a_smooth_glass_slab_transmits_one_minus_f_squared() {
    for ior in [1.5f32, 2.0] {
        let scene = slab_scene(ior, Vec3::ZERO);
        let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
        let expected = f64::from((1.0 - f0) * (1.0 - f0));
        let s = settings(&scene, 8, 8, 5, 3);
        let all: Vec<usize> = (0..64).collect();
        for (acc, label) in both(&scene, &s, 256) {
            let z = z_of(&acc, &all, expected);
            assert!(
                z.abs() < 5.0,
                "{label}, ior {ior}: z = {z} against {expected}"
            );
            let lum: f64 = all
                .iter()
                .map(|&i| f64::from(luminance(acc.mean(i))))
                .sum::<f64>()
                / 64.0;
            assert!(
                (lum - expected).abs() < 0.02,
                "{label}, ior {ior}: {lum} vs {expected}"
            );
            // Power: one interface's worth (1 − F0 alone) is told apart.
            assert!(z_of(&acc, &all, f64::from(1.0 - f0)).abs() > 5.0);
        }
    }
}

/// The slab filled with an absorbing medium (KHR_materials_volume): each crossing of its
/// thickness d keeps τ = exp(−σd) per channel, and the light reflected back and forth inside
/// crosses it again, so the slab transmits (1 − R)² τ / (1 − R² τ²) (the geometric series of
/// internal reflections, R = F0 at normal incidence). Here attenuationColor (0.25, 0.6, 0.9) at
/// attenuationDistance d, so τ is that colour.
#[test]
fn an_absorbing_glass_slab_transmits_its_attenuation_colour() {
    let (ior, d) = (1.5f32, 0.2f32);
    let colour = Vec3::new(0.25, 0.6, 0.9);
    let sigma = Vec3::new(-colour.x.ln(), -colour.y.ln(), -colour.z.ln()) / d;
    let scene = slab_scene(ior, sigma);
    let r = ((ior - 1.0) / (ior + 1.0)).powi(2);
    let through = |tau: f32| (1.0 - r).powi(2) * tau / (1.0 - r * r * tau * tau);
    let want = Vec3::new(through(colour.x), through(colour.y), through(colour.z));
    let clear = through(1.0);
    let s = settings(&scene, 8, 8, 7, 8);
    let all: Vec<usize> = (0..64).collect();
    for (acc, label) in both(&scene, &s, 256) {
        let z = z_of(&acc, &all, f64::from(luminance(want)));
        assert!(z.abs() < 5.0, "{label}: z = {z} against {want}");
        let mean = mean_rgb(&acc, &all);
        assert!(
            (mean - want).abs().max_element() < 0.01,
            "{label}: {mean} vs {want}"
        );
        // Power: the clear slab's transmission, and one crossing's absorption counted twice,
        // are told apart.
        assert!(z_of(&acc, &all, f64::from(clear)).abs() > 5.0, "{label}");
        let twice = Vec3::new(
            through(colour.x * colour.x),
            through(colour.y * colour.y),
            through(colour.z * colour.z),
        );
        assert!(
            z_of(&acc, &all, f64::from(luminance(twice))).abs() > 5.0,
            "{label}"
        );
    }
}

/// (1 − F0)² of a smooth slab of index `n` at normal incidence, F0 = ((n − 1)/(n + 1))².
fn through_slab(n: f32) -> f32 {
    let f0 = ((n - 1.0) / (n + 1.0)).powi(2);
    (1.0 - f0) * (1.0 - f0)
}

/// The dispersive slab (KHR_materials_dispersion, ior 2, dispersion 6 — Abbe number 3.3,
/// exaggerated so that one face's Fresnel tells the channels apart) before the lamp: a path
/// picks its channel at the front face and keeps it through the back, so each channel is
/// transmitted (1 − F0)² with F0 from its own index of refraction, on both backends; red and
/// blue are told apart from the undispersed slab's.
#[test]
fn a_dispersive_slab_transmits_each_channel_by_its_own_index() {
    use raygun::trace::shading::dispersed_ior;
    let (ior, dispersion) = (2.0f32, 6.0f32);
    let mut scene = slab_scene(ior, Vec3::ZERO);
    scene.material_ext[0].dispersion = dispersion;
    let want = Vec3::from_array([0, 1, 2].map(|c| through_slab(dispersed_ior(ior, dispersion, c))));
    let plain = through_slab(ior);
    let (pixels, spp) = (32 * 32usize, 256u32);
    let s = settings(&scene, 32, 32, 9, 3);
    for (acc, label) in both(&scene, &s, spp) {
        let mean = mean_rgb(&acc, &(0..pixels).collect::<Vec<_>>());
        // A sample's channel is 0, or its path's weight (1 here: smooth faces) times 3 where it
        // picked that channel: its variance is at most 3 × its mean.
        let sigma = want.map(|w| (3.0 * w / (pixels * spp as usize) as f32).sqrt());
        let z = (mean - want) / sigma;
        assert!(
            z.abs().max_element() < 5.0,
            "{label}: {mean} vs {want} (z {z})"
        );
        for c in [0, 2] {
            let z = (mean[c] - plain) / sigma[c];
            assert!(
                z.abs() > 5.0,
                "{label}: channel {c} {} is the undispersed {plain}",
                mean[c]
            );
        }
    }
}

/// A slab 2 thick tilted 50° about y (its faces 12 wide), of index `ior` and `dispersion`,
/// between an orthographic camera and a lamp that covers x > 0 behind it: the lamp's edge is
/// seen shifted sideways by t·sin θ·(1 − cos θ / √(n² − sin² θ)), 1.00 at n = 2.
fn tilted_slab_scene(ior: f32, dispersion: f32) -> Scene {
    let (lo, hi) = (Vec3::new(-6.0, -6.0, -1.0), Vec3::new(6.0, 6.0, 1.0));
    let mut tris = glass_box(lo, hi, glam::Quat::from_rotation_y(50f32.to_radians()));
    tris.extend(rect(0.0, -30.0, 30.0, 30.0, -9.0, 1));
    let glass = MaterialExt {
        dispersion,
        ..MaterialExt::default()
    };
    // 96 × 64 pixels over x ∈ [−1.5, 1.5]: a column is 1/32 wide.
    glass_before_lamp(tris, ior, glass, ortho(Vec3::new(0.0, 0.0, 9.0), 1.0))
}

/// Each channel of the dispersive tilted slab is the undispersed slab of that channel's index
/// of refraction — where the lamp's edge appears through it (the refraction) and how much
/// gets through (the Fresnel terms) — column by column on both backends (the channel picked at
/// the front face is kept through the back); the red and blue edges lie apart (1.5 columns),
/// and the blue is told apart from the undispersed one's.
#[test]
fn a_dispersive_slab_shifts_each_channel_by_its_own_index() {
    use raygun::trace::shading::dispersed_ior;
    let (ior, dispersion, spp) = (2.0f32, 6.0f32, 64u32);
    let (w, h) = (96usize, 64usize);
    let columns = |acc: &Accumulation, c: usize| -> Vec<f32> {
        (0..w)
            .map(|x| (0..h).map(|y| acc.mean(y * w + x)[c]).sum::<f32>() / h as f32)
            .collect()
    };
    let n = (h as u32 * spp) as f32;
    let scene = tilted_slab_scene(ior, dispersion);
    let s = settings(&scene, w as u32, h as u32, 13, 4);
    let dispersed = both(&scene, &s, spp);
    let mut plain = Vec::new();
    for c in 0..3 {
        let scene = tilted_slab_scene(dispersed_ior(ior, dispersion, c as u32), 0.0);
        let s = settings(&scene, w as u32, h as u32, 17 + c as u32, 4);
        plain.push(both(&scene, &s, spp));
    }
    // The largest |z| over the columns of channel c of `a` (a dispersive render when `three`:
    // a channel is 0 or 3 × its weight) against channel c of the undispersed `b`.
    let z_max = |a: &[f32], three: bool, b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(&x, &y)| {
                let var = (if three { 3.0 } else { 1.0 } * x + y) / n;
                ((x - y) / var.sqrt().max(1e-6)).abs()
            })
            .fold(0.0f32, f32::max)
    };
    for (k, (acc, label)) in dispersed.iter().enumerate() {
        for (c, plain) in plain.iter().enumerate() {
            let (got, want) = (columns(acc, c), columns(&plain[k].0, c));
            let z = z_max(&got, true, &want);
            assert!(z < 5.0, "{label}, channel {c}: z {z}: {got:?} vs {want:?}");
        }
        // Power: blue is not the undispersed slab's blue, and red's edge is not blue's.
        let blue = columns(acc, 2);
        let z = z_max(&blue, true, &columns(&plain[1][k].0, 2));
        assert!(z > 6.0, "{label}: blue is the undispersed slab's (z {z})");
        let (red, blue) = (columns(&plain[0][k].0, 0), columns(&plain[2][k].0, 2));
        let z = z_max(&red, false, &blue);
        assert!(z > 10.0, "{label}: red and blue edges coincide (z {z})");
    }
}

/// A leaf (KHR_materials_diffuse_transmission, a double-sided plane with no specular
/// reflection) before a lamp of radiance 1 that fills its far side, in a black world, seen from
/// the near side: it shows dt × its transmission colour (the lamp's light, Lambertian through
/// it), nothing of its base (nothing lights the near side), on both backends; without the
/// extension it is black.
#[test]
fn a_backlit_leaf_shows_its_diffuse_transmission() {
    let leaf = |dt: f32| {
        let mut tris = rect(-50.0, -50.0, 50.0, 50.0, 0.0, 0);
        tris.extend(rect(-500.0, -500.0, 500.0, 500.0, -0.05, 1));
        Scene {
            triangles: tris,
            materials: vec![
                material(Vec3::new(0.1, 0.9, 0.2), 0.0, 0.5, 0.0, Vec3::ZERO),
                material(Vec3::ZERO, 0.0, 1.0, 0.0, Vec3::ONE),
            ],
            material_ext: vec![MaterialExt {
                diffuse_transmission: dt,
                diffuse_transmission_color: Vec3::new(0.9, 0.6, 0.1),
                ..Default::default()
            }],
            orthographic_cameras: vec![ortho(Vec3::new(0.0, 0.0, 1.0), 0.5)],
            environment: Environment::Constant(Vec3::ZERO),
            ..Default::default()
        }
    };
    // The lamp fills the far hemisphere but for the cosine-weighted share beyond its edge
    // (tan θ = 500 / 0.05): 1 − 10⁻⁸.
    let s = |scene: &Scene| settings(scene, 8, 8, 21, 3);
    let all: Vec<usize> = (0..64).collect();
    for dt in [0.4f32, 1.0] {
        let scene = leaf(dt);
        let want = Vec3::new(0.9, 0.6, 0.1) * dt;
        for (acc, label) in both(&scene, &s(&scene), 256) {
            let z = z_of(&acc, &all, f64::from(luminance(want)));
            assert!(z.abs() < 5.0, "{label}, dt {dt}: z = {z} against {want}");
            let mean = mean_rgb(&acc, &all);
            assert!(
                (mean - want).abs().max_element() < 0.02,
                "{label}, dt {dt}: {mean} vs {want}"
            );
            // Power: the base's colour instead is told apart.
            let base = Vec3::new(0.1, 0.9, 0.2) * dt;
            assert!(
                z_of(&acc, &all, f64::from(luminance(base))).abs() > 5.0,
                "{label}"
            );
        }
    }
    let scene = leaf(0.0);
    for (acc, label) in both(&scene, &s(&scene), 16) {
        let mean = mean_rgb(&acc, &all);
        assert_eq!(
            mean,
            Vec3::ZERO,
            "{label}: an opaque leaf lets nothing through"
        );
    }
}

/// A white sheen (KHR_materials_sheen) over a black base, under a white sky, seen at an angle
/// θ: the plane reflects the sheen's directional albedo E(cos θ) — its integral over the
/// hemisphere, which raygun tabulates (`SHEEN_ALBEDO`; here at table nodes, where the table is
/// that integral to 0.5 %) — on both backends; the two angles are told apart.
#[test]
fn a_white_sheen_over_black_reflects_its_directional_albedo() {
    use raygun::trace::shading::{SHEEN_ALBEDO, SHEEN_MIN_ROUGHNESS, sheen_albedo};
    let r = SHEEN_MIN_ROUGHNESS + (1.0 - SHEEN_MIN_ROUGHNESS) * 12.0 / 31.0;
    let cosines = [19.0f32 / 63.0, 50.0 / 63.0];
    let e = cosines.map(|c| sheen_albedo(&SHEEN_ALBEDO, c, r));
    for (k, cos) in cosines.into_iter().enumerate() {
        // The plane z = 0 turned about x by θ: its normal (0, −sin θ, cos θ) meets the view
        // (+z, the orthographic camera looking down −z) at cos θ.
        let sin = (1.0 - cos * cos).sqrt();
        let turn = |p: Vec3| Vec3::new(p.x, p.y * cos, p.y * sin);
        let mut tris = rect(-2.0, -2.0, 2.0, 2.0, 0.0, 0);
        for t in &mut tris {
            *t = flat(t.p.map(turn), t.uv, 0);
        }
        let scene = Scene {
            triangles: tris,
            materials: vec![material(Vec3::ZERO, 0.0, 1.0, 0.0, Vec3::ZERO)],
            material_ext: vec![MaterialExt {
                sheen_color: Vec3::ONE,
                sheen_roughness: r,
                ..Default::default()
            }],
            orthographic_cameras: vec![ortho(Vec3::new(0.0, 0.0, 3.0), 0.5)],
            environment: Environment::Constant(Vec3::ONE),
            ..Default::default()
        };
        let s = settings(&scene, 8, 8, 9, 3);
        let all: Vec<usize> = (0..64).collect();
        for (acc, label) in both(&scene, &s, 256) {
            let want = f64::from(e[k]);
            let z = z_of(&acc, &all, want);
            let mean = all
                .iter()
                .map(|&i| f64::from(luminance(acc.mean(i))))
                .sum::<f64>()
                / 64.0;
            assert!(
                z.abs() < 5.0 || (mean - want).abs() < 0.005 * want,
                "{label}, cos θ {cos}: {mean} (z = {z}) against E = {want}"
            );
            assert!(
                (mean - want).abs() < 0.03 * want,
                "{label}, cos θ {cos}: {mean} vs {want}"
            );
            // Power: the other angle's albedo is told apart.
            assert!(z_of(&acc, &all, f64::from(e[1 - k])).abs() > 5.0, "{label}");
        }
    }
}

/// A point light of intensity I at height h over a Lambertian floor of albedo ρ: the floor's
/// radiance at distance d from the light is ρ/π · I h / d³ (inverse square × cosine); a spot
/// light equals it inside its inner cone and is dark outside its outer cone; a directional
/// light of irradiance E gives ρE/π everywhere.
#[test]
fn a_punctual_light_gives_inverse_square_irradiance_on_a_diffuse_plane() {
    let (rho, intensity, h) = (0.8f32, 5.0f32, 1.0f32);
    let floor = |kind: LightKind, direction: Vec3| Scene {
        triangles: rect(-2.0, -2.0, 2.0, 2.0, 0.0, 0),
        materials: vec![material(Vec3::splat(rho), 0.0, 1.0, 0.0, Vec3::ZERO)],
        lights: vec![PunctualLight {
            name: "lamp".into(),
            kind,
            position: Vec3::new(0.0, 0.0, h),
            direction,
            intensity: Vec3::splat(intensity),
        }],
        orthographic_cameras: vec![ortho(Vec3::new(0.0, 0.0, 3.0), 2.0)],
        environment: Environment::Constant(Vec3::ZERO),
        ..Default::default()
    };
    let (w, px) = (32usize, 4.0 / 32.0);
    let centre = |i: usize| {
        Vec2::new(
            -2.0 + ((i % w) as f32 + 0.5) * px,
            2.0 - ((i / w) as f32 + 0.5) * px,
        )
    };
    let point = floor(LightKind::Point, Vec3::NEG_Z);
    let s = settings(&point, 32, 32, 7, 1);
    let expected = |i: usize| {
        let d = (centre(i).length_squared() + h * h).sqrt();
        rho / std::f32::consts::PI * intensity * h / (d * d * d)
    };
    // The mean over a pixel's footprint against the value at its centre: the pixel jitter
    // is the only randomness (the light sample is exact), so the bound is 5 standard errors of
    // the pixel mean plus the footprint's curvature (< 0.1 %).
    let close = |acc: &Accumulation, i: usize, want: f32| {
        let got = luminance(acc.mean(i));
        let se = acc.luminance_variance_of_mean(i).unwrap().sqrt();
        ((got - want).abs() <= 5.0 * se + 1e-3 * want, got)
    };
    for (acc, label) in both(&point, &s, 32) {
        for i in 0..w * w {
            let (ok, got) = close(&acc, i, expected(i));
            assert!(ok, "{label}: pixel {i}: {got} vs {}", expected(i));
        }
    }
    let spot = floor(
        LightKind::Spot {
            inner: 30f32.to_radians(),
            outer: 40f32.to_radians(),
        },
        Vec3::NEG_Z,
    );
    for (acc, label) in both(&spot, &s, 32) {
        for i in 0..w * w {
            let angle = centre(i).length().atan2(h).to_degrees();
            let got = luminance(acc.mean(i));
            if angle < 27.0 {
                assert!(
                    close(&acc, i, expected(i)).0,
                    "{label}: in the cone, pixel {i}"
                );
            } else if angle > 43.0 {
                assert_eq!(got, 0.0, "{label}: outside the cone, pixel {i}");
            }
        }
    }
    // A directional light 60° from the zenith: E cos 60°.
    let dir = Vec3::new(60f32.to_radians().sin(), 0.0, -60f32.to_radians().cos());
    let sun = floor(LightKind::Directional, dir);
    for (acc, label) in both(&sun, &s, 4) {
        let want = rho / std::f32::consts::PI * intensity * 0.5;
        for i in 0..w * w {
            let got = luminance(acc.mean(i));
            assert!(
                (got / want - 1.0).abs() < 1e-4,
                "{label}: sun, pixel {i}: {got}"
            );
        }
    }
}

/// The highlight scenes' height of the pinhole above the plane, their image width and the
/// normal maps' tilt (towards +x).
const FLASH_HEIGHT: f32 = 2.0;
const FLASH_WIDTH: u32 = 64;
const FLASH_TILT_DEG: f32 = 10.0;

/// A 4 m square in the plane z = 0 of material `m` (with `ext`) under a pinhole
/// [`FLASH_HEIGHT`] above its centre looking down (60° field of view) and a point light at the
/// pinhole; tangents along +x, and texture 0 a normal-map texel that tilts a normal by
/// [`FLASH_TILT_DEG`] towards +x.
fn flash_scene(m: Material, ext: MaterialExt) -> Scene {
    let texel = |v: f32| ((v + 1.0) * 0.5 * 255.0).round() as u8;
    let (sin, cos) = FLASH_TILT_DEG.to_radians().sin_cos();
    let c = FLASH_HEIGHT;
    let tris = rect(-2.0, -2.0, 2.0, 2.0, 0.0, 0);
    let n = tris.len();
    Scene {
        triangles: tris,
        materials: vec![m],
        material_ext: vec![ext],
        vertex_extras: vec![
            VertexExtras {
                tangent: [Vec4::new(1.0, 0.0, 0.0, 1.0); 3],
                ..Default::default()
            };
            n
        ],
        textures: vec![texture(
            "tilt",
            1,
            1,
            vec![[texel(sin), texel(0.0), texel(cos), 255]],
            false,
        )],
        cameras: vec![Camera {
            name: "top".into(),
            position: Vec3::new(0.0, 0.0, c),
            forward: Vec3::NEG_Z,
            up: Vec3::Y,
            yfov: 60f32.to_radians(),
        }],
        lights: vec![PunctualLight {
            name: "flash".into(),
            kind: LightKind::Point,
            position: Vec3::new(0.0, 0.0, c),
            direction: Vec3::NEG_Z,
            intensity: Vec3::ONE,
        }],
        environment: Environment::Constant(Vec3::ZERO),
        ..Default::default()
    }
}

/// Where a [`flash_scene`]'s highlight should be: the column of the plane's x = 0 (`tilted`
/// false: under the camera) or of x = −c·tan(tilt) (where a normal tilted by the maps points at
/// the camera).
fn flash_column(tilted: bool) -> f32 {
    let c = FLASH_HEIGHT;
    let x = if tilted {
        -c * FLASH_TILT_DEG.to_radians().tan()
    } else {
        0.0
    };
    let half_width = c * 30f32.to_radians().tan();
    (x / half_width + 1.0) * 0.5 * FLASH_WIDTH as f32
}

/// Renders a [`flash_scene`] on both backends and checks that the middle row's brightest pixel
/// is lit and within 1.5 columns of `want`.
fn assert_flash_highlight(scene: &Scene, want: f32, what: &str) {
    let w = FLASH_WIDTH as usize;
    let s = settings(scene, FLASH_WIDTH, FLASH_WIDTH, 2, 1);
    for (acc, label) in both(scene, &s, 8) {
        let row = w / 2;
        let at = |x: usize| luminance(acc.mean(row * w + x));
        let brightest = (0..w).max_by(|&a, &b| at(a).total_cmp(&at(b))).unwrap();
        assert!(at(brightest) > 0.0, "{label}, {what}: no highlight");
        let got = brightest as f32 + 0.5;
        assert!(
            (got - want).abs() <= 1.5,
            "{label}, {what}: highlight at column {got}, predicted {want}"
        );
    }
}

/// A glossy metal plane whose normal map tilts every shading normal by 10° towards +x, lit
/// by a point light at the pinhole: the highlight sits where the tilted normal points at the
/// camera, x = −c·tan 10° (c the camera's height), not under the camera.
#[test]
fn a_normal_map_that_tilts_the_normal_moves_the_highlight_to_the_predicted_pixel() {
    for mapped in [false, true] {
        let ext = MaterialExt {
            normal_texture: if mapped { tex_ref(0) } else { None },
            ..Default::default()
        };
        let scene = flash_scene(material(Vec3::ONE, 1.0, 0.1, 1.0, Vec3::ZERO), ext);
        assert_flash_highlight(&scene, flash_column(mapped), &format!("mapped {mapped}"));
    }
}

/// An orthographic camera: a 1 m square covers the same pixels from 2 m and from 20 m.
/// A scene built in code with a normal map and an anisotropy but no vertex extras (no
/// tangents: `Scene` is public data) renders on both backends — each surface takes a frame of
/// its own about its normal — instead of reading tangents that are not there.
#[test]
fn maps_that_need_tangents_render_without_them() {
    let m = material(Vec3::ONE, 1.0, 0.3, 1.0, Vec3::ZERO);
    let ext = MaterialExt {
        normal_texture: tex_ref(0),
        anisotropy_strength: 0.8,
        ..Default::default()
    };
    let mut scene = flash_scene(m, ext);
    scene.vertex_extras.clear();
    let s = settings(&scene, 16, 16, 2, 2);
    for (acc, label) in both(&scene, &s, 2) {
        let lit = (0..256).filter(|&i| luminance(acc.mean(i)) > 0.0).count();
        assert!(
            acc.sum.iter().all(|v| v.iter().all(|c| c.is_finite())),
            "{label}"
        );
        assert!(lit > 10, "{label}: {lit} lit pixels");
    }
}

/// KHR_materials_anisotropy: a brushed metal under the flash (point light at the pinhole) has
/// a highlight stretched along the brushing direction — its spread along the image's x is more
/// than twice that along y with the direction at 0°, the other way round at 90° (rotation or the
/// texture's direction), and round when isotropic — on both backends.
#[test]
fn a_brushed_metal_stretches_its_highlight_along_the_brushing() {
    let w = FLASH_WIDTH as usize;
    // (anisotropy rotation, texture direction texel (RG) or none, expected spread x / y)
    let cases: [(f32, Option<[u8; 4]>, &str); 4] = [
        (0.0, None, "along x"),
        (std::f32::consts::FRAC_PI_2, None, "along y"),
        (0.0, Some([128, 255, 255, 255]), "along y"),
        (0.0, Some([128, 128, 0, 255]), "round"),
    ];
    for (rotation, texel, want) in cases {
        let m = material(Vec3::ONE, 1.0, 0.25, 1.0, Vec3::ZERO);
        let ext = MaterialExt {
            anisotropy_strength: 0.8,
            anisotropy_rotation: rotation,
            anisotropy_texture: texel.and(tex_ref(0)),
            ..Default::default()
        };
        let mut scene = flash_scene(m, ext);
        if let Some(t) = texel {
            scene.textures = vec![texture("direction", 1, 1, vec![t], false)];
        }
        let s = settings(&scene, FLASH_WIDTH, FLASH_WIDTH, 2, 1);
        for (acc, label) in both(&scene, &s, 4) {
            let (mut sum, mut mx, mut my) = (0f64, 0f64, 0f64);
            let c = w as f64 / 2.0;
            for y in 0..w {
                for x in 0..w {
                    let l = f64::from(luminance(acc.mean(y * w + x)));
                    let (dx, dy) = (x as f64 + 0.5 - c, y as f64 + 0.5 - c);
                    sum += l;
                    mx += l * dx * dx;
                    my += l * dy * dy;
                }
            }
            assert!(sum > 0.0, "{label}, {want}: no highlight");
            let ratio = mx / my;
            let ok = match want {
                "along x" => ratio > 2.0,
                "along y" => ratio < 0.5,
                _ => (ratio - 1.0).abs() < 0.1,
            };
            assert!(
                ok,
                "{label}, rotation {rotation}, texel {texel:?}: x / y spread {ratio}, want {want}"
            );
        }
    }
}

#[test]
fn an_orthographic_camera_projects_in_parallel() {
    for distance in [2.0f32, 20.0] {
        let scene = Scene {
            triangles: rect(-0.5, -0.5, 0.5, 0.5, 0.0, 0),
            materials: vec![material(Vec3::ZERO, 0.0, 1.0, 0.0, Vec3::ONE)],
            orthographic_cameras: vec![ortho(Vec3::new(0.0, 0.0, distance), 1.0)],
            environment: Environment::Constant(Vec3::ZERO),
            ..Default::default()
        };
        let s = settings(&scene, 16, 16, 1, 1);
        for (acc, label) in both(&scene, &s, 2) {
            for y in 0..16 {
                for x in 0..16 {
                    let inside = (4..12).contains(&x) && (4..12).contains(&y);
                    let l = luminance(acc.mean(y * 16 + x));
                    assert_eq!(
                        l,
                        if inside { 1.0 } else { 0.0 },
                        "{label} at {distance} m: ({x}, {y})"
                    );
                }
            }
        }
    }
}

/// KHR_materials_clearcoat over a black, non-reflecting base under a white sky, seen head-on
/// through an orthographic camera: the smooth coat reflects cc · F_c(0°) = cc · 0.04 of the
/// sky; without the coat the plane is black.
#[test]
fn a_clear_coat_on_black_reflects_its_fresnel_share_of_the_sky() {
    for cc in [0.0f32, 0.5, 1.0] {
        let scene = Scene {
            triangles: rect(-2.0, -2.0, 2.0, 2.0, 0.0, 0),
            materials: vec![material(Vec3::ZERO, 0.0, 1.0, 0.0, Vec3::ZERO)],
            material_ext: vec![MaterialExt {
                clearcoat: cc,
                clearcoat_roughness: 0.0,
                ..Default::default()
            }],
            orthographic_cameras: vec![ortho(Vec3::new(0.0, 0.0, 1.0), 1.0)],
            environment: Environment::Constant(Vec3::ONE),
            ..Default::default()
        };
        let s = settings(&scene, 8, 8, 4, 2);
        let want = 0.04 * cc;
        let all: Vec<usize> = (0..64).collect();
        for (acc, label) in both(&scene, &s, 64) {
            if cc == 0.0 {
                assert!(
                    acc.mean_image().iter().all(|c| *c == Vec3::ZERO),
                    "{label}: no coat"
                );
                continue;
            }
            // The GGX tail (even at α = 10⁻³) hands some samples to the sky's light sample:
            // unbiased, not exact per sample, so a Z-test over the pixels.
            let z = z_of(&acc, &all, f64::from(want));
            assert!(z.abs() < 5.0, "{label}, cc {cc}: z = {z}");
            assert!(
                z_of(&acc, &all, f64::from(want) * 1.03).abs() > 5.0,
                "{label}: power"
            );
        }
    }
}

/// The extensions' textures multiply their factors: a quad whose 2 × 1 texture is full (255)
/// on its left half and empty (0) on its right renders, pixel for pixel and to the bit, the
/// left half of the quad with the factor alone and the right half of the quad with the factor
/// times zero — for transmissionTexture (R), specularTexture (A), specularColorTexture (RGB;
/// read linear here, so that 255 is exactly 1: the loader marks it sRGB,
/// tests/scene/scene_loading.rs), clearcoatTexture (R), clearcoatRoughnessTexture (G; zero
/// roughness is the smallest α), sheenColorTexture (RGB, likewise read linear) and
/// sheenRoughnessTexture (A; zero is the sheen's smallest roughness), on both backends. Every material here takes the extensions'
/// BSDF (ior 1.6), so the references run the same code as the textured quad. The CPU twin to
/// the bit; the GPU within 1e-5 (WGSL lets a division, and so the texel's 255 / 255, be off by
/// 2.5 ulp; lavapipe's is exact).
#[test]
fn the_extensions_textures_multiply_their_factors() {
    type Apply = fn(&mut MaterialExt, &mut Material, bool);
    let with_texture: [(&str, [u8; 4], Apply); 7] = [
        ("transmission", [0, 0, 0, 0], |e, _, t| {
            if t {
                e.transmission_texture = tex_ref(0);
            }
            e.transmission = 0.9;
        }),
        ("specular", [255, 255, 255, 0], |e, m, t| {
            if t {
                e.specular_texture = tex_ref(0);
            }
            m.specular = 0.7;
        }),
        ("specular colour", [255, 0, 255, 255], |e, _, t| {
            if t {
                e.specular_color_texture = tex_ref(0);
            }
            e.specular_color = Vec3::new(0.9, 0.5, 0.2);
        }),
        ("clear coat", [0, 255, 255, 255], |e, _, t| {
            if t {
                e.clearcoat_texture = tex_ref(0);
            }
            e.clearcoat = 0.8;
        }),
        ("coat roughness", [255, 0, 255, 255], |e, _, t| {
            if t {
                e.clearcoat_roughness_texture = tex_ref(0);
            }
            e.clearcoat = 1.0;
            e.clearcoat_roughness = 0.6;
        }),
        ("sheen colour", [255, 0, 255, 255], |e, _, t| {
            if t {
                e.sheen_color_texture = tex_ref(0);
            }
            e.sheen_color = Vec3::new(0.9, 0.5, 0.2);
            e.sheen_roughness = 0.5;
        }),
        ("sheen roughness", [255, 255, 255, 0], |e, _, t| {
            if t {
                e.sheen_roughness_texture = tex_ref(0);
            }
            e.sheen_color = Vec3::ONE;
            e.sheen_roughness = 0.8;
        }),
    ];
    let mut tris = rect(-1.0, -1.0, 1.0, 1.0, 0.0, 0);
    for t in &mut tris {
        for (uv, p) in t.uv.iter_mut().zip(t.p) {
            uv.x = (p.x + 1.0) / 2.0;
        }
    }
    let scene_of = |m: Material, e: MaterialExt, empty: [u8; 4]| Scene {
        triangles: tris.clone(),
        materials: vec![m],
        material_ext: vec![e],
        textures: vec![texture("half", 2, 1, vec![[255; 4], empty], false)],
        orthographic_cameras: vec![ortho(Vec3::new(0.0, 0.0, 2.0), 1.0)],
        environment: Environment::Constant(Vec3::new(1.0, 0.9, 0.8)),
        ..Default::default()
    };
    let base = || {
        (
            material(Vec3::new(0.5, 0.6, 0.7), 0.0, 0.4, 1.0, Vec3::ZERO),
            MaterialExt {
                ior: 1.6,
                ..Default::default()
            },
        )
    };
    for (name, empty, apply) in with_texture {
        // The textured quad; the factor alone; the factor × 0 (the empty texel, as a factor).
        let (mut m, mut e) = base();
        apply(&mut e, &mut m, true);
        let textured = scene_of(m, e, empty);
        let (mut m, mut e) = base();
        apply(&mut e, &mut m, false);
        let full = scene_of(m.clone(), e, empty);
        let (zm, ze) = match name {
            "transmission" => (
                m,
                MaterialExt {
                    transmission: 0.0,
                    ..e
                },
            ),
            "specular" => (Material { specular: 0.0, ..m }, e),
            "specular colour" => (
                m,
                MaterialExt {
                    specular_color: Vec3::new(0.9, 0.0, 0.2),
                    ..e
                },
            ),
            "clear coat" => (
                m,
                MaterialExt {
                    clearcoat: 0.0,
                    ..e
                },
            ),
            "sheen colour" => (
                m,
                MaterialExt {
                    sheen_color: Vec3::new(0.9, 0.0, 0.2),
                    ..e
                },
            ),
            "sheen roughness" => (
                m,
                MaterialExt {
                    sheen_roughness: 0.0,
                    ..e
                },
            ),
            _ => (
                m,
                MaterialExt {
                    clearcoat_roughness: 0.0,
                    ..e
                },
            ),
        };
        let zero = scene_of(zm, ze, empty);
        let s = settings(&textured, 16, 16, 3, 3);
        let ctx = GpuContext::for_tests();
        let renders = |sc: &Scene| {
            [
                (render_on_cpu(sc, &s, 4), "CPU"),
                (render_gpu(&ctx, sc, &s, 4), "GPU"),
            ]
        };
        let (t, f, z) = (renders(&textured), renders(&full), renders(&zero));
        for k in 0..2 {
            let label = t[k].1;
            let mut differ = 0;
            for y in 0..16 {
                for x in 0..16 {
                    let i = y * 16 + x;
                    let want = if x < 8 {
                        f[k].0.mean(i)
                    } else {
                        z[k].0.mean(i)
                    };
                    let got = t[k].0.mean(i);
                    let tolerance = if k == 0 {
                        0.0
                    } else {
                        1e-5 * want.max_element().max(1.0)
                    };
                    assert!(
                        (got - want).abs().max_element() <= tolerance,
                        "{name}, {label}: pixel ({x}, {y}) = {got}, want {want}"
                    );
                    differ += usize::from(f[k].0.mean(i) != z[k].0.mean(i));
                }
            }
            // The two references differ: the test sees which half took which.
            assert!(differ > 200, "{name}, {label}: only {differ} pixels differ");
        }
    }
}

/// The clear coat's own normal (KHR_materials_clearcoat): on a black base that reflects
/// nothing, under a point light at the pinhole, the coat's highlight sits under the camera
/// when only the base has a normal map tilting it by 10° towards +x — the base's map does not
/// bend the coat — and at x = −c·tan 10° when the coat's own normal map tilts it so.
#[test]
fn the_coat_takes_its_own_normal_map_and_not_the_bases() {
    for (base_map, coat_map) in [(true, false), (false, true), (true, true)] {
        let ext = MaterialExt {
            normal_texture: if base_map { tex_ref(0) } else { None },
            clearcoat: 1.0,
            clearcoat_roughness: 0.3,
            clearcoat_normal_texture: if coat_map { tex_ref(0) } else { None },
            ..Default::default()
        };
        let scene = flash_scene(material(Vec3::ZERO, 0.0, 1.0, 0.0, Vec3::ZERO), ext);
        let what = format!("base map {base_map}, coat map {coat_map}");
        assert_flash_highlight(&scene, flash_column(coat_map), &what);
    }
}
