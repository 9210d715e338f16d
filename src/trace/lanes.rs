//! The shading functions of `shading.rs` (and the random numbers of `random.rs`) for
//! [`LANES`] paths at once: the CPU twin's integrator shades its paths in groups of sixteen
//! lanes (`path.rs`, [`super::path`]'s batches), the way Mitsuba's LLVM backend runs its
//! wavefronts. `wide`'s sixteen-lane types are a pair of AVX2 registers in this build (AVX-512 is
//! not part of the x86-64 target raygun is built for): two independent operations each step,
//! which the cores overlap. Measured on an Intel Xeon against groups of eight (two runs side by
//! side): ms per sample ×0.975–0.977 on the small city, ×0.965–0.981 on the Cornell boxes
//! (BENCHMARKS.md, *CPU shading and batches*).
//!
//! Every function here is its scalar twin step for step: the same IEEE operations in the same
//! order (no FMA in this build; branches become per-lane selects, both sides computed), so that
//! each lane's result is the scalar function's to the bit — which the tests check lane by lane,
//! and the integrator's test checks for whole paths. Where the scalar code takes `max`/`min`
//! with NaN semantics (`f32::max`) so do these (`wide`'s `max`/`min`); where it compares
//! (`if a > b { a } else { b }`), so do these.

use std::f32::consts::PI;

use glam::Vec3;
use wide::f32x8;

use super::shading::{COS_POLY, SIN_POLY};

/// The paths shaded at once, a lane each.
pub const LANES: usize = 16;

/// [`LANES`] lanes of `f32`, of `i32` and of `u32`.
pub type F = wide::f32x16;
pub type I = wide::i32x16;
pub type U = wide::u32x16;

/// `$v`'s operator `$trait` (`$f`) with a right-hand side of type `$rhs`, component by
/// component as glam's `Vec3` operators.
macro_rules! v3_operator {
    ($v:ident, $trait:ident, $f:ident, $rhs:ty, |$a:ident, $b:ident| $x:expr, $y:expr, $z:expr) => {
        impl std::ops::$trait<$rhs> for $v {
            type Output = $v;
            #[inline(always)]
            fn $f(self, $b: $rhs) -> $v {
                let $a = self;
                $v {
                    x: $x,
                    y: $y,
                    z: $z,
                }
            }
        }
    };
}

/// A type of `Vec3`s in lanes, `$n` lanes of `$f`: glam's arithmetic lane by lane (the same
/// operations, so the same bits) and its operators.
macro_rules! vec3_lanes {
    ($(#[$doc:meta])* $v3:ident, $f:ident, $n:expr) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug)]
        pub struct $v3 {
            pub x: $f,
            pub y: $f,
            pub z: $f,
        }

        impl $v3 {
            pub const ZERO: Self = Self {
                x: $f::ZERO,
                y: $f::ZERO,
                z: $f::ZERO,
            };

            #[inline(always)]
            #[must_use]
            pub fn splat(v: Vec3) -> Self {
                Self {
                    x: $f::splat(v.x),
                    y: $f::splat(v.y),
                    z: $f::splat(v.z),
                }
            }

            /// The lanes from a vector each.
            #[inline(always)]
            #[must_use]
            pub fn from_lanes(v: &[Vec3; $n]) -> Self {
                Self {
                    x: $f::from(v.map(|v| v.x)),
                    y: $f::from(v.map(|v| v.y)),
                    z: $f::from(v.map(|v| v.z)),
                }
            }

            /// The vectors, a lane each.
            #[inline(always)]
            #[must_use]
            pub fn lanes(self) -> [Vec3; $n] {
                let (x, y, z) = (self.x.to_array(), self.y.to_array(), self.z.to_array());
                std::array::from_fn(|i| Vec3::new(x[i], y[i], z[i]))
            }

            #[inline(always)]
            #[must_use]
            pub fn dot(self, o: Self) -> $f {
                (self.x * o.x) + (self.y * o.y) + (self.z * o.z)
            }

            #[inline(always)]
            #[must_use]
            pub fn cross(self, o: Self) -> Self {
                Self {
                    x: self.y * o.z - o.y * self.z,
                    y: self.z * o.x - o.z * self.x,
                    z: self.x * o.y - o.x * self.y,
                }
            }

            #[inline(always)]
            #[must_use]
            pub fn length_squared(self) -> $f {
                self.dot(self)
            }

            #[inline(always)]
            #[must_use]
            pub fn length(self) -> $f {
                self.dot(self).sqrt()
            }

            /// glam's `normalize`: times `1 / length`.
            #[inline(always)]
            #[must_use]
            pub fn normalize(self) -> Self {
                self * ($f::ONE / self.length())
            }

            /// The lanes of `a` where `mask` is set, of `b` elsewhere.
            #[inline(always)]
            #[must_use]
            pub fn select(mask: $f, a: Self, b: Self) -> Self {
                Self {
                    x: mask.select(a.x, b.x),
                    y: mask.select(a.y, b.y),
                    z: mask.select(a.z, b.z),
                }
            }

            /// glam's `is_finite`, as a lane mask.
            #[inline(always)]
            #[must_use]
            pub fn is_finite(self) -> $f {
                self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
            }

            /// Lanes where any component is not zero (glam's `v != Vec3::ZERO`; NaN is not zero).
            #[inline(always)]
            #[must_use]
            pub fn nonzero(self) -> $f {
                self.x.simd_ne($f::ZERO) | self.y.simd_ne($f::ZERO) | self.z.simd_ne($f::ZERO)
            }

            /// glam's `max_element`.
            #[inline(always)]
            #[must_use]
            pub fn max_element(self) -> $f {
                // `if a > b { a } else { b }` per lane (glam's `max_element` and the x86 `maxps`).
                let greater = |a: $f, b: $f| a.simd_gt(b).select(a, b);
                greater(greater(self.x, self.y), self.z)
            }
        }

        v3_operator!($v3, Add, add, $v3, |a, b| a.x + b.x, a.y + b.y, a.z + b.z);
        v3_operator!($v3, Sub, sub, $v3, |a, b| a.x - b.x, a.y - b.y, a.z - b.z);
        v3_operator!($v3, Mul, mul, $v3, |a, b| a.x * b.x, a.y * b.y, a.z * b.z);
        v3_operator!($v3, Mul, mul, $f, |a, s| a.x * s, a.y * s, a.z * s);
        v3_operator!($v3, Div, div, $f, |a, s| a.x / s, a.y / s, a.z / s);

        impl std::ops::Neg for $v3 {
            type Output = $v3;
            #[inline(always)]
            fn neg(self) -> $v3 {
                $v3 {
                    x: -self.x,
                    y: -self.y,
                    z: -self.z,
                }
            }
        }
    };
}

vec3_lanes!(
    /// [`LANES`] `Vec3`s, a lane each: the shading's.
    V3,
    F,
    LANES
);

vec3_lanes!(
    /// Eight `Vec3`s, a lane each: the rays of the CPU tree's eight-ray camera packets.
    V3x8,
    f32x8,
    8
);

/// [`super::shading::sin_cos_turns`] in lanes.
#[inline(always)]
#[must_use]
pub fn sin_cos_turns(v: F) -> (F, F) {
    let q = (v * F::splat(4.0) + F::splat(0.5)).floor();
    let x = (v - q * F::splat(0.25)) * F::splat(2.0 * PI);
    let z = x * x;
    let [s0, s1, s2] = SIN_POLY.map(F::splat);
    let [c0, c1, c2] = COS_POLY.map(F::splat);
    let s = x + x * z * (s0 + z * (s1 + z * s2));
    let c = F::ONE - F::splat(0.5) * z + z * z * (c0 + z * (c1 + z * c2));
    let quarter = q.trunc_int() & I::splat(3);
    let bit = |b: i32| -> F { bytemuck::cast((quarter & I::splat(b)).simd_ne(I::ZERO)) };
    let swap = bit(1);
    let (s, c) = (swap.select(c, s), swap.select(s, c));
    let sin = bit(2).select(-s, s);
    let one_or_two: F = bytemuck::cast(quarter.simd_eq(I::splat(1)) | quarter.simd_eq(I::splat(2)));
    let cos = one_or_two.select(-c, c);
    (sin, cos)
}

/// [`super::shading::basis`] in lanes.
#[inline(always)]
#[must_use]
pub fn basis(n: V3) -> (V3, V3) {
    let sign = n.z.simd_ge(F::ZERO).select(F::ONE, F::splat(-1.0));
    let a = F::splat(-1.0) / (sign + n.z);
    let b = n.x * n.y * a;
    (
        V3 {
            x: F::ONE + sign * n.x * n.x * a,
            y: sign * b,
            z: -sign * n.x,
        },
        V3 {
            x: b,
            y: sign + n.y * n.y * a,
            z: -n.y,
        },
    )
}

/// [`super::shading::offset_ray`] in lanes.
#[inline(always)]
#[must_use]
pub fn offset_ray(p: V3, n: V3) -> V3 {
    let one = |p: F, n: F| {
        let of = (F::splat(256.0) * n).trunc_int();
        let of = p.simd_lt(F::ZERO).select(-of, of);
        let bits: I = bytemuck::cast(p);
        let pi: F = bytemuck::cast(bits + of);
        let near = p.abs().simd_lt(F::splat(1.0 / 32.0));
        near.select(p + F::splat(1.0 / 65536.0) * n, pi)
    };
    V3 {
        x: one(p.x, n.x),
        y: one(p.y, n.y),
        z: one(p.z, n.z),
    }
}

/// [`super::shading::cosine_hemisphere`] in lanes.
#[inline(always)]
#[must_use]
pub fn cosine_hemisphere(u: F, v: F) -> V3 {
    let r = u.sqrt();
    let (sin, cos) = sin_cos_turns(v);
    V3 {
        x: r * cos,
        y: r * sin,
        z: (F::ONE - u).max(F::ZERO).sqrt(),
    }
}

/// [`super::shading::uniform_sphere`] in lanes.
#[inline(always)]
#[must_use]
pub fn uniform_sphere(u: F, v: F) -> V3 {
    let z = F::ONE - F::splat(2.0) * u;
    let r = (F::ONE - z * z).max(F::ZERO).sqrt();
    let (sin, cos) = sin_cos_turns(v);
    V3 {
        x: r * cos,
        y: r * sin,
        z,
    }
}

/// [`crate::random::pcg4d`] in lanes.
#[inline(always)]
#[must_use]
pub fn pcg4d(v: [U; 4]) -> [U; 4] {
    let mut v = v.map(|x| x * U::splat(1_664_525) + U::splat(1_013_904_223));
    mix(&mut v);
    for x in &mut v {
        *x ^= *x >> 16;
    }
    mix(&mut v);
    v
}

#[inline(always)]
fn mix(v: &mut [U; 4]) {
    v[0] += v[1] * v[3];
    v[1] += v[2] * v[0];
    v[2] += v[0] * v[1];
    v[3] += v[1] * v[2];
}

/// [`crate::random::unit_f32`] in lanes.
#[inline(always)]
#[must_use]
pub fn unit_f32(x: U) -> F {
    let top: I = bytemuck::cast(x >> 8);
    F::from_i32x16(top) * F::splat(1.0 / 16_777_216.0)
}

/// The power heuristic (β = 2) of `path.rs` in lanes.
#[inline(always)]
#[must_use]
pub fn mis(a: F, b: F) -> F {
    let (a2, b2) = (a * a, b * b);
    (a2 + b2).simd_gt(F::ZERO).select(a2 / (a2 + b2), F::ZERO)
}

/// [`super::shading::Bsdf`] in lanes.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    pub base: V3,
    pub metallic: F,
    pub alpha: F,
    pub specular: F,
}

#[inline(always)]
fn pow5(x: F) -> F {
    let x2 = x * x;
    x2 * x2 * x
}

#[inline(always)]
fn lum(c: V3) -> F {
    F::splat(0.2126) * c.x + F::splat(0.7152) * c.y + F::splat(0.0722) * c.z
}

impl Bsdf {
    #[inline(always)]
    fn fresnel(&self, c: F) -> (F, V3) {
        let k = pow5((F::ONE - c).max(F::ZERO));
        let s = self.specular;
        let fd = F::splat(0.04) * s + (s - F::splat(0.04) * s) * k;
        let fm = self.base + (V3::splat(Vec3::ONE) - self.base) * k;
        let fdv = V3 {
            x: fd,
            y: fd,
            z: fd,
        };
        (fd, fdv + (fm - fdv) * self.metallic)
    }

    /// Lanes that are pure Lambertian with lobe probability `ps` 0 (`is_lambert`).
    #[inline(always)]
    #[must_use]
    pub fn lambert(&self, ps: F) -> F {
        self.specular.simd_eq(F::ZERO)
            & self.metallic.simd_eq(F::ZERO)
            & ps.simd_eq(F::ZERO)
            & self.base.is_finite()
    }

    #[inline(always)]
    #[must_use]
    pub fn specular_probability(&self, cos_o: F) -> F {
        let (fd, f) = self.fresnel(cos_o);
        let ws = lum(f);
        let wd = lum(self.base) * (F::ONE - self.metallic) * (F::ONE - fd);
        (ws + wd)
            .simd_gt(F::ZERO)
            .select(ws / (ws + wd), F::splat(0.5))
    }

    /// `Bsdf::eval_with`; the GGX terms only when some lane needs them.
    #[inline(always)]
    #[must_use]
    pub fn eval_with(&self, ps: F, n: V3, wo: V3, wi: V3) -> (V3, F) {
        let cos_o = n.dot(wo);
        let cos_i = n.dot(wi);
        let below = cos_o.simd_le(F::ZERO) | cos_i.simd_le(F::ZERO);
        let lambert = self.lambert(ps);
        let lambert_value = self.base * F::splat(1.0 / PI);
        let lambert_pdf = cos_i / F::splat(PI);
        let (value, pdf) = if lambert.all() {
            (lambert_value, lambert_pdf)
        } else {
            let h = (wo + wi).normalize();
            let noh = n.dot(h).max(F::ZERO);
            let voh = wo.dot(h).max(F::splat(1e-7));
            let (fd, fresnel) = self.fresnel(voh);
            let a2 = self.alpha * self.alpha;
            let one = F::ONE;
            let dd = noh * noh * (a2 - one) + one;
            let d = a2 / (F::splat(PI) * dd * dd);
            let vis = F::splat(0.5)
                / (cos_i * (cos_o * cos_o * (one - a2) + a2).sqrt()
                    + cos_o * (cos_i * cos_i * (one - a2) + a2).sqrt());
            let spec = fresnel * (d * vis);
            let diff = self.base * ((one - self.metallic) * (one - fd) / F::splat(PI));
            let pdf = ps * d * noh / (F::splat(4.0) * voh) + (one - ps) * cos_i / F::splat(PI);
            (
                V3::select(lambert, lambert_value, diff + spec),
                lambert.select(lambert_pdf, pdf),
            )
        };
        (
            V3::select(below, V3::ZERO, value),
            below.select(F::ZERO, pdf),
        )
    }

    /// `Bsdf::sample_with`; the GGX lobe only when some lane picks it.
    #[inline(always)]
    #[must_use]
    pub fn sample_with(&self, ps: F, n: V3, wo: V3, u_lobe: F, u: F, v: F) -> V3 {
        let (t, b) = basis(n);
        let l = cosine_hemisphere(u, v);
        let diffuse = t * l.x + b * l.y + n * l.z;
        let specular = u_lobe.simd_lt(ps);
        if !specular.any() {
            return diffuse;
        }
        let one = F::ONE;
        let a2 = self.alpha * self.alpha;
        let cos_h = ((one - u) / (one + (a2 - one) * u)).max(F::ZERO).sqrt();
        let sin_h = (one - cos_h * cos_h).max(F::ZERO).sqrt();
        let (sin, cos) = sin_cos_turns(v);
        let h = t * (sin_h * cos) + b * (sin_h * sin) + n * cos_h;
        let reflected = h * (F::splat(2.0) * wo.dot(h)) - wo;
        V3::select(specular, reflected, diffuse)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::{pcg4d as pcg4d_scalar, unit_f32 as unit_scalar};
    use crate::trace::shading;

    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// Uniform numbers and unit vectors, [`LANES`] lanes at a time.
    fn numbers(seed: u32) -> impl FnMut() -> [f32; LANES] {
        let mut k = 0u32;
        move || {
            k += 1;
            std::array::from_fn(|i| unit_scalar(pcg4d_scalar([k, i as u32, seed, 7])[0]))
        }
    }

    fn unit(mut r: impl FnMut() -> [f32; LANES]) -> [Vec3; LANES] {
        let (a, b) = (r(), r());
        std::array::from_fn(|i| shading::uniform_sphere(a[i], b[i]))
    }

    /// Every lane of every function is its scalar twin's result to the bit.
    #[test]
    fn lanes_equal_the_scalar_functions() {
        let mut r = numbers(1);
        for round in 0..2000 {
            let (u, v, w) = (r(), r(), r());
            let (s, c) = sin_cos_turns(F::from(v));
            let (s, c) = (s.to_array(), c.to_array());
            for i in 0..LANES {
                let (ss, cc) = shading::sin_cos_turns(v[i]);
                assert_eq!(
                    (s[i].to_bits(), c[i].to_bits()),
                    (ss.to_bits(), cc.to_bits()),
                    "{}",
                    v[i]
                );
            }
            let n = unit(&mut r);
            let (t, b) = basis(V3::from_lanes(&n));
            let p: [Vec3; LANES] = std::array::from_fn(|i| {
                (Vec3::new(u[i], v[i], w[i]) - 0.5) * if round % 2 == 0 { 0.01 } else { 300.0 }
            });
            let off = offset_ray(V3::from_lanes(&p), V3::from_lanes(&n)).lanes();
            let hemi = cosine_hemisphere(F::from(u), F::from(v)).lanes();
            let sphere = uniform_sphere(F::from(u), F::from(w)).lanes();
            let (t, b) = (t.lanes(), b.lanes());
            for i in 0..LANES {
                let (ts, bs) = shading::basis(n[i]);
                assert_eq!((bits(t[i]), bits(b[i])), (bits(ts), bits(bs)));
                assert_eq!(bits(off[i]), bits(shading::offset_ray(p[i], n[i])));
                assert_eq!(bits(hemi[i]), bits(shading::cosine_hemisphere(u[i], v[i])));
                assert_eq!(bits(sphere[i]), bits(shading::uniform_sphere(u[i], w[i])));
            }
            let keys: [[u32; LANES]; 4] = std::array::from_fn(|k| {
                std::array::from_fn(|i| {
                    (round * LANES as u32 + i as u32).wrapping_mul(2_654_435_761) ^ k as u32
                })
            });
            let lanes = pcg4d(keys.map(U::from)).map(|x| unit_f32(x).to_array());
            for i in 0..LANES {
                let scalar = pcg4d_scalar(std::array::from_fn(|k| keys[k][i])).map(unit_scalar);
                for k in 0..4 {
                    assert_eq!(lanes[k][i].to_bits(), scalar[k].to_bits());
                }
            }
        }
    }

    /// The BSDF's lobe probability, evaluation and sampling per lane equal `Bsdf`'s, over
    /// Lambertian, plastic and metal lanes mixed in one group (and groups of one kind, which
    /// take the shortcuts).
    #[test]
    fn bsdf_lanes_equal_the_scalar_bsdf() {
        let mut r = numbers(2);
        for round in 0..3000 {
            let (m, a, kind) = (r(), r(), r());
            let base = unit(&mut r).map(|v| v.abs());
            let scalar: [shading::Bsdf; LANES] = std::array::from_fn(|i| {
                let k = if round % 3 == 0 {
                    0.1
                } else if round % 3 == 1 {
                    0.9
                } else {
                    kind[i]
                };
                shading::Bsdf {
                    base: base[i],
                    metallic: if k < 0.3 {
                        0.0
                    } else if k < 0.6 {
                        1.0
                    } else {
                        m[i]
                    },
                    alpha: (a[i] * a[i]).max(1e-3),
                    specular: if k < 0.3 { 0.0 } else { 1.0 },
                }
            });
            let lanes = Bsdf {
                base: V3::from_lanes(&scalar.map(|b| b.base)),
                metallic: F::from(scalar.map(|b| b.metallic)),
                alpha: F::from(scalar.map(|b| b.alpha)),
                specular: F::from(scalar.map(|b| b.specular)),
            };
            let (n, wo, wi) = (unit(&mut r), unit(&mut r), unit(&mut r));
            let (nl, wol, wil) = (V3::from_lanes(&n), V3::from_lanes(&wo), V3::from_lanes(&wi));
            let ps = lanes.specular_probability(nl.dot(wol));
            let (f, pdf) = lanes.eval_with(ps, nl, wol, wil);
            let (ul, uu, uv) = (r(), r(), r());
            let sampled = lanes
                .sample_with(ps, nl, wol, F::from(ul), F::from(uu), F::from(uv))
                .lanes();
            let (ps, f, pdf) = (ps.to_array(), f.lanes(), pdf.to_array());
            for i in 0..LANES {
                let b = &scalar[i];
                let pss = b.specular_probability(n[i].dot(wo[i]));
                assert_eq!(ps[i].to_bits(), pss.to_bits());
                let (fs, pdfs) = b.eval_with(pss, n[i], wo[i], wi[i]);
                assert_eq!(
                    (bits(f[i]), pdf[i].to_bits()),
                    (bits(fs), pdfs.to_bits()),
                    "lane {i} {b:?}"
                );
                let ws = b.sample_with(pss, n[i], wo[i], ul[i], uu[i], uv[i]);
                assert_eq!(bits(sampled[i]), bits(ws));
            }
        }
    }
}
