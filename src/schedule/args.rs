//! The tracer's indirect dispatch arguments from the list's length (DESIGN.md §6). CPU twin of
//! `shaders/schedule/args.wgsl`.

/// The indirect dispatch grid for `count` listed pixels and a tracer workgroup of
/// `workgroup_size` threads, with at most `max_per_dim` workgroups per dimension (65 535 in
/// WebGPU's defaults; 3840 × 2160 / 64 = 129 600 groups needs two dimensions).
///
/// Returns `[gx, gy, 1]` with gx·gy ≥ ⌈count / workgroup_size⌉, gx, gy ≤ max_per_dim and fewer
/// than gy idle groups; `[0, 1, 1]` when nothing is listed. The tracer's thread for list entry
/// `(wg.y · gx + wg.x) · workgroup_size + local_index` returns when that is ≥ count.
///
/// A regenerating tracer (`max_groups` > 0: the kernel lab's `+regenG`,
/// [`crate::trace::gpu::TraceKernel::max_list_groups`]) launches at most about `max_groups`
/// groups (gx·gy ≥ min(⌈count / workgroup_size⌉, max_groups)); its thread `t` of the
/// gx·gy·workgroup_size launched traces entries t, t + gx·gy·workgroup_size, … Identical to
/// `shaders/schedule/args.wgsl`.
#[must_use]
pub fn indirect_grid(
    count: u32,
    workgroup_size: u32,
    max_groups: u32,
    max_per_dim: u32,
) -> [u32; 3] {
    let mut groups = count.div_ceil(workgroup_size);
    if max_groups > 0 {
        groups = groups.min(max_groups);
    }
    let [gx, gy] = crate::gpu::grid_2d(groups, max_per_dim);
    [gx, gy, 1]
}
