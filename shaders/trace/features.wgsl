// The denoiser's feature buffers (CPU twin: src/trace/features.rs, whose module docs define
// them exactly): per pixel of the band, the mean over four fixed positions of the first
// non-specular hit's albedo, its shading normal (made unit) and the primary hit's depth (0 for
// a miss). Appended to the trace kernel's source (path.wgsl's helpers and bindings); params.seed
// holds FEATURE_SEED (the alpha coverage seeds), params.row0/rows the band; with the wall
// camera (params.wall_tiles > 0) the rays start at its eye (params.cam_pos) through the pixel's
// wall points (the `wall` table).

const FEATURE_DEPTH: u32 = 4u;
const SPECULAR_ALPHA: f32 = 0.01;

@group(1) @binding(7) var<storage, read_write> feature_albedo: array<vec4<f32>>;
@group(1) @binding(8) var<storage, read_write> feature_normal_depth: array<vec4<f32>>;

struct FeatureSample {
    albedo: vec3<f32>,
    normal: vec3<f32>,
    depth: f32,
}

// What the features and the primary-hit record read where a ray along `d` hits (twin:
// features.rs, `surface_at`).
struct SurfaceAt {
    p: vec3<f32>,
    ng: vec3<f32>,
    ns: vec3<f32>,
    front: bool,
    mb: u32,
    flags: u32,
    tri: u32,
    alpha: f32,
    metallic: f32,
    transmission: f32,
}

fn surface_at(hit: Hit, d: vec3<f32>) -> SurfaceAt {
    let pa = prims[3u * hit.prim];
    let pb = prims[3u * hit.prim + 1u];
    let pc = prims[3u * hit.prim + 2u];
    var ng = normalize(cross(pb.xyz, pc.xyz));
    let p = pa.xyz + pb.xyz * hit.u + pc.xyz * hit.v;
    let tri = bitcast<u32>(pa.w);
    let ti = 4u * tri;
    let b0 = 1.0 - hit.u - hit.v;
    var ns = normalize(shade[ti].xyz * b0 + shade[ti + 1u].xyz * hit.u + shade[ti + 2u].xyz * hit.v);
    if !is_finite3(ns) {
        ns = ng;
    }
    let mb = MATERIAL_STRIDE * bitcast<u32>(shade[ti + 3u].w);
    let m1 = materials[mb + 1u];
    let m2 = materials[mb + 2u];
    let flags = u32(m1.w);
    let front = dot(ng, d) <= 0.0;
    if !front {
        ng = -ng;
    }
    if (flags & MAT_NORMAL_TEX) != 0u {
        ns = normal_mapped(mb, tri, hit.u, hit.v, ns);
    }
    if dot(ns, ng) < 0.0 {
        ns = -ns;
    }
    var metallic = m2.x;
    var alpha = m2.y;
    if (flags & MAT_MR_TEX) != 0u {
        let mr = slot(mb, 1u, tri, hit.u, hit.v);
        alpha = max(alpha * mr.y * mr.y, MIN_ALPHA);
        metallic *= mr.z;
    }
    var transmission = 0.0;
    if (flags & MAT_EXT_BSDF) != 0u {
        transmission = materials[mb + 3u].w;
        if (flags & MAT_EXT_TEX) != 0u && bitcast<u32>(materials[mb + 5u + 2u * 4u].w) != NO_TEXTURE {
            transmission *= slot(mb, 4u, tri, hit.u, hit.v).x;
        }
    }
    return SurfaceAt(p, ng, ns, front, mb, flags, tri, alpha, metallic, transmission);
}

fn feature_ray(pixel: u32, k: u32, o_in: vec3<f32>, d_in: vec3<f32>) -> FeatureSample {
    var o = o_in;
    var d = d_in;
    var depth = 0.0;
    for (var v = 0u; v < FEATURE_DEPTH; v++) {
        ray_seed = seed_for(pixel, k, v, 0u);
        let hit = traverse(o, d, T_FAR, false);
        if hit.prim == NO_HIT {
            if v == 0u {
                return FeatureSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0);
            }
            let le = env_eval(d).xyz;
            return FeatureSample(clamp(le, vec3<f32>(0.0), vec3<f32>(1.0)), vec3<f32>(0.0), depth);
        }
        if v == 0u {
            depth = hit.t;
        }
        let sf = surface_at(hit, d);
        let p = sf.p;
        let ng = sf.ng;
        let ns = sf.ns;
        let front = sf.front;
        let mb = sf.mb;
        let flags = sf.flags;
        let tri = sf.tri;
        let alpha = sf.alpha;
        let metallic = sf.metallic;
        let transmission = sf.transmission;
        let specular = alpha <= SPECULAR_ALPHA && (metallic >= 0.5 || transmission >= 0.5);
        if !specular || v + 1u == FEATURE_DEPTH {
            let base = base_color(mb, flags, tri, hit.u, hit.v).xyz;
            return FeatureSample(clamp(base, vec3<f32>(0.0), vec3<f32>(1.0)), ns, depth);
        }
        var next = d - ns * (2.0 * dot(ns, d));
        if metallic < 0.5 {
            let ior = materials[mb + 4u].x;
            var eta = ior;
            if front {
                eta = 1.0 / ior;
            }
            let t = refract(d, ns, eta);
            if any(t != vec3<f32>(0.0)) {
                next = normalize(t);
            }
        }
        if dot(next, ng) > 0.0 {
            o = offset_ray(p, ng);
        } else {
            o = offset_ray(p, -ng);
        }
        d = next;
    }
    return FeatureSample(vec3<f32>(0.0), vec3<f32>(0.0), depth);
}

// One thread a pixel of the band (rows row0 .. row0 + rows of the image), row-major.
@compute @workgroup_size(64)
fn features(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = gid.x + gid.y * groups.x * 64u;
    if i >= params.size.x * params.rows {
        return;
    }
    let x = i % params.size.x;
    let y = params.row0 + i / params.size.x;
    let pixel = y * params.size.x + x;
    // The wall camera: a pixel no tile shows sees nothing (the miss's features).
    var tile = NO_TILE;
    if params.wall_tiles > 0u {
        tile = wall_tile(x, y);
        if tile == NO_TILE {
            feature_albedo[i] = vec4<f32>(0.0);
            feature_normal_depth[i] = vec4<f32>(0.0);
            return;
        }
    }
    let positions = array<vec2<f32>, 4>(
        vec2<f32>(0.375, 0.125), vec2<f32>(0.875, 0.375),
        vec2<f32>(0.125, 0.625), vec2<f32>(0.625, 0.875));
    var albedo = vec3<f32>(0.0);
    var normal = vec3<f32>(0.0);
    var depth = 0.0;
    for (var k = 0u; k < 4u; k++) {
        let px = f32(x) + positions[k].x;
        let py = f32(y) + positions[k].y;
        var o = params.cam_pos;
        var d = camera_direction(px, py);
        if params.wall_tiles > 0u {
            d = wall_direction(tile, x, y, positions[k]);
        } else if params.ortho_half_y > 0.0 {
            o = camera_origin(px, py);
            d = params.cam_fwd;
        }
        let f = feature_ray(pixel, k, o, d);
        albedo += f.albedo;
        normal += f.normal;
        depth += f.depth;
    }
    let m = 1.0 / 4.0;
    var n = normal * m;
    let len2 = dot(n, n);
    if len2 > 0.0 {
        n = n * inverseSqrt(len2);
    }
    feature_albedo[i] = vec4<f32>(albedo * m, 0.0);
    feature_normal_depth[i] = vec4<f32>(n, depth * m);
}

// The primary-hit record of motion reuse (CPU twin: features.rs, `hit_record`; layout:
// src/trace/reuse.rs): per pixel of the band, two vec4s — [anchor, α] and [ng, word] — from
// the ray through the pixel's centre (alpha coverage seeds of position HIT_POSITION).
const HIT_POSITION: u32 = 4u;
const REUSE_NOTHING: u32 = 0xffffffffu;
const REUSE_MISS: u32 = 0xfffffffeu;
const NEVER_REUSE: u32 = 0x80000000u;

@group(1) @binding(9) var<storage, read_write> hit_records: array<vec4<f32>>;

@compute @workgroup_size(64)
fn primary_hits(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = gid.x + gid.y * groups.x * 64u;
    if i >= params.size.x * params.rows {
        return;
    }
    let x = i % params.size.x;
    let y = params.row0 + i / params.size.x;
    let pixel = y * params.size.x + x;
    var o = params.cam_pos;
    var d = camera_direction(f32(x) + 0.5, f32(y) + 0.5);
    if params.wall_tiles > 0u {
        let tile = wall_tile(x, y);
        if tile == NO_TILE {
            hit_records[2u * i] = vec4<f32>(0.0);
            hit_records[2u * i + 1u] = vec4<f32>(vec3<f32>(0.0), bitcast<f32>(REUSE_NOTHING));
            return;
        }
        d = wall_direction(tile, x, y, vec2<f32>(0.5, 0.5));
    } else if params.ortho_half_y > 0.0 {
        o = camera_origin(f32(x) + 0.5, f32(y) + 0.5);
        d = params.cam_fwd;
    }
    ray_seed = seed_for(pixel, HIT_POSITION, 0u, 0u);
    let hit = traverse(o, d, T_FAR, false);
    if hit.prim == NO_HIT {
        hit_records[2u * i] = vec4<f32>(d, 0.0);
        hit_records[2u * i + 1u] = vec4<f32>(vec3<f32>(0.0), bitcast<f32>(REUSE_MISS));
        return;
    }
    let sf = surface_at(hit, d);
    var word = sf.mb / MATERIAL_STRIDE;
    if sf.transmission >= 0.5 || (sf.metallic >= 0.5 && sf.alpha <= SPECULAR_ALPHA) {
        word |= NEVER_REUSE;
    }
    hit_records[2u * i] = vec4<f32>(o + d * hit.t, sf.alpha);
    hit_records[2u * i + 1u] = vec4<f32>(sf.ng, bitcast<f32>(word));
}
