//! Per-pixel decisions (DESIGN.md §6): the sampling probability, the Bernoulli draw, and where
//! a list slot's pixel is (Morton order inside a tile, or the scattered permutation). CPU twin
//! of `shaders/schedule/select.wgsl`.

use crate::random::{pcg4d, stream, unit_f32};

/// The sampling probability of a pixel with DGI value `d`: `max(p_min, 1 − d)` in f32, the same
/// operations as `probability` in `shaders/schedule/select.wgsl` (bitwise equal; tested).
///
/// The DGI stage keeps d in [0, 1]; d < 0 gives p > 1 (always sampled) and d > 1 gives p_min.
#[inline]
#[must_use]
pub fn probability(d: f32, p_min: f32) -> f32 {
    p_min.max(1.0 - d)
}

/// The Bernoulli decision of `pixel` in `iteration`: a uniform number in [0, 1) from the shared
/// hash below `p`. p ≥ 1 always selects (the number is below 1) and p ≤ 0 never does, so those
/// skip the hash (most pixels of a small ROI's DGI have p = 0).
#[inline]
#[must_use]
pub fn selected(pixel: u32, iteration: u32, seed: u32, p: f32) -> bool {
    if p >= 1.0 {
        return true;
    }
    p > 0.0 && unit_f32(pcg4d([pixel, iteration, seed, stream::SCHEDULE])[0]) < p
}

/// Morton (Z-order) index inside a tile → (x, y): even bits are x, odd bits are y.
#[inline]
#[must_use]
pub fn morton_decode(m: u32) -> (u32, u32) {
    (compact_bits(m), compact_bits(m >> 1))
}

/// Keeps the even bits of `v` and packs them (the inverse of spreading a 16-bit value).
#[inline]
fn compact_bits(v: u32) -> u32 {
    let mut x = v & 0x5555_5555;
    x = (x | (x >> 1)) & 0x3333_3333;
    x = (x | (x >> 2)) & 0x0f0f_0f0f;
    x = (x | (x >> 4)) & 0x00ff_00ff;
    (x | (x >> 8)) & 0x0000_ffff
}

/// Round keys of the scatter permutation (arbitrary fixed odd constants).
const SCATTER_KEYS: [u32; 4] = [0x9e37_79b9, 0x7f4a_7c15, 0xf39c_c060, 0x5ced_c834];

/// The Feistel round function: a 32-bit integer hash (Wellons' lowbias32) of the right half.
#[inline]
fn scatter_round(x: u32, key: u32) -> u32 {
    let mut h = (x ^ key).wrapping_mul(0x7feb_352d);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846c_a68b);
    h ^ (h >> 16)
}

/// Half the bit width of the scatter domain: the smallest h ≥ 1 with 4^h ≥ n (h ≤ 16).
#[must_use]
pub fn scatter_half_bits(n: u32) -> u32 {
    let mut h = 1;
    while h < 16 && (1u64 << (2 * h)) < u64::from(n) {
        h += 1;
    }
    h
}

/// A fixed pseudo-random bijection of [0, n): a 4-round Feistel network on 2h bits, walked
/// along its cycle until the value falls below n (expected fewer than 4 steps, since
/// 4^h < 4n). `half_bits` is [`scatter_half_bits`]`(n)`. Identical to `scatter` in
/// `shaders/schedule/select.wgsl`.
#[must_use]
pub fn scatter(slot: u32, half_bits: u32, n: u32) -> u32 {
    let mask = (1u32 << half_bits) - 1;
    let mut x = slot;
    loop {
        let (mut l, mut r) = (x >> half_bits, x & mask);
        for key in SCATTER_KEYS {
            (l, r) = (r, l ^ (scatter_round(r, key) & mask));
        }
        x = (l << half_bits) | r;
        if x < n {
            return x;
        }
    }
}
