// A cluster rank's owned sums on its GPU (DESIGN.md §12): the samples of the blocks it owns —
// those it traced itself, kept on the GPU since the trace, and those other ranks sent — added to
// their pixels' sums with the one-process kernel's arithmetic (sums += (rgb, lum²)); and the
// rays per owned block it traced (the deal's weights), summed where the samples lie. A pixel
// gets at most one sample a frame, so no two threads of a dispatch write one pixel. CPU twins:
// `accumulate_sums` and `block_rays` in src/trace/accum.rs; dispatch: `OwnedSums` in
// src/trace/gpu/owned.rs.

// Mirrors `GpuOwnedParams` in src/trace/gpu/owned.rs (16 bytes).
struct OwnedParams {
    // Samples in `own` to add (entries 0..own of it).
    own: u32,
    // Samples in `foreign` to add (RGB triples).
    foreign: u32,
    // Owned blocks traced here, for `block_rays`.
    segments: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> cfg: OwnedParams;
// Per owned pixel (BLOCK_PIXELS per owned block, row-major inside the block): RGB sum, Σ lum².
@group(0) @binding(1) var<storage, read_write> sums: array<vec4<f32>>;
// This rank's own samples of owned blocks, as the trace wrote them: RGB, rays as bits.
@group(0) @binding(2) var<storage, read> own: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> own_dst: array<u32>;
// Other ranks' samples of owned blocks, RGB as they travelled.
@group(0) @binding(4) var<storage, read> foreign: array<f32>;
@group(0) @binding(5) var<storage, read> foreign_dst: array<u32>;
// Per owned block traced here: (first entry in `own`, entries).
@group(0) @binding(6) var<storage, read> segments: array<vec2<u32>>;
@group(0) @binding(7) var<storage, read_write> rays: array<u32>;

// Luminance (Rec. 709), as shading.wgsl's `lum` and the CPU's `luminance`.
fn lum(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

fn add_sample(d: u32, rgb: vec3<f32>) {
    let l = lum(rgb);
    sums[d] += vec4<f32>(rgb, l * l);
}

@compute @workgroup_size(256)
fn add(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let i = gid.x + gid.y * groups.x * 256u;
    if i < cfg.own {
        add_sample(own_dst[i], own[i].xyz);
    } else if i < cfg.own + cfg.foreign {
        let j = i - cfg.own;
        add_sample(foreign_dst[j], vec3<f32>(foreign[3u * j], foreign[3u * j + 1u], foreign[3u * j + 2u]));
    }
}

var<workgroup> total: atomic<u32>;

// One workgroup per owned block traced here: the rays of its samples.
@compute @workgroup_size(256)
fn block_rays(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let s = wg.x + wg.y * groups.x;
    if li == 0u {
        atomicStore(&total, 0u);
    }
    workgroupBarrier();
    if s < cfg.segments {
        let seg = segments[s];
        var sum = 0u;
        for (var k = li; k < seg.y; k += 256u) {
            sum += bitcast<u32>(own[seg.x + k].w);
        }
        atomicAdd(&total, sum);
    }
    workgroupBarrier();
    if li == 0u && s < cfg.segments {
        rays[s] = atomicLoad(&total);
    }
}
