//! Properties of the filter's definition, on the CPU twins (DESIGN.md §8, src/filter/mod.rs).

use glam::{DVec3, Vec3};
use raygun::filter::{self, Blend, FilterKind, FilterParams, exact, fast, synth};
use raygun::random::{pcg4d, unit_f32};
use raygun::trace::accum::Accumulation;

/// Random values, uniform in [0, 1) per channel, with a random half of the pixels unsampled;
/// sampled pixels have `count` identical samples.
fn half_sampled(w: u32, h: u32, count: u32, seed: u32) -> (Accumulation, Vec<DVec3>, Vec<bool>) {
    let mut acc = Accumulation::new(w, h);
    let mut values = Vec::new();
    let mut sampled = Vec::new();
    for i in 0..(w * h) as usize {
        let r = pcg4d([i as u32, seed, 0x5eed, 1]);
        let v = Vec3::new(unit_f32(r[1]), unit_f32(r[2]), unit_f32(r[3]));
        let s = unit_f32(r[0]) < 0.5;
        if s {
            for _ in 0..count {
                acc.add(i, v);
            }
        }
        values.push(v.as_dvec3());
        sampled.push(s);
    }
    (acc, values, sampled)
}

/// The paper's "perceived difference in brightness": unsampled pixels must not pull the mean
/// down. Sampled pixels have s = c (passed through); unsampled ones (w = 1, d = 1) become the
/// Gaussian mean of their sampled neighbours.
///
/// Tolerance, derived: the filtered mean is A = Σ_j a_j v_j over the sampled values, the
/// sampled mean B = Σ_j v_j / n_s; both weight vectors sum to 1 and depend only on the mask, so
/// D = A − B has mean 0 and standard deviation σ_v·√(Σ_j (a_j − 1/n_s)²) per channel, with
/// σ_v = 1/√12 for uniform values. The test computes the a_j exactly (scattering every
/// unsampled pixel's normalised Gaussian weights) and allows 5 standard deviations
/// (two-sided p ≈ 6e-7 per channel). The unfiltered mean (unsampled = 0) misses by about half.
#[test]
fn unsampled_pixels_do_not_change_the_mean_brightness() {
    let (w, h, c) = (160u32, 120u32, 4u32);
    let (acc, values, sampled) = half_sampled(w, h, c, 11);
    let dgi = vec![1.0f32; (w * h) as usize];
    let k = 6.0f32;
    let n = (w * h) as usize;
    let n_s = sampled.iter().filter(|&&s| s).count();
    // a_j: 1/N for each sampled pixel itself, plus each unsampled pixel's weight share.
    let mut a = vec![0.0f64; n];
    for i in 0..n {
        if sampled[i] {
            a[i] += 1.0 / n as f64;
            continue;
        }
        let (x, y) = ((i as u32 % w) as i64, (i as u32 / w) as i64);
        let mut taps = Vec::new();
        for dy in -6i64..=6 {
            for dx in -6i64..=6 {
                let (xx, yy) = (x + dx, y + dy);
                let r2 = (dx * dx + dy * dy) as f64;
                if xx < 0 || yy < 0 || xx >= i64::from(w) || yy >= i64::from(h) || r2 > 36.0 {
                    continue;
                }
                let j = (yy * i64::from(w) + xx) as usize;
                if sampled[j] {
                    taps.push((j, (-4.5 * r2 / 36.0).exp()));
                }
            }
        }
        let total: f64 = taps.iter().map(|t| t.1).sum();
        assert!(
            total > 0.0,
            "every pixel has a sampled neighbour within 6 px here"
        );
        for (j, g) in taps {
            a[j] += g / total / n as f64;
        }
    }
    let spread: f64 = (0..n)
        .filter(|&j| sampled[j])
        .map(|j| (a[j] - 1.0 / n_s as f64).powi(2))
        .sum::<f64>()
        .sqrt();
    let tol = 5.0 / 12f64.sqrt() * spread;
    let sampled_mean = (0..n)
        .filter(|&j| sampled[j])
        .map(|j| values[j])
        .sum::<DVec3>()
        / n_s as f64;
    let mean = |img: &[DVec3]| img.iter().sum::<DVec3>() / img.len() as f64;
    let params = FilterParams {
        k_max: k,
        c: c as f32,
        ..Default::default()
    };
    let exact = exact::filter_cpu(&params, &acc, &dgi);
    let d = (mean(&exact) - sampled_mean).abs().max_element();
    assert!(d <= tol, "exact: mean off by {d}, tolerance {tol}");
    // The same test on the unfiltered image fails by far.
    let raw = filter::unfiltered_cpu(&acc);
    assert!((mean(&raw) - sampled_mean).abs().min_element() > 100.0 * tol);
    // The fast filter (k = 6 mixes pyramid levels 0 and 1) weights differently; its mean
    // brightness differs from the exact one's by at most the bias bound tests/render/filter_fast.rs
    // states (FAST_REL_MEAN = 0.5 % of the mean brightness), so |D_fast| ≤ tol + that bias.
    let fast = fast::filter_cpu(&params, &acc, &dgi);
    let bias = 0.005 * mean(&exact).max_element();
    assert!((mean(&fast) - mean(&exact)).abs().max_element() <= bias);
    let d = (mean(&fast) - sampled_mean).abs().max_element();
    assert!(
        d <= tol + bias,
        "fast: mean off by {d}, tolerance {}",
        tol + bias
    );
}

/// A constant image with holes: every covered pixel is the constant (normalised weights), for
/// both implementations and both blends.
#[test]
fn a_constant_image_with_holes_stays_constant() {
    let (w, h) = (64u32, 48u32);
    let colour = Vec3::new(0.3, 0.6, 0.9);
    let mut acc = Accumulation::new(w, h);
    for i in 0..(w * h) as usize {
        let r = pcg4d([i as u32, 3, 5, 7]);
        for _ in 0..(r[0] % 3) {
            acc.add(i, colour);
        }
    }
    let dgi: Vec<f32> = (0..w * h).map(|i| (i % 7) as f32 / 6.0).collect();
    for kind in [FilterKind::Exact, FilterKind::Fast] {
        for blend in [Blend::Count, Blend::Variance] {
            let params = FilterParams {
                kind,
                blend,
                k_max: 12.0,
                c: 3.0,
                variance_threshold: 1e-3,
            };
            let out = filter::filter_cpu(&params, &acc, &dgi).unwrap();
            for (i, o) in out.iter().enumerate() {
                if *o != DVec3::ZERO {
                    let e = (*o - colour.as_dvec3()).abs().max_element();
                    assert!(e < 1e-6, "{kind:?} {blend:?} pixel {i}: {o}");
                }
            }
        }
    }
}

/// With s_i ≥ c everywhere, or the variance of the mean at or under the threshold, both
/// implementations return the unfiltered pixel exactly.
#[test]
fn converged_pixels_pass_through_exactly() {
    let (w, h) = (48u32, 32u32);
    let reference = synth::reference(synth::Pattern::Edges, w, h);
    let dgi = vec![1.0f32; (w * h) as usize];
    let acc = synth::accumulate(&reference, w, h, |_| 1.0, 16, 3);
    let raw = filter::unfiltered_cpu(&acc);
    for kind in [FilterKind::Exact, FilterKind::Fast] {
        let count = FilterParams {
            kind,
            k_max: 16.0,
            c: 16.0,
            ..Default::default()
        };
        assert_eq!(filter::filter_cpu(&count, &acc, &dgi).unwrap(), raw);
        // The largest variance of the mean in the image as the threshold: nothing is filtered.
        let vmax = (0..(w * h) as usize)
            .map(|i| filter::variance_of_mean(acc.sum[i], acc.count[i]).unwrap())
            .fold(0.0, f64::max);
        let variance = FilterParams {
            blend: Blend::Variance,
            variance_threshold: (vmax as f32) * 1.0001,
            ..count
        };
        assert_eq!(filter::filter_cpu(&variance, &acc, &dgi).unwrap(), raw);
        // Just under some pixels' variance, those pixels are filtered (the test can fail).
        let some = FilterParams {
            variance_threshold: (vmax as f32) * 0.5,
            ..variance
        };
        assert_ne!(filter::filter_cpu(&some, &acc, &dgi).unwrap(), raw);
    }
}

#[test]
fn bad_inputs_are_rejected_with_the_field_named() {
    let acc = Accumulation::new(4, 4);
    let p = FilterParams::default();
    let e = filter::filter_cpu(&p, &acc, &[0.0; 15]).unwrap_err();
    assert!(e.to_string().contains("15 values"), "{e}");
    let mut dgi = vec![0.5; 16];
    dgi[6] = 1.5;
    let e = filter::filter_cpu(&p, &acc, &dgi).unwrap_err();
    assert!(e.to_string().contains("(2, 1)"), "{e}");
    let e = filter::filter_cpu(&FilterParams { c: -1.0, ..p }, &acc, &[0.0; 16]).unwrap_err();
    assert!(e.to_string().contains("--filter-c"), "{e}");
}
