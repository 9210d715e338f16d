// The tracer's indirect dispatch arguments from the compaction's count, and the counter's
// reset for the next iteration (DESIGN.md §6: no read-back). One thread. CPU twin:
// indirect_grid in src/schedule/mod.rs; dispatch: src/schedule/gpu.rs.

// Mirrors `GpuArgsParams` in src/schedule/gpu.rs (16 bytes).
struct ArgsParams {
    // Threads per tracer workgroup.
    workgroup_size: u32,
    // The adapter's max_compute_workgroups_per_dimension.
    max_per_dim: u32,
    // A regenerating tracer's most workgroups (0: a thread an entry); its threads then trace
    // several entries each (shaders/trace/path.wgsl, `trace_jobs`).
    max_groups: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> cfg: ArgsParams;
@group(0) @binding(1) var<storage, read_write> counter: atomic<u32>;
// (gx, gy, gz) for dispatch_workgroups_indirect, then the number of listed pixels.
@group(0) @binding(2) var<storage, read_write> args: array<u32, 4>;

fn div_ceil(a: u32, b: u32) -> u32 {
    return a / b + select(0u, 1u, a % b != 0u);
}

@compute @workgroup_size(1)
fn main() {
    let count = atomicExchange(&counter, 0u);
    var groups = div_ceil(count, cfg.workgroup_size);
    if cfg.max_groups > 0u {
        groups = min(groups, cfg.max_groups);
    }
    var gx = 0u;
    var gy = 1u;
    if groups > 0u {
        gy = div_ceil(groups, cfg.max_per_dim);
        gx = div_ceil(groups, gy);
    }
    args[0] = gx;
    args[1] = gy;
    args[2] = 1u;
    args[3] = count;
}
