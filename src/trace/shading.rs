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

use std::f32::consts::PI;

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

/// sRGB-encoded 8-bit channel to linear.
#[inline]
#[must_use]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Cosine-weighted direction in the local frame (z up) from two uniform numbers.
#[inline]
#[must_use]
pub fn cosine_hemisphere(u: f32, v: f32) -> Vec3 {
    let r = u.sqrt();
    let phi = 2.0 * PI * v;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).max(0.0).sqrt())
}

/// Uniform direction on the sphere.
#[inline]
#[must_use]
pub fn uniform_sphere(u: f32, v: f32) -> Vec3 {
    let z = 1.0 - 2.0 * u;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * v;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
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
        let cos_o = n.dot(wo);
        let cos_i = n.dot(wi);
        if cos_o <= 0.0 || cos_i <= 0.0 {
            return (Vec3::ZERO, 0.0);
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
        let ps = self.specular_probability(cos_o);
        let pdf = ps * d * noh / (4.0 * voh) + (1.0 - ps) * cos_i / PI;
        (diff + spec, pdf)
    }

    /// Samples an incoming direction: `u_lobe` picks the lobe, `(u, v)` the direction.
    #[must_use]
    pub fn sample(&self, n: Vec3, wo: Vec3, u_lobe: f32, u: f32, v: f32) -> Vec3 {
        let (t, b) = basis(n);
        if u_lobe < self.specular_probability(n.dot(wo)) {
            let a2 = self.alpha * self.alpha;
            let cos_h = ((1.0 - u) / (1.0 + (a2 - 1.0) * u)).max(0.0).sqrt();
            let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
            let phi = 2.0 * PI * v;
            let h = t * (sin_h * phi.cos()) + b * (sin_h * phi.sin()) + n * cos_h;
            2.0 * wo.dot(h) * h - wo
        } else {
            let l = cosine_hemisphere(u, v);
            t * l.x + b * l.y + n * l.z
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equirect_round_trips() {
        for &(u, v) in &[(0.1f32, 0.2f32), (0.5, 0.5), (0.9, 0.7), (0.25, 0.95)] {
            let d = equirect_to_direction(u, v);
            let (u2, v2) = direction_to_equirect(d);
            assert!(
                (u - u2).abs() < 1e-5 && (v - v2).abs() < 1e-5,
                "{u},{v} → {u2},{v2}"
            );
        }
        // +Y is the zenith (row 0), −Z the image centre.
        assert!(direction_to_equirect(Vec3::Y).1 < 1e-6);
        let (u, v) = direction_to_equirect(Vec3::NEG_Z);
        assert!((u - 0.5).abs() < 1e-6 && (v - 0.5).abs() < 1e-6);
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [
            Vec3::Z,
            Vec3::NEG_Z,
            Vec3::new(0.3, -0.5, 0.8).normalize(),
            Vec3::X,
        ] {
            let (t, b) = basis(n);
            for (x, y) in [(t, b), (t, n), (b, n)] {
                assert!(x.dot(y).abs() < 1e-6);
            }
            assert!((t.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
        }
    }

    /// Monte Carlo estimates of ∫ f cos / pdf over the sampled directions: the albedo must not
    /// exceed 1 (energy conservation), and the pdf returned by `eval` must integrate to ≤ 1
    /// and reproduce the sampler's density (checked via E[1/pdf · 1] over the hemisphere = 2π
    /// when the sampler covers it).
    #[test]
    fn bsdf_conserves_energy_and_pdf_matches_sampling() {
        let n = Vec3::Z;
        for &(metallic, rough, base) in &[
            (0.0f32, 1.0f32, 0.8f32),
            (1.0, 0.3, 0.9),
            (0.5, 0.5, 1.0),
            (0.0, 0.05, 0.5),
        ] {
            let bsdf = Bsdf {
                base: Vec3::splat(base),
                metallic,
                alpha: (rough * rough).max(1e-3),
                specular: 1.0,
            };
            let wo = Vec3::new(0.4, 0.0, 0.9165).normalize();
            let m = 200_000u32;
            let (mut albedo, mut inv_pdf) = (0.0f64, 0.0f64);
            for i in 0..m {
                let r = crate::random::pcg4d([i, 5, 7, 9]);
                let wi = bsdf.sample(
                    n,
                    wo,
                    crate::random::unit_f32(r[0]),
                    crate::random::unit_f32(r[1]),
                    crate::random::unit_f32(r[2]),
                );
                let (f, pdf) = bsdf.eval(n, wo, wi);
                if pdf > 0.0 {
                    albedo += f64::from(f.x * wi.z / pdf);
                    inv_pdf += f64::from(1.0 / pdf);
                }
            }
            let albedo = albedo / f64::from(m);
            assert!(
                albedo <= 1.01,
                "albedo {albedo} for metallic {metallic}, roughness {rough}"
            );
            // E[1/pdf] over samples = measure of the sampled support ≤ 2π (hemisphere).
            let support = inv_pdf / f64::from(m);
            assert!(
                support <= 2.0 * std::f64::consts::PI * 1.02,
                "support {support}"
            );
            if rough == 1.0 && metallic == 0.0 {
                // Nearly Lambertian: the whole hemisphere is covered.
                assert!(
                    (support - 2.0 * std::f64::consts::PI).abs() < 0.1,
                    "support {support}"
                );
                assert!(albedo > 0.7, "albedo {albedo}");
            }
        }
    }
}
