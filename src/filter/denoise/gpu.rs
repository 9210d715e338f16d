//! Dispatch of the denoiser's kernel `shaders/filter/denoise.wgsl` (its text is
//! [`crate::filter::gpu::DENOISE_WGSL`]); CPU twin: [`super::denoise_cpu`].
//!
//! A run is `init` (each pixel's start, the dropped pixels counted) and P `atrous` passes,
//! ping-ponging between a work buffer and the output, all in one compute pass (wgpu orders the
//! dispatches' storage accesses inside a pass). The buffers a run binds are 16 bytes a pixel
//! each (the sums, both features, the work buffer and the output) plus the counts: a picture
//! larger than one storage binding is denoised in bands of rows with [`super::halo`] rows of
//! margin ([`DenoiseKernels::denoise_banded`]), which gives the whole picture's values bit for
//! bit.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::{DenoiseInput, DenoiseInputError, DenoiseParams, Denoised};
use crate::filter::gpu::DENOISE_WGSL;
use crate::gpu::{GpuContext, GpuError, PassTimer};

/// Mirrors `DenoiseParams` in shaders/filter/denoise.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuDenoiseParams {
    pub size: [u32; 2],
    pub step: u32,
    pub last: u32,
    pub variance_threshold: f32,
    pub _pad0: u32,
    /// Rows `[x, y)` whose dropped pixels `init` counts.
    pub count_rows: [u32; 2],
}

/// Why the GPU denoiser could not run.
#[derive(Debug, thiserror::Error)]
pub enum DenoiseGpuError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Input(#[from] DenoiseInputError),
    #[error(
        "the denoiser's {what} buffer holds {bytes} bytes; a {width}×{height} image needs {need}"
    )]
    InputBuffer {
        what: &'static str,
        bytes: u64,
        need: u64,
        width: u32,
        height: u32,
    },
}

/// The GPU inputs, row-major, all with `STORAGE` usage: the accumulation (`accum`:
/// `vec4<f32>`, `counts`: u32) and the features (`albedo`, `normal_depth`: `vec4<f32>`;
/// layout in [`super::Features`]). The tracer's own buffers plug in here.
#[derive(Clone, Copy)]
pub struct GpuDenoiseInputs<'a> {
    pub width: u32,
    pub height: u32,
    pub accum: &'a wgpu::Buffer,
    pub counts: &'a wgpu::Buffer,
    pub albedo: &'a wgpu::Buffer,
    pub normal_depth: &'a wgpu::Buffer,
}

/// CPU-side inputs uploaded (tests, benchmarks and bands).
pub struct UploadedDenoiseInputs {
    pub width: u32,
    pub height: u32,
    pub accum: wgpu::Buffer,
    pub counts: wgpu::Buffer,
    pub albedo: wgpu::Buffer,
    pub normal_depth: wgpu::Buffer,
}

impl UploadedDenoiseInputs {
    pub fn new(ctx: &GpuContext, input: &DenoiseInput<'_>) -> Result<Self, GpuError> {
        ctx.check_binding("denoiser input (16 bytes a pixel)", 16 * pixels(input))?;
        let storage = |label: &str, data: &[u8]| {
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    // An empty buffer cannot be bound.
                    contents: if data.is_empty() { &[0; 16] } else { data },
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                })
        };
        Ok(Self {
            width: input.width,
            height: input.height,
            accum: storage("denoise accum", bytemuck::cast_slice(input.sum)),
            counts: storage("denoise counts", bytemuck::cast_slice(input.count)),
            albedo: storage("denoise albedo", bytemuck::cast_slice(input.albedo)),
            normal_depth: storage(
                "denoise normal/depth",
                bytemuck::cast_slice(input.normal_depth),
            ),
        })
    }

    #[must_use]
    pub fn inputs(&self) -> GpuDenoiseInputs<'_> {
        GpuDenoiseInputs {
            width: self.width,
            height: self.height,
            accum: &self.accum,
            counts: &self.counts,
            albedo: &self.albedo,
            normal_depth: &self.normal_depth,
        }
    }
}

fn pixels(input: &DenoiseInput<'_>) -> u64 {
    u64::from(input.width) * u64::from(input.height)
}

struct Dispatch {
    pipeline: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
}

/// A prepared denoiser run: record it once per picture.
pub struct DenoiseRun {
    dispatches: Vec<Dispatch>,
    groups: [u32; 2],
    /// Kept alive for the bind groups.
    _work: wgpu::Buffer,
    /// The denoised picture: `vec4<f32>` per pixel (linear RGB, alpha 1), row-major.
    pub output: wgpu::Buffer,
    /// One u32: the dropped pixels of the counted rows.
    pub dropped: wgpu::Buffer,
}

impl DenoiseRun {
    /// Clears the dropped count and records every dispatch into one compute pass; with a
    /// timer, pass `pass` of it measures the whole denoiser.
    pub fn record(&self, enc: &mut wgpu::CommandEncoder, timer: Option<(&PassTimer, u32)>) {
        enc.clear_buffer(&self.dropped, 0, None);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("denoise"),
            timestamp_writes: timer.map(|(t, i)| t.writes(i)),
        });
        for d in &self.dispatches {
            pass.set_pipeline(&d.pipeline);
            pass.set_bind_group(0, &d.bind, &[]);
            pass.dispatch_workgroups(self.groups[0], self.groups[1], 1);
        }
    }

    /// Reads the picture and the dropped count back (after a submitted [`Self::record`]).
    pub fn read(&self, ctx: &GpuContext) -> Result<Denoised, GpuError> {
        let image = ctx.read_buffer(&self.output)?;
        let dropped: Vec<u32> = ctx.read_buffer(&self.dropped)?;
        Ok(Denoised {
            image,
            dropped: u64::from(dropped[0]),
        })
    }
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// The compiled denoiser kernel's two entry points.
pub struct DenoiseKernels {
    init: wgpu::ComputePipeline,
    atrous: wgpu::ComputePipeline,
}

/// Whether the kernels can denoise a `size` image in one go: every 16-byte-a-pixel buffer they
/// bind fits one storage binding.
#[must_use]
pub fn fits_one_binding(ctx: &GpuContext, [w, h]: [u32; 2]) -> bool {
    16 * u64::from(w) * u64::from(h) <= ctx.max_binding()
}

impl DenoiseKernels {
    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        let module = ctx.shader_module("filter/denoise.wgsl", DENOISE_WGSL);
        Self {
            init: ctx.compute_pipeline_in(&module, "filter/denoise init", "init"),
            atrous: ctx.compute_pipeline_in(&module, "filter/denoise atrous", "atrous"),
        }
    }

    /// Allocates the work buffer, the output and the dropped count and binds everything; the
    /// dropped pixels of rows `count_rows` are counted.
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        params: &DenoiseParams,
        inputs: &GpuDenoiseInputs<'_>,
        count_rows: [u32; 2],
    ) -> Result<DenoiseRun, DenoiseGpuError> {
        params.validate()?;
        let (w, h) = (inputs.width, inputs.height);
        let n = u64::from(w) * u64::from(h);
        for (what, buffer, need) in [
            ("accum", inputs.accum, n * 16),
            ("counts", inputs.counts, n * 4),
            ("albedo", inputs.albedo, n * 16),
            ("normal/depth", inputs.normal_depth, n * 16),
        ] {
            if buffer.size() < need {
                return Err(DenoiseGpuError::InputBuffer {
                    what,
                    bytes: buffer.size(),
                    need,
                    width: w,
                    height: h,
                });
            }
        }
        ctx.check_binding("denoiser output (16 bytes a pixel)", n * 16)?;
        let image = |label: &str, usage| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: n.max(1) * 16,
                usage: wgpu::BufferUsages::STORAGE | usage,
                mapped_at_creation: false,
            })
        };
        let output = image("denoise output", wgpu::BufferUsages::COPY_SRC);
        let work = image("denoise work", wgpu::BufferUsages::empty());
        let dropped = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("denoise dropped"),
            size: 4,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let uniform = |step: u32, last: bool| {
            let p = GpuDenoiseParams {
                size: [w, h],
                step,
                last: u32::from(last),
                variance_threshold: params.variance_threshold,
                _pad0: 0,
                count_rows,
            };
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("denoise params"),
                    contents: bytemuck::bytes_of(&p),
                    usage: wgpu::BufferUsages::UNIFORM,
                })
        };
        let bind =
            |pipeline: &wgpu::ComputePipeline, entries: &[wgpu::BindGroupEntry<'_>]| Dispatch {
                pipeline: pipeline.clone(),
                bind: ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("denoise"),
                    layout: &pipeline.get_bind_group_layout(0),
                    entries,
                }),
            };
        // The start goes where the last pass's source must be: with P passes alternating, the
        // output is written by the last.
        let passes = params.passes;
        let (first, second) = if passes % 2 == 1 {
            (&work, &output)
        } else {
            (&output, &work)
        };
        let init_params = uniform(0, false);
        let mut dispatches = vec![bind(
            &self.init,
            &[
                entry(0, &init_params),
                entry(1, inputs.accum),
                entry(2, inputs.counts),
                entry(6, first),
                entry(7, &dropped),
            ],
        )];
        for k in 0..passes {
            let (src, dst) = if k % 2 == 0 {
                (first, second)
            } else {
                (second, first)
            };
            let p = uniform(1 << k, k + 1 == passes);
            dispatches.push(bind(
                &self.atrous,
                &[
                    entry(0, &p),
                    entry(1, inputs.accum),
                    entry(2, inputs.counts),
                    entry(3, inputs.albedo),
                    entry(4, inputs.normal_depth),
                    entry(5, src),
                    entry(6, dst),
                ],
            ));
        }
        Ok(DenoiseRun {
            dispatches,
            groups: [w.div_ceil(16), h.div_ceil(16)],
            _work: work,
            output,
            dropped,
        })
    }

    /// Uploads `input`, denoises it in one go and reads the result back, counting the dropped
    /// pixels of rows `count_rows`.
    fn denoise_rows(
        &self,
        ctx: &GpuContext,
        params: &DenoiseParams,
        input: &DenoiseInput<'_>,
        count_rows: [u32; 2],
    ) -> Result<Denoised, DenoiseGpuError> {
        let uploaded = UploadedDenoiseInputs::new(ctx, input)?;
        let run = self.prepare(ctx, params, &uploaded.inputs(), count_rows)?;
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        run.record(&mut enc, None);
        ctx.queue.submit([enc.finish()]);
        let mut out = run.read(ctx)?;
        out.image.truncate(pixels(input) as usize);
        Ok(out)
    }

    /// The denoised picture of `input` in one go (its 16-byte-a-pixel buffers must each fit a
    /// binding: [`fits_one_binding`]).
    pub fn denoise(
        &self,
        ctx: &GpuContext,
        params: &DenoiseParams,
        input: &DenoiseInput<'_>,
    ) -> Result<Denoised, DenoiseGpuError> {
        self.denoise_rows(ctx, params, input, [0, input.height])
    }

    /// [`Self::denoise`] for a picture of any height: one that does not fit a binding is
    /// denoised in bands of rows, each with [`super::halo`] rows above and below; the same
    /// picture and count, bit for bit.
    pub fn denoise_banded(
        &self,
        ctx: &GpuContext,
        params: &DenoiseParams,
        input: &DenoiseInput<'_>,
    ) -> Result<Denoised, DenoiseGpuError> {
        params.validate()?;
        let (w, h) = (input.width, input.height);
        if fits_one_binding(ctx, [w, h]) {
            return self.denoise(ctx, params, input);
        }
        let halo = super::halo(params);
        let max = ctx.max_binding();
        let most = (max / (16 * u64::from(w).max(1))).min(u64::from(h)) as u32;
        let rows = most.saturating_sub(2 * halo);
        if rows == 0 {
            return Err(GpuError::TooLarge {
                what: "a band of the denoiser with its halo (16 bytes per pixel)",
                bytes: 16 * u64::from(w) * u64::from(1 + 2 * halo),
                max,
            }
            .into());
        }
        let wu = w as usize;
        let mut image = Vec::with_capacity(wu * h as usize);
        let mut dropped = 0;
        for r0 in (0..h).step_by(rows as usize) {
            let r1 = (r0 + rows).min(h);
            let (s, e) = (r0.saturating_sub(halo), (r1 + halo).min(h));
            let part = self.denoise_rows(ctx, params, &input.rows(s, e), [r0 - s, r1 - s])?;
            image.extend_from_slice(&part.image[wu * (r0 - s) as usize..wu * (r1 - s) as usize]);
            dropped += part.dropped;
        }
        Ok(Denoised { image, dropped })
    }
}

#[cfg(test)]
mod tests;
