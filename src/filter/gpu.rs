//! Dispatch of the filter kernels: `shaders/filter/exact.wgsl` (also the `off` pass-through),
//! and `shaders/filter/pyramid.wgsl` + `shaders/filter/fast.wgsl` for the fast filter. CPU
//! twins: [`super::exact::filter_cpu`], [`super::fast::filter_cpu`].
//!
//! A frame prepares a [`FilterRun`] once (buffers, bind groups) and records it into its own
//! encoder; all dispatches of one run share one compute pass, so one timestamp pair times the
//! whole filter (wgpu orders the dispatches' storage accesses inside a pass).

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::pyramid::{MAX_LEVELS, MAX_TAPS, Plan, Source, Target};
use super::{Blend, FilterInputError, FilterKind, FilterParams, check_inputs};
use crate::gpu::{GpuContext, GpuError, PassTimer};
use crate::trace::accum::Accumulation;

/// The exact kernel: the shared part, then the per-pixel window loop.
pub const EXACT_WGSL: &str = concat!(
    include_str!("../../shaders/filter/common.wgsl"),
    "\n",
    include_str!("../../shaders/filter/exact.wgsl")
);
/// The fast filter's final pass.
pub const FAST_WGSL: &str = concat!(
    include_str!("../../shaders/filter/common.wgsl"),
    "\n",
    include_str!("../../shaders/filter/fast.wgsl")
);
/// The fast filter's separable pyramid passes.
pub const PYRAMID_WGSL: &str = include_str!("../../shaders/filter/pyramid.wgsl");

/// The denoiser's kernel (entry points `init` and `atrous`); CPU twin and definition:
/// [`super::denoise`], its dispatch: [`super::denoise::gpu`].
pub const DENOISE_WGSL: &str = include_str!("../../shaders/filter/denoise.wgsl");

/// Mirrors `LevelDesc` in shaders/filter/common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuLevel {
    pub size: [u32; 2],
    pub origin: f32,
    pub step: f32,
    pub sigma2: f32,
    pub _pad: [f32; 3],
}

/// Mirrors `Params` in shaders/filter/common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuParams {
    pub size: [u32; 2],
    pub mode: u32,
    pub blend: u32,
    pub level_count: u32,
    pub k_max: f32,
    pub c: f32,
    pub variance_threshold: f32,
    pub levels: [GpuLevel; MAX_LEVELS],
}

/// Mirrors `Pass` in shaders/filter/pyramid.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuPass {
    pub src_size: [u32; 2],
    pub dst_size: [u32; 2],
    pub axis: u32,
    pub dec: u32,
    pub first: i32,
    pub taps: u32,
    pub weights: [[f32; 4]; MAX_TAPS / 4],
}

/// Storage buffers the fast filter's final pass binds: accumulation, counts, DGI, output and
/// one per level.
pub const FAST_STORAGE_BINDINGS: u32 = 4 + MAX_LEVELS as u32;

/// Why the GPU filter could not run.
#[derive(Debug, thiserror::Error)]
pub enum FilterGpuError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Input(#[from] FilterInputError),
    #[error(
        "the fast filter binds {need} storage buffers in one kernel; this adapter allows {max} \
         (--filter exact works with 5)"
    )]
    TooManyBindings { need: u32, max: u32 },
    #[error("the {what} buffer holds {bytes} bytes; a {width}×{height} image needs {need}")]
    InputBuffer {
        what: &'static str,
        bytes: u64,
        need: u64,
        width: u32,
        height: u32,
    },
}

/// The GPU inputs: the accumulation (`accum`: `vec4<f32>` per pixel, `counts`: u32 per pixel) and
/// the DGI (f32 per pixel), row-major, all with `STORAGE` usage.
#[derive(Clone, Copy)]
pub struct GpuFilterInputs<'a> {
    pub width: u32,
    pub height: u32,
    pub accum: &'a wgpu::Buffer,
    pub counts: &'a wgpu::Buffer,
    pub dgi: &'a wgpu::Buffer,
}

/// CPU-side inputs uploaded to the GPU (tests and benchmarks; the renderer has its own buffers).
pub struct UploadedInputs {
    pub width: u32,
    pub height: u32,
    pub accum: wgpu::Buffer,
    pub counts: wgpu::Buffer,
    pub dgi: wgpu::Buffer,
}

impl UploadedInputs {
    pub fn new(ctx: &GpuContext, acc: &Accumulation, dgi: &[f32]) -> Result<Self, GpuError> {
        ctx.check_binding(
            "filter input accumulation",
            size_of_val(&acc.sum[..]) as u64,
        )?;
        let storage = |label: &str, data: &[u8]| {
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: data,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                })
        };
        Ok(Self {
            width: acc.width,
            height: acc.height,
            accum: storage("filter accum", bytemuck::cast_slice(&acc.sum)),
            counts: storage("filter counts", bytemuck::cast_slice(&acc.count)),
            dgi: storage("filter dgi", bytemuck::cast_slice(dgi)),
        })
    }

    #[must_use]
    pub fn inputs(&self) -> GpuFilterInputs<'_> {
        GpuFilterInputs {
            width: self.width,
            height: self.height,
            accum: &self.accum,
            counts: &self.counts,
            dgi: &self.dgi,
        }
    }
}

/// The compiled filter kernels, and the last picture's buffers and bindings: a viewer filters
/// a picture of the same size with the same settings every frame, so its inputs go into the
/// buffers the last one used instead of fresh ones (on a discrete GPU each fresh buffer is an
/// allocation and a staging copy).
pub struct FilterKernels {
    exact: wgpu::ComputePipeline,
    fast: wgpu::ComputePipeline,
    blur_accumulation: wgpu::ComputePipeline,
    blur: wgpu::ComputePipeline,
    kept: std::sync::Mutex<Option<Box<KeptRun>>>,
}

/// A prepared filter over uploaded inputs, kept for the next picture of its size and settings.
struct KeptRun {
    size: [u32; 2],
    params: FilterParams,
    uploaded: UploadedInputs,
    run: FilterRun,
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

struct Dispatch {
    pipeline: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    groups: [u32; 2],
}

/// A prepared filter: record it once per frame (benchmarks repeat it).
pub struct FilterRun {
    dispatches: Vec<Dispatch>,
    /// The filtered image: `vec4<f32>` per pixel (linear RGB, alpha 1), row-major.
    pub output: wgpu::Buffer,
}

impl FilterRun {
    /// Records every dispatch into one compute pass; with a timer, pass `pass` of it measures
    /// the whole filter.
    pub fn record(&self, enc: &mut wgpu::CommandEncoder, timer: Option<(&PassTimer, u32)>) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("filter"),
            timestamp_writes: timer.map(|(t, i)| t.writes(i)),
        });
        for d in &self.dispatches {
            pass.set_pipeline(&d.pipeline);
            pass.set_bind_group(0, &d.bind, &[]);
            pass.dispatch_workgroups(d.groups[0], d.groups[1], 1);
        }
    }
}

/// Whether the kernels can filter a `size` image in one pass: every buffer they bind (the
/// input sums and the output, 16 bytes a pixel, and for the fast filter each pyramid level and
/// its intermediate, which reach past the image) fits one storage binding.
#[must_use]
pub fn fits_one_binding(ctx: &GpuContext, params: &FilterParams, [w, h]: [u32; 2]) -> bool {
    let mut largest = 16 * u64::from(w) * u64::from(h);
    if params.kind == FilterKind::Fast {
        let plan = Plan::new(w, h, params.k_max);
        for l in &plan.levels {
            largest = largest.max(16 * u64::from(l.size[0]) * u64::from(l.size[1]));
        }
        largest = largest.max(16 * plan.temp_texels());
    }
    largest <= ctx.max_binding()
}

fn groups(size: [u32; 2]) -> [u32; 2] {
    [size[0].div_ceil(16), size[1].div_ceil(16)]
}

impl FilterKernels {
    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        let module = |label: &str, src: &str| ctx.shader_module(label, src);
        let exact = module("filter/exact.wgsl", EXACT_WGSL);
        let fast = module("filter/fast.wgsl", FAST_WGSL);
        let pyramid = module("filter/pyramid.wgsl", PYRAMID_WGSL);
        Self {
            exact: ctx.compute_pipeline_in(&exact, "filter/exact", "main"),
            fast: ctx.compute_pipeline_in(&fast, "filter/fast", "main"),
            blur_accumulation: ctx.compute_pipeline_in(
                &pyramid,
                "filter/pyramid blur_accumulation",
                "blur_accumulation",
            ),
            blur: ctx.compute_pipeline_in(&pyramid, "filter/pyramid blur", "blur"),
            kept: std::sync::Mutex::new(None),
        }
    }

    /// Runs `f` on a filter prepared over `acc` and `dgi`: the kept one, its buffers
    /// overwritten, when the size and `params` are the last picture's; else a new one, kept
    /// for the next picture.
    pub fn with_prepared<R>(
        &self,
        ctx: &GpuContext,
        params: &FilterParams,
        acc: &Accumulation,
        dgi: &[f32],
        f: impl FnOnce(&FilterRun) -> Result<R, FilterGpuError>,
    ) -> Result<R, FilterGpuError> {
        check_inputs(params, acc, dgi)?;
        let size = [acc.width, acc.height];
        let mut kept = self
            .kept
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        match kept.as_ref() {
            Some(k) if k.size == size && k.params == *params => {
                let u = &k.uploaded;
                ctx.queue
                    .write_buffer(&u.accum, 0, bytemuck::cast_slice(&acc.sum));
                ctx.queue
                    .write_buffer(&u.counts, 0, bytemuck::cast_slice(&acc.count));
                ctx.queue.write_buffer(&u.dgi, 0, bytemuck::cast_slice(dgi));
            }
            _ => {
                // The old buffers go before the new ones are made: a picture's buffers, not two.
                *kept = None;
                let uploaded = UploadedInputs::new(ctx, acc, dgi)?;
                let run = self.prepare(ctx, params, &uploaded.inputs())?;
                *kept = Some(Box::new(KeptRun {
                    size,
                    params: *params,
                    uploaded,
                    run,
                }));
            }
        }
        f(&kept.as_ref().expect("prepared above").run)
    }

    /// [`Self::filter`] for an image of any height: one that does not fit the adapter's
    /// bindings (the input sums, the output and the finest pyramid level are 16 bytes a pixel)
    /// is filtered in bands of rows, each with the rows above and below that its pixels' values
    /// depend on ([`super::halo`]), starting on a row of every pyramid level's grid. The exact
    /// filter's bands are the whole image's values bit for bit; the fast filter's final read
    /// forms its level coordinates from band rows in f32, so its values agree to f32 rounding
    /// of those coordinates.
    pub fn filter_banded(
        &self,
        ctx: &GpuContext,
        params: &FilterParams,
        acc: &Accumulation,
        dgi: &[f32],
    ) -> Result<Vec<[f32; 4]>, FilterGpuError> {
        check_inputs(params, acc, dgi)?;
        params.validate().map_err(FilterInputError::from)?;
        let (w, h) = (acc.width, acc.height);
        let max = ctx.max_binding();
        let fits = |rows: u32| fits_one_binding(ctx, params, [w, rows]);
        if fits(h) {
            return self.filter(ctx, params, acc, dgi);
        }
        let (halo, align) = super::halo(params);
        // The most rows a band can have with its halo on both sides, a multiple of `align`.
        let mut rows = (max / (16 * u64::from(w))).min(u64::from(h)) as u32 / align * align;
        while rows > 0 && !fits(rows + 2 * halo) {
            rows -= align;
        }
        if rows == 0 {
            return Err(GpuError::TooLarge {
                what: "a band of the filter with its halo (16 bytes per pixel)",
                bytes: 16 * u64::from(w) * u64::from(align + 2 * halo),
                max,
            }
            .into());
        }
        let wu = w as usize;
        let mut out = Vec::with_capacity(wu * h as usize);
        for r0 in (0..h).step_by(rows as usize) {
            let r1 = (r0 + rows).min(h);
            let (s, e) = (r0.saturating_sub(halo), (r1 + halo).min(h));
            let px = wu * s as usize..wu * e as usize;
            let sub = Accumulation {
                width: w,
                height: e - s,
                sum: acc.sum[px.clone()].to_vec(),
                count: acc.count[px.clone()].to_vec(),
            };
            let part = self.filter(ctx, params, &sub, &dgi[px])?;
            out.extend_from_slice(&part[wu * (r0 - s) as usize..wu * (r1 - s) as usize]);
        }
        Ok(out)
    }

    /// Uploads the inputs, filters and reads the result back (row-major RGBA).
    pub fn filter(
        &self,
        ctx: &GpuContext,
        params: &FilterParams,
        acc: &Accumulation,
        dgi: &[f32],
    ) -> Result<Vec<[f32; 4]>, FilterGpuError> {
        self.with_prepared(ctx, params, acc, dgi, |run| {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            run.record(&mut enc, None);
            ctx.queue.submit([enc.finish()]);
            Ok(ctx.read_buffer(&run.output)?)
        })
    }

    /// Allocates the output (and the pyramid for `fast`) and binds everything: all but the
    /// dispatches.
    pub fn prepare(
        &self,
        ctx: &GpuContext,
        params: &FilterParams,
        inputs: &GpuFilterInputs<'_>,
    ) -> Result<FilterRun, FilterGpuError> {
        params.validate().map_err(FilterInputError::from)?;
        let (w, h) = (inputs.width, inputs.height);
        let n = u64::from(w) * u64::from(h);
        check_input_sizes(inputs)?;
        ctx.check_binding("filter output", n * 16)?;
        let output = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("filter output"),
            size: n * 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let plan = match params.kind {
            FilterKind::Fast => Plan::new(w, h, params.k_max),
            FilterKind::Off | FilterKind::Exact => Plan::new(w, h, 0.0),
        };
        let gpu_params = gpu_params(params, &plan, [w, h]);
        let uniform = |label: &str, bytes: &[u8]| {
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytes,
                    usage: wgpu::BufferUsages::UNIFORM,
                })
        };
        let params_buffer = uniform("filter params", bytemuck::bytes_of(&gpu_params));
        let mut dispatches = Vec::new();
        let final_pipeline = if params.kind == FilterKind::Fast {
            let max = ctx.limits.max_storage_buffers_per_shader_stage;
            if max < FAST_STORAGE_BINDINGS {
                return Err(FilterGpuError::TooManyBindings {
                    need: FAST_STORAGE_BINDINGS,
                    max,
                });
            }
            &self.fast
        } else {
            &self.exact
        };
        let mut final_entries = vec![
            entry(0, &params_buffer),
            entry(1, inputs.accum),
            entry(2, inputs.counts),
            entry(3, inputs.dgi),
            entry(4, &output),
        ];
        // Kept alive until the bind groups are made.
        let levels: Vec<wgpu::Buffer>;
        let dummy;
        if params.kind == FilterKind::Fast {
            let storage = |label: &str, texels: u64| -> Result<wgpu::Buffer, GpuError> {
                ctx.check_binding("filter pyramid level", texels * 16)?;
                Ok(ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: texels.max(1) * 16,
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                }))
            };
            levels = plan
                .levels
                .iter()
                .map(|l| storage("filter level", u64::from(l.size[0]) * u64::from(l.size[1])))
                .collect::<Result<_, _>>()?;
            let temp = storage("filter temp", plan.temp_texels())?;
            dummy = storage("filter unused level", 1)?;
            for p in &plan.passes {
                let mut weights = [[0.0f32; 4]; MAX_TAPS / 4];
                for (t, wt) in p.weights.iter().enumerate() {
                    weights[t / 4][t % 4] = *wt;
                }
                let gp = GpuPass {
                    src_size: p.src_size,
                    dst_size: p.dst_size,
                    axis: p.axis,
                    dec: p.dec,
                    first: p.first,
                    taps: p.weights.len() as u32,
                    weights,
                };
                let pass_uniform = uniform("filter pass", bytemuck::bytes_of(&gp));
                let dst = match p.target {
                    Target::Temp => &temp,
                    Target::Level(l) => &levels[l],
                };
                let (pipeline, bind) = match p.source {
                    Source::Accumulation => (
                        &self.blur_accumulation,
                        vec![
                            entry(0, &pass_uniform),
                            entry(1, inputs.accum),
                            entry(2, inputs.counts),
                            entry(4, dst),
                        ],
                    ),
                    Source::Level(l) => (
                        &self.blur,
                        vec![entry(0, &pass_uniform), entry(3, &levels[l]), entry(4, dst)],
                    ),
                    Source::Temp => (
                        &self.blur,
                        vec![entry(0, &pass_uniform), entry(3, &temp), entry(4, dst)],
                    ),
                };
                dispatches.push(Dispatch {
                    pipeline: pipeline.clone(),
                    bind: ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("filter pass"),
                        layout: &pipeline.get_bind_group_layout(0),
                        entries: &bind,
                    }),
                    groups: groups(p.dst_size),
                });
            }
            for l in 0..MAX_LEVELS {
                final_entries.push(entry(5 + l as u32, levels.get(l).unwrap_or(&dummy)));
            }
        }
        dispatches.push(Dispatch {
            pipeline: final_pipeline.clone(),
            bind: ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("filter"),
                layout: &final_pipeline.get_bind_group_layout(0),
                entries: &final_entries,
            }),
            groups: groups([w, h]),
        });
        Ok(FilterRun { dispatches, output })
    }
}

/// An error where one of `inputs`' buffers is smaller than its `width × height` entries.
fn check_input_sizes(inputs: &GpuFilterInputs<'_>) -> Result<(), FilterGpuError> {
    let (w, h) = (inputs.width, inputs.height);
    let n = u64::from(w) * u64::from(h);
    for (what, buffer, need) in [
        ("accum", inputs.accum, n * 16),
        ("counts", inputs.counts, n * 4),
        ("dgi", inputs.dgi, n * 4),
    ] {
        if buffer.size() < need {
            return Err(FilterGpuError::InputBuffer {
                what,
                bytes: buffer.size(),
                need,
                width: w,
                height: h,
            });
        }
    }
    Ok(())
}

/// The filter's uniform: `params` and the pyramid's levels of `plan`, for a picture of `size`.
fn gpu_params(params: &FilterParams, plan: &Plan, size: [u32; 2]) -> GpuParams {
    let mut gpu_params = GpuParams {
        size,
        mode: u32::from(params.kind != FilterKind::Off),
        blend: match params.blend {
            Blend::Count => 0,
            Blend::Variance => 1,
        },
        level_count: plan.levels.len() as u32,
        k_max: params.k_max,
        c: params.c,
        variance_threshold: params.variance_threshold,
        levels: [GpuLevel::zeroed(); MAX_LEVELS],
    };
    for (g, l) in gpu_params.levels.iter_mut().zip(&plan.levels) {
        *g = GpuLevel {
            size: l.size,
            origin: l.origin as f32,
            step: l.step as f32,
            sigma2: l.sigma2 as f32,
            _pad: [0.0; 3],
        };
    }
    gpu_params
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::wgsl::{assert_same_layout, validated};

    /// A kept filter gives what a fresh one gives, bit for bit, whatever came before it: two
    /// different pictures in turn, then new settings, then a new size, then the first two
    /// again (a rebuild, then a reuse).
    #[test]
    fn a_kept_filter_equals_a_fresh_one() {
        let ctx = GpuContext::for_tests();
        let picture = |w: u32, h: u32, salt: u32| {
            let n = (w * h) as usize;
            let hash = |i: usize, k: u32| {
                let x = (i as u32).wrapping_mul(0x9E37_79B9) ^ k.wrapping_mul(0x85EB_CA6B) ^ salt;
                ((x ^ (x >> 15)).wrapping_mul(0x2C1B_3C6D) >> 8) as f32 / (1 << 24) as f32
            };
            let count: Vec<u32> = (0..n).map(|i| (hash(i, 1) * 4.0) as u32).collect();
            let sum = (0..n)
                .map(|i| {
                    let c = count[i] as f32;
                    [
                        hash(i, 2) * c,
                        hash(i, 3) * c,
                        hash(i, 4) * c,
                        hash(i, 5) * c,
                    ]
                })
                .collect();
            let dgi = (0..n).map(|i| hash(i, 6)).collect::<Vec<f32>>();
            (
                Accumulation {
                    width: w,
                    height: h,
                    sum,
                    count,
                },
                dgi,
            )
        };
        let fast = FilterParams {
            kind: FilterKind::Fast,
            k_max: 6.0,
            ..FilterParams::default()
        };
        let exact = FilterParams {
            kind: FilterKind::Exact,
            k_max: 3.0,
            ..FilterParams::default()
        };
        let kept = FilterKernels::new(&ctx);
        let (a, b, c) = (picture(40, 24, 1), picture(40, 24, 2), picture(24, 40, 3));
        let order = [
            (fast, &a),
            (fast, &b),
            (exact, &b),
            (exact, &c),
            (fast, &a),
            (fast, &b),
        ];
        for (params, (acc, dgi)) in order {
            let fresh = FilterKernels::new(&ctx)
                .filter(&ctx, &params, acc, dgi)
                .unwrap();
            let again = kept.filter(&ctx, &params, acc, dgi).unwrap();
            assert!(
                fresh == again,
                "{:?} {}×{}",
                params.kind,
                acc.width,
                acc.height
            );
        }
    }

    /// The kernels parse and validate without a GPU, and every struct shared with Rust has the
    /// same size on both sides.
    #[test]
    fn kernels_validate_and_shared_structs_match_their_rust_twins() {
        for (src, name) in [(EXACT_WGSL, "exact.wgsl"), (FAST_WGSL, "fast.wgsl")] {
            let m = validated(name, src);
            assert_same_layout(
                &m,
                "Params",
                &crate::rust_layout!(GpuParams; size, mode, blend, level_count, k_max, c,
                    variance_threshold, levels),
            );
            assert_same_layout(
                &m,
                "LevelDesc",
                &crate::rust_layout!(GpuLevel; size, origin, step, sigma2, _pad),
            );
        }
        let m = validated("pyramid.wgsl", PYRAMID_WGSL);
        assert_same_layout(
            &m,
            "Pass",
            &crate::rust_layout!(GpuPass; src_size, dst_size, axis, dec, first, taps, weights),
        );
    }

    /// The WGSL constants repeat the Rust ones.
    #[test]
    fn shader_constants_match_rust() {
        use super::super::fast::{K_DIRECT, RIM_WEIGHT};
        assert!(FAST_WGSL.contains(&format!("const K_DIRECT: f32 = {K_DIRECT:.1};")));
        assert!(FAST_WGSL.contains(&format!("const RIM_WEIGHT: f32 = {RIM_WEIGHT};")));
        assert!(PYRAMID_WGSL.contains(&format!("weights: array<vec4<f32>, {}>", MAX_TAPS / 4)));
        assert!(FAST_WGSL.contains(&format!("levels: array<LevelDesc, {MAX_LEVELS}>")));
    }
}
