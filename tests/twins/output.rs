//! The display kernel (`shaders/output/srgb8.wgsl`) against its CPU twin
//! (`output::srgb8::display_rgba`). Tolerance: **exact** — the kernel reads the twin's own table
//! and compares IEEE patterns as integers, and the exposure's product is one correctly rounded
//! multiplication on both sides, so every byte must match, NaN and infinities included.

use glam::Vec3;
use raygun::gpu::GpuContext;
use raygun::output::gpu::DisplayKernel;
use raygun::output::srgb8::{display_rgba, linear_to_srgb8};

/// The values where a conversion can go wrong: every float within 40 patterns of each of
/// the 255 steps (after the exposure's scale), and the edges.
fn hard_values(scale: f32) -> Vec<f32> {
    let mut v = Vec::new();
    for k in 1..=255u32 {
        // The least float of code k, by bisection over (0, 1].
        let (mut a, mut z) = (0u32, 1f32.to_bits());
        while z - a > 1 {
            let m = a + (z - a) / 2;
            if linear_to_srgb8(f32::from_bits(m)) >= k as u8 {
                z = m;
            } else {
                a = m;
            }
        }
        for d in 0..40 {
            v.push(f32::from_bits(z + d) / scale);
            v.push(f32::from_bits(z - d) / scale);
        }
    }
    v.extend([
        0.0,
        -0.0,
        -1.0,
        f32::MIN_POSITIVE,
        1.0,
        1.0 + f32::EPSILON,
        2.0,
        f32::MAX,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        -f32::NAN,
        f32::from_bits(0x7FC0_0001),
        0.5,
    ]);
    v
}

/// Byte for byte the CPU twin's conversion, at several exposures, on every hard value in
/// every channel.
#[test]
fn equals_the_cpu_twin_on_the_hard_values() {
    let ctx = GpuContext::for_tests();
    let kernel = DisplayKernel::new(&ctx);
    for exposure in [0.0f32, 1.0, -0.5, 2.25] {
        let v = hard_values(exposure.exp2());
        // Each value in each channel, the channels shifted against each other.
        let n = v.len();
        let image: Vec<Vec3> = (0..n)
            .map(|i| Vec3::new(v[i], v[(i + 1) % n], v[(i + 7) % n]))
            .collect();
        let gpu = kernel.convert(&ctx, &image, exposure, None, None).unwrap();
        let cpu = display_rgba(&image, exposure);
        assert_eq!(gpu.len(), cpu.len());
        if let Some(i) = (0..gpu.len()).find(|&i| gpu[i] != cpu[i]) {
            let p = image[i / 4];
            panic!(
                "exposure {exposure}: pixel {} channel {}: GPU {} CPU {} (pixel {p:?})",
                i / 4,
                i % 4,
                gpu[i],
                cpu[i]
            );
        }
    }
}

/// The ROI's outline painted by the display kernel is the twin's `roi_outline` painted over
/// `display_rgba`, byte for byte: ROI shapes with edges on the picture's border, single ROI
/// pixels and pixels next to d = 0 exactly, over a wall camera's mask (the outline is painted
/// over unshown pixels too, as the host path does).
#[test]
fn the_outline_is_the_twins_exactly() {
    use raygun::output::srgb8::{paint_outline, roi_outline};
    let ctx = GpuContext::for_tests();
    let kernel = DisplayKernel::new(&ctx);
    let (w, h) = (67u32, 45u32);
    let n = (w * h) as usize;
    let image: Vec<Vec3> = (0..n)
        .map(|i| Vec3::new((i % 7) as f32 / 7.0, (i % 11) as f32 / 11.0, 0.5))
        .collect();
    // A disc touching the left border, a band along the bottom row, lone ROI pixels, and d
    // values of 0 exactly, just above 0 and negative zero (an ROI pixel).
    let dgi: Vec<f32> = (0..n)
        .map(|i| {
            let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
            if (x - 3.0).hypot(y - 20.0) < 9.0 || y == (h - 1) as f32 {
                if (x as u32).is_multiple_of(5) {
                    -0.0
                } else {
                    0.0
                }
            } else if (x as u32, y as u32) == (40, 10) || (x as u32, y as u32) == (60, 0) {
                0.0
            } else {
                1e-7 + x / 100.0
            }
        })
        .collect();
    let mask: Vec<u32> = (0..(n as u32).div_ceil(32))
        .map(|k| 0x9E37_79B9u32.wrapping_mul(k + 3))
        .collect();
    let outline = roi_outline(&dgi, [w, h]);
    assert!(outline.len() > 40, "{} outline pixels", outline.len());
    for masked in [false, true] {
        let shown = masked.then_some(&mask[..]);
        let gpu = kernel
            .convert(&ctx, &image, 0.5, shown, Some((&dgi, [w, h])))
            .unwrap();
        let mut cpu = display_rgba(&image, 0.5);
        if masked {
            for p in 0..n {
                if mask[p / 32] & (1 << (p % 32)) == 0 {
                    cpu[4 * p..4 * p + 4].copy_from_slice(&[0, 0, 0, 255]);
                }
            }
        }
        paint_outline(&mut cpu, &outline);
        if let Some(i) = (0..gpu.len()).find(|&i| gpu[i] != cpu[i]) {
            panic!(
                "masked {masked}: pixel {} ({}, {}) byte {}: GPU {} CPU {}",
                i / 4,
                (i / 4) as u32 % w,
                (i / 4) as u32 / w,
                i % 4,
                gpu[i],
                cpu[i]
            );
        }
        // Without the outline asked for, the same DGI paints nothing.
        let plain = kernel.convert(&ctx, &image, 0.5, shown, None).unwrap();
        assert_ne!(plain, gpu);
    }
}

// ---------------------------------------------------------------------------------------------
// The ROI's statistics (`shaders/output/stats.wgsl`) against `RoiStats::measure`. Tolerance:
// the totals (pixels, samples, fewest samples, noisy pixels) **exact**; the medians within
// `SE_TOLERANCE` relative — each pixel's SE is the CPU's f64 variance against the kernel's f32
// one with the cancelling product carried exactly, and an order statistic of values that each
// lie within a relative bound lies within it too. The select itself is exact: a wrong rank
// would land on a neighbouring value, which on these images lies 100–1000× farther.

mod stats {
    use glam::Vec3;
    use raygun::filter::synth;
    use raygun::gpu::GpuContext;
    use raygun::output::gpu::StatsKernel;
    use raygun::output::stats::RoiStats;

    use crate::roi_stats::same;
    use raygun::trace::accum::Accumulation;

    const W: u32 = 96;
    const H: u32 = 64;

    /// A ROI disc of radius 9 pixels (d = 0), then d rising linearly to 1 at 40 pixels: every
    /// class of pixel (ROI, between, periphery for the p_min used) in numbers.
    fn dgi() -> Vec<f32> {
        (0..W * H)
            .map(|i| {
                let (x, y) = ((i % W) as f32 - 40.0, (i / W) as f32 - 30.0);
                ((x.hypot(y) - 9.0) / 31.0).clamp(0.0, 1.0)
            })
            .collect()
    }

    fn accumulations(dgi: &[f32]) -> Vec<(&'static str, Accumulation)> {
        let smooth = synth::reference(synth::Pattern::Smooth, W, H);
        let edges = synth::reference(synth::Pattern::Edges, W, H);
        let black = vec![Vec3::ZERO; (W * H) as usize];
        vec![
            (
                "edges, p = max(0.1, 1 − d), 9 rounds",
                synth::accumulate(&edges, W, H, |i| (1.0 - dgi[i]).max(0.1), 9, 1),
            ),
            (
                "smooth, p = max(0.3, 1 − d), 4 rounds",
                synth::accumulate(&smooth, W, H, |i| (1.0 - dgi[i]).max(0.3), 4, 2),
            ),
            // Constant pixels: SE 0 everywhere, no noisy pixel in any region.
            (
                "black, 3 rounds",
                synth::accumulate(&black, W, H, |_| 1.0, 3, 3),
            ),
        ]
    }

    /// A shown mask with about a third of the pixels unshown.
    fn mask() -> Vec<u32> {
        (0..(W * H).div_ceil(32))
            .map(|w| 0x9E37_79B9u32.wrapping_mul(w + 1) | 0x0101_0101)
            .collect()
    }

    fn is_shown(mask: &[u32], i: usize) -> bool {
        mask[i / 32] & (1 << (i % 32)) != 0
    }

    #[test]
    fn roi_statistics_match_their_cpu_twin() {
        let ctx = GpuContext::for_tests();
        let kernel = StatsKernel::new(&ctx);
        let dgi = dgi();
        let mask = mask();
        let mut measured = 0;
        for (label, acc) in accumulations(&dgi) {
            for p_min in [0.1f32, 0.3, 1.0] {
                for masked in [false, true] {
                    let label = format!("{label}, p_min {p_min}, masked {masked}");
                    let shown = |i: usize| !masked || is_shown(&mask, i);
                    let cpu = RoiStats::measure(&acc, &dgi, p_min, shown);
                    let gpu = kernel
                        .measure_upload(&ctx, &acc, &dgi, p_min, masked.then_some(&mask[..]))
                        .unwrap();
                    same(&label, &cpu, &gpu);
                    measured += usize::from(cpu.contrast.is_some());
                    eprintln!("{label}: {cpu:?}");
                }
            }
        }
        // The noisy images have both regions at p_min 0.1 and 0.3, masked or not.
        assert!(
            measured >= 8,
            "{measured} measurements had a noise contrast"
        );
    }

    /// Odd and even set sizes (the median's mean of the two middle values), one value, and
    /// regions with no pixel: the ROI's progress without ROI, no periphery at p_min = 1.
    #[test]
    fn medians_of_every_set_size_and_empty_regions() {
        let ctx = GpuContext::for_tests();
        let kernel = StatsKernel::new(&ctx);
        let edges = synth::reference(synth::Pattern::Edges, W, H);
        let acc = synth::accumulate(&edges, W, H, |_| 1.0, 5, 7);
        let n = (W * H) as usize;
        for roi in [0usize, 1, 2, 3, 4, 7, 64, 65] {
            // `roi` ROI pixels spread over the image, the rest periphery (d = 1).
            let mut dgi = vec![1.0f32; n];
            for k in 0..roi {
                dgi[(k * 97 + 13) % n] = 0.0;
            }
            for p_min in [0.1f32, 1.0] {
                let label = format!("{roi} ROI pixels, p_min {p_min}");
                let cpu = RoiStats::measure(&acc, &dgi, p_min, |_| true);
                let gpu = kernel
                    .measure_upload(&ctx, &acc, &dgi, p_min, None)
                    .unwrap();
                same(&label, &cpu, &gpu);
                assert_eq!(cpu.progress.is_some(), roi > 0, "{label}");
            }
        }
    }
}
