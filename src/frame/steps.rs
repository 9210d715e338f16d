//! One frame, step by step (DESIGN.md §1), and what changes between frames: the ROI, the
//! wall camera's eye, the pinhole camera, a restart — [`Render`] for one process.

use std::time::Instant;

use super::dgi::prepare_dgi;
use super::stop::RoiProgress;
use super::{
    Engine, EyeFollow, FrameError, FrameStats, GuideConfig, PendingDgi, Render, Renderer,
    TimedIterations,
};
use crate::roi::dgi::{Roi, compute_cpu};
use crate::schedule::{DrawInput, schedule_cpu_shown};
use crate::trace::accum::Accumulation;
use crate::trace::camera::RenderCamera;
use crate::trace::path::{TraceSettings, render_cpu_with};
use crate::trace::wall::WallCamera;

/// Timer slots of a frame's passes.
const PASS_DGI: u32 = 0;
const PASS_SCHEDULE: u32 = 1;
const PASS_TRACE: u32 = 2;

/// A frame being assembled by the steps of [`Renderer::run_frame`].
struct FrameInProgress {
    timed: bool,
    stats: FrameStats,
    /// GPU: the encoder every step records into.
    encoder: Option<wgpu::CommandEncoder>,
    /// CPU: the pixels the schedule step chose (`None`: every pixel).
    list: Option<Vec<u32>>,
    /// When the frame started (the GPU's wall-clock fallback).
    started: Instant,
}

impl Render for Renderer<'_> {
    type Error = FrameError;
    type Stats = FrameStats;

    fn settings(&self) -> &TraceSettings {
        &self.settings
    }

    fn guide_config(&self) -> Option<&GuideConfig> {
        self.guidance.as_ref().map(|g| &g.config)
    }

    fn wall(&self) -> Option<&WallCamera> {
        self.wall.as_ref()
    }

    fn roi(&self) -> Option<&Roi> {
        self.guidance.as_ref().and_then(|g| g.roi.as_ref())
    }

    fn iteration(&self) -> u32 {
        self.iteration
    }

    /// The DGI is prepared here and installed by the next frame (the CPU twin computes it
    /// now).
    fn set_roi(&mut self, roi: Option<Roi>) -> Result<(), FrameError> {
        let (w, h) = (self.settings.width, self.settings.height);
        let g = self.guidance.as_mut().ok_or(FrameError::NotGuided)?;
        let prepared = match &roi {
            Some(r) => Some(prepare_dgi(&g.surface, g.pitch_m, &g.config, r, [w, h])?),
            None => None,
        };
        match &mut self.engine {
            Engine::Gpu {
                ctx,
                bands,
                dgi_kernel: Some(kernel),
                ..
            } => {
                for b in bands.iter_mut() {
                    let gg = b.guide.as_mut().ok_or(FrameError::NotGuided)?;
                    gg.pending = Some(match &prepared {
                        Some((guide, params)) => PendingDgi::Run(kernel.prepare_band(
                            ctx,
                            &g.surface,
                            guide,
                            params,
                            b.band.row0,
                            b.band.rows,
                        )?),
                        None => PendingDgi::Zero,
                    });
                }
            }
            Engine::Cpu {
                guide: Some(cg), ..
            } => {
                let t0 = Instant::now();
                let dgi = match prepared {
                    Some((guide, params)) => compute_cpu(&g.surface, &guide, &params),
                    None => vec![0.0; w as usize * h as usize],
                };
                cg.pending = Some((dgi, t0.elapsed().as_secs_f64() * 1e3));
            }
            // A guided renderer always has its guided stages.
            Engine::Gpu {
                dgi_kernel: None, ..
            }
            | Engine::Cpu { guide: None, .. } => {
                return Err(FrameError::NotGuided);
            }
        }
        g.roi = roi;
        Ok(())
    }

    fn follow_eye(&mut self, eye: glam::DVec3, threshold_m: f64) -> Result<EyeFollow, FrameError> {
        let wall = self.wall.as_ref().ok_or(FrameError::NoWall)?;
        if !wall.eye_moved(eye, threshold_m) {
            return Ok(EyeFollow::Kept);
        }
        match self.set_wall_eye(eye) {
            Ok(Some(stats)) => Ok(EyeFollow::Reused(stats)),
            Ok(None) => Ok(EyeFollow::Restarted),
            Err(FrameError::Wall(e)) => Ok(EyeFollow::Refused(e)),
            Err(e) => Err(e),
        }
    }

    fn set_camera(&mut self, camera: RenderCamera) -> Result<(), FrameError> {
        self.move_view(|r| {
            r.settings.camera = camera;
            if let Engine::Gpu { ctx, bands, .. } = &r.engine {
                for b in bands {
                    b.trace.set_settings(ctx, &r.packed, &r.settings);
                }
            }
        })?;
        Ok(())
    }

    /// One frame: the DGI if the ROI changed, the schedule, and one path for each scheduled
    /// pixel; on the GPU recorded into one command encoder and submitted once, nothing read
    /// back. With `timed`, stage times are measured (GPU timestamps where the adapter has them)
    /// and the pixel and ray counts read back, which makes the frame wait for the GPU.
    fn run_frame(&mut self, timed: bool) -> Result<FrameStats, FrameError> {
        let mut frame = self.begin(timed);
        self.install_dgi(&mut frame);
        self.schedule(&mut frame)?;
        self.trace(&mut frame);
        self.submit(frame)
    }

    /// On a GPU renderer of one band measured there ([`Renderer::roi_stats`]'s measurement);
    /// otherwise from the accumulation (a read-back on the GPU).
    fn roi_progress(&mut self) -> Result<Option<RoiProgress>, FrameError> {
        self.progress()
    }

    /// Always here (a read-back on the GPU; a copy on the CPU: [`Renderer::finish`] moves it
    /// out instead).
    fn gather(&mut self) -> Result<Option<(Accumulation, Vec<f32>)>, FrameError> {
        Ok(Some((self.accumulation()?, self.dgi()?)))
    }
}

impl Renderer<'_> {
    /// Starts a frame: on the GPU, the command encoder the steps record into (and, timed, the
    /// cleared ray counter).
    fn begin(&self, timed: bool) -> FrameInProgress {
        let encoder = match &self.engine {
            Engine::Gpu { ctx, bands, .. } => {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                if timed {
                    bands.iter().for_each(|b| b.accum.clear_stats(&mut enc));
                }
                Some(enc)
            }
            Engine::Cpu { .. } => None,
        };
        FrameInProgress {
            timed,
            stats: FrameStats {
                iteration: self.iteration,
                ..FrameStats::default()
            },
            encoder,
            list: None,
            started: Instant::now(),
        }
    }

    /// Step 1: installs the DGI of a changed ROI (recorded on the GPU; computed already by
    /// [`Self::set_roi`] on the CPU). Nothing for a full frame or an unchanged ROI.
    fn install_dgi(&mut self, frame: &mut FrameInProgress) {
        match &mut self.engine {
            Engine::Gpu { bands, timer, .. } => {
                let timer = timer.as_ref().filter(|_| frame.timed);
                let enc = frame.encoder.as_mut().expect("a GPU frame has an encoder");
                let last = bands.len() - 1;
                for (i, g) in bands.iter_mut().enumerate() {
                    let Some(g) = g.guide.as_mut() else { continue };
                    match g.pending.take() {
                        Some(PendingDgi::Run(run)) => {
                            run.record_with(
                                enc,
                                timer.and_then(|t| t.writes_part(PASS_DGI, i == 0, i == last)),
                            );
                            enc.copy_buffer_to_buffer(&run.output, 0, &g.dgi, 0, g.dgi.size());
                            frame.stats.dgi_recomputed = true;
                        }
                        Some(PendingDgi::Zero) => {
                            enc.clear_buffer(&g.dgi, 0, None);
                            frame.stats.dgi_recomputed = true;
                        }
                        None => {}
                    }
                }
            }
            Engine::Cpu { guide: Some(g), .. } => {
                if let Some((new, ms)) = g.pending.take() {
                    g.dgi = new;
                    frame.stats.dgi_recomputed = true;
                    if frame.timed {
                        frame.stats.ms_dgi = Some(ms);
                    }
                }
            }
            Engine::Cpu { guide: None, .. } => {}
        }
    }

    /// Step 2: chooses the pixels to trace from the DGI (p = max(p_min, 1 − d), Bernoulli,
    /// compaction into a list). A full frame traces every pixel: nothing to choose.
    fn schedule(&mut self, frame: &mut FrameInProgress) -> Result<(), FrameError> {
        let (w, h, seed) = (
            self.settings.width,
            self.settings.height,
            self.settings.seed,
        );
        let iteration = self.iteration;
        match (&mut self.engine, &self.guidance) {
            (Engine::Gpu { bands, timer, .. }, Some(_)) => {
                let timer = timer.as_ref().filter(|_| frame.timed);
                let enc = frame.encoder.as_mut().expect("a GPU frame has an encoder");
                let last = bands.len() - 1;
                for (i, b) in bands.iter().enumerate() {
                    if let Some(g) = &b.guide {
                        g.schedule.record_with(
                            enc,
                            iteration,
                            seed,
                            timer.and_then(|t| t.writes_part(PASS_SCHEDULE, i == 0, i == last)),
                        );
                    }
                }
            }
            (Engine::Cpu { guide: Some(g), .. }, Some(guidance)) => {
                let t0 = Instant::now();
                let c = &guidance.config;
                let shown = self.wall.as_ref().map(WallCamera::shown_mask);
                let input = DrawInput {
                    dgi: &g.dgi,
                    shown,
                    width: w,
                    height: h,
                    p_min: c.p_min,
                    iteration,
                    seed,
                };
                frame.list = Some(schedule_cpu_shown(&input, c.order)?);
                if frame.timed {
                    frame.stats.ms_schedule = Some(t0.elapsed().as_secs_f64() * 1e3);
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// Step 3: one path for each scheduled pixel (every pixel of a full frame), added to the
    /// accumulation.
    fn trace(&mut self, frame: &mut FrameInProgress) {
        match &mut self.engine {
            Engine::Gpu {
                scene,
                bands,
                timer,
                ..
            } => {
                let timer = timer.as_ref().filter(|_| frame.timed);
                let enc = frame.encoder.as_mut().expect("a GPU frame has an encoder");
                let last = bands.len() - 1;
                for (i, b) in bands.iter().enumerate() {
                    b.trace.record_with(
                        enc,
                        scene,
                        timer.and_then(|t| t.writes_part(PASS_TRACE, i == 0, i == last)),
                    );
                }
            }
            Engine::Cpu { accum, .. } => {
                let t0 = Instant::now();
                let list = frame.list.as_deref();
                let rays = render_cpu_with(
                    &self.packed,
                    &self.settings,
                    self.wall.as_ref(),
                    accum,
                    list,
                );
                let pixels = list.map_or_else(|| self.full_frame_pixels(), |l| l.len() as u32);
                frame.stats.pixels = Some(pixels);
                frame.stats.rays = Some(rays);
                if frame.timed {
                    frame.stats.ms_trace = Some(t0.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
    }

    /// Ends the frame: on the GPU, submits the steps' work once (and, timed, waits and reads
    /// the timestamps and counts back).
    fn submit(&mut self, frame: FrameInProgress) -> Result<FrameStats, FrameError> {
        let FrameInProgress {
            timed,
            mut stats,
            encoder,
            started,
            ..
        } = frame;
        if let Engine::Gpu {
            ctx,
            bands,
            dgi_kernel,
            timer,
            ..
        } = &self.engine
        {
            let guided = dgi_kernel.is_some();
            let timer = timer.as_ref().filter(|_| timed);
            let mut enc = encoder.expect("a GPU frame has an encoder");
            if let Some(t) = timer {
                t.resolve(&mut enc);
            }
            ctx.queue.submit([enc.finish()]);
            if !guided {
                stats.pixels = Some(self.full_frame_pixels());
            }
            if timed {
                ctx.wait()?;
                let wall = started.elapsed().as_secs_f64() * 1e3;
                if guided {
                    let mut pixels = 0;
                    for g in bands.iter().filter_map(|b| b.guide.as_ref()) {
                        pixels += g.schedule.read_args(ctx)?[3];
                    }
                    stats.pixels = Some(pixels);
                }
                match timer {
                    Some(t) => {
                        let ms = t.read_ms(ctx)?;
                        stats.ms_dgi = stats.dgi_recomputed.then_some(ms[PASS_DGI as usize]);
                        if guided {
                            stats.ms_schedule = Some(ms[PASS_SCHEDULE as usize]);
                        }
                        stats.ms_trace = Some(ms[PASS_TRACE as usize]);
                        stats.gpu_timestamps = true;
                    }
                    // Without timestamps only the whole frame can be timed.
                    None => stats.ms_trace = Some(wall),
                }
                let mut rays = 0;
                for b in bands {
                    rays += b.accum.rays(ctx)?;
                }
                stats.rays = Some(rays);
            }
        }
        self.iteration += 1;
        Ok(stats)
    }

    /// Pixels a full frame traces: every pixel, or those the wall camera's display shows.
    fn full_frame_pixels(&self) -> u32 {
        self.wall
            .as_ref()
            .map_or(self.settings.width * self.settings.height, |w| {
                w.shown_count() as u32
            })
    }

    /// Restarts the accumulation: every pixel's sum and count back to zero and the iteration
    /// counter to 0 (the schedule draws as a fresh renderer's do). The ROI, its DGI (installed
    /// or pending) and the scene stay.
    pub fn restart(&mut self) {
        match &mut self.engine {
            Engine::Gpu { ctx, bands, .. } => {
                let mut enc = ctx.device.create_command_encoder(&Default::default());
                bands.iter().for_each(|b| b.accum.clear(&mut enc));
                ctx.queue.submit([enc.finish()]);
            }
            Engine::Cpu { accum, .. } => {
                accum.sum.fill([0.0; 4]);
                accum.count.fill(0);
            }
        }
        self.iteration = 0;
        // The view may have changed (a camera, an eye): its features are made again, and its
        // records (whose anchors were the old accumulation's) at the next move.
        self.features = std::cell::OnceCell::new();
        self.hits = None;
    }

    /// Moves the wall camera's eye to `eye` (room frame; the room's placement in the scene
    /// kept, [`WallCamera::with_eye`]) and restarts the accumulation ([`Self::restart`]) or,
    /// with [`super::EyeMove::Reuse`], carries it over: then what it carried.
    pub fn set_wall_eye(
        &mut self,
        eye: glam::DVec3,
    ) -> Result<Option<crate::trace::reuse::ReuseStats>, FrameError> {
        let wall = self
            .wall
            .as_ref()
            .ok_or(FrameError::NoWall)?
            .with_eye(eye)?;
        self.move_view(|r| {
            if let Engine::Gpu { ctx, bands, .. } = &mut r.engine {
                for b in bands.iter_mut() {
                    let done = b.trace.set_wall(ctx, &r.packed, &r.settings, &wall);
                    debug_assert!(done, "a moved wall camera keeps its tiles");
                }
            }
            r.wall = Some(wall);
        })
    }

    /// Runs `n` frames and waits for them.
    pub fn iterate(&mut self, n: u32) -> Result<(), FrameError> {
        for _ in 0..n {
            self.run_frame(false)?;
        }
        self.wait()
    }

    /// Waits until the submitted frames are done (nothing to wait for on the CPU).
    pub fn wait(&self) -> Result<(), FrameError> {
        match &self.engine {
            Engine::Gpu { ctx, .. } => Ok(ctx.wait()?),
            Engine::Cpu { .. } => Ok(()),
        }
    }

    /// Runs `n` frames one at a time and times the trace step of each (for benchmarks).
    pub fn timed_iterations(&mut self, n: u32) -> Result<TimedIterations, FrameError> {
        let mut ms = Vec::with_capacity(n as usize);
        let mut rays = 0u64;
        let mut stamps = false;
        for _ in 0..n {
            let s = self.run_frame(true)?;
            ms.push(s.ms_trace.unwrap_or(f64::NAN));
            rays += s.rays.unwrap_or(0);
            stamps = s.gpu_timestamps;
        }
        Ok(TimedIterations {
            ms,
            rays_per_iteration: rays as f64 / f64::from(n.max(1)),
            gpu_timestamps: stamps,
        })
    }
}
