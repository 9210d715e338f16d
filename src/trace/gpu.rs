//! Dispatch of `shaders/trace/*.wgsl`, the GPU twin of [`super::path::render_cpu`].
//!
//! Bind group 0 is the scene ([`GpuScene`], uploaded once), bind group 1 the frame: the
//! parameters, the accumulation ([`GpuAccum`]) and, for guided rendering, the scheduler's pixel
//! list and its indirect-dispatch arguments `(x, y, z, count)`.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::accum::Accumulation;
use super::pack::PackedScene;
use super::path::TraceSettings;
use super::wall::WallCamera;
pub use crate::gpu::variant::{STACK_ENTRIES, TraceStack, TraceVariant};
use crate::gpu::{Band, GpuContext, GpuError, PassTimer};

/// The kernel source (WGSL has no includes).
pub const TRACE_WGSL: &str = concat!(
    include_str!("../../shaders/random.wgsl"),
    "\n",
    include_str!("../../shaders/trace/bvh.wgsl"),
    "\n",
    include_str!("../../shaders/trace/shading.wgsl"),
    "\n",
    include_str!("../../shaders/trace/path.wgsl")
);

/// Threads per workgroup of the trace kernel (`WORKGROUP` in path.wgsl), unless its variant
/// says otherwise ([`TraceVariant::workgroup`]).
pub const WORKGROUP: u32 = crate::gpu::variant::DEFAULT_WORKGROUP;

/// A cluster rank's owned sums and the rays per block it traced: `shaders/trace/accum.wgsl`.
pub const ACCUM_WGSL: &str = include_str!("../../shaders/trace/accum.wgsl");
/// Vec4s of the stand-in wall table when there is no wall camera (a binding is never empty).
const TILE_VEC4S_MIN: usize = 4;
/// The most workgroups in one dimension of a dispatch.
const MAX_GROUPS_X: u32 = 65_535;

/// Mirrors `Params` in shaders/trace/path.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuTraceParams {
    pub size: [u32; 2],
    pub count: u32,
    pub mode: u32,
    pub seed: u32,
    pub max_depth: u32,
    pub light_count: u32,
    pub groups_x: u32,
    pub env_size: [u32; 2],
    pub env_marginal: u32,
    pub env_conditional: u32,
    pub env_constant: [f32; 3],
    pub env_select: f32,
    pub cam_pos: [f32; 3],
    pub tan_half_y: f32,
    pub cam_fwd: [f32; 3],
    pub aspect: f32,
    pub cam_right: [f32; 3],
    pub node_count: u32,
    pub cam_up: [f32; 3],
    /// The wall camera's tile count (0: pinhole or orthographic).
    pub wall_tiles: u32,
    pub features: u32,
    pub extras_offset: u32,
    pub punctual_count: u32,
    pub punct_select: f32,
    pub ortho_half_y: f32,
    /// The band of rows this dispatch covers ([`Band`]): its buffers hold `size.x × rows`
    /// pixels from image row `row0`.
    pub row0: u32,
    pub rows: u32,
    /// Full frames of a regenerating variant: the threads launched, each tracing the paths of
    /// slots `linear`, `linear + stride`, …; 0: a thread a path.
    pub stride: u32,
}

/// The full-frame grid: threads (8 × 8 tiles, padded) and a 2D grid of `workgroup`-thread
/// groups within the per-dimension dispatch limit.
#[must_use]
pub fn full_frame_grid(width: u32, height: u32, workgroup: u32) -> (u32, [u32; 2]) {
    let threads = width.div_ceil(8) * height.div_ceil(8) * 64;
    let groups = threads.div_ceil(workgroup);
    let gx = groups.min(MAX_GROUPS_X);
    (threads, [gx, groups.div_ceil(gx)])
}

/// A full frame's launch for `variant`: the frame's threads (one a pixel slot, 8 × 8 tiles
/// padded), the workgroup grid dispatched, and the stride between a thread's paths — 0 where
/// each thread traces one path, the grid's thread count where a regenerating variant
/// ([`TraceVariant::regen`]) launches fewer threads than paths.
#[must_use]
pub fn full_frame_launch(width: u32, height: u32, variant: TraceVariant) -> (u32, [u32; 2], u32) {
    let (threads, [gx, gy]) = full_frame_grid(width, height, variant.workgroup);
    let groups = gx * gy;
    if variant.regen == 0 || variant.regen >= groups {
        return (threads, [gx, gy], 0);
    }
    let rx = variant.regen.min(MAX_GROUPS_X);
    let ry = variant.regen.div_ceil(rx);
    if rx * ry >= groups {
        // Rounded up to a 2D grid, as many groups as the frame needs: a thread a path.
        return (threads, [gx, gy], 0);
    }
    (threads, [rx, ry], rx * ry * variant.workgroup)
}

impl GpuTraceParams {
    /// The parameters with `wall`'s eye and tile count when given, for the kernel compiled as
    /// `variant`.
    #[must_use]
    pub fn with_wall(
        scene: &PackedScene,
        s: &TraceSettings,
        wall: Option<&WallCamera>,
        list_mode: bool,
        variant: TraceVariant,
    ) -> Self {
        Self::for_band(scene, s, wall, list_mode, Band::whole(s.height), variant)
    }

    /// [`Self::with_wall`] for the rows of `band` alone.
    #[must_use]
    pub fn for_band(
        scene: &PackedScene,
        s: &TraceSettings,
        wall: Option<&WallCamera>,
        list_mode: bool,
        band: Band,
        variant: TraceVariant,
    ) -> Self {
        let (threads, [gx, _], stride) = full_frame_launch(s.width, band.rows, variant);
        // A list is dispatched from its count, a thread a path.
        let stride = if list_mode { 0 } else { stride };
        let c = &s.camera;
        Self {
            size: [s.width, s.height],
            count: threads,
            mode: u32::from(list_mode),
            seed: s.seed,
            max_depth: s.max_depth,
            light_count: scene.light_count,
            groups_x: gx,
            env_size: scene.env_size,
            env_marginal: scene.env_marginal,
            env_conditional: scene.env_conditional,
            env_constant: scene.env_constant.to_array(),
            env_select: scene.env_select,
            cam_pos: wall.map_or(c.position, |w| w.eye).to_array(),
            tan_half_y: c.tan_half_y,
            cam_fwd: c.forward.to_array(),
            aspect: c.aspect,
            cam_right: c.right.to_array(),
            node_count: scene.bvh.cwbvh.nodes.len() as u32,
            cam_up: c.up.to_array(),
            wall_tiles: wall.map_or(0, |w| w.tiles.len() as u32),
            features: scene.features,
            extras_offset: scene.extras_offset,
            punctual_count: scene.punctual_count,
            punct_select: scene.punct_select,
            ortho_half_y: c.ortho_half_y,
            row0: band.row0,
            rows: band.rows,
            stride,
        }
    }
}

/// The kernel's source for `variant`: `TRACE_WGSL` with the stack's declaration and accesses
/// moved, the workgroup's size set, and for a `+vote` variant the triangle postponing's
/// percentage set and its lane count a subgroup ballot.
#[must_use]
pub fn kernel_source(variant: TraceVariant) -> std::borrow::Cow<'static, str> {
    const MODULE: &str = "var<private> stack: array<vec2<u32>, STACK_SIZE>;\n";
    const LOCAL: &str = "    var stack: array<vec2<u32>, STACK_SIZE>;\n";
    const FIRST: &str = "    var sp = 0u;\n";
    const PUSH: &str = "stack[sp] = current;";
    const POP: &str = "current = stack[sp];";
    const SIZE: &str = "const WORKGROUP: u32 = 64u;";
    const REGENERATE: &str = "const REGENERATE: bool = false;";
    const POSTPONE: &str = "const POSTPONE: u32 = 0u;";
    const LANES: &str = "fn lanes_voting(yes: bool) -> u32 {\n    return u32(yes);\n}";
    const BALLOT: &str = "fn lanes_voting(yes: bool) -> u32 {\n    let b = subgroupBallot(yes);\n    \
                          return countOneBits(b.x) + countOneBits(b.y) + countOneBits(b.z) + \
                          countOneBits(b.w);\n}";
    let once = |s: &str, from: &str, to: &str| {
        assert_eq!(
            s.matches(from).count(),
            1,
            "trace kernel: {from:?} not found once"
        );
        s.replacen(from, to, 1)
    };
    let mut s = std::borrow::Cow::Borrowed(TRACE_WGSL);
    if variant.workgroup != WORKGROUP {
        let size = format!("const WORKGROUP: u32 = {}u;", variant.workgroup);
        s = once(&s, SIZE, &size).into();
    }
    if variant.regen != 0 {
        s = once(&s, REGENERATE, "const REGENERATE: bool = true;").into();
    }
    if variant.vote != 0 {
        let percent = format!("const POSTPONE: u32 = {}u;", variant.vote);
        s = once(&s, POSTPONE, &percent).into();
        s = once(&s, LANES, BALLOT).into();
    }
    match variant.stack {
        TraceStack::Private => s,
        TraceStack::Function => {
            let s = once(&s, MODULE, "");
            once(&s, FIRST, &format!("{LOCAL}{FIRST}")).into()
        }
        TraceStack::Workgroup => {
            let s = once(&s, MODULE, "");
            let s = once(
                &s,
                PUSH,
                "trace_stack[sp * WORKGROUP + trace_lane] = current;",
            );
            let s = once(
                &s,
                POP,
                "current = trace_stack[sp * WORKGROUP + trace_lane];",
            );
            (s + "\nvar<workgroup> trace_stack: array<vec2<u32>, STACK_SIZE * WORKGROUP>;\n").into()
        }
    }
}

/// The compiled kernel.
#[derive(Clone)]
pub struct TraceKernel {
    pipeline: wgpu::ComputePipeline,
    variant: TraceVariant,
    /// The wavefront split's kernels, for a `+split` variant.
    split: Option<SplitKernels>,
}

/// The wavefront split's three entry points (`split_start`, `split_extend`, `split_shade` in
/// path.wgsl), sharing `trace`'s bind groups 0 and 1 (one explicit layout for all four).
#[derive(Clone)]
struct SplitKernels {
    start: wgpu::ComputePipeline,
    extend: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
    /// Bind group 2: a chunk's path states, closest hits, [`GpuSplitParams`], and its two
    /// queues of live paths with their lengths.
    chunk_layout: wgpu::BindGroupLayout,
}

/// Mirrors `SplitParams` in shaders/trace/path.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuSplitParams {
    pub first_job: u32,
    pub jobs: u32,
    pub groups_x: u32,
    /// 0: the first bounce (the chunk's paths, the live ones queued in queue 1); 1: queue 1
    /// to queue 0; 2: queue 0 to queue 1.
    pub phase: u32,
}

/// GPU bytes a path of the wavefront split holds while its chunk is traced: its state
/// (`PathState`, 64), its closest hit (`Hit`, 16) and its place in the two queues (4 each).
pub const SPLIT_PATH_BYTES: u64 = 88;

/// The paths a chunk of `variant`'s wavefront split holds for a full frame of `jobs` threads:
/// the variant's chunk, at most what one binding of `max_binding` bytes holds of path states
/// (64 bytes each), at most the frame's jobs (rounded up to 64), at least 64.
#[must_use]
pub fn split_chunk(variant: TraceVariant, jobs: u32, max_binding: u64) -> u32 {
    let most = (max_binding / 64).min(u64::from(u32::MAX)) as u32 / 64 * 64;
    variant
        .split
        .min(most)
        .min(jobs.next_multiple_of(64))
        .max(64)
}

/// GPU bytes the wavefront split of `variant` holds for a full frame of `width × rows`
/// ([`SPLIT_PATH_BYTES`] a path of a chunk, [`split_chunk`]); 0 for a kernel without it.
#[must_use]
pub fn split_bytes(variant: TraceVariant, width: u32, rows: u32, max_binding: u64) -> u64 {
    if variant.split == 0 {
        return 0;
    }
    let (jobs, _, _) = full_frame_launch(width, rows, variant);
    SPLIT_PATH_BYTES * u64::from(split_chunk(variant, jobs, max_binding))
}

/// A compute-stage bind group layout of `entries`: `(binding, type)`.
fn bind_layout(
    ctx: &GpuContext,
    label: &str,
    entries: &[(u32, wgpu::BufferBindingType)],
) -> wgpu::BindGroupLayout {
    let entries: Vec<_> = entries
        .iter()
        .map(|&(binding, ty)| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect();
    ctx.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &entries,
        })
}

impl TraceKernel {
    /// The kernel in the variant `ctx` was made with ([`GpuContext::trace_variant`]),
    /// compiled once a device and variant ([`GpuContext::kept`]): every renderer needs it, and
    /// a driver takes longer to create its pipeline than to run many frames.
    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        let variant = ctx.trace_variant();
        ctx.kept(&format!("trace kernel {variant}"), || {
            Self::compile(ctx, variant)
        })
    }

    /// The kernel compiled as `variant`.
    fn compile(ctx: &GpuContext, variant: TraceVariant) -> Self {
        let label = format!("trace/path ({variant})");
        let source = kernel_source(variant);
        let module = if variant.unchecked {
            let desc = wgpu::ShaderModuleDescriptor {
                label: Some(&label),
                source: wgpu::ShaderSource::Wgsl(source),
            };
            // SAFETY: the kernel keeps every index in bounds itself — the stack is pushed only
            // below STACK_SIZE and popped only above 0, the pixel lists are read below their
            // counts, the scene's indices come from its own packing — and every loop ends
            // (bounded by the path depth, the stack and the sampling tables' sizes); tests
            // compare its renders with the checked kernel's bit for bit.
            unsafe {
                ctx.device
                    .create_shader_module_trusted(desc, wgpu::ShaderRuntimeChecks::unchecked())
            }
        } else {
            ctx.shader_module(&label, &source)
        };
        if variant.split == 0 {
            let pipeline = ctx.compute_pipeline_in(&module, &label, "trace");
            return Self {
                pipeline,
                variant,
                split: None,
            };
        }
        // The split's kernels take the bind groups made for `trace`: one explicit layout for
        // all four (a layout derived from one pipeline serves that pipeline alone).
        use wgpu::BufferBindingType as B;
        let read = B::Storage { read_only: true };
        let write = B::Storage { read_only: false };
        let scene = bind_layout(
            ctx,
            "trace scene",
            &[0, 1, 2, 3, 4, 5, 6, 7].map(|b| (b, read)),
        );
        let frame = bind_layout(
            ctx,
            "trace frame",
            &[
                (0, B::Uniform),
                (1, write),
                (2, write),
                (3, read),
                (4, read),
                (5, write),
                (6, read),
            ],
        );
        let chunk_layout = bind_layout(
            ctx,
            "trace split chunk",
            &[
                (0, write),
                (1, write),
                (2, B::Uniform),
                (3, write),
                (4, write),
            ],
        );
        let make = |entry: &str, groups: &[Option<&wgpu::BindGroupLayout>]| {
            let layout = ctx
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(&label),
                    bind_group_layouts: groups,
                    immediate_size: 0,
                });
            ctx.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(&label),
                    layout: Some(&layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
        };
        let three = [Some(&scene), Some(&frame), Some(&chunk_layout)];
        let split = SplitKernels {
            start: make("split_start", &three),
            extend: make("split_extend", &three),
            shade: make("split_shade", &three),
            chunk_layout: chunk_layout.clone(),
        };
        Self {
            pipeline: make("trace", &[Some(&scene), Some(&frame)]),
            variant,
            split: Some(split),
        }
    }

    /// Threads per workgroup (what the scheduler's indirect dispatch arguments count in).
    #[must_use]
    pub fn workgroup(&self) -> u32 {
        self.variant.workgroup
    }

    /// The most workgroups a list's launch may have (0: no cap): a regenerating variant's
    /// [`TraceVariant::regen`], which the scheduler's indirect arguments must respect.
    #[must_use]
    pub fn max_list_groups(&self) -> u32 {
        self.variant.regen
    }
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// `wall`'s tile table as a storage buffer ([`TILE_VEC4S`](super::wall::TILE_VEC4S) vec4s a
/// tile), or a stand-in without one (a binding is never empty).
fn wall_table_buffer(ctx: &GpuContext, label: &str, wall: Option<&WallCamera>) -> wgpu::Buffer {
    let table = wall.map_or_else(|| vec![[0.0f32; 4]; TILE_VEC4S_MIN], WallCamera::gpu_table);
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(&table),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        })
}

/// Writes `wall`'s tile table into `table` and makes it `current`, where `current` is a wall
/// camera with as many tiles (a moved eye); `false`, changing nothing, otherwise.
fn replace_wall(
    ctx: &GpuContext,
    table: &wgpu::Buffer,
    current: &mut Option<WallCamera>,
    wall: &WallCamera,
) -> bool {
    match current {
        Some(w) if w.tiles.len() == wall.tiles.len() => {}
        _ => return false,
    }
    ctx.queue
        .write_buffer(table, 0, bytemuck::cast_slice(&wall.gpu_table()));
    *current = Some(wall.clone());
    true
}

/// The scene on the GPU.
pub struct GpuScene {
    bind: wgpu::BindGroup,
    /// Bytes uploaded (for reports).
    pub bytes: u64,
}

impl GpuScene {
    /// Uploads `scene`; fails with a clear error when an array exceeds the adapter's limits or
    /// the scene's tree needs more than the kernel's traversal stack holds.
    pub fn upload(
        ctx: &GpuContext,
        kernel: &TraceKernel,
        scene: &PackedScene,
    ) -> Result<Self, GpuError> {
        // A walk whose stack is full drops what it would push: that geometry would be missed.
        let needs = scene.bvh.stack_entries();
        if needs > STACK_ENTRIES {
            return Err(GpuError::TraceStack {
                needs,
                holds: STACK_ENTRIES,
            });
        }
        let nodes: &[u8] = if scene.bvh.cwbvh.nodes.is_empty() {
            &[0u8; 80]
        } else {
            bytemuck::cast_slice(&scene.bvh.cwbvh.nodes)
        };
        let arrays: [(&'static str, &[u8]); 8] = [
            ("BVH nodes", nodes),
            ("BVH primitives", bytemuck::cast_slice(&scene.bvh.prims)),
            ("triangle shading data", bytemuck::cast_slice(&scene.shade)),
            ("materials", bytemuck::cast_slice(&scene.materials)),
            ("textures", bytemuck::cast_slice(&scene.texels)),
            ("emissive triangles", bytemuck::cast_slice(&scene.lights)),
            ("sampling distributions", bytemuck::cast_slice(&scene.dist)),
            ("environment map", bytemuck::cast_slice(&scene.env)),
        ];
        let mut bytes = 0;
        let mut buffers = Vec::with_capacity(arrays.len());
        for (what, data) in arrays {
            ctx.check_binding(what, data.len() as u64)?;
            bytes += data.len() as u64;
            buffers.push(
                ctx.device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some(what),
                        contents: data,
                        usage: wgpu::BufferUsages::STORAGE,
                    }),
            );
        }
        let entries: Vec<_> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| entry(i as u32, b))
            .collect();
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace scene"),
            layout: &kernel.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        Ok(Self { bind, bytes })
    }
}

/// The accumulation on the GPU (layout: `super::accum`), and the tracer's statistics.
pub struct GpuAccum {
    pub width: u32,
    pub height: u32,
    pub accum: wgpu::Buffer,
    pub counts: wgpu::Buffer,
    /// `[rays traced]` since the last [`GpuAccum::clear_stats`].
    pub stats: wgpu::Buffer,
}

impl GpuAccum {
    /// Zeroed buffers for a `width × height` image.
    pub fn new(ctx: &GpuContext, width: u32, height: u32) -> Result<Self, GpuError> {
        let n = u64::from(width) * u64::from(height);
        ctx.check_binding("accumulation (16 bytes per pixel)", n * 16)?;
        let make = |label, size| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        Ok(Self {
            width,
            height,
            accum: make("trace accum", n * 16),
            counts: make("trace counts", n * 4),
            stats: make("trace stats", 16),
        })
    }

    /// Records zeroing the statistics.
    pub fn clear_stats(&self, enc: &mut wgpu::CommandEncoder) {
        enc.clear_buffer(&self.stats, 0, None);
    }

    /// Rays traced since the statistics were last cleared (a read-back: for benchmarks).
    pub fn rays(&self, ctx: &GpuContext) -> Result<u64, GpuError> {
        Ok(u64::from(ctx.read_buffer::<u32>(&self.stats)?[0]))
    }

    /// Records clearing both buffers (a new render).
    pub fn clear(&self, enc: &mut wgpu::CommandEncoder) {
        enc.clear_buffer(&self.accum, 0, None);
        enc.clear_buffer(&self.counts, 0, None);
        enc.clear_buffer(&self.stats, 0, None);
    }

    /// Reads the accumulation back.
    pub fn read(&self, ctx: &GpuContext) -> Result<Accumulation, GpuError> {
        Ok(Accumulation {
            width: self.width,
            height: self.height,
            sum: ctx.read_buffer::<[f32; 4]>(&self.accum)?,
            count: ctx.read_buffer::<u32>(&self.counts)?,
        })
    }
}

/// A prepared trace dispatch over one accumulation, full frame or from a pixel list.
pub struct TraceRun {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bind: wgpu::BindGroup,
    /// The scheduler's `(x, y, z, count)` buffer in list mode.
    args: Option<wgpu::Buffer>,
    groups: [u32; 2],
    /// The kernel's variant (its workgroup's size, whether its launches regenerate).
    variant: TraceVariant,
    /// The wall camera the tile table was uploaded for (its eye goes into the parameters).
    wall: Option<WallCamera>,
    /// The tile table ([`TILE_VEC4S`](super::wall::TILE_VEC4S) vec4s a tile).
    wall_table: wgpu::Buffer,
    /// The rows of the image this run's accumulation holds.
    band: Band,
    /// A full frame's wavefront split, for a `+split` kernel.
    split: Option<SplitRun>,
}

/// A full frame in the wavefront split: the kernels, and each chunk's bind groups (one a
/// phase: its parameters over the path states, hits and queues all chunks share, traced one
/// after the other) and grid.
struct SplitRun {
    start: wgpu::ComputePipeline,
    extend: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
    chunks: Vec<([wgpu::BindGroup; 3], [u32; 2])>,
    /// Bounces a chunk runs: the settings' maximum depth.
    max_depth: std::cell::Cell<u32>,
}

impl SplitRun {
    /// `jobs` full-frame jobs (threads of the one-kernel frame) in chunks of at most `chunk`
    /// paths — fewer where one binding holds fewer path states.
    fn new(
        ctx: &GpuContext,
        kernels: &SplitKernels,
        variant: TraceVariant,
        jobs: u32,
        max_depth: u32,
    ) -> Self {
        let chunk = split_chunk(variant, jobs, ctx.max_binding());
        let buffer = |label, bytes: u64| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        let states = buffer("trace split states", 64 * u64::from(chunk));
        let hits = buffer("trace split hits", 16 * u64::from(chunk));
        let queues = buffer("trace split queues", 8 * u64::from(chunk));
        let lengths = buffer("trace split queue lengths", 8);
        let chunks = (0..jobs)
            .step_by(chunk as usize)
            .map(|first_job| {
                let n = chunk.min(jobs - first_job);
                let groups = n.div_ceil(variant.workgroup);
                let gx = groups.min(MAX_GROUPS_X);
                let phase = |phase: u32| {
                    let params = ctx
                        .device
                        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                            label: Some("trace split chunk"),
                            contents: bytemuck::bytes_of(&GpuSplitParams {
                                first_job,
                                // The queues are `jobs` apart: the chunk's size, the last
                                // chunk's too.
                                jobs: n,
                                groups_x: gx,
                                phase,
                            }),
                            usage: wgpu::BufferUsages::UNIFORM,
                        });
                    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("trace split chunk"),
                        layout: &kernels.chunk_layout,
                        entries: &[
                            entry(0, &states),
                            entry(1, &hits),
                            entry(2, &params),
                            entry(3, &queues),
                            entry(4, &lengths),
                        ],
                    })
                };
                ([phase(0), phase(1), phase(2)], [gx, groups.div_ceil(gx)])
            })
            .collect();
        Self {
            start: kernels.start.clone(),
            extend: kernels.extend.clone(),
            shade: kernels.shade.clone(),
            chunks,
            max_depth: std::cell::Cell::new(max_depth),
        }
    }

    /// Each chunk in turn: its paths started, then closest hits and shading alternating, a
    /// bounce each (the first over the chunk's paths, then from one queue of live paths into
    /// the other and back), in a pass whose bind groups 0 and 1 are set.
    fn record(&self, pass: &mut wgpu::ComputePass<'_>) {
        for (phases, [gx, gy]) in &self.chunks {
            pass.set_bind_group(2, &phases[0], &[]);
            pass.set_pipeline(&self.start);
            pass.dispatch_workgroups(*gx, *gy, 1);
            for bounce in 0..self.max_depth.get() {
                let phase = match bounce {
                    0 => 0,
                    b if b % 2 == 1 => 1,
                    _ => 2,
                };
                pass.set_bind_group(2, &phases[phase], &[]);
                pass.set_pipeline(&self.extend);
                pass.dispatch_workgroups(*gx, *gy, 1);
                pass.set_pipeline(&self.shade);
                pass.dispatch_workgroups(*gx, *gy, 1);
            }
        }
    }
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
    /// [`TILE_VEC4S`](super::wall::TILE_VEC4S) vec4s a tile).
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
        Self::for_band(ctx, kernel, scene, settings, wall, accum, schedule, band)
    }

    /// [`Self::with_wall`] for the rows of `band` alone: `accum` holds those rows (it is
    /// `width × band.rows`), and `schedule`'s list, if any, holds band pixel indices.
    #[allow(clippy::too_many_arguments)]
    pub fn for_band(
        ctx: &GpuContext,
        kernel: &TraceKernel,
        scene: &PackedScene,
        settings: &TraceSettings,
        wall: Option<&WallCamera>,
        accum: &GpuAccum,
        schedule: Option<(&wgpu::Buffer, &wgpu::Buffer)>,
        band: Band,
    ) -> Self {
        debug_assert_eq!([accum.width, accum.height], [settings.width, band.rows]);
        let params = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("trace params"),
                contents: bytemuck::bytes_of(&GpuTraceParams::for_band(
                    scene,
                    settings,
                    wall,
                    schedule.is_some(),
                    band,
                    kernel.variant,
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
        let (threads, groups, _) = full_frame_launch(settings.width, band.rows, kernel.variant);
        let split = match (&kernel.split, schedule) {
            (Some(k), None) => Some(SplitRun::new(
                ctx,
                k,
                kernel.variant,
                threads,
                settings.max_depth,
            )),
            _ => None,
        };
        Self {
            split,
            pipeline: kernel.pipeline.clone(),
            params,
            bind,
            args: schedule.map(|(_, a)| a.clone()),
            groups,
            variant: kernel.variant,
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
            scene,
            settings,
            self.wall.as_ref(),
            self.args.is_some(),
            self.band,
            self.variant,
        );
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&p));
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
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &scene.bind, &[]);
        pass.set_bind_group(1, &self.bind, &[]);
        match (&self.args, &self.split) {
            (Some(args), _) => pass.dispatch_workgroups_indirect(args, 0),
            (None, Some(split)) => split.record(&mut pass),
            (None, None) => pass.dispatch_workgroups(self.groups[0], self.groups[1], 1),
        }
    }
}

/// Samples returned rather than accumulated: a cluster rank's trace (DESIGN.md §12), whose
/// samples go to the owners of their tiles. The kernel's compact mode: entry i of the list
/// traces pixel `pixels[i]` with sample index `counts[i]` (the rank has each pixel's count
/// on its CPU, from the pixel's owner) and writes the sample's RGB and its ray count into entry i, which is read back.
/// CPU twin: [`super::path::samples_cpu`].
///
/// Per sample the link to the GPU carries 8 bytes up (pixel, sample index) and 16 down; the
/// buffers grow with the longest list so far.
pub struct SampleRun {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    wall_table: wgpu::Buffer,
    wall: Option<WallCamera>,
    buffers: Option<SampleBuffers>,
    /// The kernel's variant (its workgroup's size, whether its launches regenerate).
    variant: TraceVariant,
}

/// A [`SampleRun`]'s list-sized buffers and the frame bind group over them.
struct SampleBuffers {
    capacity: u32,
    list: wgpu::Buffer,
    counts: wgpu::Buffer,
    out: wgpu::Buffer,
    args: wgpu::Buffer,
    bind: wgpu::BindGroup,
}

impl SampleRun {
    /// For `scene` with `settings`, through `wall`'s primary rays when given.
    #[must_use]
    pub fn new(
        ctx: &GpuContext,
        kernel: &TraceKernel,
        scene: &PackedScene,
        settings: &TraceSettings,
        wall: Option<&WallCamera>,
    ) -> Self {
        let params = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("samples params"),
                contents: bytemuck::bytes_of(&Self::params_of(
                    scene,
                    settings,
                    wall,
                    kernel.variant,
                )),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
        let wall_table = wall_table_buffer(ctx, "samples wall tiles", wall);
        Self {
            pipeline: kernel.pipeline.clone(),
            params,
            wall_table,
            wall: wall.cloned(),
            buffers: None,
            variant: kernel.variant,
        }
    }

    fn params_of(
        scene: &PackedScene,
        settings: &TraceSettings,
        wall: Option<&WallCamera>,
        variant: TraceVariant,
    ) -> GpuTraceParams {
        GpuTraceParams {
            mode: 2,
            ..GpuTraceParams::with_wall(scene, settings, wall, true, variant)
        }
    }

    /// The wall camera `wall` from now on (a moved eye: the same display and tile count).
    /// Returns `false`, changing nothing, where this run has no wall camera or `wall` has
    /// another tile count.
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

    /// Rewrites the parameters (a new camera or depth) before the next list.
    pub fn set_settings(&self, ctx: &GpuContext, scene: &PackedScene, settings: &TraceSettings) {
        let p = Self::params_of(scene, settings, self.wall.as_ref(), self.variant);
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&p));
    }

    /// Buffers for at least `len` entries (grown by doubling).
    fn buffers(&mut self, ctx: &GpuContext, len: u32) -> Result<&SampleBuffers, GpuError> {
        if self.buffers.as_ref().is_none_or(|b| b.capacity < len) {
            // Doubling, within what one binding holds (`samples` keeps `len` below it).
            let most = u32::try_from(ctx.max_binding() / 16).unwrap_or(u32::MAX);
            let capacity = len.max(1).next_power_of_two().max(1024).min(most).max(len);
            ctx.check_binding("a rank's samples (16 bytes each)", u64::from(capacity) * 16)?;
            let make = |label, bytes: u64, usage| {
                ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes,
                    usage,
                    mapped_at_creation: false,
                })
            };
            use wgpu::BufferUsages as U;
            let n = u64::from(capacity);
            let list = make("samples pixels", 4 * n, U::STORAGE | U::COPY_DST);
            let counts = make("samples indices", 4 * n, U::STORAGE | U::COPY_DST);
            let out = make(
                "samples out",
                16 * n,
                U::STORAGE | U::COPY_SRC | U::COPY_DST,
            );
            let args = make("samples args", 16, U::STORAGE | U::COPY_DST);
            let stats = make("samples stats", 16, U::STORAGE);
            let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("samples frame"),
                layout: &self.pipeline.get_bind_group_layout(1),
                entries: &[
                    entry(0, &self.params),
                    entry(1, &out),
                    entry(2, &counts),
                    entry(3, &list),
                    entry(4, &args),
                    entry(5, &stats),
                    entry(6, &self.wall_table),
                ],
            });
            self.buffers = Some(SampleBuffers {
                capacity,
                list,
                counts,
                out,
                args,
                bind,
            });
        }
        Ok(self.buffers.as_ref().expect("made above"))
    }

    /// One sample for each of `pixels` (sample index `counts[i]` for `pixels[i]`): its RGB and
    /// the rays it took, in list order; a pixel the wall camera does not show gives black and
    /// no rays. A list longer than one binding holds (16 bytes an entry) goes in pieces.
    pub fn samples(
        &mut self,
        ctx: &GpuContext,
        scene: &GpuScene,
        pixels: &[u32],
        counts: &[u32],
    ) -> Result<Vec<(glam::Vec3, u32)>, GpuError> {
        Ok(self
            .samples_raw(ctx, scene, pixels, counts)?
            .iter()
            .map(|v| (glam::Vec3::new(v[0], v[1], v[2]), v[3].to_bits()))
            .collect())
    }

    /// [`Self::samples`] as the kernel writes them: RGB, then the rays as the bits of the
    /// fourth float — the read-back itself, not a converted copy (a GPU rank's list is
    /// millions of samples).
    pub fn samples_raw(
        &mut self,
        ctx: &GpuContext,
        scene: &GpuScene,
        pixels: &[u32],
        counts: &[u32],
    ) -> Result<Vec<[f32; 4]>, GpuError> {
        assert_eq!(pixels.len(), counts.len(), "a sample index for each pixel");
        if Self::fits_one_binding(ctx, pixels.len()) {
            return self.samples_prefix(ctx, scene, pixels, counts, pixels.len());
        }
        let piece = Self::piece(ctx);
        let mut out = Vec::with_capacity(pixels.len());
        for (p, c) in pixels.chunks(piece).zip(counts.chunks(piece)) {
            out.extend(self.samples_prefix(ctx, scene, p, c, p.len())?);
        }
        Ok(out)
    }

    /// The most samples one dispatch takes: one binding of 16 bytes each.
    fn piece(ctx: &GpuContext) -> usize {
        (ctx.max_binding() / 16).clamp(1, 1 << 30) as usize
    }

    /// Traces `pixels` (a list one binding holds: [`Self::fits_one_binding`]) and reads back
    /// the first `read` samples only; the others stay in [`Self::out`] until the next list (a
    /// cluster rank keeps the samples of its own blocks on its GPU: [`OwnedSums::keep`]).
    pub fn samples_prefix(
        &mut self,
        ctx: &GpuContext,
        scene: &GpuScene,
        pixels: &[u32],
        counts: &[u32],
        read: usize,
    ) -> Result<Vec<[f32; 4]>, GpuError> {
        assert_eq!(pixels.len(), counts.len(), "a sample index for each pixel");
        assert!(read <= pixels.len(), "{read} of {} samples", pixels.len());
        if pixels.is_empty() {
            return Ok(Vec::new());
        }
        let len = u32::try_from(pixels.len()).expect("a list of u32 pixel indices");
        // The scheduler's grid for this kernel (capped where it regenerates).
        let [gx, gy, _] = crate::schedule::indirect_grid(
            len,
            self.variant.workgroup,
            self.variant.regen,
            ctx.limits.max_compute_workgroups_per_dimension,
        );
        let pipeline = self.pipeline.clone();
        let b = self.buffers(ctx, len)?;
        ctx.queue
            .write_buffer(&b.list, 0, bytemuck::cast_slice(pixels));
        ctx.queue
            .write_buffer(&b.counts, 0, bytemuck::cast_slice(counts));
        ctx.queue
            .write_buffer(&b.args, 0, bytemuck::cast_slice(&[gx, gy, 1, len]));
        let mut enc = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("trace/samples"),
            });
        enc.clear_buffer(&b.out, 0, Some(16 * u64::from(len)));
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("trace/samples"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &scene.bind, &[]);
            pass.set_bind_group(1, &b.bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        ctx.queue.submit([enc.finish()]);
        ctx.read_prefix(&b.out, 16 * read as u64)
    }

    /// Whether a list of `len` samples is traced in one dispatch (16 bytes a sample in one
    /// binding), so [`Self::samples_prefix`] can take it.
    #[must_use]
    pub fn fits_one_binding(ctx: &GpuContext, len: usize) -> bool {
        len <= Self::piece(ctx)
    }

    /// The last list's samples (RGB, rays as bits), entry i for its pixel i.
    #[must_use]
    pub fn out(&self) -> Option<&wgpu::Buffer> {
        self.buffers.as_ref().map(|b| &b.out)
    }
}

/// The parameters of `shaders/trace/accum.wgsl` (mirrors `OwnedParams`, 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuOwnedParams {
    pub own: u32,
    pub foreign: u32,
    pub segments: u32,
    pub _pad: u32,
}

/// Threads per workgroup of `accum.wgsl`'s entry points.
const ACCUM_WORKGROUP: u32 = 256;

/// A cluster rank's owned sums on its GPU (DESIGN.md §12): `BLOCK_PIXELS` entries per owned
/// block (RGB sum, Σ lum²), as the rank's CPU lays them out. The samples of its own blocks that
/// it traced stay on the GPU from the trace ([`Self::keep`]) and are added with the other
/// ranks' samples when the frame is collected ([`Self::add`]), so only other owners' samples
/// are read back. CPU twins: `accumulate_sums` and `block_rays` (src/trace/accum.rs).
pub struct OwnedSums {
    add: wgpu::ComputePipeline,
    rays: wgpu::ComputePipeline,
    /// The owned sums.
    pub sums: wgpu::Buffer,
    /// The kept samples, oldest first: each traced frame's own blocks' samples, in the order
    /// of their blocks, with their count, until its frame is collected (with the exchange
    /// overlapped, the next frame keeps its own before the last one's are added).
    kept: std::collections::VecDeque<(wgpu::Buffer, u32)>,
    /// Kept buffers added already, for the next frames to reuse.
    free: Vec<wgpu::Buffer>,
    /// Owned pixels.
    entries: u64,
}

fn storage_init(ctx: &GpuContext, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    // A binding may not be empty: one zero word where there is nothing.
    let bytes = if bytes.is_empty() {
        &[0u8; 4][..]
    } else {
        bytes
    };
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytes,
            usage: wgpu::BufferUsages::STORAGE,
        })
}

impl OwnedSums {
    /// Zeroed sums for `entries` owned pixels (`None` where they exceed one binding: the rank
    /// adds on its CPU then).
    pub fn new(ctx: &GpuContext, entries: u64) -> Option<Self> {
        if entries * 16 > ctx.max_binding() {
            return None;
        }
        let module = ctx.shader_module("trace/accum.wgsl", ACCUM_WGSL);
        Some(Self {
            add: ctx.compute_pipeline_in(&module, "trace/accum add", "add"),
            rays: ctx.compute_pipeline_in(&module, "trace/accum block_rays", "block_rays"),
            sums: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("owned sums"),
                size: (entries * 16).max(16),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            kept: std::collections::VecDeque::new(),
            free: Vec::new(),
            entries,
        })
    }

    /// Every owned sum back to zero (a restart; the frames in flight are collected as stale:
    /// [`Self::drop_kept`]).
    pub fn clear(&mut self, ctx: &GpuContext) {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        enc.clear_buffer(&self.sums, 0, None);
        ctx.queue.submit([enc.finish()]);
    }

    /// Drops the oldest kept samples unadded (their frame was collected after a restart).
    pub fn drop_kept(&mut self) {
        if let Some((b, _)) = self.kept.pop_front() {
            self.free.push(b);
        }
    }

    /// Keeps entries `from..from + len` of `out` (the last list's samples: own blocks' samples
    /// after the others; `None` where the list was empty) until [`Self::add`], and returns the rays of each run `segments`
    /// gives ((first, length) in the kept samples).
    pub fn keep(
        &mut self,
        ctx: &GpuContext,
        out: Option<&wgpu::Buffer>,
        from: u64,
        len: u32,
        segments: &[[u32; 2]],
    ) -> Result<Vec<u32>, GpuError> {
        let bytes = 16 * u64::from(len.max(1));
        ctx.check_binding("a rank's own samples (16 bytes each)", bytes)?;
        let buffer = match self.free.iter().position(|b| b.size() >= bytes) {
            Some(i) => self.free.swap_remove(i),
            None => ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("owned samples kept"),
                size: bytes.next_power_of_two(),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        };
        self.kept.push_back((buffer, len));
        let kept = &self.kept.back().expect("pushed above").0;
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        if len > 0 {
            let out = out.expect("samples to keep come from a traced list");
            enc.copy_buffer_to_buffer(out, 16 * from, kept, 0, 16 * u64::from(len));
        }
        if segments.is_empty() {
            ctx.queue.submit([enc.finish()]);
            return Ok(Vec::new());
        }
        let n = u32::try_from(segments.len()).expect("blocks of a u32 list");
        let params = self.params(ctx, 0, 0, n);
        let seg = storage_init(ctx, "owned segments", bytemuck::cast_slice(segments));
        let rays = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("owned block rays"),
            size: 4 * u64::from(n),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("owned block rays"),
            layout: &self.rays.get_bind_group_layout(0),
            entries: &[
                entry(0, &params),
                entry(2, kept),
                entry(6, &seg),
                entry(7, &rays),
            ],
        });
        let [gx, gy] = ctx.grid_2d(n);
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.rays);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        ctx.queue.submit([enc.finish()]);
        ctx.read_buffer(&rays)
    }

    fn params(&self, ctx: &GpuContext, own: u32, foreign: u32, segments: u32) -> wgpu::Buffer {
        ctx.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("owned params"),
                contents: bytemuck::bytes_of(&GpuOwnedParams {
                    own,
                    foreign,
                    segments,
                    _pad: 0,
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    /// Adds the kept samples to the sums at `own_dst` (one entry each, in kept order; `None`:
    /// the kept samples are dropped, as a restarted accumulation drops them) and the samples
    /// `foreign` (RGB triples) at `foreign_dst`. No two of them may be one pixel (a pixel gets
    /// at most one sample a frame).
    pub fn add(
        &mut self,
        ctx: &GpuContext,
        own_dst: Option<&[u32]>,
        foreign: &[f32],
        foreign_dst: &[u32],
    ) -> Result<(), GpuError> {
        assert_eq!(
            foreign.len(),
            3 * foreign_dst.len(),
            "an RGB triple per destination"
        );
        let kept = match own_dst {
            Some(d) => {
                let (b, len) = self.kept.pop_front().expect("samples kept for this frame");
                assert_eq!(d.len(), len as usize, "a destination per kept sample");
                Some((b, len))
            }
            None => None,
        };
        let own = kept.as_ref().map_or(0, |k| k.1);
        let foreign_n = u32::try_from(foreign_dst.len()).expect("a u32 list");
        let total = own + foreign_n;
        if total == 0 {
            self.free.extend(kept.map(|k| k.0));
            return Ok(());
        }
        ctx.check_binding(
            "other ranks' samples (12 bytes each)",
            12 * u64::from(foreign_n),
        )?;
        let params = self.params(ctx, own, foreign_n, 0);
        let own_dst = storage_init(
            ctx,
            "owned destinations",
            bytemuck::cast_slice(own_dst.unwrap_or(&[])),
        );
        let foreign_buf = storage_init(ctx, "other ranks' samples", bytemuck::cast_slice(foreign));
        let foreign_dst = storage_init(
            ctx,
            "other ranks' destinations",
            bytemuck::cast_slice(foreign_dst),
        );
        let empty;
        let kept_buffer = match &kept {
            Some(k) => &k.0,
            None => {
                empty = storage_init(ctx, "no kept samples", &[0u8; 16]);
                &empty
            }
        };
        let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("owned add"),
            layout: &self.add.get_bind_group_layout(0),
            entries: &[
                entry(0, &params),
                entry(1, &self.sums),
                entry(2, kept_buffer),
                entry(3, &own_dst),
                entry(4, &foreign_buf),
                entry(5, &foreign_dst),
            ],
        });
        let [gx, gy] = ctx.grid_2d(total.div_ceil(ACCUM_WORKGROUP));
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.add);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        ctx.queue.submit([enc.finish()]);
        // Reused only by a later submit, which the queue orders after this one.
        self.free.extend(kept.map(|k| k.0));
        Ok(())
    }

    /// The owned sums, read back.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<[f32; 4]>, GpuError> {
        ctx.read_prefix(&self.sums, 16 * self.entries)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::wgsl::{assert_same_layout, struct_size, validated, validated_with};

    #[test]
    fn kernel_validates_and_params_match_their_rust_twin() {
        let module = validated("path.wgsl", TRACE_WGSL);
        assert_same_layout(
            &module,
            "Params",
            &crate::rust_layout!(GpuTraceParams; size, count, mode, seed, max_depth, light_count,
                groups_x, env_size, env_marginal, env_conditional, env_constant, env_select,
                cam_pos, tan_half_y, cam_fwd, aspect, cam_right, node_count, cam_up, wall_tiles,
                features, extras_offset, punctual_count, punct_select, ortho_half_y, row0, rows,
                stride),
        );
        assert_eq!(
            struct_size(&module, "Node"),
            std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>()
        );
        assert_same_layout(
            &module,
            "SplitParams",
            &crate::rust_layout!(GpuSplitParams; first_job, jobs, groups_x, phase),
        );
        // The split's buffers: a path's state, its closest hit and its two queue entries.
        assert_eq!(
            (struct_size(&module, "PathState") + struct_size(&module, "Hit") + 8) as u64,
            SPLIT_PATH_BYTES
        );
        assert_eq!(struct_size(&module, "PathState"), 64);
    }

    /// The constants the kernel shares with the CPU twin by value: the packed material's
    /// layout and flags, the dispersion's wavelength terms to the bit and the all-channels
    /// marker.
    #[test]
    fn the_kernels_material_constants_are_the_twins() {
        use crate::gpu::wgsl::const_literal;
        use wgpu::naga::Literal;
        let module = validated("path.wgsl", TRACE_WGSL);
        for (name, want) in ["DISPERSION_R", "DISPERSION_G", "DISPERSION_B"]
            .iter()
            .zip(crate::trace::shading::DISPERSION_TERMS)
        {
            match const_literal(&module, name) {
                Literal::F32(v) => assert_eq!(v.to_bits(), want.to_bits(), "{name}: {v} vs {want}"),
                other => panic!("{name} is {other:?}"),
            }
        }
        use crate::trace::pack as p;
        let u32s = [
            ("MATERIAL_STRIDE", p::MATERIAL_STRIDE as u32),
            ("MATERIAL_COAT_ROW", p::MATERIAL_COAT_ROW as u32),
            ("MATERIAL_SHEEN_ROW", p::MATERIAL_SHEEN_ROW as u32),
            ("MATERIAL_ANISO_ROW", p::MATERIAL_ANISO_ROW as u32),
            ("MATERIAL_DIFFUSE_ROW", p::MATERIAL_DIFFUSE_ROW as u32),
            ("SHEEN_TABLE_ROWS", p::SHEEN_TABLE_ROWS as u32),
            ("EXTRAS_STRIDE", p::EXTRAS_STRIDE as u32),
            ("MAT_BASE_TEX", p::MAT_BASE_TEX),
            ("MAT_MR_TEX", p::MAT_MR_TEX),
            ("MAT_NORMAL_TEX", p::MAT_NORMAL_TEX),
            ("MAT_EMISSIVE_TEX", p::MAT_EMISSIVE_TEX),
            ("MAT_MASK", p::MAT_MASK),
            ("MAT_BLEND", p::MAT_BLEND),
            ("MAT_EXT_BSDF", p::MAT_EXT_BSDF),
            ("MAT_EXT_TEX", p::MAT_EXT_TEX),
            ("MAT_VOLUME", p::MAT_VOLUME),
            ("MAT_DISPERSION", p::MAT_DISPERSION),
            ("FEAT_EXTRAS", p::FEAT_EXTRAS),
            ("FEAT_ALPHA", p::FEAT_ALPHA),
        ];
        for (name, want) in u32s {
            assert_eq!(const_literal(&module, name), Literal::U32(want), "{name}");
        }
        assert_eq!(
            const_literal(&module, "ALL_CHANNELS"),
            Literal::U32(crate::trace::path::ALL_CHANNELS)
        );
    }

    #[test]
    fn the_owned_sums_kernel_validates_and_matches_its_rust_twins() {
        let module = validated("accum.wgsl", ACCUM_WGSL);
        assert_same_layout(
            &module,
            "OwnedParams",
            &crate::rust_layout!(GpuOwnedParams; own, foreign, segments, _pad),
        );
        assert!(ACCUM_WGSL.contains(&format!("@workgroup_size({ACCUM_WORKGROUP})")));
        // The luminance the one-process kernel and the CPU use.
        let lum = "return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;";
        assert!(ACCUM_WGSL.contains(lum) && TRACE_WGSL.contains(lum));
    }

    /// The variants the tests compile and render: every stack and checks choice, every
    /// workgroup size with the stack as written and in workgroup memory, and the vote with
    /// each stack.
    pub(crate) fn tested_variants() -> Vec<TraceVariant> {
        let mut v = TraceVariant::ALL.to_vec();
        for n in TraceVariant::WORKGROUPS {
            if n != WORKGROUP {
                v.push(TraceVariant::default().with_workgroup(n));
                v.push(TraceVariant::new(TraceStack::Workgroup, true).with_workgroup(n));
            }
        }
        v.push(TraceVariant::default().with_vote(TraceVariant::VOTE_PERCENT));
        v.push(TraceVariant::new(TraceStack::Workgroup, true).with_vote(100));
        v.push(
            TraceVariant::new(TraceStack::Function, false)
                .with_workgroup(32)
                .with_vote(1),
        );
        v
    }

    #[test]
    fn every_trace_kernel_variant_validates_and_names_itself() {
        // The workgroup stack's size is the kernel's stack and workgroup.
        assert!(TRACE_WGSL.contains(&format!("const STACK_SIZE: u32 = {STACK_ENTRIES}u;")));
        assert!(TRACE_WGSL.contains(&format!("const WORKGROUP: u32 = {WORKGROUP}u;")));
        assert!(TRACE_WGSL.contains("@workgroup_size(WORKGROUP)"));
        assert_eq!(
            TraceVariant::new(TraceStack::Workgroup, false).workgroup_bytes(),
            4 + 32 * 8 * WORKGROUP
        );
        let mut sources = std::collections::HashSet::new();
        for v in tested_variants() {
            let source = kernel_source(v);
            // Only a vote uses subgroup operations: every other variant runs without them.
            let voting = v.vote != 0;
            assert_eq!(source.contains("subgroupBallot"), voting, "{v}");
            let module = validated_with(&format!("path.wgsl ({v})"), &source, voting);
            let entry = module
                .entry_points
                .iter()
                .find(|e| e.name == "trace")
                .unwrap();
            assert_eq!(entry.workgroup_size, [v.workgroup, 1, 1], "{v}");
            // Only the function-scope variant zeroes a stack in `traverse`.
            let local = source.contains("    var stack: array<vec2<u32>, STACK_SIZE>;\n");
            assert_eq!(local, v.stack == TraceStack::Function, "{v}");
            assert_eq!(
                source.contains("var<workgroup> trace_stack"),
                v.stack == TraceStack::Workgroup,
                "{v}"
            );
            sources.insert(source.into_owned());
            assert_eq!(v.to_string().parse::<TraceVariant>(), Ok(v));
        }
        // The checks are a compile option, not a source change: 3 stacks at the default size,
        // 2 at each of the 3 others, and 3 votes.
        assert_eq!(sources.len(), 3 + 2 * 3 + 3);
    }

    #[test]
    fn a_regenerating_launch_covers_every_slot_once() {
        for (w, h) in [(1, 1), (40, 24), (3840, 2160), (13_519, 5_457)] {
            for wg in TraceVariant::WORKGROUPS {
                let one = TraceVariant::default().with_workgroup(wg);
                let (threads, grid, stride) = full_frame_launch(w, h, one);
                assert_eq!((stride, (threads, grid)), (0, full_frame_grid(w, h, wg)));
                for g in [1, 7, 1000, 70_000] {
                    let (t, [gx, gy], stride) = full_frame_launch(w, h, one.with_regen(g));
                    assert_eq!(t, threads);
                    assert!(gx <= MAX_GROUPS_X);
                    if stride == 0 {
                        // As many groups as the frame needs or more: a thread a path.
                        assert_eq!([gx, gy], grid, "{w}x{h}, wg {wg}, regen {g}");
                        let rx = g.min(MAX_GROUPS_X);
                        assert!(rx * g.div_ceil(rx) >= grid[0] * grid[1]);
                    } else {
                        // Thread k traces slots k, k + stride, …: every slot below `threads`
                        // once, as the launch has `stride` threads.
                        assert_eq!(stride, gx * gy * wg);
                        assert!(gx * gy >= g && gx * gy < g + gx);
                        assert!(gx * gy < grid[0] * grid[1] && stride < threads);
                    }
                }
            }
        }
    }

    #[test]
    fn full_frame_grid_stays_within_dispatch_limits() {
        for (w, h) in [(1, 1), (7, 9), (128, 72), (3840, 2160), (7680, 4320)] {
            for wg in TraceVariant::WORKGROUPS {
                let (threads, [gx, gy]) = full_frame_grid(w, h, wg);
                assert!(gx <= MAX_GROUPS_X);
                assert!(u64::from(gx) * u64::from(gy) * u64::from(wg) >= u64::from(threads));
                assert!(u64::from(threads) >= u64::from(w) * u64::from(h));
            }
        }
    }
}
