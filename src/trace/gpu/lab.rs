//! The kernel lab (the `kernel-lab` feature): the trace kernel's variants, the same function
//! compiled as other code ([`TraceVariant`]: where the traversal stack lives, wgpu's run-time
//! checks, the workgroup's size, path regeneration, the wavefront split, triangle tests
//! postponed by subgroup vote), so that one binary can time them side by side on a GPU. The
//! default variant is the kernel raygun ships, compiled as it is without the feature.

use super::params::{MAX_GROUPS_X, full_frame_grid};
use super::split::{SplitKernels, SplitLayouts, SplitRun};
use super::{ENTRY, STACK_ENTRIES, TRACE_WGSL, TraceKernel, TraceStack, TraceVariant};
use crate::gpu::GpuContext;

/// What a lab build's [`TraceKernel`] knows beside its pipeline.
#[derive(Clone, Default)]
pub(super) struct LabKernel {
    variant: TraceVariant,
    /// The wavefront split's kernels, for a `+split` variant.
    split: Option<SplitKernels>,
}

impl LabKernel {
    /// The kernel of the variant `ctx` was made with, compiled once a device and variant; `None`
    /// for the default variant, which is compiled as without the feature.
    pub(super) fn compiled(ctx: &GpuContext) -> Option<TraceKernel> {
        let variant = ctx.trace_variant();
        (variant != TraceVariant::default())
            .then(|| ctx.kept(&format!("trace kernel {variant}"), || compile(ctx, variant)))
    }
}

/// The kernel's launches, by its variant.
impl TraceKernel {
    /// Threads per workgroup (what the scheduler's indirect dispatch arguments count in).
    #[must_use]
    pub fn workgroup(&self) -> u32 {
        self.lab.variant.workgroup
    }

    /// The most workgroups a list's launch may have (0: no cap): a regenerating variant's
    /// [`TraceVariant::regen`], which the scheduler's indirect arguments must respect.
    #[must_use]
    pub fn max_list_groups(&self) -> u32 {
        self.lab.variant.regen
    }

    /// A full frame's launch of `width × rows` pixels ([`full_frame_launch`]).
    pub(super) fn full_frame_launch(&self, width: u32, rows: u32) -> (u32, [u32; 2], u32) {
        full_frame_launch(width, rows, self.lab.variant)
    }

    /// The wavefront split of a full frame of `jobs` threads (`None` for a list, or a kernel
    /// without the split).
    pub(super) fn split_run(
        &self,
        ctx: &GpuContext,
        full_frame: bool,
        jobs: u32,
        max_depth: u32,
    ) -> Option<SplitRun> {
        let kernels = self.lab.split.as_ref().filter(|_| full_frame)?;
        Some(SplitRun::new(
            ctx,
            kernels,
            self.lab.variant,
            jobs,
            max_depth,
        ))
    }
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

/// The kernel's source for `variant`: [`TRACE_WGSL`] as written, but where an override
/// constant cannot say it — WGSL has no conditional compilation — with
///
/// * the traversal stack moved out of module scope: into `traverse` (`function`) or into
///   workgroup memory (`workgroup`, `STACK_SIZE × WORKGROUP` entries), an address space being
///   part of a declaration;
/// * for a `+vote` variant, `lanes_voting` a subgroup ballot: a module that names a subgroup
///   operation needs the adapter's subgroup operations even where it never calls it.
///
/// Everything else a variant changes is a pipeline constant ([`constants`]) or a compile
/// option, on the source as written.
#[must_use]
pub fn kernel_source(variant: TraceVariant) -> std::borrow::Cow<'static, str> {
    const MODULE: &str = "var<private> stack: array<vec2<u32>, STACK_SIZE>;\n";
    const LOCAL: &str = "    var stack: array<vec2<u32>, STACK_SIZE>;\n";
    const FIRST: &str = "    var sp = 0u;\n";
    const PUSH: &str = "stack[sp] = current;";
    const POP: &str = "current = stack[sp];";
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
    if variant.vote != 0 {
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
            // Sized by the variant's workgroup: a workgroup array sized by an override
            // expression is beyond what naga's back ends take.
            let entries = STACK_ENTRIES * variant.workgroup;
            (s + &format!("\nvar<workgroup> trace_stack: array<vec2<u32>, {entries}>;\n")).into()
        }
    }
}

/// The pipeline constants that specialise the kernel as `variant` (WGSL `override`s, at their
/// defaults in the kernel as written): its workgroup's size, whether lists regenerate their
/// paths, and the vote's percentage.
#[must_use]
pub fn constants(variant: TraceVariant) -> [(&'static str, f64); 3] {
    [
        ("WORKGROUP", f64::from(variant.workgroup)),
        ("REGENERATE", f64::from(u8::from(variant.regen != 0))),
        ("POSTPONE", f64::from(variant.vote)),
    ]
}

/// The kernel compiled as `variant` (not the default: [`TraceKernel::new`] compiles that):
/// [`kernel_source`] with [`constants`], without wgpu's
/// run-time checks where `+unchecked`, and the wavefront split's three kernels beside `trace`
/// where `+split`.
fn compile(ctx: &GpuContext, variant: TraceVariant) -> TraceKernel {
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
    let constants = constants(variant);
    let make = |entry: &str, layout: Option<&wgpu::PipelineLayout>| {
        ctx.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(&label),
                layout,
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                cache: None,
            })
    };
    if variant.split == 0 {
        return TraceKernel {
            pipeline: make(ENTRY, None),
            lab: LabKernel {
                variant,
                split: None,
            },
        };
    }
    let layouts = SplitLayouts::new(ctx);
    let three = layouts.pipeline(ctx, &label, true);
    let split = SplitKernels {
        start: make("split_start", Some(&three)),
        extend: make("split_extend", Some(&three)),
        shade: make("split_shade", Some(&three)),
        chunk_layout: layouts.chunk.clone(),
    };
    TraceKernel {
        pipeline: make(ENTRY, Some(&layouts.pipeline(ctx, &label, false))),
        lab: LabKernel {
            variant,
            split: Some(split),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::super::WORKGROUP;
    use super::*;
    use crate::gpu::wgsl::{const_literal, specialised};
    use wgpu::naga::Literal;

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
        // The variants' defaults are the kernel's (the variant type lives below the trace stage).
        assert_eq!(crate::gpu::variant::STACK_ENTRIES, STACK_ENTRIES);
        assert_eq!(crate::gpu::variant::DEFAULT_WORKGROUP, WORKGROUP);
        // The workgroup stack's size is the kernel's stack and workgroup; the workgroup's size
        // and the other constants a variant sets are the kernel's overrides.
        assert!(TRACE_WGSL.contains(&format!("const STACK_SIZE: u32 = {STACK_ENTRIES}u;")));
        assert!(TRACE_WGSL.contains(&format!("override WORKGROUP: u32 = {WORKGROUP}u;")));
        assert!(TRACE_WGSL.contains("override REGENERATE: bool = false;"));
        assert!(TRACE_WGSL.contains("override POSTPONE: u32 = 0u;"));
        assert!(TRACE_WGSL.contains("@workgroup_size(WORKGROUP)"));
        assert_eq!(
            TraceVariant::new(TraceStack::Workgroup, false).workgroup_bytes(),
            4 + 32 * 8 * WORKGROUP
        );
        // The default is the kernel as written, its constants at their defaults.
        let default = TraceVariant::default();
        assert_eq!(kernel_source(default), TRACE_WGSL);
        assert_eq!(
            constants(default),
            [("WORKGROUP", 64.0), ("REGENERATE", 0.0), ("POSTPONE", 0.0)]
        );
        let mut sources = std::collections::HashSet::new();
        let mut variants = tested_variants();
        variants.push(default.with_regen(3));
        variants.push(TraceVariant::new(TraceStack::Workgroup, true).with_split(64));
        for v in variants {
            let source = kernel_source(v);
            // Only a vote uses subgroup operations: every other variant runs without them.
            let voting = v.vote != 0;
            assert_eq!(source.contains("subgroupBallot"), voting, "{v}");
            let name = format!("path.wgsl ({v})");
            let entries: &[&str] = if v.split == 0 {
                &["trace"]
            } else {
                &["trace", "split_start", "split_extend", "split_shade"]
            };
            for entry in entries {
                let module = specialised(&name, &source, voting, entry, &constants(v));
                let e = module
                    .entry_points
                    .iter()
                    .find(|e| e.name == *entry)
                    .unwrap();
                assert_eq!(e.workgroup_size, [v.workgroup, 1, 1], "{v}: {entry}");
                if *entry == "trace" {
                    // Each override became a constant of the variant's value.
                    let regen = v.regen != 0;
                    assert_eq!(const_literal(&module, "REGENERATE"), Literal::Bool(regen));
                    assert_eq!(const_literal(&module, "POSTPONE"), Literal::U32(v.vote));
                }
            }
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
        // The checks are a compile option and the workgroup's size, the regeneration and the
        // vote's percentage pipeline constants, not source changes: 3 stacks, the workgroup
        // stack at each of the 3 other sizes, and the ballot with each stack.
        assert_eq!(sources.len(), 3 + 3 + 3);
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
