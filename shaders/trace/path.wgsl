// The path-tracing integrator (CPU twin: src/trace/path.rs). One thread traces one path for one
// pixel — every pixel in tile order (full frame) or the pixels of the scheduler's list — and
// adds it to the pixel's accumulation (a regenerating kernel's thread traces several paths,
// one after the other). A cluster rank's samples (mode 2, DESIGN.md §12) are
// returned instead: entry i of a compact list traces pixel list[i] with sample index counts[i]
// and writes its RGB and its ray count into accum[i] (CPU twin: `samples_cpu`).

struct Params {
    size: vec2<u32>,
    count: u32,       // full frame: threads to run (tile-padded pixel count)
    mode: u32,        // 0 full frame, 1 the scheduler's list, 2 a compact list (samples out)
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
    wall_tiles: u32,     // the wall camera's tile count (0: pinhole or orthographic)
    features: u32,       // 1 vertex extras packed, 2 some primitive alpha-tested
    extras_offset: u32,  // vec4 index of the vertex extras in `shade`
    punctual_count: u32,
    punct_select: f32,
    ortho_half_y: f32,   // orthographic window half height (0: pinhole)
    // The band of image rows this dispatch covers (a frame split to fit the bindings): the
    // buffers hold size.x × rows pixels from image row row0 (src/gpu/mod.rs, `Band`).
    row0: u32,
    rows: u32,
    // Full frames of a regenerating kernel (the kernel lab's `+regenG`): threads launched (a
    // thread's paths are that far apart); 0: a thread a path.
    stride: u32,
}

// Layout constants: src/trace/pack.rs (module doc).
const MATERIAL_STRIDE: u32 = 39u;
const MATERIAL_COAT_ROW: u32 = 35u;
const MATERIAL_SHEEN_ROW: u32 = 36u;
const MATERIAL_ANISO_ROW: u32 = 37u;
const MATERIAL_DIFFUSE_ROW: u32 = 38u;
// The sheen's albedo table after the materials: SHEEN_COLUMNS × SHEEN_ROWS entries in
// SHEEN_TABLE_ROWS vec4s.
const SHEEN_COLUMNS: u32 = 64u;
const SHEEN_ROWS: u32 = 32u;
const SHEEN_TABLE_ROWS: u32 = 512u;
const SHEEN_MIN_ROUGHNESS: f32 = 0.07;
const EXTRAS_STRIDE: u32 = 8u;
const MAT_BASE_TEX: u32 = 2u;
const MAT_MR_TEX: u32 = 4u;
const MAT_NORMAL_TEX: u32 = 8u;
const MAT_EMISSIVE_TEX: u32 = 16u;
const MAT_MASK: u32 = 32u;
const MAT_BLEND: u32 = 64u;
const MAT_EXT_BSDF: u32 = 128u;
const MAT_EXT_TEX: u32 = 256u;
const MAT_VOLUME: u32 = 512u;
const MAT_DISPERSION: u32 = 1024u;
// ext_bsdf's channel at a surface that is not dispersive: the material's own index of
// refraction (CPU twin: path::ALL_CHANNELS).
const ALL_CHANNELS: u32 = 3u;
const FEAT_EXTRAS: u32 = 1u;
const FEAT_ALPHA: u32 = 2u;
const LIGHT_SPOT: u32 = 1u;
const LIGHT_DIRECTIONAL: u32 = 2u;
const ALPHA_HASH: u32 = 0x414c5048u;
const MIN_ALPHA: f32 = 1e-3;

const NO_TEXTURE: u32 = 0xffffffffu;
const STREAM_TRACE: u32 = 0x7a3c0000u;
// Threads a workgroup; the kernel lab's `+wgN` variants set it (a pipeline constant).
override WORKGROUP: u32 = 64u;

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
// The wall camera's tiles (DESIGN.md §11; layout: src/trace/wall.rs, `WallCamera::gpu_table`):
// 4 vec4s each — the image pixels x0..x1 × y0..y1 it shows (u32 bits), then the scene-frame
// vector from the eye to image point (x0, y0)'s wall point and the steps of one image pixel.
@group(1) @binding(6) var<storage, read> wall: array<vec4<f32>>;

const NO_TILE: u32 = 0xffffffffu;

var<private> rays_traced: u32;
var<workgroup> workgroup_rays: atomic<u32>;
// This thread's index in its workgroup (the kernel lab's workgroup-memory traversal stack,
// src/trace/gpu/lab.rs, indexes its entries by it).
var<private> trace_lane: u32;

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

fn wrap(i: i32, n: u32, mode: u32) -> u32 {
    let ni = i32(n);
    if mode == 1u {
        return u32(clamp(i, 0, ni - 1));
    }
    if mode == 2u {
        let k = ((i % (2 * ni)) + 2 * ni) % (2 * ni);
        return u32(select(k, 2 * ni - 1 - k, k >= ni));
    }
    return u32(((i % ni) + ni) % ni);
}

fn texel(off: u32, w: u32, h: u32, smp: u32, x: i32, y: i32) -> vec4<f32> {
    let xi = wrap(x, w, smp & 3u);
    let yi = wrap(y, h, (smp >> 2u) & 3u);
    let c = texels[off + yi * w + xi];
    let ch = vec4<f32>(f32(c & 0xffu), f32((c >> 8u) & 0xffu), f32((c >> 16u) & 0xffu), f32(c >> 24u)) / 255.0;
    if (smp & 32u) != 0u {
        return vec4<f32>(srgb_to_linear(ch.x), srgb_to_linear(ch.y), srgb_to_linear(ch.z), ch.w);
    }
    return ch;
}

fn texture(tex: u32, uv_in: vec2<f32>) -> vec4<f32> {
    let off = texels[4u * tex];
    let w = texels[4u * tex + 1u];
    let h = texels[4u * tex + 2u];
    let smp = texels[4u * tex + 3u];
    // Non-finite coordinates read as 0 (the CPU twin does the same).
    var uv = uv_in;
    if !(abs(uv.x) <= T_FAR && abs(uv.y) <= T_FAR) {
        uv = vec2<f32>(0.0);
    }
    if (smp & 16u) != 0u {
        return texel(off, w, h, smp, i32(floor(uv.x * f32(w))), i32(floor(uv.y * f32(h))));
    }
    let x = uv.x * f32(w) - 0.5;
    let y = uv.y * f32(h) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let xi = i32(x0);
    let yi = i32(y0);
    let a = texel(off, w, h, smp, xi, yi);
    let b = texel(off, w, h, smp, xi + 1, yi);
    let c = texel(off, w, h, smp, xi, yi + 1);
    let d = texel(off, w, h, smp, xi + 1, yi + 1);
    return (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy;
}

fn lerp4(a: vec4<f32>, b: vec4<f32>, c: vec4<f32>, u: f32, v: f32) -> vec4<f32> {
    return a * (1.0 - u - v) + b * u + c * v;
}

fn surface_uv(tri: u32, u: f32, v: f32, uv_set: u32) -> vec2<f32> {
    let b0 = 1.0 - u - v;
    if uv_set == 1u && (params.features & FEAT_EXTRAS) != 0u {
        let e = params.extras_offset + EXTRAS_STRIDE * tri;
        let a = shade[e + 3u];
        let b = shade[e + 4u];
        return a.xy * b0 + a.zw * u + b.xy * v;
    }
    let ti = 4u * tri;
    return vec2<f32>(shade[ti].w, shade[ti + 1u].w) * b0 + vec2<f32>(shade[ti + 2u].w, shade[ti + 3u].x) * u
        + shade[ti + 3u].yz * v;
}

fn slot(mb: u32, k: u32, tri: u32, u: f32, v: f32) -> vec4<f32> {
    let r0 = materials[mb + 5u + 2u * k];
    let r1 = materials[mb + 6u + 2u * k];
    let uv = vec3<f32>(surface_uv(tri, u, v, bitcast<u32>(r1.w)), 1.0);
    return texture(bitcast<u32>(r0.w), vec2<f32>(dot(r0.xyz, uv), dot(r1.xyz, uv)));
}

fn material_base(tri: u32) -> u32 {
    return MATERIAL_STRIDE * bitcast<u32>(shade[4u * tri + 3u].w);
}

fn base_color(mb: u32, flags: u32, tri: u32, u: f32, v: f32) -> vec4<f32> {
    var base = materials[mb];
    if (flags & MAT_BASE_TEX) != 0u {
        base *= slot(mb, 0u, tri, u, v);
    }
    if (params.features & FEAT_EXTRAS) != 0u {
        let e = params.extras_offset + EXTRAS_STRIDE * tri;
        base *= lerp4(shade[e], shade[e + 1u], shade[e + 2u], u, v);
    }
    return base;
}

// The coverage seed of the ray being traced (set before each traverse).
var<private> ray_seed: u32;

// Called by traverse() for alpha-tested primitives (CPU twin: cpu::alpha_covered).
fn alpha_covered(tri: u32, u: f32, v: f32) -> bool {
    let mb = material_base(tri);
    let flags = u32(materials[mb + 1u].w);
    let a = base_color(mb, flags, tri, u, v).w;
    if (flags & MAT_MASK) != 0u {
        return a >= materials[mb + 2u].w;
    }
    return a > unit_f32(pcg4d(vec4<u32>(ray_seed, tri, ALPHA_HASH, 0u)).x);
}

fn seed_for(pixel: u32, sample: u32, depth: u32, which: u32) -> u32 {
    return pcg4d(vec4<u32>(pixel, sample, params.seed, STREAM_TRACE + 0x8000u + 2u * depth + which)).x;
}

fn emission_at(mb: u32, flags: u32, tri: u32, u: f32, v: f32) -> vec3<f32> {
    var e = materials[mb + 1u].xyz;
    if (flags & MAT_EMISSIVE_TEX) != 0u {
        e *= slot(mb, 3u, tri, u, v).xyz;
    }
    return e;
}

// Whether the material's texture slot k holds a texture.
fn textured(mb: u32, k: u32) -> bool {
    return bitcast<u32>(materials[mb + 5u + 2u * k].w) != NO_TEXTURE;
}

// The extensions' BSDF over the core one: each factor times its texture where the material has
// one; a dispersive one's index of refraction that of the path's `channel` unless it is
// ALL_CHANNELS (CPU twin: path::ext_bsdf).
fn ext_bsdf(mb: u32, flags: u32, core_in: Bsdf, front: bool, tri: u32, u: f32, v: f32, ns: vec3<f32>, ng: vec3<f32>, channel: u32) -> BsdfExt {
    let m3 = materials[mb + 3u];
    let m4 = materials[mb + 4u];
    // The anisotropy's strength and its direction in the tangent frame, and the dispersion.
    let an = materials[mb + MATERIAL_ANISO_ROW];
    var ior = m4.x;
    if channel != ALL_CHANNELS {
        ior = dispersed_ior(m4.x, an.w, channel);
    }
    let f0 = (ior - 1.0) / (ior + 1.0);
    var core = core_in;
    var specular_color = m3.xyz;
    var transmission = m3.w;
    var clearcoat = m4.y;
    var clearcoat_alpha = m4.z;
    var coat_normal = ns;
    let sh = materials[mb + MATERIAL_SHEEN_ROW];
    var sheen = sh.xyz;
    var sheen_roughness = sh.w;
    var strength = an.x;
    var dir = an.yz;
    let dt = materials[mb + MATERIAL_DIFFUSE_ROW];
    var diffuse_transmission = dt.w;
    var diffuse_transmission_color = dt.xyz;
    if (flags & MAT_EXT_TEX) != 0u {
        if textured(mb, 4u) {
            transmission *= slot(mb, 4u, tri, u, v).x;
        }
        if textured(mb, 5u) {
            core.specular *= slot(mb, 5u, tri, u, v).w;
        }
        if textured(mb, 6u) {
            specular_color *= slot(mb, 6u, tri, u, v).xyz;
        }
        if textured(mb, 7u) {
            clearcoat *= slot(mb, 7u, tri, u, v).x;
        }
        if textured(mb, 8u) {
            let g = slot(mb, 8u, tri, u, v).y;
            clearcoat_alpha = max(clearcoat_alpha * g * g, MIN_ALPHA);
        }
        if textured(mb, 9u) {
            coat_normal = normal_mapped_by(mb, 9u, materials[mb + MATERIAL_COAT_ROW].x, tri, u, v, ns);
        }
        if textured(mb, 10u) {
            sheen *= slot(mb, 10u, tri, u, v).xyz;
        }
        if textured(mb, 11u) {
            sheen_roughness *= slot(mb, 11u, tri, u, v).w;
        }
        if textured(mb, 12u) {
            let a = slot(mb, 12u, tri, u, v);
            let d = vec2<f32>(a.x * 2.0 - 1.0, a.y * 2.0 - 1.0);
            dir = vec2<f32>(d.x * dir.x - d.y * dir.y, d.x * dir.y + d.y * dir.x);
            strength *= a.z;
        }
        if textured(mb, 13u) {
            diffuse_transmission *= slot(mb, 13u, tri, u, v).w;
        }
        if textured(mb, 14u) {
            diffuse_transmission_color *= slot(mb, 14u, tri, u, v).xyz;
        }
    }
    var aniso_dir = vec3<f32>(0.0);
    var alpha_t = core.alpha;
    if strength > 0.0 {
        let tb = tangent_frame(tri, u, v, ns);
        aniso_dir = tb[0] * dir.x + tb[1] * dir.y;
        alpha_t = core.alpha + (1.0 - core.alpha) * (strength * strength);
    }
    if dot(coat_normal, ng) < 0.0 {
        coat_normal = -coat_normal;
    }
    return BsdfExt(core, specular_color, f0 * f0, select(1.0 / ior, ior, front), transmission,
        clearcoat, clearcoat_alpha, coat_normal, sheen, max(sheen_roughness, SHEEN_MIN_ROUGHNESS),
        aniso_dir, alpha_t, diffuse_transmission, diffuse_transmission_color);
}

fn normal_mapped(mb: u32, tri: u32, u: f32, v: f32, ns: vec3<f32>) -> vec3<f32> {
    return normal_mapped_by(mb, 2u, materials[mb + 4u].w, tri, u, v, ns);
}

// normal_mapped by the normal map in texture slot k with `scale`.
fn normal_mapped_by(mb: u32, k: u32, scale: f32, tri: u32, u: f32, v: f32, ns: vec3<f32>) -> vec3<f32> {
    let tn = slot(mb, k, tri, u, v).xyz * 2.0 - vec3<f32>(1.0);
    let tb = tangent_frame(tri, u, v, ns);
    let m = normalize(tb[0] * (tn.x * scale) + tb[1] * (tn.y * scale) + ns * tn.z);
    if is_finite3(m) {
        return m;
    }
    return ns;
}

// The interpolated tangent frame about `ns`: the unit tangent orthogonal to it and the
// bitangent with its sign; a frame of its own about `ns` where the scene has no tangents (CPU
// twin: path::tangent_frame).
fn tangent_frame(tri: u32, u: f32, v: f32, ns: vec3<f32>) -> mat2x3<f32> {
    if (params.features & FEAT_EXTRAS) == 0u {
        let t = basis_t(ns)[0];
        return mat2x3<f32>(t, cross(ns, t));
    }
    let e = params.extras_offset + EXTRAS_STRIDE * tri;
    let t4 = lerp4(shade[e + 5u], shade[e + 6u], shade[e + 7u], u, v);
    var t = t4.xyz - ns * dot(ns, t4.xyz);
    if !(dot(t, t) > 1e-12) {
        t = basis_t(ns)[0];
    }
    t = normalize(t);
    return mat2x3<f32>(t, cross(ns, t) * select(1.0, -1.0, t4.w < 0.0));
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

// The orthographic camera's ray origin for image point (x, y).
fn camera_origin(x: f32, y: f32) -> vec3<f32> {
    let sx = (2.0 * x / f32(params.size.x) - 1.0) * params.ortho_half_y * params.aspect;
    let sy = (1.0 - 2.0 * y / f32(params.size.y)) * params.ortho_half_y;
    return params.cam_pos + params.cam_right * sx + params.cam_up * sy;
}

// The wall tile that shows image pixel (x, y), the first listed; NO_TILE where none does
// (twin: WallCamera::tile_of).
fn wall_tile(x: u32, y: u32) -> u32 {
    for (var i = 0u; i < params.wall_tiles; i++) {
        let b = bitcast<vec4<u32>>(wall[4u * i]);
        if x >= b.x && x < b.y && y >= b.z && y < b.w {
            return i;
        }
    }
    return NO_TILE;
}

// The wall camera's primary direction through image point (x + j.x, y + j.y) of a pixel on
// tile `tile` (twin: WallCamera::ray).
fn wall_direction(tile: u32, x: u32, y: u32, j: vec2<f32>) -> vec3<f32> {
    let b = bitcast<vec4<u32>>(wall[4u * tile]);
    let fx = f32(x - b.x) + j.x;
    let fy = f32(y - b.z) + j.y;
    return normalize(wall[4u * tile + 1u].xyz + wall[4u * tile + 2u].xyz * fx + wall[4u * tile + 3u].xyz * fy);
}

fn is_finite3(v: vec3<f32>) -> bool {
    return all(abs(v) <= vec3<f32>(T_FAR));
}

// A path in flight: where its next ray starts and goes, what it has gathered, and the vertex
// it is at. `trace_sample` runs one path to its end; a regenerating launch (`trace_jobs`)
// starts a thread's next path as soon as its last one ends.
struct PathState {
    o: vec3<f32>,
    depth: u32,
    d: vec3<f32>,
    prev_pdf: f32,
    throughput: vec3<f32>,
    pixel: u32,
    radiance: vec3<f32>,
    sample: u32,
}

// The camera ray of sample `sample` of `pixel`; `tile` is its wall tile when the wall camera
// is on.
fn path_start(pixel: u32, sample: u32, tile: u32) -> PathState {
    let x = pixel % params.size.x;
    let y = pixel / params.size.x;
    let r0 = rand4(pixel, sample, 0u);
    var d: vec3<f32>;
    var o: vec3<f32>;
    if params.wall_tiles > 0u {
        d = wall_direction(tile, x, y, r0.xy);
        o = params.cam_pos;
    } else if params.ortho_half_y > 0.0 {
        o = camera_origin(f32(x) + r0.x, f32(y) + r0.y);
        d = params.cam_fwd;
    } else {
        d = camera_direction(f32(x) + r0.x, f32(y) + r0.y);
        o = params.cam_pos;
    }
    return PathState(o, 0u, d, 0.0, vec3<f32>(1.0), pixel, vec3<f32>(0.0), sample);
}

// The alpha-test seed of the path's next closest-hit ray (0 in scenes without cut-outs).
fn closest_hit_seed(st: PathState) -> u32 {
    if (params.features & FEAT_ALPHA) != 0u {
        return seed_for(st.pixel, st.sample, st.depth, 0u);
    }
    return 0u;
}

// One vertex of the path `st`: its ray traced, emission gathered, the light sampled, the next
// direction chosen. False when the path ends here (its radiance final).
fn path_bounce(st: ptr<function, PathState>) -> bool {
    ray_seed = closest_hit_seed(*st);
    return path_shade(st, traverse((*st).o, (*st).d, T_FAR, false));
}

// `path_bounce` after its closest-hit ray: `hit` is where the path's ray meets the scene.
fn path_shade(st: ptr<function, PathState>, hit: Hit) -> bool {
    let d = (*st).d;
    var throughput = (*st).throughput;
    var radiance = (*st).radiance;
    var prev_pdf = (*st).prev_pdf;
    let depth = (*st).depth;
    let pixel = (*st).pixel;
    let sample = (*st).sample;
    let alpha_scene = (params.features & FEAT_ALPHA) != 0u;
    let tri_select = 1.0 - params.env_select - params.punct_select;
    if hit.prim == NO_HIT {
        let le = env_eval(d);
        var w = 1.0;
        if prev_pdf != 0.0 {
            w = mis(prev_pdf, params.env_select * le.w);
        }
        radiance += throughput * le.xyz * w;
        (*st).radiance = radiance;
        return false;
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
    let tri = bitcast<u32>(pa.w);
    let ti = 4u * tri;
    let s0 = shade[ti];
    let s1 = shade[ti + 1u];
    let s2 = shade[ti + 2u];
    let s3 = shade[ti + 3u];
    let b0 = 1.0 - hit.u - hit.v;
    var ns = normalize(s0.xyz * b0 + s1.xyz * hit.u + s2.xyz * hit.v);
    if !is_finite3(ns) {
        ns = ng;
    }
    let ns_interpolated = ns;
    let mb = MATERIAL_STRIDE * bitcast<u32>(s3.w);
    let m1 = materials[mb + 1u];
    let m2 = materials[mb + 2u];
    let flags = u32(m1.w);
    let wo = -d;
    let cos_hit = abs(dot(ng, d));
    let front = dot(ng, wo) >= 0.0;
    if !front {
        ng = -ng;
        // Leaving an absorbing medium (KHR_materials_volume): exp(−σt) of the light is left.
        if (flags & MAT_VOLUME) != 0u {
            throughput *= exp(-materials[mb + MATERIAL_COAT_ROW].yzw * hit.t);
        }
    }
    if (flags & MAT_NORMAL_TEX) != 0u {
        ns = normal_mapped(mb, tri, hit.u, hit.v, ns);
    }
    if dot(ns, ng) < 0.0 {
        ns = -ns;
    }
    let emission = emission_at(mb, flags, tri, hit.u, hit.v);
    if any(emission != vec3<f32>(0.0)) {
        var w = 1.0;
        if prev_pdf != 0.0 {
            let pdf_light = tri_select * light_density * hit.t * hit.t / cos_hit;
            w = mis(prev_pdf, pdf_light);
        }
        radiance += throughput * emission * w;
    }
    let base = base_color(mb, flags, tri, hit.u, hit.v);
    var metallic = m2.x;
    var alpha = m2.y;
    if (flags & MAT_MR_TEX) != 0u {
        let mr = slot(mb, 1u, tri, hit.u, hit.v);
        alpha = max(alpha * mr.y * mr.y, MIN_ALPHA);
        metallic *= mr.z;
    }
    let bsdf = Bsdf(base.xyz, metallic, alpha, m2.z);
    let r2 = rand4(pixel, sample, 2u + 2u * depth);
    // A dispersive surface: the path follows one channel from here on (after this vertex's
    // emission, before its light sample and BSDF, which refract by it).
    var channel = ALL_CHANNELS;
    if (flags & MAT_DISPERSION) != 0u {
        let picked = pick_channel(throughput, r2.w);
        channel = picked.channel;
        throughput = picked.throughput;
    }
    let has_ext = (flags & MAT_EXT_BSDF) != 0u;
    var ext = BsdfExt(bsdf, vec3<f32>(1.0), 0.04, 1.5, 0.0, 0.0, 0.1, ns, vec3<f32>(0.0), 1.0,
        vec3<f32>(0.0), bsdf.alpha, 0.0, vec3<f32>(1.0));
    if has_ext {
        ext = ext_bsdf(mb, flags, bsdf, front, tri, hit.u, hit.v, ns_interpolated, ng, channel);
    }
    let transmits = has_ext && ext_transmits(ext);
    let r1 = rand4(pixel, sample, 1u + 2u * depth);
    let po = offset_ray(p, ng);

    if params.env_select > 0.0 || params.light_count > 0u || params.punctual_count > 0u {
        var wi: vec3<f32>;
        var le: vec3<f32>;
        var pdf_l: f32;
        var tmax: f32;
        var delta = false;
        if r1.x < params.env_select {
            let es = sample_env(r1.y, r1.z);
            wi = es.dir;
            le = es.radiance;
            pdf_l = params.env_select * es.pdf;
            tmax = T_FAR;
        } else if r1.x < params.env_select + params.punct_select {
            let n = params.punctual_count;
            let k = min(u32((r1.x - params.env_select) / params.punct_select * f32(n)), n - 1u);
            let l = 3u * (params.light_count + k);
            let la = lights[l];
            let lb = lights[l + 1u];
            let lc = lights[l + 2u];
            pdf_l = params.punct_select / f32(n);
            delta = true;
            if u32(la.w) == LIGHT_DIRECTIONAL {
                wi = la.xyz;
                le = lb.xyz;
                tmax = T_FAR;
            } else {
                let to = la.xyz - po;
                let dist2 = dot(to, to);
                let dl = sqrt(dist2);
                wi = to / dl;
                le = lb.xyz / dist2;
                if u32(la.w) == LIGHT_SPOT {
                    let scale = 1.0 / max(lc.w - lb.w, 0.001);
                    let t = clamp((dot(lc.xyz, -wi) - lb.w) * scale, 0.0, 1.0);
                    le *= t * t;
                }
                tmax = dl * (1.0 - 1e-4);
            }
        } else {
            let u = min((r1.x - params.env_select - params.punct_select) / tri_select, 0.99999994);
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
            // A single-sided light emits ray_from its front (towards n_l) only; seen ray_from behind
            // the sample is discarded (pdf 0).
            let facing = -dot(n_l, wi) / area2;
            var cos_l = max(facing, 0.0);
            if lights[3u * k + 1u].w != 0.0 {
                cos_l = abs(facing);
            }
            let ltri = bitcast<u32>(la.w);
            let lmb = material_base(ltri);
            let lflags = u32(materials[lmb + 1u].w);
            le = emission_at(lmb, lflags, ltri, a, b);
            // A cut-out emitter emits only where it is there (BSDF rays see the same).
            if (lflags & MAT_MASK) != 0u {
                if base_color(lmb, lflags, ltri, a, b).w < materials[lmb + 2u].w {
                    le = vec3<f32>(0.0);
                }
            } else if (lflags & MAT_BLEND) != 0u {
                le *= base_color(lmb, lflags, ltri, a, b).w;
            }
            let density = dist[k + 1u] - dist[k];
            pdf_l = 0.0;
            if cos_l > 0.0 {
                pdf_l = tri_select * density / (0.5 * area2) * dist2 / cos_l;
            }
            tmax = dl * (1.0 - 1e-4);
        }
        let side = dot(wi, ng);
        if pdf_l > 0.0 && pdf_l <= T_FAR && (side > 0.0 || (transmits && side < 0.0)) {
            var fb: vec4<f32>;
            if has_ext {
                fb = ext_eval(ext, ns, wo, wi);
            } else {
                fb = bsdf_eval(bsdf, ns, wo, wi);
            }
            // The last vertex's light sample carries the whole estimate: no BSDF ray
            // follows. A delta light cannot be hit at all.
            var w = mis(pdf_l, fb.w);
            if delta || depth + 1u == params.max_depth {
                w = 1.0;
            }
            let contrib = throughput * fb.xyz * le * (abs(dot(ns, wi)) / pdf_l) * w;
            if any(contrib != vec3<f32>(0.0)) {
                var ray_from = po;
                if side < 0.0 {
                    ray_from = offset_ray(p, -ng);
                }
                if alpha_scene {
                    ray_seed = seed_for(pixel, sample, depth, 1u);
                }
                let blocker = traverse(ray_from, wi, tmax, true);
                if blocker.prim == NO_HIT {
                    radiance += contrib;
                }
            }
        }
    }

    var wi: vec3<f32>;
    if has_ext {
        wi = ext_sample(ext, ns, wo, r1.w, r2.x, r2.y);
    } else {
        wi = bsdf_sample(bsdf, ns, wo, r1.w, r2.x, r2.y);
    }
    let side = dot(wi, ng);
    if !(side > 0.0 || (transmits && side < 0.0 && dot(ns, wi) < 0.0)) {
        (*st).radiance = radiance;
        return false;
    }
    var fb: vec4<f32>;
    if has_ext {
        fb = ext_eval(ext, ns, wo, wi);
    } else {
        fb = bsdf_eval(bsdf, ns, wo, wi);
    }
    if !(fb.w > 0.0) {
        (*st).radiance = radiance;
        return false;
    }
    throughput *= fb.xyz * (abs(dot(ns, wi)) / fb.w);
    prev_pdf = fb.w;
    if depth >= 3u {
        let q = min(max(max(throughput.x, throughput.y), throughput.z), 0.95);
        if r2.z >= q {
            (*st).radiance = radiance;
            return false;
        }
        throughput /= q;
    }
    if side > 0.0 {
        (*st).o = po;
    } else {
        (*st).o = offset_ray(p, -ng);
    }
    (*st).d = wi;
    (*st).throughput = throughput;
    (*st).radiance = radiance;
    (*st).prev_pdf = prev_pdf;
    (*st).depth = depth + 1u;
    return true;
}

// The path's estimate (a non-finite one is dropped).
fn path_result(st: PathState) -> vec3<f32> {
    if is_finite3(st.radiance) {
        return st.radiance;
    }
    return vec3<f32>(0.0);
}

// One path of `pixel`; `tile` is its wall tile when the wall camera is on.
fn trace_sample(pixel: u32, sample: u32, tile: u32) -> vec3<f32> {
    var st = path_start(pixel, sample, tile);
    while st.depth < params.max_depth {
        if !path_bounce(&st) {
            break;
        }
    }
    return path_result(st);
}

const NO_SLOT: u32 = 0xffffffffu;

// Full-frame thread `linear`'s slot in this band's buffers, or NO_SLOT past the frame's edge:
// 8 × 8 tiles in row-major tile order, so neighbouring threads trace neighbouring pixels.
fn full_frame_slot(linear: u32) -> u32 {
    let tiles_x = (params.size.x + 7u) / 8u;
    let tile = linear / 64u;
    let l = linear % 64u;
    let x = (tile % tiles_x) * 8u + l % 8u;
    let y = (tile / tiles_x) * 8u + l / 8u;
    if linear < params.count && x < params.size.x && y < params.rows {
        return y * params.size.x + x;
    }
    return NO_SLOT;
}

// The wall tile showing `pixel` (0 without the wall camera), or NO_TILE where none does.
fn tile_of(pixel: u32) -> u32 {
    if params.wall_tiles > 0u {
        return wall_tile(pixel % params.size.x, pixel / params.size.x);
    }
    return 0u;
}

// Adds a finished path's estimate to its slot (one sample more).
fn accumulate(slot: u32, sample: u32, rgb: vec3<f32>) {
    let l = lum(rgb);
    accum[slot] += vec4<f32>(rgb, l * l);
    counts[slot] = sample + 1u;
}

// Job `job` of this dispatch (below its count): its slot in this band's buffers (NO_SLOT
// where a full frame's padding has none) and the image pixel it traces — a full frame's
// tile-ordered slot, the scheduler's listed pixel, or entry `job` of a rank's compact list.
fn job_of(job: u32) -> vec2<u32> {
    if params.mode == 2u {
        return vec2<u32>(job, list[job]);
    }
    var slot: u32;
    if params.mode == 0u {
        slot = full_frame_slot(job);
    } else {
        slot = list[job];
    }
    return vec2<u32>(slot, params.row0 * params.size.x + slot);
}

// A finished path of `slot`: added to its accumulation, or — a rank's compact list — returned
// with the rays it took (the rank's CPU keeps the counts, the owner of the pixel the sums).
fn finish(slot: u32, sample: u32, rgb: vec3<f32>, rays: u32) {
    if params.mode == 2u {
        accum[slot] = vec4<f32>(rgb, bitcast<f32>(rays));
    } else {
        accumulate(slot, sample, rgb);
    }
}

// Jobs `first`, `first + stride`, … below `count`, each path traced as `trace_sample` traces
// it, to the bit, but the thread starts its next path as soon as its last one ends (path
// regeneration: a regenerating kernel's capped launch, `stride` its threads), so that a
// group's threads stay busy while paths of different lengths finish.
fn trace_jobs(first: u32, count: u32, stride: u32) {
    var job = first;
    var st: PathState;
    var slot = 0u;
    var rays_before = 0u;
    var busy = false;
    loop {
        if !busy {
            while !busy && job < count {
                let j = job_of(job);
                job += stride;
                if j.x != NO_SLOT {
                    // The wall camera traces only pixels a tile shows.
                    let tile = tile_of(j.y);
                    if tile != NO_TILE {
                        slot = j.x;
                        rays_before = rays_traced;
                        st = path_start(j.y, counts[j.x], tile);
                        busy = true;
                    }
                }
            }
            if !busy {
                break;
            }
        }
        if st.depth < params.max_depth && path_bounce(&st) {
            continue;
        }
        finish(slot, st.sample, path_result(st), rays_traced - rays_before);
        busy = false;
    }
}

// Job `job` alone, if below `count`: a thread a path.
fn trace_job(job: u32, count: u32) {
    if job >= count {
        return;
    }
    let j = job_of(job);
    if j.x == NO_SLOT {
        return;
    }
    // The wall camera traces only pixels a tile shows (the schedule lists no others).
    let tile = tile_of(j.y);
    if tile == NO_TILE {
        return;
    }
    let sample = counts[j.x];
    finish(j.x, sample, trace_sample(j.y, sample, tile), rays_traced);
}

// Whether lists regenerate their paths (a pipeline constant the kernel lab's `+regenG` variants
// set: src/trace/gpu/lab.rs); their launches are capped by the scheduler's arguments pass or the
// rank's dispatch, and the kernel reads its stride from the grid they launch.
override REGENERATE: bool = false;

@compute @workgroup_size(WORKGROUP)
fn trace(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    // No early return: the ray count is reduced per workgroup behind a barrier.
    trace_lane = li;
    rays_traced = 0u;
    // This thread's first job, the dispatch's job count, and the stride between the thread's
    // jobs where its launch regenerates (0: a thread a job).
    var first: u32;
    var count: u32;
    var stride = 0u;
    if params.mode == 0u {
        first = (wg.y * params.groups_x + wg.x) * WORKGROUP + li;
        count = params.count;
        stride = params.stride;
    } else {
        // A list, launched from `args` = (x, y, z, count).
        first = (wg.y * args[0] + wg.x) * WORKGROUP + li;
        count = args[3];
        if REGENERATE {
            stride = args[0] * args[1] * WORKGROUP;
        }
    }
    if stride != 0u {
        trace_jobs(first, count, stride);
    } else {
        trace_job(first, count);
    }
    atomicAdd(&workgroup_rays, rays_traced);
    workgroupBarrier();
    if li == 0u {
        atomicAdd(&stats[0], atomicLoad(&workgroup_rays));
    }
}

// The wavefront split (the kernel lab's `+split` variants, full frames only; src/trace/gpu/
// split.rs, `SplitRun`): the same paths as `trace`, to the bit, in three kernels a bounce apart,
// so that the traversal runs in a kernel of its own (few registers, many threads resident) and
// the shading in another. A frame's jobs go in chunks of `split.jobs`; the chunk's paths wait in
// `split_states` between kernels and their closest hits in `split_hits`. `split_start` starts
// them, then `split_extend` (closest hits) and `split_shade` (the rest of `path_bounce`, shadow
// rays included) alternate `params.max_depth` times. A path that ends is added to its slot at
// once; one that goes on is queued for the next bounce (its index appended to a queue, a
// workgroup's together), so that each bounce's threads are the live paths, packed, and the
// threads past the queue's length end at once. The queues' order is the atomics' and changes
// nothing: each path is its own.
struct SplitParams {
    first_job: u32, // the chunk's first full-frame job
    jobs: u32,      // jobs in this chunk
    groups_x: u32,  // the chunk's dispatch grid's width in workgroups
    // Which bounce: 0 the first (the chunk's paths in order, live ones to queue 1), 1 from
    // queue 1 to queue 0, 2 from queue 0 to queue 1.
    phase: u32,
}

@group(2) @binding(0) var<storage, read_write> split_states: array<PathState>;
@group(2) @binding(1) var<storage, read_write> split_hits: array<Hit>;
@group(2) @binding(2) var<uniform> split: SplitParams;
// Two queues of path indices, `split.jobs` apart, and their lengths.
@group(2) @binding(3) var<storage, read_write> split_queues: array<u32>;
@group(2) @binding(4) var<storage, read_write> split_lengths: array<atomic<u32>, 2>;

// A path that did not start (padding, or a pixel no wall tile shows): past every depth.
const SPLIT_DEAD: u32 = 0xffffffffu;

// This thread's path in the chunk for this bounce, or SPLIT_DEAD where it has none.
fn split_path(wg: vec3<u32>, li: u32) -> u32 {
    let k = (wg.y * split.groups_x + wg.x) * WORKGROUP + li;
    if split.phase == 0u {
        if k < split.jobs && split_states[k].depth < params.max_depth {
            return k;
        }
        return SPLIT_DEAD;
    }
    let queue = 2u - split.phase;
    if k < atomicLoad(&split_lengths[queue]) {
        return split_queues[queue * split.jobs + k];
    }
    return SPLIT_DEAD;
}

// Adds this workgroup's rays to the frame's count (every thread reaches it: no early return).
fn split_count_rays(li: u32) {
    atomicAdd(&workgroup_rays, rays_traced);
    workgroupBarrier();
    if li == 0u {
        atomicAdd(&stats[0], atomicLoad(&workgroup_rays));
    }
}

// A path that ended: its estimate added to its slot.
fn split_finish(i: u32, st: PathState) {
    accumulate(full_frame_slot(split.first_job + i), st.sample, path_result(st));
}

@compute @workgroup_size(WORKGROUP)
fn split_start(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let i = (wg.y * split.groups_x + wg.x) * WORKGROUP + li;
    if i == 0u {
        // The first bounce's queue, filled by its shading.
        atomicStore(&split_lengths[1], 0u);
    }
    if i < split.jobs {
        var st: PathState;
        st.depth = SPLIT_DEAD;
        // A full frame's job (NO_SLOT past the frame's padded end).
        let j = job_of(split.first_job + i);
        if j.x != NO_SLOT {
            let tile = tile_of(j.y);
            if tile != NO_TILE {
                st = path_start(j.y, counts[j.x], tile);
            }
        }
        split_states[i] = st;
        if st.depth == 0u && params.max_depth == 0u {
            split_finish(i, st);
        }
    }
}

@compute @workgroup_size(WORKGROUP)
fn split_extend(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    trace_lane = li;
    rays_traced = 0u;
    if split.phase != 0u && wg.x == 0u && wg.y == 0u && li == 0u {
        // The queue this bounce's shading fills (read last by the bounce before).
        atomicStore(&split_lengths[split.phase - 1u], 0u);
    }
    let i = split_path(wg, li);
    if i != SPLIT_DEAD {
        let st = split_states[i];
        ray_seed = closest_hit_seed(st);
        split_hits[i] = traverse(st.o, st.d, T_FAR, false);
    }
    split_count_rays(li);
}

// The workgroup's paths that go on: how many (each takes the next place) and where in the
// next queue they start.
var<workgroup> split_going_on: atomic<u32>;
var<workgroup> split_queue_base: u32;

@compute @workgroup_size(WORKGROUP)
fn split_shade(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    trace_lane = li;
    rays_traced = 0u;
    let to = select(split.phase - 1u, 1u, split.phase == 0u);
    let i = split_path(wg, li);
    // This path's place among its workgroup's that go on (SPLIT_DEAD: it ends or has none).
    var place = SPLIT_DEAD;
    if i != SPLIT_DEAD {
        var st = split_states[i];
        if path_shade(&st, split_hits[i]) && st.depth < params.max_depth {
            split_states[i] = st;
            place = atomicAdd(&split_going_on, 1u);
        } else {
            split_finish(i, st);
        }
    }
    // One reservation a workgroup in the next queue: its paths stay together there.
    workgroupBarrier();
    if li == 0u {
        split_queue_base = atomicAdd(&split_lengths[to], atomicLoad(&split_going_on));
    }
    workgroupBarrier();
    if place != SPLIT_DEAD {
        split_queues[to * split.jobs + split_queue_base + place] = i;
    }
    split_count_rays(li);
}
