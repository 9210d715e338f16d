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
        let gpu = kernel.convert(&ctx, &image, exposure, None).unwrap();
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
