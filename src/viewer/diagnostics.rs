//! Images that explain a render: the ROI outline, the sample-count heat map, the noise map and
//! the noise contrast between ROI and periphery.

use rayon::prelude::*;

use crate::trace::accum::Accumulation;

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

/// Samples per pixel as RGBA: black (0) through red and yellow to white (the most).
#[must_use]
pub fn heat_map(counts: &[u32]) -> Vec<u8> {
    let max = counts.iter().copied().max().unwrap_or(0).max(1) as f32;
    counts
        .iter()
        .flat_map(|&c| {
            let t = c as f32 / max * 3.0;
            let ch = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
            [ch(t), ch(t - 1.0), ch(t - 2.0), 255]
        })
        .collect()
}

/// Undefined noise (fewer than two samples) in the noise overlay: dark blue.
pub const NOISE_UNDEFINED: [u8; 4] = [0, 0, 110, 255];

/// The standard error of each pixel's mean luminance, √(s²/n) with the unbiased sample variance
/// s² of the luminances (from the accumulation's Σ luminance², its RGB sum and count; see
/// [`Accumulation::luminance_variance_of_mean`]). Pixels with fewer than two samples have no
/// estimate: NaN there.
#[must_use]
pub fn noise_image(acc: &Accumulation) -> Vec<f32> {
    (0..acc.count.len())
        .into_par_iter()
        .map(|i| {
            acc.luminance_variance_of_mean(i)
                .map_or(f32::NAN, f32::sqrt)
        })
        .collect()
}

/// The median of the finite values; `None` when there is none.
#[must_use]
pub fn median_finite(values: impl IntoIterator<Item = f32>) -> Option<f32> {
    let mut v: Vec<f32> = values.into_iter().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    // Selection, not a sort: this runs on every displayed frame over every pixel.
    let n = v.len();
    let (lower, &mut upper, _) = v.select_nth_unstable_by(n / 2, f32::total_cmp);
    Some(if n % 2 == 1 {
        upper
    } else {
        let below = lower.iter().copied().max_by(f32::total_cmp).expect("n ≥ 2");
        0.5 * (below + upper)
    })
}

/// The two regions the noise is compared over: the ROI (d = 0, sampled every iteration) and the
/// periphery (pixels whose sampling probability max(p_min, 1 − d) is the floor p_min, i.e.
/// d ≥ 1 − p_min).
#[derive(Clone, Copy, Debug)]
pub struct NoiseRegions<'a> {
    pub dgi: &'a [f32],
    pub p_min: f32,
}

impl NoiseRegions<'_> {
    /// `values` at the ROI's pixels.
    #[must_use]
    pub fn roi(&self, values: &[f32]) -> Vec<f32> {
        self.select(values, |d| d == 0.0)
    }

    /// `values` at the periphery's pixels (none while p_min = 1: every pixel is the ROI's).
    #[must_use]
    pub fn periphery(&self, values: &[f32]) -> Vec<f32> {
        let floor = 1.0 - self.p_min;
        self.select(values, |d| d > 0.0 && d >= floor)
    }

    fn select(&self, values: &[f32], keep: impl Fn(f32) -> bool) -> Vec<f32> {
        values
            .iter()
            .zip(self.dgi)
            .filter(|(_, d)| keep(**d))
            .map(|(v, _)| *v)
            .collect()
    }
}

/// The ROI's noise against the periphery's: the median standard error of the mean luminance
/// over each region's noisy pixels, and how many there are.
///
/// Absolute SE, not SE relative to the mean: dividing by the mean brings in how bright each
/// region is, which has nothing to do with the sampler. Measured on the Cornell box (124×50, 64
/// iterations, every pixel sampled alike): the ROI/periphery ratio of the absolute SE was
/// 1.02–1.07 over three ROI placements, of the relative SE 0.86–1.44; the absolute ratio
/// isolates the sampler. Pixels whose samples all agree (SE 0: a constant
/// background or an emitter seen directly) have no noise however they are sampled and are left
/// out, as are pixels without an estimate (fewer than two samples).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseContrast {
    pub roi: f32,
    pub periphery: f32,
    pub roi_pixels: usize,
    pub periphery_pixels: usize,
}

impl NoiseContrast {
    /// Measures `noise` (SE of the mean luminance) over `regions`; `None` when a region has no
    /// noisy pixel.
    #[must_use]
    pub fn measure(noise: &[f32], regions: &NoiseRegions<'_>) -> Option<Self> {
        let noisy = |v: Vec<f32>| -> Vec<f32> {
            v.into_iter()
                .filter(|x| x.is_finite() && *x > 0.0)
                .collect()
        };
        let (roi, far) = (noisy(regions.roi(noise)), noisy(regions.periphery(noise)));
        Some(Self {
            roi_pixels: roi.len(),
            periphery_pixels: far.len(),
            roi: median_finite(roi)?,
            periphery: median_finite(far)?,
        })
    }

    /// ROI noise over periphery noise.
    #[must_use]
    pub fn ratio(&self) -> f32 {
        self.roi / self.periphery
    }
}

/// The ratio of standard errors the guide predicts between the ROI (sampled every iteration)
/// and the periphery (sampled with probability p_min): SE ∝ 1/√n and n_roi / n_periphery =
/// 1 / p_min, so √p_min for pixels whose samples spread alike.
#[must_use]
pub fn predicted_noise_ratio(p_min: f32) -> f32 {
    p_min.sqrt()
}

/// The noise overlay: SE as grey scaled by its 99th percentile, undefined pixels
/// [`NOISE_UNDEFINED`].
#[must_use]
pub fn noise_map(noise: &[f32]) -> Vec<u8> {
    let mut finite: Vec<f32> = noise.iter().copied().filter(|v| v.is_finite()).collect();
    let rank = (finite.len().saturating_sub(1) * 99) / 100;
    let top = if finite.is_empty() {
        None
    } else {
        Some(*finite.select_nth_unstable_by(rank, f32::total_cmp).1)
    }
    .filter(|v| *v > 0.0)
    .unwrap_or(1.0);
    noise
        .iter()
        .flat_map(|&v| {
            if v.is_finite() {
                let g = crate::output::unit_to_u8((v / top).clamp(0.0, 1.0));
                [g, g, g, 255]
            } else {
                NOISE_UNDEFINED
            }
        })
        .collect()
}

/// Samples taken in the ROI (pixels with d = 0) and how many pixels it covers — with a wall
/// camera only the pixels a tile shows (`shown`: bezels are never sampled); (0, 0) without an
/// ROI.
#[must_use]
pub fn roi_samples(
    acc: &Accumulation,
    dgi: &[f32],
    has_roi: bool,
    shown: impl Fn(usize) -> bool,
) -> (u64, u64) {
    if !has_roi {
        return (0, 0);
    }
    dgi.iter()
        .zip(&acc.count)
        .enumerate()
        .filter(|&(p, (d, _))| *d == 0.0 && shown(p))
        .fold((0, 0), |(s, n), (_, (_, &c))| (s + u64::from(c), n + 1))
}
