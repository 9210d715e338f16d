//! The ROI's statistics as the window and the stop conditions report them ([`RoiStats`]): the
//! samples and pixels of the ROI, the noise of the ROI against the periphery
//! ([`NoiseContrast`]) and the ROI's progress ([`RoiProgress`]).
//!
//! [`RoiStats::measure`] is the definition and the CPU twin; [`super::gpu::StatsKernel`]
//! (`shaders/output/stats.wgsl`) measures the same where the accumulation lives, so that a GPU
//! renderer's statistics cost a few dozen bytes of read-back instead of the accumulation and
//! the DGI (24 bytes a pixel: about 200 MB at 3840×2160).

use rayon::prelude::*;

use crate::trace::accum::Accumulation;

/// What the ROI has gathered, over the pixels a wall camera's tiles show (all without one).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RoiStats {
    /// Samples taken in the ROI's pixels (d = 0).
    pub roi_samples: u64,
    /// The ROI's pixels.
    pub roi_pixels: u64,
    /// The median standard error of the mean luminance over the ROI's and the periphery's
    /// noisy pixels; `None` when a region has none.
    pub contrast: Option<NoiseContrast>,
    /// The ROI's fewest samples and median SE; `None` without ROI pixels.
    pub progress: Option<RoiProgress>,
}

impl RoiStats {
    /// Measures `acc` against `dgi` (the periphery: d ≥ 1 − `p_min`), the ROI over the pixels
    /// `shown` keeps.
    #[must_use]
    pub fn measure(
        acc: &Accumulation,
        dgi: &[f32],
        p_min: f32,
        shown: impl Fn(usize) -> bool,
    ) -> Self {
        Self::measure_with_noise(acc, dgi, &noise_image(acc), p_min, shown)
    }

    /// [`Self::measure`] with the noise image (`noise_image(acc)`) already made.
    #[must_use]
    pub fn measure_with_noise(
        acc: &Accumulation,
        dgi: &[f32],
        noise: &[f32],
        p_min: f32,
        shown: impl Fn(usize) -> bool,
    ) -> Self {
        let (roi_samples, roi_pixels) = roi_samples(acc, dgi, true, &shown);
        Self {
            roi_samples,
            roi_pixels,
            contrast: NoiseContrast::measure(noise, &NoiseRegions { dgi, p_min }),
            progress: RoiProgress::measure_where(acc, dgi, &shown),
        }
    }

    /// Whether `other` (measured on the GPU) is this measurement (the CPU twin's) within the
    /// kernel's precision: the totals equal, each median within `tolerance` relative (see
    /// [`super::gpu::SE_TOLERANCE`]); the error names the first that is not.
    pub fn matches(&self, other: &Self, tolerance: f32) -> Result<(), StatsMismatch> {
        let close = |what: &'static str, a: f32, b: f32| {
            if a == b || (a - b).abs() <= tolerance * a.abs() {
                Ok(())
            } else {
                Err(StatsMismatch::Median { what, a, b })
            }
        };
        if (self.roi_samples, self.roi_pixels) != (other.roi_samples, other.roi_pixels) {
            return Err(StatsMismatch::Totals {
                a: (self.roi_samples, self.roi_pixels),
                b: (other.roi_samples, other.roi_pixels),
            });
        }
        match (&self.contrast, &other.contrast) {
            (Some(a), Some(b)) => {
                if (a.roi_pixels, a.periphery_pixels) != (b.roi_pixels, b.periphery_pixels) {
                    return Err(StatsMismatch::NoisyPixels {
                        a: (a.roi_pixels, a.periphery_pixels),
                        b: (b.roi_pixels, b.periphery_pixels),
                    });
                }
                close("the ROI's noise", a.roi, b.roi)?;
                close("the periphery's noise", a.periphery, b.periphery)?;
            }
            (None, None) => {}
            (a, b) => return Err(StatsMismatch::Contrast { a: *a, b: *b }),
        }
        match (&self.progress, &other.progress) {
            (Some(a), Some(b)) => {
                if (a.pixels, a.min_samples) != (b.pixels, b.min_samples) {
                    return Err(StatsMismatch::Progress {
                        a: (a.pixels, a.min_samples),
                        b: (b.pixels, b.min_samples),
                    });
                }
                close("the progress's median SE", a.median_se, b.median_se)
            }
            (None, None) => Ok(()),
            (a, b) => Err(StatsMismatch::HasProgress { a: *a, b: *b }),
        }
    }
}

/// Where two measurements of [`RoiStats`] differ ([`RoiStats::matches`]): the first value
/// that does, this measurement's (`a`) against the other's (`b`).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum StatsMismatch {
    #[error("ROI samples and pixels: {a:?} against {b:?}")]
    Totals { a: (u64, u64), b: (u64, u64) },
    #[error("noisy pixels (ROI, periphery): {a:?} against {b:?}")]
    NoisyPixels {
        a: (usize, usize),
        b: (usize, usize),
    },
    #[error("noise contrast: {a:?} against {b:?}")]
    Contrast {
        a: Option<NoiseContrast>,
        b: Option<NoiseContrast>,
    },
    #[error("progress (pixels, fewest samples): {a:?} against {b:?}")]
    Progress { a: (u64, u32), b: (u64, u32) },
    #[error("progress: {a:?} against {b:?}")]
    HasProgress {
        a: Option<RoiProgress>,
        b: Option<RoiProgress>,
    },
    #[error("{what}: {a:e} against {b:e}")]
    Median { what: &'static str, a: f32, b: f32 },
}

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

/// How far the ROI has come: its pixels (d = 0), their fewest samples and the median standard
/// error of their mean luminance (pixels with fewer than two samples count as infinitely
/// noisy: the median is +∞ until most have two).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoiProgress {
    pub pixels: u64,
    pub min_samples: u32,
    pub median_se: f32,
}

impl RoiProgress {
    /// Measures `acc` over the pixels where `dgi` is 0; `None` when there are none.
    #[must_use]
    pub fn measure(acc: &Accumulation, dgi: &[f32]) -> Option<Self> {
        Self::measure_where(acc, dgi, |_| true)
    }

    /// [`Self::measure`] over the ROI pixels `shown` keeps (a wall camera's: pixels no tile
    /// shows are never sampled and would hold the fewest samples at 0 for ever).
    pub fn measure_where(
        acc: &Accumulation,
        dgi: &[f32],
        shown: impl Fn(usize) -> bool,
    ) -> Option<Self> {
        let mut se = Vec::new();
        let mut min_samples = u32::MAX;
        for (i, d) in dgi.iter().enumerate() {
            if *d != 0.0 || !shown(i) {
                continue;
            }
            min_samples = min_samples.min(acc.count[i]);
            se.push(
                acc.luminance_variance_of_mean(i)
                    .map_or(f32::INFINITY, f32::sqrt),
            );
        }
        if se.is_empty() {
            return None;
        }
        let n = se.len();
        let median = *se.select_nth_unstable_by(n / 2, f32::total_cmp).1;
        Some(Self {
            pixels: n as u64,
            min_samples,
            median_se: median,
        })
    }

    /// Seconds until the median SE reaches `target`, from the rate it fell at: SE ∝ 1/√n, and
    /// samples grow linearly in time, so t_target = t · (SE/target)² − t for `elapsed` = t
    /// seconds of sampling this ROI. `None` while the SE is undefined.
    #[must_use]
    pub fn seconds_to_se(&self, target: f64, elapsed: f64) -> Option<f64> {
        let se = f64::from(self.median_se);
        if !se.is_finite() || !(target > 0.0) || !(elapsed > 0.0) {
            return None;
        }
        Some((elapsed * (se / target).powi(2) - elapsed).max(0.0))
    }
}
