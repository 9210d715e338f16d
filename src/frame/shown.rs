//! Step 4 as a window shows it: the picture filtered, at an exposure, in 8-bit sRGB RGBA, the
//! wall camera's unshown pixels black ([`Renderer::shown_picture`]).
//!
//! On the GPU the picture stays there: the filter reads the renderer's own accumulation and DGI
//! buffers, the display kernel converts its output, one submit, and only the 4 bytes a pixel
//! the window shows come back. The host path it replaces ([`Renderer::picture`], then
//! [`display_rgba`]) reads back the accumulation and the DGI (20 bytes a pixel), uploads them
//! again as the filter's inputs, reads the filtered picture back (16 bytes a pixel) and
//! converts on the CPU: at 3840×2160 about 300 MB moved and 8 M pixels converted per picture.
//! Both give the same bytes (tested); the CPU twins, and a frame split into bands or too large
//! for one filter binding, take the host path.

use std::time::Instant;

use super::{Engine, FrameError, Render, Renderer};
use crate::filter::gpu::{FilterRun, GpuFilterInputs, fits_one_binding};
use crate::filter::{Filter, FilterParams};
use crate::gpu::PassTimer;
use crate::output::gpu::{DisplayKernel, DisplayRun, OutlineDgi};
use crate::output::srgb8::{display_rgba, paint_outline, roi_outline};

/// A picture as shown: RGBA8, row-major.
pub struct ShownPicture {
    pub size: [u32; 2],
    pub rgba: Vec<u8>,
    /// What it took, when timing was asked for.
    pub times: Option<ShownTimes>,
}

/// The times of one shown picture (ms).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct ShownTimes {
    /// Whether the picture stayed on the GPU ([`Renderer::shows_on_gpu`]).
    pub resident: bool,
    /// The filter's kernels (GPU timestamps where the adapter has them) or the CPU twin's wall
    /// clock; on the host path on a GPU, the kernels' wall clock with the transfers around them.
    pub filter_ms: f64,
    /// The conversion to 8 bits: the display kernel (timestamps) or the CPU's wall clock.
    pub display_ms: f64,
    /// The whole call's wall clock: the stages, the transfers and the waits.
    pub wall_ms: f64,
    /// Whether `filter_ms` and `display_ms` come from GPU timestamps.
    pub gpu_timestamps: bool,
}

/// The filter and the display kernel bound to the renderer's own buffers, kept for the next
/// picture with the same filter settings (the renderer's buffers live as long as it does).
pub(super) struct Resident {
    params: FilterParams,
    filter: FilterRun,
    display: DisplayRun,
    /// A full-frame renderer's DGI: 0 everywhere (the filter binds one).
    _zero_dgi: Option<wgpu::Buffer>,
}

impl Renderer<'_> {
    /// Whether [`Self::shown_picture`] keeps the picture on the GPU with `params`: a GPU
    /// renderer whose frame is one band and whose filter fits one binding.
    #[must_use]
    pub fn shows_on_gpu(&self, params: &FilterParams) -> bool {
        match &self.engine {
            Engine::Gpu { ctx, bands, .. } => {
                bands.len() == 1
                    && fits_one_binding(ctx, params, [self.settings.width, self.settings.height])
            }
            Engine::Cpu { .. } => false,
        }
    }

    /// The picture as a window shows it: [`Self::picture`] filtered by `params`, at `exposure`
    /// stops, in 8-bit sRGB RGBA (`output::srgb8::display_rgba`), the wall camera's unshown
    /// pixels black, and with `outline` the ROI's outline painted over (where there is an ROI:
    /// `output::srgb8::roi_outline`); on the GPU without leaving it where it can
    /// ([`Self::shows_on_gpu`]: the DGI stays there too). With `timed`, the stages' times come
    /// with it.
    pub fn shown_picture(
        &self,
        params: &FilterParams,
        exposure: f32,
        outline: bool,
        timed: bool,
    ) -> Result<ShownPicture, FrameError> {
        let size = [self.settings.width, self.settings.height];
        let outline = outline && self.roi().is_some();
        let t0 = Instant::now();
        if self.shows_on_gpu(params) {
            return self.shown_on_gpu(params, exposure, outline, timed, t0);
        }
        let (acc, dgi) = (self.accumulation()?, self.dgi()?);
        let image = self.picture_of(params, &acc, &dgi)?;
        let filter_ms = t0.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        let mut rgba = display_rgba(&image, exposure);
        if outline {
            paint_outline(&mut rgba, &roi_outline(&dgi, size));
        }
        let display_ms = t.elapsed().as_secs_f64() * 1e3;
        Ok(ShownPicture {
            size,
            rgba,
            times: timed.then(|| ShownTimes {
                resident: false,
                filter_ms,
                display_ms,
                wall_ms: t0.elapsed().as_secs_f64() * 1e3,
                gpu_timestamps: false,
            }),
        })
    }

    /// [`Self::shown_picture`]'s bytes written into `texture` on the GPU, read back by nobody:
    /// the filter, the display kernel and a copy into the texture recorded in one submit,
    /// not waited for (what is submitted after it on the same queue, such as a window's frame
    /// drawing the texture, sees the picture). For a window that draws with the renderer's own
    /// device: no 8-bit read-back and no upload from the host. Only where
    /// [`Self::shows_on_gpu`]; `texture` must be the picture's size, `Rgba8Unorm` or
    /// `Rgba8UnormSrgb` (the bytes are sRGB-encoded either way), with `COPY_DST` usage.
    pub fn shown_picture_into(
        &self,
        params: &FilterParams,
        exposure: f32,
        outline: bool,
        texture: &wgpu::Texture,
    ) -> Result<(), FrameError> {
        self.write_shown(params, exposure, outline, texture, false)
            .map(|_| ())
    }

    /// [`Self::shown_picture_into`] waited for, with its times: the filter's and the display
    /// kernel's (GPU timestamps where the adapter has them, else each stage submitted and
    /// waited for on its own — the copy with the display), and the whole call's wall clock.
    pub fn shown_picture_into_timed(
        &self,
        params: &FilterParams,
        exposure: f32,
        outline: bool,
        texture: &wgpu::Texture,
    ) -> Result<ShownTimes, FrameError> {
        let times = self.write_shown(params, exposure, outline, texture, true)?;
        Ok(times.expect("timed"))
    }

    fn write_shown(
        &self,
        params: &FilterParams,
        exposure: f32,
        outline: bool,
        texture: &wgpu::Texture,
        timed: bool,
    ) -> Result<Option<ShownTimes>, FrameError> {
        let t0 = Instant::now();
        let size = [self.settings.width, self.settings.height];
        let Engine::Gpu { ctx, .. } = &self.engine else {
            return Err(FrameError::NotResident);
        };
        if !self.shows_on_gpu(params) {
            return Err(FrameError::NotResident);
        }
        let extent = texture.size();
        let format = texture.format();
        if [extent.width, extent.height] != size
            || extent.depth_or_array_layers != 1
            || !matches!(
                format,
                wgpu::TextureFormat::Rgba8Unorm | wgpu::TextureFormat::Rgba8UnormSrgb
            )
            || !texture.usage().contains(wgpu::TextureUsages::COPY_DST)
        {
            return Err(FrameError::PictureTexture {
                texture: [extent.width, extent.height, extent.depth_or_array_layers],
                format,
                picture: size,
            });
        }
        let outline = outline && self.roi().is_some();
        let resident = self.prepare_resident(params)?;
        let r = resident.as_ref().expect("prepared above");
        r.display.set_look(ctx, exposure, outline, true);
        let times = run_resident(ctx, r, timed, Some(texture))?;
        Ok(
            times.map(|(filter_ms, display_ms, gpu_timestamps)| ShownTimes {
                resident: true,
                filter_ms,
                display_ms,
                wall_ms: t0.elapsed().as_secs_f64() * 1e3,
                gpu_timestamps,
            }),
        )
    }

    /// The filter and the display kernel bound to the renderer's buffers for `params` (made
    /// now unless the last picture's were for the same settings). Only where
    /// [`Self::shows_on_gpu`].
    fn prepare_resident(
        &self,
        params: &FilterParams,
    ) -> Result<std::cell::RefMut<'_, Option<Resident>>, FrameError> {
        let Engine::Gpu { ctx, bands, .. } = &self.engine else {
            unreachable!("shows_on_gpu checked the engine");
        };
        let band = &bands[0];
        let [w, h] = [self.settings.width, self.settings.height];
        let pixels = w * h;
        let mut resident = self.resident.borrow_mut();
        if resident.as_ref().is_none_or(|r| r.params != *params) {
            // The old bindings go before the new ones are made.
            *resident = None;
            let Filter::Gpu { kernels, .. } = self.filter.get_or_init(|| Filter::new(self.backend))
            else {
                unreachable!("a GPU renderer's filter is on its GPU");
            };
            let zero_dgi = band.guide.is_none().then(|| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("full frame DGI (0)"),
                    size: 4 * u64::from(pixels).max(1),
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                })
            });
            let dgi = match (&band.guide, &zero_dgi) {
                (Some(g), _) => &g.dgi,
                (None, Some(z)) => z,
                (None, None) => unreachable!("made above without a guide"),
            };
            let inputs = GpuFilterInputs {
                width: w,
                height: h,
                accum: &band.accum.accum,
                counts: &band.accum.counts,
                dgi,
            };
            let filter = kernels.prepare(ctx, params, &inputs)?;
            let kernel = self.display.get_or_init(|| DisplayKernel::new(ctx));
            let mask = self.wall.as_ref().map(|wc| wc.shown_mask());
            let display = kernel.prepare(
                ctx,
                &filter.output,
                pixels,
                mask,
                Some(OutlineDgi { dgi, size: [w, h] }),
            )?;
            *resident = Some(Resident {
                params: *params,
                filter,
                display,
                _zero_dgi: zero_dgi,
            });
        }
        Ok(resident)
    }

    fn shown_on_gpu(
        &self,
        params: &FilterParams,
        exposure: f32,
        outline: bool,
        timed: bool,
        t0: Instant,
    ) -> Result<ShownPicture, FrameError> {
        let Engine::Gpu { ctx, .. } = &self.engine else {
            unreachable!("shows_on_gpu checked the engine");
        };
        let [w, h] = [self.settings.width, self.settings.height];
        let resident = self.prepare_resident(params)?;
        let r = resident.as_ref().expect("prepared above");
        r.display.set_look(ctx, exposure, outline, false);
        let times = run_resident(ctx, r, timed, None)?;
        let rgba = r.display.read(ctx)?;
        Ok(ShownPicture {
            size: [w, h],
            rgba,
            times: times.map(|(filter_ms, display_ms, gpu_timestamps)| ShownTimes {
                resident: true,
                filter_ms,
                display_ms,
                wall_ms: t0.elapsed().as_secs_f64() * 1e3,
                gpu_timestamps,
            }),
        })
    }
}

/// Records the resident filter and display (and, with `copy`, the display's copy into a
/// texture) and submits them; with `timed`, waits and returns the filter's and the display's
/// ms and whether they are GPU timestamps (without timestamps each stage is submitted and
/// waited for on its own, by the wall clock). Untimed, nothing is waited for.
fn run_resident(
    ctx: &crate::gpu::GpuContext,
    r: &Resident,
    timed: bool,
    copy: Option<&wgpu::Texture>,
) -> Result<Option<(f64, f64, bool)>, FrameError> {
    let copy_into = |enc: &mut wgpu::CommandEncoder| {
        if let Some(texture) = copy {
            r.display.copy_to_texture(enc, texture);
        }
    };
    let timer = if timed { PassTimer::new(ctx, 2) } else { None };
    if timed && timer.is_none() {
        let mut ms = [0.0; 2];
        for (stage, m) in ms.iter_mut().enumerate() {
            let t = Instant::now();
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            match stage {
                0 => r.filter.record(&mut enc, None),
                _ => {
                    r.display.record(&mut enc, None);
                    copy_into(&mut enc);
                }
            }
            ctx.queue.submit([enc.finish()]);
            ctx.wait()?;
            *m = t.elapsed().as_secs_f64() * 1e3;
        }
        return Ok(Some((ms[0], ms[1], false)));
    }
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    r.filter.record(&mut enc, timer.as_ref().map(|t| (t, 0)));
    r.display.record(&mut enc, timer.as_ref().map(|t| (t, 1)));
    copy_into(&mut enc);
    if let Some(t) = &timer {
        t.resolve(&mut enc);
    }
    ctx.queue.submit([enc.finish()]);
    match &timer {
        Some(t) => {
            let ms = t.read_ms(ctx)?;
            Ok(Some((ms[0], ms[1], true)))
        }
        None => Ok(None),
    }
}
