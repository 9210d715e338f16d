use super::*;
use crate::scene::{Environment, EnvironmentMap, Scene};
use crate::trace::camera::RenderCamera;

fn map_scene() -> PackedScene {
    // A dim sky with one bright patch (a "sun") near the zenith and a coloured band.
    let (w, h) = (32u32, 16u32);
    let texels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if (x, y) == (5, 3) {
                Vec3::new(200.0, 180.0, 150.0)
            } else if y == 10 {
                Vec3::new(0.1, 0.4, 0.9)
            } else {
                Vec3::splat(0.2)
            }
        })
        .collect();
    PackedScene::new(&Scene {
        environment: Environment::Map(EnvironmentMap {
            name: "test".into(),
            width: w,
            height: h,
            texels,
        }),
        ..Default::default()
    })
}

/// The pair of wrapped neighbours is two wraps, for every mode, sizes 1 to 5 and
/// coordinates around zero, the sizes' multiples and the ends of i32.
#[test]
fn wrap_pair_is_two_wraps() {
    for n in 1..=5u32 {
        for mode in 0..4 {
            let near = -40..40;
            let ends = [i32::MIN, i32::MIN + 1, i32::MAX - 1, i32::MAX];
            for i in near.chain(ends) {
                assert_eq!(
                    wrap_pair(i, n, mode),
                    (wrap(i, n, mode), wrap(i.wrapping_add(1), n, mode)),
                    "i {i}, n {n}, mode {mode}"
                );
            }
        }
    }
}

/// The environment sampler's density is the one `env_eval` reports for the sampled
/// direction, and it integrates to 1 over the sphere (Monte Carlo with uniform directions).
#[test]
fn environment_sampling_density_is_consistent_and_normalised() {
    let sc = map_scene();
    for i in 0..2000u32 {
        let r = pcg4d([i, 1, 2, 3]).map(unit_f32);
        let (d, le, pdf) = sample_env(&sc, r[0], r[1]);
        let (le2, pdf2) = env_eval(&sc, d);
        assert!((d.length() - 1.0).abs() < 1e-5);
        if pdf > 0.0 {
            assert!(
                (pdf - pdf2).abs() <= 2e-3 * pdf,
                "pdf {pdf} vs {pdf2} at {d}"
            );
            assert_eq!(le, le2);
        }
    }
    let n = 400_000u32;
    let mut integral = 0f64;
    for i in 0..n {
        let r = pcg4d([i, 9, 9, 9]).map(unit_f32);
        let d = uniform_sphere(r[0], r[1]);
        integral += f64::from(env_eval(&sc, d).1) * 4.0 * std::f64::consts::PI;
    }
    let integral = integral / f64::from(n);
    assert!((integral - 1.0).abs() < 0.02, "∫ pdf dω = {integral}");
    // Importance: the sun's texel is chosen far more often than its solid angle share.
    let sun = (0..20_000u32)
        .filter(|&i| {
            let r = pcg4d([i, 4, 4, 4]).map(unit_f32);
            let (d, _, _) = sample_env(&sc, r[0], r[1]);
            let (u, v) = direction_to_equirect(d);
            ((u * 32.0) as u32, (v * 16.0) as u32) == (5, 3)
        })
        .count();
    assert!(sun > 10_000, "the sun was sampled {sun} times of 20 000");
}

/// The plain instantiation is the same function on a plain scene: every sample of the
/// builtin scenes (area light, environment, textures, single-sided emitters) equal bit for
/// bit to the full one's; and any feature beyond the core makes a scene not plain.
#[test]
fn the_plain_path_is_the_full_path_on_plain_scenes() {
    for name in ["cornell", "cornell-light", "city-small"] {
        let scene = Scene::builtin(name).unwrap();
        let sc = PackedScene::new(&scene);
        assert!(sc.plain, "builtin:{name} should be plain");
        let (width, height) = (24, 16);
        let camera = RenderCamera::choose(&scene, None, width, height).unwrap();
        let s = TraceSettings {
            width,
            height,
            seed: 7,
            max_depth: 8,
            camera,
        };
        let mut lit = 0;
        for pixel in 0..width * height {
            for sample in 0..3 {
                let r0 = rand4(pixel, sample, s.seed, 0);
                let (x, y) = ((pixel % width) as f32, (pixel / width) as f32);
                let (o, d) = s.camera.ray(x + r0[0], y + r0[1], width, height);
                let (full, full_rays) = trace_path::<true>(&sc, &s, pixel, sample, o, d);
                let (plain, plain_rays) = trace_path::<false>(&sc, &s, pixel, sample, o, d);
                assert_eq!(
                    full.to_array().map(f32::to_bits),
                    plain.to_array().map(f32::to_bits),
                    "builtin:{name} pixel {pixel} sample {sample}"
                );
                assert_eq!(full_rays, plain_rays);
                lit += usize::from(full != Vec3::ZERO);
            }
        }
        assert!(lit > 100, "builtin:{name}: only {lit} samples saw light");
    }
    let base = Scene::builtin("cornell-light").unwrap();
    let mut glass = base.clone();
    glass.material_ext = vec![
        crate::scene::MaterialExt {
            transmission: 1.0,
            ..Default::default()
        };
        glass.materials.len()
    ];
    assert!(!PackedScene::new(&glass).plain, "glass is not plain");
    let mut masked = base.clone();
    masked.material_ext = vec![
        crate::scene::MaterialExt {
            alpha: crate::scene::AlphaMode::Mask(0.5),
            ..Default::default()
        };
        masked.materials.len()
    ];
    assert!(
        !PackedScene::new(&masked).plain,
        "alpha masks are not plain"
    );
    // An absorbing medium alone (no glass: a camera inside it) needs the full
    // instantiation too.
    let mut medium = base.clone();
    medium.material_ext = vec![
        crate::scene::MaterialExt {
            absorption: Vec3::ONE,
            ..Default::default()
        };
        medium.materials.len()
    ];
    assert!(
        !PackedScene::new(&medium).plain,
        "absorbing media are not plain"
    );
    let mut lamp = base;
    lamp.lights.push(crate::scene::PunctualLight {
        name: "lamp".into(),
        kind: crate::scene::LightKind::Point,
        position: Vec3::new(0.0, 1.0, 0.0),
        direction: Vec3::NEG_Y,
        intensity: Vec3::ONE,
    });
    assert!(
        !PackedScene::new(&lamp).plain,
        "punctual lights are not plain"
    );
}
