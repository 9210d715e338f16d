//! The denoised picture (DESIGN.md §8): the feature buffers of the renderer's view — albedo,
//! shading normal and depth for every pixel, sampled or not, from the features kernel on the
//! GPU (per band of rows) or its CPU twin — and the picture denoised with them by raygun's own
//! denoiser or by OIDN.

use glam::Vec3;

use super::{Engine, FrameError, Renderer};
use crate::filter::denoise::{self, DenoiseInput, Features};
use crate::filter::{Denoiser, FilterParams, oidn};
use crate::gpu::Backend;
use crate::trace::accum::Accumulation;
use crate::trace::features::features_cpu;
use crate::trace::gpu::{FeatureInputs, FeaturesKernel, GpuFeatures, TraceKernel};
use crate::trace::wall::WallCamera;

/// Rows of a band of the CPU denoiser: its working set stays a band's (the picture is the
/// unbanded one bit for bit).
const CPU_DENOISE_ROWS: u32 = 256;

impl Renderer<'_> {
    /// The feature buffers of the current view (camera or wall camera's eye): every pixel's, on
    /// this renderer's backend (the GPU kernel in the frame's bands, read back, or the CPU
    /// twin). They do not depend on the samples, only on the view: made once and kept until
    /// the view changes.
    pub fn features(&self) -> Result<&Features, FrameError> {
        if let Some(f) = self.features.get() {
            return Ok(f);
        }
        let f = self.compute_features()?;
        Ok(self.features.get_or_init(|| f))
    }

    /// [`Self::features`] moved out of the renderer (made now unless kept): for a caller about
    /// to end the render, without a second copy.
    pub fn take_features(&mut self) -> Result<Features, FrameError> {
        match self.features.take() {
            Some(f) => Ok(f),
            None => self.compute_features(),
        }
    }

    /// The picture of an accumulation and DGI read back already ([`Self::picture_of`])
    /// denoised by `denoiser` with this view's features ([`denoise_picture`]); `every` > 1 for
    /// an accumulation read at every `every`-th pixel of every `every`-th row (the viewer's
    /// reduced picture: the features are taken at the same pixels). Returns the picture and
    /// the pixels the denoiser dropped.
    pub fn denoised_picture_of(
        &self,
        params: &FilterParams,
        denoiser: Denoiser<'_>,
        acc: &Accumulation,
        dgi: &[f32],
        every: u32,
    ) -> Result<(Vec<Vec3>, u64), FrameError> {
        let filled = self.picture_of(params, acc, dgi)?;
        let all = self.features()?;
        let reduced;
        let features = if every > 1 {
            reduced = reduce(all, every, [acc.width, acc.height]);
            &reduced
        } else {
            all
        };
        // A reduced picture's pixels are not the wall camera's: its unshown ones are blacked
        // out below by the image pixel each one is.
        let wall = self.wall.as_ref().filter(|_| every <= 1);
        let kernels = match self.backend {
            Backend::Gpu(ctx) => Some(
                self.denoise_kernels
                    .get_or_init(|| denoise::gpu::DenoiseKernels::new(ctx)),
            ),
            Backend::Cpu => None,
        };
        let (mut image, dropped) = run_denoiser(
            self.backend,
            kernels,
            denoiser,
            acc,
            features,
            &filled,
            wall,
        )?;
        if let Some(wc) = self.wall.as_ref().filter(|_| every > 1) {
            let (w, step) = (acc.width as usize, every as usize);
            let full = self.settings.width as usize;
            for (i, v) in image.iter_mut().enumerate() {
                let p = (i / w * step) * full + (i % w) * step;
                if !wc.is_shown(p as u32) {
                    *v = Vec3::ZERO;
                }
            }
        }
        Ok((image, dropped))
    }

    fn compute_features(&self) -> Result<Features, FrameError> {
        let (w, h) = (self.settings.width, self.settings.height);
        let buffers = match &self.engine {
            Engine::Gpu {
                ctx, scene, bands, ..
            } => {
                let trace = TraceKernel::new(ctx);
                let kernel = FeaturesKernel::new(ctx);
                let mut albedo = Vec::with_capacity(w as usize * h as usize);
                let mut normal_depth = Vec::with_capacity(w as usize * h as usize);
                // One band at a time: its buffers are freed before the next one's.
                for b in bands {
                    let out = GpuFeatures::new(ctx, w, b.band)?;
                    let mut enc = ctx.device.create_command_encoder(&Default::default());
                    let inputs = FeatureInputs {
                        trace: &trace,
                        scene_gpu: scene,
                        scene: &self.packed,
                        settings: &self.settings,
                        wall: self.wall.as_ref(),
                    };
                    kernel.record(ctx, &mut enc, inputs, &out);
                    ctx.queue.submit([enc.finish()]);
                    let part = out.read(ctx)?;
                    albedo.extend(part.albedo);
                    normal_depth.extend(part.normal_depth);
                }
                crate::trace::features::FeatureBuffers {
                    albedo,
                    normal_depth,
                }
            }
            Engine::Cpu { .. } => features_cpu(&self.packed, &self.settings, self.wall.as_ref()),
        };
        Ok(Features {
            width: w,
            height: h,
            albedo: buffers.albedo,
            normal_depth: buffers.normal_depth,
        })
    }
}

/// `features` at every `every`-th pixel of every `every`-th row: a `size` picture's.
fn reduce(features: &Features, every: u32, size: [u32; 2]) -> Features {
    let (fw, step) = (features.width as usize, every as usize);
    let at = |i: usize| (i / size[0] as usize * step) * fw + (i % size[0] as usize) * step;
    let n = size[0] as usize * size[1] as usize;
    Features {
        width: size[0],
        height: size[1],
        albedo: (0..n).map(|i| features.albedo[at(i)]).collect(),
        normal_depth: (0..n).map(|i| features.normal_depth[at(i)]).collect(),
    }
}

/// `filled` (the filter's picture of `acc`) denoised by `denoiser` with `features` on
/// `backend`; pixels `wall` does not show stay black. Returns the picture and how many pixels
/// raygun's denoiser dropped for a NaN or infinite sum (0 with OIDN, which never sees one).
///
/// raygun's denoiser fills unsampled pixels from similar neighbours within its reach (62
/// pixels); one with no similar sampled neighbour in reach keeps the filter's value, as does
/// one OIDN gets no mean for ([`oidn::colour_input`]).
pub fn denoise_picture(
    backend: &Backend,
    denoiser: Denoiser<'_>,
    acc: &Accumulation,
    features: &Features,
    filled: &[Vec3],
    wall: Option<&WallCamera>,
) -> Result<(Vec<Vec3>, u64), FrameError> {
    run_denoiser(backend, None, denoiser, acc, features, filled, wall)
}

/// [`denoise_picture`] with the GPU's denoiser kernels when made already.
fn run_denoiser(
    backend: &Backend,
    kernels: Option<&denoise::gpu::DenoiseKernels>,
    denoiser: Denoiser<'_>,
    acc: &Accumulation,
    features: &Features,
    filled: &[Vec3],
    wall: Option<&WallCamera>,
) -> Result<(Vec<Vec3>, u64), FrameError> {
    let mut dropped = 0;
    let mut image = match denoiser {
        Denoiser::Interactive(params) => {
            let input = DenoiseInput::new(acc, features)?;
            let out = match backend {
                Backend::Gpu(ctx) => match kernels {
                    Some(k) => k.denoise_banded(ctx, &params, &input)?,
                    None => denoise::gpu::DenoiseKernels::new(ctx)
                        .denoise_banded(ctx, &params, &input)?,
                },
                Backend::Cpu => denoise::denoise_cpu_banded(&params, &input, CPU_DENOISE_ROWS)?,
            };
            dropped = out.dropped;
            filled_where_unreached(&out.image, acc, filled)
        }
        Denoiser::Oidn(device, quality) => {
            oidn::denoise_picture(device, acc, filled, Some(features), quality)?
        }
    };
    if let Some(wc) = wall {
        wc.blank_unshown(&mut image);
    }
    Ok((image, dropped))
}

/// raygun's denoiser's output as the picture shows it: where a pixel has no usable mean of its
/// own (unsampled, or a non-finite sum) and no similar source reached it (its output is 0), the
/// filter's value `filled`; elsewhere the denoiser's.
#[must_use]
pub fn filled_where_unreached(out: &[[f32; 4]], acc: &Accumulation, filled: &[Vec3]) -> Vec<Vec3> {
    out.iter()
        .zip(&acc.sum)
        .zip(&acc.count)
        .zip(filled)
        .map(|(((o, s), &n), f)| {
            let v = Vec3::new(o[0], o[1], o[2]);
            let usable = n > 0 && s.iter().all(|c| c.is_finite());
            if !usable && v == Vec3::ZERO { *f } else { v }
        })
        .collect()
}
