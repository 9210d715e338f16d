// Sparse-sample filter, shared part of exact.wgsl and fast.wgsl (concatenated before them: WGSL
// has no includes). Definitions: src/filter/mod.rs; CPU twins: src/filter/exact.rs and
// src/filter/fast.rs; dispatch: src/filter/gpu.rs.

// Mirrors `GpuLevel` in src/filter/gpu.rs (32 bytes).
struct LevelDesc {
    size: vec2<u32>,
    // Full-resolution position of texel 0's centre (both axes); texel t at origin + t·step.
    origin: f32,
    step: f32,
    sigma2: f32,
    _pad0: f32,
    _pad1: f32,
    _pad2: f32,
}

// Mirrors `GpuParams` in src/filter/gpu.rs (320 bytes).
struct Params {
    size: vec2<u32>,
    // 0: off (the unfiltered mean), 1: filter.
    mode: u32,
    // 0: count (w = max(0, 1 − s/c)), 1: variance of the mean against a threshold.
    blend: u32,
    level_count: u32,
    k_max: f32,
    c: f32,
    variance_threshold: f32,
    levels: array<LevelDesc, 9>,
}

@group(0) @binding(0) var<uniform> params: Params;
// .xyz RGB sum, .w sum of squared luminance (src/trace/accum.rs).
@group(0) @binding(1) var<storage, read> accum: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> counts: array<u32>;
@group(0) @binding(3) var<storage, read> dgi: array<f32>;
@group(0) @binding(4) var<storage, read_write> out_image: array<vec4<f32>>;

const MODE_OFF: u32 = 0u;
const BLEND_VARIANCE: u32 = 1u;

fn luminance(rgb: vec3<f32>) -> f32 {
    return 0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z;
}

// u_i: the pixel's mean, 0 without samples.
fn unfiltered(i: u32) -> vec3<f32> {
    let n = counts[i];
    if n == 0u {
        return vec3<f32>(0.0);
    }
    return accum[i].xyz / f32(n);
}

// w_i (src/filter/mod.rs `blend_weight`).
fn blend_weight(i: u32) -> f32 {
    let n = counts[i];
    if params.blend != BLEND_VARIANCE {
        return max(0.0, 1.0 - f32(n) / params.c);
    }
    if n < 2u {
        return 1.0;
    }
    let a = accum[i];
    let nf = f32(n);
    let mean_l = luminance(a.xyz) / nf;
    let v = max(0.0, (a.w - nf * mean_l * mean_l) / (nf - 1.0)) / nf;
    if v <= params.variance_threshold {
        return 0.0;
    }
    return 1.0 - params.variance_threshold / v;
}

// (Σ g·u_j / Σ g, Σ g) over the sampled pixels of the window dx² + dy² ≤ k², g the Gaussian of
// σ = k/3 (src/filter/exact.rs `window_mean`); .w = 0 when the window holds no sampled pixel.
fn window_mean(x: u32, y: u32, k: f32) -> vec4<f32> {
    let r = i32(floor(k));
    let k2 = k * k;
    let scale = -4.5 / k2;
    let size = vec2<i32>(params.size);
    let y0 = max(i32(y) - r, 0);
    let y1 = min(i32(y) + r, size.y - 1);
    let x0 = max(i32(x) - r, 0);
    let x1 = min(i32(x) + r, size.x - 1);
    var num = vec3<f32>(0.0);
    var den = 0.0;
    for (var yy = y0; yy <= y1; yy++) {
        let dy = yy - i32(y);
        for (var xx = x0; xx <= x1; xx++) {
            let dx = xx - i32(x);
            let r2 = f32(dx * dx + dy * dy);
            let j = u32(yy * size.x + xx);
            let n = counts[j];
            if r2 > k2 || n == 0u {
                continue;
            }
            let g = exp(scale * r2);
            num += g * (accum[j].xyz / f32(n));
            den += g;
        }
    }
    if den > 0.0 {
        return vec4<f32>(num / den, den);
    }
    return vec4<f32>(0.0);
}

struct Pixel {
    mean: vec3<f32>,
    w: f32,
    k: f32,
}

fn pixel_state(i: u32) -> Pixel {
    let w = blend_weight(i);
    return Pixel(unfiltered(i), w, w * params.k_max * dgi[i]);
}
