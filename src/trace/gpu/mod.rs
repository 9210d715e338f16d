//! Dispatch of `shaders/trace/*.wgsl`, the GPU twin of [`super::path::render_cpu`]: the
//! kernel's source and its compiled pipeline here, the rest by job —
//!
//! * `params`: the frame's parameters ([`GpuTraceParams`]), the full frame's launch grid and
//!   the wall camera's tile table;
//! * `scene`: the scene's arrays uploaded ([`GpuScene`]);
//! * `accumulation`: the accumulation buffers ([`GpuAccum`]);
//! * `features`: the denoiser's feature buffers ([`FeaturesKernel`], [`GpuFeatures`];
//!   `shaders/trace/features.wgsl`, CPU twin [`crate::trace::features`]);
//! * `reuse`: motion reuse when the eye moves ([`ReuseKernel`], `shaders/trace/reuse.wgsl`,
//!   CPU twin [`crate::trace::reuse`]; its primary-hit records come from the features
//!   kernel's `primary_hits`, [`GpuHits`]);
//! * `run`: the runs over one accumulation ([`TraceRun`]) — full frames, the scheduler's
//!   lists, bands of rows;
//! * `samples` and `owned`: a cluster rank's runs — its samples returned ([`SampleRun`]) and
//!   its owned sums added on its GPU ([`OwnedSums`], `shaders/trace/accum.wgsl`);
//! * with the `kernel-lab` feature, `lab` and `split`: the kernel's variants, for timing them
//!   on a GPU (DESIGN.md §7), and the wavefront split among them.
//!
//! Bind group 0 is the scene ([`GpuScene`], uploaded once), bind group 1 the frame: the
//! parameters, the accumulation ([`GpuAccum`]) and, for guided rendering, the scheduler's pixel
//! list and its indirect-dispatch arguments `(x, y, z, count)`.
//!
//! raygun ships one trace kernel: [`TRACE_WGSL`] as written, every override constant at its
//! default.

mod accumulation;
mod features;
#[cfg(feature = "kernel-lab")]
mod lab;
mod owned;
mod params;
mod reuse;
mod run;
mod samples;
mod scene;
#[cfg(feature = "kernel-lab")]
mod split;

pub use accumulation::GpuAccum;
pub use features::{FeatureInputs, FeaturesKernel, GpuFeatures, GpuHits, HIT_BYTES_PER_PIXEL};
pub use owned::{GpuOwnedParams, OwnedSums};
pub use params::{GpuTraceParams, full_frame_grid};
pub use reuse::{GpuReuseParams, GpuView, ReuseInputs, ReuseKernel};
pub use run::{RunInputs, TraceRun};
pub use samples::SampleRun;
pub use scene::GpuScene;

#[cfg(feature = "kernel-lab")]
pub use crate::gpu::variant::{TraceStack, TraceVariant};
#[cfg(feature = "kernel-lab")]
pub use lab::{constants, full_frame_launch, kernel_source};
#[cfg(feature = "kernel-lab")]
pub use split::{GpuSplitParams, SPLIT_PATH_BYTES, split_bytes, split_chunk};

use crate::gpu::GpuContext;

/// The kernel source (WGSL has no includes).
pub const TRACE_WGSL: &str = concat!(
    include_str!("../../../shaders/random.wgsl"),
    "\n",
    include_str!("../../../shaders/trace/bvh.wgsl"),
    "\n",
    include_str!("../../../shaders/trace/shading.wgsl"),
    "\n",
    include_str!("../../../shaders/trace/path.wgsl")
);

/// The features kernel's source: the trace kernel's (its helpers and bindings) and
/// `features.wgsl` (WGSL has no includes).
pub const FEATURES_WGSL: &str = concat!(
    include_str!("../../../shaders/random.wgsl"),
    "\n",
    include_str!("../../../shaders/trace/bvh.wgsl"),
    "\n",
    include_str!("../../../shaders/trace/shading.wgsl"),
    "\n",
    include_str!("../../../shaders/trace/path.wgsl"),
    "\n",
    include_str!("../../../shaders/trace/features.wgsl")
);

/// The reuse kernel's source (it traces nothing: no helpers of the trace kernel).
pub const REUSE_WGSL: &str = include_str!("../../../shaders/trace/reuse.wgsl");

/// Threads per workgroup of the trace kernel (the default of the override `WORKGROUP` in
/// path.wgsl).
pub const WORKGROUP: u32 = 64;

/// Entries of the kernel's traversal stack (`STACK_SIZE` in bvh.wgsl): a scene whose tree a
/// walk could need more of is refused ([`GpuScene::upload`]).
pub const STACK_ENTRIES: u32 = 32;

/// The kernel's entry point (path.wgsl's `trace`).
const ENTRY: &str = "trace";

/// A cluster rank's owned sums and the rays per block it traced: `shaders/trace/accum.wgsl`.
pub const ACCUM_WGSL: &str = include_str!("../../../shaders/trace/accum.wgsl");

/// The compiled kernel.
#[derive(Clone)]
pub struct TraceKernel {
    pipeline: wgpu::ComputePipeline,
    /// The variant it was compiled as, and the wavefront split's kernels where it has them.
    #[cfg(feature = "kernel-lab")]
    lab: lab::LabKernel,
}

impl TraceKernel {
    /// The kernel, compiled once a device ([`GpuContext::kept`]): every renderer needs it, and
    /// a driver takes longer to create its pipeline than to run many frames. With the
    /// `kernel-lab` feature, the variant `ctx` was made with (`GpuContext::trace_variant`),
    /// compiled once a device and variant.
    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        #[cfg(feature = "kernel-lab")]
        if let Some(kernel) = lab::LabKernel::compiled(ctx) {
            return kernel;
        }
        ctx.kept("trace kernel", || Self::compile(ctx))
    }

    /// [`TRACE_WGSL`] as written, its overrides at their defaults.
    fn compile(ctx: &GpuContext) -> Self {
        let module = ctx.shader_module("trace/path", TRACE_WGSL);
        Self {
            pipeline: ctx.compute_pipeline_in(&module, "trace/path", ENTRY),
            #[cfg(feature = "kernel-lab")]
            lab: lab::LabKernel::default(),
        }
    }
}

/// The kernel's launches (a kernel-lab build has its own, by variant: `lab.rs`).
#[cfg(not(feature = "kernel-lab"))]
impl TraceKernel {
    /// Threads per workgroup (what the scheduler's indirect dispatch arguments count in).
    #[must_use]
    pub fn workgroup(&self) -> u32 {
        WORKGROUP
    }

    /// The most workgroups a list's launch may have (0: no cap, a thread a listed pixel),
    /// which the scheduler's indirect arguments respect.
    #[must_use]
    pub fn max_list_groups(&self) -> u32 {
        0
    }

    /// A full frame's launch of `width × rows` pixels: its threads (one a pixel slot, 8 × 8
    /// tiles padded), the workgroup grid dispatched, and the stride between a thread's paths
    /// (0: a thread a path).
    fn full_frame_launch(&self, width: u32, rows: u32) -> (u32, [u32; 2], u32) {
        let (threads, grid) = full_frame_grid(width, rows, WORKGROUP);
        (threads, grid, 0)
    }
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::wgsl::{assert_same_layout, specialised, struct_size, validated};
    use owned::ACCUM_WORKGROUP;

    #[test]
    fn kernel_validates_and_params_match_their_rust_twin() {
        let module = validated("path.wgsl", TRACE_WGSL);
        // As a device compiles it: every override at its default, `WORKGROUP` threads a group.
        let compiled = specialised("path.wgsl", TRACE_WGSL, false, ENTRY, &[]);
        assert_eq!(compiled.entry_points.len(), 1);
        assert_eq!(compiled.entry_points[0].workgroup_size, [WORKGROUP, 1, 1]);
        use crate::gpu::wgsl::const_literal;
        use wgpu::naga::Literal;
        assert_eq!(const_literal(&compiled, "REGENERATE"), Literal::Bool(false));
        assert_eq!(const_literal(&compiled, "POSTPONE"), Literal::U32(0));
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
}
