//! The fast filter: a pyramid of normalised convolutions (`pyramid.rs`, the CPU twin of
//! `shaders/filter/pyramid.wgsl`) read per pixel (this file, the CPU twin of
//! `shaders/filter/fast.wgsl`), in f64; the plan ([`Plan`]) is shared by both backends, so they
//! run the same passes with the same tap weights.
//!
//! # Per pixel
//!
//! w_i, k_i as in [`crate::filter`]. If w_i = 0 or k_i < 1: u_i. If k_i ≤ [`K_DIRECT`]: the exact
//! loop. Else the two levels whose kernel variance brackets σ_i² are read bilinearly, and mixed
//! with the weight that makes the mixture's variance σ_i²; the kernel variance of a bilinear
//! read of level ℓ at fractional texel position (f_x, f_y) is σ_ℓ² + step²·(f_x(1−f_x) +
//! f_y(1−f_y))/2 (the tent's variance, averaged over the two axes). F = Σ(g·u)/Σ g from the
//! mixture. The exact filter falls back to u_i when no sampled pixel lies within k_i; every tap
//! it has weighs at least exp(−4.5) (the rim, r = 3σ). The fast version falls back when the
//! kernel's total weight, 2πσ_i²·(mixed Σ g), is below that rim weight [`RIM_WEIGHT`]; the two
//! rules differ only where the nearest sample sits near the rim.

use glam::DVec3;
use rayon::prelude::*;

use super::exact::window_mean;
pub use super::pyramid::K_DIRECT;
use super::pyramid::Plan;
use super::pyramid::{Grid, Level, build_pyramid};
use super::{FilterParams, pixel_state};
use crate::trace::accum::Accumulation;

/// Weight of a tap on the rim of the exact window, exp(−(3σ)²/(2σ²)).
pub const RIM_WEIGHT: f64 = 0.011_108_996_538_242_306;

/// A bilinear read of `level` at full-resolution pixel (x, y): the blurred pair and the
/// kernel variance of the read (σ_ℓ² plus the tent's).
fn read_level(level: &Level, grid: &Grid, x: u32, y: u32) -> ([f64; 4], f64) {
    let r = f64::from(level.step);
    let coord = |p: u32, n: u32| {
        let t = (f64::from(p) - level.origin) / r;
        let i = (t.floor() as i64).clamp(0, i64::from(n) - 2);
        (i as usize, t - i as f64)
    };
    let (ix, fx) = coord(x, level.size[0]);
    let (iy, fy) = coord(y, level.size[1]);
    let w = level.size[0] as usize;
    let at = |i: usize, j: usize| grid[j * w + i];
    let out = std::array::from_fn(|c| {
        let top = at(ix, iy)[c] * (1.0 - fx) + at(ix + 1, iy)[c] * fx;
        let bottom = at(ix, iy + 1)[c] * (1.0 - fx) + at(ix + 1, iy + 1)[c] * fx;
        top * (1.0 - fy) + bottom * fy
    });
    let var = level.sigma2 + r * r * (fx * (1.0 - fx) + fy * (1.0 - fy)) / 2.0;
    (out, var)
}

/// The pyramid's estimate for a kernel of variance σ²: the mixed (Σ g·u, Σ g) pair.
#[must_use]
fn pyramid_read(plan: &Plan, grids: &[Grid], x: u32, y: u32, sigma2: f64) -> [f64; 4] {
    let mut prev: Option<([f64; 4], f64)> = None;
    for (level, grid) in plan.levels.iter().zip(grids) {
        let (v, var) = read_level(level, grid, x, y);
        if var >= sigma2 {
            return match prev {
                None => v,
                Some((pv, pvar)) => {
                    let t = (sigma2 - pvar) / (var - pvar);
                    std::array::from_fn(|c| pv[c] + t * (v[c] - pv[c]))
                }
            };
        }
        prev = Some((v, var));
    }
    prev.expect("the plan has levels when k > K_DIRECT").0
}

/// The fast filter's value at pixel `i`.
#[must_use]
pub fn filter_pixel(
    params: &FilterParams,
    plan: &Plan,
    grids: &[Grid],
    acc: &Accumulation,
    dgi: &[f32],
    i: usize,
) -> DVec3 {
    let st = pixel_state(params, acc, dgi, i);
    if st.w <= 0.0 || st.k < 1.0 {
        return st.mean;
    }
    let (x, y) = (
        (i % acc.width as usize) as u32,
        (i / acc.width as usize) as u32,
    );
    let filtered = if st.k <= K_DIRECT {
        window_mean(acc, x, y, st.k)
    } else {
        let sigma2 = st.k * st.k / 9.0;
        let v = pyramid_read(plan, grids, x, y, sigma2);
        let total = v[3] * std::f64::consts::TAU * sigma2;
        (total >= RIM_WEIGHT).then(|| DVec3::new(v[0], v[1], v[2]) / v[3])
    };
    match filtered {
        Some(f) => st.w * f + (1.0 - st.w) * st.mean,
        None => st.mean,
    }
}

/// The fast filter over the whole image. Inputs as checked by [`super::check_inputs`].
#[must_use]
pub fn filter_cpu(params: &FilterParams, acc: &Accumulation, dgi: &[f32]) -> Vec<DVec3> {
    let plan = Plan::new(acc.width, acc.height, params.k_max);
    let grids = build_pyramid(&plan, acc);
    (0..acc.count.len())
        .into_par_iter()
        .map(|i| filter_pixel(params, &plan, &grids, acc, dgi, i))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rim_weight_is_exp_minus_four_and_a_half() {
        assert_eq!(RIM_WEIGHT, (-4.5f64).exp());
    }
}
