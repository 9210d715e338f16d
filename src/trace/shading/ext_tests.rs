use super::*;

fn glass(alpha: f32, eta: f32) -> BsdfExt {
    BsdfExt {
        core: Bsdf {
            base: Vec3::ONE,
            metallic: 0.0,
            alpha,
            specular: 1.0,
        },
        specular_color: Vec3::ONE,
        f0: 0.04,
        eta,
        transmission: 1.0,
        clearcoat: 0.0,
        clearcoat_alpha: 0.1,
        coat_normal: Vec3::Z,
        sheen: Vec3::ZERO,
        sheen_roughness: 1.0,
        aniso_dir: Vec3::ZERO,
        alpha_t: alpha,
        diffuse_transmission: 0.0,
        diffuse_transmission_color: Vec3::ONE,
    }
}

/// A sheen of colour 1 and roughness `r` over `base` (Lambertian: specular 0).
fn velvet(base: f32, r: f32) -> BsdfExt {
    BsdfExt {
        core: Bsdf {
            base: Vec3::splat(base),
            metallic: 0.0,
            alpha: 1.0,
            specular: 0.0,
        },
        transmission: 0.0,
        eta: 1.5,
        sheen: Vec3::ONE,
        sheen_roughness: r,
        ..glass(1.0, 1.5)
    }
}

/// Sampled estimates of ∫ f cos θᵢ dωᵢ (value / pdf over the BSDF's own samples, and the
/// same integrand over uniform hemisphere directions) and of E[1/pdf], with the standard
/// error of the first.
fn albedo(e: &BsdfExt, wo: Vec3, m: u32, seed: u32) -> (f64, f64, f64, f64) {
    let n = Vec3::Z;
    let (mut sum, mut sum2, mut uniform, mut inv_pdf) = (0f64, 0f64, 0f64, 0f64);
    for i in 0..m {
        let r = crate::random::pcg4d([i, seed, 7, 9]);
        let u = r.map(crate::random::unit_f32);
        let wi = e.sample(n, wo, u[0], u[1], u[2]);
        let (f, pdf) = e.eval(n, wo, wi);
        if pdf > 0.0 && wi.z > 0.0 {
            let x = f64::from(f.x * wi.z / pdf);
            sum += x;
            sum2 += x * x;
            inv_pdf += f64::from(1.0 / pdf);
        }
        let l = uniform_sphere(0.5 * u[3], u[1]);
        uniform += f64::from(e.eval(n, wo, l).0.x * l.z) * 2.0 * std::f64::consts::PI;
    }
    let mean = sum / f64::from(m);
    let se = ((sum2 / f64::from(m) - mean * mean) / f64::from(m)).sqrt();
    (mean, se, uniform / f64::from(m), inv_pdf / f64::from(m))
}

/// The sheen's albedo table is the integral of the f32 BRDF both backends evaluate: over a
/// black base the BSDF reflects E(cos θ) — estimated from its own samples (so its pdf is
/// the sampler's too) and from uniform directions — at every roughness and angle tried;
/// and E stays within [0, 1].
#[test]
fn a_sheen_over_black_reflects_its_tabulated_albedo() {
    assert!(SHEEN_ALBEDO.iter().all(|&e| (0.0..=1.0).contains(&e)));
    // Rows 0, 9, 20, 31 and columns 10, 32, 57 (table nodes: no interpolation), then
    // points between nodes, where the bilinear lookup's error is allowed 4 %.
    let node = |j: u32| SHEEN_MIN_ROUGHNESS + (1.0 - SHEEN_MIN_ROUGHNESS) * j as f32 / 31.0;
    let nodes = [0, 9, 20, 31].map(|j| (node(j), [10.0f32, 32.0, 57.0].map(|i| i / 63.0)));
    let between = [0.3f32, 0.65].map(|r| (r, [0.15f32, 0.5, 0.9]));
    for (k, (r, cosines)) in nodes.into_iter().chain(between).enumerate() {
        for cos in cosines {
            let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
            let e = velvet(0.0, r);
            let want = f64::from(sheen_albedo(&SHEEN_ALBEDO, cos, r));
            let (got, se, uniform, support) = albedo(&e, wo, 200_000, 3);
            let model = if k < 4 { 0.005 } else { 0.04 };
            let tol = 4.0 * se + model * want + 1e-3;
            assert!(
                (got - want).abs() < tol,
                "r {r}, cos {cos}: {got} ± {se} vs {want}"
            );
            assert!(
                (uniform - got).abs() < 0.03 * got + 2e-3,
                "uniform: {uniform} vs {got}"
            );
            // The sheen's lobe covers the hemisphere: E[1/pdf] = 2π.
            let tau = 2.0 * std::f64::consts::PI;
            assert!((support - tau).abs() < 0.02 * tau, "support {support}");
        }
    }
    // Power: at the smooth end the sheen reflects more at grazing views than head-on.
    let e = |cos| sheen_albedo(&SHEEN_ALBEDO, cos, SHEEN_MIN_ROUGHNESS);
    assert!(e(0.1) > 2.0 * e(0.9), "{} {}", e(0.1), e(0.9));
}

/// Anisotropic GGX (KHR_materials_anisotropy) samples what it evaluates: for a brushed
/// metal and a brushed rough glass, ∫ f |cos| estimated from the BSDF's own samples (value /
/// pdf) equals the estimate from uniform directions, the metal reflects at most 1, and the
/// sampled support is at most the sphere; the lobe turns with the brushing direction (the
/// value along x with the direction along x is the value along y with it along y), and
/// differs from the isotropic lobe.
#[test]
fn anisotropic_lobes_sample_what_they_evaluate() {
    let alpha = 0.09f32;
    let brushed = |dir: Vec3, transmission: f32, metallic: f32| BsdfExt {
        core: Bsdf {
            base: Vec3::ONE,
            metallic,
            alpha,
            specular: 1.0,
        },
        transmission,
        aniso_dir: dir,
        alpha_t: alpha + (1.0 - alpha) * 0.49,
        ..glass(alpha, 1.5)
    };
    let n = Vec3::Z;
    let tau = 2.0 * std::f64::consts::PI;
    for (k, (transmission, metallic)) in [(0.0f32, 1.0f32), (1.0, 0.0)].into_iter().enumerate() {
        let e = brushed(Vec3::X, transmission, metallic);
        for wo in [
            Vec3::new(0.3, 0.1, 0.95),
            Vec3::new(0.8, 0.0, 0.6),
            Vec3::new(0.0, 0.8, 0.6),
        ] {
            let wo = wo.normalize();
            let m = 400_000u32;
            let (mut own, mut uniform, mut support) = (0f64, 0f64, 0f64);
            for i in 0..m {
                let r = crate::random::pcg4d([i, 17, 3, k as u32]);
                let u = r.map(crate::random::unit_f32);
                let wi = e.sample(n, wo, u[0], u[1], u[2]);
                let (f, pdf) = e.eval(n, wo, wi);
                if pdf > 0.0 && wi != Vec3::ZERO {
                    own += f64::from(f.x * wi.z.abs() / pdf);
                    support += f64::from(1.0 / pdf);
                }
                let l = uniform_sphere(u[3], u[1]);
                uniform += f64::from(e.eval(n, wo, l).0.x * l.z.abs()) * 2.0 * tau;
            }
            let (own, uniform, support) = (
                own / f64::from(m),
                uniform / f64::from(m),
                support / f64::from(m),
            );
            assert!(
                (own - uniform).abs() < 0.04 * own + 0.01,
                "{k} {wo}: {own} vs {uniform}"
            );
            assert!(support <= 2.0 * tau * 1.02, "{k} {wo}: support {support}");
            if metallic == 1.0 {
                assert!(own <= 1.01 && own > 0.7, "{k} {wo}: albedo {own}");
            }
        }
    }
    // The lobe turns with the brushing; it is not the isotropic one.
    let (along_x, along_y) = (brushed(Vec3::X, 0.0, 1.0), brushed(Vec3::Y, 0.0, 1.0));
    let iso = BsdfExt {
        aniso_dir: Vec3::ZERO,
        ..along_x
    };
    let wo = Vec3::new(0.0, 0.0, 1.0);
    let (wx, wy) = (
        Vec3::new(0.3, 0.0, 0.954).normalize(),
        Vec3::new(0.0, 0.3, 0.954).normalize(),
    );
    let (fx, fy) = (along_x.eval(n, wo, wx).0.x, along_y.eval(n, wo, wy).0.x);
    assert!((fx - fy).abs() <= 1e-5 * fx, "{fx} vs {fy}");
    assert!(along_x.eval(n, wo, wx).0.x > 2.0 * along_x.eval(n, wo, wy).0.x);
    assert!((iso.eval(n, wo, wx).0.x - fx).abs() > 0.1 * fx);
}

/// The albedo-scaling layering conserves energy: a white sheen over a white Lambertian base
/// reflects at most everything (the base loses what the sheen takes), and more than the
/// sheen alone.
#[test]
fn a_sheen_over_white_reflects_at_most_everything() {
    for r in [SHEEN_MIN_ROUGHNESS, 0.5, 1.0] {
        for cos in [0.2f32, 0.7] {
            let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
            let (got, se, _, _) = albedo(&velvet(1.0, r), wo, 100_000, 5);
            assert!(got <= 1.0 + 4.0 * se, "r {r}, cos {cos}: {got} ± {se}");
            let alone = f64::from(sheen_albedo(&SHEEN_ALBEDO, cos, r));
            assert!(got > alone + 0.3, "r {r}, cos {cos}: {got} vs {alone}");
        }
    }
}

/// ∫ f |cos| dωi over the sphere by sampling: reflection + transmission of rough glass
/// adds up to at most 1 (the Smith masking loses up to ~10 % at this roughness), and
/// the pdf from `eval` integrates to ≤ 1 (E[1/pdf] over the sampled support ≤ 4π).
#[test]
fn rough_glass_conserves_energy_and_its_pdf_matches_sampling() {
    let n = Vec3::Z;
    for (eta, alpha) in [(1.5f32, 0.3f32), (1.0 / 1.5, 0.3), (1.5, 0.05)] {
        let bsdf = glass(alpha, eta);
        let wo = Vec3::new(0.3, 0.0, 0.954).normalize();
        let (mut total, mut transmitted, mut m) = (0.0f64, 0.0f64, 0u32);
        for i in 0..200_000u32 {
            let r = crate::random::pcg4d([i, 3, 1, 4]).map(crate::random::unit_f32);
            m += 1;
            let wi = bsdf.sample(n, wo, r[0], r[1], r[2]);
            if wi == Vec3::ZERO {
                continue;
            }
            let (f, pdf) = bsdf.eval(n, wo, wi);
            if pdf > 0.0 {
                let w = f64::from(f.x * n.dot(wi).abs() / pdf);
                total += w;
                if n.dot(wi) < 0.0 {
                    transmitted += w;
                }
            }
        }
        let total = total / f64::from(m);
        let transmitted = transmitted / f64::from(m);
        assert!(
            // Smith masking loses energy at α = 0.3, most for light leaving the
            // denser side (its transmitted directions spread towards grazing).
            (0.85..=1.01).contains(&total),
            "eta {eta}, alpha {alpha}: albedo {total}"
        );
        assert!(transmitted > 0.8, "eta {eta}: transmitted {transmitted}");
    }
}

/// At normal incidence smooth glass reflects F0 = ((η − 1)/(η + 1))² and transmits the rest.
#[test]
fn smooth_glass_at_normal_incidence_transmits_one_minus_f0() {
    let n = Vec3::Z;
    let bsdf = glass(1e-3, 1.5);
    let (mut refl, mut trans, m) = (0.0f64, 0.0f64, 100_000u32);
    for i in 0..m {
        let r = crate::random::pcg4d([i, 8, 8, 8]).map(crate::random::unit_f32);
        let wi = bsdf.sample(n, Vec3::Z, r[0], r[1], r[2]);
        let (f, pdf) = bsdf.eval(n, Vec3::Z, wi);
        if pdf > 0.0 {
            let w = f64::from(f.x * n.dot(wi).abs() / pdf);
            if wi.z > 0.0 {
                refl += w;
            } else {
                trans += w;
            }
        }
    }
    let (refl, trans) = (refl / f64::from(m), trans / f64::from(m));
    assert!((refl - 0.04).abs() < 0.004, "reflected {refl}");
    assert!((trans - 0.96).abs() < 0.01, "transmitted {trans}");
}

/// Leaving glass beyond the critical angle (41.8° for η = 1.5) everything is reflected.
#[test]
fn total_internal_reflection_beyond_the_critical_angle() {
    let bsdf = glass(1e-3, 1.0 / 1.5);
    let c = 50f32.to_radians().cos();
    let (fd, _) = bsdf.fresnel(c);
    assert_eq!(fd, Vec3::ONE);
    let p = bsdf.lobes(c, c);
    assert_eq!(p[2], 0.0, "no transmission sampled: {p:?}");
}

/// The wavelength terms are the extension's formula at the Fraunhofer lines, to the bit.
#[test]
fn dispersion_terms_are_the_formula_at_the_fraunhofer_lines() {
    for (term, lambda) in DISPERSION_TERMS.iter().zip([656.27f64, 587.56, 486.13]) {
        let want = ((523_655.0 / (lambda * lambda) - 1.5168) / 20.0) as f32;
        assert_eq!(
            term.to_bits(),
            want.to_bits(),
            "{lambda} nm: {term} vs {want}"
        );
    }
}

/// Blue's index exceeds red's by (n_d − 1)/V (the Abbe number's definition, to the
/// formula's rounding of its constants), green keeps n_d, and no index falls below 1.
#[test]
fn dispersed_iors_spread_by_the_abbe_number() {
    for (ior, abbe) in [(1.5f32, 59.0f32), (2.42, 55.0), (1.58, 32.0), (2.6, 9.8)] {
        let d = 20.0 / abbe;
        let [r, g, b] = [0, 1, 2].map(|c| dispersed_ior(ior, d, c));
        assert!(r < g && g < b, "ior {ior}: {r} {g} {b}");
        let spread = (ior - 1.0) / abbe;
        assert!(
            ((b - r) / spread - 1.0).abs() < 1e-3,
            "ior {ior}: {}",
            b - r
        );
        assert!((g - ior).abs() < 1e-5, "ior {ior}: green {g}");
    }
    assert_eq!(dispersed_ior(1.5, 0.0, 0), 1.5);
    assert_eq!([0, 1, 2].map(|c| dispersed_ior(1.0, 3.0, c)), [1.0; 3]);
    assert_eq!(dispersed_ior(1.2, 100.0, 0), 1.0, "clamped at 1");
    assert_eq!(dispersed_ior(9.0, 100.0, 2), 10.0, "clamped at 10");
}

/// The pick keeps every channel's expectation (over u ∈ [0, 1), by a fine midpoint rule),
/// never picks a channel without throughput, and leaves a one-channel throughput exactly.
#[test]
fn the_channel_pick_is_unbiased_and_keeps_a_picked_channel() {
    let n = 1 << 16;
    for t in [
        Vec3::ONE,
        Vec3::new(0.2, 0.7, 0.05),
        Vec3::new(0.0, 0.3, 0.6),
        Vec3::new(0.5, 0.0, 0.0),
        Vec3::new(1e-30, 4.0, 0.0),
    ] {
        let mut mean = [0f64; 3];
        for k in 0..n {
            let u = (k as f32 + 0.5) / n as f32;
            let (c, out) = pick_channel(t, u);
            assert!(t[c as usize] > 0.0, "{t}: picked {c} at u = {u}");
            for (m, o) in mean.iter_mut().zip(out.to_array()) {
                *m += f64::from(o) / f64::from(n);
            }
        }
        for (c, m) in mean.iter().enumerate() {
            let want = f64::from(t[c]);
            assert!(
                (m - want).abs() <= 1e-4 * want.max(1e-3),
                "{t}: channel {c} {m}"
            );
        }
        // The last u below 1: the top channel with throughput, never one without.
        let (c, _) = pick_channel(t, 1.0 - f32::EPSILON / 2.0);
        assert!(t[c as usize] > 0.0, "{t}: picked {c} at the top");
    }
    for c in 0..3 {
        let mut t = Vec3::ZERO;
        t[c] = 0.37;
        for u in [0.0, 0.3, 0.999_999_9] {
            let (picked, out) = pick_channel(t, u);
            assert_eq!(
                (picked, out.to_array().map(f32::to_bits)),
                (c as u32, t.to_array().map(f32::to_bits))
            );
        }
    }
    assert_eq!(pick_channel(Vec3::ZERO, 0.5), (0, Vec3::ZERO));
}

/// KHR_materials_diffuse_transmission: a white Lambertian base with no specular reflection
/// reflects (1 − dt)·base and transmits dt·colour, Lambertian on the far side: each
/// estimated from the BSDF's own samples (so its pdf is the sampler's) and from uniform
/// directions over the whole sphere; a plain diffuse base transmits nothing; specular
/// transmission takes the diffuse transmission's place where both are given.
#[test]
fn a_diffuse_transmission_reflects_and_transmits_its_shares() {
    let n = Vec3::Z;
    let leaf = |dt: f32, transmission: f32| BsdfExt {
        core: Bsdf {
            base: Vec3::new(0.9, 0.6, 0.3),
            metallic: 0.0,
            alpha: 0.5,
            specular: 0.0,
        },
        transmission,
        diffuse_transmission: dt,
        diffuse_transmission_color: Vec3::new(0.2, 0.8, 0.4),
        ..glass(0.5, 1.5)
    };
    // (reflected, transmitted) of channel `c` from the BSDF's samples; the whole sphere's
    // integral from uniform directions.
    let shares = |e: &BsdfExt, wo: Vec3, c: usize| {
        let m = 200_000u32;
        let (mut up, mut down, mut sphere) = (0f64, 0f64, 0f64);
        for i in 0..m {
            let u = crate::random::pcg4d([i, 5, 11, 13]).map(crate::random::unit_f32);
            let wi = e.sample(n, wo, u[0], u[1], u[2]);
            let (f, pdf) = e.eval(n, wo, wi);
            if pdf > 0.0 {
                let x = f64::from(f[c] * wi.z.abs() / pdf);
                if wi.z > 0.0 { up += x } else { down += x }
            }
            let l = uniform_sphere(u[3], u[1]);
            sphere += f64::from(e.eval(n, wo, l).0[c] * l.z.abs()) * 4.0 * std::f64::consts::PI;
        }
        let m = f64::from(m);
        (up / m, down / m, sphere / m)
    };
    for wo in [Vec3::Z, Vec3::new(0.6, 0.0, 0.8)] {
        for (dt, c) in [(0.0f32, 0), (0.4, 0), (0.4, 1), (1.0, 2)] {
            let e = leaf(dt, 0.0);
            let (up, down, sphere) = shares(&e, wo, c);
            let want_up = f64::from((1.0 - dt) * e.core.base[c]);
            let want_down = f64::from(dt * e.diffuse_transmission_color[c]);
            assert!(
                (up - want_up).abs() < 0.01,
                "dt {dt}, {c}: up {up} vs {want_up}"
            );
            assert!(
                (down - want_down).abs() < 0.01,
                "dt {dt}, {c}: down {down} vs {want_down}"
            );
            assert!(
                (sphere - up - down).abs() < 0.02,
                "dt {dt}: sphere {sphere}"
            );
            assert_eq!(e.transmits(), dt > 0.0);
        }
    }
    // With specular transmission as well, the diffuse transmission's share goes to it.
    let both = leaf(1.0, 1.0);
    assert_eq!(both.lobes(1.0, 1.0)[5], 0.0);
    let (_, down, _) = shares(&both, Vec3::Z, 0);
    assert!(down > 0.5 * f64::from(both.core.base.x), "{down}");
    // Without it, the numbers are the ones before it existed: the sixth lobe is 0.
    assert_eq!(leaf(0.0, 0.0).lobes(0.7, 0.7)[5], 0.0);
}
