//! Selection statistics of the schedule on both backends: per-region counts within binomial
//! bounds of p, per-pixel counts as dispersed as independent iterations give, p = 1 pixels in
//! every iteration and p = 0 pixels in none.
//!
//! The bounds. In a region of n pixels with one probability p, the selections over N
//! iterations are a sum of nN independent Bernoulli(p) draws if the hash behaves like a random
//! function. The test accepts the count S when it lies inside both Chernoff intervals (for S
//! with mean μ = nNp and for the non-selections n N − S with mean nN(1 − p)):
//! P(S ≥ (1 + δ)μ) ≤ exp(−δ²μ / (2 + δ)) and P(S ≤ (1 − δ)μ) ≤ exp(−δ²μ / 2), each δ
//! solved for a tail probability α. These hold for every n, N and p (no normal
//! approximation). Bonferroni: four tails per region and at most `MAX_CHECKS` region checks
//! per test, so α = FAMILY_ALPHA / (4 · MAX_CHECKS) keeps the chance that a correct schedule
//! fails a test below FAMILY_ALPHA. (The hash is deterministic, so a given seed either passes
//! or fails forever; the bound says how unlikely a failure of a correct sampler would be.)
//!
//! Per-pixel counts c_i ~ Binomial(N, p) give X = Σ (c_i − Np)² / (Np(1 − p)) with mean n and
//! variance n(2 − 6/N + 1/(Np(1 − p))). Iterations that reused each other's coin flips (the
//! iteration left out of the hash) would push every c_i to 0 or N and X to about nN, which the
//! region counts alone cannot see. X is a sum of n independent terms (n ≥ 1024 here), so the
//! test allows ±DISPERSION_SIGMAS standard deviations (normal approximation, stated as such).

use raygun::gpu::GpuContext;
use raygun::schedule::gpu::{ScheduleConfig, ScheduleKernel};
use raygun::schedule::{Order, probability, schedule_cpu};
use wgpu::util::DeviceExt;

/// Chance that a correct sampler fails one test.
const FAMILY_ALPHA: f64 = 1e-6;
/// Region checks per test at most (regions × p_min settings).
const MAX_CHECKS: f64 = 32.0;
const DISPERSION_SIGMAS: f64 = 6.0;

/// Eight vertical bands of 16 × 64 pixels, one DGI value each: p = 1, p = 0 (with p_min = 0)
/// and values between, including a small p that gives few selections.
const BAND_D: [f32; 8] = [0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 0.97, 1.0];
const WIDTH: u32 = 128;
const HEIGHT: u32 = 64;

fn band_dgi() -> Vec<f32> {
    (0..WIDTH * HEIGHT)
        .map(|i| BAND_D[((i % WIDTH) / 16) as usize])
        .collect()
}

fn band_of(pixel: u32) -> usize {
    ((pixel % WIDTH) / 16) as usize
}

/// The Chernoff interval for a sum of `trials` Bernoulli(p) draws at tail probability `alpha`.
fn chernoff(trials: f64, p: f64, alpha: f64) -> (f64, f64) {
    let l = (1.0 / alpha).ln();
    let bounds = |mu: f64| {
        if mu == 0.0 {
            return (0.0, 0.0);
        }
        let up = (l + (l * l + 8.0 * mu * l).sqrt()) / (2.0 * mu);
        let down = (2.0 * l / mu).sqrt();
        ((1.0 - down) * mu, (1.0 + up) * mu)
    };
    let (lo_s, hi_s) = bounds(trials * p);
    let (lo_f, hi_f) = bounds(trials * (1.0 - p));
    (lo_s.max(trials - hi_f), hi_s.min(trials - lo_f))
}

/// Checks the per-band statistics of per-pixel selection counts over `iterations`; returns
/// the failed checks.
fn check_counts(counts: &[u32], iterations: u32, p_min: f32, backend: &str) -> Vec<String> {
    let mut failures = Vec::new();
    let alpha = FAMILY_ALPHA / (4.0 * MAX_CHECKS);
    let n_band = f64::from(16 * HEIGHT);
    let big_n = f64::from(iterations);
    for (band, &d) in BAND_D.iter().enumerate() {
        let p = probability(d, p_min);
        let what = format!("{backend}: band {band} (d {d}, p_min {p_min}, p {p})");
        let pixels: Vec<u32> = (0..WIDTH * HEIGHT)
            .filter(|&px| band_of(px) == band)
            .map(|px| counts[px as usize])
            .collect();
        if p >= 1.0 {
            if pixels.iter().any(|&c| c != iterations) {
                failures.push(format!("{what}: p = 1 pixel missed"));
            }
            continue;
        }
        if p <= 0.0 {
            if pixels.iter().any(|&c| c != 0) {
                failures.push(format!("{what}: p = 0 pixel sampled"));
            }
            continue;
        }
        let p = f64::from(p);
        let total: f64 = pixels.iter().map(|&c| f64::from(c)).sum();
        let (lo, hi) = chernoff(n_band * big_n, p, alpha);
        if !(lo..=hi).contains(&total) {
            failures.push(format!(
                "{what}: {total} selections, expected {:.0} in [{lo:.0}, {hi:.0}]",
                n_band * big_n * p
            ));
        }
        let var1 = big_n * p * (1.0 - p);
        let x: f64 = pixels
            .iter()
            .map(|&c| (f64::from(c) - big_n * p).powi(2) / var1)
            .sum();
        let sd = (n_band * (2.0 - 6.0 / big_n + 1.0 / var1)).sqrt();
        if (x - n_band).abs() > DISPERSION_SIGMAS * sd {
            failures.push(format!(
                "{what}: dispersion {x:.0}, expected {n_band} ± {:.0}",
                DISPERSION_SIGMAS * sd
            ));
        }
    }
    failures
}

#[test]
fn chernoff_interval_is_sane() {
    // Mean inside, width growing like the square root of the mean, degenerate at p = 0 and 1.
    let (lo, hi) = chernoff(10_000.0, 0.5, 1e-8);
    assert!(
        lo < 5000.0 && hi > 5000.0 && hi - lo < 1000.0,
        "[{lo}, {hi}]"
    );
    assert_eq!(chernoff(100.0, 1.0, 1e-8), (100.0, 100.0));
    assert_eq!(chernoff(100.0, 0.0, 1e-8), (0.0, 0.0));
}

#[test]
fn cpu_twin_counts_are_binomial_per_region() {
    let dgi = band_dgi();
    let iterations = 200;
    for (p_min, seed) in [(0.0, 1), (0.2, 2), (0.0, 0xdead_beef)] {
        let mut counts = vec![0u32; dgi.len()];
        for iteration in 0..iterations {
            for px in
                schedule_cpu(&dgi, WIDTH, HEIGHT, p_min, iteration, seed, Order::Coherent).unwrap()
            {
                counts[px as usize] += 1;
            }
        }
        let failures = check_counts(&counts, iterations, p_min, "CPU");
        assert!(failures.is_empty(), "{failures:#?}");
    }
}

/// The checks detect a sampler whose iterations repeat each other's decisions.
#[test]
fn a_schedule_that_ignores_the_iteration_fails_the_dispersion_check() {
    let dgi = band_dgi();
    let iterations = 50;
    let once = schedule_cpu(&dgi, WIDTH, HEIGHT, 0.0, 0, 1, Order::Coherent).unwrap();
    let mut counts = vec![0u32; dgi.len()];
    for px in once {
        counts[px as usize] += iterations;
    }
    let failures = check_counts(&counts, iterations, 0.0, "frozen");
    // Every band with 0 < p < 1 (six of eight) is caught by its dispersion.
    let dispersion = failures.iter().filter(|f| f.contains("dispersion")).count();
    assert_eq!(dispersion, 6, "{failures:#?}");
}

#[test]
fn gpu_counts_are_binomial_per_region() {
    let ctx = GpuContext::for_tests();
    let kernel = ScheduleKernel::new(&ctx);
    let dgi = band_dgi();
    let dgi_buf = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("band dgi"),
            contents: bytemuck::cast_slice(&dgi),
            usage: wgpu::BufferUsages::STORAGE,
        });
    // Fewer iterations than the CPU test (lavapipe): μ ≥ 1024 · 24 · 0.03 ≈ 740 selections in
    // the sparsest band keeps the interval tight.
    let iterations = 24;
    for (p_min, order) in [(0.0, Order::Coherent), (0.2, Order::Scattered)] {
        let run = kernel
            .prepare(
                &ctx,
                &dgi_buf,
                &ScheduleConfig {
                    width: WIDTH,
                    height: HEIGHT,
                    p_min,
                    order,
                    trace_workgroup_size: 64,
                    trace_max_groups: 0,
                },
            )
            .unwrap();
        let mut counts = vec![0u32; dgi.len()];
        for iteration in 0..iterations {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            run.record(&mut enc, iteration, 77, None);
            ctx.queue.submit([enc.finish()]);
            for px in run.read_list(&ctx).unwrap() {
                counts[px as usize] += 1;
            }
        }
        let failures = check_counts(&counts, iterations, p_min, &format!("GPU {order:?}"));
        assert!(failures.is_empty(), "{failures:#?}");
    }
}
