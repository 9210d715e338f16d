//! The paper's filter computed exactly: CPU twin (f64) of `shaders/filter/exact.wgsl`.
//!
//! One 2D loop per pixel over its circular window (module docs of [`crate::filter`]); a
//! variable radius is not separable.

use glam::DVec3;
use rayon::prelude::*;

use super::{FilterParams, pixel_state};
use crate::trace::accum::Accumulation;

/// Σ g·u_j / Σ g over the sampled pixels j of the window dx² + dy² ≤ k² around (x, y), with
/// g = exp(−(dx² + dy²)/(2σ²)), σ = k/3; `None` when the window holds no sampled pixel.
#[must_use]
pub fn window_mean(acc: &Accumulation, x: u32, y: u32, k: f64) -> Option<DVec3> {
    let (w, h) = (i64::from(acc.width), i64::from(acc.height));
    let r = k.floor() as i64;
    let k2 = k * k;
    // exp(−r²/(2σ²)) with σ = k/3.
    let scale = -4.5 / k2;
    let (mut num, mut den) = (DVec3::ZERO, 0.0f64);
    for yy in (i64::from(y) - r).max(0)..=(i64::from(y) + r).min(h - 1) {
        let dy = yy - i64::from(y);
        for xx in (i64::from(x) - r).max(0)..=(i64::from(x) + r).min(w - 1) {
            let dx = xx - i64::from(x);
            let r2 = (dx * dx + dy * dy) as f64;
            let j = (yy * w + xx) as usize;
            let n = acc.count[j];
            if r2 > k2 || n == 0 {
                continue;
            }
            let g = (scale * r2).exp();
            let s = acc.sum[j];
            num += g * DVec3::new(f64::from(s[0]), f64::from(s[1]), f64::from(s[2])) / f64::from(n);
            den += g;
        }
    }
    (den > 0.0).then(|| num / den)
}

/// The filtered value of pixel `i` (module docs of [`crate::filter`]).
#[must_use]
pub fn filter_pixel(params: &FilterParams, acc: &Accumulation, dgi: &[f32], i: usize) -> DVec3 {
    let st = pixel_state(params, acc, dgi, i);
    if st.w <= 0.0 || st.k < 1.0 {
        return st.mean;
    }
    let (x, y) = (
        (i % acc.width as usize) as u32,
        (i / acc.width as usize) as u32,
    );
    match window_mean(acc, x, y, st.k) {
        Some(f) => st.w * f + (1.0 - st.w) * st.mean,
        None => st.mean,
    }
}

/// The exact filter over the whole image (rayon). Inputs as checked by
/// [`super::check_inputs`]; [`super::filter_cpu`] checks them.
#[must_use]
pub fn filter_cpu(params: &FilterParams, acc: &Accumulation, dgi: &[f32]) -> Vec<DVec3> {
    (0..acc.count.len())
        .into_par_iter()
        .map(|i| filter_pixel(params, acc, dgi, i))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// One sample of value 1 at the centre of a 9×9 image, all else unsampled: every pixel
    /// whose window reaches the centre takes exactly its value (a single tap normalises to 1).
    #[test]
    fn a_single_sample_fills_exactly_the_pixels_whose_window_reaches_it() {
        let mut acc = Accumulation::new(9, 9);
        acc.add(40, Vec3::new(1.0, 0.5, 0.25));
        let dgi = vec![1.0; 81];
        let params = FilterParams {
            k_max: 3.0,
            c: 4.0,
            ..Default::default()
        };
        let out = filter_cpu(&params, &acc, &dgi);
        for (i, o) in out.iter().enumerate() {
            let (dx, dy) = (i as i64 % 9 - 4, i as i64 / 9 - 4);
            // Unsampled pixels: w = 1, k = 3. The centre: s = 1, w = 3/4, its own value.
            let want = if dx * dx + dy * dy <= 9 {
                DVec3::new(1.0, 0.5, 0.25)
            } else {
                DVec3::ZERO
            };
            assert!((*o - want).abs().max_element() < 1e-15, "({dx},{dy}): {o}");
        }
    }

    /// Two samples at distance 2 from a pixel, one on each side, with values 0 and 1: the
    /// Gaussian weights are equal, so the unsampled pixel between them gets exactly 1/2; a
    /// third at distance 1 enters with weight exp(−4.5/k²) relative to exp(−4.5·4/k²).
    #[test]
    fn weights_are_the_gaussian_of_sigma_k_over_3() {
        let mut acc = Accumulation::new(7, 1);
        acc.add(1, Vec3::ZERO);
        acc.add(5, Vec3::ONE);
        acc.add(4, Vec3::splat(2.0));
        let dgi = vec![1.0; 7];
        let params = FilterParams {
            k_max: 2.5,
            c: 1.0,
            ..Default::default()
        };
        let o = filter_pixel(&params, &acc, &dgi, 3);
        let (g1, g2) = ((-4.5f64 / 6.25).exp(), (-4.5f64 * 4.0 / 6.25).exp());
        let want = (g2 * 1.0 + g1 * 2.0) / (2.0 * g2 + g1);
        assert!((o.x - want).abs() < 1e-15, "{o} vs {want}");
    }
}
