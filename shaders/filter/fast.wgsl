// The fast filter's final pass: per pixel, the exact loop for small kernels, else a read of the
// two pyramid levels whose kernel variance brackets σ² (built by pyramid.wgsl). Concatenated
// after common.wgsl. CPU twin: src/filter/fast.rs (`filter_pixel`).

// The levels (unused ones are bound to a dummy buffer). WGSL has no arrays of bindings without
// an extra feature; `level_texel` switches.
@group(0) @binding(5) var<storage, read> level0: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> level1: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> level2: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read> level3: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read> level4: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> level5: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read> level6: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read> level7: array<vec4<f32>>;
@group(0) @binding(13) var<storage, read> level8: array<vec4<f32>>;

// src/filter/pyramid.rs K_DIRECT and src/filter/fast.rs RIM_WEIGHT (exp(−4.5)).
const K_DIRECT: f32 = 4.0;
const RIM_WEIGHT: f32 = 0.011108996538242306;
const TAU: f32 = 6.283185307179586;

fn level_texel(l: u32, t: u32) -> vec4<f32> {
    switch l {
        case 0u: { return level0[t]; }
        case 1u: { return level1[t]; }
        case 2u: { return level2[t]; }
        case 3u: { return level3[t]; }
        case 4u: { return level4[t]; }
        case 5u: { return level5[t]; }
        case 6u: { return level6[t]; }
        case 7u: { return level7[t]; }
        default: { return level8[t]; }
    }
}

struct LevelRead {
    value: vec4<f32>,
    // Kernel variance of the read: σ_ℓ² plus the bilinear tent's.
    variance: f32,
}

fn read_level(l: u32, x: u32, y: u32) -> LevelRead {
    let d = params.levels[l];
    let t = (vec2<f32>(f32(x), f32(y)) - d.origin) / d.step;
    let i = clamp(vec2<i32>(floor(t)), vec2<i32>(0), vec2<i32>(d.size) - 2);
    let f = t - vec2<f32>(i);
    let base = u32(i.y) * d.size.x + u32(i.x);
    let a = level_texel(l, base);
    let b = level_texel(l, base + 1u);
    let c = level_texel(l, base + d.size.x);
    let e = level_texel(l, base + d.size.x + 1u);
    let v = mix(mix(a, b, f.x), mix(c, e, f.x), f.y);
    let tent = d.step * d.step * (f.x * (1.0 - f.x) + f.y * (1.0 - f.y)) * 0.5;
    return LevelRead(v, d.sigma2 + tent);
}

// The mixed (Σ g·u, Σ g) pair for a kernel of variance sigma2.
fn pyramid_read(x: u32, y: u32, sigma2: f32) -> vec4<f32> {
    var prev = read_level(0u, x, y);
    if prev.variance >= sigma2 {
        return prev.value;
    }
    for (var l = 1u; l < params.level_count; l++) {
        let cur = read_level(l, x, y);
        if cur.variance >= sigma2 {
            let t = (sigma2 - prev.variance) / (cur.variance - prev.variance);
            return mix(prev.value, cur.value, t);
        }
        prev = cur;
    }
    return prev.value;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.size.x || gid.y >= params.size.y {
        return;
    }
    let i = gid.y * params.size.x + gid.x;
    let p = pixel_state(i);
    var o = p.mean;
    if params.mode != MODE_OFF && p.w > 0.0 && p.k >= 1.0 {
        var f = vec4<f32>(0.0);
        if p.k <= K_DIRECT {
            f = window_mean(gid.x, gid.y, p.k);
        } else {
            let sigma2 = p.k * p.k / 9.0;
            let v = pyramid_read(gid.x, gid.y, sigma2);
            if v.w * TAU * sigma2 >= RIM_WEIGHT {
                f = vec4<f32>(v.xyz / v.w, v.w);
            }
        }
        if f.w > 0.0 {
            o = p.w * f.xyz + (1.0 - p.w) * p.mean;
        }
    }
    out_image[i] = vec4<f32>(o, 1.0);
}
