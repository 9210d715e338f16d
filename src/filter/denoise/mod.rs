//! raygun's interactive denoiser (DESIGN.md §8): an edge-avoiding à-trous wavelet filter
//! (Dammertz et al. 2010, with SVGF-style edge-stopping weights) over the accumulation, steered
//! by per-pixel features (albedo, shading normal, primary-hit depth) and by each pixel's sample
//! count and variance. Cheap enough for every shown picture: five passes of 25 taps.
//!
//! This file is the CPU twin of the kernel `shaders/filter/denoise.wgsl`: the same f32
//! arithmetic in the same order, so that the two agree to the rounding of `exp`, `sqrt` and
//! division on the GPU (`gpu::tests` names the tolerance). Dispatch: [`gpu`].
//!
//! # Inputs
//!
//! Per pixel i, row-major: the accumulation (RGB sum S_i, Σ of squared sample luminances Q_i,
//! sample count n_i; [`Accumulation`]) and the features ([`Features`]), which exist for every
//! pixel, sampled or not:
//!
//! * albedo a_i (RGB, the first non-specular hit's albedo averaged over the pixel's samples),
//!   stored as `[f32; 4]` / `vec4<f32>` whose fourth value is ignored;
//! * shading normal N_i (xyz, unit) and primary-hit depth z_i (distance along the ray, > 0),
//!   packed as `[N.x, N.y, N.z, z]`. **A miss has z = 0** (not ∞: ∞ − ∞ and ∞/∞ would make the
//!   depth weight NaN); its normal is ignored. Features must be finite and z ≥ 0
//!   ([`DenoiseInputError::Feature`] names the pixel and the field otherwise).
//!
//! # The filter, exactly
//!
//! Everything is f32; L(c) = 0.2126·c.r + 0.7152·c.g + 0.0722·c.b (in that order).
//!
//! **Classes.** Each pixel is, from its accumulation alone:
//!
//! * *unsampled*: n_i = 0;
//! * *dropped*: n_i > 0 and one of S_i.r, S_i.g, S_i.b, Q_i is NaN or ±∞ (tested by the bits:
//!   WGSL may assume finite values). Treated as unsampled, never read, and counted
//!   ([`Denoised::dropped`]);
//! * *sparse*: 1 ≤ n_i < 4 ([`MIN_VARIANCE_SAMPLES`]: too few samples to trust a variance
//!   estimate);
//! * *converged*: n_i ≥ 4 and v_i ≤ τ, with v_i the variance of the mean luminance evaluated
//!   in f32 as [`super::variance_of_mean`] defines it (and as the variance blend's kernel does):
//!   l̄ = L(S_i)/n, v_i = max(0, (Q_i − n·l̄·l̄)/(n − 1))/n;
//! * *noisy*: otherwise (n_i ≥ 4, v_i > τ).
//!
//! v_i is kept for noisy and converged pixels; it counts as 0 for the other classes.
//!
//! **Start.** x⁰_i = S_i.rgb / n_i and c⁰_i = n_i for sampled pixels (sparse, noisy, converged);
//! x⁰_i = 0, c⁰_i = 0 for unsampled and dropped ones. c is a pixel's weight as a source: its
//! sample count at the start, so each pixel's own estimate counts by its samples.
//!
//! **Pass k** (k = 0 … P − 1, step s = 2^k, default P = 5: steps 1, 2, 4, 8, 16), from
//! (x, c) to (x', c'). A converged pixel keeps (x, c). Any other pixel p visits the 5 × 5
//! taps q = p + s·(u, v), u, v ∈ {−2, …, 2}, rows (v) outer and columns (u) inner, skipping
//! those outside the image, with
//!
//! * h = h_u · h_v, h = (1, 4, 6, 4, 1)/16 (the cubic B-spline);
//! * w = h for q = p; otherwise the tap is **cut** (skipped: it adds nothing) if
//!   Δa = max_channel |a_p − a_q| > 0.1 (hard: albedo edges do not bleed), or exactly one of
//!   p, q is a miss, or both hit and d < 0.9 (≈ 25.8°) or r > 0.1, with
//!   d = N_p.x·N_q.x + N_p.y·N_q.y + N_p.z·N_q.z and r = |z_p − z_q| / max(z_p, z_q);
//!   else w = (h · w_n) · exp(−e) with one exponential for all the terms
//!   ([`feature_terms`]):
//!   * w_n = d^64 (six squarings) for two hits, 1 for two misses;
//!   * e = Δa/0.05 + r/0.05 for two hits, Δa/0.05 for two misses, in that order;
//!   * for a noisy p, then e += |L(x_p) − L(x_q)| / (4·√(v_p + v_q)) — the difference measured
//!     in standard deviations of the difference of the two means; nothing otherwise (a sparse
//!     or unsampled pixel has no variance to scale it with and relies on the features).
//!     Scaling by σ_p alone (SVGF) biases the picture dark under heavy-tailed noise: a dark
//!     pixel's variance estimate is small too, so it rejects bright neighbours (9 % on a flat
//!     plane at 4 samples a pixel, against 0.1 % with the pair's variance).
//!
//! Accumulating over the taps in order: num += (w·c_q)·x_q, den += w·c_q, W += w. If den > 0:
//! x'_p = num/den (per channel) and c'_p = den/W — the weighted mean of the sources' weights, so
//! a filled pixel becomes a source for the next pass without outweighing sampled ones. If
//! den = 0 (no similar source in reach): (x'_p, c'_p) = (x_p, c_p).
//!
//! **Output** o_p = x^P_p, RGB with alpha 1. Hence:
//!
//! * a converged pixel is its own mean S.rgb/n, bit for bit;
//! * a sparse or noisy pixel is a weighted mean of itself and its similar neighbours;
//! * an unsampled or dropped pixel is filled from similar neighbours within reach, and stays 0
//!   where there is none;
//! * a dropped pixel's values are never read: its weight as a source is 0;
//! * nothing crosses an edge where f = 0 (an albedo jump above 0.1, a normal turn above 25.8°, a
//!   relative depth jump above 10 %, hit against miss). What a pixel straddling an edge
//!   averaged into its own samples (and its averaged albedo) reaches its similar side: one
//!   pixel.
//!
//! The constants: σ_l = 4 (on the pair's standard deviation) and the normal exponent 64 are SVGF's order of magnitude (its 4 and
//! 128, a shallower normal falloff here because these normals are averaged over a pixel's
//! samples); σ_a = 0.05 and the albedo cut 0.1 keep albedos of one material (noise of textures,
//! averaging) together and separate materials that differ by a tenth; the depth cut 10 % and
//! σ_z = 0.05 separate objects whose depth differs by a tenth (a grazing surface whose depth
//! changes faster than 10 % over a tap is filtered less at the coarse steps).
//!
//! **Reach.** o_p depends on pixels within 2·(2^P − 1) = 62 pixels (P = 5) of p along each axis
//! ([`halo`]); a band of rows with that many rows of margin on each side gives the whole image's
//! values, bit for bit ([`denoise_cpu_banded`], [`gpu::DenoiseKernels::denoise_banded`]).
//!
//! # Memory
//!
//! On the GPU, [`DEVICE_BPP`] bytes a pixel: the accumulation (16 + 4), the two features
//! (16 each), a work buffer and the output (16 each). The CPU twin holds [`HOST_BPP`] beyond its
//! inputs: the classes, two (x, c) images, and the output's alpha set in place.
//!
//! # Numerics
//!
//! f32 throughout, on both sides. The kernel and this twin perform the same operations in the
//! same order; they differ where the GPU rounds `exp`, `sqrt` and division differently (a few
//! ulp) or contracts a multiply-add, and through five passes of weighted means.

pub mod gpu;

use rayon::prelude::*;

use crate::trace::accum::Accumulation;

/// σ_l: the luminance weight's scale, in standard deviations of the difference of two means.
pub const SIGMA_L: f32 = 4.0;
/// σ_a: the albedo weight's scale (largest channel difference).
pub const SIGMA_A: f32 = 0.05;
/// The albedo difference above which two pixels never mix.
pub const ALBEDO_CUT: f32 = 0.1;
/// The cosine between normals below which two pixels never mix (≈ 25.8°).
pub const NORMAL_CUT: f32 = 0.9;
/// σ_z: the depth weight's scale (relative depth difference).
pub const SIGMA_Z: f32 = 0.05;
/// The relative depth difference above which two pixels never mix.
pub const DEPTH_CUT: f32 = 0.1;
/// GPU bytes a pixel while denoising: accumulation 16 + 4, albedo 16, normal/depth 16, work
/// 16, output 16.
pub const DEVICE_BPP: u64 = 84;
/// The CPU twin's working set a pixel beyond its inputs: the class (8) and two `[f32; 4]`
/// images (32).
pub const HOST_BPP: u64 = 40;
/// The fewest samples whose variance a pixel's class and luminance weight trust: below, a
/// pixel is sparse. Two or three samples of a heavy-tailed estimator say little about its
/// variance: two dark samples (v = 0) would pass as converged and stay dark, and a variance
/// estimate that tracks the value makes dark sources reject bright neighbours more often than
/// the reverse (a filled region 3.4 % dark at 1.2 samples a pixel with 2).
pub const MIN_VARIANCE_SAMPLES: u32 = 4;
/// The cubic B-spline taps (1, 4, 6, 4, 1)/16.
pub const TAPS: [f32; 5] = [0.0625, 0.25, 0.375, 0.25, 0.0625];

/// The denoiser's settings.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DenoiseParams {
    /// τ: the variance of the mean luminance at and below which a pixel is converged and
    /// passes through (the filter's `--variance-threshold`, same units).
    pub variance_threshold: f32,
    /// P: the number of à-trous passes, steps 1, 2, …, 2^(P−1).
    pub passes: u32,
}

impl DenoiseParams {
    /// Five passes: steps up to 16, a footprint of 125 pixels — a sparse region sampled at a
    /// few per cent still finds sources.
    pub const DEFAULT_PASSES: u32 = 5;
    /// Most passes: steps up to 32 (a footprint of 253 pixels).
    pub const MAX_PASSES: u32 = 6;

    /// Checks both fields; the error names the field.
    pub fn validate(&self) -> Result<(), DenoiseInputError> {
        if !(self.variance_threshold > 0.0 && self.variance_threshold.is_finite()) {
            return Err(DenoiseInputError::Param {
                field: "variance_threshold",
                value: f64::from(self.variance_threshold),
                allowed: "a finite variance above 0",
            });
        }
        if !(1..=Self::MAX_PASSES).contains(&self.passes) {
            return Err(DenoiseInputError::Param {
                field: "passes",
                value: f64::from(self.passes),
                allowed: "1 to 6",
            });
        }
        Ok(())
    }
}

impl Default for DenoiseParams {
    fn default() -> Self {
        Self {
            variance_threshold: super::FilterParams::DEFAULT_VARIANCE_THRESHOLD,
            passes: Self::DEFAULT_PASSES,
        }
    }
}

/// The feature buffers (module docs): what the tracer writes beside the accumulation, in the
/// layout the kernel binds (`vec4<f32>` per pixel each, row-major).
#[derive(Clone, Debug, PartialEq)]
pub struct Features {
    pub width: u32,
    pub height: u32,
    /// `[r, g, b, ignored]`: the first non-specular hit's albedo, averaged over the samples.
    pub albedo: Vec<[f32; 4]>,
    /// `[N.x, N.y, N.z, depth]`: unit shading normal and primary-hit depth, 0 for a miss.
    pub normal_depth: Vec<[f32; 4]>,
}

/// Inputs or settings that the denoiser cannot use.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DenoiseInputError {
    #[error("denoiser parameter {field} = {value}: expected {allowed}")]
    Param {
        field: &'static str,
        value: f64,
        allowed: &'static str,
    },
    #[error(
        "the denoiser's {what} holds {got} pixels; the {width}×{height} accumulation needs {want}"
    )]
    Size {
        what: &'static str,
        got: usize,
        want: usize,
        width: u32,
        height: u32,
    },
    #[error("feature {field} at pixel ({x}, {y}) is {value}: expected {allowed}")]
    Feature {
        field: &'static str,
        value: f32,
        x: u32,
        y: u32,
        allowed: &'static str,
    },
}

/// The denoiser's inputs as slices (a band of rows is a sub-slice).
#[derive(Clone, Copy, Debug)]
pub struct DenoiseInput<'a> {
    pub width: u32,
    pub height: u32,
    pub sum: &'a [[f32; 4]],
    pub count: &'a [u32],
    pub albedo: &'a [[f32; 4]],
    pub normal_depth: &'a [[f32; 4]],
}

impl<'a> DenoiseInput<'a> {
    /// Checks that the accumulation and the features fit together and that every feature is
    /// usable (finite, depth ≥ 0).
    pub fn new(acc: &'a Accumulation, features: &'a Features) -> Result<Self, DenoiseInputError> {
        let (width, height) = (acc.width, acc.height);
        let want = width as usize * height as usize;
        let size = |what, got: usize| {
            if got == want {
                Ok(())
            } else {
                Err(DenoiseInputError::Size {
                    what,
                    got,
                    want,
                    width,
                    height,
                })
            }
        };
        size("accumulation sums", acc.sum.len())?;
        size("accumulation counts", acc.count.len())?;
        size("albedo feature", features.albedo.len())?;
        size("normal/depth feature", features.normal_depth.len())?;
        if (features.width, features.height) != (width, height) {
            return Err(DenoiseInputError::Size {
                what: "features",
                got: features.width as usize * features.height as usize,
                want,
                width,
                height,
            });
        }
        let at = |i: usize| ((i % width as usize) as u32, (i / width as usize) as u32);
        let bad = |field, value, i, allowed| {
            let (x, y) = at(i);
            DenoiseInputError::Feature {
                field,
                value,
                x,
                y,
                allowed,
            }
        };
        for (i, (a, nd)) in features
            .albedo
            .iter()
            .zip(&features.normal_depth)
            .enumerate()
        {
            for (c, name) in ["albedo.r", "albedo.g", "albedo.b"].into_iter().enumerate() {
                if !a[c].is_finite() {
                    return Err(bad(name, a[c], i, "a finite albedo"));
                }
            }
            for (c, name) in ["normal.x", "normal.y", "normal.z"].into_iter().enumerate() {
                if !nd[c].is_finite() {
                    return Err(bad(name, nd[c], i, "a finite normal"));
                }
            }
            if !(nd[3].is_finite() && nd[3] >= 0.0) {
                return Err(bad("depth", nd[3], i, "a finite depth ≥ 0 (0 for a miss)"));
            }
        }
        Ok(Self {
            width,
            height,
            sum: &acc.sum,
            count: &acc.count,
            albedo: &features.albedo,
            normal_depth: &features.normal_depth,
        })
    }

    /// Rows `r0..r1` alone.
    #[must_use]
    pub fn rows(&self, r0: u32, r1: u32) -> Self {
        let w = self.width as usize;
        let px = w * r0 as usize..w * r1 as usize;
        Self {
            width: self.width,
            height: r1 - r0,
            sum: &self.sum[px.clone()],
            count: &self.count[px.clone()],
            albedo: &self.albedo[px.clone()],
            normal_depth: &self.normal_depth[px],
        }
    }
}

/// The denoised picture and what was dropped.
#[derive(Clone, Debug, PartialEq)]
pub struct Denoised {
    /// Linear RGB with alpha 1, row-major.
    pub image: Vec<[f32; 4]>,
    /// Pixels whose accumulation was NaN or infinite, treated as unsampled.
    pub dropped: u64,
}

/// A pixel's class (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Class {
    Unsampled,
    Dropped,
    Sparse,
    /// With v, the variance of the mean luminance.
    Noisy(f32),
    /// With v.
    Converged(f32),
}

impl Class {
    /// v: the variance of the mean luminance of a noisy or converged pixel, else 0.
    #[must_use]
    pub fn variance(self) -> f32 {
        match self {
            Self::Noisy(v) | Self::Converged(v) => v,
            _ => 0.0,
        }
    }
}

/// Rec. 709 luminance, in the kernel's order.
#[inline]
#[must_use]
pub fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// A pixel's start (x⁰, c⁰) and class (the kernel's `own`).
#[must_use]
pub fn own(tau: f32, sum: [f32; 4], n: u32) -> ([f32; 4], Class) {
    if n == 0 {
        return ([0.0; 4], Class::Unsampled);
    }
    if !sum.iter().all(|v| v.is_finite()) {
        return ([0.0; 4], Class::Dropped);
    }
    let nf = n as f32;
    let x = [sum[0] / nf, sum[1] / nf, sum[2] / nf, nf];
    if n < MIN_VARIANCE_SAMPLES {
        return (x, Class::Sparse);
    }
    let mean_l = luminance([sum[0], sum[1], sum[2]]) / nf;
    let v = ((sum[3] - nf * mean_l * mean_l) / (nf - 1.0)).max(0.0) / nf;
    if v <= tau {
        return (x, Class::Converged(v));
    }
    (x, Class::Noisy(v))
}

/// The albedo, normal and depth terms of a pair (module docs): `None` where the tap is cut,
/// else `(w_n, e)` — the normal weight and the exponent the albedo and depth weights add up to.
#[inline]
#[must_use]
pub fn feature_terms(ap: [f32; 4], aq: [f32; 4], fp: [f32; 4], fq: [f32; 4]) -> Option<(f32, f32)> {
    let d = [
        (ap[0] - aq[0]).abs(),
        (ap[1] - aq[1]).abs(),
        (ap[2] - aq[2]).abs(),
    ];
    let da = d[0].max(d[1].max(d[2]));
    if da > ALBEDO_CUT {
        return None;
    }
    let hit_p = fp[3] > 0.0;
    if hit_p != (fq[3] > 0.0) {
        return None;
    }
    let ea = da / SIGMA_A;
    if !hit_p {
        return Some((1.0, ea));
    }
    let c = fp[0] * fq[0] + fp[1] * fq[1] + fp[2] * fq[2];
    if c < NORMAL_CUT {
        return None;
    }
    let rel = (fp[3] - fq[3]).abs() / fp[3].max(fq[3]);
    if rel > DEPTH_CUT {
        return None;
    }
    let mut wn = c;
    for _ in 0..6 {
        wn = wn * wn;
    }
    Some((wn, ea + rel / SIGMA_Z))
}

/// f(p, q) = w_n · exp(−e) of [`feature_terms`], 0 where the tap is cut: how much the features
/// let q count for p.
#[must_use]
pub fn feature_weight(ap: [f32; 4], aq: [f32; 4], fp: [f32; 4], fq: [f32; 4]) -> f32 {
    feature_terms(ap, aq, fp, fq).map_or(0.0, |(wn, e)| wn * (-e).exp())
}

/// The pixels the output at a pixel depends on along each axis: 2·(2^P − 1).
#[must_use]
pub fn halo(params: &DenoiseParams) -> u32 {
    2 * ((1 << params.passes) - 1)
}

/// The start: (x⁰, c⁰) per pixel, each pixel's class, and the dropped pixels of rows
/// `count_rows`.
fn start(
    tau: f32,
    input: &DenoiseInput<'_>,
    count_rows: std::ops::Range<u32>,
) -> (Vec<[f32; 4]>, Vec<Class>, u64) {
    let (x, class): (Vec<[f32; 4]>, Vec<Class>) = input
        .sum
        .par_iter()
        .zip(input.count.par_iter())
        .map(|(&s, &n)| own(tau, s, n))
        .unzip();
    let w = input.width as usize;
    let dropped = class[w * count_rows.start as usize..w * count_rows.end as usize]
        .iter()
        .filter(|c| **c == Class::Dropped)
        .count() as u64;
    (x, class, dropped)
}

/// One pass of step `step` for pixel (px, py) (the kernel's `atrous`, before the write).
fn atrous_pixel(
    input: &DenoiseInput<'_>,
    class: &[Class],
    src: &[[f32; 4]],
    step: i32,
    px: i32,
    py: i32,
) -> [f32; 4] {
    let (w, h) = (input.width as i32, input.height as i32);
    let i = (py * w + px) as usize;
    let here = src[i];
    if let Class::Converged(_) = class[i] {
        return here;
    }
    let lp = luminance([here[0], here[1], here[2]]);
    let (mut num, mut den, mut wsum) = ([0.0f32; 3], 0.0f32, 0.0f32);
    for (ty, hy) in TAPS.iter().enumerate() {
        let yy = py + (ty as i32 - 2) * step;
        if yy < 0 || yy >= h {
            continue;
        }
        for (tx, hx) in TAPS.iter().enumerate() {
            let xx = px + (tx as i32 - 2) * step;
            if xx < 0 || xx >= w {
                continue;
            }
            let q = (yy * w + xx) as usize;
            let t = src[q];
            let mut wt = hy * hx;
            if q != i {
                let Some((wn, mut e)) = feature_terms(
                    input.albedo[i],
                    input.albedo[q],
                    input.normal_depth[i],
                    input.normal_depth[q],
                ) else {
                    continue;
                };
                if let Class::Noisy(v) = class[i] {
                    let sd = (v + class[q].variance()).sqrt();
                    e += (lp - luminance([t[0], t[1], t[2]])).abs() / (SIGMA_L * sd);
                }
                wt = wt * wn * (-e).exp();
            }
            let wc = wt * t[3];
            num[0] += wc * t[0];
            num[1] += wc * t[1];
            num[2] += wc * t[2];
            den += wc;
            wsum += wt;
        }
    }
    if den > 0.0 {
        [num[0] / den, num[1] / den, num[2] / den, den / wsum]
    } else {
        here
    }
}

/// The denoiser over `input` (its parameters checked), counting the dropped pixels of rows
/// `count_rows` only (a band counts its own rows, not its halo's).
fn run(
    params: &DenoiseParams,
    input: &DenoiseInput<'_>,
    count_rows: std::ops::Range<u32>,
) -> Denoised {
    let (mut x, class, dropped) = start(params.variance_threshold, input, count_rows);
    let w = input.width as usize;
    let mut next = vec![[0.0f32; 4]; x.len()];
    for k in 0..params.passes {
        let step = 1i32 << k;
        next.par_chunks_mut(w.max(1))
            .enumerate()
            .for_each(|(py, row)| {
                for (px, o) in row.iter_mut().enumerate() {
                    *o = atrous_pixel(input, &class, &x, step, px as i32, py as i32);
                }
            });
        std::mem::swap(&mut x, &mut next);
    }
    for p in &mut x {
        p[3] = 1.0;
    }
    Denoised { image: x, dropped }
}

/// The denoised picture of `input` (the CPU twin of `shaders/filter/denoise.wgsl`).
pub fn denoise_cpu(
    params: &DenoiseParams,
    input: &DenoiseInput<'_>,
) -> Result<Denoised, DenoiseInputError> {
    params.validate()?;
    Ok(run(params, input, 0..input.height))
}

/// [`denoise_cpu`] in bands of at most `rows` rows, each denoised with [`halo`] rows of margin
/// on either side: the same picture, bit for bit, holding a band's working set at a time.
pub fn denoise_cpu_banded(
    params: &DenoiseParams,
    input: &DenoiseInput<'_>,
    rows: u32,
) -> Result<Denoised, DenoiseInputError> {
    params.validate()?;
    let rows = rows.max(1);
    let halo = halo(params);
    let (w, h) = (input.width as usize, input.height);
    let mut image = Vec::with_capacity(w * h as usize);
    let mut dropped = 0;
    for r0 in (0..h).step_by(rows as usize) {
        let r1 = (r0 + rows).min(h);
        let (s, e) = (r0.saturating_sub(halo), (r1 + halo).min(h));
        let part = run(params, &input.rows(s, e), r0 - s..r1 - s);
        image.extend_from_slice(&part.image[w * (r0 - s) as usize..w * (r1 - s) as usize]);
        dropped += part.dropped;
    }
    Ok(Denoised { image, dropped })
}

/// A synthetic scene for the denoiser's tests and benchmark, until the tracer writes features:
/// the noise-free radiance, a noisy accumulation of it and the features.
#[derive(Clone, Debug)]
pub struct SynthScene {
    /// The noise-free radiance per pixel (what the accumulation converges to).
    pub truth: Vec<[f32; 3]>,
    pub acc: Accumulation,
    pub features: Features,
}

/// `rounds` rounds of sampling `truth` ([`crate::filter::synth`]'s noise model: each sample is
/// the truth times an exponential variate of mean 1): a pixel takes a sample in a round with
/// probability `p`. Deterministic in `seed`.
#[must_use]
pub fn synth_samples(
    truth: &[[f32; 3]],
    width: u32,
    height: u32,
    rounds: u32,
    p: f32,
    seed: u32,
) -> Accumulation {
    let reference: Vec<glam::Vec3> = truth.iter().map(|t| glam::Vec3::from_array(*t)).collect();
    super::synth::accumulate(&reference, width, height, |_| p, rounds, seed)
}

/// A wall lit by a smooth gradient (its upper eighth a sky: misses, depth 0), split at 40 % of
/// the width into two albedos (grey 0.7; blue (0.2, 0.3, 0.6)), with a box face in the lower
/// right of the grey's albedo but turned 37° and 20 % nearer (an edge in normal and depth
/// only); sampled `rounds` times with probability `p` ([`synth_samples`]).
#[must_use]
pub fn synth_scene(width: u32, height: u32, rounds: u32, p: f32, seed: u32) -> SynthScene {
    let n = width as usize * height as usize;
    let (mut truth, mut albedo, mut normal_depth) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    let (wf, hf) = (width as f32, height as f32);
    for y in 0..height {
        for x in 0..width {
            let (u, v) = ((x as f32 + 0.5) / wf, (y as f32 + 0.5) / hf);
            if v < 0.125 {
                truth.push([0.6, 0.7, 0.9]);
                albedo.push([0.0; 4]);
                normal_depth.push([0.0; 4]);
                continue;
            }
            let light = 0.6 + 0.4 * (3.0 * u).sin() * (2.0 * v).cos();
            let (a, nd) = if u > 0.6 && v > 0.55 && u < 0.9 {
                ([0.7, 0.7, 0.7], [0.6, 0.0, 0.8, 3.2])
            } else if u < 0.4 {
                ([0.7, 0.7, 0.7], [0.0, 0.0, 1.0, 4.0 + 0.2 * v])
            } else {
                ([0.2, 0.3, 0.6], [0.0, 0.0, 1.0, 4.0 + 0.2 * v])
            };
            truth.push([a[0] * light, a[1] * light, a[2] * light]);
            albedo.push([a[0], a[1], a[2], 0.0]);
            normal_depth.push(nd);
        }
    }
    let acc = synth_samples(&truth, width, height, rounds, p, seed);
    SynthScene {
        truth,
        acc,
        features: Features {
            width,
            height,
            albedo,
            normal_depth,
        },
    }
}

#[cfg(test)]
mod tests;
