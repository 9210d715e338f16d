// Sampling and shading (CPU twin: src/trace/shading.rs — same formulas, same order).

const PI: f32 = 3.14159265358979;

fn basis_t(n: vec3<f32>) -> mat2x3<f32> {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    return mat2x3<f32>(
        vec3<f32>(1.0 + s * n.x * n.x * a, s * b, -s * n.x),
        vec3<f32>(b, s + n.y * n.y * a, -n.y),
    );
}

fn offset_ray(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let off = vec3<i32>(256.0 * n);
    let pi = bitcast<vec3<f32>>(bitcast<vec3<i32>>(p) + select(off, -off, p < vec3<f32>(0.0)));
    return select(pi, p + (1.0 / 65536.0) * n, abs(p) < vec3<f32>(1.0 / 32.0));
}

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        return c / 12.92;
    }
    return pow((c + 0.055) / 1.055, 2.4);
}

fn cosine_hemisphere(u: f32, v: f32) -> vec3<f32> {
    let r = sqrt(u);
    let phi = 2.0 * PI * v;
    return vec3<f32>(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u, 0.0)));
}

fn uniform_sphere(u: f32, v: f32) -> vec3<f32> {
    let z = 1.0 - 2.0 * u;
    let r = sqrt(max(1.0 - z * z, 0.0));
    let phi = 2.0 * PI * v;
    return vec3<f32>(r * cos(phi), r * sin(phi), z);
}

fn direction_to_equirect(d: vec3<f32>) -> vec2<f32> {
    return vec2<f32>(0.5 + atan2(d.x, -d.z) * (0.5 / PI), acos(clamp(d.y, -1.0, 1.0)) * (1.0 / PI));
}

fn equirect_to_direction(u: f32, v: f32) -> vec3<f32> {
    let phi = (u - 0.5) * 2.0 * PI;
    let theta = v * PI;
    let s = sin(theta);
    return vec3<f32>(s * sin(phi), cos(theta), -s * cos(phi));
}

fn lum(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

struct Bsdf {
    base: vec3<f32>,
    metallic: f32,
    alpha: f32,
    specular: f32,
}

fn pow5(x: f32) -> f32 {
    let x2 = x * x;
    return x2 * x2 * x;
}

// (F_d in .w, F in .xyz)
fn bsdf_fresnel(b: Bsdf, c: f32) -> vec4<f32> {
    let k = pow5(max(1.0 - c, 0.0));
    let fd = 0.04 * b.specular + (b.specular - 0.04 * b.specular) * k;
    let fm = b.base + (vec3<f32>(1.0) - b.base) * k;
    return vec4<f32>(mix(vec3<f32>(fd), fm, b.metallic), fd);
}

fn specular_probability(b: Bsdf, cos_o: f32) -> f32 {
    let f = bsdf_fresnel(b, cos_o);
    let ws = lum(f.xyz);
    let wd = lum(b.base) * (1.0 - b.metallic) * (1.0 - f.w);
    if ws + wd > 0.0 {
        return ws / (ws + wd);
    }
    return 0.5;
}

// BSDF value in .xyz and sampling pdf in .w.
fn bsdf_eval(b: Bsdf, n: vec3<f32>, wo: vec3<f32>, wi: vec3<f32>) -> vec4<f32> {
    let cos_o = dot(n, wo);
    let cos_i = dot(n, wi);
    if cos_o <= 0.0 || cos_i <= 0.0 {
        return vec4<f32>(0.0);
    }
    let h = normalize(wo + wi);
    let noh = max(dot(n, h), 0.0);
    let voh = max(dot(wo, h), 1e-7);
    let fr = bsdf_fresnel(b, voh);
    let a2 = b.alpha * b.alpha;
    let dd = noh * noh * (a2 - 1.0) + 1.0;
    let d = a2 / (PI * dd * dd);
    let vis = 0.5 / (cos_i * sqrt(cos_o * cos_o * (1.0 - a2) + a2) + cos_o * sqrt(cos_i * cos_i * (1.0 - a2) + a2));
    let spec = fr.xyz * (d * vis);
    let diff = b.base * ((1.0 - b.metallic) * (1.0 - fr.w) / PI);
    let ps = specular_probability(b, cos_o);
    let pdf = ps * d * noh / (4.0 * voh) + (1.0 - ps) * cos_i / PI;
    return vec4<f32>(diff + spec, pdf);
}

fn bsdf_sample(b: Bsdf, n: vec3<f32>, wo: vec3<f32>, u_lobe: f32, u: f32, v: f32) -> vec3<f32> {
    let tb = basis_t(n);
    if u_lobe < specular_probability(b, dot(n, wo)) {
        let a2 = b.alpha * b.alpha;
        let cos_h = sqrt(max((1.0 - u) / (1.0 + (a2 - 1.0) * u), 0.0));
        let sin_h = sqrt(max(1.0 - cos_h * cos_h, 0.0));
        let phi = 2.0 * PI * v;
        let h = tb[0] * (sin_h * cos(phi)) + tb[1] * (sin_h * sin(phi)) + n * cos_h;
        return 2.0 * dot(wo, h) * h - wo;
    }
    let l = cosine_hemisphere(u, v);
    return tb[0] * l.x + tb[1] * l.y + n * l.z;
}

// glTF's BSDF extensions (CPU twin: BsdfExt in src/trace/shading.rs).
struct BsdfExt {
    core: Bsdf,
    specular_color: vec3<f32>,
    f0: f32,
    eta: f32,
    transmission: f32,
    clearcoat: f32,
    clearcoat_alpha: f32,
    // The coat's own shading normal, on the viewer's side.
    coat_normal: vec3<f32>,
    // KHR_materials_sheen's colour (zero: none) and perceptual roughness (≥ SHEEN_MIN_ROUGHNESS).
    sheen: vec3<f32>,
    sheen_roughness: f32,
    // KHR_materials_anisotropy: the direction (zero: isotropic) along which α is alpha_t.
    aniso_dir: vec3<f32>,
    alpha_t: f32,
    // KHR_materials_diffuse_transmission: the share of the diffuse base transmitted, its colour.
    diffuse_transmission: f32,
    diffuse_transmission_color: vec3<f32>,
}

// The anisotropic frame about n (CPU twin: shading::aniso_frame): tangent, bitangent, and
// (α along, α across, 1 where anisotropic else 0) in `a`.
struct Aniso {
    t: vec3<f32>,
    b: vec3<f32>,
    a: vec3<f32>,
}

fn aniso_frame(e: BsdfExt, n: vec3<f32>) -> Aniso {
    if all(e.aniso_dir == vec3<f32>(0.0)) {
        return Aniso(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    }
    let t = e.aniso_dir - n * dot(n, e.aniso_dir);
    if !(dot(t, t) > 1e-12) {
        return Aniso(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    }
    let tt = normalize(t);
    return Aniso(tt, cross(n, tt), vec3<f32>(e.alpha_t, e.core.alpha, 1.0));
}

fn aniso_d(f: Aniso, n: vec3<f32>, h: vec3<f32>) -> f32 {
    let x = dot(f.t, h) / f.a.x;
    let y = dot(f.b, h) / f.a.y;
    let z = dot(n, h);
    let d = x * x + y * y + z * z;
    return 1.0 / (PI * f.a.x * f.a.y * d * d);
}

fn aniso_root(f: Aniso, n: vec3<f32>, w: vec3<f32>) -> f32 {
    let x = f.a.x * dot(f.t, w);
    let y = f.a.y * dot(f.b, w);
    let z = dot(n, w);
    return sqrt(x * x + y * y + z * z);
}

fn aniso_vis(f: Aniso, n: vec3<f32>, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    return 0.5 / (dot(n, wo) * aniso_root(f, n, wi) + dot(n, wi) * aniso_root(f, n, wo));
}

fn aniso_g1(f: Aniso, n: vec3<f32>, w: vec3<f32>) -> f32 {
    let c = abs(dot(n, w));
    return 2.0 * c / (c + aniso_root(f, n, w));
}

fn aniso_half(f: Aniso, n: vec3<f32>, u: f32, v: f32) -> vec3<f32> {
    let s = sqrt(u);
    let phi = 2.0 * PI * v;
    return normalize(f.t * (f.a.x * s * cos(phi)) + f.b * (f.a.y * s * sin(phi)) + n * sqrt(max(1.0 - u, 0.0)));
}

// The sheen's fitted Λ (KHR_materials_sheen's `l` and `lambda_sheen`; CPU twin: sheen_lambda).
fn sheen_l(x: f32, alpha: f32) -> f32 {
    let t = (1.0 - alpha) * (1.0 - alpha);
    let a = mix(21.5473, 25.3245, t);
    let b = mix(3.82987, 3.32435, t);
    let c = mix(0.19823, 0.16801, t);
    let d = mix(-1.97760, -1.27393, t);
    let e = mix(-4.32054, -4.85967, t);
    return a / (1.0 + b * pow(x, c)) + d * x + e;
}

fn sheen_lambda(c: f32, alpha: f32) -> f32 {
    if c < 0.5 {
        return exp(sheen_l(c, alpha));
    }
    return exp(2.0 * sheen_l(0.5, alpha) - sheen_l(1.0 - c, alpha));
}

// The Charlie sheen BRDF at colour 1: D(n·h) · G / (4 cos_i cos_o), α = r².
fn sheen_brdf(noh: f32, cos_i: f32, cos_o: f32, r: f32) -> f32 {
    let alpha = r * r;
    let inv = 1.0 / alpha;
    let sin2 = max(1.0 - noh * noh, 0.0);
    let d = (2.0 + inv) * pow(sin2, 0.5 * inv) / (2.0 * PI);
    let g = 1.0 / (1.0 + sheen_lambda(cos_o, alpha) + sheen_lambda(cos_i, alpha));
    return d * g / (4.0 * cos_i * cos_o);
}

// The sheen's directional albedo E(cos, r), bilinear in the table after the materials
// (src/trace/pack.rs; CPU twin: shading::sheen_albedo).
fn sheen_table(k: u32) -> f32 {
    let base = arrayLength(&materials) - SHEEN_TABLE_ROWS;
    return materials[base + k / 4u][k % 4u];
}

fn sheen_albedo(cos: f32, r: f32) -> f32 {
    let last_x = f32(SHEEN_COLUMNS - 1u);
    let last_y = f32(SHEEN_ROWS - 1u);
    let x = clamp(cos, 0.0, 1.0) * last_x;
    let y = clamp((r - SHEEN_MIN_ROUGHNESS) / (1.0 - SHEEN_MIN_ROUGHNESS), 0.0, 1.0) * last_y;
    let x0 = min(floor(x), last_x - 1.0);
    let y0 = min(floor(y), last_y - 1.0);
    let fx = x - x0;
    let fy = y - y0;
    let k = u32(y0) * SHEEN_COLUMNS + u32(x0);
    let a = sheen_table(k);
    let b = sheen_table(k + 1u);
    let c = sheen_table(k + SHEEN_COLUMNS);
    let d = sheen_table(k + SHEEN_COLUMNS + 1u);
    let top = a + (b - a) * fx;
    let bottom = c + (d - c) * fx;
    return top + (bottom - top) * fy;
}

fn ext_sheen_e(e: BsdfExt, cos: f32) -> f32 {
    if all(e.sheen == vec3<f32>(0.0)) {
        return 0.0;
    }
    return sheen_albedo(cos, e.sheen_roughness);
}

fn ggx_d(noh: f32, a2: f32) -> f32 {
    let dd = noh * noh * (a2 - 1.0) + 1.0;
    return a2 / (PI * dd * dd);
}

fn ggx_vis(cos_i: f32, cos_o: f32, a2: f32) -> f32 {
    return 0.5 / (cos_i * sqrt(cos_o * cos_o * (1.0 - a2) + a2) + cos_o * sqrt(cos_i * cos_i * (1.0 - a2) + a2));
}

fn ggx_g1(c: f32, a2: f32) -> f32 {
    return 2.0 * c / (c + sqrt(a2 + (1.0 - a2) * c * c));
}

fn ggx_half(tb: mat2x3<f32>, n: vec3<f32>, alpha: f32, u: f32, v: f32) -> vec3<f32> {
    let a2 = alpha * alpha;
    let cos_h = sqrt(max((1.0 - u) / (1.0 + (a2 - 1.0) * u), 0.0));
    let sin_h = sqrt(max(1.0 - cos_h * cos_h, 0.0));
    let phi = 2.0 * PI * v;
    return tb[0] * (sin_h * cos(phi)) + tb[1] * (sin_h * sin(phi)) + n * cos_h;
}

fn max3(v: vec3<f32>) -> f32 {
    return max(max(v.x, v.y), v.z);
}

// KHR_materials_dispersion's wavelength term per channel, (523655/λ² − 1.5168) / 20, at the
// Fraunhofer C, d and F lines (CPU twin: shading::DISPERSION_TERMS, the same literals).
const DISPERSION_R: f32 = -0.0150474785;
const DISPERSION_G: f32 = 0.0000021811952;
const DISPERSION_B: f32 = 0.034952514;

// The index of refraction in `channel` (0 red, 1 green, 2 blue) of a material of `ior` and
// `dispersion` (20 / Abbe number), in [1, 10] (CPU twin: shading::dispersed_ior).
fn dispersed_ior(ior: f32, dispersion: f32, channel: u32) -> f32 {
    let terms = vec3<f32>(DISPERSION_R, DISPERSION_G, DISPERSION_B);
    return clamp(ior + (ior - 1.0) * dispersion * terms[channel], 1.0, 10.0);
}

struct Picked {
    channel: u32,
    throughput: vec3<f32>,
}

// The colour channel a path follows from a dispersive surface on, picked in proportion to its
// throughput, and the throughput from here on: that channel alone over its probability (CPU
// twin: shading::pick_channel, which says why a path needs no state for it).
fn pick_channel(t: vec3<f32>, u: f32) -> Picked {
    let sum = t.x + t.y + t.z;
    let x = u * sum;
    var channel = 2u;
    if x < t.x || (t.y == 0.0 && t.z == 0.0) {
        channel = 0u;
    } else if x < t.x + t.y || t.z == 0.0 {
        channel = 1u;
    }
    var out = vec3<f32>(0.0);
    out[channel] = sum;
    return Picked(channel, out);
}

fn ext_transmits(e: BsdfExt) -> bool {
    return (e.transmission > 0.0 || e.diffuse_transmission > 0.0) && e.core.metallic < 1.0;
}

struct ExtFresnel {
    fd: vec3<f32>,
    f: vec3<f32>,
}

fn ext_fresnel(e: BsdfExt, c: f32) -> ExtFresnel {
    let b = e.core;
    let f0 = min(e.specular_color * e.f0, vec3<f32>(1.0));
    var cc = c;
    var tir = false;
    if e.transmission > 0.0 && e.eta < 1.0 {
        let s2 = (1.0 - c * c) / (e.eta * e.eta);
        tir = s2 >= 1.0;
        cc = sqrt(max(1.0 - s2, 0.0));
    }
    let k = pow5(max(1.0 - cc, 0.0));
    var fd = vec3<f32>(1.0);
    if !tir {
        fd = (f0 + (vec3<f32>(1.0) - f0) * k) * b.specular;
    }
    let km = pow5(max(1.0 - c, 0.0));
    let fm = b.base + (vec3<f32>(1.0) - b.base) * km;
    return ExtFresnel(fd, mix(fd, fm, b.metallic));
}

fn ext_coat(e: BsdfExt, cos_oc: f32) -> f32 {
    if e.clearcoat > 0.0 && cos_oc > 0.0 {
        return e.clearcoat * (0.04 + 0.96 * pow5(max(1.0 - cos_oc, 0.0)));
    }
    return 0.0;
}

// Lobe probabilities: specular, diffuse, transmission, coat in `p`, the sheen's and the
// diffuse transmission's apart.
struct ExtLobes {
    p: vec4<f32>,
    sheen: f32,
    dt: f32,
}

fn ext_lobes(e: BsdfExt, cos_o: f32, cos_oc: f32) -> ExtLobes {
    let b = e.core;
    let fr = ext_fresnel(e, cos_o);
    let coat = ext_coat(e, cos_oc);
    let e_o = ext_sheen_e(e, cos_o);
    let under = 1.0 - max3(e.sheen) * e_o;
    let ws = lum(fr.f) * (1.0 - coat) * under;
    let rest = lum(b.base) * (1.0 - b.metallic) * (1.0 - max3(fr.fd)) * (1.0 - coat) * under;
    let dt = e.diffuse_transmission;
    let wd = rest * (1.0 - e.transmission) * (1.0 - dt);
    let wt = rest * e.transmission;
    let wsh = lum(e.sheen) * e_o * (1.0 - coat);
    let wdt = lum(e.diffuse_transmission_color) * (1.0 - b.metallic) * (1.0 - max3(fr.fd))
        * (1.0 - coat) * under * (1.0 - e.transmission) * dt;
    let total = ws + wd + wt + coat + wsh + wdt;
    if total > 0.0 {
        return ExtLobes(vec4<f32>(ws / total, wd / total, wt / total, coat / total), wsh / total,
            wdt / total);
    }
    return ExtLobes(vec4<f32>(0.5, 0.5, 0.0, 0.0), 0.0, 0.0);
}

fn ext_eval(e: BsdfExt, n: vec3<f32>, wo: vec3<f32>, wi: vec3<f32>) -> vec4<f32> {
    let b = e.core;
    let cos_o = dot(n, wo);
    let cos_i = dot(n, wi);
    if cos_o <= 0.0 || cos_i == 0.0 {
        return vec4<f32>(0.0);
    }
    let cn = e.coat_normal;
    let cos_oc = dot(cn, wo);
    let lobes = ext_lobes(e, cos_o, cos_oc);
    let p = lobes.p;
    let coat = ext_coat(e, cos_oc);
    let a2 = b.alpha * b.alpha;
    let sheened = any(e.sheen != vec3<f32>(0.0));
    let an = aniso_frame(e, n);
    if cos_i > 0.0 {
        let h = normalize(wo + wi);
        let noh = max(dot(n, h), 0.0);
        let voh = max(dot(wo, h), 1e-7);
        let fr = ext_fresnel(e, voh);
        var d = 0.0;
        var vis = 0.0;
        if an.a.z > 0.0 {
            d = aniso_d(an, n, h);
            vis = aniso_vis(an, n, wi, wo);
        } else {
            d = ggx_d(noh, a2);
            vis = ggx_vis(cos_i, cos_o, a2);
        }
        let spec = fr.f * (d * vis);
        let diff = b.base * ((1.0 - b.metallic) * (1.0 - max3(fr.fd)) * (1.0 - e.transmission)
            * (1.0 - e.diffuse_transmission) / PI);
        var value = (spec + diff) * (1.0 - coat);
        var pdf = p.x * d * noh / (4.0 * voh) + p.y * cos_i / PI;
        if sheened {
            // The sheen over the base, the base scaled by its albedo-scaling term.
            let s = max3(e.sheen);
            let scale = min(1.0 - s * ext_sheen_e(e, cos_o), 1.0 - s * ext_sheen_e(e, cos_i));
            let sheen = e.sheen * sheen_brdf(noh, cos_i, cos_o, e.sheen_roughness);
            value = (sheen + (spec + diff) * scale) * (1.0 - coat);
            pdf += lobes.sheen * (0.5 / PI);
        }
        if coat > 0.0 {
            let c = ext_coat_term(e, coat, p.w, cos_oc, wi, h, voh);
            value += vec3<f32>(c.x);
            pdf += c.y;
        }
        return vec4<f32>(value, pdf);
    }
    // Below the base's normal: the coat's reflection where its own normal bends it there, and
    // the base's transmission.
    let bent = any(cn != n);
    var c = vec2<f32>(0.0);
    if coat > 0.0 && bent {
        let hr = normalize(wo + wi);
        c = ext_coat_term(e, coat, p.w, cos_oc, wi, hr, max(dot(wo, hr), 1e-7));
    }
    if !ext_transmits(e) {
        return vec4<f32>(vec3<f32>(c.x), c.y);
    }
    // The diffuse transmission: Lambertian through the surface, its share of the base (the
    // Fresnel weight at the view, as its lobe's probability takes it).
    var cv = vec3<f32>(c.x);
    var cp = c.y;
    let diffuse = e.diffuse_transmission > 0.0;
    if diffuse {
        let fo = ext_fresnel(e, cos_o);
        var value = e.diffuse_transmission_color * ((1.0 - b.metallic) * (1.0 - max3(fo.fd))
            * (1.0 - e.transmission) * e.diffuse_transmission * (1.0 - coat) / PI);
        if sheened {
            value *= 1.0 - max3(e.sheen) * ext_sheen_e(e, cos_o);
        }
        cv += value;
        cp += lobes.dt * -cos_i / PI;
    }
    if e.transmission == 0.0 {
        return vec4<f32>(cv, cp);
    }
    let eta = e.eta;
    var h = -normalize(wo + wi * eta);
    if dot(n, h) < 0.0 {
        h = -h;
    }
    let woh = dot(wo, h);
    let wih = dot(wi, h);
    let denom = woh + eta * wih;
    if !(woh > 0.0 && wih < 0.0) || abs(denom) < 1e-7 || !all(abs(h) <= vec3<f32>(T_FAR)) {
        return vec4<f32>(cv, cp);
    }
    let noh = dot(n, h);
    let fr = ext_fresnel(e, woh);
    var d = 0.0;
    var g = 0.0;
    if an.a.z > 0.0 {
        d = aniso_d(an, n, h);
        g = aniso_g1(an, n, wo) * aniso_g1(an, n, wi);
    } else {
        d = ggx_d(noh, a2);
        g = ggx_g1(cos_o, a2) * ggx_g1(-cos_i, a2);
    }
    let jac = eta * eta * -wih / (denom * denom);
    let btdf = woh * d * g * jac / (cos_o * -cos_i);
    var value = b.base * ((1.0 - b.metallic) * (1.0 - max3(fr.fd)) * e.transmission * btdf * (1.0 - coat));
    if sheened {
        value *= 1.0 - max3(e.sheen) * ext_sheen_e(e, cos_o);
    }
    if bent || diffuse {
        return vec4<f32>(value + cv, p.z * d * noh * jac + cp);
    }
    return vec4<f32>(value, p.z * d * noh * jac);
}

// The coat's reflection about its own normal for `wi` above the coat: its value and its pdf
// (CPU twin: the closure `coat_term` in BsdfExt::eval).
fn ext_coat_term(e: BsdfExt, coat: f32, p3: f32, cos_oc: f32, wi: vec3<f32>, h: vec3<f32>, voh: f32) -> vec2<f32> {
    let cn = e.coat_normal;
    let cos_ic = dot(cn, wi);
    if coat > 0.0 && cos_ic > 0.0 {
        let c2 = e.clearcoat_alpha * e.clearcoat_alpha;
        let noh = max(dot(cn, h), 0.0);
        let dc = ggx_d(noh, c2);
        return vec2<f32>(coat * dc * ggx_vis(cos_ic, cos_oc, c2), p3 * dc * noh / (4.0 * voh));
    }
    return vec2<f32>(0.0);
}

fn ext_sample(e: BsdfExt, n: vec3<f32>, wo: vec3<f32>, u_lobe: f32, u: f32, v: f32) -> vec3<f32> {
    let tb = basis_t(n);
    let lobes = ext_lobes(e, dot(n, wo), dot(e.coat_normal, wo));
    let p = lobes.p;
    let an = aniso_frame(e, n);
    if u_lobe < p.x {
        var h = ggx_half(tb, n, e.core.alpha, u, v);
        if an.a.z > 0.0 {
            h = aniso_half(an, n, u, v);
        }
        return 2.0 * dot(wo, h) * h - wo;
    } else if u_lobe < p.x + p.y {
        let l = cosine_hemisphere(u, v);
        return tb[0] * l.x + tb[1] * l.y + n * l.z;
    } else if u_lobe < p.x + p.y + p.z {
        var h = ggx_half(tb, n, e.core.alpha, u, v);
        if an.a.z > 0.0 {
            h = aniso_half(an, n, u, v);
        }
        let c = dot(wo, h);
        let r = 1.0 / e.eta;
        let k = 1.0 - r * r * (1.0 - c * c);
        if c <= 0.0 || k < 0.0 {
            return vec3<f32>(0.0);
        }
        return -r * wo + (r * c - sqrt(k)) * h;
    } else if lobes.dt > 0.0 && u_lobe >= p.x + p.y + p.z + p.w + lobes.sheen {
        // The diffuse transmission: cosine-weighted about the other side.
        let l = cosine_hemisphere(u, v);
        return -(tb[0] * l.x + tb[1] * l.y + n * l.z);
    } else if lobes.sheen > 0.0 && u_lobe >= p.x + p.y + p.z + p.w {
        // The sheen: uniform over the hemisphere (its value peaks at grazing angles).
        let l = uniform_sphere(0.5 * u, v);
        return tb[0] * l.x + tb[1] * l.y + n * l.z;
    }
    let cn = e.coat_normal;
    var tbc = tb;
    if any(cn != n) {
        tbc = basis_t(cn);
    }
    let h = ggx_half(tbc, cn, e.clearcoat_alpha, u, v);
    return 2.0 * dot(wo, h) * h - wo;
}
