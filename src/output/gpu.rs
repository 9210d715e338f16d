//! The output stage's kernels: the picture as the viewer shows it, the GPU twin of
//! [`display_rgba`](super::srgb8::display_rgba) (`shaders/output/srgb8.wgsl`), and the ROI's
//! statistics, the GPU twin of [`RoiStats::measure`] (`shaders/output/stats.wgsl`, below).
//!
//! A filtered picture that stays on the GPU is converted there to the 8-bit RGBA the window
//! shows, so a frame reads back 4 bytes a pixel instead of the accumulation, the DGI and the
//! filtered picture (16 + 4 + 4 + 16 bytes, and the filter's inputs uploaded again:
//! [`crate::frame::Renderer::shown_picture`]). The kernel reads the CPU's own table
//! ([`super::srgb8::gpu_table`]) and compares IEEE patterns as integers, so it gives the CPU
//! twin's byte for every value, NaN and infinities included (the exposure's product is IEEE
//! multiplication on both; Vulkan requires it correctly rounded).

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use wgpu::util::DeviceExt;

use super::stats::{NoiseContrast, RoiProgress, RoiStats};
use crate::gpu::{GpuContext, GpuError, PassTimer};

/// The kernel's source.
pub const SRGB8_WGSL: &str = include_str!("../../shaders/output/srgb8.wgsl");

/// Threads per workgroup (the kernel's `@workgroup_size`).
const WORKGROUP: u32 = 256;

/// The kernel's parameters (mirrors `DisplayParams` in the WGSL, 32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuDisplayParams {
    pub pixels: u32,
    /// 2^exposure.
    pub scale: f32,
    /// 1: pixels whose bit in the shown mask is 0 are black.
    pub masked: u32,
    /// 1: the ROI's outline in the bound DGI is painted ([`super::srgb8::roi_outline`]).
    pub outline: u32,
    /// The picture's size (the outline's neighbours).
    pub width: u32,
    pub height: u32,
    /// Output words a row: `width`, or [`texture_pitch`] for a copy into a texture.
    pub pitch: u32,
    pub _pad1: u32,
}

/// The output's row pitch, in pixels, for a copy into a texture of `width`: a buffer-to-texture
/// copy of several rows needs rows of a multiple of 256 bytes (64 pixels).
#[must_use]
pub fn texture_pitch(width: u32) -> u32 {
    width.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT / 4)
}

/// The compiled kernel and the sRGB table it reads.
pub struct DisplayKernel {
    pipeline: wgpu::ComputePipeline,
    table: wgpu::Buffer,
}

/// The conversion of one picture buffer, bound: record it each time the picture changes.
pub struct DisplayRun {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bind: wgpu::BindGroup,
    groups: [u32; 2],
    pixels: u32,
    masked: bool,
    /// The picture's size when a DGI is bound (its outline can be painted).
    outline_size: Option<[u32; 2]>,
    /// The shown picture: one u32 per pixel, bytes R, G, B, A (255) in memory order.
    pub output: wgpu::Buffer,
}

/// A DGI for the display kernel's outline: the buffer (`f32` per pixel, `STORAGE`) and the
/// picture's size.
#[derive(Clone, Copy)]
pub struct OutlineDgi<'a> {
    pub dgi: &'a wgpu::Buffer,
    pub size: [u32; 2],
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// A 2D grid of `WORKGROUP`-thread groups covering `pixels` (at most 65 535 groups along x;
/// the kernel indexes `x + y · groups_x · WORKGROUP`).
fn grid(pixels: u32, max_per_dim: u32) -> [u32; 2] {
    crate::gpu::grid_2d(pixels.div_ceil(WORKGROUP).max(1), max_per_dim)
}

impl DisplayKernel {
    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        let table = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("display sRGB table"),
                contents: bytemuck::cast_slice(&super::srgb8::gpu_table()),
                usage: wgpu::BufferUsages::STORAGE,
            });
        Self {
            pipeline: ctx.compute_pipeline("output/srgb8.wgsl", SRGB8_WGSL, "main"),
            table,
        }
    }

    /// Binds the conversion of `image` (`vec4<f32>` per pixel, `pixels` of them, `STORAGE`
    /// usage) into a new output buffer; with `shown` (one bit per pixel, bit `p % 32` of word
    /// `p / 32`), the pixels whose bit is 0 come out black; with `dgi`, the ROI's outline can
    /// be painted over. The exposure and the outline are set per conversion
    /// ([`DisplayRun::set_look`]; 0 stops and no outline until then).
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        image: &wgpu::Buffer,
        pixels: u32,
        shown: Option<&[u32]>,
        dgi: Option<OutlineDgi<'_>>,
    ) -> Result<DisplayRun, GpuError> {
        let max = ctx.limits.max_compute_workgroups_per_dimension;
        self.prepare_on_grid(ctx, image, pixels, shown, dgi, max)
    }

    /// [`Self::prepare`] with at most `max_per_dim` workgroups along x (tests force a grid of
    /// several rows with a small one).
    fn prepare_on_grid(
        &self,
        ctx: &GpuContext,
        image: &wgpu::Buffer,
        pixels: u32,
        shown: Option<&[u32]>,
        dgi: Option<OutlineDgi<'_>>,
        max_per_dim: u32,
    ) -> Result<DisplayRun, GpuError> {
        let n = u64::from(pixels);
        ctx.check_binding("shown picture (4 bytes per pixel)", n * 4)?;
        assert!(
            image.size() >= n * 16,
            "the display kernel's input holds {} bytes, {pixels} pixels need {}",
            image.size(),
            n * 16
        );
        if let Some(mask) = shown {
            assert!(
                mask.len() as u64 >= n.div_ceil(32),
                "a shown mask of {} words for {pixels} pixels",
                mask.len()
            );
        }
        if let Some(d) = dgi {
            assert!(
                u64::from(d.size[0]) * u64::from(d.size[1]) == n && d.dgi.size() >= 4 * n,
                "an outline DGI of {} bytes for a {}×{} picture of {pixels} pixels",
                d.dgi.size(),
                d.size[0],
                d.size[1]
            );
        }
        let outline_size = dgi.map(|d| d.size);
        let params = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("display params"),
                contents: bytemuck::bytes_of(&display_params(
                    pixels,
                    1.0,
                    shown.is_some(),
                    outline_size,
                    false,
                    false,
                )),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
        // Without a DGI the binding still needs a buffer (one value, never read).
        let no_dgi;
        let dgi_buffer = match dgi {
            Some(d) => d.dgi,
            None => {
                no_dgi = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("display without DGI"),
                    size: 4,
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                });
                &no_dgi
            }
        };
        // Without a mask the binding still needs a buffer (one word, never read).
        let mask = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("display shown mask"),
                contents: bytemuck::cast_slice(shown.unwrap_or(&[0u32])),
                usage: wgpu::BufferUsages::STORAGE,
            });
        // Room for rows padded for a copy into a texture where the picture's size is known.
        let words = outline_size.map_or(n, |[w, h]| u64::from(texture_pitch(w)) * u64::from(h));
        ctx.check_binding("shown picture (rows padded for a texture)", words * 4)?;
        let output = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shown picture"),
            size: (words * 4).max(4),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("display"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                entry(0, &params),
                entry(1, image),
                entry(2, &self.table),
                entry(3, &mask),
                entry(4, &output),
                entry(5, dgi_buffer),
            ],
        });
        Ok(DisplayRun {
            pipeline: self.pipeline.clone(),
            params,
            bind,
            groups: grid(pixels, max_per_dim),
            pixels,
            masked: shown.is_some(),
            outline_size,
            output,
        })
    }

    /// Uploads `image`, converts it at `exposure` stops (with `outline`, the ROI's outline of
    /// that DGI and picture size painted over) and reads the bytes back (tests and benchmarks;
    /// the renderer converts its own filtered picture in place).
    pub fn convert(
        &self,
        ctx: &GpuContext,
        image: &[Vec3],
        exposure: f32,
        shown: Option<&[u32]>,
        outline: Option<(&[f32], [u32; 2])>,
    ) -> Result<Vec<u8>, GpuError> {
        let texels: Vec<[f32; 4]> = image.iter().map(|p| [p.x, p.y, p.z, 1.0]).collect();
        ctx.check_binding(
            "display input (16 bytes per pixel)",
            16 * texels.len() as u64,
        )?;
        let input = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("display input"),
                contents: bytemuck::cast_slice(&texels),
                usage: wgpu::BufferUsages::STORAGE,
            });
        let pixels = u32::try_from(image.len()).map_err(|_| GpuError::TooLarge {
            what: "a picture of more than 2^32 pixels",
            bytes: 16 * image.len() as u64,
            max: ctx.max_binding(),
        })?;
        let dgi = outline.map(|(dgi, _)| {
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("display outline DGI"),
                    contents: bytemuck::cast_slice(dgi),
                    usage: wgpu::BufferUsages::STORAGE,
                })
        });
        let bound = dgi
            .as_ref()
            .zip(outline)
            .map(|(dgi, (_, size))| OutlineDgi { dgi, size });
        let run = self.prepare(ctx, &input, pixels, shown, bound)?;
        run.set_look(ctx, exposure, outline.is_some(), false);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        run.record(&mut enc, None);
        ctx.queue.submit([enc.finish()]);
        run.read(ctx)
    }
}

/// The kernel's parameters; the outline is painted only with a DGI bound (`size`).
/// The kernel's parameters; with `padded` (only for a picture of known `size`) the output's
/// rows are [`texture_pitch`] apart, else packed.
fn display_params(
    pixels: u32,
    scale: f32,
    masked: bool,
    size: Option<[u32; 2]>,
    outline: bool,
    padded: bool,
) -> GpuDisplayParams {
    let [width, height] = size.unwrap_or([pixels, 1]);
    GpuDisplayParams {
        pixels,
        scale,
        masked: u32::from(masked),
        outline: u32::from(outline && size.is_some()),
        width,
        height,
        pitch: if padded && size.is_some() {
            texture_pitch(width)
        } else {
            width
        },
        _pad1: 0,
    }
}

impl DisplayRun {
    /// The exposure of the next conversions submitted, whether they paint the ROI's outline
    /// (only where a DGI is bound), and whether their rows are padded for
    /// [`Self::copy_to_texture`] (else packed, as [`Self::read`] takes them); a uniform
    /// written before the submit.
    pub fn set_look(&self, ctx: &GpuContext, exposure: f32, outline: bool, for_texture: bool) {
        let params = display_params(
            self.pixels,
            exposure.exp2(),
            self.masked,
            self.outline_size,
            outline,
            for_texture,
        );
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
    }

    /// Records the conversion as one compute pass; with a timer, pass `pass` of it measures it.
    pub fn record(&self, enc: &mut wgpu::CommandEncoder, timer: Option<(&PassTimer, u32)>) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("display"),
            timestamp_writes: timer.map(|(t, i)| t.writes(i)),
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind, &[]);
        pass.dispatch_workgroups(self.groups[0], self.groups[1], 1);
    }

    /// Records a copy of the shown picture, converted with its rows padded
    /// ([`Self::set_look`] `for_texture`), into `texture` (the picture's size, four bytes a
    /// texel, `COPY_DST`): one copy of rows [`texture_pitch`] apart. Only for a run bound with
    /// its picture's size (a DGI).
    pub fn copy_to_texture(&self, enc: &mut wgpu::CommandEncoder, texture: &wgpu::Texture) {
        let [w, h] = self
            .outline_size
            .expect("a picture copied into a texture has a known size");
        enc.copy_buffer_to_texture(
            wgpu::TexelCopyBufferInfo {
                buffer: &self.output,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(4 * texture_pitch(w)),
                    rows_per_image: Some(h),
                },
            },
            texture.as_image_copy(),
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
    }

    /// The shown picture's bytes (RGBA8, row-major), read back.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<u8>, GpuError> {
        ctx.read_prefix(&self.output, 4 * u64::from(self.pixels))
    }
}

// ---------------------------------------------------------------------------------------------
// [`RoiStats`] measured on the GPU (`shaders/output/stats.wgsl`): the GPU twin of
// [`RoiStats::measure`].
//
// The kernel reads the renderer's own accumulation, counts, DGI and the wall camera's shown
// mask, and one submit of ten dispatches leaves the totals and five selected values (the
// medians' order statistics, exact: a radix select over the values' IEEE patterns) in a
// buffer of 224 bytes, which is all that comes back. The totals are the CPU's exactly; each
// pixel's standard error is the CPU's within a few units in the last place (the CPU computes
// the variance in f64, the kernel in f32 with the cancelling product carried exactly by FMA:
// [`SE_TOLERANCE`]), and the medians with them.

/// The kernel's source.
pub const STATS_WGSL: &str = include_str!("../../shaders/output/stats.wgsl");

/// How far a standard error measured by the kernel may lie from the CPU's, relative: the CPU's
/// variance is f64 rounded once to f32, the kernel's f32 with four roundings after the exact
/// cancellation (and the luminance's sum may be fused), then a square root that WGSL does not
/// require correctly rounded. The medians, order statistics of such values, lie as close.
pub const SE_TOLERANCE: f32 = 4e-6;

/// The statistics' threads per workgroup and pixels per thread (the kernel's `WORKGROUP` and `PER_THREAD`).
const STATS_WORKGROUP: u32 = 256;
const PER_THREAD: u32 = 16;
/// Selections, bins a round, rounds (the kernel's `SELECTIONS`, `BINS`; 32 bits, 8 a round).
const SELECTIONS: usize = 5;
const BINS: usize = 256;
const ROUNDS: usize = 4;

/// The kernel's parameters (mirrors `StatsParams` in the WGSL, 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuStatsParams {
    pub pixels: u32,
    /// 1: only the pixels whose bit in the shown mask is set are the ROI's.
    pub masked: u32,
    /// 1 − p_min: the periphery is d > 0 and d ≥ floor.
    pub floor: f32,
    pub _pad: u32,
}

/// One order statistic being selected (mirrors `Selection` in the WGSL, 32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuSelection {
    pub group: u32,
    pub rank: u32,
    pub prefix: u32,
    pub mask: u32,
    pub wanted: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// The part of the kernel's `Stats` that is read back (its totals and selections; 208 bytes);
/// the histograms follow it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuStatsHead {
    pub totals: [u32; 8],
    pub rounds_done: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
    pub sel: [GpuSelection; SELECTIONS],
}

/// Indices of [`GpuStatsHead::totals`] (the kernel's `T_*`).
const T_ROI_NOISY: usize = 0;
const T_PERIPHERY_NOISY: usize = 1;
const T_ROI_PIXELS: usize = 2;
const T_SAMPLES_LO: usize = 3;
const T_SAMPLES_HI: usize = 4;
const T_MIN_SAMPLES: usize = 5;

/// Bytes of the kernel's `Stats`: the head, then 5 × 256 histogram bins.
const STATE_BYTES: u64 = (size_of::<GpuStatsHead>() + 4 * SELECTIONS * BINS) as u64;

/// The compiled entry points.
pub struct StatsKernel {
    totals: wgpu::ComputePipeline,
    ranks: wgpu::ComputePipeline,
    histogram: wgpu::ComputePipeline,
    pick: wgpu::ComputePipeline,
}

/// The buffers a measurement reads: a frame's accumulation (`vec4<f32>` per pixel: RGB sum,
/// Σ luminance²), sample counts (`u32`) and DGI (`f32`), all `STORAGE`, and the wall camera's
/// shown mask (bit `p % 32` of word `p / 32`), if any.
pub struct GpuStatsInputs<'a> {
    pub pixels: u32,
    pub accum: &'a wgpu::Buffer,
    pub counts: &'a wgpu::Buffer,
    pub dgi: &'a wgpu::Buffer,
    pub shown: Option<&'a [u32]>,
}

/// The measurement bound to one frame's buffers: [`Self::measure`] it as often as wanted.
pub struct StatsRun {
    totals: wgpu::ComputePipeline,
    ranks: wgpu::ComputePipeline,
    histogram: wgpu::ComputePipeline,
    pick: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    state: wgpu::Buffer,
    /// Bindings of `totals` and `histogram` (every input), and of `ranks` and `pick` (the
    /// state only): each entry point's layout is its own.
    bind_totals: wgpu::BindGroup,
    bind_histogram: wgpu::BindGroup,
    bind_ranks: wgpu::BindGroup,
    bind_pick: wgpu::BindGroup,
    groups: [u32; 2],
    pixels: u32,
    masked: bool,
}

impl StatsKernel {
    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        let module = ctx.shader_module("output/stats.wgsl", STATS_WGSL);
        let pipeline =
            |entry: &str| ctx.compute_pipeline_in(&module, &format!("output/stats {entry}"), entry);
        Self {
            totals: pipeline("totals"),
            ranks: pipeline("ranks"),
            histogram: pipeline("histogram"),
            pick: pipeline("pick"),
        }
    }

    /// Binds a measurement of `inputs`.
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        inputs: &GpuStatsInputs<'_>,
    ) -> Result<StatsRun, GpuError> {
        let max = ctx.limits.max_compute_workgroups_per_dimension;
        self.prepare_on_grid(ctx, inputs, max)
    }

    /// [`Self::prepare`] with at most `max_per_dim` workgroups along x (tests force a grid of
    /// several rows with a small one).
    fn prepare_on_grid(
        &self,
        ctx: &GpuContext,
        inputs: &GpuStatsInputs<'_>,
        max_per_dim: u32,
    ) -> Result<StatsRun, GpuError> {
        let n = u64::from(inputs.pixels);
        for (what, buffer, bytes) in [
            ("accumulation", inputs.accum, 16 * n),
            ("sample counts", inputs.counts, 4 * n),
            ("DGI", inputs.dgi, 4 * n),
        ] {
            assert!(
                buffer.size() >= bytes,
                "the statistics' {what} holds {} bytes, {n} pixels need {bytes}",
                buffer.size()
            );
        }
        if let Some(mask) = inputs.shown {
            assert!(
                mask.len() as u64 >= n.div_ceil(32),
                "a shown mask of {} words for {n} pixels",
                mask.len()
            );
        }
        let params = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("statistics params"),
            size: size_of::<GpuStatsParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // Without a mask the binding still needs a buffer (one word, never read).
        let mask = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("statistics shown mask"),
                contents: bytemuck::cast_slice(inputs.shown.unwrap_or(&[0u32])),
                usage: wgpu::BufferUsages::STORAGE,
            });
        let state = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("statistics state"),
            size: STATE_BYTES,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let all = |pipeline: &wgpu::ComputePipeline, label| {
            ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &[
                    entry(0, &params),
                    entry(1, inputs.accum),
                    entry(2, inputs.counts),
                    entry(3, inputs.dgi),
                    entry(4, &mask),
                    entry(5, &state),
                ],
            })
        };
        let state_only = |pipeline: &wgpu::ComputePipeline, label| {
            ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &[entry(5, &state)],
            })
        };
        let per_group = STATS_WORKGROUP * PER_THREAD;
        Ok(StatsRun {
            bind_totals: all(&self.totals, "statistics totals"),
            bind_histogram: all(&self.histogram, "statistics histogram"),
            bind_ranks: state_only(&self.ranks, "statistics ranks"),
            bind_pick: state_only(&self.pick, "statistics pick"),
            totals: self.totals.clone(),
            ranks: self.ranks.clone(),
            histogram: self.histogram.clone(),
            pick: self.pick.clone(),
            params,
            state,
            groups: crate::gpu::grid_2d(inputs.pixels.div_ceil(per_group), max_per_dim),
            pixels: inputs.pixels,
            masked: inputs.shown.is_some(),
        })
    }

    /// Uploads an accumulation and a DGI and measures them (tests and benchmarks; a renderer
    /// measures its own buffers in place).
    pub fn measure_upload(
        &self,
        ctx: &GpuContext,
        acc: &crate::trace::accum::Accumulation,
        dgi: &[f32],
        p_min: f32,
        shown: Option<&[u32]>,
    ) -> Result<RoiStats, GpuError> {
        let max = ctx.limits.max_compute_workgroups_per_dimension;
        self.measure_upload_on_grid(ctx, acc, dgi, p_min, shown, max)
    }

    /// [`Self::measure_upload`] on a grid of at most `max_per_dim` workgroups along x.
    fn measure_upload_on_grid(
        &self,
        ctx: &GpuContext,
        acc: &crate::trace::accum::Accumulation,
        dgi: &[f32],
        p_min: f32,
        shown: Option<&[u32]>,
        max_per_dim: u32,
    ) -> Result<RoiStats, GpuError> {
        let pixels = u32::try_from(acc.count.len()).map_err(|_| GpuError::TooLarge {
            what: "statistics of more than 2^32 pixels",
            bytes: 16 * acc.count.len() as u64,
            max: ctx.max_binding(),
        })?;
        assert_eq!(dgi.len(), acc.count.len(), "one DGI value a pixel");
        ctx.check_binding(
            "statistics' accumulation (16 bytes per pixel)",
            16 * u64::from(pixels),
        )?;
        let upload = |label, contents: &[u8]| {
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    // A binding is never empty.
                    contents: if contents.is_empty() {
                        &[0; 16]
                    } else {
                        contents
                    },
                    usage: wgpu::BufferUsages::STORAGE,
                })
        };
        let accum = upload("statistics accumulation", bytemuck::cast_slice(&acc.sum));
        let counts = upload("statistics counts", bytemuck::cast_slice(&acc.count));
        let dgi = upload("statistics DGI", bytemuck::cast_slice(dgi));
        let inputs = GpuStatsInputs {
            pixels,
            accum: &accum,
            counts: &counts,
            dgi: &dgi,
            shown,
        };
        self.prepare_on_grid(ctx, &inputs, max_per_dim)?
            .measure(ctx, p_min)
    }
}

impl StatsRun {
    /// Records the measurement with the periphery of `p_min`: the state cleared, the totals,
    /// the ranks and four rounds of the select.
    pub fn record(&self, ctx: &GpuContext, enc: &mut wgpu::CommandEncoder, p_min: f32) {
        let params = GpuStatsParams {
            pixels: self.pixels,
            masked: u32::from(self.masked),
            floor: 1.0 - p_min,
            _pad: 0,
        };
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        // Zero totals and histograms, the fewest samples at u32::MAX (written at the submit,
        // before the passes).
        let mut state = vec![0u8; STATE_BYTES as usize];
        let mut head = GpuStatsHead::zeroed();
        head.totals[T_MIN_SAMPLES] = u32::MAX;
        state[..size_of::<GpuStatsHead>()].copy_from_slice(bytemuck::bytes_of(&head));
        ctx.queue.write_buffer(&self.state, 0, &state);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("statistics"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.totals);
        pass.set_bind_group(0, &self.bind_totals, &[]);
        pass.dispatch_workgroups(self.groups[0], self.groups[1], 1);
        pass.set_pipeline(&self.ranks);
        pass.set_bind_group(0, &self.bind_ranks, &[]);
        pass.dispatch_workgroups(1, 1, 1);
        for _ in 0..ROUNDS {
            pass.set_pipeline(&self.histogram);
            pass.set_bind_group(0, &self.bind_histogram, &[]);
            pass.dispatch_workgroups(self.groups[0], self.groups[1], 1);
            pass.set_pipeline(&self.pick);
            pass.set_bind_group(0, &self.bind_pick, &[]);
            pass.dispatch_workgroups(1, 1, 1);
        }
    }

    /// Measures the bound buffers as they are now (one submit, 208 bytes read back).
    pub fn measure(&self, ctx: &GpuContext, p_min: f32) -> Result<RoiStats, GpuError> {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        self.record(ctx, &mut enc, p_min);
        ctx.queue.submit([enc.finish()]);
        let head: Vec<GpuStatsHead> =
            ctx.read_prefix(&self.state, size_of::<GpuStatsHead>() as u64)?;
        Ok(stats_of(&head[0]))
    }
}

/// The statistics in a read-back head: the totals as they are, each median from its
/// selections as the CPU's `median_finite` and `RoiProgress::measure_where` take it.
fn stats_of(head: &GpuStatsHead) -> RoiStats {
    let t = &head.totals;
    let value = |s: usize| f32::from_bits(head.sel[s].prefix);
    // The upper middle value (rank n/2), and for an even n the mean with the lower one.
    let median = |upper: usize, n: u32| {
        if n % 2 == 1 {
            value(upper)
        } else {
            0.5 * (value(upper + 1) + value(upper))
        }
    };
    let (n_roi, n_far, n_px) = (t[T_ROI_NOISY], t[T_PERIPHERY_NOISY], t[T_ROI_PIXELS]);
    RoiStats {
        roi_samples: u64::from(t[T_SAMPLES_LO]) | (u64::from(t[T_SAMPLES_HI]) << 32),
        roi_pixels: u64::from(n_px),
        contrast: (n_roi > 0 && n_far > 0).then(|| NoiseContrast {
            roi: median(0, n_roi),
            periphery: median(2, n_far),
            roi_pixels: n_roi as usize,
            periphery_pixels: n_far as usize,
        }),
        progress: (n_px > 0).then(|| RoiProgress {
            pixels: u64::from(n_px),
            min_samples: t[T_MIN_SAMPLES],
            median_se: value(4),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::wgsl::{assert_same_layout, validated};
    use crate::output::srgb8::{GPU_TABLE_SHIFT, display_rgba};

    #[test]
    fn kernel_validates_and_its_params_match_rust() {
        let m = validated("srgb8.wgsl", SRGB8_WGSL);
        assert_same_layout(
            &m,
            "DisplayParams",
            &crate::rust_layout!(GpuDisplayParams; pixels, scale, masked, outline, width, height, pitch, _pad1),
        );
        assert!(SRGB8_WGSL.contains(&format!("const SHIFT: u32 = {GPU_TABLE_SHIFT}u;")));
        assert!(SRGB8_WGSL.contains(&format!(
            "const OUTLINE: u32 = 0x{:08X}u;",
            u32::from_le_bytes(crate::output::srgb8::OUTLINE)
        )));
        assert!(SRGB8_WGSL.contains(&format!("@workgroup_size({WORKGROUP})")));
    }

    #[test]
    fn grids_cover_the_pixels_within_the_limit() {
        for (pixels, max) in [
            (0, 65_535),
            (1, 65_535),
            (8_294_400, 65_535),
            (73_800_000, 65_535),
            (1000, 2),
            (257, 1),
        ] {
            let [gx, gy] = grid(pixels, max);
            assert!(
                gx <= max && gx >= 1 && gy >= 1,
                "{pixels} pixels, max {max}: {gx}×{gy}"
            );
            assert!(u64::from(gx) * u64::from(gy) * u64::from(WORKGROUP) >= u64::from(pixels));
            // No whole row of groups beyond the pixels.
            assert!(
                u64::from(gx) * u64::from(gy - 1) * u64::from(WORKGROUP) < u64::from(pixels.max(1))
            );
        }
    }

    /// The mask blacks out exactly the unshown pixels (opaque), on a grid of several rows of
    /// workgroups.
    #[test]
    fn the_mask_blacks_unshown_pixels_on_a_grid_of_rows() {
        let ctx = GpuContext::for_tests();
        let kernel = DisplayKernel::new(&ctx);
        let n = 5000u32;
        let image: Vec<Vec3> = (0..n)
            .map(|i| Vec3::new(i as f32 / n as f32, 0.25, 1.0 - i as f32 / n as f32))
            .collect();
        let shown: Vec<u32> = (0..n.div_ceil(32))
            .map(|w| 0x9E37_79B9u32.wrapping_mul(w + 1))
            .collect();
        let texels: Vec<[f32; 4]> = image.iter().map(|p| [p.x, p.y, p.z, 1.0]).collect();
        let input = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: None,
                contents: bytemuck::cast_slice(&texels),
                usage: wgpu::BufferUsages::STORAGE,
            });
        // 20 groups of 256 on rows of 3: 7 rows, the last partial.
        let run = kernel
            .prepare_on_grid(&ctx, &input, n, Some(&shown), None, 3)
            .unwrap();
        assert_eq!(run.groups, [3, 7]);
        run.set_look(&ctx, 0.5, true, false);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        run.record(&mut enc, None);
        ctx.queue.submit([enc.finish()]);
        let gpu = run.read(&ctx).unwrap();
        let mut want = display_rgba(&image, 0.5);
        let mut blacked = 0;
        for p in 0..n as usize {
            if shown[p / 32] & (1 << (p % 32)) == 0 {
                want[4 * p..4 * p + 4].copy_from_slice(&[0, 0, 0, 255]);
                blacked += 1;
            }
        }
        assert!(blacked > 1000 && blacked < 4000, "{blacked} unshown");
        assert_eq!(gpu, want);
    }

    use crate::trace::accum::Accumulation;

    #[test]
    fn kernel_validates_and_its_structs_match_rust() {
        let m = validated("stats.wgsl", STATS_WGSL);
        assert_same_layout(
            &m,
            "StatsParams",
            &crate::rust_layout!(GpuStatsParams; pixels, masked, floor, _pad),
        );
        assert_same_layout(
            &m,
            "Selection",
            &crate::rust_layout!(GpuSelection; group, rank, prefix, mask, wanted, _pad0, _pad1, _pad2),
        );
        for (name, value) in [
            ("WORKGROUP", STATS_WORKGROUP as usize),
            ("PER_THREAD", PER_THREAD as usize),
            ("SELECTIONS", SELECTIONS),
            ("BINS", BINS),
            ("T_ROI_NOISY", T_ROI_NOISY),
            ("T_PERIPHERY_NOISY", T_PERIPHERY_NOISY),
            ("T_ROI_PIXELS", T_ROI_PIXELS),
            ("T_SAMPLES_LO", T_SAMPLES_LO),
            ("T_SAMPLES_HI", T_SAMPLES_HI),
            ("T_MIN_SAMPLES", T_MIN_SAMPLES),
        ] {
            assert!(
                STATS_WGSL.contains(&format!("const {name}: u32 = {value}u;")),
                "{name} = {value} in the kernel"
            );
        }
        assert!(STATS_WGSL.contains(&format!("@workgroup_size({STATS_WORKGROUP})")));
        assert!(STATS_WGSL.contains(&format!("hist: array<atomic<u32>, {}>", SELECTIONS * BINS)));
        // The head as the kernel lays it out: 8 totals, the rounds done and padding, 5 selections.
        assert_eq!(size_of::<GpuStatsHead>(), 48 + SELECTIONS * 32);
    }

    /// Sample totals beyond 2^32 carry into the high word within a workgroup and across
    /// workgroups, and a grid of several rows of workgroups covers every pixel.
    #[test]
    fn sample_totals_carry_past_32_bits_on_a_grid_of_rows() {
        let ctx = GpuContext::for_tests();
        let kernel = StatsKernel::new(&ctx);
        let (w, h) = (128u32, 100u32);
        let n = (w * h) as usize;
        let mut acc = Accumulation::new(w, h);
        let mut dgi = vec![0.5f32; n];
        for (i, d) in dgi.iter_mut().enumerate() {
            if i % 3 == 0 {
                *d = 0.0;
                acc.count[i] = 1 + (i as u32 % 5);
            }
        }
        // Three pixels of 3·10^9 samples (sums 0: SE 0): in one workgroup (pixels 0 and 3) and
        // in another (pixel 9 999).
        for i in [0, 3, 9_999] {
            acc.count[i] = 3_000_000_000;
        }
        let cpu = RoiStats::measure(&acc, &dgi, 0.5, |_| true);
        assert!(cpu.roi_samples > 9_000_000_000, "{}", cpu.roi_samples);
        let gpu = kernel
            .measure_upload_on_grid(&ctx, &acc, &dgi, 0.5, None, 1)
            .unwrap();
        // 12 800 pixels: four workgroups of 4 096 on a grid of one column.
        assert_eq!(cpu, gpu);
    }
}
