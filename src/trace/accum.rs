//! Per-pixel progressive accumulation, shared by the tracer, the scheduler and the filter.
//!
//! On the GPU it is two storage buffers indexed by pixel `y * width + x` (row 0 at the top):
//! `accum: array<vec4<f32>>` — `.xyz` the sum of the sample radiances (linear RGB), `.w` the
//! sum of the squared sample luminances — and `counts: array<u32>`, the number of samples.
//! [`Accumulation`] is the same data on the CPU (and what a read-back returns).

use glam::Vec3;

/// Rec. 709 luminance of linear RGB.
#[inline]
#[must_use]
pub fn luminance(rgb: Vec3) -> f32 {
    0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z
}

/// Adds one sample of radiance `rgb` to a pixel's sums and count (the kernel's arithmetic).
#[inline]
pub fn accumulate(sum: &mut [f32; 4], count: &mut u32, rgb: Vec3) {
    accumulate_sums(sum, rgb);
    *count += 1;
}

/// [`accumulate`]'s sums without the count: the cluster's owners count a sample when it is
/// dealt and add its sums when it arrives (on a GPU rank, `add` in `shaders/trace/accum.wgsl`).
#[inline]
pub fn accumulate_sums(sum: &mut [f32; 4], rgb: Vec3) {
    let l = luminance(rgb);
    sum[0] += rgb.x;
    sum[1] += rgb.y;
    sum[2] += rgb.z;
    sum[3] += l * l;
}

/// The rays of each run of samples: `segments` are (first, length) into `samples`, whose
/// fourth float holds a sample's rays as its bits (the trace's compact output) — a cluster
/// rank's rays per traced block, the deal's weights (`block_rays` in
/// `shaders/trace/accum.wgsl` on a GPU rank).
#[must_use]
pub fn block_rays(samples: &[[f32; 4]], segments: &[[u32; 2]]) -> Vec<u32> {
    segments
        .iter()
        .map(|&[first, len]| {
            samples[first as usize..(first + len) as usize]
                .iter()
                .map(|s| s[3].to_bits())
                .sum()
        })
        .collect()
}

/// Per-pixel sums and sample counts of a progressive render.
#[derive(Clone, Debug, PartialEq)]
pub struct Accumulation {
    pub width: u32,
    pub height: u32,
    /// Per pixel: RGB sum in `[0..3]`, sum of squared luminance in `[3]`.
    pub sum: Vec<[f32; 4]>,
    /// Per pixel: samples taken.
    pub count: Vec<u32>,
}

impl Accumulation {
    /// An empty accumulation (no samples anywhere).
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            sum: vec![[0.0; 4]; n],
            count: vec![0; n],
        }
    }

    /// Adds one sample of radiance `rgb` to pixel `i`.
    #[inline]
    pub fn add(&mut self, i: usize, rgb: Vec3) {
        accumulate(&mut self.sum[i], &mut self.count[i], rgb);
    }

    /// The pixel's mean radiance (black where it has no sample yet).
    #[must_use]
    pub fn mean(&self, i: usize) -> Vec3 {
        let n = self.count[i];
        if n == 0 {
            return Vec3::ZERO;
        }
        Vec3::new(self.sum[i][0], self.sum[i][1], self.sum[i][2]) / n as f32
    }

    /// The estimated variance of the pixel's mean luminance, s²/n with the unbiased sample
    /// variance s²; `None` with fewer than two samples.
    #[must_use]
    pub fn luminance_variance_of_mean(&self, i: usize) -> Option<f32> {
        let n = self.count[i];
        if n < 2 {
            return None;
        }
        let nf = n as f64;
        let s = self.sum[i];
        let mean_l = f64::from(luminance(Vec3::new(s[0], s[1], s[2]))) / nf;
        let var = ((f64::from(s[3]) - nf * mean_l * mean_l) / (nf - 1.0)).max(0.0);
        Some((var / nf) as f32)
    }

    /// The mean image, row-major linear RGB.
    #[must_use]
    pub fn mean_image(&self) -> Vec<Vec3> {
        (0..self.count.len()).map(|i| self.mean(i)).collect()
    }

    /// Merges each `block × block` square of pixels into one (sums and counts add), dropping
    /// the partial squares at the right and bottom edges. A pooled pixel's mean is the mean of
    /// all its samples and its variance estimate uses all of them — what statistical tests need
    /// when per-pixel sample counts are too small for a trustworthy variance.
    #[must_use]
    pub fn pooled(&self, block: u32) -> Self {
        assert!(block > 0, "pooling block must be at least one pixel");
        let (w, h) = (self.width / block, self.height / block);
        let mut out = Self::new(w, h);
        for y in 0..h * block {
            for x in 0..w * block {
                let (i, o) = (
                    (y * self.width + x) as usize,
                    ((y / block) * w + x / block) as usize,
                );
                for k in 0..4 {
                    out.sum[o][k] += self.sum[i][k];
                }
                out.count[o] += self.count[i];
            }
        }
        out
    }

    /// The pixels at every `step`-th column of every `step`-th row (x and y multiples of
    /// `step`), as an image of [`every_size`]: a picture's nearest-neighbour reduction, whose
    /// pixels keep their own sums and counts (their means, noise and sample counts unchanged).
    #[must_use]
    pub fn every(&self, step: u32) -> Self {
        let [width, height] = every_size([self.width, self.height], step);
        Self {
            width,
            height,
            sum: every(&self.sum, [self.width, self.height], step),
            count: every(&self.count, [self.width, self.height], step),
        }
    }
}

/// The size of the reduction of a `size` image to every `step`-th pixel of every `step`-th row:
/// ⌈width / step⌉ × ⌈height / step⌉.
#[must_use]
pub fn every_size(size: [u32; 2], step: u32) -> [u32; 2] {
    assert!(step > 0, "a reduction keeps every step ≥ 1 pixels");
    size.map(|n| n.div_ceil(step))
}

/// The values of a `size` image (row-major) at x and y multiples of `step`, row-major.
#[must_use]
pub fn every<T: Copy>(values: &[T], size: [u32; 2], step: u32) -> Vec<T> {
    assert_eq!(
        values.len(),
        size[0] as usize * size[1] as usize,
        "one value a pixel"
    );
    let [w, h] = size.map(|n| n as usize);
    let step = step as usize;
    (0..h)
        .step_by(step)
        .flat_map(|y| (0..w).step_by(step).map(move |x| values[y * w + x]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variance_of_mean_matches_the_textbook_formula() {
        let mut a = Accumulation::new(1, 1);
        for v in [1.0f32, 2.0, 3.0, 4.0] {
            a.add(0, Vec3::splat(v));
        }
        // Luminance of grey v is v (the weights sum to 1). Sample variance of 1..4 is 5/3.
        let got = a.luminance_variance_of_mean(0).unwrap();
        assert!((got - 5.0 / 12.0).abs() < 1e-6, "{got}");
        assert_eq!(a.mean(0), Vec3::splat(2.5));
        assert_eq!(Accumulation::new(1, 1).luminance_variance_of_mean(0), None);
    }

    #[test]
    fn every_keeps_the_pixels_on_the_grid_with_their_sums() {
        let mut a = Accumulation::new(5, 3);
        for i in 0..15 {
            for _ in 0..=i % 4 {
                a.add(i, Vec3::new(i as f32, 1.0, 2.0));
            }
        }
        let e = a.every(2);
        // Columns 0, 2, 4 of rows 0 and 2: the partial squares at the edges keep their pixel.
        assert_eq!((e.width, e.height), (3, 2));
        for (o, i) in [0, 2, 4, 10, 12, 14].into_iter().enumerate() {
            assert_eq!((e.sum[o], e.count[o]), (a.sum[i], a.count[i]), "pixel {i}");
        }
        assert_eq!(a.every(1), a);
        assert_eq!(every_size([5, 3], 5), [1, 1]);
        assert_eq!(a.every(7).count, vec![a.count[0]]);
    }

    #[test]
    fn pooling_adds_sums_and_counts_per_block_and_drops_partial_blocks() {
        let mut a = Accumulation::new(5, 3);
        for i in 0..15 {
            for _ in 0..=i % 3 {
                a.add(i, Vec3::splat(i as f32));
            }
        }
        let p = a.pooled(2);
        assert_eq!((p.width, p.height), (2, 1));
        // Block (0, 0) holds pixels 0, 1, 5, 6; block (1, 0) pixels 2, 3, 7, 8.
        for (o, pixels) in [(0, [0usize, 1, 5, 6]), (1, [2, 3, 7, 8])] {
            let count: u32 = pixels.iter().map(|&i| a.count[i]).sum();
            assert_eq!(p.count[o], count);
            for k in 0..4 {
                let sum: f32 = pixels.iter().map(|&i| a.sum[i][k]).sum();
                assert_eq!(p.sum[o][k], sum);
            }
        }
        assert_eq!(a.pooled(1), a);
    }
}
