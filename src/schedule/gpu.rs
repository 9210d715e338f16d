//! Dispatch of the scheduling kernels, the GPU twin of [`super::schedule_cpu`].
//!
//! One iteration is one compute pass of two dispatches, recorded by [`ScheduleRun::record`]
//! into the frame's encoder ahead of the tracer:
//!
//! 1. `shaders/schedule/compact.wgsl` — mask and compaction: one workgroup per 32 × 32 block,
//!    Bernoulli decisions, a workgroup prefix sum, one `atomicAdd` per block to reserve its
//!    output range (see that file for why not a decoupled scan).
//! 2. `shaders/schedule/args.wgsl` — one thread turns the count into the tracer's indirect
//!    dispatch grid and resets the counter to 0 for the next iteration.
//!
//! Nothing is read back: the tracer is dispatched with `dispatch_workgroups_indirect`.
//!
//! # Buffers the tracer reads
//!
//! * [`ScheduleRun::list`] — `array<u32>`, capacity `width × height`: the selected pixel
//!   indices `y * width + x`; entries `0..count` are valid.
//! * [`ScheduleRun::args`] — `array<u32, 4>` with `INDIRECT | STORAGE` usage: `(gx, gy, 1)`
//!   for `dispatch_workgroups_indirect(args, 0)`, then `count`. The grid is 2D because
//!   3840 × 2160 / 64 = 129 600 workgroups exceeds the 65 535 per dimension; gx·gy workgroups
//!   of the tracer's size cover `count` (see [`super::indirect_grid`]). Bind it read-only
//!   (indirect and read-only storage may share a dispatch) and index as
//!
//! ```wgsl
//! @group(0) @binding(0) var<storage, read> schedule_args: array<u32, 4>;
//! @group(0) @binding(1) var<storage, read> schedule_list: array<u32>;
//!
//! @compute @workgroup_size(64) // = ScheduleConfig::trace_workgroup_size
//! fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
//!     let i = (wg.y * schedule_args[0] + wg.x) * 64u + li;
//!     if i >= schedule_args[3] { return; }
//!     let pixel = schedule_list[i];
//!     // … trace one path for `pixel` and accumulate it …
//! }
//! ```
//!
//! # Per-iteration parameters
//!
//! The iteration number and seed change every iteration. `queue.write_buffer` would apply
//! the last value written before a submit to every iteration recorded in it (writes are
//! staged ahead of the submit's command buffers), so a frame that records several iterations
//! in one encoder, or a benchmark's repetitions, would all draw the same coin flips. Instead
//! [`ScheduleRun::record`] copies a 48-byte buffer with this iteration's parameters into the
//! uniform inside the encoder, ordered with the passes around it. The copy is one small
//! transfer per iteration; [`ScheduleRun::params`] exposes the uniform so the tracer can read
//! the same iteration and seed instead of uploading its own.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::{Layout, Order, ScheduleError, validate_p_min};
use crate::gpu::{GpuContext, GpuError, PassTimer};

/// Decision functions alone (pcg4d, probability, selected, the pixel orders), for kernels and
/// tests that need the scheduler's per-pixel rule.
pub const SELECT_WGSL: &str = concat!(
    include_str!("../../shaders/random.wgsl"),
    "\n",
    include_str!("../../shaders/schedule/select.wgsl")
);

/// The mask-and-compaction kernel (WGSL has no includes: the shared files come first).
pub const COMPACT_WGSL: &str = concat!(
    include_str!("../../shaders/random.wgsl"),
    "\n",
    include_str!("../../shaders/schedule/select.wgsl"),
    "\n",
    include_str!("../../shaders/schedule/compact.wgsl")
);

/// The indirect-arguments kernel.
pub const ARGS_WGSL: &str = include_str!("../../shaders/schedule/args.wgsl");

/// The block-masks kernel: the coherent schedule as each block's selected slots.
pub const MASKS_WGSL: &str = concat!(
    include_str!("../../shaders/random.wgsl"),
    "\n",
    include_str!("../../shaders/schedule/select.wgsl"),
    "\n",
    include_str!("../../shaders/schedule/masks.wgsl")
);

/// Mirrors `Params` in shaders/schedule/compact.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuParams {
    pub size: [u32; 2],
    pub tiles_x: u32,
    pub order: u32,
    pub iteration: u32,
    pub seed: u32,
    pub p_min: f32,
    pub scatter_half_bits: u32,
    /// 1: only pixels whose bit is set in the shown mask may be selected (the wall camera's
    /// display shows them, DESIGN.md §11); 0: every pixel.
    pub masked: u32,
    /// The image's index of this schedule's pixel 0 (a frame split into bands of rows): the
    /// coin flips are drawn for image pixel `pixel_base + p`, so every band flips the whole
    /// image's coins.
    pub pixel_base: u32,
    pub _pad: [u32; 2],
}

/// Mirrors `ArgsParams` in shaders/schedule/args.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuArgsParams {
    pub workgroup_size: u32,
    pub max_per_dim: u32,
    pub max_groups: u32,
    pub _pad: u32,
}

/// What a [`ScheduleRun`] schedules.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScheduleConfig {
    pub width: u32,
    pub height: u32,
    /// Lowest sampling probability, in [0, 1] (paper preset 0).
    pub p_min: f32,
    pub order: Order,
    /// Threads per workgroup of the tracer that consumes the list (the indirect grid's unit).
    pub trace_workgroup_size: u32,
    /// The most workgroups the tracer's launch may have (0: a thread an entry, the kernel
    /// raygun ships): a regenerating tracer's cap (the kernel lab's `+regenG`,
    /// [`crate::trace::gpu::TraceKernel::max_list_groups`]), whose threads trace several
    /// entries.
    pub trace_max_groups: u32,
}

/// The compiled scheduling kernels.
pub struct ScheduleKernel {
    compact: wgpu::ComputePipeline,
    args: wgpu::ComputePipeline,
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// The kernels' shown mask (a stand-in of 16 bytes where there is none: a binding may not be
/// empty, and `Params.masked` = 0 leaves it unread).
fn shown_buffer(ctx: &GpuContext, shown: Option<&[u32]>) -> wgpu::Buffer {
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("schedule shown mask"),
            contents: bytemuck::cast_slice(shown.unwrap_or(&[0u32; 4])),
            usage: wgpu::BufferUsages::STORAGE,
        })
}

/// What the kernels are recorded with besides the iteration and seed: the order, the
/// probability floor, whether a shown mask applies, and the band's first pixel.
#[derive(Clone, Copy, Debug)]
struct Recorded {
    order: Order,
    p_min: f32,
    masked: bool,
    pixel_base: u32,
}

/// The kernels' parameters of one iteration over `layout`.
fn gpu_params(layout: &Layout, recorded: Recorded, iteration: u32, seed: u32) -> GpuParams {
    let Recorded {
        order,
        p_min,
        masked,
        pixel_base,
    } = recorded;
    GpuParams {
        size: [layout.width, layout.height],
        tiles_x: layout.tiles[0],
        order: order.code(),
        iteration,
        seed,
        p_min,
        scatter_half_bits: layout.scatter_half_bits,
        masked: u32::from(masked),
        pixel_base,
        _pad: [0; 2],
    }
}

impl ScheduleKernel {
    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        Self {
            compact: ctx.compute_pipeline("schedule/compact", COMPACT_WGSL, "main"),
            args: ctx.compute_pipeline("schedule/args", ARGS_WGSL, "main"),
        }
    }

    /// Binds the kernels to a DGI buffer (`width × height` f32 with `STORAGE` usage, e.g.
    /// [`crate::roi::gpu::DgiRun::output`]) and allocates the list, counter and arguments.
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        dgi: &wgpu::Buffer,
        config: &ScheduleConfig,
    ) -> Result<ScheduleRun, ScheduleError> {
        self.prepare_shown(ctx, dgi, None, config)
    }

    /// [`Self::prepare`] with a shown mask (bit `p % 32` of word `p / 32` for pixel `p`): pixels
    /// whose bit is clear get probability 0, as in [`super::schedule_cpu_shown`].
    pub fn prepare_shown(
        &self,
        ctx: &GpuContext,
        dgi: &wgpu::Buffer,
        shown: Option<&[u32]>,
        config: &ScheduleConfig,
    ) -> Result<ScheduleRun, ScheduleError> {
        self.prepare_band(ctx, dgi, shown, config, 0)
    }

    /// [`Self::prepare_shown`] for a band of an image split to fit the adapter's bindings:
    /// `config` gives the band's size, `dgi`, `shown` and the list are the band's own (pixel
    /// `p` of them is image pixel `pixel_base + p`), and the coin flips are the whole image's.
    pub fn prepare_band(
        &self,
        ctx: &GpuContext,
        dgi: &wgpu::Buffer,
        shown: Option<&[u32]>,
        config: &ScheduleConfig,
        pixel_base: u32,
    ) -> Result<ScheduleRun, ScheduleError> {
        let p_min = validate_p_min(config.p_min)?;
        let layout = Layout::new(config.width, config.height)?;
        super::compact::check_shown(shown, &layout)?;
        let mask = shown_buffer(ctx, shown);
        let list_bytes = u64::from(layout.pixels()) * 4;
        if dgi.size() < list_bytes || !dgi.usage().contains(wgpu::BufferUsages::STORAGE) {
            return Err(ScheduleError::DgiBuffer {
                bytes: dgi.size(),
                needed: list_bytes,
                storage: dgi.usage().contains(wgpu::BufferUsages::STORAGE),
            });
        }
        ctx.check_binding("schedule list", list_bytes)?;
        let list = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("schedule list"),
            size: list_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        // wgpu zero-initialises buffers; afterwards the args kernel resets it every iteration.
        let counter = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("schedule counter"),
            size: 4,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let params = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("schedule params"),
            size: size_of::<GpuParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("schedule/compact"),
            layout: &self.compact.get_bind_group_layout(0),
            entries: &[
                entry(0, &params),
                entry(1, dgi),
                entry(2, &list),
                entry(3, &counter),
                entry(4, &mask),
            ],
        });
        let args = self.prepare_args(
            ctx,
            &counter,
            config.trace_workgroup_size,
            config.trace_max_groups,
            layout.pixels(),
        )?;
        Ok(ScheduleRun {
            device: ctx.device.clone(),
            compact: self.compact.clone(),
            bind,
            params,
            list,
            args,
            layout,
            order: config.order,
            p_min,
            masked: shown.is_some(),
            pixel_base,
        })
    }

    /// The arguments pass alone, reading the count from any `counter` buffer (a u32 with
    /// `STORAGE` usage, reset to 0 by every run) for up to `max_count` entries, for a tracer of
    /// `workgroup_size` threads a group launching at most `max_groups` groups (0: no cap).
    /// [`Self::prepare`] uses it for the list's counter; tests feed it synthetic counts.
    pub fn prepare_args(
        &self,
        ctx: &GpuContext,
        counter: &wgpu::Buffer,
        workgroup_size: u32,
        max_groups: u32,
        max_count: u32,
    ) -> Result<ArgsRun, ScheduleError> {
        let max_threads = ctx.limits.max_compute_invocations_per_workgroup;
        if workgroup_size == 0 || workgroup_size > max_threads {
            return Err(ScheduleError::WorkgroupSize {
                size: workgroup_size,
                max: max_threads,
            });
        }
        let max_per_dim = ctx.limits.max_compute_workgroups_per_dimension;
        let groups = u64::from(max_count).div_ceil(u64::from(workgroup_size));
        if groups > u64::from(max_per_dim).pow(2) {
            return Err(ScheduleError::TooManyGroups {
                count: max_count,
                workgroup_size,
                max_per_dim,
            });
        }
        let uniform = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("schedule/args params"),
                contents: bytemuck::bytes_of(&GpuArgsParams {
                    workgroup_size,
                    max_per_dim,
                    max_groups,
                    _pad: 0,
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let args = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("schedule args"),
            size: 16,
            usage: wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("schedule/args"),
            layout: &self.args.get_bind_group_layout(0),
            entries: &[entry(0, &uniform), entry(1, counter), entry(2, &args)],
        });
        Ok(ArgsRun {
            pipeline: self.args.clone(),
            bind,
            args,
            workgroup_size,
        })
    }
}

/// A prepared arguments pass (see [`ScheduleKernel::prepare_args`]).
pub struct ArgsRun {
    pipeline: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    args: wgpu::Buffer,
    workgroup_size: u32,
}

impl ArgsRun {
    /// Records the one-thread dispatch into an open pass.
    pub fn dispatch(&self, pass: &mut wgpu::ComputePass<'_>) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind, &[]);
        pass.dispatch_workgroups(1, 1, 1);
    }

    /// Records the dispatch in a pass of its own.
    pub fn record(&self, enc: &mut wgpu::CommandEncoder) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("schedule/args"),
            timestamp_writes: None,
        });
        self.dispatch(&mut pass);
    }

    /// `(gx, gy, 1, count)`.
    #[must_use]
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.args
    }

    #[must_use]
    pub fn workgroup_size(&self) -> u32 {
        self.workgroup_size
    }

    /// Reads `[gx, gy, gz, count]` back (tests and benchmarks; the frame never does).
    pub fn read(&self, ctx: &GpuContext) -> Result<[u32; 4], GpuError> {
        let v: Vec<u32> = ctx.read_buffer(&self.args)?;
        Ok([v[0], v[1], v[2], v[3]])
    }
}

/// A prepared schedule: record one iteration per [`Self::record`], as often as needed.
pub struct ScheduleRun {
    device: wgpu::Device,
    compact: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    params: wgpu::Buffer,
    list: wgpu::Buffer,
    args: ArgsRun,
    layout: Layout,
    order: Order,
    p_min: f32,
    masked: bool,
    pixel_base: u32,
}

impl ScheduleRun {
    /// Records iteration `iteration` with `seed`: the parameter upload, then one compute pass
    /// with the compaction and the arguments dispatch (the timer, if any, measures that pass as
    /// its pass number `.1`). Afterwards [`Self::list`] and [`Self::args`] hold this
    /// iteration's schedule for every pass recorded after it.
    pub fn record(
        &self,
        enc: &mut wgpu::CommandEncoder,
        iteration: u32,
        seed: u32,
        timer: Option<(&PassTimer, u32)>,
    ) {
        self.record_with(enc, iteration, seed, timer.map(|(t, i)| t.writes(i)));
    }

    /// [`Self::record`] with these timestamp writes (a part of a split pass:
    /// [`PassTimer::writes_part`]).
    pub fn record_with(
        &self,
        enc: &mut wgpu::CommandEncoder,
        iteration: u32,
        seed: u32,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let upload = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("schedule params upload"),
                contents: bytemuck::bytes_of(&self.gpu_params(iteration, seed)),
                usage: wgpu::BufferUsages::COPY_SRC,
            });
        enc.copy_buffer_to_buffer(&upload, 0, &self.params, 0, self.params.size());
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("schedule"),
            timestamp_writes,
        });
        pass.set_pipeline(&self.compact);
        pass.set_bind_group(0, &self.bind, &[]);
        pass.dispatch_workgroups(self.layout.tiles[0], self.layout.tiles[1], 1);
        // wgpu orders dispatches in a pass that write the same storage buffer (the counter).
        self.args.dispatch(&mut pass);
    }

    /// The kernel's parameters for one iteration.
    #[must_use]
    pub fn gpu_params(&self, iteration: u32, seed: u32) -> GpuParams {
        let recorded = Recorded {
            order: self.order,
            p_min: self.p_min,
            masked: self.masked,
            pixel_base: self.pixel_base,
        };
        gpu_params(&self.layout, recorded, iteration, seed)
    }

    /// Changes p_min for the iterations recorded from now on.
    pub fn set_p_min(&mut self, p_min: f32) -> Result<(), ScheduleError> {
        self.p_min = validate_p_min(p_min)?;
        Ok(())
    }

    /// The selected pixel indices (`array<u32>`, capacity width × height).
    #[must_use]
    pub fn list(&self) -> &wgpu::Buffer {
        &self.list
    }

    /// `(gx, gy, 1, count)`: the tracer's indirect dispatch and the list's length.
    #[must_use]
    pub fn args(&self) -> &wgpu::Buffer {
        self.args.buffer()
    }

    /// The uniform with the iteration's `GpuParams` (size, iteration, seed, …).
    #[must_use]
    pub fn params(&self) -> &wgpu::Buffer {
        &self.params
    }

    #[must_use]
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    #[must_use]
    pub fn order(&self) -> Order {
        self.order
    }

    #[must_use]
    pub fn trace_workgroup_size(&self) -> u32 {
        self.args.workgroup_size()
    }

    /// Reads back `[gx, gy, gz, count]`.
    pub fn read_args(&self, ctx: &GpuContext) -> Result<[u32; 4], GpuError> {
        self.args.read(ctx)
    }

    /// Reads back the list's valid entries (tests and benchmarks; the frame never does).
    pub fn read_list(&self, ctx: &GpuContext) -> Result<Vec<u32>, GpuError> {
        let count = self.read_args(ctx)?[3] as usize;
        let mut list: Vec<u32> = ctx.read_buffer(&self.list)?;
        list.truncate(count);
        Ok(list)
    }
}

/// The coherent schedule of a whole image drawn on the GPU as every block's selected slots
/// ([`super::SlotMask`], 128 bytes a block) and read back: the GPU twin of
/// [`super::schedule_cpu_block_masks`] over every block. A cluster's GPU rank draws its
/// iterations so (DESIGN.md §12) instead of a share on its CPU and the others' shares from the
/// link. The DGI lives on the GPU ([`Self::set_dgi`], once per ROI).
pub struct BlockMasksRun {
    pipeline: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    params: wgpu::Buffer,
    dgi: wgpu::Buffer,
    masks: wgpu::Buffer,
    layout: Layout,
    p_min: f32,
    masked: bool,
}

impl BlockMasksRun {
    /// A `width × height` image's draw with `p_min` (and the shown mask, as
    /// [`ScheduleKernel::prepare_shown`]). Fails where the DGI does not fit one of the
    /// adapter's bindings (the caller draws on the CPU then).
    pub fn new(
        ctx: &GpuContext,
        width: u32,
        height: u32,
        p_min: f32,
        shown: Option<&[u32]>,
    ) -> Result<Self, ScheduleError> {
        let p_min = validate_p_min(p_min)?;
        let layout = Layout::new(width, height)?;
        super::compact::check_shown(shown, &layout)?;
        let dgi_bytes = u64::from(layout.pixels()) * 4;
        let mask_bytes = u64::from(layout.blocks()) * u64::from(super::BLOCK_PIXELS / 8);
        ctx.check_binding("schedule masks' DGI", dgi_bytes)?;
        ctx.check_binding("schedule masks", mask_bytes)?;
        let pipeline = ctx.compute_pipeline("schedule/masks", MASKS_WGSL, "main");
        let shown_buffer = shown_buffer(ctx, shown);
        let dgi = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("schedule masks' DGI"),
            size: dgi_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let masks = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("schedule masks"),
            size: mask_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let params = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("schedule masks' params"),
            size: size_of::<GpuParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("schedule/masks"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                entry(0, &params),
                entry(1, &dgi),
                entry(2, &masks),
                entry(3, &shown_buffer),
            ],
        });
        Ok(Self {
            pipeline,
            bind,
            params,
            dgi,
            masks,
            layout,
            p_min,
            masked: shown.is_some(),
        })
    }

    /// The DGI the next draws use (`width × height` values).
    pub fn set_dgi(&self, ctx: &GpuContext, dgi: &[f32]) {
        assert_eq!(
            dgi.len(),
            self.layout.pixels() as usize,
            "one DGI value a pixel"
        );
        ctx.queue
            .write_buffer(&self.dgi, 0, bytemuck::cast_slice(dgi));
    }

    /// Iteration `iteration`'s draw with `seed`: every block's selected slots, blocks in index
    /// order.
    pub fn masks(
        &self,
        ctx: &GpuContext,
        iteration: u32,
        seed: u32,
    ) -> Result<Vec<super::SlotMask>, GpuError> {
        let recorded = Recorded {
            order: Order::Coherent,
            p_min: self.p_min,
            masked: self.masked,
            pixel_base: 0,
        };
        let params = gpu_params(&self.layout, recorded, iteration, seed);
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("schedule masks"),
            });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("schedule/masks"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind, &[]);
            pass.dispatch_workgroups(self.layout.tiles[0], self.layout.tiles[1], 1);
        }
        ctx.queue.submit([enc.finish()]);
        let words: Vec<u32> = ctx.read_buffer(&self.masks)?;
        Ok(words
            .chunks_exact((super::BLOCK_PIXELS / 32) as usize)
            .map(|w| w.try_into().expect("a block's words"))
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::wgsl::{assert_same_layout, validated};
    use wgpu::naga;

    /// The kernels parse and validate without a GPU, and the structs shared with Rust have the
    /// same size on both sides.
    #[test]
    fn kernels_validate_and_shared_structs_match_their_rust_twins() {
        validated("select.wgsl", SELECT_WGSL);
        let compact = validated("compact.wgsl", COMPACT_WGSL);
        assert_same_layout(
            &compact,
            "Params",
            &crate::rust_layout!(GpuParams; size, tiles_x, order, iteration, seed, p_min,
                scatter_half_bits, masked, pixel_base, _pad),
        );
        let masks = validated("masks.wgsl", MASKS_WGSL);
        assert_same_layout(
            &masks,
            "Params",
            &crate::rust_layout!(GpuParams; size, tiles_x, order, iteration, seed, p_min,
                scatter_half_bits, masked, pixel_base, _pad),
        );
        let args = validated("args.wgsl", ARGS_WGSL);
        assert_same_layout(
            &args,
            "ArgsParams",
            &crate::rust_layout!(GpuArgsParams; workgroup_size, max_per_dim, max_groups, _pad),
        );
    }

    /// The kernel's stream constant and tile shape are the CPU twin's.
    #[test]
    fn kernel_constants_match_the_cpu_twin() {
        let m = validated("compact.wgsl", COMPACT_WGSL);
        let constant = |name: &str| match crate::gpu::wgsl::const_literal(&m, name) {
            naga::Literal::U32(v) => v,
            l => panic!("{name} is {l:?}, not a u32 literal"),
        };
        assert_eq!(constant("STREAM_SCHEDULE"), crate::random::stream::SCHEDULE);
        assert_eq!(constant("TILE_EDGE"), super::super::TILE_EDGE);
        assert_eq!(constant("THREADS"), super::super::BLOCK_THREADS);
        assert_eq!(constant("SLOTS"), super::super::SLOTS_PER_THREAD);
        let wg = m
            .entry_points
            .iter()
            .find(|e| e.name == "main")
            .expect("compact.wgsl has main")
            .workgroup_size;
        assert_eq!(wg, [super::super::BLOCK_THREADS, 1, 1]);
    }
}
