//! `bench denoise`'s four methods on one accumulation, and the denoisers' time per picture on the
//! synthetic scene ([`super`]).

use std::time::Instant;

use glam::Vec3;

use super::DenoiseBenchError;
use crate::bench::median;
use crate::filter::denoise::gpu::{DenoiseKernels, UploadedDenoiseInputs};
use crate::filter::denoise::{self, DenoiseInput, DenoiseParams, Features};
use crate::filter::{Filter, FilterParams, oidn};
use crate::gpu::{Backend, GpuContext, PassTimer};
use crate::trace::accum::Accumulation;

/// The denoiser's kernels on one picture: its output (RGBA) and the kernels' time (timestamps where
/// the adapter has them, else the wall clock around submit-and-wait; a picture larger than one
/// binding is denoised in bands, timed by the wall clock around them all).
pub(super) fn interactive_gpu(
    ctx: &GpuContext,
    kernels: &DenoiseKernels,
    params: &DenoiseParams,
    input: &DenoiseInput<'_>,
) -> Result<(Vec<[f32; 4]>, f64), DenoiseBenchError> {
    if !denoise::gpu::fits_one_binding(ctx, [input.width, input.height]) {
        let t = Instant::now();
        let d = kernels.denoise_banded(ctx, params, input)?;
        return Ok((d.image, t.elapsed().as_secs_f64() * 1e3));
    }
    let uploaded = UploadedDenoiseInputs::new(ctx, input)?;
    let run = kernels.prepare(ctx, params, &uploaded.inputs(), [0, input.height])?;
    let timer = PassTimer::new(ctx, 1);
    let t = Instant::now();
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
    let out = run.read(ctx)?;
    Ok((out.image, ms))
}

/// One listed iteration count of one FOV: the count, the render's time to it, each method's
/// [relMSE ROI, periphery, ꟻLIP ROI, periphery] (`None` for a method not run) and time.
pub(super) type Measured = (u32, f64, [Option<[f64; 4]>; 4], [f64; 4]);

/// The four pictures of one accumulation, and each method's time.
pub(super) struct Pictures {
    pub(super) images: Vec<Option<Vec<Vec3>>>,
    pub(super) ms: [f64; 4],
    pub(super) ms_cpu_twin: Option<f64>,
}

pub(super) struct Methods<'a> {
    pub(super) backend: &'a Backend,
    pub(super) filter: Filter<'a>,
    pub(super) kernels: Option<DenoiseKernels>,
    pub(super) oidn: Option<oidn::Device>,
    pub(super) features: Features,
    pub(super) albedo3: Vec<f32>,
    pub(super) normal3: Vec<f32>,
}

impl<'a> Methods<'a> {
    /// The methods on `backend`, with the features of `g`'s view (the CPU twin; its time in
    /// ms beside) and OIDN's `device` where there is one.
    pub(super) fn new(
        backend: &'a Backend,
        g: &crate::frame::Renderer<'_>,
        oidn: Option<oidn::Device>,
    ) -> (Self, f64) {
        let t = Instant::now();
        let f = crate::trace::features::features_cpu(
            &g.packed,
            &g.settings,
            crate::frame::Render::wall(g),
        );
        let features_ms = t.elapsed().as_secs_f64() * 1e3;
        let features = Features {
            width: g.settings.width,
            height: g.settings.height,
            albedo: f.albedo,
            normal_depth: f.normal_depth,
        };
        let (albedo3, normal3) = oidn::auxiliary(&features);
        let methods = Self {
            backend,
            filter: Filter::new(backend),
            kernels: match backend {
                Backend::Gpu(ctx) => Some(DenoiseKernels::new(ctx)),
                Backend::Cpu => None,
            },
            oidn,
            features,
            albedo3,
            normal3,
        };
        (methods, features_ms)
    }

    pub(super) fn pictures(
        &self,
        acc: &Accumulation,
        dgi: &[f32],
    ) -> Result<Pictures, DenoiseBenchError> {
        let off = acc.mean_image();
        let (filtered, filter_ms, _) =
            self.filter
                .timed_image(&FilterParams::default(), acc, dgi)?;
        let params = DenoiseParams::default();
        let input = DenoiseInput::new(acc, &self.features)?;
        let t = Instant::now();
        let cpu = denoise::denoise_cpu(&params, &input)?;
        let cpu_ms = t.elapsed().as_secs_f64() * 1e3;
        let (raw, interactive_ms, twin) = match (self.backend, &self.kernels) {
            (Backend::Gpu(ctx), Some(k)) => {
                let (image, ms) = interactive_gpu(ctx, k, &params, &input)?;
                (image, ms, Some(cpu_ms))
            }
            _ => (cpu.image, cpu_ms, None),
        };
        // As the picture shows it: the filter's value where no similar source reached a pixel
        // without a sample (the filter's time is not counted: it is the picture without a
        // denoiser).
        let interactive = crate::frame::filled_where_unreached(&raw, acc, &filtered);
        let (oidn_image, oidn_ms) = match &self.oidn {
            Some(device) => {
                let (colour, _) = oidn::colour_input(acc, &filtered);
                let t = Instant::now();
                let out = device.denoise(
                    oidn::Images {
                        size: [acc.width, acc.height],
                        color: &colour,
                        albedo: Some(&self.albedo3),
                        normal: Some(&self.normal3),
                    },
                    oidn::Quality::High,
                )?;
                let ms = t.elapsed().as_secs_f64() * 1e3 + filter_ms;
                let image = out
                    .chunks_exact(3)
                    .map(|c| Vec3::new(c[0], c[1], c[2]))
                    .collect();
                (Some(image), ms)
            }
            None => (None, f64::NAN),
        };
        Ok(Pictures {
            images: vec![Some(off), Some(filtered), Some(interactive), oidn_image],
            ms: [0.0, filter_ms, interactive_ms, oidn_ms],
            ms_cpu_twin: twin,
        })
    }
}

/// What [`time_interactive`] measured.
pub(super) struct InteractiveTiming {
    pub(super) cpu_ms: f64,
    pub(super) gpu_ms: Option<f64>,
    pub(super) gpu_timestamps: bool,
}

/// The denoiser's ms per picture on the synthetic scene at `width × height`: the CPU twin's
/// wall clock and, on a GPU backend, the kernels' time ([`interactive_gpu`]); medians of `runs`
/// after a warm-up run of each when `warm_up` (the first size: later ones find the threads and
/// pipelines warm).
pub(super) fn time_interactive(
    backend: &Backend,
    kernels: Option<&DenoiseKernels>,
    width: u32,
    height: u32,
    runs: u32,
    warm_up: bool,
) -> Result<InteractiveTiming, DenoiseBenchError> {
    let s = denoise::synth_scene(width, height, 1, 0.5, 1);
    let input = DenoiseInput::new(&s.acc, &s.features)?;
    let params = DenoiseParams::default();
    let skip = u32::from(warm_up);
    let mut cpu = Vec::new();
    for r in 0..runs + skip {
        let t = Instant::now();
        std::hint::black_box(denoise::denoise_cpu(&params, &input)?);
        if r >= skip {
            cpu.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let (mut gpu_ms, mut gpu_timestamps) = (None, false);
    if let (Backend::Gpu(ctx), Some(k)) = (backend, kernels) {
        let mut gpu = Vec::new();
        for r in 0..runs + skip {
            let (_, ms) = interactive_gpu(ctx, k, &params, &input)?;
            if r >= skip {
                gpu.push(ms);
            }
        }
        gpu_ms = Some(median(gpu));
        gpu_timestamps = ctx.timestamps && denoise::gpu::fits_one_binding(ctx, [width, height]);
    }
    Ok(InteractiveTiming {
        cpu_ms: median(cpu),
        gpu_ms,
        gpu_timestamps,
    })
}

/// OIDN's ms per picture on the synthetic scene at `width × height` (colour: each pixel's
/// mean, black where unsampled; the scene's albedo and normal), median of `runs` after a
/// warm-up run when `warm_up`.
pub(super) fn time_oidn(
    device: &oidn::Device,
    width: u32,
    height: u32,
    runs: u32,
    warm_up: bool,
) -> Result<f64, DenoiseBenchError> {
    let s = denoise::synth_scene(width, height, 1, 0.5, 1);
    let (colour, _) = oidn::colour_input(&s.acc, &s.acc.mean_image());
    let (albedo, normal) = oidn::auxiliary(&s.features);
    let images = oidn::Images {
        size: [width, height],
        color: &colour,
        albedo: Some(&albedo),
        normal: Some(&normal),
    };
    let mut ms = Vec::new();
    for r in 0..runs + u32::from(warm_up) {
        let t = Instant::now();
        std::hint::black_box(device.denoise(images, oidn::Quality::High)?);
        if r >= u32::from(warm_up) {
            ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    Ok(median(ms))
}
