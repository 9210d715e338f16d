//! Sparse-sample filtering (DESIGN.md §8): the paper's variable-radius Gaussian over sampled
//! pixels only, blended with the unfiltered pixel as the pixel converges.
//!
//! # The filter, exactly
//!
//! For pixel *i* with sample count s_i, RGB sum S_i, DGI value d_i ∈ [0, 1]:
//!
//! * Unfiltered value u_i = S_i / s_i, and 0 where s_i = 0.
//! * Blend weight w_i ∈ [0, 1] ([`Blend`]):
//!   - `count` (the paper): w_i = max(0, 1 − s_i / c).
//!   - `variance` (the paper's proposal instead of the fixed c): with v_i the estimated variance
//!     of the pixel's mean luminance (unbiased sample variance of the sample luminances, from the
//!     accumulated sum of squares, divided by s_i) and the user threshold τ:
//!     w_i = 0 when v_i ≤ τ, w_i = 1 − τ / v_i when v_i > τ, and w_i = 1 with fewer than two
//!     samples (no estimate yet). The mapping is the paper's count blend with c replaced by the
//!     count at which this pixel's variance of the mean would reach τ: v ∝ 1/s gives
//!     s/c = τ/v. It is continuous in v and exactly 0 at and under the threshold.
//! * Kernel radius k_i = w_i · k_max · d_i (pixels), σ_i = k_i / 3.
//! * Support: the circular window dx² + dy² ≤ k_i² (a Gaussian of radius k_i is cut at 3σ),
//!   clipped to the image. Taps are the pixels of the window with s_j ≥ 1, each weighted by
//!   g = exp(−(dx² + dy²) / (2σ_i²)) — not by its sample count: the paper weights pixels, and
//!   unsampled pixels carry no weight at all, so they never darken the result.
//! * F_i = Σ g·u_j / Σ g over the taps; output o_i = w_i · F_i + (1 − w_i) · u_i.
//! * Exact pass-throughs: o_i = u_i, bit for bit, when w_i = 0 (s_i ≥ c, or v_i ≤ τ) and when
//!   k_i < 1 (the window holds only the pixel itself).
//! * No sampled pixel in the window (Σ g = 0; only possible for an unsampled pixel): o_i = u_i
//!   = 0. The filter does not invent data beyond k_max: with the paper's p_min = 0 a pixel far
//!   from every sample stays black, as in the raw image.
//!
//! The output is linear RGB with alpha 1.
//!
//! # Implementations
//!
//! * [`exact`]: the definition above, a 2D loop per pixel (a variable radius is not separable).
//!   CPU twin in f64 ([`exact::filter_cpu`]) and kernel `shaders/filter/exact.wgsl`.
//! * [`fast`]: the same function from a pyramid of Gaussian-blurred (Σ g·u, Σ g) pairs — a
//!   normalised convolution, so unsampled pixels contribute zero weight there too. Pixels with
//!   k_i ≤ [`fast::K_DIRECT`] run the exact loop; larger kernels interpolate between the two
//!   pyramid levels that bracket σ_i² (matching the kernel's variance). Its error against the
//!   exact filter is measured and bounded in `tests/render/filter_fast.rs`. CPU twin
//!   [`fast::filter_cpu`] (the pyramid in [`pyramid`]); kernels `shaders/filter/pyramid.wgsl` and
//!   `shaders/filter/fast.wgsl`.
//! * This file: the definitions both kernels share (w_i, k_i, the per-pixel state), whose WGSL
//!   is `shaders/filter/common.wgsl`.
//! * [`gpu`]: the dispatch of both.
//! * [`Filter`]: the stage's one entry point, on either backend.
//!
//! # Numerics
//!
//! The variance estimate comes from the f32 sum of squared luminance; its cancellation limits
//! its resolution to about 1e-7 of the mean squared luminance per sample, so thresholds far
//! below that are not meaningful. The kernels work in f32, the exact twin in f64.

pub mod denoise;
pub mod exact;
pub mod fast;
pub mod gpu;
pub mod oidn;
pub mod pyramid;
pub mod synth;

use glam::{DVec3, Vec3};
use serde::Serialize;

pub use gpu::FilterGpuError;

use crate::gpu::{Backend, GpuContext};
use crate::trace::accum::Accumulation;

/// Which implementation runs (`--filter`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FilterKind {
    /// No filtering: the unfiltered mean image (0 where a pixel has no sample).
    Off,
    /// The paper's filter, computed exactly (slow at large k_max).
    Exact,
    /// The pyramid approximation of the paper's filter, for interactive use.
    #[default]
    Fast,
}

/// What denoises the picture after the filter (`--denoise`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DenoiseKind {
    /// None: the filter's picture.
    #[default]
    Off,
    /// raygun's own edge-avoiding à-trous denoiser, on the render's backend.
    Interactive,
    /// Intel Open Image Denoise 2, opened at run time.
    Oidn,
}

/// How a picture is denoised once `--denoise` is resolved (DESIGN.md §8): both are steered by
/// the render's feature buffers (albedo, shading normal, depth).
#[derive(Clone, Copy, Debug)]
pub enum Denoiser<'a> {
    /// raygun's own denoiser ([`denoise`]) with these settings, on the render's backend.
    Interactive(denoise::DenoiseParams),
    /// Intel Open Image Denoise on this device at this quality.
    Oidn(&'a oidn::Device, oidn::Quality),
}

/// How the filtered value is blended with the unfiltered pixel (`--filter-blend`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Blend {
    /// The paper: w = max(0, 1 − s/c), fixed c.
    #[default]
    Count,
    /// Per-pixel estimated variance of the mean luminance against a threshold τ.
    Variance,
}

/// The filter's settings. f32 because that is what the kernels see; the CPU twins widen them
/// exactly, so both decide on the same numbers.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FilterParams {
    pub kind: FilterKind,
    pub blend: Blend,
    /// Largest kernel radius, pixels (k_i = w_i · k_max · d_i).
    pub k_max: f32,
    /// Sample count at which the count blend reaches the unfiltered pixel.
    pub c: f32,
    /// τ: variance of the mean luminance (linear luminance², the accumulation's units) at and
    /// below which the variance blend returns the unfiltered pixel.
    pub variance_threshold: f32,
}

impl FilterParams {
    /// 16 px: a quarter of a HORNET panel's height at 4K render scale; `bench filter` reports
    /// the error for 8, 16 and 32.
    pub const DEFAULT_K_MAX: f32 = 16.0;
    /// 64 samples: outside the ROI a pixel sampled with p = 1/2 sheds its blur after about 128
    /// iterations, as its own noise has dropped to 1/8 of one sample's.
    pub const DEFAULT_C: f32 = 64.0;
    /// τ = 1e-4: a standard error of the mean luminance of 0.01, 1 % of a white diffuse surface
    /// under a unit environment.
    pub const DEFAULT_VARIANCE_THRESHOLD: f32 = 1e-4;
    /// Largest accepted k_max: the fast pyramid has at most [`pyramid::MAX_LEVELS`] levels, which
    /// reach σ = 64/3; the exact loop then visits 129² pixels per pixel.
    pub const MAX_K_MAX: f32 = 64.0;

    /// Checks every field; the error names the field and says what is allowed.
    pub fn validate(&self) -> Result<(), FilterParamsError> {
        let check = |field, value: f32, ok: bool, allowed| {
            if ok {
                Ok(())
            } else {
                Err(FilterParamsError {
                    field,
                    value,
                    allowed,
                })
            }
        };
        check(
            "k_max (--k-max)",
            self.k_max,
            self.k_max >= 0.0 && self.k_max <= Self::MAX_K_MAX,
            "a number of pixels from 0 to 64",
        )?;
        check(
            "c (--filter-c)",
            self.c,
            self.c > 0.0 && self.c.is_finite(),
            "a finite sample count above 0",
        )?;
        check(
            "variance_threshold (--variance-threshold)",
            self.variance_threshold,
            self.variance_threshold > 0.0 && self.variance_threshold.is_finite(),
            "a finite variance above 0",
        )
    }
}

impl Default for FilterParams {
    fn default() -> Self {
        Self {
            kind: FilterKind::default(),
            blend: Blend::default(),
            k_max: Self::DEFAULT_K_MAX,
            c: Self::DEFAULT_C,
            variance_threshold: Self::DEFAULT_VARIANCE_THRESHOLD,
        }
    }
}

/// A filter parameter outside its range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("filter parameter {field} = {value}: expected {allowed}")]
pub struct FilterParamsError {
    pub field: &'static str,
    pub value: f32,
    pub allowed: &'static str,
}

/// Inputs that do not fit together.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FilterInputError {
    #[error("the DGI has {got} values; the {width}×{height} accumulation needs {want}")]
    DgiSize {
        got: usize,
        want: usize,
        width: u32,
        height: u32,
    },
    #[error(
        "the accumulation's buffers hold {sum} sums and {count} counts; {width}×{height} needs {want}"
    )]
    AccumulationSize {
        sum: usize,
        count: usize,
        want: usize,
        width: u32,
        height: u32,
    },
    #[error("DGI value {value} at pixel ({x}, {y}) is outside [0, 1]")]
    DgiValue { value: f32, x: u32, y: u32 },
    #[error(transparent)]
    Params(#[from] FilterParamsError),
}

/// Checks that the accumulation, the DGI and the parameters fit together.
pub fn check_inputs(
    params: &FilterParams,
    acc: &Accumulation,
    dgi: &[f32],
) -> Result<(), FilterInputError> {
    params.validate()?;
    let want = acc.width as usize * acc.height as usize;
    if acc.sum.len() != want || acc.count.len() != want {
        return Err(FilterInputError::AccumulationSize {
            sum: acc.sum.len(),
            count: acc.count.len(),
            want,
            width: acc.width,
            height: acc.height,
        });
    }
    if dgi.len() != want {
        return Err(FilterInputError::DgiSize {
            got: dgi.len(),
            want,
            width: acc.width,
            height: acc.height,
        });
    }
    if let Some(i) = dgi.iter().position(|d| !(0.0..=1.0).contains(d)) {
        return Err(FilterInputError::DgiValue {
            value: dgi[i],
            x: (i % acc.width as usize) as u32,
            y: (i / acc.width as usize) as u32,
        });
    }
    Ok(())
}

/// Rec. 709 luminance in f64 (the weights of [`crate::trace::accum::luminance`]).
#[inline]
fn luminance64(r: f64, g: f64, b: f64) -> f64 {
    0.2126 * r + 0.7152 * g + 0.0722 * b
}

/// The estimated variance of the pixel's mean luminance (f64), `None` with fewer than two
/// samples. Same formula as the kernels: (Σl² − n·l̄²) / (n − 1) / n, clamped at 0.
#[must_use]
pub fn variance_of_mean(sum: [f32; 4], count: u32) -> Option<f64> {
    if count < 2 {
        return None;
    }
    let n = f64::from(count);
    let mean_l = luminance64(f64::from(sum[0]), f64::from(sum[1]), f64::from(sum[2])) / n;
    let var = ((f64::from(sum[3]) - n * mean_l * mean_l) / (n - 1.0)).max(0.0);
    Some(var / n)
}

/// The blend weight w_i (module docs).
#[must_use]
pub fn blend_weight(params: &FilterParams, sum: [f32; 4], count: u32) -> f64 {
    match params.blend {
        Blend::Count => (1.0 - f64::from(count) / f64::from(params.c)).max(0.0),
        Blend::Variance => match variance_of_mean(sum, count) {
            None => 1.0,
            Some(v) => {
                let tau = f64::from(params.variance_threshold);
                if v <= tau { 0.0 } else { 1.0 - tau / v }
            }
        },
    }
}

/// What the filter knows about one pixel before looking at its neighbours.
#[derive(Clone, Copy, Debug)]
pub struct PixelState {
    /// The unfiltered value u_i.
    pub mean: DVec3,
    pub sampled: bool,
    /// Blend weight w_i.
    pub w: f64,
    /// Kernel radius k_i, pixels.
    pub k: f64,
}

/// u_i, w_i and k_i of pixel `i` (f64 from the f32 inputs).
#[must_use]
pub fn pixel_state(params: &FilterParams, acc: &Accumulation, dgi: &[f32], i: usize) -> PixelState {
    let (s, n) = (acc.sum[i], acc.count[i]);
    let mean = if n == 0 {
        DVec3::ZERO
    } else {
        DVec3::new(f64::from(s[0]), f64::from(s[1]), f64::from(s[2])) / f64::from(n)
    };
    let w = blend_weight(params, s, n);
    PixelState {
        mean,
        sampled: n > 0,
        w,
        k: w * f64::from(params.k_max) * f64::from(dgi[i]),
    }
}

/// The unfiltered mean image (0 where a pixel has no sample), f64.
#[must_use]
pub fn unfiltered_cpu(acc: &Accumulation) -> Vec<DVec3> {
    (0..acc.count.len())
        .map(|i| {
            let (s, n) = (acc.sum[i], acc.count[i]);
            if n == 0 {
                DVec3::ZERO
            } else {
                DVec3::new(f64::from(s[0]), f64::from(s[1]), f64::from(s[2])) / f64::from(n)
            }
        })
        .collect()
}

/// Runs the CPU twin that `params.kind` names.
pub fn filter_cpu(
    params: &FilterParams,
    acc: &Accumulation,
    dgi: &[f32],
) -> Result<Vec<DVec3>, FilterInputError> {
    check_inputs(params, acc, dgi)?;
    Ok(match params.kind {
        FilterKind::Off => unfiltered_cpu(acc),
        FilterKind::Exact => exact::filter_cpu(params, acc, dgi),
        FilterKind::Fast => fast::filter_cpu(params, acc, dgi),
    })
}

/// The filter stage on one backend: the GPU kernels (compiled once, at [`Filter::new`]) or
/// the CPU twin. Every caller that wants a filtered image goes through here; on the GPU, a
/// picture larger than one storage binding is filtered in bands of rows.
pub enum Filter<'a> {
    Gpu {
        ctx: &'a GpuContext,
        kernels: gpu::FilterKernels,
    },
    Cpu,
}

impl<'a> Filter<'a> {
    #[must_use]
    pub fn new(backend: &'a Backend) -> Self {
        match backend {
            Backend::Gpu(ctx) => Self::Gpu {
                ctx,
                kernels: gpu::FilterKernels::new(ctx),
            },
            Backend::Cpu => Self::Cpu,
        }
    }

    /// `"gpu"` or `"cpu"`.
    #[must_use]
    pub fn backend_name(&self) -> &'static str {
        match self {
            Self::Gpu { .. } => "gpu",
            Self::Cpu => "cpu",
        }
    }

    /// The filtered mean image in f64 (the GPU's f32 widened): [`filter_cpu`] or its kernels.
    pub fn apply(
        &self,
        params: &FilterParams,
        acc: &Accumulation,
        dgi: &[f32],
    ) -> Result<Vec<DVec3>, gpu::FilterGpuError> {
        Ok(match self.gpu_banded(params, acc, dgi)? {
            Some(image) => image
                .iter()
                .map(|p| DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
                .collect(),
            None => filter_cpu(params, acc, dgi)?,
        })
    }

    /// The GPU kernels' picture, in bands where it exceeds one binding; `None` on the CPU
    /// backend, and where not even one band with its halo fits a binding (a binding of fewer
    /// rows than the filter reaches): the CPU twin, the same function, filters those.
    fn gpu_banded(
        &self,
        params: &FilterParams,
        acc: &Accumulation,
        dgi: &[f32],
    ) -> Result<Option<Vec<[f32; 4]>>, gpu::FilterGpuError> {
        let Self::Gpu { ctx, kernels } = self else {
            return Ok(None);
        };
        match kernels.filter_banded(ctx, params, acc, dgi) {
            Ok(image) => Ok(Some(image)),
            Err(gpu::FilterGpuError::Gpu(crate::gpu::GpuError::TooLarge { .. })) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// [`Self::image`] with the filter's own time in ms: the kernels' (GPU timestamps where
    /// the adapter has them, else the wall clock around submit-and-wait; uploads and the
    /// read-back excluded) or the CPU twin's wall clock; a picture the kernels filter in bands
    /// ([`gpu::fits_one_binding`]) is timed by the wall clock around them all. The flag says
    /// whether timestamps were used.
    pub fn timed_image(
        &self,
        params: &FilterParams,
        acc: &Accumulation,
        dgi: &[f32],
    ) -> Result<(Vec<Vec3>, f64, bool), gpu::FilterGpuError> {
        match self {
            Self::Gpu { ctx, kernels }
                if params.kind != FilterKind::Off
                    && gpu::fits_one_binding(ctx, params, [acc.width, acc.height]) =>
            {
                kernels.with_prepared(ctx, params, acc, dgi, |run| {
                    let timer = crate::gpu::PassTimer::new(ctx, 1);
                    let t = std::time::Instant::now();
                    let mut enc = ctx.device.create_command_encoder(&Default::default());
                    run.record(&mut enc, timer.as_ref().map(|t| (t, 0)));
                    if let Some(timer) = &timer {
                        timer.resolve(&mut enc);
                    }
                    ctx.queue.submit([enc.finish()]);
                    ctx.wait()?;
                    let wall = t.elapsed().as_secs_f64() * 1e3;
                    let ms = match &timer {
                        Some(timer) => timer.read_ms(ctx)?[0],
                        None => wall,
                    };
                    let out: Vec<[f32; 4]> = ctx.read_buffer(&run.output)?;
                    let image = out.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
                    Ok((image, ms, timer.is_some()))
                })
            }
            _ => {
                let t = std::time::Instant::now();
                let image = self.image(params, acc, dgi)?;
                Ok((image, t.elapsed().as_secs_f64() * 1e3, false))
            }
        }
    }

    /// The picture: the mean image of `acc` filtered by `params` (linear RGB, row-major);
    /// [`FilterKind::Off`] is the accumulation's own mean image on either backend.
    pub fn image(
        &self,
        params: &FilterParams,
        acc: &Accumulation,
        dgi: &[f32],
    ) -> Result<Vec<Vec3>, gpu::FilterGpuError> {
        // Straight to f32: a widened copy of a large image would only raise the peak.
        Ok(match (self, params.kind) {
            (_, FilterKind::Off) => acc.mean_image(),
            _ => match self.gpu_banded(params, acc, dgi)? {
                Some(image) => image.iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect(),
                None => filter_cpu(params, acc, dgi)?
                    .iter()
                    .map(|p| p.as_vec3())
                    .collect(),
            },
        })
    }
}

/// The pixels on each side of a region that the filter reads for the region's pixels, and the
/// multiple a region's origin must sit on: `(halo, align)`, the halo a multiple of `align`.
/// The filter is the same along both axes, so one pair serves rows (bands) and columns (an
/// owner's tiles, DESIGN.md §12); a region of the image filtered on its own with that margin
/// around it, its origin on multiples of `align`, has the whole image's values inside.
///
/// [`FilterKind::Off`] reads the pixel alone. The exact filter's window reaches ⌊k⌋ ≤ ⌊k_max⌋
/// pixels. The fast filter's pixel reads two texels of a level (± its step); a level-ℓ texel
/// sums its predecessor's texels within its pass's reach, down to the accumulation: the halo is the largest of those sums plus the
/// step, and regions start on a multiple of the coarsest step so that every level's texel grid
/// in a region is the whole image's (the levels' origins and steps do not depend on the image's
/// size).
#[must_use]
pub fn halo(params: &FilterParams) -> (u32, u32) {
    use pyramid::{Plan, Target};
    let round_up = |v: u32, a: u32| v.div_ceil(a) * a;
    match params.kind {
        FilterKind::Off => return (0, 1),
        FilterKind::Exact => return (params.k_max.floor() as u32 + 1, 1),
        FilterKind::Fast => {}
    }
    let plan = Plan::new(1, 1, params.k_max);
    let mut reach = pyramid::K_DIRECT.ceil();
    let mut depth = 0.0f64;
    let mut align = 1;
    for (l, level) in plan.levels.iter().enumerate() {
        let (src_origin, src_step) = match l {
            0 => (0.0, 1.0),
            _ => (
                plan.levels[l - 1].origin,
                f64::from(plan.levels[l - 1].step),
            ),
        };
        let pass = plan
            .passes
            .iter()
            .find(|p| p.axis == 1 && p.target == Target::Level(l))
            .expect("every level has its y pass");
        let offset = |t: usize| {
            (src_origin - level.origin + (f64::from(pass.first) + t as f64) * src_step).abs()
        };
        depth += offset(0).max(offset(pass.weights.len().saturating_sub(1)));
        reach = reach.max(depth + f64::from(level.step));
        align = align.max(level.step);
    }
    (round_up(reach.ceil() as u32 + 2, align), align)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_each_bad_field_is_named() {
        FilterParams::default().validate().unwrap();
        let bad = [
            (
                FilterParams {
                    k_max: 65.0,
                    ..Default::default()
                },
                "k_max",
            ),
            (
                FilterParams {
                    k_max: f32::NAN,
                    ..Default::default()
                },
                "k_max",
            ),
            (
                FilterParams {
                    c: 0.0,
                    ..Default::default()
                },
                "c (--filter-c)",
            ),
            (
                FilterParams {
                    variance_threshold: f32::INFINITY,
                    ..Default::default()
                },
                "variance_threshold",
            ),
        ];
        for (p, field) in bad {
            let e = p.validate().unwrap_err();
            assert!(e.field.starts_with(field), "{e}");
            assert!(e.to_string().contains(field), "{e}");
        }
    }

    #[test]
    fn variance_blend_is_zero_at_the_threshold_and_continuous_above_it() {
        // Grey samples 1, 3: luminance variance 2, variance of the mean 1.
        let sum = [4.0, 4.0, 4.0, 10.0];
        let v = variance_of_mean(sum, 2).unwrap();
        assert!((v - 1.0).abs() < 1e-6, "{v}");
        let at = |tau: f32| {
            blend_weight(
                &FilterParams {
                    blend: Blend::Variance,
                    variance_threshold: tau,
                    ..Default::default()
                },
                sum,
                2,
            )
        };
        assert_eq!(at(1.5), 0.0);
        assert!((at(0.5) - 0.5).abs() < 1e-6);
        assert!(at(1.0 - 1e-6) < 1e-5);
        // One sample: no estimate, fully filtered.
        let p = FilterParams {
            blend: Blend::Variance,
            ..Default::default()
        };
        assert_eq!(blend_weight(&p, [1.0, 1.0, 1.0, 1.0], 1), 1.0);
    }

    #[test]
    fn count_blend_matches_the_paper() {
        let p = FilterParams {
            c: 8.0,
            ..Default::default()
        };
        assert_eq!(blend_weight(&p, [0.0; 4], 0), 1.0);
        assert_eq!(blend_weight(&p, [0.0; 4], 2), 0.75);
        assert_eq!(blend_weight(&p, [0.0; 4], 8), 0.0);
        assert_eq!(blend_weight(&p, [0.0; 4], 100), 0.0);
    }
}
