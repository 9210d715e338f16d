//! A progressive render on either backend: the one object the commands drive.

use std::time::Instant;

use super::accum::Accumulation;
use super::cpu::{TraceSettings, render_cpu};
use super::gpu::{GpuAccum, GpuScene, TraceKernel, TraceRun};
use super::pack::PackedScene;
use crate::gpu::{Backend, GpuContext, GpuError, PassTimer};
use crate::scene::Scene;

enum Engine<'a> {
    Gpu {
        ctx: &'a GpuContext,
        scene: GpuScene,
        accum: GpuAccum,
        run: TraceRun,
    },
    Cpu {
        accum: Accumulation,
    },
}

/// Times of full-frame iterations run one at a time.
#[derive(Clone, Debug)]
pub struct TimedIterations {
    /// Milliseconds per iteration: GPU timestamps where the adapter has them, else wall clock
    /// around submit-and-wait (CPU: wall clock).
    pub ms: Vec<f64>,
    /// Rays traced per iteration (closest-hit and shadow rays), averaged.
    pub rays_per_iteration: f64,
    /// Whether `ms` comes from GPU timestamps.
    pub gpu_timestamps: bool,
}

/// A scene being rendered progressively, full frame, on the chosen backend.
pub struct Renderer<'a> {
    pub packed: PackedScene,
    pub settings: TraceSettings,
    engine: Engine<'a>,
    /// Seconds spent building the BVH and packing the scene.
    pub build_seconds: f64,
}

impl<'a> Renderer<'a> {
    /// Packs `scene`, builds its BVH and, on the GPU, uploads it.
    pub fn new(
        backend: &'a Backend,
        scene: &Scene,
        settings: TraceSettings,
    ) -> Result<Self, GpuError> {
        let t0 = Instant::now();
        let packed = PackedScene::new(scene);
        let build_seconds = t0.elapsed().as_secs_f64();
        let engine = match backend {
            Backend::Gpu(ctx) => {
                let kernel = TraceKernel::new(ctx);
                let gs = GpuScene::upload(ctx, &kernel, &packed)?;
                let accum = GpuAccum::new(ctx, settings.width, settings.height)?;
                let run = TraceRun::new(ctx, &kernel, &packed, &settings, &accum, None);
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                accum.clear(&mut enc);
                ctx.queue.submit([enc.finish()]);
                Engine::Gpu {
                    ctx,
                    scene: gs,
                    accum,
                    run,
                }
            }
            Backend::Cpu => Engine::Cpu {
                accum: Accumulation::new(settings.width, settings.height),
            },
        };
        Ok(Self {
            packed,
            settings,
            engine,
            build_seconds,
        })
    }

    /// Runs `n` full-frame iterations (one sample per pixel each) and waits for them.
    pub fn iterate(&mut self, n: u32) -> Result<(), GpuError> {
        match &mut self.engine {
            Engine::Gpu {
                ctx, scene, run, ..
            } => {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                for _ in 0..n {
                    run.record(&mut enc, scene, None);
                }
                ctx.queue.submit([enc.finish()]);
                ctx.wait()
            }
            Engine::Cpu { accum } => {
                for _ in 0..n {
                    render_cpu(&self.packed, &self.settings, accum, None);
                }
                Ok(())
            }
        }
    }

    /// Runs `n` iterations one at a time and times each (for benchmarks).
    pub fn timed_iterations(&mut self, n: u32) -> Result<TimedIterations, GpuError> {
        let mut times = Vec::with_capacity(n as usize);
        let mut rays = 0u64;
        let mut stamps = false;
        match &mut self.engine {
            Engine::Gpu {
                ctx,
                scene,
                accum,
                run,
            } => {
                let timer = PassTimer::new(ctx, 1);
                stamps = timer.is_some();
                for _ in 0..n {
                    let mut enc = ctx.device.create_command_encoder(&Default::default());
                    accum.clear_stats(&mut enc);
                    run.record(&mut enc, scene, timer.as_ref().map(|t| (t, 0)));
                    if let Some(t) = &timer {
                        t.resolve(&mut enc);
                    }
                    let t0 = Instant::now();
                    ctx.queue.submit([enc.finish()]);
                    ctx.wait()?;
                    let wall = t0.elapsed().as_secs_f64() * 1e3;
                    times.push(match &timer {
                        Some(t) => t.read_ms(ctx)?[0],
                        None => wall,
                    });
                    rays += accum.rays(ctx)?;
                }
            }
            Engine::Cpu { accum } => {
                for _ in 0..n {
                    let t0 = Instant::now();
                    rays += render_cpu(&self.packed, &self.settings, accum, None);
                    times.push(t0.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
        Ok(TimedIterations {
            ms: times,
            rays_per_iteration: rays as f64 / f64::from(n.max(1)),
            gpu_timestamps: stamps,
        })
    }

    /// The accumulation so far (a read-back on the GPU).
    pub fn accumulation(&self) -> Result<Accumulation, GpuError> {
        match &self.engine {
            Engine::Gpu { ctx, accum, .. } => accum.read(ctx),
            Engine::Cpu { accum } => Ok(accum.clone()),
        }
    }
}
