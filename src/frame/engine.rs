//! The renderer's set-up: the constructors, each backend's buffers and kernels, and the bands
//! of rows a GPU frame is split into where one storage binding cannot hold it (DESIGN.md §11).

use std::cell::OnceCell;
use std::time::Instant;

use super::{
    CpuGuide, Engine, FrameError, GpuBand, GpuGuide, Guidance, GuideConfig, Renderer, roi_stats,
};
use crate::display::DisplayModel;
use crate::gpu::{Backend, Band, GpuContext, GpuError, PassTimer};
use crate::roi::gpu::DgiKernel;
use crate::scene::Scene;
use crate::schedule::gpu::{ScheduleConfig, ScheduleKernel};
use crate::trace::accum::Accumulation;
use crate::trace::gpu::{GpuAccum, GpuScene, RunInputs, TraceKernel, TraceRun};
use crate::trace::pack::PackedScene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

impl<'a> Renderer<'a> {
    /// A full-frame render of `scene`: one path per pixel per frame.
    pub fn full(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
    ) -> Result<Self, FrameError> {
        Self::new(backend, scene, settings, None, None)
    }

    /// A full-frame render through the wall camera `wall`: every pixel its display shows, every
    /// frame; the others are never traced.
    pub fn full_wall(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
        wall: WallCamera,
    ) -> Result<Self, FrameError> {
        Self::new(backend, scene, settings, None, Some(wall))
    }

    /// A render of `settings.width × settings.height` pixels covering `display`'s canvas,
    /// steered by the ROI set with [`Render::set_roi`](super::Render::set_roi) (none yet: the whole frame is sampled).
    pub fn guided(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
        display: &DisplayModel,
        config: GuideConfig,
    ) -> Result<Self, FrameError> {
        Self::guided_wall(backend, scene, settings, display, config, None)
    }

    /// [`Self::guided`] through the wall camera `wall` when given: the schedule never lists a
    /// pixel its display does not show.
    pub fn guided_wall(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
        display: &DisplayModel,
        config: GuideConfig,
        wall: Option<WallCamera>,
    ) -> Result<Self, FrameError> {
        let guidance = Guidance::new(display, config)?;
        Self::new(backend, scene, settings, Some(guidance), wall)
    }

    /// A guided renderer of this one's scene with other settings, guide or wall camera
    /// ([`Self::guided_wall`]'s arguments less the scene), starting from nothing: the scene
    /// is not packed and its BVH not built again (the viewer's rebuild when its settings
    /// change or a reset is asked for: seconds for a large scene). What a move does
    /// ([`super::EyeMove`]) is kept.
    pub fn rebuilt_guided(
        &self,
        settings: TraceSettings,
        display: &DisplayModel,
        config: GuideConfig,
        wall: Option<WallCamera>,
    ) -> Result<Renderer<'a>, FrameError> {
        Self::check_wall(&settings, wall.as_ref())?;
        let guidance = Guidance::new(display, config)?;
        let mut r = Renderer::with_packed(
            self.backend,
            std::sync::Arc::clone(&self.packed),
            self.build_seconds,
            settings,
            Some(guidance),
            wall,
        )?;
        r.on_eye_move = self.on_eye_move;
        Ok(r)
    }

    /// Packs the scene, builds its BVH and prepares every stage (on the GPU: uploads and
    /// clears).
    fn new(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
        guidance: Option<Guidance>,
        wall: Option<WallCamera>,
    ) -> Result<Self, FrameError> {
        Self::check_wall(&settings, wall.as_ref())?;
        let t0 = Instant::now();
        let packed = std::sync::Arc::new(PackedScene::new(scene));
        if !backend.is_gpu() {
            // The CPU twin's own tree is one-time work: here, not in the first frame's time.
            packed.bvh.prepare_cpu();
        }
        let build_seconds = t0.elapsed().as_secs_f64();
        Self::with_packed(backend, packed, build_seconds, settings, guidance, wall)
    }

    /// A wall camera's image must be the render's.
    fn check_wall(settings: &TraceSettings, wall: Option<&WallCamera>) -> Result<(), FrameError> {
        match wall {
            Some(wc) if [wc.width, wc.height] != [settings.width, settings.height] => {
                Err(FrameError::WallSize {
                    wall: [wc.width, wc.height],
                    image: [settings.width, settings.height],
                })
            }
            _ => Ok(()),
        }
    }

    /// Prepares every stage for the packed scene `packed` (on the GPU: uploads and clears);
    /// the callers have checked the wall camera ([`Self::check_wall`]).
    fn with_packed(
        backend: &'a Backend,
        packed: std::sync::Arc<PackedScene>,
        build_seconds: f64,
        settings: TraceSettings,
        guidance: Option<Guidance>,
        wall: Option<WallCamera>,
    ) -> Result<Self, FrameError> {
        let (w, h) = (settings.width, settings.height);
        let n = w as usize * h as usize;
        let t0 = Instant::now();
        let engine = match backend {
            Backend::Gpu(ctx) => {
                let ctx: &GpuContext = ctx;
                let kernel = TraceKernel::new(ctx);
                let gscene = GpuScene::upload(ctx, &kernel, &packed)?;
                let schedule_kernel = guidance.as_ref().map(|_| ScheduleKernel::new(ctx));
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                let mut bands = Vec::new();
                for band in frame_bands(ctx, w, h)? {
                    let accum = GpuAccum::new(ctx, w, band.rows)?;
                    let guide = match (&guidance, &schedule_kernel) {
                        (Some(g), Some(k)) => Some(gpu_guide(
                            ctx,
                            k,
                            w,
                            band,
                            &g.config,
                            wall.as_ref().map(WallCamera::shown_mask),
                            &kernel,
                        )?),
                        _ => None,
                    };
                    let inputs = RunInputs {
                        scene: &packed,
                        settings: &settings,
                        wall: wall.as_ref(),
                        accum: &accum,
                        schedule: guide
                            .as_ref()
                            .map(|g| (g.schedule.list(), g.schedule.args())),
                    };
                    let trace = TraceRun::for_band(ctx, &kernel, inputs, band);
                    accum.clear(&mut enc);
                    if let Some(g) = &guide {
                        enc.clear_buffer(&g.dgi, 0, None);
                    }
                    bands.push(GpuBand {
                        band,
                        accum,
                        trace,
                        guide,
                    });
                }
                ctx.queue.submit([enc.finish()]);
                // Waited for, so that the upload's time is its own and not the first frame's.
                ctx.wait()?;
                Engine::Gpu {
                    ctx,
                    scene: gscene,
                    bands,
                    dgi_kernel: guidance.as_ref().map(|_| DgiKernel::new(ctx)),
                    timer: PassTimer::new(ctx, 3),
                }
            }
            Backend::Cpu => Engine::Cpu {
                accum: Accumulation::new(w, h),
                guide: guidance.as_ref().map(|_| CpuGuide {
                    dgi: vec![0.0; n],
                    pending: None,
                }),
            },
        };
        let upload_seconds = t0.elapsed().as_secs_f64();
        Ok(Self {
            packed,
            settings,
            build_seconds,
            upload_seconds,
            backend,
            guidance,
            engine,
            iteration: 0,
            filter: OnceCell::new(),
            display: OnceCell::new(),
            resident: std::cell::RefCell::new(None),
            stats: roi_stats::Stats::new(),
            wall,
            features: OnceCell::new(),
            denoise_kernels: OnceCell::new(),
            on_eye_move: super::EyeMove::default(),
            hits: None,
            last_reuse: None,
        })
    }

    /// The backend the frames run on.
    #[must_use]
    pub fn backend(&self) -> &'a Backend {
        self.backend
    }

    /// The bands of rows a GPU frame is split into to fit the adapter's storage bindings
    /// (1: unsplit); `None` on the CPU backend.
    #[must_use]
    pub fn gpu_bands(&self) -> Option<usize> {
        match &self.engine {
            Engine::Gpu { bands, .. } => Some(bands.len()),
            Engine::Cpu { .. } => None,
        }
    }
}

/// The bands of a `w × h` frame on this adapter: one where every buffer fits a storage
/// binding, else as few bands of rows as fit (the accumulation's 16 bytes a pixel is the
/// largest buffer).
fn frame_bands(ctx: &GpuContext, w: u32, h: u32) -> Result<Vec<Band>, FrameError> {
    let max = ctx.max_binding();
    Band::split(w, h, ACCUM_BYTES_PER_PIXEL, max).ok_or_else(|| {
        GpuError::TooLarge {
            what: "one row of the accumulation (16 bytes per pixel)",
            bytes: u64::from(w) * ACCUM_BYTES_PER_PIXEL,
            max,
        }
        .into()
    })
}

/// Bytes per pixel of the largest per-pixel GPU buffer, the accumulation's RGB sum and
/// Σ luminance².
const ACCUM_BYTES_PER_PIXEL: u64 = 16;

/// The bits of `shown` (bit `p % 32` of word `p / 32` for image pixel `p`) for the `n` pixels
/// from `base`, as a mask of their own.
fn band_mask(shown: &[u32], base: u32, n: u32) -> Vec<u32> {
    let words = n.div_ceil(32) as usize;
    if base.is_multiple_of(32) {
        // Word-aligned (a one-band frame's band, say): the words as they are. Bits past the
        // band's last pixel may belong to the next band; the kernel never reads them.
        let first = (base / 32) as usize;
        return shown[first..first + words].to_vec();
    }
    let bit = |p: u32| (shown[(p / 32) as usize] >> (p % 32)) & 1;
    let mut out = vec![0u32; words];
    for p in 0..n {
        out[(p / 32) as usize] |= bit(base + p) << (p % 32);
    }
    out
}

/// The guided stages on the GPU for one `band` of a `w`-wide frame, with a cleared DGI.
fn gpu_guide(
    ctx: &GpuContext,
    kernel: &ScheduleKernel,
    w: u32,
    band: Band,
    config: &GuideConfig,
    shown: Option<&[u32]>,
    trace: &TraceKernel,
) -> Result<GpuGuide, FrameError> {
    let dgi = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("frame dgi"),
        size: u64::from(w) * u64::from(band.rows) * 4,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let base = band.pixel_base(w);
    let mask = shown.map(|m| band_mask(m, base, w * band.rows));
    let schedule = kernel.prepare_band(
        ctx,
        &dgi,
        mask.as_deref(),
        &ScheduleConfig {
            width: w,
            height: band.rows,
            p_min: config.p_min,
            order: config.order,
            trace_workgroup_size: trace.workgroup(),
            trace_max_groups: trace.max_list_groups(),
        },
        base,
    )?;
    Ok(GpuGuide {
        dgi,
        schedule,
        pending: None,
    })
}
