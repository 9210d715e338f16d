// The path-tracing integrator (CPU twin: src/trace/cpu.rs). One thread traces one path for one
// pixel — every pixel in tile order (full frame) or the pixels of the scheduler's list — and
// adds it to the pixel's accumulation.

struct Params {
    size: vec2<u32>,
    count: u32,       // full frame: threads to run (tile-padded pixel count)
    mode: u32,        // 0 full frame, 1 the scheduler's list
    seed: u32,
    max_depth: u32,
    light_count: u32,
    groups_x: u32,    // full frame: workgroups per grid row
    env_size: vec2<u32>,
    env_marginal: u32,
    env_conditional: u32,
    env_constant: vec3<f32>,
    env_select: f32,
    cam_pos: vec3<f32>,
    tan_half_y: f32,
    cam_fwd: vec3<f32>,
    aspect: f32,
    cam_right: vec3<f32>,
    node_count: u32,
    cam_up: vec3<f32>,
    _pad: u32,
}

const NO_TEXTURE: u32 = 0xffffffffu;
const STREAM_TRACE: u32 = 0x7a3c0000u;
const WORKGROUP: u32 = 64u;

@group(0) @binding(2) var<storage, read> shade: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> materials: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> texels: array<u32>;
@group(0) @binding(5) var<storage, read> lights: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> dist: array<f32>;
@group(0) @binding(7) var<storage, read> env: array<vec4<f32>>;

@group(1) @binding(0) var<uniform> params: Params;
@group(1) @binding(1) var<storage, read_write> accum: array<vec4<f32>>;
@group(1) @binding(2) var<storage, read_write> counts: array<u32>;
@group(1) @binding(3) var<storage, read> list: array<u32>;
@group(1) @binding(4) var<storage, read> args: array<u32>; // (x, y, z, count)
// [0]: rays traced (closest-hit and shadow), summed per workgroup then added once.
@group(1) @binding(5) var<storage, read_write> stats: array<atomic<u32>>;

var<private> rays_traced: u32;
var<workgroup> workgroup_rays: atomic<u32>;

fn rand4(pixel: u32, sample: u32, dim: u32) -> vec4<f32> {
    let r = pcg4d(vec4<u32>(pixel, sample, params.seed, STREAM_TRACE + dim));
    return vec4<f32>(unit_f32(r.x), unit_f32(r.y), unit_f32(r.z), unit_f32(r.w));
}

fn mis(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    let b2 = b * b;
    if a2 + b2 > 0.0 {
        return a2 / (a2 + b2);
    }
    return 0.0;
}

fn sample_cdf(offset: u32, n: u32, u: f32) -> u32 {
    var lo = 0u;
    var hi = n;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if dist[offset + mid] <= u {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

fn texel(off: u32, w: u32, h: u32, x: i32, y: i32) -> vec4<f32> {
    let wi = i32(w);
    let hi = i32(h);
    let xi = u32(((x % wi) + wi) % wi);
    let yi = u32(((y % hi) + hi) % hi);
    let c = texels[off + yi * w + xi];
    let ch = vec4<f32>(f32(c & 0xffu), f32((c >> 8u) & 0xffu), f32((c >> 16u) & 0xffu), f32(c >> 24u)) / 255.0;
    return vec4<f32>(srgb_to_linear(ch.x), srgb_to_linear(ch.y), srgb_to_linear(ch.z), ch.w);
}

fn texture(tex: u32, uv_in: vec2<f32>) -> vec4<f32> {
    let off = texels[4u * tex];
    let w = texels[4u * tex + 1u];
    let h = texels[4u * tex + 2u];
    // Non-finite coordinates read as 0 (the CPU twin does the same).
    var uv = uv_in;
    if !(abs(uv.x) <= T_FAR && abs(uv.y) <= T_FAR) {
        uv = vec2<f32>(0.0);
    }
    let x = uv.x * f32(w) - 0.5;
    let y = uv.y * f32(h) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let xi = i32(x0);
    let yi = i32(y0);
    let a = texel(off, w, h, xi, yi);
    let b = texel(off, w, h, xi + 1, yi);
    let c = texel(off, w, h, xi, yi + 1);
    let d = texel(off, w, h, xi + 1, yi + 1);
    return (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy;
}

// Radiance in .xyz, sampling density in .w.
fn env_eval(d: vec3<f32>) -> vec4<f32> {
    let w = params.env_size.x;
    let h = params.env_size.y;
    if w == 0u {
        return vec4<f32>(params.env_constant, 1.0 / (4.0 * PI));
    }
    let uv = direction_to_equirect(d);
    let col = min(u32(uv.x * f32(w)), w - 1u);
    let row = min(u32(uv.y * f32(h)), h - 1u);
    let e = env[row * w + col];
    let sin_theta = sqrt(max(1.0 - d.y * d.y, 0.0));
    var pdf = 0.0;
    if sin_theta > 0.0 {
        pdf = e.w / (2.0 * PI * PI * sin_theta);
    }
    return vec4<f32>(e.xyz, pdf);
}

struct EnvSample {
    dir: vec3<f32>,
    radiance: vec3<f32>,
    pdf: f32,
}

fn sample_env(u1: f32, u2: f32) -> EnvSample {
    let w = params.env_size.x;
    let h = params.env_size.y;
    if w == 0u {
        return EnvSample(uniform_sphere(u1, u2), params.env_constant, 1.0 / (4.0 * PI));
    }
    let row = sample_cdf(params.env_marginal, h, u1);
    let r0 = dist[params.env_marginal + row];
    let r1 = dist[params.env_marginal + row + 1u];
    var fy = 0.5;
    if r1 > r0 {
        fy = clamp((u1 - r0) / (r1 - r0), 0.0, 1.0);
    }
    let base = params.env_conditional + row * (w + 1u);
    let col = sample_cdf(base, w, u2);
    let c0 = dist[base + col];
    let c1 = dist[base + col + 1u];
    var fx = 0.5;
    if c1 > c0 {
        fx = clamp((u2 - c0) / (c1 - c0), 0.0, 1.0);
    }
    let uu = (f32(col) + fx) / f32(w);
    let vv = (f32(row) + fy) / f32(h);
    let d = equirect_to_direction(uu, vv);
    let e = env[row * w + col];
    let sin_theta = sin(vv * PI);
    var pdf = 0.0;
    if sin_theta > 0.0 {
        pdf = e.w / (2.0 * PI * PI * sin_theta);
    }
    return EnvSample(d, e.xyz, pdf);
}

fn camera_direction(x: f32, y: f32) -> vec3<f32> {
    let sx = (2.0 * x / f32(params.size.x) - 1.0) * params.tan_half_y * params.aspect;
    let sy = (1.0 - 2.0 * y / f32(params.size.y)) * params.tan_half_y;
    return normalize(params.cam_fwd + params.cam_right * sx + params.cam_up * sy);
}

fn is_finite3(v: vec3<f32>) -> bool {
    return all(abs(v) <= vec3<f32>(T_FAR));
}

fn trace_sample(pixel: u32, sample: u32) -> vec3<f32> {
    let x = pixel % params.size.x;
    let y = pixel / params.size.x;
    let r0 = rand4(pixel, sample, 0u);
    var d = camera_direction(f32(x) + r0.x, f32(y) + r0.y);
    var o = params.cam_pos;
    var throughput = vec3<f32>(1.0);
    var radiance = vec3<f32>(0.0);
    var prev_pdf = 0.0;
    for (var depth = 0u; depth < params.max_depth; depth++) {
        let hit = traverse(o, d, T_FAR, false);
        if hit.prim == NO_HIT {
            let le = env_eval(d);
            var w = 1.0;
            if prev_pdf != 0.0 {
                w = mis(prev_pdf, params.env_select * le.w);
            }
            radiance += throughput * le.xyz * w;
            break;
        }
        let pa = prims[3u * hit.prim];
        let pb = prims[3u * hit.prim + 1u];
        let pc = prims[3u * hit.prim + 2u];
        let v0 = pa.xyz;
        let e1 = pb.xyz;
        let e2 = pc.xyz;
        let light_density = pb.w;
        var ng = normalize(cross(e1, e2));
        let p = v0 + e1 * hit.u + e2 * hit.v;
        let ti = 4u * bitcast<u32>(pa.w);
        let s0 = shade[ti];
        let s1 = shade[ti + 1u];
        let s2 = shade[ti + 2u];
        let s3 = shade[ti + 3u];
        let b0 = 1.0 - hit.u - hit.v;
        var ns = normalize(s0.xyz * b0 + s1.xyz * hit.u + s2.xyz * hit.v);
        if !is_finite3(ns) {
            ns = ng;
        }
        let uv = vec2<f32>(s0.w, s1.w) * b0 + vec2<f32>(s2.w, s3.x) * hit.u + vec2<f32>(s3.y, s3.z) * hit.v;
        let mi = 3u * bitcast<u32>(s3.w);
        let m0 = materials[mi];
        let m1 = materials[mi + 1u];
        let m2 = materials[mi + 2u];
        let wo = -d;
        let cos_hit = abs(dot(ng, d));
        if dot(ng, wo) < 0.0 {
            ng = -ng;
        }
        if dot(ns, ng) < 0.0 {
            ns = -ns;
        }
        let emission = m1.xyz;
        if any(emission != vec3<f32>(0.0)) {
            var w = 1.0;
            if prev_pdf != 0.0 {
                let pdf_light = (1.0 - params.env_select) * light_density * hit.t * hit.t / cos_hit;
                w = mis(prev_pdf, pdf_light);
            }
            radiance += throughput * emission * w;
        }
        var base = m0;
        let tex = bitcast<u32>(m1.w);
        if tex != NO_TEXTURE {
            base *= texture(tex, uv);
        }
        let bsdf = Bsdf(base.xyz, m2.x, m2.y, m2.z);
        let r1 = rand4(pixel, sample, 1u + 2u * depth);
        let r2 = rand4(pixel, sample, 2u + 2u * depth);
        let po = offset_ray(p, ng);

        if params.env_select > 0.0 || params.light_count > 0u {
            var wi: vec3<f32>;
            var le: vec3<f32>;
            var pdf_l: f32;
            var tmax: f32;
            if r1.x < params.env_select {
                let es = sample_env(r1.y, r1.z);
                wi = es.dir;
                le = es.radiance;
                pdf_l = params.env_select * es.pdf;
                tmax = T_FAR;
            } else {
                let u = min((r1.x - params.env_select) / (1.0 - params.env_select), 0.99999994);
                let k = sample_cdf(0u, params.light_count, u);
                let la = lights[3u * k];
                let le1 = lights[3u * k + 1u].xyz;
                let le2 = lights[3u * k + 2u].xyz;
                var a = r1.y;
                var b = r1.z;
                if a + b > 1.0 {
                    a = 1.0 - a;
                    b = 1.0 - b;
                }
                let q = la.xyz + le1 * a + le2 * b;
                let to = q - po;
                let dist2 = dot(to, to);
                let dl = sqrt(dist2);
                wi = to / dl;
                let n_l = cross(le1, le2);
                let area2 = length(n_l);
                // A single-sided light emits from its front (towards n_l) only; seen from behind
                // the sample is discarded (pdf 0).
                let facing = -dot(n_l, wi) / area2;
                var cos_l = max(facing, 0.0);
                if lights[3u * k + 1u].w != 0.0 {
                    cos_l = abs(facing);
                }
                let tri = bitcast<u32>(la.w);
                let lmi = 3u * bitcast<u32>(shade[4u * tri + 3u].w);
                let density = dist[k + 1u] - dist[k];
                pdf_l = 0.0;
                if cos_l > 0.0 {
                    pdf_l = (1.0 - params.env_select) * density / (0.5 * area2) * dist2 / cos_l;
                }
                le = materials[lmi + 1u].xyz;
                tmax = dl * (1.0 - 1e-4);
            }
            if pdf_l > 0.0 && pdf_l <= T_FAR && dot(wi, ng) > 0.0 {
                let fb = bsdf_eval(bsdf, ns, wo, wi);
                // The last vertex's light sample carries the whole estimate: no BSDF ray follows.
                var w = mis(pdf_l, fb.w);
                if depth + 1u == params.max_depth {
                    w = 1.0;
                }
                let contrib = throughput * fb.xyz * le * (dot(ns, wi) / pdf_l) * w;
                if any(contrib != vec3<f32>(0.0)) {
                    let blocker = traverse(po, wi, tmax, true);
                    if blocker.prim == NO_HIT {
                        radiance += contrib;
                    }
                }
            }
        }

        let wi = bsdf_sample(bsdf, ns, wo, r1.w, r2.x, r2.y);
        if dot(wi, ng) <= 0.0 {
            break;
        }
        let fb = bsdf_eval(bsdf, ns, wo, wi);
        if !(fb.w > 0.0) {
            break;
        }
        throughput *= fb.xyz * (dot(ns, wi) / fb.w);
        prev_pdf = fb.w;
        if depth >= 3u {
            let q = min(max(max(throughput.x, throughput.y), throughput.z), 0.95);
            if r2.z >= q {
                break;
            }
            throughput /= q;
        }
        o = po;
        d = wi;
    }
    if is_finite3(radiance) {
        return radiance;
    }
    return vec3<f32>(0.0);
}

@compute @workgroup_size(64)
fn trace(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    // No early return: the ray count is reduced per workgroup behind a barrier.
    var pixel = 0u;
    var live = false;
    if params.mode == 1u {
        let linear = (wg.y * args[0] + wg.x) * WORKGROUP + li;
        if linear < args[3] {
            pixel = list[linear];
            live = true;
        }
    } else {
        let linear = (wg.y * params.groups_x + wg.x) * WORKGROUP + li;
        // 8 × 8 tiles in row-major tile order: neighbouring threads trace neighbouring pixels.
        let tiles_x = (params.size.x + 7u) / 8u;
        let tile = linear / 64u;
        let l = linear % 64u;
        let x = (tile % tiles_x) * 8u + l % 8u;
        let y = (tile / tiles_x) * 8u + l / 8u;
        if linear < params.count && x < params.size.x && y < params.size.y {
            pixel = y * params.size.x + x;
            live = true;
        }
    }
    rays_traced = 0u;
    if live {
        let sample = counts[pixel];
        let rgb = trace_sample(pixel, sample);
        let l = lum(rgb);
        accum[pixel] += vec4<f32>(rgb, l * l);
        counts[pixel] = sample + 1u;
    }
    atomicAdd(&workgroup_rays, rays_traced);
    workgroupBarrier();
    if li == 0u {
        atomicAdd(&stats[0], atomicLoad(&workgroup_rays));
    }
}
