use super::crops::crop_corners;
use super::*;

/// relMSE in closed form: a uniform offset δ on a uniform reference r gives
/// δ² / (r² + 0.01) in every channel; the mask picks the pixels.
#[test]
fn rel_mse_closed_form_and_mask() {
    let r = Vec3::new(0.5, 0.2, 1.0);
    let reference = vec![r; 6];
    let mut image = vec![r + Vec3::splat(0.1); 6];
    image[5] = Vec3::splat(100.0);
    let mask = [true, true, true, true, true, false];
    let want = [0.5f64, 0.2, 1.0]
        .iter()
        .map(|r| 0.01 / (r * r + 0.01))
        .sum::<f64>()
        / 3.0;
    let got = rel_mse(&image, &reference, &mask);
    assert!((got - want).abs() < 1e-6 * want, "{got} vs {want}");
    assert_eq!(rel_mse(&reference, &reference, &mask), 0.0);
    assert!(rel_mse(&image, &reference, &[false; 6]).is_nan());
    // Black reference: the offset keeps it finite.
    let black = vec![Vec3::ZERO; 2];
    let one = vec![Vec3::splat(0.1); 2];
    assert!((rel_mse(&one, &black, &[true; 2]) - 1.0).abs() < 1e-6);
}

fn noisy(base: u8, amplitude: i32, n: usize, seed: u32) -> Vec<u8> {
    let mut state = seed;
    (0..n)
        .map(|_| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let u = (state >> 8) as i32 % (2 * amplitude + 1) - amplitude;
            (i32::from(base) + u).clamp(0, 255) as u8
        })
        .collect()
}

/// ꟻLIP's analytic cases: a picture against itself is 0 everywhere; black against white is
/// the same at every pixel, NVIDIA's implementation's 0.9674 (its colour term alone, as a
/// uniform picture has no edges or points); more noise is more error.
#[test]
fn flip_analytic_cases() {
    let (w, h) = (32u32, 24u32);
    let n = (w * h * 3) as usize;
    let grey = vec![118u8; n];
    assert!(flip_map(&grey, &grey, w, h).iter().all(|&v| v == 0.0));
    let noise = noisy(118, 40, n, 7);
    assert!(flip_map(&noise, &noise, w, h).iter().all(|&v| v == 0.0));
    let bw = flip_map(&vec![0; n], &vec![255; n], w, h);
    assert_eq!(bw.len(), (w * h) as usize);
    for v in &bw {
        assert!((v - 0.9674).abs() < 1e-3, "black vs white: {v}");
    }
    let all = vec![true; (w * h) as usize];
    let mut last = 0.0;
    for amplitude in [2, 8, 24, 64] {
        let m = masked_mean(&flip_map(&grey, &noisy(118, amplitude, n, 3), w, h), &all);
        assert!(m > last && m <= 1.0, "noise ±{amplitude}: {m} after {last}");
        last = m;
    }
}

#[test]
fn bad_settings_name_their_flag() {
    let bad = [
        (
            DenoiseBenchConfig {
                size: [8, 8],
                ..Default::default()
            },
            "--size",
        ),
        (
            DenoiseBenchConfig {
                iterations: vec![1, 512],
                ..Default::default()
            },
            "--iterations",
        ),
        (
            DenoiseBenchConfig {
                iterations: vec![4, 1],
                ..Default::default()
            },
            "--iterations",
        ),
        (
            DenoiseBenchConfig {
                timing_sizes: vec![[7680, 4320]],
                ..Default::default()
            },
            "--timing-sizes",
        ),
        (
            DenoiseBenchConfig {
                crops_iterations: 3,
                ..Default::default()
            },
            "--crops-iterations",
        ),
        (
            DenoiseBenchConfig {
                reference_spp: 0,
                ..Default::default()
            },
            "--reference-spp",
        ),
        (
            DenoiseBenchConfig {
                fovs_deg: vec![f64::NAN],
                ..Default::default()
            },
            "--fov",
        ),
    ];
    for (cfg, flag) in bad {
        let e = cfg.validate().unwrap_err().to_string();
        assert!(e.starts_with(flag), "{e}");
    }
    DenoiseBenchConfig::default().validate().unwrap();
}

#[test]
fn crops_fit_the_picture() {
    for size in [[48, 27], [320, 180], [16, 16]] {
        let (side, scale) = crop_geometry(size);
        assert!(side <= size[0] && side <= size[1] && side * scale >= CROP_SHOWN);
        let dgi: Vec<f32> = (0..size[0] * size[1])
            .map(|p| if p % size[0] > size[0] / 2 { 0.0 } else { 0.5 })
            .collect();
        let (e, p) = crop_corners(&dgi, size, side);
        for [x, y] in [e, p] {
            assert!(x + side <= size[0] && y + side <= size[1]);
        }
    }
}
