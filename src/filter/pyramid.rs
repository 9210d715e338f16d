//! The fast filter's pyramid (DESIGN.md §8): the CPU twin (f64) of `shaders/filter/pyramid.wgsl`.
//! The plan ([`Plan`]) is shared with the GPU (`gpu.rs`), so both run the same passes with the
//! same tap weights.
//!
//! Level ℓ holds G_{σ_ℓ} ∗ (m·u, m) — the Gaussian-blurred premultiplied value and weight of the
//! sampled pixels (m = 1 where s ≥ 1, else 0) — with σ_ℓ = σ₀·2^{ℓ/2}, σ₀ = K_DIRECT/3, up to
//! the first level with σ_ℓ ≥ k_max/3. Half-octave spacing keeps the two kernels that an
//! intermediate σ mixes close in shape. Each level is its predecessor blurred by the increment
//! σ_ℓ² − σ_{ℓ−1}² with two separable passes (level 0: the raw pixels, blurred by σ₀ — the same
//! discrete Gaussian the exact loop sums). A level is stored every `step` pixels, doubled while
//! the level's σ stays at least [`MIN_GRID_SIGMA`] of its texels, so the blurred signal is
//! smooth on its grid; the decimating pass evaluates the blur at the new texel centres. Levels
//! extend 3σ_ℓ beyond the image (outside is unsampled, weight 0), so the blur near the border is
//! not cut short.

use rayon::prelude::*;

use crate::trace::accum::Accumulation;

/// Kernels up to this radius (pixels) run the exact loop (at most 49 taps); larger ones read
/// the pyramid.
pub const K_DIRECT: f64 = 4.0;
/// A level is decimated by 2 only while its σ stays at least this many of its texels: the
/// bilinear read then widens the kernel's variance by at most step²/4 ≤ σ²/9.
pub const MIN_GRID_SIGMA: f64 = 1.5;
/// Most pyramid levels (k_max = 64 needs 9: σ₀·2⁴ = 64/3).
pub const MAX_LEVELS: usize = 9;
/// Most taps of one separable pass. An increment's σ is the previous level's σ in that level's
/// texels, which stays under 2·MIN_GRID_SIGMA = 3 (a level is decimated as soon as its σ
/// reaches 3 texels of the previous step), so a pass spans under ±9 texels: at most 19 taps.
/// The plan asserts it.
pub const MAX_TAPS: usize = 20;

/// One pyramid level.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    /// σ_ℓ², full-resolution pixels².
    pub sigma2: f64,
    /// Pixels per texel (a power of two).
    pub step: u32,
    /// Texels along x and y.
    pub size: [u32; 2],
    /// Full-resolution position of texel 0's centre on both axes (pixel centres are at
    /// integers); texel t sits at `origin + t·step`.
    pub origin: f64,
}

/// Where a pass reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// The accumulation: (m·u, m) formed on the fly.
    Accumulation,
    /// A pyramid level.
    Level(usize),
    /// The intermediate buffer the previous pass wrote.
    Temp,
}

/// Where a pass writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    Temp,
    Level(usize),
}

/// One separable blur pass: `out(X) = Σ_t weights[t]·in(X·dec + first + t)` along `axis`
/// (0 = x, 1 = y), the other coordinate unchanged; reads outside `src_size` are 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Pass {
    pub source: Source,
    pub target: Target,
    pub axis: u32,
    pub dec: u32,
    pub src_size: [u32; 2],
    pub dst_size: [u32; 2],
    pub first: i32,
    /// Normalised to sum 1 (f32: what the kernel uses; the twin widens them).
    pub weights: Vec<f32>,
}

/// The pyramid for an image size and k_max.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub width: u32,
    pub height: u32,
    pub levels: Vec<Level>,
    pub passes: Vec<Pass>,
}

impl Plan {
    /// Levels up to σ ≥ k_max/3 (none when k_max ≤ K_DIRECT: every pixel runs the exact loop).
    /// `k_max` must have passed [`FilterParams::validate`](crate::filter::FilterParams::validate).
    #[must_use]
    pub fn new(width: u32, height: u32, k_max: f32) -> Self {
        let sigma_max = f64::from(k_max) / 3.0;
        let sigma0 = K_DIRECT / 3.0;
        let mut levels: Vec<Level> = Vec::new();
        if f64::from(k_max) > K_DIRECT {
            let mut step = 1u32;
            for l in 0..MAX_LEVELS {
                let sigma2 = sigma0 * sigma0 * f64::from(1u32 << l);
                let sigma = sigma2.sqrt();
                if l > 0 && sigma / f64::from(2 * step) >= MIN_GRID_SIGMA {
                    step *= 2;
                }
                let r = f64::from(step);
                let margin = (3.0 * sigma / r).ceil() + 1.0;
                let n = |len: u32| len.div_ceil(step) + 1 + 2 * margin as u32;
                levels.push(Level {
                    sigma2,
                    step,
                    size: [n(width), n(height)],
                    origin: (r - 1.0) / 2.0 - margin * r,
                });
                if sigma >= sigma_max * (1.0 - 1e-12) {
                    break;
                }
            }
            assert!(
                levels
                    .last()
                    .is_some_and(|l| l.sigma2.sqrt() >= sigma_max * (1.0 - 1e-12)),
                "k_max {k_max} needs more than {MAX_LEVELS} levels (validate the parameters)"
            );
        }
        let mut passes = Vec::new();
        for (l, level) in levels.iter().enumerate() {
            let (src_size, src_origin, src_step, prev_sigma2) = match l {
                0 => ([width, height], 0.0, 1u32, 0.0),
                _ => {
                    let p = &levels[l - 1];
                    (p.size, p.origin, p.step, p.sigma2)
                }
            };
            let dec = level.step / src_step;
            let c0 = (level.origin - src_origin) / f64::from(src_step);
            let grid_sigma = (level.sigma2 - prev_sigma2).sqrt() / f64::from(src_step);
            let (first, weights) = taps(c0, grid_sigma);
            let temp_size = [level.size[0], src_size[1]];
            passes.push(Pass {
                source: if l == 0 {
                    Source::Accumulation
                } else {
                    Source::Level(l - 1)
                },
                target: Target::Temp,
                axis: 0,
                dec,
                src_size,
                dst_size: temp_size,
                first,
                weights: weights.clone(),
            });
            passes.push(Pass {
                source: Source::Temp,
                target: Target::Level(l),
                axis: 1,
                dec,
                src_size: temp_size,
                dst_size: level.size,
                first,
                weights,
            });
        }
        Self {
            width,
            height,
            levels,
            passes,
        }
    }

    /// Texels of the largest intermediate (x-blurred) buffer.
    #[must_use]
    pub fn temp_texels(&self) -> u64 {
        self.passes
            .iter()
            .filter(|p| p.target == Target::Temp)
            .map(|p| u64::from(p.dst_size[0]) * u64::from(p.dst_size[1]))
            .max()
            .unwrap_or(0)
    }
}

/// Taps of a blur of σ (grid units) evaluated at offset c0 from the output's base index:
/// integer source positions within 3σ of c0, weights exp(−o²/2σ²) normalised to 1.
fn taps(c0: f64, sigma: f64) -> (i32, Vec<f32>) {
    let radius = 3.0 * sigma;
    let first = (c0 - radius).ceil() as i32;
    let last = (c0 + radius).floor() as i32;
    let raw: Vec<f64> = (first..=last)
        .map(|j| {
            let o = f64::from(j) - c0;
            (-o * o / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    assert!(raw.len() <= MAX_TAPS, "{} taps for σ {sigma}", raw.len());
    let total: f64 = raw.iter().sum();
    (first, raw.iter().map(|g| (g / total) as f32).collect())
}

/// A level's texels: (Σ g·u.rgb, Σ g) per texel, row-major.
pub(super) type Grid = Vec<[f64; 4]>;

/// One separable pass on the CPU, the twin of `pyramid.wgsl`'s `blur`/`blur_accumulation`.
fn run_pass(pass: &Pass, src: &[[f64; 4]]) -> Grid {
    let [dw, dh] = pass.dst_size;
    let [sw, sh] = pass.src_size;
    let sw_usize = sw as usize;
    let weights: Vec<f64> = pass.weights.iter().map(|&w| f64::from(w)).collect();
    (0..dw as usize * dh as usize)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % dw as usize, i / dw as usize);
            let (base, len) = if pass.axis == 0 {
                (x as i64, sw)
            } else {
                (y as i64, sh)
            };
            let start = base * i64::from(pass.dec) + i64::from(pass.first);
            let mut acc = [0.0; 4];
            for (t, wt) in weights.iter().enumerate() {
                let j = start + t as i64;
                if j < 0 || j >= i64::from(len) {
                    continue;
                }
                let v = if pass.axis == 0 {
                    src[y * sw_usize + j as usize]
                } else {
                    src[j as usize * sw_usize + x]
                };
                for c in 0..4 {
                    acc[c] += wt * v[c];
                }
            }
            acc
        })
        .collect()
}

/// Each pixel's (u_i, 1), or 0 without samples: the first passes' source, made once (the same
/// values the passes divided out tap by tap before, at a division per channel and tap).
fn accumulation_grid(acc: &Accumulation) -> Grid {
    (0..acc.count.len())
        .into_par_iter()
        .map(|i| {
            let n = acc.count[i];
            if n == 0 {
                return [0.0; 4];
            }
            let s = acc.sum[i];
            let n = f64::from(n);
            [
                f64::from(s[0]) / n,
                f64::from(s[1]) / n,
                f64::from(s[2]) / n,
                1.0,
            ]
        })
        .collect()
}

/// Builds every level (the twin of the pyramid passes).
#[must_use]
pub fn build_pyramid(plan: &Plan, acc: &Accumulation) -> Vec<Grid> {
    let mut levels: Vec<Grid> = Vec::with_capacity(plan.levels.len());
    let mut temp: Grid = Vec::new();
    for pass in &plan.passes {
        let out = match pass.source {
            // Only level 0's first pass reads it: made for that pass and dropped after it, so
            // that it never lives beside the levels (the working set `memory.rs` states).
            Source::Accumulation => run_pass(pass, &accumulation_grid(acc)),
            Source::Level(l) => run_pass(pass, &levels[l]),
            Source::Temp => run_pass(pass, &temp),
        };
        match pass.target {
            Target::Temp => temp = out,
            Target::Level(_) => levels.push(out),
        }
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plan_for_k_max_32_reaches_sigma_32_over_3_in_half_octaves() {
        let plan = Plan::new(3840, 2160, 32.0);
        let sigmas: Vec<f64> = plan.levels.iter().map(|l| l.sigma2.sqrt()).collect();
        assert_eq!(sigmas.len(), 7, "{sigmas:?}");
        assert!((sigmas[6] - 32.0 / 3.0).abs() < 1e-12);
        let steps: Vec<u32> = plan.levels.iter().map(|l| l.step).collect();
        assert_eq!(steps, [1, 1, 1, 2, 2, 4, 4]);
        for l in &plan.levels {
            // Decimated levels keep their σ at least MIN_GRID_SIGMA texels (and under twice it).
            let grid_sigma = l.sigma2.sqrt() / f64::from(l.step);
            assert!(l.step == 1 || grid_sigma >= MIN_GRID_SIGMA, "{l:?}");
            assert!(grid_sigma < 2.0 * MIN_GRID_SIGMA, "{l:?}");
            // Texel centres cover the image and 3σ beyond it on both sides.
            let last = l.origin + f64::from(l.size[0] - 1) * f64::from(l.step);
            assert!(l.origin <= -3.0 * l.sigma2.sqrt() && last >= 3839.0 + 3.0 * l.sigma2.sqrt());
        }
        assert_eq!(plan.passes.len(), 14);
        assert!(Plan::new(64, 64, 4.0).levels.is_empty());
        assert_eq!(Plan::new(64, 64, 64.0).levels.len(), MAX_LEVELS);
    }

    #[test]
    fn tap_weights_are_normalised_and_centred() {
        for (c0, s) in [(0.0, 1.3), (0.5, 2.7), (-7.0, 1.5), (-6.5, 2.99)] {
            let (first, w) = taps(c0, s);
            let total: f64 = w.iter().map(|&x| f64::from(x)).sum();
            assert!((total - 1.0).abs() < 1e-6);
            let mean: f64 = w
                .iter()
                .enumerate()
                .map(|(t, &x)| f64::from(x) * (f64::from(first) + t as f64))
                .sum();
            assert!((mean - c0).abs() < 1e-6, "{c0} {s}: mean {mean}");
        }
    }
}
