//! The kernel lab's trace kernel variants (the `kernel-lab` feature; raygun itself ships one
//! kernel, the default variant): how the trace kernel is compiled, a choice the GPU context
//! carries ([`super::GpuContext::trace_variant`]) and the trace stage applies
//! (`src/trace/gpu/lab.rs` turns a variant into the kernel's source, its pipeline constants and
//! compile options). Every variant computes the same function; they differ in the code a GPU
//! runs, so that one binary can time them all. It lives in the base layer because the context
//! carries it.

use super::GpuError;

/// Threads per workgroup of the trace kernel unless a variant says otherwise (the override
/// `WORKGROUP` in `shaders/trace/path.wgsl`; `crate::trace::gpu::WORKGROUP`).
pub const DEFAULT_WORKGROUP: u32 = 64;

/// Where the trace kernel keeps its BVH traversal stack (`STACK_SIZE` = 32 entries of 8
/// bytes a ray, in `shaders/trace/bvh.wgsl`). Every choice visits the same nodes in the same
/// order and finds the same hits; they differ only in the memory the GPU uses, which on a GPU
/// decides how fast a traversal-bound scene (the 343 740-triangle city) traces. Chosen per
/// context ([`super::GpuContext::with_trace_variant`], `RAYGUN_TRACE_KERNEL`) so that one
/// binary can time every choice on one GPU machine.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TraceStack {
    /// A module-scope private variable (the kernel as written): local memory, zeroed once a
    /// thread.
    #[default]
    Private,
    /// A variable of `traverse` (the kernel before 2026-12-05): WGSL zero-initialises it at
    /// every call, so every ray first writes 256 bytes of the thread's local memory.
    Function,
    /// Workgroup (shared) memory, entry `i` of thread `l` at `i · WORKGROUP + l` (16 KiB a
    /// workgroup of 64, 256 bytes a thread; wgpu zeroes it once a workgroup).
    Workgroup,
}

/// A compiled variant of the trace kernel: the same function (tested against the default bit
/// for bit), different code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TraceVariant {
    pub stack: TraceStack,
    /// Compiled without wgpu's run-time checks (index clamping of the kernel's arrays, loop
    /// counters, integer-division guards): `wgpu::ShaderRuntimeChecks::unchecked`. Sound
    /// because the kernel bounds every index itself (the stack's pushes and pops, the lists by
    /// their counts, the scene's indices by construction) and every loop ends; for timing.
    pub unchecked: bool,
    /// Threads per workgroup, one of [`TraceVariant::WORKGROUPS`]: the kernel waits at a
    /// barrier for the group's longest path before it ends (its ray count's reduction), so the
    /// size decides how long finished threads hold their registers.
    pub workgroup: u32,
    /// Launches of at most this many workgroups (0: a thread a path) — full frames, the
    /// scheduler's lists (guided iterations) and a cluster rank's samples: each thread starts
    /// its next path as soon as its last one ends (path regeneration, Novák et al. 2010), so a
    /// group's threads stay busy while paths of different lengths finish.
    pub regen: u32,
    /// Full frames in the wavefront split (0: off): three kernels a bounce apart — the paths'
    /// start, their closest hits, the rest of each bounce — over chunks of this many paths
    /// (88 bytes each on the GPU while the chunk is traced), so that the traversal runs in a
    /// kernel of its own with few registers (Laine et al. 2013, "Megakernels considered
    /// harmful"). Lists keep the one kernel. Not with [`Self::regen`].
    pub split: u32,
    /// Triangle postponing by subgroup vote at this percentage (0: off; 1 to 100): a lane
    /// whose leaf's triangles fewer than this share of its subgroup's traversing lanes are
    /// testing with it walks on into its next node and tests them before its next pop
    /// (Ylitie, Karras and Laine 2017, §4, who found 20 % best on their GPUs), so that a
    /// subgroup's lanes spend less time waiting on each other's triangle loops. Needs the
    /// adapter's subgroup operations (`wgpu::Features::SUBGROUP`).
    pub vote: u32,
}

impl Default for TraceVariant {
    fn default() -> Self {
        Self::new(TraceStack::Private, false)
    }
}

/// Entries of the trace kernel's traversal stack (`STACK_SIZE` in `shaders/trace/bvh.wgsl`;
/// `crate::trace::gpu::STACK_ENTRIES`).
pub const STACK_ENTRIES: u32 = 32;

/// Bytes of one thread's traversal stack ([`STACK_ENTRIES`] of `vec2<u32>`).
pub const STACK_BYTES: u32 = STACK_ENTRIES * 8;

impl TraceVariant {
    /// The workgroup sizes a variant may have.
    pub const WORKGROUPS: [u32; 4] = [32, 64, 128, 256];

    /// Every stack and checks choice at the default workgroup size, the default first.
    pub const ALL: [Self; 6] = [
        Self::new(TraceStack::Private, false),
        Self::new(TraceStack::Function, false),
        Self::new(TraceStack::Workgroup, false),
        Self::new(TraceStack::Private, true),
        Self::new(TraceStack::Function, true),
        Self::new(TraceStack::Workgroup, true),
    ];

    /// `stack`, checks off where `unchecked`, [`DEFAULT_WORKGROUP`] threads a group.
    #[must_use]
    pub const fn new(stack: TraceStack, unchecked: bool) -> Self {
        Self {
            stack,
            unchecked,
            workgroup: DEFAULT_WORKGROUP,
            regen: 0,
            split: 0,
            vote: 0,
        }
    }

    /// The percentage `+vote` means without a number: Ylitie, Karras and Laine's.
    pub const VOTE_PERCENT: u32 = 20;

    /// This variant postponing triangle tests by subgroup vote at `percent` (0: off).
    #[must_use]
    pub const fn with_vote(self, percent: u32) -> Self {
        Self {
            vote: percent,
            ..self
        }
    }

    /// Paths a chunk of the wavefront split has where `+split` names no number: 20 MiB of
    /// path state, within a large GPU's L2 cache.
    pub const SPLIT_CHUNK: u32 = 1 << 18;

    /// This variant tracing full frames in the wavefront split, `paths` a chunk (0: off).
    #[must_use]
    pub const fn with_split(self, paths: u32) -> Self {
        Self {
            split: paths,
            ..self
        }
    }

    /// This variant regenerating full frames' paths in at most `groups` workgroups (0: off).
    #[must_use]
    pub const fn with_regen(self, groups: u32) -> Self {
        Self {
            regen: groups,
            ..self
        }
    }

    /// This variant with `threads` a workgroup (one of [`Self::WORKGROUPS`]).
    #[must_use]
    pub const fn with_workgroup(self, threads: u32) -> Self {
        Self {
            workgroup: threads,
            ..self
        }
    }

    /// Workgroup memory the kernel takes (bytes): its ray count, and the stacks of a
    /// [`TraceStack::Workgroup`] variant.
    #[must_use]
    pub fn workgroup_bytes(self) -> u32 {
        4 + match self.stack {
            TraceStack::Workgroup => STACK_BYTES * self.workgroup,
            _ => 0,
        }
    }

    /// Whether a device of `limits` and `features` can run this variant: its workgroup's
    /// threads and memory, and the subgroup operations a `+vote` variant needs.
    pub fn check(self, limits: &wgpu::Limits, features: wgpu::Features) -> Result<(), GpuError> {
        let refuse = |why: String| {
            Err(GpuError::TraceVariant {
                variant: self.to_string(),
                why,
            })
        };
        if !Self::WORKGROUPS.contains(&self.workgroup) {
            return refuse(format!(
                "{} threads a workgroup; expected one of {:?}",
                self.workgroup,
                Self::WORKGROUPS
            ));
        }
        if self.workgroup > limits.max_compute_invocations_per_workgroup
            || self.workgroup > limits.max_compute_workgroup_size_x
        {
            return refuse(format!(
                "{} threads a workgroup; this adapter allows {}",
                self.workgroup,
                limits
                    .max_compute_invocations_per_workgroup
                    .min(limits.max_compute_workgroup_size_x)
            ));
        }
        if self.vote != 0 && !features.contains(wgpu::Features::SUBGROUP) {
            return refuse("votes with subgroup operations; this adapter has none".into());
        }
        let needs = self.workgroup_bytes();
        if needs > limits.max_compute_workgroup_storage_size {
            return refuse(format!(
                "needs {needs} bytes of workgroup memory; this adapter allows {}",
                limits.max_compute_workgroup_storage_size
            ));
        }
        Ok(())
    }
}

impl std::fmt::Display for TraceVariant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self.stack {
            TraceStack::Function => "function",
            TraceStack::Private => "private",
            TraceStack::Workgroup => "workgroup",
        })?;
        if self.unchecked {
            f.write_str("+unchecked")?;
        }
        if self.workgroup != DEFAULT_WORKGROUP {
            write!(f, "+wg{}", self.workgroup)?;
        }
        if self.regen != 0 {
            write!(f, "+regen{}", self.regen)?;
        }
        match self.split {
            0 => {}
            Self::SPLIT_CHUNK => f.write_str("+split")?,
            n => write!(f, "+split{n}")?,
        }
        match self.vote {
            0 => {}
            Self::VOTE_PERCENT => f.write_str("+vote")?,
            p => write!(f, "+vote{p}")?,
        }
        Ok(())
    }
}

impl std::str::FromStr for TraceVariant {
    type Err = String;

    /// `function`, `private` or `workgroup` (the stack), then optionally `+unchecked`, `+wgN`
    /// (N threads a workgroup: 32, 64, 128 or 256), and `+regenG` (paths regenerated
    /// in launches of at most G workgroups, 1 to 65 535) or `+split[N]` (full frames in the
    /// wavefront split, N paths a chunk: a multiple of 64 up to 2²⁴, [`Self::SPLIT_CHUNK`]
    /// without N), and `+vote[P]` (triangle tests postponed by subgroup vote at P %, 1 to 100,
    /// [`Self::VOTE_PERCENT`] without P), e.g. `private+unchecked+wg32`, `private+regen2048`,
    /// `workgroup+split` or `private+vote`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || {
            format!(
                "unknown trace kernel {s:?}: expected function, private or workgroup, then \
                 optionally +unchecked, +wgN (N = 32, 64, 128 or 256), and +regenG (G = 1 to \
                 65535 workgroups) or +split[N] (full frames in three kernels, N paths a chunk: \
                 a multiple of 64 up to 16777216; 262144 without N), and +vote[P] (triangle \
                 tests postponed by subgroup vote at P = 1 to 100 %; 20 without P), e.g. \
                 private+unchecked+wg32"
            )
        };
        let number = |w: &str, prefix: &str| w.strip_prefix(prefix)?.parse::<u32>().ok();
        let mut words = s.trim().split('+');
        let stack = match words.next() {
            Some("function") => TraceStack::Function,
            Some("private") => TraceStack::Private,
            Some("workgroup") => TraceStack::Workgroup,
            _ => return Err(bad()),
        };
        let mut v = Self::new(stack, false);
        let mut sized = false;
        for w in words {
            if w == "unchecked" && !v.unchecked {
                v.unchecked = true;
            } else if let Some(n) = number(w, "wg").filter(|n| Self::WORKGROUPS.contains(n)) {
                if std::mem::replace(&mut sized, true) {
                    return Err(bad());
                }
                v.workgroup = n;
            } else if let Some(g) = number(w, "regen").filter(|g| (1..=65_535).contains(g)) {
                if v.regen != 0 {
                    return Err(bad());
                }
                v.regen = g;
            } else if let Some(n) = (w == "split").then_some(Self::SPLIT_CHUNK).or_else(|| {
                number(w, "split").filter(|n| (64..=1 << 24).contains(n) && n % 64 == 0)
            }) {
                if v.split != 0 {
                    return Err(bad());
                }
                v.split = n;
            } else if let Some(p) = (w == "vote")
                .then_some(Self::VOTE_PERCENT)
                .or_else(|| number(w, "vote").filter(|p| (1..=100).contains(p)))
            {
                if v.vote != 0 {
                    return Err(bad());
                }
                v.vote = p;
            } else {
                return Err(bad());
            }
        }
        if v.split != 0 && v.regen != 0 {
            return Err(bad());
        }
        Ok(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variants_name_themselves_and_parse_back() {
        for stack in [
            TraceStack::Private,
            TraceStack::Function,
            TraceStack::Workgroup,
        ] {
            for unchecked in [false, true] {
                for n in TraceVariant::WORKGROUPS {
                    for g in [0, 1, 2048, 65_535] {
                        for p in [0, 1, TraceVariant::VOTE_PERCENT, 35, 100] {
                            let v = TraceVariant::new(stack, unchecked)
                                .with_workgroup(n)
                                .with_regen(g)
                                .with_vote(p);
                            assert_eq!(v.to_string().parse::<TraceVariant>(), Ok(v));
                        }
                    }
                }
            }
        }
        assert_eq!(
            "private+regen512+wg32".parse(),
            Ok(TraceVariant::default().with_workgroup(32).with_regen(512))
        );
        for n in [64, 4096, TraceVariant::SPLIT_CHUNK, 1 << 24] {
            let v = TraceVariant::new(TraceStack::Workgroup, true).with_split(n);
            assert_eq!(v.to_string().parse::<TraceVariant>(), Ok(v));
        }
        assert_eq!(
            "private+split".parse(),
            Ok(TraceVariant::default().with_split(1 << 18))
        );
        assert_eq!(
            TraceVariant::default().with_split(1 << 18).to_string(),
            "private+split"
        );
        assert_eq!(
            TraceVariant::default().with_split(4096).to_string(),
            "private+split4096"
        );
        for bad in [
            "private+split0",
            "private+split63",
            "private+split100",
            "private+split33554432",
            "private+split+split",
            "private+split+regen4",
            "private+regen4+split64",
        ] {
            assert!(bad.parse::<TraceVariant>().is_err(), "{bad}");
        }
        assert_eq!(
            "private+vote".parse(),
            Ok(TraceVariant::default().with_vote(20))
        );
        assert_eq!(
            TraceVariant::default().with_vote(20).to_string(),
            "private+vote"
        );
        assert_eq!(
            "workgroup+vote35+split".parse(),
            Ok(TraceVariant::new(TraceStack::Workgroup, false)
                .with_split(TraceVariant::SPLIT_CHUNK)
                .with_vote(35))
        );
        for bad in [
            "private+vote0",
            "private+vote101",
            "private+vote+vote",
            "private+vote20+vote",
            "private+votes",
        ] {
            assert!(bad.parse::<TraceVariant>().is_err(), "{bad}");
        }
        for bad in [
            "private+regen0",
            "private+regen65536",
            "private+regen",
            "private+regen4+regen8",
        ] {
            assert!(bad.parse::<TraceVariant>().is_err(), "{bad}");
        }
        assert_eq!(TraceVariant::default().to_string(), "private");
        assert_eq!(
            " workgroup+wg32+unchecked ".parse::<TraceVariant>(),
            Ok(TraceVariant::new(TraceStack::Workgroup, true).with_workgroup(32))
        );
        assert_eq!(
            "private+wg64".parse(),
            Ok(TraceVariant::new(TraceStack::Private, false))
        );
        for bad in [
            "",
            "shared",
            "workgroup+",
            "+unchecked",
            "unchecked+workgroup",
            "function+unchecked+unchecked",
            "function+wg48",
            "function+wg32+wg64",
            "function+wg",
        ] {
            let err = bad.parse::<TraceVariant>().unwrap_err();
            assert!(
                err.contains("function, private or workgroup"),
                "{bad:?}: {err}"
            );
        }
    }

    #[test]
    fn variants_the_adapter_cannot_run_are_refused_by_name() {
        let mut limits = wgpu::Limits {
            max_compute_workgroup_storage_size: 4 + 32 * 8 * 64,
            ..wgpu::Limits::default()
        };
        for v in TraceVariant::ALL {
            v.check(&limits, wgpu::Features::empty()).unwrap();
        }
        limits.max_compute_workgroup_storage_size -= 1;
        let err = TraceVariant::new(TraceStack::Workgroup, false)
            .check(&limits, wgpu::Features::empty())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("trace kernel workgroup:") && err.contains("16388 bytes"),
            "{err}"
        );
        TraceVariant::new(TraceStack::Private, true)
            .check(&limits, wgpu::Features::empty())
            .unwrap();
        // The workgroup stack grows with the workgroup: 64 KiB at 256 threads.
        limits.max_compute_workgroup_storage_size = 49_152;
        let big = TraceVariant::new(TraceStack::Workgroup, true).with_workgroup(256);
        let err = big
            .check(&limits, wgpu::Features::empty())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("workgroup+unchecked+wg256") && err.contains("65540"),
            "{err}"
        );
        limits.max_compute_invocations_per_workgroup = 128;
        let err = TraceVariant::default()
            .with_workgroup(256)
            .check(&limits, wgpu::Features::empty())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("256 threads") && err.contains("allows 128"),
            "{err}"
        );
        // A vote needs the adapter's subgroup operations.
        let vote = TraceVariant::default().with_vote(20);
        let err = vote
            .check(&limits, wgpu::Features::empty())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("private+vote") && err.contains("subgroup"),
            "{err}"
        );
        vote.check(&limits, wgpu::Features::SUBGROUP).unwrap();
        let odd = TraceVariant::default().with_workgroup(48);
        assert!(
            odd.check(&limits, wgpu::Features::empty())
                .unwrap_err()
                .to_string()
                .contains("[32, 64, 128, 256]")
        );
    }
}
