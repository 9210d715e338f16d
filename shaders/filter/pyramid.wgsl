// One separable blur pass of the fast filter's pyramid: out(X) = Σ_t w_t · in(X·dec + first + t)
// along one axis, reads outside the source being 0 (unsampled). The passes and their weights
// come from `Plan` in src/filter/pyramid.rs (the CPU twin, `run_pass`); dispatch: src/filter/gpu.rs.
// Texels hold (Σ g·u.rgb, Σ g): a normalised convolution over sampled pixels only.

// Mirrors `GpuPass` in src/filter/gpu.rs (112 bytes).
struct Pass {
    src_size: vec2<u32>,
    dst_size: vec2<u32>,
    axis: u32,
    dec: u32,
    first: i32,
    taps: u32,
    // 20 weights (MAX_TAPS), four per vec4 (uniform arrays have a 16-byte stride).
    weights: array<vec4<f32>, 5>,
}

@group(0) @binding(0) var<uniform> pass_params: Pass;
@group(0) @binding(1) var<storage, read> accum: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> counts: array<u32>;
@group(0) @binding(3) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> dst: array<vec4<f32>>;

fn tap_weight(t: u32) -> f32 {
    return pass_params.weights[t / 4u][t % 4u];
}

// (the source texel index, whether it lies inside the source) of tap t for output (x, y).
fn tap_index(x: u32, y: u32, t: u32) -> vec2<i32> {
    var base = i32(x);
    var len = i32(pass_params.src_size.x);
    if pass_params.axis == 1u {
        base = i32(y);
        len = i32(pass_params.src_size.y);
    }
    let j = base * i32(pass_params.dec) + pass_params.first + i32(t);
    if j < 0 || j >= len {
        return vec2<i32>(0, 0);
    }
    var idx = i32(y) * i32(pass_params.src_size.x) + j;
    if pass_params.axis == 1u {
        idx = j * i32(pass_params.src_size.x) + i32(x);
    }
    return vec2<i32>(idx, 1);
}

// Level 0's x pass: reads the accumulation as (u, 1) for sampled pixels, 0 elsewhere.
@compute @workgroup_size(16, 16)
fn blur_accumulation(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= pass_params.dst_size.x || gid.y >= pass_params.dst_size.y {
        return;
    }
    var acc = vec4<f32>(0.0);
    for (var t = 0u; t < pass_params.taps; t++) {
        let j = tap_index(gid.x, gid.y, t);
        if j.y == 0 {
            continue;
        }
        let n = counts[j.x];
        if n > 0u {
            acc += tap_weight(t) * vec4<f32>(accum[j.x].xyz / f32(n), 1.0);
        }
    }
    dst[gid.y * pass_params.dst_size.x + gid.x] = acc;
}

@compute @workgroup_size(16, 16)
fn blur(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= pass_params.dst_size.x || gid.y >= pass_params.dst_size.y {
        return;
    }
    var acc = vec4<f32>(0.0);
    for (var t = 0u; t < pass_params.taps; t++) {
        let j = tap_index(gid.x, gid.y, t);
        if j.y == 0 {
            continue;
        }
        acc += tap_weight(t) * src[j.x];
    }
    dst[gid.y * pass_params.dst_size.x + gid.x] = acc;
}
