//! 8-bit sRGB of linear values, fast and exact: `linear_to_srgb8(v)` equals
//! `unit_to_u8(linear_to_srgb(v))` for every `f32`, from a table instead of a `powf` per
//! channel. The viewer converts every shown picture this way (a 3840×2160 picture is 25 M
//! channels: 194 ms per picture on one thread of the H200 machine's Xeon with `powf`), and
//! the PNGs use it too.
//!
//! The table splits (0, 1) by the top bits of the value's IEEE pattern — positive floats order
//! as their bits — into buckets of 2^15 neighbouring floats. Each bucket holds the code of its
//! first float and the first float of the bucket with the next code, if the bucket has one; no
//! bucket holds two steps, since successive codes' linear values lie at least 0.89 % apart (near
//! 1.0) and a bucket spans at most 0.4 % (checked when the table is built).

use std::sync::LazyLock;

use glam::Vec3;
use rayon::prelude::*;

use super::{linear_to_srgb, unit_to_u8};

/// Bits dropped from the IEEE pattern to index a bucket.
const SHIFT: u32 = 15;
/// Buckets up to 1.0's pattern (0x3F80_0000).
const BUCKETS: usize = (0x3F80_0000u32 >> SHIFT) as usize;

struct Table {
    /// The code of each bucket's first float.
    base: Vec<u8>,
    /// The least float of the bucket whose code is `base + 1` (infinity where there is none).
    next: Vec<f32>,
}

/// The reference: the sRGB transfer function, then rounding to 8 bits.
fn exact(v: f32) -> u8 {
    unit_to_u8(linear_to_srgb(v))
}

static TABLE: LazyLock<Table> = LazyLock::new(|| {
    let mut base = Vec::with_capacity(BUCKETS);
    let mut next = Vec::with_capacity(BUCKETS);
    for i in 0..BUCKETS as u32 {
        let (lo, hi) = (i << SHIFT, ((i + 1) << SHIFT) - 1);
        let b = exact(f32::from_bits(lo));
        let top = exact(f32::from_bits(hi));
        assert!(top <= b.saturating_add(1), "two sRGB steps in bucket {i}");
        base.push(b);
        next.push(if top == b {
            f32::INFINITY
        } else {
            // The least pattern in (lo, hi] whose code is b + 1.
            let (mut a, mut z) = (lo, hi);
            while z - a > 1 {
                let m = a + (z - a) / 2;
                if exact(f32::from_bits(m)) > b {
                    z = m;
                } else {
                    a = m;
                }
            }
            f32::from_bits(z)
        });
    }
    Table { base, next }
});

/// `unit_to_u8(linear_to_srgb(v))`, by table: values ≤ 0 and NaN give 0, values ≥ 1 give 255.
#[must_use]
#[inline]
pub fn linear_to_srgb8(v: f32) -> u8 {
    // `!(v > 0.0)` is true for NaN too.
    if !(v > 0.0) {
        return 0;
    }
    if v >= 1.0 {
        return 255;
    }
    let t = &*TABLE;
    let i = (v.to_bits() >> SHIFT) as usize;
    t.base[i] + u8::from(v >= t.next[i])
}

/// The table as the GPU twin (`shaders/output/srgb8.wgsl`) reads it: per bucket, the code of
/// its first float and the IEEE pattern of the least float with the next code (`+inf`'s,
/// `0x7F80_0000`, where the bucket has no step). Positive floats order as their patterns, so
/// the kernel compares patterns as integers: the same byte as [`linear_to_srgb8`] for every
/// `f32`, whatever the GPU's float comparisons do with NaN.
#[must_use]
pub fn gpu_table() -> Vec<[u32; 2]> {
    let t = &*TABLE;
    t.base
        .iter()
        .zip(&t.next)
        .map(|(&b, &n)| [u32::from(b), n.to_bits()])
        .collect()
}

/// Bits dropped from an `f32`'s pattern to index [`gpu_table`] (the kernel's `SHIFT`).
pub const GPU_TABLE_SHIFT: u32 = SHIFT;

/// A linear picture as the viewer shows it: `exposure` stops, sRGB, 8 bits, opaque RGBA, on all
/// cores.
#[must_use]
pub fn display_rgba(image: &[Vec3], exposure: f32) -> Vec<u8> {
    encode::<4>(image, exposure)
}

/// The ROI outline colour (opaque yellow).
pub const OUTLINE: [u8; 4] = [255, 220, 0, 255];

/// Pixels inside the ROI (d = 0) with a 4-neighbour outside it: the ROI's outline on the wall,
/// whatever the ROI's kind.
#[must_use]
pub fn roi_outline(dgi: &[f32], size: [u32; 2]) -> Vec<usize> {
    let (w, h) = (size[0] as usize, size[1] as usize);
    // Rows on all cores, in row order (every shown picture runs this over every pixel).
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..w).filter_map(move |x| {
                let i = y * w + x;
                if dgi[i] != 0.0 {
                    return None;
                }
                let outside = |j: usize| dgi[j] > 0.0;
                ((x > 0 && outside(i - 1))
                    || (x + 1 < w && outside(i + 1))
                    || (y > 0 && outside(i - w))
                    || (y + 1 < h && outside(i + w)))
                .then_some(i)
            })
        })
        .collect()
}

/// Paints the pixels `outline` lists ([`roi_outline`]) in [`OUTLINE`] on an RGBA picture.
pub fn paint_outline(rgba: &mut [u8], outline: &[usize]) {
    for &i in outline {
        rgba[4 * i..4 * i + 4].copy_from_slice(&OUTLINE);
    }
}

/// A linear picture as 8-bit sRGB RGB (a PNG's bytes) at `exposure` stops, on all cores.
#[must_use]
pub fn display_rgb(image: &[Vec3], exposure: f32) -> Vec<u8> {
    encode::<3>(image, exposure)
}

/// `N` bytes a pixel: its three channels at `exposure` stops, then (N = 4) an opaque alpha.
fn encode<const N: usize>(image: &[Vec3], exposure: f32) -> Vec<u8> {
    const CHUNK: usize = 4096;
    let scale = exposure.exp2();
    let mut out = vec![255u8; image.len() * N];
    out.par_chunks_mut(N * CHUNK)
        .zip(image.par_chunks(CHUNK))
        .for_each(|(out, px)| {
            for (o, p) in out.chunks_exact_mut(N).zip(px) {
                o[0] = linear_to_srgb8(p.x * scale);
                o[1] = linear_to_srgb8(p.y * scale);
                o[2] = linear_to_srgb8(p.z * scale);
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(v: f32) {
        assert_eq!(
            linear_to_srgb8(v),
            exact(v),
            "v = {v:e} (bits {:#010x})",
            v.to_bits()
        );
    }

    /// Every float within 300 patterns of each of the 255 steps, on both sides: where an
    /// off-by-one bisection or a non-monotone `powf` would show.
    #[test]
    fn equals_the_reference_around_every_step() {
        let mut steps = 0;
        for k in 1..=255u8 {
            // The least float with code k, by bisection over (0, 1].
            let (mut a, mut z) = (0u32, 1f32.to_bits());
            while z - a > 1 {
                let m = a + (z - a) / 2;
                if exact(f32::from_bits(m)) >= k {
                    z = m;
                } else {
                    a = m;
                }
            }
            for d in 0..300 {
                check(f32::from_bits(z + d));
                check(f32::from_bits(z - d));
            }
            steps += 1;
        }
        assert_eq!(steps, 255);
    }

    /// Every 61st float pattern from 0 to just past 1 (17.5 M values, all buckets many times),
    /// and the edges: zeros, negatives, subnormals, one, above one, infinities, NaN.
    #[test]
    fn equals_the_reference_across_the_range_and_at_the_edges() {
        (0..=(1f32.to_bits() + 1000) / 61)
            .into_par_iter()
            .for_each(|i| check(f32::from_bits(i * 61)));
        for v in [
            0.0,
            -0.0,
            -1.0,
            f32::MIN_POSITIVE,
            f32::from_bits(1),
            1.0,
            1.0 + f32::EPSILON,
            2.0,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            0.003_130_8,
            0.5,
        ] {
            check(v);
        }
    }

    /// The pictures' functions are the per-channel conversion with the exposure applied first.
    #[test]
    fn pictures_convert_each_channel_with_the_exposure() {
        let image: Vec<Vec3> = (0..10_000)
            .map(|i| {
                let t = i as f32 / 10_000.0;
                Vec3::new(t, 1.5 * t - 0.2, (t * 37.0).fract())
            })
            .collect();
        let (rgba, rgb) = (display_rgba(&image, 0.5), display_rgb(&image, 0.5));
        let s = 0.5f32.exp2();
        for (i, p) in image.iter().enumerate() {
            let want = [exact(p.x * s), exact(p.y * s), exact(p.z * s)];
            assert_eq!(rgba[4 * i..4 * i + 3], want);
            assert_eq!(rgba[4 * i + 3], 255);
            assert_eq!(rgb[3 * i..3 * i + 3], want);
        }
    }
}
