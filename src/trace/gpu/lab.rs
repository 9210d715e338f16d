//! The trace kernel's variants: the same function compiled as other code
//! ([`TraceVariant`]: where the traversal stack lives, wgpu's run-time checks, the workgroup's
//! size, path regeneration, the wavefront split, triangle tests postponed by subgroup vote), so
//! that one binary can time them side by side.

use super::params::{MAX_GROUPS_X, full_frame_grid};
use super::split::{SplitKernels, bind_layout};
use super::{TRACE_WGSL, TraceKernel, TraceStack, TraceVariant, WORKGROUP};
use crate::gpu::GpuContext;

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

/// The kernel compiled as `variant`.
pub(super) fn compile(ctx: &GpuContext, variant: TraceVariant) -> TraceKernel {
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
        return TraceKernel {
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
    TraceKernel {
        pipeline: make("trace", &[Some(&scene), Some(&frame)]),
        variant,
        split: Some(split),
    }
}

#[cfg(test)]
mod tests {
    use super::super::STACK_ENTRIES;
    use super::*;
    use crate::gpu::wgsl::validated_with;

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
}
