//! One frame of the pipeline (DESIGN.md §1), on either backend:
//!
//! ```text
//! ROI (if changed) ──► DGI ──► scheduling (p = max(p_min, 1 − d), Bernoulli, compaction)
//!                               ──► path tracing of exactly the listed pixels ──► accumulation
//! ```
//!
//! [`GuidedRenderer::run_frame`] is that function. On the GPU it records every stage into one
//! command encoder — the DGI only when the ROI changed, then the scheduler, whose pixel count
//! feeds the tracer's indirect dispatch — and submits once: nothing is read back. On the CPU
//! the twins run in the same order on the same data, so both backends take the same
//! decisions. Per-pixel sample counts live in the accumulation and persist across ROI changes.
//! Filtering and display read the accumulation and the DGI when a picture is wanted.
//!
//! Without an ROI (before the first shot) the DGI is 0 everywhere: the whole frame is sampled.

use std::time::Instant;

use crate::display::DisplayModel;
use crate::gpu::{Backend, GpuContext, GpuError, PassTimer};
use crate::roi::dgi::{
    DgiParams, Falloff, Guide, GuideError, Metric, Roi, Surface, compute_cpu, roi_radius_m,
};
use crate::roi::gpu::DgiKernel;
use crate::scene::Scene;
use crate::schedule::gpu::{ScheduleConfig, ScheduleKernel, ScheduleRun};
use crate::schedule::{Order, ScheduleError, schedule_cpu};
use crate::trace::accum::Accumulation;
use crate::trace::cpu::{TraceSettings, render_cpu};
use crate::trace::gpu::{GpuAccum, GpuScene, TraceKernel, TraceRun, WORKGROUP};
use crate::trace::pack::PackedScene;

/// How the ROI steers sampling.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct GuideConfig {
    pub metric: Metric,
    pub falloff: Falloff,
    /// Lowest sampling probability (paper preset 0).
    pub p_min: f32,
    pub order: Order,
}

impl Default for GuideConfig {
    fn default() -> Self {
        Self {
            metric: Metric::Exact,
            falloff: Falloff::default(),
            p_min: 0.0,
            order: Order::Coherent,
        }
    }
}

/// Why a guided render failed.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Schedule(#[from] ScheduleError),
    #[error(transparent)]
    Guide(#[from] GuideError),
}

/// What one frame did.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct FrameStats {
    pub iteration: u32,
    /// Whether the DGI was recomputed (the ROI changed).
    pub dgi_recomputed: bool,
    /// Pixels traced (CPU: always; GPU: only with timing, which reads the count back).
    pub pixels: Option<u32>,
    /// Stage times in ms (GPU timestamps or CPU wall clock), when timing was asked for.
    pub ms_dgi: Option<f64>,
    pub ms_schedule: Option<f64>,
    pub ms_trace: Option<f64>,
}

/// A new DGI for the next frame to install.
enum PendingDgi {
    Run(crate::roi::gpu::DgiRun),
    /// No ROI: d = 0 everywhere.
    Zero,
}

// One engine per renderer: the size difference between the variants does not matter.
#[allow(clippy::large_enum_variant)]
enum Engine<'a> {
    Gpu {
        ctx: &'a GpuContext,
        dgi_kernel: DgiKernel,
        scene: GpuScene,
        accum: GpuAccum,
        /// The DGI the scheduler reads (a DGI run's output is copied in on ROI changes).
        dgi: wgpu::Buffer,
        schedule: ScheduleRun,
        trace: TraceRun,
        /// A DGI change waiting for the next frame.
        pending: Option<PendingDgi>,
        timer: Option<PassTimer>,
    },
    Cpu {
        accum: Accumulation,
        dgi: Vec<f32>,
        /// The next DGI and the ms it took.
        pending: Option<(Vec<f32>, f64)>,
    },
}

/// A progressive render steered by an ROI on a display wall.
pub struct GuidedRenderer<'a> {
    pub packed: PackedScene,
    pub settings: TraceSettings,
    pub config: GuideConfig,
    surface: Surface,
    pitch_m: f64,
    engine: Engine<'a>,
    iteration: u32,
    roi: Option<Roi>,
}

impl<'a> GuidedRenderer<'a> {
    /// Prepares the scene and every stage for `settings.width × settings.height` pixels
    /// covering `display`'s canvas.
    pub fn new(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
        display: &DisplayModel,
        config: GuideConfig,
    ) -> Result<Self, FrameError> {
        crate::schedule::validate_p_min(config.p_min)?;
        let packed = PackedScene::new(scene);
        let (w, h) = (settings.width, settings.height);
        let n = w as usize * h as usize;
        let engine = match backend {
            Backend::Gpu(ctx) => {
                let ctx: &GpuContext = ctx;
                let kernel = TraceKernel::new(ctx);
                let gscene = GpuScene::upload(ctx, &kernel, &packed)?;
                let accum = GpuAccum::new(ctx, w, h)?;
                let dgi = ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("frame dgi"),
                    size: n as u64 * 4,
                    usage: wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_DST
                        | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                let schedule = ScheduleKernel::new(ctx).prepare(
                    ctx,
                    &dgi,
                    &ScheduleConfig {
                        width: w,
                        height: h,
                        p_min: config.p_min,
                        order: config.order,
                        trace_workgroup_size: WORKGROUP,
                    },
                )?;
                let trace = TraceRun::new(
                    ctx,
                    &kernel,
                    &packed,
                    &settings,
                    &accum,
                    Some((schedule.list(), schedule.args())),
                );
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                accum.clear(&mut enc);
                enc.clear_buffer(&dgi, 0, None);
                ctx.queue.submit([enc.finish()]);
                Engine::Gpu {
                    ctx,
                    dgi_kernel: DgiKernel::new(ctx),
                    scene: gscene,
                    accum,
                    dgi,
                    schedule,
                    trace,
                    pending: None,
                    timer: PassTimer::new(ctx, 3),
                }
            }
            Backend::Cpu => Engine::Cpu {
                accum: Accumulation::new(w, h),
                dgi: vec![0.0; n],
                pending: None,
            },
        };
        Ok(Self {
            packed,
            settings,
            config,
            surface: Surface::from_model(display),
            pitch_m: display.pitch_m(),
            engine,
            iteration: 0,
            roi: None,
        })
    }

    /// Iterations run so far.
    #[must_use]
    pub fn iteration(&self) -> u32 {
        self.iteration
    }

    /// The current ROI.
    #[must_use]
    pub fn roi(&self) -> Option<&Roi> {
        self.roi.as_ref()
    }

    /// Sets the ROI; its DGI is computed by the next frame (`None`: sample the whole frame).
    /// The accumulation is kept: samples taken under the old ROI still count.
    pub fn set_roi(&mut self, roi: Option<Roi>) -> Result<(), FrameError> {
        let (w, h) = (self.settings.width, self.settings.height);
        let prepared = match &roi {
            Some(r) => {
                let guide = Guide::new(&self.surface, r, self.config.metric)?;
                let length = self
                    .config
                    .falloff
                    .length_px(roi_radius_m(&self.surface, r), self.pitch_m);
                Some((
                    guide,
                    DgiParams {
                        width: w,
                        height: h,
                        falloff_px: Some(length),
                    },
                ))
            }
            None => None,
        };
        match &mut self.engine {
            Engine::Gpu {
                ctx,
                dgi_kernel,
                pending,
                ..
            } => {
                *pending = Some(match prepared {
                    Some((guide, params)) => {
                        PendingDgi::Run(dgi_kernel.prepare(ctx, &self.surface, &guide, &params)?)
                    }
                    None => PendingDgi::Zero,
                });
            }
            Engine::Cpu { pending, .. } => {
                let t0 = Instant::now();
                let dgi = match prepared {
                    Some((guide, params)) => compute_cpu(&self.surface, &guide, &params),
                    None => vec![0.0; w as usize * h as usize],
                };
                *pending = Some((dgi, t0.elapsed().as_secs_f64() * 1e3));
            }
        }
        self.roi = roi;
        Ok(())
    }

    /// Runs one frame: the DGI if the ROI changed, the schedule, and one path for each
    /// scheduled pixel. With `timed`, stage times are measured (GPU timestamps where the
    /// adapter has them) and the pixel count is read back — for benchmarks; an interactive
    /// loop leaves it off so nothing waits on the GPU.
    pub fn run_frame(&mut self, timed: bool) -> Result<FrameStats, FrameError> {
        let iteration = self.iteration;
        let seed = self.settings.seed;
        let mut stats = FrameStats {
            iteration,
            ..Default::default()
        };
        match &mut self.engine {
            Engine::Gpu {
                ctx,
                scene,
                dgi,
                schedule,
                trace,
                pending,
                timer,
                ..
            } => {
                let timer = if timed { timer.as_ref() } else { None };
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                let t0 = Instant::now();
                match pending.take() {
                    Some(PendingDgi::Run(run)) => {
                        run.record(&mut enc, timer.map(|t| (t, 0)));
                        enc.copy_buffer_to_buffer(&run.output, 0, dgi, 0, dgi.size());
                        stats.dgi_recomputed = true;
                    }
                    Some(PendingDgi::Zero) => {
                        enc.clear_buffer(dgi, 0, None);
                        stats.dgi_recomputed = true;
                    }
                    None => {}
                }
                schedule.record(&mut enc, iteration, seed, timer.map(|t| (t, 1)));
                trace.record(&mut enc, scene, timer.map(|t| (t, 2)));
                if let Some(t) = timer {
                    t.resolve(&mut enc);
                }
                ctx.queue.submit([enc.finish()]);
                if timed {
                    ctx.wait()?;
                    let wall = t0.elapsed().as_secs_f64() * 1e3;
                    stats.pixels = Some(schedule.read_args(ctx)?[3]);
                    match timer {
                        Some(t) => {
                            let ms = t.read_ms(ctx)?;
                            stats.ms_dgi = stats.dgi_recomputed.then_some(ms[0]);
                            stats.ms_schedule = Some(ms[1]);
                            stats.ms_trace = Some(ms[2]);
                        }
                        // Without timestamps only the whole frame can be timed.
                        None => stats.ms_trace = Some(wall),
                    }
                }
            }
            Engine::Cpu {
                accum,
                dgi,
                pending,
            } => {
                if let Some((new, ms)) = pending.take() {
                    *dgi = new;
                    stats.dgi_recomputed = true;
                    if timed {
                        stats.ms_dgi = Some(ms);
                    }
                }
                let t0 = Instant::now();
                let list = schedule_cpu(
                    dgi,
                    self.settings.width,
                    self.settings.height,
                    self.config.p_min,
                    iteration,
                    seed,
                    self.config.order,
                )?;
                let t1 = Instant::now();
                render_cpu(&self.packed, &self.settings, accum, Some(&list));
                stats.pixels = Some(list.len() as u32);
                if timed {
                    stats.ms_schedule = Some((t1 - t0).as_secs_f64() * 1e3);
                    stats.ms_trace = Some(t1.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
        self.iteration += 1;
        Ok(stats)
    }

    /// The accumulation so far (a read-back on the GPU).
    pub fn accumulation(&self) -> Result<Accumulation, FrameError> {
        Ok(match &self.engine {
            Engine::Gpu { ctx, accum, .. } => accum.read(ctx)?,
            Engine::Cpu { accum, .. } => accum.clone(),
        })
    }

    /// How far the ROI has come (a read-back on the GPU); `None` without ROI pixels.
    pub fn roi_progress(&self) -> Result<Option<crate::stop::RoiProgress>, FrameError> {
        Ok(match &self.engine {
            Engine::Gpu {
                ctx, accum, dgi, ..
            } => {
                let acc = accum.read(ctx)?;
                let dgi = ctx.read_buffer::<f32>(dgi)?;
                crate::stop::RoiProgress::measure(&acc, &dgi)
            }
            Engine::Cpu { accum, dgi, .. } => crate::stop::RoiProgress::measure(accum, dgi),
        })
    }

    /// The accumulation and the DGI the last frame used, ending the render (moved out on the
    /// CPU, read back on the GPU).
    pub fn finish(self) -> Result<(Accumulation, Vec<f32>), FrameError> {
        Ok(match self.engine {
            Engine::Gpu {
                ctx, accum, dgi, ..
            } => (accum.read(ctx)?, ctx.read_buffer::<f32>(&dgi)?),
            Engine::Cpu { accum, dgi, .. } => (accum, dgi),
        })
    }

    /// The DGI the last frame used (a read-back on the GPU).
    pub fn dgi(&self) -> Result<Vec<f32>, FrameError> {
        Ok(match &self.engine {
            Engine::Gpu { ctx, dgi, .. } => ctx.read_buffer::<f32>(dgi)?,
            Engine::Cpu { dgi, .. } => dgi.clone(),
        })
    }
}
