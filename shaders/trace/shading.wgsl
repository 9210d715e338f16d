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
