//! A prepared trace over one accumulation ([`TraceRun`]): full frames, the scheduler's lists,
//! the rows of one band; recorded into a frame's command encoder.

use wgpu::util::DeviceExt;

use super::params::{replace_wall, wall_table_buffer};
#[cfg(feature = "kernel-lab")]
use super::split::SplitRun;
use super::{GpuAccum, GpuScene, GpuTraceParams, TraceKernel, entry};
use crate::gpu::{Band, GpuContext, PassTimer};
use crate::trace::pack::PackedScene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

/// A prepared trace dispatch over one accumulation, full frame or from a pixel list.
pub struct TraceRun {
    /// The kernel (its pipeline, its workgroup's size, whether its launches regenerate).
    kernel: TraceKernel,
    params: wgpu::Buffer,
    bind: wgpu::BindGroup,
    /// The scheduler's `(x, y, z, count)` buffer in list mode.
    args: Option<wgpu::Buffer>,
    groups: [u32; 2],
    /// The wall camera the tile table was uploaded for (its eye goes into the parameters).
    wall: Option<WallCamera>,
    /// The tile table ([`TILE_VEC4S`](crate::trace::wall::TILE_VEC4S) vec4s a tile).
    wall_table: wgpu::Buffer,
    /// The rows of the image this run's accumulation holds.
    band: Band,
    /// A full frame's wavefront split, for the kernel lab's `+split` variants.
    #[cfg(feature = "kernel-lab")]
    split: Option<SplitRun>,
}

/// What a trace run traces and where its samples go: the scene and its settings, the wall
/// camera's primary rays when given, the accumulation, and the scheduler's `list` and
/// indirect `args` (`None`: every pixel; see [`TraceRun::new`]).
#[derive(Clone, Copy)]
pub struct RunInputs<'a> {
    pub scene: &'a PackedScene,
    pub settings: &'a TraceSettings,
    pub wall: Option<&'a WallCamera>,
    pub accum: &'a GpuAccum,
    pub schedule: Option<(&'a wgpu::Buffer, &'a wgpu::Buffer)>,
}

impl TraceRun {
    /// Full frame when `schedule` is `None`; otherwise one path per entry of the scheduler's
    /// `list` (pixel indices), launched indirectly from `args` = `(x, y, z, count)` (which
    /// needs `INDIRECT | STORAGE` usage).
    pub fn new(
        ctx: &GpuContext,
        kernel: &TraceKernel,
        scene: &PackedScene,
        settings: &TraceSettings,
        accum: &GpuAccum,
        schedule: Option<(&wgpu::Buffer, &wgpu::Buffer)>,
    ) -> Self {
        Self::with_wall(ctx, kernel, scene, settings, None, accum, schedule)
    }

    /// [`Self::new`] through `wall`'s primary rays when given (its tile table is uploaded:
    /// [`TILE_VEC4S`](crate::trace::wall::TILE_VEC4S) vec4s a tile).
    pub fn with_wall(
        ctx: &GpuContext,
        kernel: &TraceKernel,
        scene: &PackedScene,
        settings: &TraceSettings,
        wall: Option<&WallCamera>,
        accum: &GpuAccum,
        schedule: Option<(&wgpu::Buffer, &wgpu::Buffer)>,
    ) -> Self {
        let band = Band::whole(settings.height);
        let inputs = RunInputs {
            scene,
            settings,
            wall,
            accum,
            schedule,
        };
        Self::for_band(ctx, kernel, inputs, band)
    }

    /// [`Self::with_wall`] for the rows of `band` alone: `inputs.accum` holds those rows (it
    /// is `width × band.rows`), and `inputs.schedule`'s list, if any, holds band pixel indices.
    pub fn for_band(
        ctx: &GpuContext,
        kernel: &TraceKernel,
        inputs: RunInputs<'_>,
        band: Band,
    ) -> Self {
        let RunInputs {
            scene,
            settings,
            wall,
            accum,
            schedule,
        } = inputs;
        debug_assert_eq!([accum.width, accum.height], [settings.width, band.rows]);
        let params = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("trace params"),
                contents: bytemuck::bytes_of(&GpuTraceParams::for_band(
                    kernel,
                    scene,
                    settings,
                    wall,
                    schedule.is_some(),
                    band,
                )),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
        let wall_buf = wall_table_buffer(ctx, "trace wall tiles", wall);
        let dummy = || {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("trace: no list"),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        let (list_owned, args_owned);
        let (list, args) = match schedule {
            Some((l, a)) => (l, a),
            None => {
                list_owned = dummy();
                args_owned = dummy();
                (&list_owned, &args_owned)
            }
        };
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace frame"),
            layout: &kernel.pipeline.get_bind_group_layout(1),
            entries: &[
                entry(0, &params),
                entry(1, &accum.accum),
                entry(2, &accum.counts),
                entry(3, list),
                entry(4, args),
                entry(5, &accum.stats),
                entry(6, &wall_buf),
            ],
        });
        let launch = kernel.full_frame_launch(settings.width, band.rows);
        Self {
            #[cfg(feature = "kernel-lab")]
            split: kernel.split_run(ctx, schedule.is_none(), launch.0, settings.max_depth),
            kernel: kernel.clone(),
            params,
            bind,
            args: schedule.map(|(_, a)| a.clone()),
            groups: launch.1,
            wall: wall.cloned(),
            wall_table: wall_buf,
            band,
        }
    }

    /// Replaces the wall camera by `wall` (a moved eye: the same display, image size and tile
    /// count) before the next submit: its tile table and its eye in the parameters. Returns
    /// `false`, changing nothing, where this run has no wall camera or `wall` has another
    /// tile count.
    pub fn set_wall(
        &mut self,
        ctx: &GpuContext,
        scene: &PackedScene,
        settings: &TraceSettings,
        wall: &WallCamera,
    ) -> bool {
        if !replace_wall(ctx, &self.wall_table, &mut self.wall, wall) {
            return false;
        }
        self.set_settings(ctx, scene, settings);
        true
    }

    /// Rewrites the parameters (a new camera, seed or depth) before the next submit.
    pub fn set_settings(&self, ctx: &GpuContext, scene: &PackedScene, settings: &TraceSettings) {
        let p = GpuTraceParams::for_band(
            &self.kernel,
            scene,
            settings,
            self.wall.as_ref(),
            self.args.is_some(),
            self.band,
        );
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&p));
        #[cfg(feature = "kernel-lab")]
        if let Some(split) = &self.split {
            split.max_depth.set(settings.max_depth);
        }
    }

    /// Records one iteration (one path per pixel, or per listed pixel).
    pub fn record(
        &self,
        enc: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        timer: Option<(&PassTimer, u32)>,
    ) {
        self.record_with(enc, scene, timer.map(|(t, i)| t.writes(i)));
    }

    /// [`Self::record`] with these timestamp writes (a part of a split pass:
    /// [`PassTimer::writes_part`]).
    pub fn record_with(
        &self,
        enc: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("trace/path"),
            timestamp_writes,
        });
        pass.set_pipeline(&self.kernel.pipeline);
        pass.set_bind_group(0, &scene.bind, &[]);
        pass.set_bind_group(1, &self.bind, &[]);
        if let Some(args) = &self.args {
            pass.dispatch_workgroups_indirect(args, 0);
            return;
        }
        #[cfg(feature = "kernel-lab")]
        if let Some(split) = &self.split {
            split.record(&mut pass);
            return;
        }
        pass.dispatch_workgroups(self.groups[0], self.groups[1], 1);
    }
}
