//! The denoiser's kernel against its CPU twin (lavapipe here: small images; without an adapter
//! these tests fail, they do not skip).

use super::*;
use crate::filter::denoise::{Class, denoise_cpu, own, synth_scene};
use crate::gpu::wgsl::{assert_same_layout, validated};

/// |GPU − CPU| ≤ TWIN_ABS + TWIN_REL·|CPU| per channel. Both run the same f32 operations in the
/// same order; the GPU rounds `exp`, `sqrt` and division to a few ulp (Vulkan allows 3 + 2|x|
/// ulp for exp, 2.5 for division) and may contract multiply-adds, and five passes of weighted
/// means of ≤ 25 taps each carry those differences along: of order 1e-6 relative. The
/// discrete decisions (the cuts, the class) sit far from their thresholds on these inputs.
const TWIN_ABS: f32 = 1e-6;
const TWIN_REL: f32 = 1e-4;

fn poisoned_scene(w: u32, h: u32, rounds: u32, p: f32, seed: u32) -> super::super::SynthScene {
    let mut s = synth_scene(w, h, rounds, p, seed);
    let n = (w * h) as usize;
    for (k, i) in [n / 7, n / 3, n / 2 + 5, n - 1].into_iter().enumerate() {
        s.acc.sum[i][k % 4] = if k % 2 == 0 { f32::NAN } else { f32::INFINITY };
        s.acc.count[i] = 2;
    }
    s
}

#[test]
fn the_kernel_matches_its_cpu_twin() {
    let ctx = GpuContext::for_tests();
    let kernels = DenoiseKernels::new(&ctx);
    let cases = [
        (
            "sparse, 1 round at p = 0.5",
            poisoned_scene(72, 56, 1, 0.5, 1),
        ),
        ("2 samples a pixel", poisoned_scene(64, 48, 2, 1.0, 2)),
        ("16 rounds at p = 0.7", poisoned_scene(48, 64, 16, 0.7, 3)),
    ];
    for (name, scene) in &cases {
        for passes in [5, 2] {
            let params = DenoiseParams {
                passes,
                variance_threshold: 2e-3,
            };
            let input = DenoiseInput::new(&scene.acc, &scene.features).unwrap();
            let cpu = denoise_cpu(&params, &input).unwrap();
            let gpu = kernels.denoise(&ctx, &params, &input).unwrap();
            assert_eq!(gpu.dropped, cpu.dropped, "{name}");
            assert_eq!(gpu.dropped, 4, "{name}");
            let mut worst = 0.0f32;
            for (i, (c, g)) in cpu.image.iter().zip(&gpu.image).enumerate() {
                assert_eq!(g[3], 1.0, "{name}: alpha at pixel {i}");
                for ch in 0..3 {
                    let tol = TWIN_ABS + TWIN_REL * c[ch].abs();
                    let err = (c[ch] - g[ch]).abs();
                    assert!(
                        err <= tol,
                        "{name}, {passes} passes: pixel ({}, {}) channel {ch}: CPU {} GPU {}",
                        i as u32 % input.width,
                        i as u32 / input.width,
                        c[ch],
                        g[ch]
                    );
                    worst = worst.max(err / tol);
                }
            }
            eprintln!("{name}, {passes} passes: worst error {worst:.4} of the tolerance");
        }
    }
}

/// Converged pixels come out of the kernel as the GPU's own mean image (the filter's `off`
/// kernel, `accum.xyz / f32(count)`), bit for bit.
#[test]
fn the_kernel_passes_converged_pixels_through_bit_for_bit() {
    use crate::filter::gpu::FilterKernels;
    use crate::filter::{FilterKind, FilterParams};
    let ctx = GpuContext::for_tests();
    let scene = synth_scene(48, 40, 64, 1.0, 4);
    // With 64 samples about half the lit pixels are under this τ.
    let tau = 8e-4;
    let params = DenoiseParams {
        variance_threshold: tau,
        ..Default::default()
    };
    let input = DenoiseInput::new(&scene.acc, &scene.features).unwrap();
    let gpu = DenoiseKernels::new(&ctx)
        .denoise(&ctx, &params, &input)
        .unwrap();
    let off = FilterParams {
        kind: FilterKind::Off,
        ..Default::default()
    };
    let means = FilterKernels::new(&ctx)
        .filter(&ctx, &off, &scene.acc, &vec![0.0; 48 * 40])
        .unwrap();
    let mut converged = 0;
    for (i, mean) in means.iter().enumerate() {
        if let Class::Converged(_) = own(tau, scene.acc.sum[i], scene.acc.count[i]).1 {
            assert_eq!(gpu.image[i].map(f32::to_bits), mean.map(f32::to_bits));
            converged += 1;
        }
    }
    eprintln!("{converged} converged pixels");
    assert!(converged > 200, "{converged}");
}

/// On a device whose binding holds 150 rows of a 180-row picture, the kernel runs in bands
/// with the halo, and gives the one-go picture (on a device that fits it) bit for bit.
#[test]
fn the_kernel_in_bands_equals_it_in_one_go() {
    let (w, h) = (24, 180);
    let scene = poisoned_scene(w, h, 2, 0.6, 5);
    let input = DenoiseInput::new(&scene.acc, &scene.features).unwrap();
    let ctx = GpuContext::for_tests();
    let small = GpuContext::with_max_binding(16 * u64::from(w) * 150).unwrap();
    for passes in [5, 3] {
        let params = DenoiseParams {
            passes,
            ..Default::default()
        };
        assert!(!fits_one_binding(&small, [w, h]));
        let whole = DenoiseKernels::new(&ctx)
            .denoise(&ctx, &params, &input)
            .unwrap();
        let banded = DenoiseKernels::new(&small)
            .denoise_banded(&small, &params, &input)
            .unwrap();
        assert_eq!(banded.dropped, 4);
        assert!(banded == whole, "{passes} passes");
    }
}

/// A binding too small for one band with its halo is a clear error, not a wrong picture.
#[test]
fn a_binding_smaller_than_the_halo_is_an_error() {
    let scene = synth_scene(16, 200, 1, 1.0, 6);
    let input = DenoiseInput::new(&scene.acc, &scene.features).unwrap();
    let small = GpuContext::with_max_binding(16 * 16 * 100).unwrap();
    let e = DenoiseKernels::new(&small)
        .denoise_banded(&small, &DenoiseParams::default(), &input)
        .unwrap_err();
    assert!(e.to_string().contains("halo"), "{e}");
}

/// The kernel parses and validates without a GPU, and its parameter struct has the Rust
/// twin's layout.
#[test]
fn the_kernel_validates_and_its_params_match_rust() {
    let m = validated("denoise.wgsl", DENOISE_WGSL);
    assert_same_layout(
        &m,
        "DenoiseParams",
        &crate::rust_layout!(GpuDenoiseParams; size, step, last, variance_threshold, _pad0,
            count_rows),
    );
}

/// The WGSL constants repeat the Rust ones.
#[test]
fn shader_constants_match_rust() {
    use crate::filter::denoise::{
        ALBEDO_CUT, DEPTH_CUT, NORMAL_CUT, SIGMA_A, SIGMA_L, SIGMA_Z, TAPS,
    };
    for (name, v) in [
        ("SIGMA_L", SIGMA_L),
        ("SIGMA_A", SIGMA_A),
        ("ALBEDO_CUT", ALBEDO_CUT),
        ("NORMAL_CUT", NORMAL_CUT),
        ("SIGMA_Z", SIGMA_Z),
        ("DEPTH_CUT", DEPTH_CUT),
    ] {
        let line = format!("const {name}: f32 = {v:?};");
        assert!(DENOISE_WGSL.contains(&line), "{line}");
    }
    let taps = format!(
        "array<f32, 5>({:?}, {:?}, {:?}, {:?}, {:?})",
        TAPS[0], TAPS[1], TAPS[2], TAPS[3], TAPS[4]
    );
    assert!(DENOISE_WGSL.contains(&taps), "{taps}");
}
