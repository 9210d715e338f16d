// raygun's interactive denoiser: an edge-avoiding à-trous wavelet filter over the accumulation,
// steered by albedo, normal and depth features and by each pixel's sample count and variance.
// Definition (exactly) and CPU twin of the same arithmetic: src/filter/denoise/mod.rs;
// dispatch: src/filter/denoise/gpu.rs (the kernel text is included by src/filter/gpu.rs).
//
// Entry points: `init` writes each pixel's (mean, weight) into `dst` and counts the dropped
// (non-finite) pixels of rows count_rows.x..count_rows.y; `atrous` is one pass of step
// params.step from `src` to `dst` (alpha 1 instead of the weight when params.last = 1).

// Mirrors `GpuDenoiseParams` in src/filter/denoise/gpu.rs (32 bytes).
struct DenoiseParams {
    size: vec2<u32>,
    step: u32,
    last: u32,
    variance_threshold: f32,
    _pad0: u32,
    count_rows: vec2<u32>,
}

@group(0) @binding(0) var<uniform> params: DenoiseParams;
// .xyz RGB sum, .w sum of squared luminance (src/trace/accum.rs).
@group(0) @binding(1) var<storage, read> accum: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> counts: array<u32>;
// .xyz albedo (.w ignored).
@group(0) @binding(3) var<storage, read> albedo: array<vec4<f32>>;
// .xyz shading normal, .w primary-hit depth (0 = miss).
@group(0) @binding(4) var<storage, read> normal_depth: array<vec4<f32>>;
// .xyz the current estimate, .w its weight.
@group(0) @binding(5) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> dst: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> dropped: atomic<u32>;

const SIGMA_L: f32 = 4.0;
const SIGMA_A: f32 = 0.05;
const ALBEDO_CUT: f32 = 0.1;
const NORMAL_CUT: f32 = 0.9;
const SIGMA_Z: f32 = 0.05;
const DEPTH_CUT: f32 = 0.1;
const MIN_VARIANCE_SAMPLES: u32 = 4u;

const UNSAMPLED: u32 = 0u;
const DROPPED: u32 = 1u;
const SPARSE: u32 = 2u;
const NOISY: u32 = 3u;
const CONVERGED: u32 = 4u;

// The B-spline taps (1, 4, 6, 4, 1) / 16.
const TAPS = array<f32, 5>(0.0625, 0.25, 0.375, 0.25, 0.0625);

fn luminance(rgb: vec3<f32>) -> f32 {
    return 0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z;
}

// By the bits: WGSL lets a compiler assume that no value is NaN or infinite.
fn is_finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

struct Own {
    mean: vec3<f32>,
    count: f32,
    kind: u32,
    // The variance of the mean luminance (NOISY and CONVERGED; else 0).
    v: f32,
}

fn own(i: u32) -> Own {
    let n = counts[i];
    if n == 0u {
        return Own(vec3<f32>(0.0), 0.0, UNSAMPLED, 0.0);
    }
    let a = accum[i];
    if !(is_finite(a.x) && is_finite(a.y) && is_finite(a.z) && is_finite(a.w)) {
        return Own(vec3<f32>(0.0), 0.0, DROPPED, 0.0);
    }
    let nf = f32(n);
    let mean = a.xyz / nf;
    if n < MIN_VARIANCE_SAMPLES {
        return Own(mean, nf, SPARSE, 0.0);
    }
    let mean_l = luminance(a.xyz) / nf;
    let v = max(0.0, (a.w - nf * mean_l * mean_l) / (nf - 1.0)) / nf;
    if v <= params.variance_threshold {
        return Own(mean, nf, CONVERGED, v);
    }
    return Own(mean, nf, NOISY, v);
}

@compute @workgroup_size(16, 16)
fn init(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.size.x || gid.y >= params.size.y {
        return;
    }
    let i = gid.y * params.size.x + gid.x;
    let o = own(i);
    if o.kind == DROPPED && gid.y >= params.count_rows.x && gid.y < params.count_rows.y {
        atomicAdd(&dropped, 1u);
    }
    dst[i] = vec4<f32>(o.mean, o.count);
}

// The albedo, normal and depth terms of the pair (p, q) (twin: `feature_terms`): x = w_n and
// y = the exponent e, or x < 0 where the tap is cut.
fn feature_terms(p: u32, q: u32) -> vec2<f32> {
    let d = abs(albedo[p].xyz - albedo[q].xyz);
    let da = max(d.x, max(d.y, d.z));
    if da > ALBEDO_CUT {
        return vec2<f32>(-1.0, 0.0);
    }
    let fp = normal_depth[p];
    let fq = normal_depth[q];
    let hit_p = fp.w > 0.0;
    if hit_p != (fq.w > 0.0) {
        return vec2<f32>(-1.0, 0.0);
    }
    let ea = da / SIGMA_A;
    if !hit_p {
        return vec2<f32>(1.0, ea);
    }
    let c = fp.x * fq.x + fp.y * fq.y + fp.z * fq.z;
    if c < NORMAL_CUT {
        return vec2<f32>(-1.0, 0.0);
    }
    let rel = abs(fp.w - fq.w) / max(fp.w, fq.w);
    if rel > DEPTH_CUT {
        return vec2<f32>(-1.0, 0.0);
    }
    // c^64 by six squarings.
    var wn = c;
    for (var k = 0; k < 6; k++) {
        wn = wn * wn;
    }
    return vec2<f32>(wn, ea + rel / SIGMA_Z);
}

@compute @workgroup_size(16, 16)
fn atrous(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.size.x || gid.y >= params.size.y {
        return;
    }
    let size = vec2<i32>(params.size);
    let i = gid.y * params.size.x + gid.x;
    let me = own(i);
    let here = src[i];
    var out = here;
    if me.kind != CONVERGED {
        let lp = luminance(here.xyz);
        let s = i32(params.step);
        var num = vec3<f32>(0.0);
        var den = 0.0;
        var wsum = 0.0;
        for (var ty = 0; ty < 5; ty++) {
            let yy = i32(gid.y) + (ty - 2) * s;
            if yy < 0 || yy >= size.y {
                continue;
            }
            for (var tx = 0; tx < 5; tx++) {
                let xx = i32(gid.x) + (tx - 2) * s;
                if xx < 0 || xx >= size.x {
                    continue;
                }
                let q = u32(yy * size.x + xx);
                let t = src[q];
                var w = TAPS[ty] * TAPS[tx];
                if q != i {
                    let f = feature_terms(i, q);
                    if f.x < 0.0 {
                        continue;
                    }
                    var e = f.y;
                    if me.kind == NOISY {
                        let sd = sqrt(me.v + own(q).v);
                        e = e + abs(lp - luminance(t.xyz)) / (SIGMA_L * sd);
                    }
                    w = w * f.x * exp(-e);
                }
                let wc = w * t.w;
                num = num + wc * t.xyz;
                den = den + wc;
                wsum = wsum + w;
            }
        }
        if den > 0.0 {
            out = vec4<f32>(num / den, den / wsum);
        }
    }
    if params.last == 1u {
        dst[i] = vec4<f32>(out.xyz, 1.0);
    } else {
        dst[i] = out;
    }
}
