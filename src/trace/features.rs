//! Per-pixel feature buffers for the denoiser (DESIGN.md §8): albedo, shading normal and
//! primary-hit depth, in the layout `crate::filter::denoise` reads (`[r, g, b, 0]` and
//! `[n.x, n.y, n.z, depth]`). This is the CPU definition and the twin of the kernel
//! `shaders/trace/features.wgsl` (dispatch: [`crate::trace::gpu::FeaturesKernel`]).
//!
//! Features are computed once per view (camera or eye), for every pixel, independent of the
//! sampling schedule: a guided frame leaves periphery pixels unsampled for a while, and the
//! denoiser needs their features all the same. They cost a few primary rays a pixel (plus the
//! specular chains those meet), not a path per iteration.
//!
//! # The definition, exactly
//!
//! Pixel `(x, y)` is looked at through the [`FEATURE_POSITIONS`] points
//! `(x + px, y + py)` (a fixed rotated grid: no random numbers, so the same view gives the
//! same features), each through [`RenderCamera::ray`](super::camera::RenderCamera::ray). Along each such ray, for vertex
//! `v = 0, 1, …` up to [`FEATURE_DEPTH`] − 1:
//!
//! * the closest hit, alpha-tested as the integrator does (`alpha_covered` with the coverage
//!   seed `ray_seed(pixel, k, FEATURE_SEED, v, 0)`, `k` the position's index);
//! * **a miss**: at `v = 0` everything is 0 (albedo, normal, depth: the denoiser's miss); after
//!   a specular chain the albedo is the environment's radiance in that direction clamped to
//!   [0, 1] per channel (what the mirror or glass shows), the normal 0;
//! * at `v = 0` the depth is the hit's distance along the (unit) camera ray;
//! * the shading normal: interpolated, normal-mapped where the material has a normal map,
//!   turned to the viewer's side of the geometric normal (as the integrator shades);
//! * the material's α (roughness², × the metallic-roughness texture's G², ≥ `MIN_ALPHA`),
//!   metallic (× its B) and, for an extension BSDF, the transmission (factor × its texture's
//!   R); the vertex is **specular** when α ≤ [`SPECULAR_ALPHA`] and metallic ≥ 0.5 or
//!   transmission ≥ 0.5;
//! * a vertex that is not specular, or the last one allowed, gives the features: albedo = the
//!   base colour (factor × texture × vertex colour) clamped to [0, 1] — an emitter's too (its
//!   emission is not albedo) — and its shading normal;
//! * a specular vertex continues the ray: a metal (metallic ≥ 0.5) reflects it about the
//!   shading normal; otherwise it refracts with η = 1/ior entering (front face), ior leaving,
//!   reflecting at total internal reflection; the new ray starts offset from the surface on
//!   the side it goes to (`offset_ray`).
//!
//! The pixel's features are the means over its positions of albedo and depth (a miss counts
//! depth 0), and the mean normal made unit (0 where the mean is 0).

use glam::Vec3;
use rayon::prelude::*;

use super::bvh::TraceHit;
use super::pack::{MAT_EXT_BSDF, MAT_EXT_TEX, MAT_MR_TEX, MAT_NORMAL_TEX, MIN_ALPHA, NO_TEXTURE};
use super::pack::{MATERIAL_STRIDE, PackedScene};
use super::path::{
    SurfacePoint, TraceSettings, alpha_covered, base_color, env_eval, normal_mapped, ray_seed,
    slot, v3,
};
use super::reuse;
use super::shading::offset_ray;
use super::wall::WallCamera;

/// The points inside a pixel (in pixels from its top-left corner) that its features look
/// through: a 4-point rotated grid.
pub const FEATURE_POSITIONS: [[f32; 2]; 4] = [
    [0.375, 0.125],
    [0.875, 0.375],
    [0.125, 0.625],
    [0.625, 0.875],
];

/// The most surfaces a feature ray meets: the first and up to three specular ones after it.
pub const FEATURE_DEPTH: u32 = 4;

/// A surface with α (roughness²) at most this, and metallic or transmitting, is specular: the
/// features look through it.
pub const SPECULAR_ALPHA: f32 = 0.01;

/// The seed (third word of `ray_seed`) of the feature rays' alpha coverage.
pub const FEATURE_SEED: u32 = 0x4645_4154;

/// The feature buffers of a picture, row-major, one entry per pixel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FeatureBuffers {
    /// `[r, g, b, 0]`: the first non-specular hit's albedo.
    pub albedo: Vec<[f32; 4]>,
    /// `[n.x, n.y, n.z, depth]`: its unit shading normal and the primary hit's depth (0 for
    /// a miss).
    pub normal_depth: Vec<[f32; 4]>,
}

/// WGSL's `refract(i, n, eta)`: 0 at total internal reflection.
#[inline]
fn refract(i: Vec3, n: Vec3, eta: f32) -> Vec3 {
    let c = n.dot(i);
    let k = 1.0 - eta * eta * (1.0 - c * c);
    if k < 0.0 {
        Vec3::ZERO
    } else {
        i * eta - n * (eta * c + k.sqrt())
    }
}

/// What the features and the primary-hit record read where a ray along `d` hits (the
/// module docs' definition): the point, the geometric normal and the shading normal both
/// turned to the ray's side, whether the ray hit the front face, the material (its row in
/// `materials` and flags) and its α, metallic and transmission at that point.
pub(super) struct SurfaceAt {
    pub p: Vec3,
    pub ng: Vec3,
    pub ns: Vec3,
    pub front: bool,
    pub mb: usize,
    pub flags: u32,
    pub sp: SurfacePoint,
    pub alpha: f32,
    pub metallic: f32,
    pub transmission: f32,
}

/// [`SurfaceAt`] of `hit` on a ray along `d` (the twin of `surface_at` in features.wgsl).
pub(super) fn surface_at(sc: &PackedScene, hit: &TraceHit, d: Vec3) -> SurfaceAt {
    let prim = sc.bvh.hit_prim(hit.prim);
    let (v0, e1, e2) = (v3(prim[0]), v3(prim[1]), v3(prim[2]));
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
    let front = ng.dot(d) <= 0.0;
    if !front {
        ng = -ng;
    }
    if flags & MAT_NORMAL_TEX != 0 {
        ns = normal_mapped(sc, mb, sp, ns);
    }
    if ns.dot(ng) < 0.0 {
        ns = -ns;
    }
    let (mut metallic, mut alpha) = (m2[0], m2[1]);
    if flags & MAT_MR_TEX != 0 {
        let mr = slot(sc, mb, 1, sp);
        alpha = (alpha * mr.y * mr.y).max(MIN_ALPHA);
        metallic *= mr.z;
    }
    let mut transmission = 0.0;
    if flags & MAT_EXT_BSDF != 0 {
        transmission = sc.materials[mb + 3][3];
        if flags & MAT_EXT_TEX != 0 && sc.materials[mb + 5 + 2 * 4][3].to_bits() != NO_TEXTURE {
            transmission *= slot(sc, mb, 4, sp).x;
        }
    }
    SurfaceAt {
        p,
        ng,
        ns,
        front,
        mb,
        flags,
        sp,
        alpha,
        metallic,
        transmission,
    }
}

/// One feature ray from `o` along unit `d` (position `k` of `pixel`): albedo, shading normal
/// and depth, as the module docs define them.
fn feature_ray(
    sc: &PackedScene,
    pixel: u32,
    k: u32,
    mut o: Vec3,
    mut d: Vec3,
) -> (Vec3, Vec3, f32) {
    let bvh = &sc.bvh;
    let mut depth = 0.0f32;
    for v in 0..FEATURE_DEPTH {
        let seed = ray_seed(pixel, k, FEATURE_SEED, v, 0);
        let hit = bvh.closest_hit_filtered(o, d, f32::INFINITY, |tri, u, w| {
            alpha_covered(sc, tri, u, w, seed)
        });
        let Some(hit) = hit else {
            if v == 0 {
                return (Vec3::ZERO, Vec3::ZERO, 0.0);
            }
            let le = env_eval(sc, d).0;
            return (le.clamp(Vec3::ZERO, Vec3::ONE), Vec3::ZERO, depth);
        };
        if v == 0 {
            depth = hit.t;
        }
        let SurfaceAt {
            p,
            ng,
            ns,
            front,
            mb,
            flags,
            sp,
            alpha,
            metallic,
            transmission,
        } = surface_at(sc, &hit, d);
        let specular = alpha <= SPECULAR_ALPHA && (metallic >= 0.5 || transmission >= 0.5);
        if !specular || v + 1 == FEATURE_DEPTH {
            let base = base_color(sc, mb, flags, sp).truncate();
            return (base.clamp(Vec3::ZERO, Vec3::ONE), ns, depth);
        }
        let reflected = d - ns * (2.0 * ns.dot(d));
        let mut next = reflected;
        if metallic < 0.5 {
            let ior = sc.materials[mb + 4][0];
            let eta = if front { 1.0 / ior } else { ior };
            let t = refract(d, ns, eta);
            if t != Vec3::ZERO {
                next = t.normalize();
            }
        }
        o = if next.dot(ng) > 0.0 {
            offset_ray(p, ng)
        } else {
            offset_ray(p, -ng)
        };
        d = next;
    }
    // Unreachable: the last vertex returns above (FEATURE_DEPTH ≥ 1).
    (Vec3::ZERO, Vec3::ZERO, depth)
}

/// The features of `pixel` (row-major index in `s.width` × `s.height`) as the module docs
/// define them, through `wall`'s primary ray when given (0 everywhere for a pixel no tile of
/// its display shows): `([r, g, b, 0], [n.x, n.y, n.z, depth])`.
#[must_use]
pub fn pixel_features(
    sc: &PackedScene,
    s: &TraceSettings,
    wall: Option<&WallCamera>,
    pixel: u32,
) -> ([f32; 4], [f32; 4]) {
    let (x, y) = (pixel % s.width, pixel / s.width);
    let tile = match wall {
        Some(wc) => match wc.tile_of(x, y) {
            Some(t) => Some(t),
            // A pixel no tile shows sees nothing: the miss's features.
            None => return ([0.0; 4], [0.0; 4]),
        },
        None => None,
    };
    let (mut albedo, mut normal, mut depth) = (Vec3::ZERO, Vec3::ZERO, 0.0f32);
    for (k, [px, py]) in FEATURE_POSITIONS.into_iter().enumerate() {
        let (o, d) = match (wall, tile) {
            (Some(wc), Some(t)) => wc.ray(t, x, y, px, py),
            _ => s
                .camera
                .ray(x as f32 + px, y as f32 + py, s.width, s.height),
        };
        let (a, n, z) = feature_ray(sc, pixel, k as u32, o, d);
        albedo += a;
        normal += n;
        depth += z;
    }
    let m = 1.0 / FEATURE_POSITIONS.len() as f32;
    let albedo = albedo * m;
    let normal = (normal * m).normalize_or_zero();
    (
        [albedo.x, albedo.y, albedo.z, 0.0],
        [normal.x, normal.y, normal.z, depth * m],
    )
}

/// Every pixel's features ([`pixel_features`]) on all cores, through `wall`'s primary rays
/// when given: the CPU twin of the features kernel.
#[must_use]
pub fn features_cpu(
    sc: &PackedScene,
    s: &TraceSettings,
    wall: Option<&WallCamera>,
) -> FeatureBuffers {
    let n = s.width * s.height;
    let (albedo, normal_depth) = (0..n)
        .into_par_iter()
        .map(|p| pixel_features(sc, s, wall, p))
        .unzip();
    FeatureBuffers {
        albedo,
        normal_depth,
    }
}

/// The index of the centre ray among a pixel's feature rays (its alpha coverage seeds).
pub const HIT_POSITION: u32 = 4;

/// The primary-hit record of `pixel` (layout and meaning: [`crate::trace::reuse`]) from the
/// ray through its centre, through `wall`'s primary ray when given: the twin of
/// `primary_hits` in features.wgsl.
#[must_use]
pub fn hit_record(
    sc: &PackedScene,
    s: &TraceSettings,
    wall: Option<&WallCamera>,
    pixel: u32,
) -> [[f32; 4]; 2] {
    let (x, y) = (pixel % s.width, pixel / s.width);
    let (o, d) = match wall {
        Some(wc) => match wc.tile_of(x, y) {
            Some(t) => wc.ray(t, x, y, 0.5, 0.5),
            None => return [[0.0; 4], [0.0, 0.0, 0.0, f32::from_bits(reuse::NOTHING)]],
        },
        None => s
            .camera
            .ray(x as f32 + 0.5, y as f32 + 0.5, s.width, s.height),
    };
    let seed = ray_seed(pixel, HIT_POSITION, FEATURE_SEED, 0, 0);
    let hit = sc
        .bvh
        .closest_hit_filtered(o, d, f32::INFINITY, |tri, u, w| {
            alpha_covered(sc, tri, u, w, seed)
        });
    let Some(hit) = hit else {
        return [
            [d.x, d.y, d.z, 0.0],
            [0.0, 0.0, 0.0, f32::from_bits(reuse::MISS)],
        ];
    };
    let sf = surface_at(sc, &hit, d);
    let mut word = (sf.mb / MATERIAL_STRIDE) as u32;
    if sf.transmission >= 0.5 || (sf.metallic >= 0.5 && sf.alpha <= SPECULAR_ALPHA) {
        word |= reuse::NEVER_REUSE;
    }
    let a = o + d * hit.t;
    [
        [a.x, a.y, a.z, sf.alpha],
        [sf.ng.x, sf.ng.y, sf.ng.z, f32::from_bits(word)],
    ]
}

/// Every pixel's primary-hit record ([`hit_record`]) on all cores: the CPU twin of the
/// `primary_hits` kernel.
#[must_use]
pub fn hit_records_cpu(
    sc: &PackedScene,
    s: &TraceSettings,
    wall: Option<&WallCamera>,
) -> Vec<[[f32; 4]; 2]> {
    (0..s.width * s.height)
        .into_par_iter()
        .map(|p| hit_record(sc, s, wall, p))
        .collect()
}

#[cfg(test)]
mod tests {
    use glam::{Vec2, Vec4};

    use super::*;
    use crate::scene::{Environment, Material, Scene, Triangle};
    use crate::trace::camera::{LookAt, RenderCamera};

    /// A square of side `2 h` centred on `c` facing +Z (normal towards the camera at +Z).
    fn quad(c: Vec3, h: f32, material: u32) -> [Triangle; 2] {
        let p = [
            c + Vec3::new(-h, -h, 0.0),
            c + Vec3::new(h, -h, 0.0),
            c + Vec3::new(h, h, 0.0),
            c + Vec3::new(-h, h, 0.0),
        ];
        let t = |a: usize, b: usize, cc: usize| Triangle {
            p: [p[a], p[b], p[cc]],
            n: [Vec3::Z; 3],
            uv: [Vec2::ZERO; 3],
            material,
        };
        [t(0, 1, 2), t(0, 2, 3)]
    }

    fn material(base: Vec3, metallic: f32, roughness: f32) -> Material {
        Material {
            base_color: base.extend(1.0),
            metallic,
            roughness,
            double_sided: true,
            ..Default::default()
        }
    }

    fn settings(width: u32, height: u32, from: Vec3, at: Vec3, yfov_deg: f32) -> TraceSettings {
        let look = LookAt { from, at, yfov_deg };
        TraceSettings {
            width,
            height,
            seed: 0,
            max_depth: 8,
            camera: RenderCamera::look_at(&look, width, height).unwrap(),
        }
    }

    /// The mean distance along the feature positions' rays of `pixel` to the plane z = 0.
    fn plane_depth(s: &TraceSettings, pixel: u32) -> f32 {
        let (x, y) = (pixel % s.width, pixel / s.width);
        let sum: f32 = FEATURE_POSITIONS
            .iter()
            .map(|[px, py]| {
                let (o, d) = s
                    .camera
                    .ray(x as f32 + px, y as f32 + py, s.width, s.height);
                -o.z / d.z
            })
            .sum();
        sum / FEATURE_POSITIONS.len() as f32
    }

    /// A camera 3 units in front of a large diffuse plane sees its albedo, its normal (+Z) and
    /// its distance along each ray, at every pixel.
    #[test]
    fn a_plane_gives_its_albedo_normal_and_depth() {
        let albedo = Vec3::new(0.7, 0.3, 0.2);
        let sc = PackedScene::new(&Scene {
            triangles: quad(Vec3::ZERO, 100.0, 0).to_vec(),
            materials: vec![material(albedo, 0.0, 1.0)],
            environment: Environment::Constant(Vec3::splat(0.5)),
            ..Default::default()
        });
        let s = settings(8, 6, Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 40.0);
        let f = features_cpu(&sc, &s, None);
        assert_eq!(f.albedo.len(), 48);
        for p in 0..48 {
            let a = f.albedo[p];
            let nd = f.normal_depth[p];
            for c in 0..3 {
                assert!((a[c] - albedo[c]).abs() < 1e-6, "pixel {p}: albedo {a:?}");
            }
            assert!(
                (Vec3::new(nd[0], nd[1], nd[2]) - Vec3::Z).length() < 1e-5,
                "{nd:?}"
            );
            let want = plane_depth(&s, p as u32);
            assert!(
                (nd[3] - want).abs() < 1e-4 * want,
                "pixel {p}: depth {} vs {want}",
                nd[3]
            );
            assert!(nd[3] > 3.0 && nd[3] < 3.6, "{}", nd[3]);
        }
    }

    /// Rays that hit nothing give albedo 0, normal 0 and depth 0.
    #[test]
    fn a_miss_gives_zeros() {
        let sc = PackedScene::new(&Scene {
            triangles: quad(Vec3::new(0.0, 0.0, -5.0), 1.0, 0).to_vec(),
            materials: vec![material(Vec3::ONE, 0.0, 1.0)],
            environment: Environment::Constant(Vec3::splat(0.8)),
            ..Default::default()
        });
        // Looking away from the quad.
        let s = settings(4, 4, Vec3::ZERO, Vec3::new(0.0, 0.0, 1.0), 40.0);
        let f = features_cpu(&sc, &s, None);
        for p in 0..16 {
            assert_eq!(f.albedo[p], [0.0; 4]);
            assert_eq!(f.normal_depth[p], [0.0; 4]);
        }
    }

    /// A mirror facing the camera, with a diffuse wall behind the camera: the features are the
    /// wall's albedo and normal (towards the mirror), and the depth is the mirror's.
    #[test]
    fn a_mirror_shows_the_wall_behind_the_camera() {
        let wall_albedo = Vec3::new(0.2, 0.6, 0.4);
        let mut wall = quad(Vec3::new(0.0, 0.0, 10.0), 100.0, 1);
        // Facing −Z (towards the mirror).
        for t in &mut wall {
            t.n = [-Vec3::Z; 3];
            t.p.swap(1, 2);
        }
        let mut triangles = quad(Vec3::ZERO, 100.0, 0).to_vec();
        triangles.extend(wall);
        let sc = PackedScene::new(&Scene {
            triangles,
            materials: vec![
                material(Vec3::splat(0.9), 1.0, 0.0),
                material(wall_albedo, 0.0, 1.0),
            ],
            environment: Environment::Constant(Vec3::splat(0.5)),
            ..Default::default()
        });
        let s = settings(6, 4, Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 30.0);
        let f = features_cpu(&sc, &s, None);
        for p in 0..24 {
            let a = f.albedo[p];
            let nd = f.normal_depth[p];
            for c in 0..3 {
                assert!(
                    (a[c] - wall_albedo[c]).abs() < 1e-6,
                    "pixel {p}: albedo {a:?}"
                );
            }
            assert!(
                (Vec3::new(nd[0], nd[1], nd[2]) + Vec3::Z).length() < 1e-5,
                "{nd:?}"
            );
            let want = plane_depth(&s, p as u32);
            assert!(
                (nd[3] - want).abs() < 1e-4 * want,
                "pixel {p}: depth {}",
                nd[3]
            );
        }
        // A rough metal is not specular: its own albedo.
        let mut rough = sc.clone();
        let mb = 0;
        rough.materials[mb + 2][1] = 0.25;
        let f = features_cpu(&rough, &s, None);
        assert!((Vec4::from_array(f.albedo[0]) - Vec4::new(0.9, 0.9, 0.9, 0.0)).length() < 1e-6);
    }

    /// A pixel half on a plane, half off it: means over the positions (albedo halved, depth
    /// the mean with 0 for the misses) and the normal still unit.
    #[test]
    fn an_edge_pixel_averages_its_positions() {
        let albedo = Vec3::new(0.5, 0.5, 0.5);
        // An orthographic-like narrow view of the quad's edge at x = 0: the quad covers x < 0.
        let sc = PackedScene::new(&Scene {
            triangles: quad(Vec3::new(-50.0, 0.0, 0.0), 50.0, 0).to_vec(),
            materials: vec![material(albedo, 0.0, 1.0)],
            environment: Environment::Constant(Vec3::ONE),
            ..Default::default()
        });
        // 2 × 1 pixels: the boundary between them is at x = 0 exactly (the view's centre).
        let s = settings(2, 1, Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 10.0);
        let f = features_cpu(&sc, &s, None);
        assert!((f.albedo[0][0] - 0.5).abs() < 1e-6, "{:?}", f.albedo);
        assert_eq!(f.albedo[1], [0.0; 4]);
        assert_eq!(f.normal_depth[1], [0.0; 4]);
        let n = Vec3::new(
            f.normal_depth[0][0],
            f.normal_depth[0][1],
            f.normal_depth[0][2],
        );
        assert!((n - Vec3::Z).length() < 1e-5);
    }
}
