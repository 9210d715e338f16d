use super::*;

#[test]
fn equirect_round_trips() {
    for &(u, v) in &[(0.1f32, 0.2f32), (0.5, 0.5), (0.9, 0.7), (0.25, 0.95)] {
        let d = equirect_to_direction(u, v);
        let (u2, v2) = direction_to_equirect(d);
        assert!(
            (u - u2).abs() < 1e-5 && (v - v2).abs() < 1e-5,
            "{u},{v} → {u2},{v2}"
        );
    }
    // +Y is the zenith (row 0), −Z the image centre.
    assert!(direction_to_equirect(Vec3::Y).1 < 1e-6);
    let (u, v) = direction_to_equirect(Vec3::NEG_Z);
    assert!((u - 0.5).abs() < 1e-6 && (v - 0.5).abs() < 1e-6);
}

/// The turns' sine and cosine against f64's, over every quarter and its edges: within
/// 2e-7 absolute (the rounding of a value of magnitude ≤ 1), and sin² + cos² = 1.
#[test]
fn sin_cos_turns_is_accurate() {
    let mut worst = 0f64;
    let edges = [
        0.0,
        0.125,
        0.25,
        0.375,
        0.5,
        0.625,
        0.75,
        0.875,
        1.0 - 2f32.powi(-24),
    ];
    let samples = (0..200_000u32)
        .map(|i| crate::random::unit_f32(crate::random::pcg4d([i, 1, 2, 3])[0]))
        .chain(
            edges
                .iter()
                .flat_map(|&e: &f32| [e, e.next_up(), e.next_down().max(0.0)]),
        );
    for v in samples {
        let (s, c) = sin_cos_turns(v);
        let a = 2.0 * std::f64::consts::PI * f64::from(v);
        worst = worst
            .max((f64::from(s) - a.sin()).abs())
            .max((f64::from(c) - a.cos()).abs());
        assert!(
            (f64::from(s).hypot(f64::from(c)) - 1.0).abs() < 3e-7,
            "v {v}"
        );
    }
    assert!(worst < 2e-7, "worst error {worst}");
}

#[test]
fn basis_is_orthonormal() {
    for n in [
        Vec3::Z,
        Vec3::NEG_Z,
        Vec3::new(0.3, -0.5, 0.8).normalize(),
        Vec3::X,
    ] {
        let (t, b) = basis(n);
        for (x, y) in [(t, b), (t, n), (b, n)] {
            assert!(x.dot(y).abs() < 1e-6);
        }
        assert!((t.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
    }
}

/// Monte Carlo estimates of ∫ f cos / pdf over the sampled directions: the albedo must not
/// exceed 1 (energy conservation), and the pdf returned by `eval` must integrate to ≤ 1
/// and reproduce the sampler's density (checked via E[1/pdf · 1] over the hemisphere = 2π
/// when the sampler covers it).
#[test]
fn bsdf_conserves_energy_and_pdf_matches_sampling() {
    let n = Vec3::Z;
    for &(metallic, rough, base) in &[
        (0.0f32, 1.0f32, 0.8f32),
        (1.0, 0.3, 0.9),
        (0.5, 0.5, 1.0),
        (0.0, 0.05, 0.5),
    ] {
        let bsdf = Bsdf {
            base: Vec3::splat(base),
            metallic,
            alpha: (rough * rough).max(1e-3),
            specular: 1.0,
        };
        let wo = Vec3::new(0.4, 0.0, 0.9165).normalize();
        let m = 200_000u32;
        let (mut albedo, mut inv_pdf) = (0.0f64, 0.0f64);
        for i in 0..m {
            let r = crate::random::pcg4d([i, 5, 7, 9]);
            let wi = bsdf.sample(
                n,
                wo,
                crate::random::unit_f32(r[0]),
                crate::random::unit_f32(r[1]),
                crate::random::unit_f32(r[2]),
            );
            let (f, pdf) = bsdf.eval(n, wo, wi);
            if pdf > 0.0 {
                albedo += f64::from(f.x * wi.z / pdf);
                inv_pdf += f64::from(1.0 / pdf);
            }
        }
        let albedo = albedo / f64::from(m);
        assert!(
            albedo <= 1.01,
            "albedo {albedo} for metallic {metallic}, roughness {rough}"
        );
        // E[1/pdf] over samples = measure of the sampled support ≤ 2π (hemisphere).
        let support = inv_pdf / f64::from(m);
        assert!(
            support <= 2.0 * std::f64::consts::PI * 1.02,
            "support {support}"
        );
        if rough == 1.0 && metallic == 0.0 {
            // Nearly Lambertian: the whole hemisphere is covered.
            assert!(
                (support - 2.0 * std::f64::consts::PI).abs() < 0.1,
                "support {support}"
            );
            assert!(albedo > 0.7, "albedo {albedo}");
        }
    }
}
