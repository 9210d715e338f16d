//! The integrator on the CPU: the twin of `shaders/trace/path.wgsl` (same data, same random
//! numbers, same formulas, f32), used as the test oracle and as the fallback backend.
//!
//! One call of [`trace_sample`] is one path: a pinhole (or orthographic) primary ray jittered
//! inside the pixel (or the wall camera's, [`trace_counted_with`]: from the eye through the
//! pixel's point on the display, `super::wall`), then at each vertex emission (MIS-weighted
//! against next-event estimation), one light sample (the environment, a punctual light — a
//! delta light, weight 1 — or an emissive triangle, power heuristic), one BSDF sample (reflected, or refracted
//! through glass), and Russian roulette from the fourth vertex on, up to `max_depth` vertices.
//! At a dispersive surface (KHR_materials_dispersion) the path picks one colour channel in
//! proportion to its throughput and carries that channel alone from there on, refracted by its
//! own index (`shading::pick_channel`: a path already on one channel keeps it, so no state
//! travels with the path).
//! Alpha-masked and blended triangles are tested during traversal (`alpha_covered`); the
//! features a scene lacks (pack.rs's flags) cost a bit test.
//!
//! Random numbers: `pcg4d([pixel, sample, seed, stream::TRACE + dim])` where `sample` is the
//! pixel's sample count before this sample (so a pixel's sequence does not depend on which
//! other pixels were sampled), dimension 0 is the pixel jitter and dimensions 1 + 2·depth and
//! 2 + 2·depth serve the path vertex at `depth` (light selection and point, BSDF lobe and
//! direction, Russian roulette, the dispersion's channel).
//!
//! [`render_cpu_with`] and [`samples_cpu`] trace their pixels in batches of paths (`batch.rs`):
//! the paths of a batch advance a vertex at a time and are shaded sixteen at once in lanes
//! ([`crate::trace::lanes`]), the same function as `trace_path` path by path to the bit, every
//! material feature included.

use std::f32::consts::PI;
use std::sync::LazyLock;

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;

use super::accum::{Accumulation, accumulate};
use super::camera::RenderCamera;
use super::pack::{
    EXTRAS_STRIDE, FEAT_ALPHA, FEAT_EXTRAS, LIGHT_DIRECTIONAL, LIGHT_SPOT, MAT_BASE_TEX, MAT_BLEND,
    MAT_DISPERSION, MAT_EMISSIVE_TEX, MAT_EXT_BSDF, MAT_EXT_TEX, MAT_MASK, MAT_MR_TEX,
    MAT_NORMAL_TEX, MAT_VOLUME, MATERIAL_ANISO_ROW, MATERIAL_COAT_ROW, MATERIAL_DIFFUSE_ROW,
    MATERIAL_SHEEN_ROW, MATERIAL_STRIDE, MIN_ALPHA, NO_TEXTURE, PackedScene,
};
use super::shading::{
    Bsdf, BsdfExt, SHEEN_MIN_ROUGHNESS, basis, direction_to_equirect, dispersed_ior,
    equirect_to_direction, offset_ray, pick_channel, srgb_to_linear, uniform_sphere,
};
use super::wall::WallCamera;
use crate::random::{pcg4d, stream, unit_f32};

mod batch;

/// `ext_bsdf`'s channel at a surface that is not dispersive: the material's own index of
/// refraction. (A path that follows one channel carries it in its throughput, where the others
/// are zero, so nothing else needs to know.)
pub const ALL_CHANNELS: u32 = 3;

/// What one iteration of the integrator needs besides the scene.
#[derive(Clone, Copy, Debug)]
pub struct TraceSettings {
    pub width: u32,
    pub height: u32,
    pub seed: u32,
    /// Maximum number of path vertices (1 = direct visibility of emitters and the environment
    /// plus direct lighting at the first hit).
    pub max_depth: u32,
    pub camera: RenderCamera,
}

/// The default maximum path depth.
pub const DEFAULT_MAX_DEPTH: u32 = 8;

#[inline]
fn rand4(pixel: u32, sample: u32, seed: u32, dim: u32) -> [f32; 4] {
    pcg4d([pixel, sample, seed, stream::TRACE.wrapping_add(dim)]).map(unit_f32)
}

#[inline]
pub(super) fn v3(a: [f32; 4]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

/// Power heuristic (β = 2).
#[inline]
fn mis(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 { a2 / (a2 + b2) } else { 0.0 }
}

/// The largest `k < n` with `dist[offset + k] ≤ u` (a CDF of `n + 1` entries).
#[inline]
fn sample_cdf(dist: &[f32], offset: u32, n: u32, u: f32) -> u32 {
    let (mut lo, mut hi) = (0u32, n);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if dist[(offset + mid) as usize] <= u {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// `i` wrapped into `0..n` by a glTF wrap mode (0 repeat, 1 clamp to edge, 2 mirrored repeat).
#[inline]
fn wrap(i: i32, n: u32, mode: u32) -> u32 {
    let n = n as i32;
    (match mode {
        1 => i.clamp(0, n - 1),
        2 => {
            let k = i.rem_euclid(2 * n);
            if k >= n { 2 * n - 1 - k } else { k }
        }
        _ => i.rem_euclid(n),
    }) as u32
}

/// `i.rem_euclid(n)` for `n > 0`, a mask where `n` is a power of two (most textures' sizes):
/// the same value without an integer division.
#[inline(always)]
fn rem_euclid(i: i32, n: i32) -> i32 {
    if n & (n - 1) == 0 {
        i & (n - 1)
    } else {
        i.rem_euclid(n)
    }
}

/// `(wrap(i, n, mode), wrap(i + 1, n, mode))` (`i + 1` wrapping as a bilinear lookup's
/// neighbour does) with one integer division instead of two: the neighbour of the wrapped
/// `i` is the next value, back to the start past the end. Four divisions a bilinear lookup
/// were a visible part of a textured scene's profile.
#[inline]
fn wrap_pair(i: i32, n: u32, mode: u32) -> (u32, u32) {
    let j = i.wrapping_add(1);
    if j == i32::MIN {
        return (wrap(i, n, mode), wrap(j, n, mode));
    }
    let n = n as i32;
    let (a, b) = match mode {
        1 => (i.clamp(0, n - 1), j.clamp(0, n - 1)),
        2 => {
            let k = rem_euclid(i, 2 * n);
            let next = if k + 1 == 2 * n { 0 } else { k + 1 };
            let mirror = |k: i32| if k >= n { 2 * n - 1 - k } else { k };
            (mirror(k), mirror(next))
        }
        _ => {
            let k = rem_euclid(i, n);
            (k, if k + 1 == n { 0 } else { k + 1 })
        }
    };
    (a as u32, b as u32)
}

/// `srgb_to_linear(i / 255)` for every 8-bit channel value `i`: the decoding of a colour
/// texel, computed once (the same values; a `powf` per channel was 6.8 % of the small city's
/// profile: BENCHMARKS.md, *CPU shading and batches*).
static SRGB_TO_LINEAR: LazyLock<[f32; 256]> =
    LazyLock::new(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)));

fn texel(sc: &PackedScene, off: u32, w: u32, h: u32, sampler: u32, x: i32, y: i32) -> Vec4 {
    let xi = wrap(x, w, sampler & 3);
    let yi = wrap(y, h, (sampler >> 2) & 3);
    texel_at(sc, off, w, sampler, xi, yi)
}

/// The texel at wrapped coordinates (`xi`, `yi`) of the texture at `off`, `w` wide.
#[inline]
fn texel_at(sc: &PackedScene, off: u32, w: u32, sampler: u32, xi: u32, yi: u32) -> Vec4 {
    let c = sc.texels[(off + yi * w + xi) as usize];
    let ch = |s: u32| ((c >> s) & 0xff) as f32 / 255.0;
    if sampler & 32 != 0 {
        let lut = &*SRGB_TO_LINEAR;
        let lin = |s: u32| lut[((c >> s) & 0xff) as usize];
        Vec4::new(lin(0), lin(8), lin(16), ch(24))
    } else {
        Vec4::new(ch(0), ch(8), ch(16), ch(24))
    }
}

/// A texture lookup with the texture's sampler (wrap modes, nearest or bilinear), in linear
/// values (sRGB-decoded for colour textures).
fn texture(sc: &PackedScene, tex: u32, uv: Vec2) -> Vec4 {
    let hdr = &sc.texels[4 * tex as usize..4 * tex as usize + 4];
    let (off, w, h, sampler) = (hdr[0], hdr[1], hdr[2], hdr[3]);
    let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
    if sampler & 16 != 0 {
        let x = (uv.x * w as f32).floor() as i32;
        let y = (uv.y * h as f32).floor() as i32;
        return texel(sc, off, w, h, sampler, x, y);
    }
    let x = uv.x * w as f32 - 0.5;
    let y = uv.y * h as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (x0, x1) = wrap_pair(x0 as i32, w, sampler & 3);
    let (y0, y1) = wrap_pair(y0 as i32, h, (sampler >> 2) & 3);
    let a = texel_at(sc, off, w, sampler, x0, y0);
    let b = texel_at(sc, off, w, sampler, x1, y0);
    let c = texel_at(sc, off, w, sampler, x0, y1);
    let d = texel_at(sc, off, w, sampler, x1, y1);
    (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy
}

/// A point on a triangle: its index and the barycentrics of its second and third vertex.
#[derive(Clone, Copy)]
pub(super) struct SurfacePoint {
    pub(super) tri: u32,
    pub(super) u: f32,
    pub(super) v: f32,
}

impl SurfacePoint {
    fn lerp4(&self, a: [f32; 4], b: [f32; 4], c: [f32; 4]) -> Vec4 {
        Vec4::from_array(a) * (1.0 - self.u - self.v)
            + Vec4::from_array(b) * self.u
            + Vec4::from_array(c) * self.v
    }
}

/// The texture coordinates of set `set` at `sp` (TEXCOORD_1 from the vertex extras).
fn surface_uv(sc: &PackedScene, sp: SurfacePoint, set: u32) -> Vec2 {
    let b0 = 1.0 - sp.u - sp.v;
    if set == 1 && sc.features & FEAT_EXTRAS != 0 {
        let e = (sc.extras_offset + EXTRAS_STRIDE as u32 * sp.tri) as usize;
        let (a, b) = (sc.shade[e + 3], sc.shade[e + 4]);
        return Vec2::new(a[0], a[1]) * b0
            + Vec2::new(a[2], a[3]) * sp.u
            + Vec2::new(b[0], b[1]) * sp.v;
    }
    let sh = &sc.shade[4 * sp.tri as usize..4 * sp.tri as usize + 4];
    Vec2::new(sh[0][3], sh[1][3]) * b0
        + Vec2::new(sh[2][3], sh[3][0]) * sp.u
        + Vec2::new(sh[3][1], sh[3][2]) * sp.v
}

/// Material `mb`'s texture slot `k` at `sp` (the slot's set and transform).
pub(super) fn slot(sc: &PackedScene, mb: usize, k: usize, sp: SurfacePoint) -> Vec4 {
    let (r0, r1) = (sc.materials[mb + 5 + 2 * k], sc.materials[mb + 6 + 2 * k]);
    let uv = surface_uv(sc, sp, r1[3].to_bits()).extend(1.0);
    let t = Vec2::new(v3(r0).dot(uv), v3(r1).dot(uv));
    texture(sc, r0[3].to_bits(), t)
}

/// The material base (vec4 index) of triangle `tri`.
fn material_base(sc: &PackedScene, tri: u32) -> usize {
    MATERIAL_STRIDE * sc.shade[4 * tri as usize + 3][3].to_bits() as usize
}

/// Base colour (factor × texture × vertex colour) at `sp` for material `mb` with `flags`.
pub(super) fn base_color(sc: &PackedScene, mb: usize, flags: u32, sp: SurfacePoint) -> Vec4 {
    let mut base = Vec4::from_array(sc.materials[mb]);
    if flags & MAT_BASE_TEX != 0 {
        base *= slot(sc, mb, 0, sp);
    }
    if sc.features & FEAT_EXTRAS != 0 {
        let e = (sc.extras_offset + EXTRAS_STRIDE as u32 * sp.tri) as usize;
        base *= sp.lerp4(sc.shade[e], sc.shade[e + 1], sc.shade[e + 2]);
    }
    base
}

/// Coverage of an alpha-tested triangle at (u, v): MASK compares alpha with the cutoff, BLEND
/// with a uniform threshold hashed from the ray's seed and the triangle (so a ray sees a
/// blended surface with probability alpha). The twin of `alpha_covered` in path.wgsl.
#[inline(never)]
pub(super) fn alpha_covered(sc: &PackedScene, tri: u32, u: f32, v: f32, seed: u32) -> bool {
    let mb = material_base(sc, tri);
    let flags = sc.materials[mb + 1][3] as u32;
    let a = base_color(sc, mb, flags, SurfacePoint { tri, u, v }).w;
    if flags & MAT_MASK != 0 {
        return a >= sc.materials[mb + 2][3];
    }
    a > unit_f32(pcg4d([seed, tri, ALPHA_HASH, 0])[0])
}

/// The coverage hash's third word (any constant apart from the other streams).
const ALPHA_HASH: u32 = 0x414c_5048;

/// A ray's coverage seed: `which` 0 for the path's ray at `depth`, 1 for its shadow ray.
#[inline]
pub(super) fn ray_seed(pixel: u32, sample: u32, seed: u32, depth: u32, which: u32) -> u32 {
    pcg4d([
        pixel,
        sample,
        seed,
        stream::TRACE.wrapping_add(0x8000 + 2 * depth + which),
    ])[0]
}

/// The emitted radiance of material `mb` (with `flags`) at `sp`: the factor × the emissive
/// texture.
fn emission_at(sc: &PackedScene, mb: usize, flags: u32, sp: SurfacePoint) -> Vec3 {
    let mut e = v3(sc.materials[mb + 1]);
    if flags & MAT_EMISSIVE_TEX != 0 {
        e *= slot(sc, mb, 3, sp).truncate();
    }
    e
}

/// Where [`ext_bsdf`] is evaluated: the surface point `sp`, hit from the front or not, `ns`
/// the interpolated normal before any normal map and `ng` the geometric normal towards the
/// viewer.
#[derive(Clone, Copy)]
struct ExtSurface {
    front: bool,
    sp: SurfacePoint,
    ns: Vec3,
    ng: Vec3,
}

/// The extensions' BSDF of material `mb` (with `flags`) over its core BSDF `core` at
/// `surface.sp`, hit from the front or not (KHR_materials_transmission, _ior, _specular, _clearcoat, _sheen,
/// _anisotropy, _dispersion, _diffuse_transmission): each factor times its texture where the
/// material has one — transmission × R, specular × A, specular colour × RGB, coat × R, coat
/// roughness × G (α = max(α · G², [`MIN_ALPHA`]), as the metallic-roughness map's), diffuse
/// transmission × A, its colour × RGB — and the coat's normal: `ns`, the interpolated normal
/// before any normal map, bent by the coat's own normal map where it has one, on `ng`'s side
/// (the geometric normal towards the viewer). `channel` is the colour channel a path follows
/// through a dispersive material (its index of refraction then that channel's), or
/// [`ALL_CHANNELS`]. The twin of `ext_bsdf` in path.wgsl.
#[inline(never)]
fn ext_bsdf(
    sc: &PackedScene,
    mb: usize,
    flags: u32,
    mut core: Bsdf,
    surface: ExtSurface,
    channel: u32,
) -> BsdfExt {
    let ExtSurface { front, sp, ns, ng } = surface;
    let (m3, m4) = (sc.materials[mb + 3], sc.materials[mb + 4]);
    // The anisotropy's strength and its direction in the tangent frame (cos, sin of the
    // rotation, or the texture's direction rotated by it), and the dispersion.
    let an = sc.materials[mb + MATERIAL_ANISO_ROW];
    let ior = if channel == ALL_CHANNELS {
        m4[0]
    } else {
        dispersed_ior(m4[0], an[3], channel)
    };
    let f0 = (ior - 1.0) / (ior + 1.0);
    let mut specular_color = v3(m3);
    let mut transmission = m3[3];
    let (mut clearcoat, mut clearcoat_alpha) = (m4[1], m4[2]);
    let mut coat_normal = ns;
    let sh = sc.materials[mb + MATERIAL_SHEEN_ROW];
    let (mut sheen, mut sheen_roughness) = (v3(sh), sh[3]);
    let (mut strength, mut dir) = (an[0], Vec2::new(an[1], an[2]));
    let dt = sc.materials[mb + MATERIAL_DIFFUSE_ROW];
    let (mut diffuse_transmission, mut diffuse_transmission_color) = (dt[3], v3(dt));
    if flags & MAT_EXT_TEX != 0 {
        // Slots 4..14 (after base colour, metallic-roughness, normal and emissive); a slot
        // without a texture leaves its factor.
        let textured = |k: usize| sc.materials[mb + 5 + 2 * k][3].to_bits() != NO_TEXTURE;
        if textured(4) {
            transmission *= slot(sc, mb, 4, sp).x;
        }
        if textured(5) {
            core.specular *= slot(sc, mb, 5, sp).w;
        }
        if textured(6) {
            specular_color *= slot(sc, mb, 6, sp).truncate();
        }
        if textured(7) {
            clearcoat *= slot(sc, mb, 7, sp).x;
        }
        if textured(8) {
            let g = slot(sc, mb, 8, sp).y;
            clearcoat_alpha = (clearcoat_alpha * g * g).max(MIN_ALPHA);
        }
        if textured(9) {
            coat_normal =
                normal_mapped_by(sc, mb, 9, sc.materials[mb + MATERIAL_COAT_ROW][0], sp, ns);
        }
        if textured(10) {
            sheen *= slot(sc, mb, 10, sp).truncate();
        }
        if textured(11) {
            sheen_roughness *= slot(sc, mb, 11, sp).w;
        }
        if textured(12) {
            let a = slot(sc, mb, 12, sp);
            let d = Vec2::new(a.x * 2.0 - 1.0, a.y * 2.0 - 1.0);
            dir = Vec2::new(d.x * dir.x - d.y * dir.y, d.x * dir.y + d.y * dir.x);
            strength *= a.z;
        }
        if textured(13) {
            diffuse_transmission *= slot(sc, mb, 13, sp).w;
        }
        if textured(14) {
            diffuse_transmission_color *= slot(sc, mb, 14, sp).truncate();
        }
    }
    let (mut aniso_dir, mut alpha_t) = (Vec3::ZERO, core.alpha);
    if strength > 0.0 {
        let (t, b) = tangent_frame(sc, sp, ns);
        aniso_dir = t * dir.x + b * dir.y;
        alpha_t = core.alpha + (1.0 - core.alpha) * (strength * strength);
    }
    if coat_normal.dot(ng) < 0.0 {
        coat_normal = -coat_normal;
    }
    BsdfExt {
        core,
        specular_color,
        f0: f0 * f0,
        eta: if front { ior } else { 1.0 / ior },
        transmission,
        clearcoat,
        clearcoat_alpha,
        coat_normal,
        sheen,
        sheen_roughness: sheen_roughness.max(SHEEN_MIN_ROUGHNESS),
        aniso_dir,
        alpha_t,
        diffuse_transmission,
        diffuse_transmission_color,
    }
}

/// Next-event estimation of one punctual light (`u` the selection number): direction,
/// radiance × falloff (inverse square, spot cone), selection probability, shadow ray length,
/// and `true`: a delta light.
#[inline(never)]
fn sample_punctual(sc: &PackedScene, po: Vec3, u: f32) -> (Vec3, Vec3, f32, f32, bool) {
    let n = sc.punctual_count;
    let k = (((u - sc.env_select) / sc.punct_select * n as f32) as u32).min(n - 1);
    let l = 3 * (sc.light_count + k) as usize;
    let (la, lb, lc) = (sc.lights[l], sc.lights[l + 1], sc.lights[l + 2]);
    let pdf = sc.punct_select / n as f32;
    if la[3] as u32 == LIGHT_DIRECTIONAL {
        return (v3(la), v3(lb), pdf, f32::INFINITY, true);
    }
    let to = v3(la) - po;
    let dist2 = to.length_squared();
    let dist = dist2.sqrt();
    let wi = to / dist;
    let mut le = v3(lb) / dist2;
    if la[3] as u32 == LIGHT_SPOT {
        // glTF's recommended smooth falloff between the cones.
        let scale = 1.0 / (lc[3] - lb[3]).max(0.001);
        let t = ((v3(lc).dot(-wi) - lb[3]) * scale).clamp(0.0, 1.0);
        le *= t * t;
    }
    (wi, le, pdf, dist * (1.0 - 1e-4), true)
}

/// What is left of light that crossed a length `t` of the medium inside material `mb`'s
/// surface (KHR_materials_volume, Beer–Lambert): exp(−σt) per channel. A ray that meets a
/// [`MAT_VOLUME`] surface from behind has just crossed it; the medium is that of the closed
/// mesh the surface bounds (media do not nest).
#[inline]
fn absorbed(sc: &PackedScene, mb: usize, t: f32) -> Vec3 {
    let s = sc.materials[mb + MATERIAL_COAT_ROW];
    Vec3::new((-s[1] * t).exp(), (-s[2] * t).exp(), (-s[3] * t).exp())
}

/// The normal-mapped shading normal: the slot-2 texel in the frame of the interpolated
/// tangent (sign in w) and `ns` (before any flip to the viewer's side).
#[inline(never)]
pub(super) fn normal_mapped(sc: &PackedScene, mb: usize, sp: SurfacePoint, ns: Vec3) -> Vec3 {
    normal_mapped_by(sc, mb, 2, sc.materials[mb + 4][3], sp, ns)
}

/// [`normal_mapped`] by the normal map in texture slot `k` with `scale`.
fn normal_mapped_by(
    sc: &PackedScene,
    mb: usize,
    k: usize,
    scale: f32,
    sp: SurfacePoint,
    ns: Vec3,
) -> Vec3 {
    let tn = slot(sc, mb, k, sp).truncate() * 2.0 - Vec3::ONE;
    let (t, b) = tangent_frame(sc, sp, ns);
    let m = (t * (tn.x * scale) + b * (tn.y * scale) + ns * tn.z).normalize();
    if m.is_finite() { m } else { ns }
}

/// The interpolated tangent frame at `sp` about `ns` (before any flip to the viewer's side):
/// the unit tangent orthogonal to `ns` and the bitangent with its sign; a frame of its own
/// about `ns` where the scene has no tangents (no vertex extras: a scene built without them).
fn tangent_frame(sc: &PackedScene, sp: SurfacePoint, ns: Vec3) -> (Vec3, Vec3) {
    if sc.features & FEAT_EXTRAS == 0 {
        let t = basis(ns).0;
        return (t, ns.cross(t));
    }
    let e = (sc.extras_offset + EXTRAS_STRIDE as u32 * sp.tri) as usize;
    let t4 = sp.lerp4(sc.shade[e + 5], sc.shade[e + 6], sc.shade[e + 7]);
    let mut t = t4.truncate() - ns * ns.dot(t4.truncate());
    if !(t.length_squared() > 1e-12) {
        t = basis(ns).0;
    }
    let t = t.normalize();
    (t, ns.cross(t) * if t4.w < 0.0 { -1.0 } else { 1.0 })
}

/// Environment radiance arriving along `-d` (i.e. seen looking along `d`) and the density
/// (solid angle) with which [`sample_env`] picks `d`.
pub(super) fn env_eval(sc: &PackedScene, d: Vec3) -> (Vec3, f32) {
    let [w, h] = sc.env_size;
    if w == 0 {
        return (sc.env_constant, 1.0 / (4.0 * PI));
    }
    let (u, v) = direction_to_equirect(d);
    let col = ((u * w as f32) as u32).min(w - 1);
    let row = ((v * h as f32) as u32).min(h - 1);
    let e = sc.env[(row * w + col) as usize];
    let sin_theta = (1.0 - d.y * d.y).max(0.0).sqrt();
    let pdf = if sin_theta > 0.0 {
        e[3] / (2.0 * PI * PI * sin_theta)
    } else {
        0.0
    };
    (v3(e), pdf)
}

/// Samples an environment direction: (direction, radiance, density in solid angle).
fn sample_env(sc: &PackedScene, u1: f32, u2: f32) -> (Vec3, Vec3, f32) {
    let [w, h] = sc.env_size;
    if w == 0 {
        return (uniform_sphere(u1, u2), sc.env_constant, 1.0 / (4.0 * PI));
    }
    let row = sample_cdf(&sc.dist, sc.env_marginal, h, u1);
    let (r0, r1) = (
        sc.dist[(sc.env_marginal + row) as usize],
        sc.dist[(sc.env_marginal + row + 1) as usize],
    );
    let fy = if r1 > r0 {
        ((u1 - r0) / (r1 - r0)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let base = sc.env_conditional + row * (w + 1);
    let col = sample_cdf(&sc.dist, base, w, u2);
    let (c0, c1) = (
        sc.dist[(base + col) as usize],
        sc.dist[(base + col + 1) as usize],
    );
    let fx = if c1 > c0 {
        ((u2 - c0) / (c1 - c0)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let (uu, vv) = ((col as f32 + fx) / w as f32, (row as f32 + fy) / h as f32);
    let d = equirect_to_direction(uu, vv);
    let e = sc.env[(row * w + col) as usize];
    let sin_theta = (vv * PI).sin();
    let pdf = if sin_theta > 0.0 {
        e[3] / (2.0 * PI * PI * sin_theta)
    } else {
        0.0
    };
    (d, v3(e), pdf)
}

/// One path through `pixel` as its sample number `sample`: the radiance estimate (finite; a
/// non-finite estimate is returned as black).
#[must_use]
pub fn trace_sample(sc: &PackedScene, s: &TraceSettings, pixel: u32, sample: u32) -> Vec3 {
    trace_counted(sc, s, pixel, sample).0
}

/// [`trace_sample`] and the number of rays it traced (closest-hit and shadow rays).
#[must_use]
pub fn trace_counted(sc: &PackedScene, s: &TraceSettings, pixel: u32, sample: u32) -> (Vec3, u32) {
    let (x, y) = (pixel % s.width, pixel / s.width);
    let r0 = rand4(pixel, sample, s.seed, 0);
    let (o, d) = s
        .camera
        .ray(x as f32 + r0[0], y as f32 + r0[1], s.width, s.height);
    trace(sc, s, pixel, sample, o, d)
}

/// [`trace_counted`] with `wall`'s primary ray when given (DESIGN.md §11); `None` for a pixel
/// the wall camera's display does not show (nothing traced).
#[must_use]
pub fn trace_counted_with(
    sc: &PackedScene,
    s: &TraceSettings,
    wall: Option<&WallCamera>,
    pixel: u32,
    sample: u32,
) -> Option<(Vec3, u32)> {
    let Some(wall) = wall else {
        return Some(trace_counted(sc, s, pixel, sample));
    };
    let (x, y) = (pixel % s.width, pixel / s.width);
    let tile = wall.tile_of(x, y)?;
    let r0 = rand4(pixel, sample, s.seed, 0);
    let (o, d) = wall.ray(tile, x, y, r0[0], r0[1]);
    Some(trace(sc, s, pixel, sample, o, d))
}

/// One sample for each of `pixels`, pixel `pixels[i]` with sample index `counts[i]`: its RGB
/// and the rays it took, in list order, on all cores — a cluster rank's samples (DESIGN.md
/// §12), which go to the owners of their tiles instead of into an accumulation here. A pixel
/// `wall` does not show gives black and no rays. The CPU twin of the trace kernel's compact
/// mode ([`crate::trace::gpu::SampleRun`]).
#[must_use]
pub fn samples_cpu(
    sc: &PackedScene,
    s: &TraceSettings,
    wall: Option<&WallCamera>,
    pixels: &[u32],
    counts: &[u32],
) -> Vec<(Vec3, u32)> {
    assert_eq!(pixels.len(), counts.len(), "a sample index for each pixel");
    traced(sc, s, wall, pixels, counts)
        .into_iter()
        .map(|r| r.unwrap_or((Vec3::ZERO, 0)))
        .collect()
}

/// [`trace_counted_with`] for each of `pixels` with sample index `counts[i]`, on all cores in
/// batches of paths (`batch.rs`), in list order.
fn traced(
    sc: &PackedScene,
    s: &TraceSettings,
    wall: Option<&WallCamera>,
    pixels: &[u32],
    counts: &[u32],
) -> Vec<Option<(Vec3, u32)>> {
    // Pixels per task: a batch, or less where that leaves fewer than four tasks a core (a
    // short list still spreads over the cores; every path's result is the same in any batch).
    let task = pixels
        .len()
        .div_ceil(4 * rayon::current_num_threads())
        .clamp(256, batch::BATCH);
    let mut out = vec![None; pixels.len()];
    out.par_chunks_mut(task)
        .zip(pixels.par_chunks(task).zip(counts.par_chunks(task)))
        .for_each(|(out, (pixels, counts))| batch::trace_batch(sc, s, wall, pixels, counts, out));
    out
}

/// [`trace_path`] in the instantiation the scene needs: the plain one where
/// [`PackedScene::plain`] holds (the same function, its other branches compiled out).
#[inline]
fn trace(
    sc: &PackedScene,
    s: &TraceSettings,
    pixel: u32,
    sample: u32,
    o: Vec3,
    d: Vec3,
) -> (Vec3, u32) {
    if sc.plain {
        trace_path::<false>(sc, s, pixel, sample, o, d)
    } else {
        trace_path::<true>(sc, s, pixel, sample, o, d)
    }
}

/// The path from primary ray `(o, d)` of `pixel`'s sample `sample`: radiance and rays traced.
/// `FULL`: the scene may use every material feature; `false` only for a
/// [`PackedScene::plain`] scene, where the alpha tests, normal and metallic-roughness maps,
/// extension BSDFs, absorbing media and punctual lights it lacks are not even tested for.
// Long: the CPU twin of path.wgsl's path loop, kept step for step in the kernel's order so that
// the two stay bit-identical and can be read side by side.
fn trace_path<const FULL: bool>(
    sc: &PackedScene,
    s: &TraceSettings,
    pixel: u32,
    sample: u32,
    mut o: Vec3,
    mut d: Vec3,
) -> (Vec3, u32) {
    let mut rays = 0u32;
    let mut throughput = Vec3::ONE;
    let mut radiance = Vec3::ZERO;
    // The BSDF density of the direction just taken; 0 for the camera ray (no MIS).
    let mut prev_pdf = 0.0f32;
    let bvh = &sc.bvh;
    let alpha_scene = FULL && sc.features & FEAT_ALPHA != 0;
    // Probability that next-event estimation picks an emissive triangle.
    let tri_select = 1.0 - sc.env_select - sc.punct_select;
    for depth in 0..s.max_depth {
        rays += 1;
        let seed = if alpha_scene {
            ray_seed(pixel, sample, s.seed, depth, 0)
        } else {
            0
        };
        let hit = if FULL {
            bvh.closest_hit_filtered(o, d, f32::INFINITY, |tri, u, v| {
                alpha_covered(sc, tri, u, v, seed)
            })
        } else {
            bvh.closest_hit(o, d, f32::INFINITY)
        };
        let Some(hit) = hit else {
            let (le, pdf_env) = env_eval(sc, d);
            let w = if prev_pdf == 0.0 {
                1.0
            } else {
                mis(prev_pdf, sc.env_select * pdf_env)
            };
            radiance += throughput * le * w;
            break;
        };
        let prim = bvh.hit_prim(hit.prim);
        let (v0, e1, e2) = (v3(prim[0]), v3(prim[1]), v3(prim[2]));
        let light_density = prim[1][3];
        let mut ng = e1.cross(e2).normalize();
        let p = v0 + e1 * hit.u + e2 * hit.v;
        let ti = 4 * hit.triangle as usize;
        let sh = &sc.shade[ti..ti + 4];
        let b0 = 1.0 - hit.u - hit.v;
        let sp = SurfacePoint {
            tri: hit.triangle,
            u: hit.u,
            v: hit.v,
        };
        let mut ns = (v3(sh[0]) * b0 + v3(sh[1]) * hit.u + v3(sh[2]) * hit.v).normalize();
        if !ns.is_finite() {
            ns = ng;
        }
        let mb = MATERIAL_STRIDE * sh[3][3].to_bits() as usize;
        let (m1, m2) = (sc.materials[mb + 1], sc.materials[mb + 2]);
        let flags = m1[3] as u32;
        let wo = -d;
        let cos_hit = ng.dot(d).abs();
        let front = ng.dot(wo) >= 0.0;
        if !front {
            ng = -ng;
            if FULL && flags & MAT_VOLUME != 0 {
                throughput *= absorbed(sc, mb, hit.t);
            }
        }
        let ns_interpolated = ns;
        if FULL && flags & MAT_NORMAL_TEX != 0 {
            ns = normal_mapped(sc, mb, sp, ns);
        }
        if ns.dot(ng) < 0.0 {
            ns = -ns;
        }
        let emission = emission_at(sc, mb, flags, sp);
        if emission != Vec3::ZERO {
            let w = if prev_pdf == 0.0 {
                1.0
            } else {
                let pdf_light = tri_select * light_density * hit.t * hit.t / cos_hit;
                mis(prev_pdf, pdf_light)
            };
            radiance += throughput * emission * w;
        }
        let base = base_color(sc, mb, flags, sp);
        let (mut metallic, mut alpha) = (m2[0], m2[1]);
        if FULL && flags & MAT_MR_TEX != 0 {
            let mr = slot(sc, mb, 1, sp);
            alpha = (alpha * mr.y * mr.y).max(MIN_ALPHA);
            metallic *= mr.z;
        }
        let bsdf = Bsdf {
            base: base.truncate(),
            metallic,
            alpha,
            specular: m2[2],
        };
        let r2 = rand4(pixel, sample, s.seed, 2 + 2 * depth);
        // A dispersive surface: the path follows one channel from here on (after this
        // vertex's emission, before its light sample and BSDF, which refract by it).
        let mut channel = ALL_CHANNELS;
        if FULL && flags & MAT_DISPERSION != 0 {
            (channel, throughput) = pick_channel(throughput, r2[3]);
        }
        let surface = ExtSurface {
            front,
            sp,
            ns: ns_interpolated,
            ng,
        };
        let ext = (FULL && flags & MAT_EXT_BSDF != 0)
            .then(|| ext_bsdf(sc, mb, flags, bsdf, surface, channel));
        let transmits = ext.is_some_and(|e| e.transmits());
        // The core BSDF's lobe probability, shared by its two evaluations and its sample.
        let ps = if ext.is_none() {
            bsdf.specular_probability(ns.dot(wo))
        } else {
            0.0
        };
        let eval = |wi: Vec3| {
            if let Some(e) = &ext {
                e.eval(ns, wo, wi)
            } else {
                bsdf.eval_with(ps, ns, wo, wi)
            }
        };
        let r1 = rand4(pixel, sample, s.seed, 1 + 2 * depth);
        let po = offset_ray(p, ng);

        // Next-event estimation: the environment, a punctual light or one emissive triangle.
        if sc.env_select > 0.0 || sc.light_count > 0 || (FULL && sc.punctual_count > 0) {
            // (direction, radiance × falloff, pdf, shadow ray length, a delta light)
            let (wi, le, pdf_l, tmax, delta) = if r1[0] < sc.env_select {
                let (wi, le, pdf) = sample_env(sc, r1[1], r1[2]);
                (wi, le, sc.env_select * pdf, f32::INFINITY, false)
            } else if FULL && r1[0] < sc.env_select + sc.punct_select {
                sample_punctual(sc, po, r1[0])
            } else {
                let u = ((r1[0] - sc.env_select - sc.punct_select) / tri_select).min(0.99999994);
                let k = sample_cdf(&sc.dist, 0, sc.light_count, u);
                let l = 3 * k as usize;
                let (lv0, le1, le2) =
                    (v3(sc.lights[l]), v3(sc.lights[l + 1]), v3(sc.lights[l + 2]));
                let (mut a, mut b) = (r1[1], r1[2]);
                if a + b > 1.0 {
                    a = 1.0 - a;
                    b = 1.0 - b;
                }
                let q = lv0 + le1 * a + le2 * b;
                let to = q - po;
                let dist2 = to.length_squared();
                let dist = dist2.sqrt();
                let wi = to / dist;
                let n_l = le1.cross(le2);
                let area2 = n_l.length();
                // A single-sided light emits from its front (towards n_l) only: seen from
                // behind it contributes nothing, and the sample is discarded (pdf 0).
                let facing = -n_l.dot(wi) / area2;
                let cos_l = if sc.lights[l + 1][3] != 0.0 {
                    facing.abs()
                } else {
                    facing.max(0.0)
                };
                let tri = sc.lights[l][3].to_bits();
                let lmb = material_base(sc, tri);
                let lflags = sc.materials[lmb + 1][3] as u32;
                let lsp = SurfacePoint { tri, u: a, v: b };
                let mut le = emission_at(sc, lmb, lflags, lsp);
                // A cut-out emitter emits only where it is there (BSDF rays see the same).
                if FULL && lflags & MAT_MASK != 0 {
                    let a = base_color(sc, lmb, lflags, lsp).w;
                    if a < sc.materials[lmb + 2][3] {
                        le = Vec3::ZERO;
                    }
                } else if FULL && lflags & MAT_BLEND != 0 {
                    le *= base_color(sc, lmb, lflags, lsp).w;
                }
                let density = sc.dist[k as usize + 1] - sc.dist[k as usize];
                let pdf = if cos_l > 0.0 {
                    tri_select * density / (0.5 * area2) * dist2 / cos_l
                } else {
                    0.0
                };
                (wi, le, pdf, dist * (1.0 - 1e-4), false)
            };
            let side = wi.dot(ng);
            if pdf_l > 0.0 && pdf_l.is_finite() && (side > 0.0 || (transmits && side < 0.0)) {
                let (f, pdf_b) = eval(wi);
                // At the last vertex no BSDF ray follows to find this light, so its sample
                // carries the whole estimate: MIS against a strategy that is never taken
                // would drop that strategy's share. A delta light cannot be hit at all.
                let w = if delta || depth + 1 == s.max_depth {
                    1.0
                } else {
                    mis(pdf_l, pdf_b)
                };
                let contrib = throughput * f * le * (ns.dot(wi).abs() / pdf_l) * w;
                if contrib != Vec3::ZERO {
                    rays += 1;
                    let from = if side > 0.0 { po } else { offset_ray(p, -ng) };
                    let shadow_seed = if alpha_scene {
                        ray_seed(pixel, sample, s.seed, depth, 1)
                    } else {
                        0
                    };
                    let blocked = if FULL {
                        bvh.occluded_filtered(from, wi, tmax, |tri, u, v| {
                            alpha_covered(sc, tri, u, v, shadow_seed)
                        })
                    } else {
                        bvh.occluded(from, wi, tmax)
                    };
                    if !blocked {
                        radiance += contrib;
                    }
                }
            }
        }

        // Continue the path by sampling the BSDF.
        let wi = match &ext {
            Some(e) => e.sample(ns, wo, r1[3], r2[0], r2[1]),
            None => bsdf.sample_with(ps, ns, wo, r1[3], r2[0], r2[1]),
        };
        let side = wi.dot(ng);
        // Below the surface only through a transmitting one, and on the same side of the
        // shading normal as of the geometric one (no light leaks).
        if !(side > 0.0 || (transmits && side < 0.0 && ns.dot(wi) < 0.0)) {
            break;
        }
        let (f, pdf) = eval(wi);
        if !(pdf > 0.0) {
            break;
        }
        throughput *= f * (ns.dot(wi).abs() / pdf);
        prev_pdf = pdf;
        if depth >= 3 {
            let q = throughput.max_element().min(0.95);
            if r2[2] >= q {
                break;
            }
            throughput /= q;
        }
        o = if side > 0.0 { po } else { offset_ray(p, -ng) };
        d = wi;
    }
    let radiance = if radiance.is_finite() {
        radiance
    } else {
        Vec3::ZERO
    };
    (radiance, rays)
}

/// One iteration: one sample for each pixel of `list` (every pixel when `None`), accumulated.
/// Returns the number of rays traced.
pub fn render_cpu(
    sc: &PackedScene,
    s: &TraceSettings,
    accum: &mut Accumulation,
    list: Option<&[u32]>,
) -> u64 {
    render_cpu_with(sc, s, None, accum, list)
}

/// [`render_cpu`] through `wall`'s primary rays when given: pixels its display does not show
/// are skipped (no sample, no count), in the list or not.
pub fn render_cpu_with(
    sc: &PackedScene,
    s: &TraceSettings,
    wall: Option<&WallCamera>,
    accum: &mut Accumulation,
    list: Option<&[u32]>,
) -> u64 {
    match list {
        None => {
            // Bands of whole rows, as many as fill a batch: its paths' rays, grouped by
            // direction octant past the camera, then fill their packets
            // (BENCHMARKS.md, *CPU shading and batches*).
            let band = s.width as usize * (batch::BATCH / s.width as usize).max(1);
            accum
                .sum
                .par_chunks_mut(band)
                .zip(accum.count.par_chunks_mut(band))
                .enumerate()
                .map(|(b, (sums, counts))| {
                    let first = b * band;
                    let pixels: Vec<u32> = (first..first + sums.len()).map(|p| p as u32).collect();
                    let mut out = vec![None; sums.len()];
                    batch::trace_batch(sc, s, wall, &pixels, counts, &mut out);
                    let mut rays = 0u64;
                    for (x, out) in out.into_iter().enumerate() {
                        if let Some((rgb, r)) = out {
                            accumulate(&mut sums[x], &mut counts[x], rgb);
                            rays += u64::from(r);
                        }
                    }
                    rays
                })
                .sum()
        }
        Some(list) => {
            let counts: Vec<u32> = list.iter().map(|&p| accum.count[p as usize]).collect();
            let samples = traced(sc, s, wall, list, &counts);
            let mut rays = 0u64;
            for (&p, (rgb, r)) in list.iter().zip(samples).filter_map(|(p, s)| Some((p, s?))) {
                let i = p as usize;
                accumulate(&mut accum.sum[i], &mut accum.count[i], rgb);
                rays += u64::from(r);
            }
            rays
        }
    }
}

#[cfg(test)]
mod tests;
