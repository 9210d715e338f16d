//! Sampling and shading functions of the integrator, the CPU twin of
//! `shaders/trace/shading.wgsl` (same formulas, same order of operations, f32).
//!
//! The BSDF is glTF 2.0's metallic-roughness model (the specification's Appendix B, with
//! KHR_materials_specular's scalar factor s): a Lambertian diffuse lobe weighted by
//! (1 − F_d)(1 − metallic) and a GGX specular lobe with the height-correlated Smith visibility,
//! weighted by F = mix(F_d, F_m, metallic), where F_d = 0.04·s + (s − 0.04·s)(1 − v·h)⁵ is the
//! dielectric and F_m = base + (1 − base)(1 − v·h)⁵ the conductor Fresnel (Schlick). With
//! s = 0 and metallic = 0 the BSDF is exactly Lambertian (the furnace tests use that).
//! Sampling picks the specular lobe with a probability from the Fresnel-weighted lobe albedos,
//! then samples GGX normals (D·cos θh) or the cosine-weighted hemisphere; the returned pdf is
//! the mixture's, as multiple importance sampling needs.
//!
//! Materials with glTF's extensions ([`BsdfExt`], only where a material's flag says so) add:
//! KHR_materials_specular's colour (F0 = min(((ior − 1)/(ior + 1))² · colour, 1) · s, F90 = s),
//! KHR_materials_ior, KHR_materials_transmission as a rough dielectric interface (Walter et al.
//! 2007: GGX refraction with separable Smith masking, the relative index η from the side the
//! ray arrives on, Schlick's Fresnel taken on the rarer side so that total internal reflection
//! is exact; tinted by the base colour; radiance is not scaled by η², which cancels for light
//! that enters and leaves a closed object), and KHR_materials_clearcoat as a GGX layer over
//! everything, weighted by cc · F_c(n·v) with F_c Schlick at F0 = 0.04 (the specification's
//! `fresnel_coat`), and KHR_materials_sheen beneath the coat: the specification's Charlie
//! sheen (Conty Estevez and Kulla 2017: the exponentiated-sine distribution at α = r², their
//! fitted visibility) over the base scaled by its albedo-scaling term min(1 − max(sheen)·E(v),
//! 1 − max(sheen)·E(l)), E the sheen's directional albedo ([`SHEEN_ALBEDO`]); the base's
//! transmission by 1 − max(sheen)·E(v); and KHR_materials_anisotropy: the specular and
//! transmission lobes' GGX anisotropic (Heitz 2014: α_t = mix(α, 1, strength²) along the
//! brushing direction, α across it; the height-correlated visibility for reflection, separable
//! Smith for refraction; half vectors sampled by D·cos θh through the slopes), and
//! KHR_materials_dispersion: a dispersive material's index of refraction per colour channel
//! ([`dispersed_ior`]); the integrator makes a path that meets one follow a single channel
//! ([`pick_channel`]) and builds the BSDF with that channel's index; and
//! KHR_materials_diffuse_transmission: a share dt of the diffuse base goes Lambertian to the
//! far side, tinted by its colour (the specification's mix of diffuse BRDF and BTDF, under the
//! same Fresnel weight — taken at the view for the transmitted part, as its lobe's
//! probability is — and beneath specular transmission, which takes its place). Lobes:
//! specular reflection, diffuse, transmission, coat, sheen (sampled uniformly over the
//! hemisphere: its peak is at grazing angles), diffuse transmission (cosine-weighted about the
//! far side).

use std::f32::consts::PI;
use std::sync::LazyLock;

use glam::Vec3;

/// An orthonormal basis around `n` (Duff et al., "Building an Orthonormal Basis, Revisited").
#[inline]
#[must_use]
pub fn basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Moves a ray origin off a surface along the geometric normal by a few ULPs (Wächter & Binder,
/// "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6): the
/// offset scales with the coordinates' magnitude, so it works for huge scenes too.
#[inline]
#[must_use]
pub fn offset_ray(p: Vec3, n: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let one = |p: f32, n: f32| {
        let of = (INT_SCALE * n) as i32;
        let pi = f32::from_bits(
            (p.to_bits() as i32).wrapping_add(if p < 0.0 { -of } else { of }) as u32,
        );
        if p.abs() < ORIGIN {
            p + FLOAT_SCALE * n
        } else {
            pi
        }
    };
    Vec3::new(one(p.x, n.x), one(p.y, n.y), one(p.z, n.z))
}

/// sRGB-encoded channel to linear: the scene's decoding (`shading.wgsl` has its WGSL twin).
pub use crate::scene::srgb_to_linear;

/// The coefficients of [`sin_cos_turns`]' polynomials on [−π/4, π/4] (Cephes' `sinf` and
/// `cosf`: within about one unit in the last place there).
pub(crate) const SIN_POLY: [f32; 3] = [-1.666_665_5e-1, 8.332_161e-3, -1.951_529_6e-4];
pub(crate) const COS_POLY: [f32; 3] = [4.166_664_6e-2, -1.388_731_6e-3, 2.443_315_7e-5];

/// (sin 2πv, cos 2πv) for a number of turns `v` in [0, 1) (a uniform random number): the
/// nearest quarter turn is taken off exactly (v and the quarter are multiples of 2⁻²⁴ within
/// 1/8 of each other), the rest is one rounding away from its angle in [−π/4, π/4], where two
/// short polynomials give the sine and cosine, swapped and negated for the quarter. The CPU
/// twin's samplers use it instead of libm's `sinf`/`cosf` so that their eight-path lanes
/// ([`crate::trace::lanes::sin_cos_turns`]) compute the very same bits with the same
/// operations; the WGSL keeps the GPU's `sin`/`cos` (its own rounding either way).
#[inline]
#[must_use]
pub fn sin_cos_turns(v: f32) -> (f32, f32) {
    let q = (v * 4.0 + 0.5).floor();
    let x = (v - q * 0.25) * (2.0 * PI);
    let z = x * x;
    let s = x + x * z * (SIN_POLY[0] + z * (SIN_POLY[1] + z * SIN_POLY[2]));
    let c = 1.0 - 0.5 * z + z * z * (COS_POLY[0] + z * (COS_POLY[1] + z * COS_POLY[2]));
    let quarter = (q as i32) & 3;
    let (s, c) = if quarter & 1 != 0 { (c, s) } else { (s, c) };
    let sin = if quarter & 2 != 0 { -s } else { s };
    let cos = if quarter == 1 || quarter == 2 { -c } else { c };
    (sin, cos)
}

/// Cosine-weighted direction in the local frame (z up) from two uniform numbers.
#[inline]
#[must_use]
pub fn cosine_hemisphere(u: f32, v: f32) -> Vec3 {
    let r = u.sqrt();
    let (sin, cos) = sin_cos_turns(v);
    Vec3::new(r * cos, r * sin, (1.0 - u).max(0.0).sqrt())
}

/// Uniform direction on the sphere.
#[inline]
#[must_use]
pub fn uniform_sphere(u: f32, v: f32) -> Vec3 {
    let z = 1.0 - 2.0 * u;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (sin, cos) = sin_cos_turns(v);
    Vec3::new(r * cos, r * sin, z)
}

/// Equirectangular direction → (u, v) in the unit square (see `scene::EnvironmentMap`).
#[inline]
#[must_use]
pub fn direction_to_equirect(d: Vec3) -> (f32, f32) {
    let u = 0.5 + d.x.atan2(-d.z) * (0.5 / PI);
    let v = d.y.clamp(-1.0, 1.0).acos() * (1.0 / PI);
    (u, v)
}

/// (u, v) in the unit square → direction; the inverse of [`direction_to_equirect`].
#[inline]
#[must_use]
pub fn equirect_to_direction(u: f32, v: f32) -> Vec3 {
    let phi = (u - 0.5) * 2.0 * PI;
    let theta = v * PI;
    let s = theta.sin();
    Vec3::new(s * phi.sin(), theta.cos(), -s * phi.cos())
}

/// A surface point's material, ready for shading.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    pub base: Vec3,
    pub metallic: f32,
    pub alpha: f32,
    /// KHR_materials_specular's factor (1 by default).
    pub specular: f32,
}

/// A surface point's material with glTF's BSDF extensions (see the module doc).
#[derive(Clone, Copy, Debug)]
pub struct BsdfExt {
    pub core: Bsdf,
    /// KHR_materials_specular's colour.
    pub specular_color: Vec3,
    /// ((ior − 1)/(ior + 1))².
    pub f0: f32,
    /// Relative index of refraction η_t / η_i for a ray leaving towards the far side (ior when
    /// the surface is hit from its front, 1/ior from its back).
    pub eta: f32,
    pub transmission: f32,
    pub clearcoat: f32,
    pub clearcoat_alpha: f32,
    /// The coat's own shading normal, on the viewer's side: the interpolated normal, or its
    /// own normal map's (KHR_materials_clearcoat: the base's normal map does not bend the
    /// coat). The base's normal where neither differs.
    pub coat_normal: Vec3,
    /// KHR_materials_sheen's colour (zero: no sheen) and perceptual roughness r (at least
    /// [`SHEEN_MIN_ROUGHNESS`]).
    pub sheen: Vec3,
    pub sheen_roughness: f32,
    /// KHR_materials_anisotropy: the direction (in the surface, world space; zero: isotropic)
    /// along which the specular and transmission lobes' roughness is `alpha_t`, `core.alpha`
    /// across it.
    pub aniso_dir: Vec3,
    pub alpha_t: f32,
    /// KHR_materials_diffuse_transmission: the share of the diffuse base that is transmitted
    /// (Lambertian, to the other side) instead of reflected, and its colour.
    pub diffuse_transmission: f32,
    pub diffuse_transmission_color: Vec3,
}

/// The anisotropic frame about `n`: (tangent along `dir`, bitangent, α along, α across), or
/// None where the material is isotropic (or `dir` has no part in the surface).
#[inline]
fn aniso_frame(e: &BsdfExt, n: Vec3) -> Option<(Vec3, Vec3, f32, f32)> {
    if e.aniso_dir == Vec3::ZERO {
        return None;
    }
    let t = e.aniso_dir - n * n.dot(e.aniso_dir);
    if !(t.length_squared() > 1e-12) {
        return None;
    }
    let t = t.normalize();
    Some((t, n.cross(t), e.alpha_t, e.core.alpha))
}

/// Anisotropic GGX (Heitz 2014) in the frame (t, b, n): D at half vector `h`.
fn aniso_d(f: (Vec3, Vec3, f32, f32), n: Vec3, h: Vec3) -> f32 {
    let (t, b, at, ab) = f;
    let (x, y, z) = (t.dot(h) / at, b.dot(h) / ab, n.dot(h));
    let d = x * x + y * y + z * z;
    1.0 / (PI * at * ab * d * d)
}

/// |(α_t x, α_b y, z)| of direction `w` in the frame: the anisotropic Smith Λ's root.
fn aniso_root(f: (Vec3, Vec3, f32, f32), n: Vec3, w: Vec3) -> f32 {
    let (t, b, at, ab) = f;
    let (x, y, z) = (at * t.dot(w), ab * b.dot(w), n.dot(w));
    (x * x + y * y + z * z).sqrt()
}

/// The height-correlated visibility G₂ / (4 cos_i cos_o), anisotropic.
fn aniso_vis(f: (Vec3, Vec3, f32, f32), n: Vec3, wi: Vec3, wo: Vec3) -> f32 {
    let (ci, co) = (n.dot(wi), n.dot(wo));
    0.5 / (co * aniso_root(f, n, wi) + ci * aniso_root(f, n, wo))
}

/// Smith G₁ of direction `w` (either side), anisotropic.
fn aniso_g1(f: (Vec3, Vec3, f32, f32), n: Vec3, w: Vec3) -> f32 {
    let c = n.dot(w).abs();
    2.0 * c / (c + aniso_root(f, n, w))
}

/// A half vector with density D·(n·h), anisotropic: the slopes (α_t r cos φ, α_b r sin φ),
/// r² = u / (1 − u), scaled by √(1 − u).
fn aniso_half(f: (Vec3, Vec3, f32, f32), n: Vec3, u: f32, v: f32) -> Vec3 {
    let (t, b, at, ab) = f;
    let s = u.sqrt();
    let (sin, cos) = sin_cos_turns(v);
    (t * (at * s * cos) + b * (ab * s * sin) + n * (1.0 - u).max(0.0).sqrt()).normalize()
}

/// The sheen's perceptual roughness never goes below this: Charlie's distribution sharpens
/// without bound towards r = 0 (α = r² = 0.0049 here, a peak about 4° wide at grazing).
pub const SHEEN_MIN_ROUGHNESS: f32 = 0.07;

/// Columns (cos θ from 0 to 1) and rows (r from [`SHEEN_MIN_ROUGHNESS`] to 1) of
/// [`SHEEN_ALBEDO`].
pub const SHEEN_COLUMNS: usize = 64;
pub const SHEEN_ROWS: usize = 32;

/// The Charlie sheen's directional albedo E(cos θ, r) = ∫ f_sheen cos θᵢ dωᵢ at sheen colour 1,
/// for cos θ = i/63 (column i) and perceptual roughness r from [`SHEEN_MIN_ROUGHNESS`] (row 0)
/// to 1 (row 31) in equal steps, at most 1: the same sheen functions integrated in f64 over the
/// half vectors (the specification points to a published table of the same function; this one
/// is computed so that both backends read one set of numbers — the GPU gets a copy after the
/// materials, `trace::pack`). Looked up bilinearly by [`sheen_albedo`]; made on first use, on
/// all cores.
pub static SHEEN_ALBEDO: LazyLock<Vec<f32>> = LazyLock::new(|| {
    use rayon::prelude::*;
    let (columns, rows) = (SHEEN_COLUMNS, SHEEN_ROWS);
    let r_min = f64::from(SHEEN_MIN_ROUGHNESS);
    (0..rows * columns)
        .into_par_iter()
        .map(|k| {
            let (i, j) = (k % columns, k / columns);
            let r = r_min + (1.0 - r_min) * j as f64 / (rows - 1) as f64;
            // At cos θ = 0 the albedo near it (the integrand divides by cos θ). The fitted
            // visibility lets the smoothest sheens reflect more than they receive at the most
            // grazing views (E up to 2.9 at cos θ = 10⁻³, above 1 below cos θ ≈ 0.05 for
            // r ≤ 0.07): E is capped at 1 there, so that the base beneath keeps a share ≥ 0.
            let c = (i as f64 / (columns - 1) as f64).max(1e-3);
            (sheen_albedo_f64(c, r * r) as f32).min(1.0)
        })
        .collect()
});

/// E(cos_o) at α by the midpoint rule over the half vectors h (θ_h 512 steps, φ_h over half
/// the circle, 64 steps, doubled by symmetry): ∫ D(h) G(o, i) (o·h) / cos_o dω_h, i = o
/// reflected about h, over the h whose i is above the surface.
fn sheen_albedo_f64(cos_o: f64, alpha: f64) -> f64 {
    use std::f64::consts::PI;
    let (steps_t, steps_p) = (512, 64);
    let o = [(1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o];
    let (dt, dp) = (0.5 * PI / f64::from(steps_t), PI / f64::from(steps_p));
    // Λ in f32, as the renderers evaluate it (the rest in f64).
    let lambda = |c: f64| f64::from(sheen_lambda(c as f32, alpha as f32));
    let lambda_o = lambda(cos_o);
    let mut sum = 0.0;
    for a in 0..steps_t {
        let th = (f64::from(a) + 0.5) * dt;
        let (st, ct) = th.sin_cos();
        let d = (2.0 + 1.0 / alpha) * (st * st).powf(0.5 / alpha) / (2.0 * PI);
        for b in 0..steps_p {
            let ph = (f64::from(b) + 0.5) * dp;
            let h = [st * ph.cos(), st * ph.sin(), ct];
            let oh = o[0] * h[0] + o[2] * h[2];
            let cos_i = 2.0 * oh * h[2] - o[2];
            if oh <= 0.0 || cos_i <= 0.0 {
                continue;
            }
            let g = 1.0 / (1.0 + lambda_o + lambda(cos_i));
            sum += d * g * oh / cos_o * st;
        }
    }
    2.0 * sum * dt * dp
}

/// The specification's fitted Λ of the Charlie sheen (its `l` and `lambda_sheen`; as
/// `sheen_lambda` in WGSL).
fn sheen_lambda(c: f32, alpha: f32) -> f32 {
    let l = |x: f32| {
        let t = (1.0 - alpha) * (1.0 - alpha);
        let mix = |a: f32, b: f32| a + (b - a) * t;
        let (a, b, cc) = (
            mix(21.5473, 25.3245),
            mix(3.82987, 3.32435),
            mix(0.19823, 0.16801),
        );
        let (d, e) = (mix(-1.97760, -1.27393), mix(-4.32054, -4.85967));
        a / (1.0 + b * x.powf(cc)) + d * x + e
    };
    if c < 0.5 {
        l(c).exp()
    } else {
        (2.0 * l(0.5) - l(1.0 - c)).exp()
    }
}

/// The Charlie sheen BRDF at colour 1: D(n·h) · G / (4 cos_i cos_o), α = r².
fn sheen_brdf(noh: f32, cos_i: f32, cos_o: f32, r: f32) -> f32 {
    let alpha = r * r;
    let inv = 1.0 / alpha;
    let sin2 = (1.0 - noh * noh).max(0.0);
    let d = (2.0 + inv) * sin2.powf(0.5 * inv) / (2.0 * PI);
    let g = 1.0 / (1.0 + sheen_lambda(cos_o, alpha) + sheen_lambda(cos_i, alpha));
    d * g / (4.0 * cos_i * cos_o)
}

/// E(cos θ, r) from `table` ([`SHEEN_ALBEDO`]'s layout), bilinear (as `sheen_albedo` in WGSL).
#[must_use]
pub fn sheen_albedo(table: &[f32], cos: f32, r: f32) -> f32 {
    let (last_x, last_y) = ((SHEEN_COLUMNS - 1) as f32, (SHEEN_ROWS - 1) as f32);
    let x = cos.clamp(0.0, 1.0) * last_x;
    let y = ((r - SHEEN_MIN_ROUGHNESS) / (1.0 - SHEEN_MIN_ROUGHNESS)).clamp(0.0, 1.0) * last_y;
    let (x0, y0) = (x.floor().min(last_x - 1.0), y.floor().min(last_y - 1.0));
    let (fx, fy) = (x - x0, y - y0);
    let k = y0 as usize * SHEEN_COLUMNS + x0 as usize;
    let (a, b) = (table[k], table[k + 1]);
    let (c, d) = (table[k + SHEEN_COLUMNS], table[k + SHEEN_COLUMNS + 1]);
    let top = a + (b - a) * fx;
    let bottom = c + (d - c) * fx;
    top + (bottom - top) * fy
}

/// x⁵ as WGSL's `pow5` computes it.
#[inline]
fn pow5(x: f32) -> f32 {
    let x2 = x * x;
    x2 * x2 * x
}

#[inline]
fn mix3(a: Vec3, b: Vec3, t: f32) -> Vec3 {
    a + (b - a) * t
}

#[inline]
fn lum(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl Bsdf {
    /// (dielectric Fresnel F_d, combined Fresnel F) at cosine `c` between the view and the
    /// half vector.
    fn fresnel(&self, c: f32) -> (f32, Vec3) {
        let k = pow5((1.0 - c).max(0.0));
        let fd = 0.04 * self.specular + (self.specular - 0.04 * self.specular) * k;
        let fm = self.base + (Vec3::ONE - self.base) * k;
        (fd, mix3(Vec3::splat(fd), fm, self.metallic))
    }

    /// Whether this is a pure Lambertian surface (KHR_materials_specular 0, not metallic, a
    /// finite base colour) whose specular lobe probability `ps` is 0 (a base colour that is not
    /// black): then [`Self::eval_with`] skips the GGX terms, which are exactly zero.
    #[inline]
    fn is_lambert(&self, ps: f32) -> bool {
        self.specular == 0.0 && self.metallic == 0.0 && ps == 0.0 && self.base.is_finite()
    }

    /// Probability of sampling the specular lobe when leaving in direction with cosine `cos_o`.
    #[must_use]
    pub fn specular_probability(&self, cos_o: f32) -> f32 {
        let (fd, f) = self.fresnel(cos_o);
        let ws = lum(f);
        let wd = lum(self.base) * (1.0 - self.metallic) * (1.0 - fd);
        if ws + wd > 0.0 { ws / (ws + wd) } else { 0.5 }
    }

    /// BSDF value and sampling pdf (solid angle) for outgoing `wo` and incoming `wi` about the
    /// shading normal `n`; zero below the surface.
    #[must_use]
    pub fn eval(&self, n: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        self.eval_with(self.specular_probability(n.dot(wo)), n, wo, wi)
    }

    /// [`Self::eval`] with the lobe probability `ps = specular_probability(n·wo)` computed by
    /// the caller (once per path vertex: the light sample's and the BSDF sample's evaluation
    /// and the sampling itself share it).
    #[must_use]
    #[inline]
    pub fn eval_with(&self, ps: f32, n: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let cos_o = n.dot(wo);
        let cos_i = n.dot(wi);
        if cos_o <= 0.0 || cos_i <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        if self.is_lambert(ps) {
            // What the general formulas give, to the bit, when s = metallic = 0 (F = F_d = 0,
            // so the specular term is +0) and the specular lobe is never picked (ps = 0): the
            // diffuse lobe base · (1 · 1 / π) and its pdf 0 + (1 · cos_i) / π.
            return (self.base * (1.0 / PI), cos_i / PI);
        }
        let h = (wo + wi).normalize();
        let noh = n.dot(h).max(0.0);
        let voh = wo.dot(h).max(1e-7);
        let (fd, fresnel) = self.fresnel(voh);
        let a2 = self.alpha * self.alpha;
        let dd = noh * noh * (a2 - 1.0) + 1.0;
        let d = a2 / (PI * dd * dd);
        let vis = 0.5
            / (cos_i * (cos_o * cos_o * (1.0 - a2) + a2).sqrt()
                + cos_o * (cos_i * cos_i * (1.0 - a2) + a2).sqrt());
        let spec = fresnel * (d * vis);
        let diff = self.base * ((1.0 - self.metallic) * (1.0 - fd) / PI);
        let pdf = ps * d * noh / (4.0 * voh) + (1.0 - ps) * cos_i / PI;
        (diff + spec, pdf)
    }

    /// Samples an incoming direction: `u_lobe` picks the lobe, `(u, v)` the direction.
    #[must_use]
    pub fn sample(&self, n: Vec3, wo: Vec3, u_lobe: f32, u: f32, v: f32) -> Vec3 {
        self.sample_with(self.specular_probability(n.dot(wo)), n, wo, u_lobe, u, v)
    }

    /// [`Self::sample`] with `ps = specular_probability(n·wo)` from the caller.
    #[must_use]
    #[inline]
    pub fn sample_with(&self, ps: f32, n: Vec3, wo: Vec3, u_lobe: f32, u: f32, v: f32) -> Vec3 {
        let (t, b) = basis(n);
        if u_lobe < ps {
            let a2 = self.alpha * self.alpha;
            let cos_h = ((1.0 - u) / (1.0 + (a2 - 1.0) * u)).max(0.0).sqrt();
            let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
            let (sin, cos) = sin_cos_turns(v);
            let h = t * (sin_h * cos) + b * (sin_h * sin) + n * cos_h;
            2.0 * wo.dot(h) * h - wo
        } else {
            let l = cosine_hemisphere(u, v);
            t * l.x + b * l.y + n * l.z
        }
    }
}

/// GGX D for `noh` and α² `a2`.
#[inline]
fn ggx_d(noh: f32, a2: f32) -> f32 {
    let dd = noh * noh * (a2 - 1.0) + 1.0;
    a2 / (PI * dd * dd)
}

/// Height-correlated Smith visibility V = G / (4 cos_i cos_o).
#[inline]
fn ggx_vis(cos_i: f32, cos_o: f32, a2: f32) -> f32 {
    0.5 / (cos_i * (cos_o * cos_o * (1.0 - a2) + a2).sqrt()
        + cos_o * (cos_i * cos_i * (1.0 - a2) + a2).sqrt())
}

/// Smith G1 for GGX at |cos θ| `c`.
#[inline]
fn ggx_g1(c: f32, a2: f32) -> f32 {
    2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt())
}

/// A GGX microfacet normal (D·cos θh sampling) about the frame `(t, b, n)`.
#[inline]
fn ggx_half(t: Vec3, b: Vec3, n: Vec3, alpha: f32, u: f32, v: f32) -> Vec3 {
    let a2 = alpha * alpha;
    let cos_h = ((1.0 - u) / (1.0 + (a2 - 1.0) * u)).max(0.0).sqrt();
    let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
    let (sin, cos) = sin_cos_turns(v);
    t * (sin_h * cos) + b * (sin_h * sin) + n * cos_h
}

/// KHR_materials_dispersion's wavelength term per channel, (523655/λ² − 1.5168) / 20, at the
/// Fraunhofer lines the Abbe number is defined by: C (656.27 nm) for red, d (587.56 nm) for
/// green and F (486.13 nm) for blue ([`dispersed_ior`]). The same literals as path.wgsl's
/// `DISPERSION_*` (a test compares their bits).
pub const DISPERSION_TERMS: [f32; 3] = [-0.015_047_478_5, 0.000_002_181_195_2, 0.034_952_514];

/// The index of refraction in `channel` (0 red, 1 green, 2 blue) of a material whose ior at
/// the d line is `ior` and whose KHR_materials_dispersion is `dispersion` (20 / its Abbe
/// number V): the extension's two terms of Cauchy's equation,
/// n(λ) = max(n_d + (n_d − 1)/V · (523655/λ² − 1.5168), 1), at most 10 as the loader's ior.
#[inline]
#[must_use]
pub fn dispersed_ior(ior: f32, dispersion: f32, channel: u32) -> f32 {
    let term = DISPERSION_TERMS[channel as usize];
    (ior + (ior - 1.0) * dispersion * term).clamp(1.0, 10.0)
}

/// The colour channel a path follows from a dispersive surface on (0 red, 1 green, 2 blue),
/// chosen with probability proportional to its `throughput` in that channel by `u` ∈ [0, 1),
/// and the throughput from here on: that channel alone, divided by its probability (the sum of
/// the three). Unbiased for each channel wherever it has throughput; a path that already
/// follows one channel (the others zero) keeps it and its throughput exactly, so a path needs
/// no state to stay on its wavelength through later dispersive surfaces, and one that has
/// none in a channel never picks it. A throughput of zero picks red and stays zero.
#[inline]
#[must_use]
pub fn pick_channel(throughput: Vec3, u: f32) -> (u32, Vec3) {
    let t = throughput;
    let sum = t.x + t.y + t.z;
    let x = u * sum;
    let channel = if x < t.x || (t.y == 0.0 && t.z == 0.0) {
        0
    } else if x < t.x + t.y || t.z == 0.0 {
        1
    } else {
        2
    };
    let mut out = Vec3::ZERO;
    out[channel] = sum;
    (channel as u32, out)
}

#[inline]
fn max3(v: Vec3) -> f32 {
    v.x.max(v.y).max(v.z)
}

impl BsdfExt {
    /// Whether light passes through (the path may continue below the surface).
    #[must_use]
    pub fn transmits(&self) -> bool {
        (self.transmission > 0.0 || self.diffuse_transmission > 0.0) && self.core.metallic < 1.0
    }

    /// (dielectric Fresnel F_d, combined F) at microfacet cosine `c` on the view side; with
    /// transmission, Schlick on the rarer side and 1 under total internal reflection.
    fn fresnel(&self, c: f32) -> (Vec3, Vec3) {
        let b = &self.core;
        let f0 = (self.specular_color * self.f0).min(Vec3::ONE);
        let mut cc = c;
        let mut tir = false;
        if self.transmission > 0.0 && self.eta < 1.0 {
            let s2 = (1.0 - c * c) / (self.eta * self.eta);
            tir = s2 >= 1.0;
            cc = (1.0 - s2).max(0.0).sqrt();
        }
        let k = pow5((1.0 - cc).max(0.0));
        let fd = if tir {
            Vec3::ONE
        } else {
            (f0 + (Vec3::ONE - f0) * k) * b.specular
        };
        let km = pow5((1.0 - c).max(0.0));
        let fm = b.base + (Vec3::ONE - b.base) * km;
        (fd, mix3(fd, fm, b.metallic))
    }

    /// The coat's weight cc · F_c(n_c·v); none where the coat's normal faces away from the
    /// view.
    fn coat(&self, cos_oc: f32) -> f32 {
        if self.clearcoat > 0.0 && cos_oc > 0.0 {
            self.clearcoat * (0.04 + 0.96 * pow5((1.0 - cos_oc).max(0.0)))
        } else {
            0.0
        }
    }

    /// The sheen's directional albedo E at `cos` (0 without a sheen).
    fn sheen_e(&self, cos: f32) -> f32 {
        if self.sheen == Vec3::ZERO {
            0.0
        } else {
            sheen_albedo(&SHEEN_ALBEDO, cos, self.sheen_roughness)
        }
    }

    /// Lobe sampling probabilities (specular, diffuse, transmission, coat, sheen, diffuse
    /// transmission) at `cos_o` (the view's cosine to the shading normal) and `cos_oc` (to the
    /// coat's normal). Without a sheen or a diffuse transmission, the same numbers to the bit
    /// as without their terms.
    #[must_use]
    pub fn lobes(&self, cos_o: f32, cos_oc: f32) -> [f32; 6] {
        let b = &self.core;
        let (fd, f) = self.fresnel(cos_o);
        let coat = self.coat(cos_oc);
        let e_o = self.sheen_e(cos_o);
        // The base's share beneath the sheen (its albedo scaling towards the view).
        let under = 1.0 - max3(self.sheen) * e_o;
        let ws = lum(f) * (1.0 - coat) * under;
        let rest = lum(b.base) * (1.0 - b.metallic) * (1.0 - max3(fd)) * (1.0 - coat) * under;
        let dt = self.diffuse_transmission;
        let wd = rest * (1.0 - self.transmission) * (1.0 - dt);
        let wt = rest * self.transmission;
        let wsh = lum(self.sheen) * e_o * (1.0 - coat);
        let wdt = if dt > 0.0 {
            lum(self.diffuse_transmission_color)
                * (1.0 - b.metallic)
                * (1.0 - max3(fd))
                * (1.0 - coat)
                * under
                * (1.0 - self.transmission)
                * dt
        } else {
            0.0
        };
        let total = ws + wd + wt + coat + wsh + wdt;
        if total > 0.0 {
            [
                ws / total,
                wd / total,
                wt / total,
                coat / total,
                wsh / total,
                wdt / total,
            ]
        } else {
            [0.5, 0.5, 0.0, 0.0, 0.0, 0.0]
        }
    }

    /// BSDF value and sampling pdf (solid angle) for `wo`, `wi` about the shading normal `n`
    /// (on `wo`'s side): reflection where `wi` is above, transmission where it is below.
    /// Kept out of line: scenes without glass or coats never call it, and inlined it would
    /// grow the integrator's hot loop (measured: ~8 % slower Cornell box on the CPU).
    #[must_use]
    #[inline(never)]
    pub fn eval(&self, n: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let b = &self.core;
        let cos_o = n.dot(wo);
        let cos_i = n.dot(wi);
        if cos_o <= 0.0 || cos_i == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let cn = self.coat_normal;
        let cos_oc = cn.dot(wo);
        let p = self.lobes(cos_o, cos_oc);
        let coat = self.coat(cos_oc);
        let a2 = b.alpha * b.alpha;
        let aniso = aniso_frame(self, n);
        // The coat's reflection about its own normal, for `wi` above the coat (where the coat's
        // normal is the base's, exactly the base's reflection half vector and cosines).
        let coat_term = |h: Vec3, voh: f32| {
            let cos_ic = cn.dot(wi);
            if coat > 0.0 && cos_ic > 0.0 {
                let c2 = self.clearcoat_alpha * self.clearcoat_alpha;
                let noh = cn.dot(h).max(0.0);
                let dc = ggx_d(noh, c2);
                (
                    coat * dc * ggx_vis(cos_ic, cos_oc, c2),
                    p[3] * dc * noh / (4.0 * voh),
                )
            } else {
                (0.0, 0.0)
            }
        };
        if cos_i > 0.0 {
            let h = (wo + wi).normalize();
            let noh = n.dot(h).max(0.0);
            let voh = wo.dot(h).max(1e-7);
            let (fd, f) = self.fresnel(voh);
            let (d, vis) = match aniso {
                Some(fr) => (aniso_d(fr, n, h), aniso_vis(fr, n, wi, wo)),
                None => (ggx_d(noh, a2), ggx_vis(cos_i, cos_o, a2)),
            };
            let spec = f * (d * vis);
            let diff = b.base
                * ((1.0 - b.metallic)
                    * (1.0 - max3(fd))
                    * (1.0 - self.transmission)
                    * (1.0 - self.diffuse_transmission)
                    / PI);
            let mut value = (spec + diff) * (1.0 - coat);
            let mut pdf = p[0] * d * noh / (4.0 * voh) + p[1] * cos_i / PI;
            if self.sheen != Vec3::ZERO {
                // The sheen over the base, the base scaled by its albedo-scaling term.
                let s = max3(self.sheen);
                let scale = (1.0 - s * self.sheen_e(cos_o)).min(1.0 - s * self.sheen_e(cos_i));
                let sheen = self.sheen * sheen_brdf(noh, cos_i, cos_o, self.sheen_roughness);
                value = (sheen + (spec + diff) * scale) * (1.0 - coat);
                pdf += p[4] * (0.5 / PI);
            }
            if coat > 0.0 {
                let (cv, cp) = coat_term(h, voh);
                value += Vec3::splat(cv);
                pdf += cp;
            }
            return (value, pdf);
        }
        // Below the base's normal: the coat's reflection where its own normal bends it there
        // (its lobe samples such directions), and the base's transmission.
        let (cv, cp) = if coat > 0.0 && cn != n {
            let h = (wo + wi).normalize();
            coat_term(h, wo.dot(h).max(1e-7))
        } else {
            (0.0, 0.0)
        };
        if !self.transmits() {
            return (Vec3::splat(cv), cp);
        }
        // The diffuse transmission: Lambertian through the surface, its share of the base
        // (the Fresnel weight at the view, as its lobe's probability takes it).
        let (mut cv, mut cp) = (Vec3::splat(cv), cp);
        if self.diffuse_transmission > 0.0 {
            let (fd, _) = self.fresnel(cos_o);
            let mut value = self.diffuse_transmission_color
                * ((1.0 - b.metallic)
                    * (1.0 - max3(fd))
                    * (1.0 - self.transmission)
                    * self.diffuse_transmission
                    * (1.0 - coat)
                    / PI);
            if self.sheen != Vec3::ZERO {
                value *= 1.0 - max3(self.sheen) * self.sheen_e(cos_o);
            }
            cv += value;
            cp += p[5] * -cos_i / PI;
        }
        if self.transmission == 0.0 {
            return (cv, cp);
        }
        let eta = self.eta;
        let mut h = -(wo + wi * eta).normalize();
        if n.dot(h) < 0.0 {
            h = -h;
        }
        let (woh, wih) = (wo.dot(h), wi.dot(h));
        let denom = woh + eta * wih;
        if !(woh > 0.0 && wih < 0.0) || denom.abs() < 1e-7 || !h.is_finite() {
            return (cv, cp);
        }
        let noh = n.dot(h);
        let (fd, _) = self.fresnel(woh);
        let (d, g) = match aniso {
            Some(fr) => (aniso_d(fr, n, h), aniso_g1(fr, n, wo) * aniso_g1(fr, n, wi)),
            None => (ggx_d(noh, a2), ggx_g1(cos_o, a2) * ggx_g1(-cos_i, a2)),
        };
        let jac = eta * eta * -wih / (denom * denom);
        let core = woh * d * g * jac / (cos_o * -cos_i);
        let mut value = b.base
            * ((1.0 - b.metallic) * (1.0 - max3(fd)) * self.transmission * core * (1.0 - coat));
        if self.sheen != Vec3::ZERO {
            value *= 1.0 - max3(self.sheen) * self.sheen_e(cos_o);
        }
        if cn != n || self.diffuse_transmission > 0.0 {
            return (value + cv, p[2] * d * noh * jac + cp);
        }
        (value, p[2] * d * noh * jac)
    }

    /// Samples an incoming direction (`u_lobe` picks the lobe); `Vec3::ZERO` where the
    /// transmission lobe meets total internal reflection (no sample: the path ends there,
    /// where that lobe's value is 0 anyway).
    #[must_use]
    #[inline(never)]
    pub fn sample(&self, n: Vec3, wo: Vec3, u_lobe: f32, u: f32, v: f32) -> Vec3 {
        let (t, b) = basis(n);
        let p = self.lobes(n.dot(wo), self.coat_normal.dot(wo));
        let half = |u, v| match aniso_frame(self, n) {
            Some(fr) => aniso_half(fr, n, u, v),
            None => ggx_half(t, b, n, self.core.alpha, u, v),
        };
        if u_lobe < p[0] {
            let h = half(u, v);
            2.0 * wo.dot(h) * h - wo
        } else if u_lobe < p[0] + p[1] {
            let l = cosine_hemisphere(u, v);
            t * l.x + b * l.y + n * l.z
        } else if u_lobe < p[0] + p[1] + p[2] {
            let h = half(u, v);
            let c = wo.dot(h);
            let r = 1.0 / self.eta;
            let k = 1.0 - r * r * (1.0 - c * c);
            if c <= 0.0 || k < 0.0 {
                return Vec3::ZERO;
            }
            -r * wo + (r * c - k.sqrt()) * h
        } else if p[5] > 0.0 && u_lobe >= p[0] + p[1] + p[2] + p[3] + p[4] {
            // The diffuse transmission: cosine-weighted about the other side.
            let l = cosine_hemisphere(u, v);
            -(t * l.x + b * l.y + n * l.z)
        } else if p[4] > 0.0 && u_lobe >= p[0] + p[1] + p[2] + p[3] {
            // The sheen: uniform over the hemisphere (its value peaks at grazing angles).
            let l = uniform_sphere(0.5 * u, v);
            t * l.x + b * l.y + n * l.z
        } else {
            let cn = self.coat_normal;
            let (tc, bc) = if cn == n { (t, b) } else { basis(cn) };
            let h = ggx_half(tc, bc, cn, self.clearcoat_alpha, u, v);
            2.0 * wo.dot(h) * h - wo
        }
    }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod ext_tests;
