//! The picture as the viewer shows it, on the GPU: the GPU twin of
//! [`display_rgba`](super::srgb8::display_rgba) (`shaders/output/srgb8.wgsl`).
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

use crate::gpu::{GpuContext, GpuError, PassTimer};

/// The kernel's source.
pub const SRGB8_WGSL: &str = include_str!("../../shaders/output/srgb8.wgsl");

/// Threads per workgroup (the kernel's `@workgroup_size`).
const WORKGROUP: u32 = 256;

/// The kernel's parameters (mirrors `DisplayParams` in the WGSL, 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuDisplayParams {
    pub pixels: u32,
    /// 2^exposure.
    pub scale: f32,
    /// 1: pixels whose bit in the shown mask is 0 are black.
    pub masked: u32,
    pub _pad: u32,
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
    /// The shown picture: one u32 per pixel, bytes R, G, B, A (255) in memory order.
    pub output: wgpu::Buffer,
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
    /// `p / 32`), the pixels whose bit is 0 come out black. The exposure is set per
    /// conversion ([`DisplayRun::set_exposure`]; 0 stops until then).
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        image: &wgpu::Buffer,
        pixels: u32,
        shown: Option<&[u32]>,
    ) -> Result<DisplayRun, GpuError> {
        let max = ctx.limits.max_compute_workgroups_per_dimension;
        self.prepare_on_grid(ctx, image, pixels, shown, max)
    }

    /// [`Self::prepare`] with at most `max_per_dim` workgroups along x (tests force a grid of
    /// several rows with a small one).
    fn prepare_on_grid(
        &self,
        ctx: &GpuContext,
        image: &wgpu::Buffer,
        pixels: u32,
        shown: Option<&[u32]>,
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
        let params = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("display params"),
                contents: bytemuck::bytes_of(&GpuDisplayParams {
                    pixels,
                    scale: 1.0,
                    masked: u32::from(shown.is_some()),
                    _pad: 0,
                }),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
        // Without a mask the binding still needs a buffer (one word, never read).
        let mask = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("display shown mask"),
                contents: bytemuck::cast_slice(shown.unwrap_or(&[0u32])),
                usage: wgpu::BufferUsages::STORAGE,
            });
        let output = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shown picture"),
            size: (n * 4).max(4),
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
            ],
        });
        Ok(DisplayRun {
            pipeline: self.pipeline.clone(),
            params,
            bind,
            groups: grid(pixels, max_per_dim),
            pixels,
            masked: shown.is_some(),
            output,
        })
    }

    /// Uploads `image`, converts it at `exposure` stops and reads the bytes back (tests and
    /// benchmarks; the renderer converts its own filtered picture in place).
    pub fn convert(
        &self,
        ctx: &GpuContext,
        image: &[Vec3],
        exposure: f32,
        shown: Option<&[u32]>,
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
        let run = self.prepare(ctx, &input, pixels, shown)?;
        run.set_exposure(ctx, exposure);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        run.record(&mut enc, None);
        ctx.queue.submit([enc.finish()]);
        run.read(ctx)
    }
}

impl DisplayRun {
    /// The exposure of the next conversions submitted (a uniform written before the submit).
    pub fn set_exposure(&self, ctx: &GpuContext, exposure: f32) {
        let params = GpuDisplayParams {
            pixels: self.pixels,
            scale: exposure.exp2(),
            masked: u32::from(self.masked),
            _pad: 0,
        };
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

    /// The shown picture's bytes (RGBA8, row-major), read back.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<u8>, GpuError> {
        ctx.read_prefix(&self.output, 4 * u64::from(self.pixels))
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
            &crate::rust_layout!(GpuDisplayParams; pixels, scale, masked, _pad),
        );
        assert!(SRGB8_WGSL.contains(&format!("const SHIFT: u32 = {GPU_TABLE_SHIFT}u;")));
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
            .prepare_on_grid(&ctx, &input, n, Some(&shown), 3)
            .unwrap();
        assert_eq!(run.groups, [3, 7]);
        run.set_exposure(&ctx, 0.5);
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
}
