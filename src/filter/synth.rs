//! Synthetic "renders" for the filter's tests and benchmark until the guided renderer exists: a
//! known reference image, and an accumulation of noisy samples of it taken where a per-pixel
//! Bernoulli schedule says so.
//!
//! Noise model: each sample is the reference times an exponential variate of mean 1 (variance
//! 1 — the heavy relative noise of a few-bounce path tracer), so the sample mean converges to
//! the reference and its variance of the mean is ref²/s.

use glam::Vec3;
use rayon::prelude::*;

use crate::random::{pcg4d, stream, unit_f32};
use crate::trace::accum::Accumulation;

/// A reference image to sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Pattern {
    /// Smooth colour waves, a quarter of the image wide.
    Smooth,
    /// Hard edges: a two-colour checkerboard (cells 1/16 of the width) with a bright disc.
    Edges,
}

/// The reference image, row-major linear RGB.
#[must_use]
pub fn reference(pattern: Pattern, width: u32, height: u32) -> Vec<Vec3> {
    let (w, h) = (width as f32, height as f32);
    let mut out = Vec::with_capacity(width as usize * height as usize);
    for y in 0..height {
        for x in 0..width {
            let (u, v) = ((x as f32 + 0.5) / w, (y as f32 + 0.5) / h);
            out.push(match pattern {
                Pattern::Smooth => {
                    let tau = std::f32::consts::TAU;
                    let a = (tau * 4.0 * u).sin() * (tau * 2.0 * v).cos();
                    let b = (tau * (3.0 * u + 2.0 * v)).sin();
                    Vec3::new(0.5 + 0.4 * a, 0.5 + 0.3 * b, 0.5 - 0.2 * a * b)
                }
                Pattern::Edges => {
                    let cell = (w / 16.0).max(2.0);
                    let odd = ((x as f32 / cell) as u32 + (y as f32 / cell) as u32) % 2 == 1;
                    let (dx, dy) = (x as f32 - 0.7 * w, y as f32 - 0.4 * h);
                    if dx * dx + dy * dy < (0.12 * h) * (0.12 * h) {
                        Vec3::new(4.0, 3.5, 3.0)
                    } else if odd {
                        Vec3::new(0.9, 0.8, 0.2)
                    } else {
                        Vec3::new(0.05, 0.1, 0.3)
                    }
                }
            });
        }
    }
    out
}

/// `iterations` rounds of Bernoulli sampling: pixel i takes one noisy sample of `reference[i]`
/// in a round with probability `probability(i)`. Deterministic in `seed` (pcg4d counters).
#[must_use]
pub fn accumulate(
    reference: &[Vec3],
    width: u32,
    height: u32,
    probability: impl Fn(usize) -> f32 + Sync,
    iterations: u32,
    seed: u32,
) -> Accumulation {
    // Pixels are independent: accumulate each on its own (same order of additions as
    // `Accumulation::add` in a round-by-round loop).
    let pixels: Vec<([f32; 4], u32)> = reference
        .par_iter()
        .enumerate()
        .map(|(i, r)| {
            let p = probability(i);
            let mut one = Accumulation::new(1, 1);
            for it in 0..iterations {
                let h = pcg4d([i as u32, it, seed, stream::SCHEDULE]);
                if unit_f32(h[0]) >= p {
                    continue;
                }
                // Exponential variate of mean 1: −ln(1 − U), U ∈ [0, 1).
                let u = unit_f32(pcg4d([i as u32, it, seed, stream::TRACE])[0]);
                one.add(0, *r * -(1.0 - u).ln());
            }
            (one.sum[0], one.count[0])
        })
        .collect();
    let (sum, count) = pixels.into_iter().unzip();
    Accumulation {
        width,
        height,
        sum,
        count,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_converge_to_the_reference_at_the_scheduled_rate() {
        let reference = vec![Vec3::new(1.0, 0.5, 0.25); 256];
        let acc = accumulate(&reference, 16, 16, |_| 0.5, 400, 1);
        // Counts: Binomial(400, 1/2) per pixel, total over 256 pixels: mean 51 200, sd 160.
        let total: u32 = acc.count.iter().sum();
        assert!((f64::from(total) - 51_200.0).abs() < 5.0 * 160.0, "{total}");
        // The mean of all samples: each has mean ref and sd ref; 51 200 samples → sd 0.0044.
        let sum: f32 = acc.sum.iter().map(|s| s[0]).sum();
        let mean = f64::from(sum) / f64::from(total);
        assert!((mean - 1.0).abs() < 5.0 * 0.0044, "{mean}");
    }
}
