//! Counter-based random numbers, the CPU twin of `shaders/random.wgsl`.
//!
//! Every random decision in raygun — a scheduling coin flip, a path's direction — is a pure
//! function of a counter such as (pixel, iteration, seed, stream). Nothing is carried between
//! iterations, any pixel can be recomputed on its own, and the CPU twin reproduces the GPU's
//! decisions bit for bit (integer arithmetic only, then one exact conversion).
//!
//! The hash is pcg4d (Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 2020).

/// Random streams: the fourth counter word, so that different uses never share numbers.
pub mod stream {
    /// Scheduling: the Bernoulli decision of a pixel in an iteration.
    pub const SCHEDULE: u32 = 0x5c4e_d01e;
    /// Path tracing: the per-sample sequence (the dimension index is added to it).
    pub const TRACE: u32 = 0x7a3c_0000;
}

/// pcg4d: a bijective hash of four 32-bit words (wrapping arithmetic, as in WGSL).
#[inline]
#[must_use]
pub fn pcg4d(v: [u32; 4]) -> [u32; 4] {
    let mut v = v.map(|x| x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223));
    mix(&mut v);
    for x in &mut v {
        *x ^= *x >> 16;
    }
    mix(&mut v);
    v
}

#[inline]
fn mix(v: &mut [u32; 4]) {
    v[0] = v[0].wrapping_add(v[1].wrapping_mul(v[3]));
    v[1] = v[1].wrapping_add(v[2].wrapping_mul(v[0]));
    v[2] = v[2].wrapping_add(v[0].wrapping_mul(v[1]));
    v[3] = v[3].wrapping_add(v[1].wrapping_mul(v[2]));
}

/// The top 24 bits of `x` as a float in [0, 1); exact, identical to WGSL's `unit_f32`.
#[inline]
#[must_use]
pub fn unit_f32(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_f32_is_in_the_half_open_unit_interval() {
        assert_eq!(unit_f32(0), 0.0);
        assert!(unit_f32(u32::MAX) < 1.0);
        assert_eq!(unit_f32(u32::MAX), 1.0 - 1.0 / 16_777_216.0);
    }

    #[test]
    fn pcg4d_is_a_bijection_on_a_sample_and_spreads_bits() {
        // Neighbouring counters give unrelated outputs: about half the bits flip.
        let mut flipped = 0u32;
        let n = 4096u32;
        for i in 0..n {
            let a = pcg4d([i, 7, 11, stream::SCHEDULE]);
            let b = pcg4d([i + 1, 7, 11, stream::SCHEDULE]);
            flipped += (a[0] ^ b[0]).count_ones();
        }
        let mean = f64::from(flipped) / f64::from(n);
        // 32 bits, each flipping with p = 1/2: mean 16, sd of the mean sqrt(8/4096) ≈ 0.044.
        assert!((mean - 16.0).abs() < 0.3, "mean flipped bits {mean}");
    }

    #[test]
    fn uniform_numbers_pass_a_chi_square_test() {
        // 16 bins, 65 536 draws; chi-square with 15 degrees of freedom, p = 0.001 cut-off 37.7.
        let mut bins = [0u32; 16];
        for i in 0..65_536u32 {
            let u = unit_f32(pcg4d([i % 256, i / 256, 3, stream::TRACE])[0]);
            bins[(u * 16.0) as usize] += 1;
        }
        let expected = 65_536.0 / 16.0;
        let chi2: f64 = bins
            .iter()
            .map(|&b| (f64::from(b) - expected).powi(2) / expected)
            .sum();
        assert!(chi2 < 37.7, "chi-square {chi2}, bins {bins:?}");
    }
}
