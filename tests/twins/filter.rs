//! GPU filter kernels against their CPU twins (lavapipe in CI: small images, k_max ≤ 16).

use glam::DVec3;
use raygun::filter::gpu::FilterKernels;
use raygun::filter::{self, Blend, FilterKind, FilterParams, synth};
use raygun::gpu::GpuContext;
use raygun::trace::accum::Accumulation;

const W: u32 = 96;
const H: u32 = 64;

/// |GPU − CPU| ≤ TWIN_ABS + TWIN_REL·|CPU| per channel. Both sum the same taps; the kernels do
/// it in f32 (weights exp() to a few ulp, sums of up to 217 taps for k = 8, or the pyramid's
/// 14 passes of ≤ 19 taps), the twins in f64: a relative error of order 1e-6, plus f32 blend
/// weights and radii. Radii are dyadic here (d = j/64, c = 8, k_max integer), so the window's
/// discrete decisions (r² ≤ k², k ≤ K_DIRECT, the level bracket) are identical on both sides.
const TWIN_ABS: f64 = 1e-6;
const TWIN_REL: f64 = 2e-5;

/// A DGI with dyadic values: a ramp from the centre, quantised to 1/64.
fn dyadic_dgi() -> Vec<f32> {
    (0..W * H)
        .map(|i| {
            let (x, y) = (
                (i % W) as f32 - W as f32 / 2.0,
                (i / W) as f32 - H as f32 / 2.0,
            );
            let d = ((x * x + y * y).sqrt() / (0.4 * W as f32)).min(1.0);
            (d * 64.0).round() / 64.0
        })
        .collect()
}

fn inputs() -> Vec<(&'static str, Accumulation)> {
    let dgi = dyadic_dgi();
    let smooth = synth::reference(synth::Pattern::Smooth, W, H);
    let edges = synth::reference(synth::Pattern::Edges, W, H);
    vec![
        (
            "sparse edges (10 %, one round)",
            synth::accumulate(&edges, W, H, |_| 0.1, 1, 1),
        ),
        (
            "smooth, p = 1 − d, 6 rounds",
            synth::accumulate(&smooth, W, H, |i| 1.0 - dgi[i], 6, 2),
        ),
        (
            "edges, p = 1 − d, 12 rounds",
            synth::accumulate(&edges, W, H, |i| 1.0 - dgi[i], 12, 3),
        ),
    ]
}

fn compare(label: &str, cpu: &[DVec3], gpu: &[[f32; 4]]) {
    assert_eq!(cpu.len(), gpu.len());
    let mut worst = 0.0f64;
    for (i, (c, g)) in cpu.iter().zip(gpu).enumerate() {
        assert_eq!(g[3], 1.0, "{label}: alpha at pixel {i}");
        for ch in 0..3 {
            let (c, g) = (c[ch], f64::from(g[ch]));
            let err = (c - g).abs();
            assert!(
                err <= TWIN_ABS + TWIN_REL * c.abs(),
                "{label}: pixel ({}, {}) channel {ch}: CPU {c} GPU {g}",
                i as u32 % W,
                i as u32 / W
            );
            worst = worst.max(err / (TWIN_ABS + TWIN_REL * c.abs()));
        }
    }
    eprintln!("{label}: worst error {worst:.3} of the tolerance");
}

#[test]
fn gpu_kernels_match_their_cpu_twins() {
    let ctx = GpuContext::for_tests();
    let kernels = FilterKernels::new(&ctx);
    let dgi = dyadic_dgi();
    for (name, acc) in inputs() {
        for (kind, k_max) in [
            (FilterKind::Off, 8.0),
            (FilterKind::Exact, 8.0),
            (FilterKind::Fast, 8.0),
            (FilterKind::Fast, 16.0),
        ] {
            for blend in [Blend::Count, Blend::Variance] {
                let params = FilterParams {
                    kind,
                    blend,
                    k_max,
                    c: 8.0,
                    variance_threshold: 1e-2,
                };
                let cpu = filter::filter_cpu(&params, &acc, &dgi).unwrap();
                let gpu = kernels.filter(&ctx, &params, &acc, &dgi).unwrap();
                compare(
                    &format!("{name}, {kind:?} {blend:?} k_max {k_max}"),
                    &cpu,
                    &gpu,
                );
            }
        }
    }
}

/// s ≥ c (or variance under the threshold) everywhere: the GPU filters return the GPU's own
/// unfiltered image bit for bit.
#[test]
fn gpu_converged_pixels_pass_through_exactly() {
    let ctx = GpuContext::for_tests();
    let kernels = FilterKernels::new(&ctx);
    let dgi = vec![1.0f32; (W * H) as usize];
    let edges = synth::reference(synth::Pattern::Edges, W, H);
    let acc = synth::accumulate(&edges, W, H, |_| 1.0, 8, 4);
    let off = FilterParams {
        kind: FilterKind::Off,
        k_max: 16.0,
        c: 8.0,
        variance_threshold: 1e6,
        ..Default::default()
    };
    let raw = kernels.filter(&ctx, &off, &acc, &dgi).unwrap();
    for kind in [FilterKind::Exact, FilterKind::Fast] {
        for blend in [Blend::Count, Blend::Variance] {
            let p = FilterParams { kind, blend, ..off };
            assert!(
                kernels.filter(&ctx, &p, &acc, &dgi).unwrap() == raw,
                "{kind:?} {blend:?} changed a converged pixel"
            );
        }
        // One sample fewer than c: filtered (the comparison above can fail).
        let p = FilterParams {
            kind,
            c: 9.0,
            ..off
        };
        assert!(kernels.filter(&ctx, &p, &acc, &dgi).unwrap() != raw);
    }
}

/// A picture larger than the adapter's bindings is filtered in bands of rows with halos
/// (`FilterKernels::filter_banded`): on a device whose binding holds 260 of its 700 rows, the
/// exact filter's bands give the one-binding kernels' values bit for bit, the fast filter's
/// agree with them and with the CPU twin within the twin tolerance (its final read forms level
/// coordinates in f32 from band rows).
#[test]
fn a_picture_larger_than_one_binding_is_filtered_in_bands() {
    const BW: u32 = 96;
    const BH: u32 = 700;
    let small = GpuContext::with_max_binding(16 * u64::from(BW) * 260).unwrap();
    let whole = GpuContext::for_tests();
    let (ks, kw) = (FilterKernels::new(&small), FilterKernels::new(&whole));
    let dgi: Vec<f32> = (0..BW * BH)
        .map(|i| (((i / BW) % 128) as f32 / 127.0 * 64.0).round() / 64.0)
        .collect();
    let edges = synth::reference(synth::Pattern::Edges, BW, BH);
    let acc = synth::accumulate(&edges, BW, BH, |i| 1.0 - dgi[i], 6, 5);
    for (kind, k_max) in [
        (FilterKind::Exact, 8.0),
        (FilterKind::Fast, 8.0),
        (FilterKind::Fast, 16.0),
        (FilterKind::Fast, 32.0),
    ] {
        let params = FilterParams {
            kind,
            blend: Blend::Count,
            k_max,
            c: 8.0,
            variance_threshold: 1e-2,
        };
        let label = format!("{kind:?} k_max {k_max}");
        assert!(
            ks.filter(&small, &params, &acc, &dgi).is_err(),
            "{label}: the image does not fit the small device in one piece"
        );
        let banded = ks.filter_banded(&small, &params, &acc, &dgi).unwrap();
        let one = kw.filter(&whole, &params, &acc, &dgi).unwrap();
        if kind == FilterKind::Exact {
            assert!(banded == one, "{label}: banded exact filter differs");
        }
        let cpu = filter::filter_cpu(&params, &acc, &dgi).unwrap();
        let one64: Vec<DVec3> = one
            .iter()
            .map(|p| DVec3::new(p[0].into(), p[1].into(), p[2].into()))
            .collect();
        for (reference, what) in [(&cpu, "CPU twin"), (&one64, "one binding")] {
            for (i, (c, g)) in reference.iter().zip(&banded).enumerate() {
                for ch in 0..3 {
                    let (c, g) = (c[ch], f64::from(g[ch]));
                    assert!(
                        (c - g).abs() <= TWIN_ABS + TWIN_REL * c.abs(),
                        "{label} against the {what}: pixel ({}, {}) channel {ch}: {c} vs {g}",
                        i as u32 % BW,
                        i as u32 / BW
                    );
                }
            }
        }
    }
}
