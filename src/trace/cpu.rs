//! The integrator on the CPU: the twin of `shaders/trace/path.wgsl` (same data, same random
//! numbers, same formulas, f32), used as the test oracle and as the fallback backend.
//!
//! One call of [`trace_sample`] is one path: a pinhole primary ray jittered inside the pixel,
//! then at each vertex emission (MIS-weighted against next-event estimation), one light sample
//! (the environment or an emissive triangle, power heuristic), one BSDF sample, and Russian
//! roulette from the fourth vertex on, up to `max_depth` vertices.
//!
//! Random numbers: `pcg4d([pixel, sample, seed, stream::TRACE + dim])` where `sample` is the
//! pixel's sample count before this sample (so a pixel's sequence does not depend on which
//! other pixels were sampled), dimension 0 is the pixel jitter and dimensions 1 + 2·depth and
//! 2 + 2·depth serve the path vertex at `depth`.

use std::f32::consts::PI;

use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;

use super::accum::{Accumulation, accumulate};
use super::camera::RenderCamera;
use super::pack::{NO_TEXTURE, PackedScene};
use super::shading::{
    Bsdf, direction_to_equirect, equirect_to_direction, offset_ray, srgb_to_linear, uniform_sphere,
};
use crate::random::{pcg4d, stream, unit_f32};

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
fn v3(a: [f32; 4]) -> Vec3 {
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

fn texel(sc: &PackedScene, off: u32, w: u32, h: u32, x: i32, y: i32) -> Vec4 {
    let xi = x.rem_euclid(w as i32) as u32;
    let yi = y.rem_euclid(h as i32) as u32;
    let c = sc.texels[(off + yi * w + xi) as usize];
    let ch = |s: u32| ((c >> s) & 0xff) as f32 / 255.0;
    Vec4::new(
        srgb_to_linear(ch(0)),
        srgb_to_linear(ch(8)),
        srgb_to_linear(ch(16)),
        ch(24),
    )
}

/// Bilinear, wrapping texture lookup in linear colour.
fn texture(sc: &PackedScene, tex: u32, uv: Vec2) -> Vec4 {
    let hdr = &sc.texels[4 * tex as usize..4 * tex as usize + 3];
    let (off, w, h) = (hdr[0], hdr[1], hdr[2]);
    let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
    let x = uv.x * w as f32 - 0.5;
    let y = uv.y * h as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (xi, yi) = (x0 as i32, y0 as i32);
    let a = texel(sc, off, w, h, xi, yi);
    let b = texel(sc, off, w, h, xi.wrapping_add(1), yi);
    let c = texel(sc, off, w, h, xi, yi.wrapping_add(1));
    let d = texel(sc, off, w, h, xi.wrapping_add(1), yi.wrapping_add(1));
    (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy
}

/// Environment radiance arriving along `-d` (i.e. seen looking along `d`) and the density
/// (solid angle) with which [`sample_env`] picks `d`.
fn env_eval(sc: &PackedScene, d: Vec3) -> (Vec3, f32) {
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
    let mut rays = 0u32;
    let (x, y) = (pixel % s.width, pixel / s.width);
    let r0 = rand4(pixel, sample, s.seed, 0);
    let mut d = s
        .camera
        .direction(x as f32 + r0[0], y as f32 + r0[1], s.width, s.height);
    let mut o = s.camera.position;
    let mut throughput = Vec3::ONE;
    let mut radiance = Vec3::ZERO;
    // The BSDF density of the direction just taken; 0 for the camera ray (no MIS).
    let mut prev_pdf = 0.0f32;
    let bvh = &sc.bvh;
    for depth in 0..s.max_depth {
        rays += 1;
        let Some(hit) = bvh.closest_hit(o, d, f32::INFINITY) else {
            let (le, pdf_env) = env_eval(sc, d);
            let w = if prev_pdf == 0.0 {
                1.0
            } else {
                mis(prev_pdf, sc.env_select * pdf_env)
            };
            radiance += throughput * le * w;
            break;
        };
        let pi = 3 * hit.prim as usize;
        let (v0, e1, e2) = (
            v3(bvh.prims[pi]),
            v3(bvh.prims[pi + 1]),
            v3(bvh.prims[pi + 2]),
        );
        let light_density = bvh.prims[pi + 1][3];
        let mut ng = e1.cross(e2).normalize();
        let p = v0 + e1 * hit.u + e2 * hit.v;
        let ti = 4 * hit.triangle as usize;
        let sh = &sc.shade[ti..ti + 4];
        let b0 = 1.0 - hit.u - hit.v;
        let mut ns = (v3(sh[0]) * b0 + v3(sh[1]) * hit.u + v3(sh[2]) * hit.v).normalize();
        if !ns.is_finite() {
            ns = ng;
        }
        let uv = Vec2::new(sh[0][3], sh[1][3]) * b0
            + Vec2::new(sh[2][3], sh[3][0]) * hit.u
            + Vec2::new(sh[3][1], sh[3][2]) * hit.v;
        let mi = 3 * sh[3][3].to_bits() as usize;
        let (m0, m1, m2) = (sc.materials[mi], sc.materials[mi + 1], sc.materials[mi + 2]);
        let wo = -d;
        let cos_hit = ng.dot(d).abs();
        if ng.dot(wo) < 0.0 {
            ng = -ng;
        }
        if ns.dot(ng) < 0.0 {
            ns = -ns;
        }
        let emission = v3(m1);
        if emission != Vec3::ZERO {
            let w = if prev_pdf == 0.0 {
                1.0
            } else {
                let pdf_light = (1.0 - sc.env_select) * light_density * hit.t * hit.t / cos_hit;
                mis(prev_pdf, pdf_light)
            };
            radiance += throughput * emission * w;
        }
        let mut base = Vec4::from_array(m0);
        let tex = m1[3].to_bits();
        if tex != NO_TEXTURE {
            base *= texture(sc, tex, uv);
        }
        let bsdf = Bsdf {
            base: base.truncate(),
            metallic: m2[0],
            alpha: m2[1],
            specular: m2[2],
        };
        let r1 = rand4(pixel, sample, s.seed, 1 + 2 * depth);
        let r2 = rand4(pixel, sample, s.seed, 2 + 2 * depth);
        let po = offset_ray(p, ng);

        // Next-event estimation: the environment or one emissive triangle.
        if sc.env_select > 0.0 || sc.light_count > 0 {
            let (wi, le, pdf_l, tmax) = if r1[0] < sc.env_select {
                let (wi, le, pdf) = sample_env(sc, r1[1], r1[2]);
                (wi, le, sc.env_select * pdf, f32::INFINITY)
            } else {
                let u = ((r1[0] - sc.env_select) / (1.0 - sc.env_select)).min(0.99999994);
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
                let tri = sc.lights[l][3].to_bits() as usize;
                let lmi = 3 * sc.shade[4 * tri + 3][3].to_bits() as usize;
                let density = sc.dist[k as usize + 1] - sc.dist[k as usize];
                let pdf = if cos_l > 0.0 {
                    (1.0 - sc.env_select) * density / (0.5 * area2) * dist2 / cos_l
                } else {
                    0.0
                };
                (wi, v3(sc.materials[lmi + 1]), pdf, dist * (1.0 - 1e-4))
            };
            if pdf_l > 0.0 && pdf_l.is_finite() && wi.dot(ng) > 0.0 {
                let (f, pdf_b) = bsdf.eval(ns, wo, wi);
                // At the last vertex no BSDF ray follows to find this light, so its sample
                // carries the whole estimate: MIS against a strategy that is never taken
                // would drop that strategy's share.
                let w = if depth + 1 == s.max_depth {
                    1.0
                } else {
                    mis(pdf_l, pdf_b)
                };
                let contrib = throughput * f * le * (ns.dot(wi) / pdf_l) * w;
                if contrib != Vec3::ZERO {
                    rays += 1;
                    if !bvh.occluded(po, wi, tmax) {
                        radiance += contrib;
                    }
                }
            }
        }

        // Continue the path by sampling the BSDF.
        let wi = bsdf.sample(ns, wo, r1[3], r2[0], r2[1]);
        if wi.dot(ng) <= 0.0 {
            break;
        }
        let (f, pdf) = bsdf.eval(ns, wo, wi);
        if !(pdf > 0.0) {
            break;
        }
        throughput *= f * (ns.dot(wi) / pdf);
        prev_pdf = pdf;
        if depth >= 3 {
            let q = throughput.max_element().min(0.95);
            if r2[2] >= q {
                break;
            }
            throughput /= q;
        }
        o = po;
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
    match list {
        None => {
            let w = s.width as usize;
            accum
                .sum
                .par_chunks_mut(w)
                .zip(accum.count.par_chunks_mut(w))
                .enumerate()
                .map(|(y, (sums, counts))| {
                    let mut rays = 0u64;
                    for x in 0..w {
                        let pixel = (y * w + x) as u32;
                        let (rgb, r) = trace_counted(sc, s, pixel, counts[x]);
                        accumulate(&mut sums[x], &mut counts[x], rgb);
                        rays += u64::from(r);
                    }
                    rays
                })
                .sum()
        }
        Some(list) => {
            let samples: Vec<(Vec3, u32)> = list
                .par_iter()
                .map(|&p| trace_counted(sc, s, p, accum.count[p as usize]))
                .collect();
            let mut rays = 0u64;
            for (&p, (rgb, r)) in list.iter().zip(samples) {
                let i = p as usize;
                accumulate(&mut accum.sum[i], &mut accum.count[i], rgb);
                rays += u64::from(r);
            }
            rays
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Environment, EnvironmentMap, Scene};

    fn map_scene() -> PackedScene {
        // A dim sky with one bright patch (a "sun") near the zenith and a coloured band.
        let (w, h) = (32u32, 16u32);
        let texels = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (x, y) == (5, 3) {
                    Vec3::new(200.0, 180.0, 150.0)
                } else if y == 10 {
                    Vec3::new(0.1, 0.4, 0.9)
                } else {
                    Vec3::splat(0.2)
                }
            })
            .collect();
        PackedScene::new(&Scene {
            environment: Environment::Map(EnvironmentMap {
                name: "test".into(),
                width: w,
                height: h,
                texels,
            }),
            ..Default::default()
        })
    }

    /// The environment sampler's density is the one `env_eval` reports for the sampled
    /// direction, and it integrates to 1 over the sphere (Monte Carlo with uniform directions).
    #[test]
    fn environment_sampling_density_is_consistent_and_normalised() {
        let sc = map_scene();
        for i in 0..2000u32 {
            let r = pcg4d([i, 1, 2, 3]).map(unit_f32);
            let (d, le, pdf) = sample_env(&sc, r[0], r[1]);
            let (le2, pdf2) = env_eval(&sc, d);
            assert!((d.length() - 1.0).abs() < 1e-5);
            if pdf > 0.0 {
                assert!(
                    (pdf - pdf2).abs() <= 2e-3 * pdf,
                    "pdf {pdf} vs {pdf2} at {d}"
                );
                assert_eq!(le, le2);
            }
        }
        let n = 400_000u32;
        let mut integral = 0f64;
        for i in 0..n {
            let r = pcg4d([i, 9, 9, 9]).map(unit_f32);
            let d = uniform_sphere(r[0], r[1]);
            integral += f64::from(env_eval(&sc, d).1) * 4.0 * std::f64::consts::PI;
        }
        let integral = integral / f64::from(n);
        assert!((integral - 1.0).abs() < 0.02, "∫ pdf dω = {integral}");
        // Importance: the sun's texel is chosen far more often than its solid angle share.
        let sun = (0..20_000u32)
            .filter(|&i| {
                let r = pcg4d([i, 4, 4, 4]).map(unit_f32);
                let (d, _, _) = sample_env(&sc, r[0], r[1]);
                let (u, v) = direction_to_equirect(d);
                ((u * 32.0) as u32, (v * 16.0) as u32) == (5, 3)
            })
            .count();
        assert!(sun > 10_000, "the sun was sampled {sun} times of 20 000");
    }
}
