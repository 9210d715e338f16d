//! The scene's BVH: an eight-wide compressed BVH (CWBVH, Ylitie et al. 2017) built by `obvhs`.
//!
//! Node layout (80 bytes, obvhs' `CwBvhNode` uploaded as is, read in WGSL as five `vec4<u32>`):
//!
//! | words | content |
//! |---|---|
//! | 0–2 | node origin `p` (f32) |
//! | 3 | child-box exponents `e[0..3]` (bytes 0–2) and `imask` (byte 3) |
//! | 4, 5 | first child node, first primitive |
//! | 6, 7 | `child_meta[8]` |
//! | 8–19 | quantised child boxes: min x, max x, min y, max y, min z, max z (8 bytes each) |
//!
//! Why this layout: a GPU without ray-tracing cores is bound by memory traffic during traversal.
//! One 80-byte node gives the boxes of eight children (a BVH2 needs four 32-byte nodes = 128
//! bytes for the same eight boxes, and twice the depth), the quantised boxes are conservative
//! so no hit is lost, and the child order is sorted by ray octant with two integer operations
//! (`oct_inv4`), so traversal visits near children first without sorting. This is the layout
//! and traversal of the Tray Racing benchmark that `obvhs` was built for.
//!
//! Primitives are stored in BVH order (`prims`, three `vec4<f32>` each: `v0` and the original
//! triangle index, `e1 = v1 − v0` and the light-selection density, `e2 = v2 − v0` and the
//! primitive's flags as a small float — [`PRIM_CULL`] for a single-sided triangle, whose back
//! face rays pass through, plus [`PRIM_ALPHA`] for one whose material is alpha-masked or
//! blended, where the caller decides per hit whether the surface is there), so a leaf's
//! triangles are contiguous in memory.

use std::time::Duration;

use glam::{UVec2, Vec3, Vec3A, vec3a};
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, node::CwBvhNode},
    ray::Ray,
    triangle::Triangle as ObvhsTriangle,
};

/// Primitive flag: single-sided (rays pass the back face).
pub const PRIM_CULL: u32 = 1;
/// Primitive flag: alpha-tested (MASK or BLEND): a hit counts only where the traversal's
/// coverage test says the surface is there.
pub const PRIM_ALPHA: u32 = 2;

/// The BVH and the primitives in BVH order.
#[derive(Clone, Debug)]
pub struct SceneBvh {
    pub cwbvh: CwBvh,
    /// Three entries per BVH primitive: `[v0, orig]`, `[e1, light_density]`, `[e2, 0]`.
    pub prims: Vec<[f32; 4]>,
    /// The same triangles as structure of arrays for the CPU's 8-wide leaf test.
    pub lanes: PrimLanes,
}

/// The BVH primitives' triangles as ten arrays (v0, e1, e2 by component, then 1.0 for a
/// single-sided one), each padded by `LANE_PAD` zeros, so that the triangles of a node's
/// leaves — contiguous, at most 24 from the node's first primitive — load as 8-wide lanes.
/// `alpha`: whether any primitive is alpha-tested (then the per-triangle test runs, in order,
/// since coverage is decided per hit).
#[derive(Clone, Debug, Default)]
pub struct PrimLanes {
    stride: usize,
    data: Vec<f32>,
    alpha: bool,
}

/// Zeros after each array of [`PrimLanes`]: the lanes of a node's last chunk may run past the
/// last primitive (such lanes are masked off, and a zero triangle is no hit anyway).
const LANE_PAD: usize = 24;

impl PrimLanes {
    fn new(prims: &[[f32; 4]]) -> Self {
        let n = prims.len() / 3;
        let stride = n + LANE_PAD;
        let mut data = vec![0.0; 10 * stride];
        let mut alpha = false;
        for i in 0..n {
            for k in 0..9 {
                data[k * stride + i] = prims[3 * i + k / 3][k % 3];
            }
            let flags = prims[3 * i + 2][3] as u32;
            data[9 * stride + i] = if flags & PRIM_CULL != 0 { 1.0 } else { 0.0 };
            alpha |= flags & PRIM_ALPHA != 0;
        }
        Self {
            stride,
            data,
            alpha,
        }
    }
}

/// A closest hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceHit {
    pub t: f32,
    /// Barycentrics of `v1` and `v2`.
    pub u: f32,
    pub v: f32,
    /// The original triangle index (into `Scene::triangles`).
    pub triangle: u32,
    /// Index of the BVH primitive (into `prims / 3`).
    pub prim: u32,
}

/// Möller–Trumbore with precomputed edges; the same arithmetic as `intersect_triangle` in
/// `shaders/trace/bvh.wgsl`. Returns (t, u, v) for `tmin < t < tmax`.
#[inline]
#[must_use]
pub fn intersect_triangle(
    origin: Vec3,
    dir: Vec3,
    v0: Vec3,
    e1: Vec3,
    e2: Vec3,
    tmax: f32,
) -> Option<(f32, f32, f32)> {
    intersect_triangle_sided(origin, dir, v0, e1, e2, tmax, false)
}

/// [`intersect_triangle`], with the back face ignored when `cull_back` (a single-sided glTF
/// material). `det = e1·(d × e2) = −d·(e1 × e2)` is positive exactly when the ray meets the
/// front face (the one `e1 × e2` points out of, counter-clockwise winding).
#[must_use]
#[inline]
pub fn intersect_triangle_sided(
    origin: Vec3,
    dir: Vec3,
    v0: Vec3,
    e1: Vec3,
    e2: Vec3,
    tmax: f32,
    cull_back: bool,
) -> Option<(f32, f32, f32)> {
    let pv = dir.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() || (cull_back && det < 0.0) {
        return None;
    }
    let inv_det = 1.0 / det;
    let tv = origin - v0;
    let u = tv.dot(pv) * inv_det;
    let qv = tv.cross(e1);
    let v = dir.dot(qv) * inv_det;
    let t = e2.dot(qv) * inv_det;
    if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && t < tmax {
        Some((t, u, v))
    } else {
        None
    }
}

/// The hit mask of `node`'s eight children for `ray` (inner children in the high byte, leaf
/// triangles in the low 24 bits, in the ray octant's order): obvhs' `intersect_ray` and
/// `node_hits` in bvh.wgsl, the same products, sums, maxima and minima in the same order, so the
/// same children are hit. All eight children in one pass of 8-wide AVX2 lanes (obvhs tests
/// four at a time, two passes, building the lanes with scalar conversions); DESIGN.md §7.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
#[inline(always)]
fn node_hits(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    use std::arch::x86_64::{
        _CMP_LE_OQ, _mm_loadl_epi64, _mm256_add_ps, _mm256_cmp_ps, _mm256_cvtepi32_ps,
        _mm256_cvtepu8_epi32, _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps,
        _mm256_set1_ps,
    };
    let adj_dir_inv = node.compute_extent() * ray.inv_direction;
    let adj_orig = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    // SAFETY: this is compiled only where AVX and AVX2 are enabled for the whole build
    // (.cargo/config.toml; the `cfg` above), so every intrinsic here is available; the one
    // memory access, `_mm_loadl_epi64`, reads the 8 bytes of a `[u8; 8]` (unaligned loads are
    // allowed). Why it pays: see the doc comment and BENCHMARKS.md.
    let mut hit = unsafe {
        // The eight children's quantised planes on one axis as f32 lanes.
        let planes = |q: &[u8; 8]| {
            let bytes = _mm_loadl_epi64(q.as_ptr().cast());
            _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(bytes))
        };
        let slab = |lo: &[u8; 8], hi: &[u8; 8], negative: bool, scale: f32, offset: f32| {
            let (near, far) = if negative { (hi, lo) } else { (lo, hi) };
            let (s, o) = (_mm256_set1_ps(scale), _mm256_set1_ps(offset));
            (
                _mm256_add_ps(_mm256_mul_ps(planes(near), s), o),
                _mm256_add_ps(_mm256_mul_ps(planes(far), s), o),
            )
        };
        let d = ray.direction;
        let (x0, x1) = slab(
            &node.child_min_x,
            &node.child_max_x,
            d.x < 0.0,
            adj_dir_inv.x,
            adj_orig.x,
        );
        let (y0, y1) = slab(
            &node.child_min_y,
            &node.child_max_y,
            d.y < 0.0,
            adj_dir_inv.y,
            adj_orig.y,
        );
        let (z0, z1) = slab(
            &node.child_min_z,
            &node.child_max_z,
            d.z < 0.0,
            adj_dir_inv.z,
            adj_orig.z,
        );
        let t_near = _mm256_max_ps(
            _mm256_max_ps(x0, _mm256_max_ps(y0, z0)),
            _mm256_set1_ps(NODE_EPSILON),
        );
        let t_far = _mm256_min_ps(
            _mm256_min_ps(x1, _mm256_min_ps(y1, z1)),
            _mm256_set1_ps(ray.tmax),
        );
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, t_far)) as u32
    };
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let mut mask = 0u32;
    while hit != 0 {
        let c = hit.trailing_zeros();
        hit &= hit - 1;
        let child_bits = (child_bits8 >> (8 * c)) as u32 & 0xff;
        let bit_index = (bit_index8 >> (8 * c)) as u32 & 0xff;
        mask |= child_bits << bit_index;
    }
    mask
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
impl PrimLanes {
    /// [`intersect_triangle_sided`] on the eight primitives `first..first + 8` at once, the
    /// same operations in the same order per lane (no FMA in this build, so each lane's t, u,
    /// v are the scalar test's to the bit): the mask of the lanes hit with `0 < t < tmax`, and
    /// t, u, v per lane.
    #[inline(always)]
    fn test8(
        &self,
        first: usize,
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> (u32, [f32; 8], [f32; 8], [f32; 8]) {
        use std::arch::x86_64::{
            __m256, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_NEQ_OQ, _mm256_add_ps,
            _mm256_and_ps, _mm256_andnot_ps, _mm256_cmp_ps, _mm256_div_ps, _mm256_loadu_ps,
            _mm256_movemask_ps, _mm256_mul_ps, _mm256_set1_ps, _mm256_setzero_ps, _mm256_storeu_ps,
            _mm256_sub_ps,
        };
        assert!(first + 8 <= self.stride, "lanes past the padding");
        let (mut tt, mut uu, mut vv) = ([0f32; 8], [0f32; 8], [0f32; 8]);
        // SAFETY: AVX and AVX2 are enabled for the whole build (the `cfg`); the loads read
        // `data[k·stride + first .. k·stride + first + 8]`, inside array k (`first + 8 ≤
        // stride`, asserted above) and so inside `data` (10 · stride long); the stores write
        // the three local arrays of 8. Why it pays: BENCHMARKS.md (the per-triangle test was
        // the largest part of traversal).
        let mask = unsafe {
            let ld = |k: usize| _mm256_loadu_ps(self.data.as_ptr().add(k * self.stride + first));
            let (dx, dy, dz) = (
                _mm256_set1_ps(d.x),
                _mm256_set1_ps(d.y),
                _mm256_set1_ps(d.z),
            );
            let (v0x, v0y, v0z) = (ld(0), ld(1), ld(2));
            let (e1x, e1y, e1z) = (ld(3), ld(4), ld(5));
            let (e2x, e2y, e2z) = (ld(6), ld(7), ld(8));
            let cull = ld(9);
            let mul = |a: __m256, b: __m256| _mm256_mul_ps(a, b);
            let sub = |a: __m256, b: __m256| _mm256_sub_ps(a, b);
            let add = |a: __m256, b: __m256| _mm256_add_ps(a, b);
            let zero = _mm256_setzero_ps();
            // pv = d × e2 (glam's cross: y·z' − y'·z, z·x' − z'·x, x·y' − x'·y)
            let pvx = sub(mul(dy, e2z), mul(e2y, dz));
            let pvy = sub(mul(dz, e2x), mul(e2z, dx));
            let pvz = sub(mul(dx, e2y), mul(e2x, dy));
            // det = e1 · pv (glam's dot: (x·x' + y·y') + z·z')
            let det = add(add(mul(e1x, pvx), mul(e1y, pvy)), mul(e1z, pvz));
            let abs_det = _mm256_andnot_ps(_mm256_set1_ps(-0.0), det);
            let finite = _mm256_cmp_ps::<_CMP_LT_OQ>(abs_det, _mm256_set1_ps(f32::INFINITY));
            let nonzero = _mm256_cmp_ps::<_CMP_NEQ_OQ>(det, zero);
            let culled = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_NEQ_OQ>(cull, zero),
                _mm256_cmp_ps::<_CMP_LT_OQ>(det, zero),
            );
            let ok = _mm256_andnot_ps(culled, _mm256_and_ps(finite, nonzero));
            let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), det);
            let tvx = sub(_mm256_set1_ps(o.x), v0x);
            let tvy = sub(_mm256_set1_ps(o.y), v0y);
            let tvz = sub(_mm256_set1_ps(o.z), v0z);
            let u = mul(
                add(add(mul(tvx, pvx), mul(tvy, pvy)), mul(tvz, pvz)),
                inv_det,
            );
            // qv = tv × e1
            let qvx = sub(mul(tvy, e1z), mul(e1y, tvz));
            let qvy = sub(mul(tvz, e1x), mul(e1z, tvx));
            let qvz = sub(mul(tvx, e1y), mul(e1x, tvy));
            let v = mul(add(add(mul(dx, qvx), mul(dy, qvy)), mul(dz, qvz)), inv_det);
            let t = mul(
                add(add(mul(e2x, qvx), mul(e2y, qvy)), mul(e2z, qvz)),
                inv_det,
            );
            let inside = _mm256_and_ps(
                _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_GE_OQ>(u, zero),
                    _mm256_cmp_ps::<_CMP_GE_OQ>(v, zero),
                ),
                _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_LE_OQ>(add(u, v), _mm256_set1_ps(1.0)),
                    _mm256_and_ps(
                        _mm256_cmp_ps::<_CMP_GT_OQ>(t, zero),
                        _mm256_cmp_ps::<_CMP_LT_OQ>(t, _mm256_set1_ps(tmax)),
                    ),
                ),
            );
            _mm256_storeu_ps(tt.as_mut_ptr(), t);
            _mm256_storeu_ps(uu.as_mut_ptr(), u);
            _mm256_storeu_ps(vv.as_mut_ptr(), v);
            _mm256_movemask_ps(_mm256_and_ps(ok, inside)) as u32
        };
        (mask, tt, uu, vv)
    }

    /// The closest hit among the primitives `first + k` for the set bits k of `bits` (a node's
    /// leaf triangles): (t, u, v, primitive). The one the per-triangle loop of obvhs'
    /// `traverse!` finds — it visits the highest bit first and keeps a hit only if strictly
    /// nearer, so of equal t the highest bit wins, here too.
    #[inline(always)]
    fn closest(
        &self,
        first: u32,
        bits: u32,
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> Option<(f32, f32, f32, u32)> {
        let mut best: Option<(f32, f32, f32, u32)> = None;
        let mut bound = tmax;
        for chunk in (0..3).rev() {
            let want = (bits >> (8 * chunk)) & 0xff;
            if want == 0 {
                continue;
            }
            let base = first as usize + 8 * chunk;
            let (hit, t, u, v) = self.test8(base, o, d, tmax);
            let mut m = hit & want;
            while m != 0 {
                let k = 31 - m.leading_zeros();
                m &= !(1 << k);
                let k = k as usize;
                if t[k] < bound {
                    bound = t[k];
                    best = Some((t[k], u[k], v[k], (base + k) as u32));
                }
            }
        }
        best
    }

    /// Whether any of the primitives `first + k` (set bits k of `bits`) is hit with
    /// `0 < t < tmax`.
    #[inline(always)]
    fn any(&self, first: u32, bits: u32, o: Vec3, d: Vec3, tmax: f32) -> bool {
        (0..3).any(|chunk| {
            let want = (bits >> (8 * chunk)) & 0xff;
            want != 0 && self.test8(first as usize + 8 * chunk, o, d, tmax).0 & want != 0
        })
    }
}

/// Without AVX2: obvhs' own node test (four children at a time).
#[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
#[inline(always)]
fn node_hits(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    node.intersect_ray(ray, oct_inv4)
}

/// obvhs' near-plane bound of the node test (`NODE_EPSILON` in bvh.wgsl).
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
const NODE_EPSILON: f32 = 0.0001;

impl SceneBvh {
    /// Builds the BVH over `triangles` (world-space vertices) with obvhs' high-quality preset
    /// (`slow_build`: spatial pre-splits, PLOC, reinsertion). `light_density[i]` is stored with
    /// triangle `i` (the probability density, per unit area, with which next-event estimation
    /// picks a point on it; 0 for non-emitters).
    #[must_use]
    pub fn build(triangles: &[[Vec3; 3]], light_density: &[f32]) -> Self {
        Self::build_sided(triangles, light_density, &[])
    }

    /// [`Self::build`] with `single_sided[i]` set for the triangles whose back face rays pass
    /// (missing entries: double-sided).
    #[must_use]
    pub fn build_sided(
        triangles: &[[Vec3; 3]],
        light_density: &[f32],
        single_sided: &[bool],
    ) -> Self {
        let flags: Vec<u32> = single_sided
            .iter()
            .map(|&s| if s { PRIM_CULL } else { 0 })
            .collect();
        Self::build_flagged(triangles, light_density, &flags)
    }

    /// [`Self::build`] with per-triangle flags ([`PRIM_CULL`], [`PRIM_ALPHA`]; missing
    /// entries: none), stored as the float `flags as f32` (exact, and a normal number on every
    /// GPU, where a bit pattern this small would be a subnormal that may be flushed).
    #[must_use]
    pub fn build_flagged(triangles: &[[Vec3; 3]], light_density: &[f32], flags: &[u32]) -> Self {
        if triangles.is_empty() {
            return Self {
                cwbvh: CwBvh::default(),
                prims: Vec::new(),
                lanes: PrimLanes::default(),
            };
        }
        let tris: Vec<ObvhsTriangle> = triangles
            .iter()
            .map(|t| ObvhsTriangle {
                v0: t[0].into(),
                v1: t[1].into(),
                v2: t[2].into(),
            })
            .collect();
        let cwbvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::slow_build(),
            &mut Duration::default(),
        );
        let mut prims = Vec::with_capacity(cwbvh.primitive_indices.len() * 3);
        for &orig in &cwbvh.primitive_indices {
            let t = &triangles[orig as usize];
            let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
            prims.push([t[0].x, t[0].y, t[0].z, f32::from_bits(orig)]);
            prims.push([e1.x, e1.y, e1.z, light_density[orig as usize]]);
            let f = flags.get(orig as usize).copied().unwrap_or(0);
            prims.push([e2.x, e2.y, e2.z, f as f32]);
        }
        let lanes = PrimLanes::new(&prims);
        Self {
            cwbvh,
            prims,
            lanes,
        }
    }

    /// BVH primitive `i`'s flags ([`PRIM_CULL`], [`PRIM_ALPHA`]).
    #[inline]
    fn flags(&self, i: usize) -> u32 {
        self.prims[3 * i + 2][3] as u32
    }

    fn prim(&self, i: usize) -> (Vec3, Vec3, Vec3) {
        let p = &self.prims[3 * i..3 * i + 3];
        (
            Vec3::new(p[0][0], p[0][1], p[0][2]),
            Vec3::new(p[1][0], p[1][1], p[1][2]),
            Vec3::new(p[2][0], p[2][1], p[2][2]),
        )
    }

    /// The original triangle index of BVH primitive `i`.
    #[must_use]
    pub fn prim_triangle(&self, i: u32) -> u32 {
        self.prims[3 * i as usize][3].to_bits()
    }

    /// The light density stored with BVH primitive `i`.
    #[must_use]
    pub fn prim_light_density(&self, i: u32) -> f32 {
        self.prims[3 * i as usize + 1][3]
    }

    fn ray(origin: Vec3, dir: Vec3, tmax: f32) -> Ray {
        // obvhs' node test uses a reciprocal with a guard for tiny components; our twin in
        // WGSL computes the same `safe_inverse`.
        Ray::new(Vec3A::from(origin), Vec3A::from(dir), 0.0, tmax)
    }

    /// The closest hit along `origin + t·dir`, `0 < t < tmax`.
    #[must_use]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<TraceHit> {
        self.closest_hit_filtered(origin, dir, tmax, |_, _, _| true)
    }

    /// [`Self::closest_hit`] where a hit on an alpha-tested primitive ([`PRIM_ALPHA`]) counts
    /// only if `covered(triangle, u, v)` (the CPU twin of `alpha_covered` in path.wgsl).
    #[must_use]
    pub fn closest_hit_filtered(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: impl Fn(u32, f32, f32) -> bool,
    ) -> Option<TraceHit> {
        if self.cwbvh.nodes.is_empty() {
            return None;
        }
        let mut ray = Self::ray(origin, dir, tmax);
        let mut best: Option<TraceHit> = None;
        let mut state = self.cwbvh.new_traversal(vec3a(dir.x, dir.y, dir.z));
        let mut node;
        let bvh = &self.cwbvh;
        obvhs::traverse!(bvh, node, state, node_hits(node, &ray, state.oct_inv4), {
            #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
            if !self.lanes.alpha {
                // The whole group of this node's leaf triangles at once.
                let local = state.primitive_id - state.primitive_group.x;
                let bits = state.primitive_group.y | (1 << local);
                state.primitive_group.y = 0;
                if let Some((t, u, v, i)) =
                    self.lanes
                        .closest(state.primitive_group.x, bits, origin, dir, ray.tmax)
                {
                    ray.tmax = t;
                    best = Some(TraceHit {
                        t,
                        u,
                        v,
                        triangle: self.prims[3 * i as usize][3].to_bits(),
                        prim: i,
                    });
                }
                continue;
            }
            let i = state.primitive_id as usize;
            let (v0, e1, e2) = self.prim(i);
            let flags = self.flags(i);
            if let Some((t, u, v)) =
                intersect_triangle_sided(origin, dir, v0, e1, e2, ray.tmax, flags & PRIM_CULL != 0)
                    .filter(|&(_, u, v)| {
                        flags & PRIM_ALPHA == 0 || covered(self.prims[3 * i][3].to_bits(), u, v)
                    })
            {
                ray.tmax = t;
                best = Some(TraceHit {
                    t,
                    u,
                    v,
                    triangle: self.prims[3 * i][3].to_bits(),
                    prim: i as u32,
                });
            }
        });
        best
    }

    /// Whether anything blocks `origin + t·dir` for `0 < t < tmax` (shadow rays).
    #[must_use]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.occluded_filtered(origin, dir, tmax, |_, _, _| true)
    }

    /// [`Self::occluded`] with the coverage test of [`Self::closest_hit_filtered`].
    #[must_use]
    pub fn occluded_filtered(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        if self.cwbvh.nodes.is_empty() {
            return false;
        }
        let ray = Self::ray(origin, dir, tmax);
        let mut state = self.cwbvh.new_traversal(vec3a(dir.x, dir.y, dir.z));
        let mut node;
        let bvh = &self.cwbvh;
        let mut blocked = false;
        'search: {
            obvhs::traverse!(bvh, node, state, node_hits(node, &ray, state.oct_inv4), {
                #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
                if !self.lanes.alpha {
                    let local = state.primitive_id - state.primitive_group.x;
                    let bits = state.primitive_group.y | (1 << local);
                    state.primitive_group.y = 0;
                    if self
                        .lanes
                        .any(state.primitive_group.x, bits, origin, dir, tmax)
                    {
                        blocked = true;
                        break 'search;
                    }
                    continue;
                }
                let i = state.primitive_id as usize;
                let (v0, e1, e2) = self.prim(i);
                let flags = self.flags(i);
                if intersect_triangle_sided(origin, dir, v0, e1, e2, tmax, flags & PRIM_CULL != 0)
                    .is_some_and(|(_, u, v)| {
                        flags & PRIM_ALPHA == 0 || covered(self.prims[3 * i][3].to_bits(), u, v)
                    })
                {
                    blocked = true;
                    break 'search;
                }
            });
        }
        blocked
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A brute-force oracle over the same triangles.
    fn brute(tris: &[[Vec3; 3]], o: Vec3, d: Vec3) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for (i, t) in tris.iter().enumerate() {
            let tmax = best.map_or(f32::INFINITY, |b| b.0);
            if let Some((h, _, _)) = intersect_triangle(o, d, t[0], t[1] - t[0], t[2] - t[0], tmax)
            {
                best = Some((h, i as u32));
            }
        }
        best
    }

    fn random_triangles(n: usize, seed: u32) -> Vec<[Vec3; 3]> {
        let mut k = 0u32;
        let mut r = move || {
            k += 1;
            crate::random::unit_f32(crate::random::pcg4d([k, seed, 0, 0])[0])
        };
        (0..n)
            .map(|_| {
                let c = Vec3::new(r(), r(), r()) * 10.0 - 5.0;
                let a = Vec3::new(r(), r(), r()) - 0.5;
                let b = Vec3::new(r(), r(), r()) - 0.5;
                [c, c + a, c + b]
            })
            .collect()
    }

    #[test]
    fn closest_hits_equal_brute_force() {
        let tris = random_triangles(3000, 1);
        let bvh = SceneBvh::build(&tris, &vec![0.0; tris.len()]);
        let mut k = 0u32;
        let mut r = move || {
            k += 1;
            crate::random::unit_f32(crate::random::pcg4d([k, 99, 0, 0])[0])
        };
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Vec3::new(r(), r(), r()) * 14.0 - 7.0;
            let d = (Vec3::new(r(), r(), r()) - 0.5).normalize();
            let got = bvh.closest_hit(o, d, f32::INFINITY);
            let want = brute(&tris, o, d);
            match (got, want) {
                (None, None) => {}
                (Some(g), Some(w)) => {
                    hits += 1;
                    assert_eq!(g.t, w.0, "t differs for ray {o} {d}");
                    // Equal t on two triangles is possible only at shared points; ours are random.
                    assert_eq!(g.triangle, w.1);
                    assert!(bvh.occluded(o, d, g.t * 1.0001));
                    assert!(!bvh.occluded(o, d, g.t * 0.9999));
                }
                (g, w) => panic!("ray {o} {d}: bvh {g:?}, brute force {w:?}"),
            }
        }
        assert!(hits > 300, "the test must exercise hits ({hits})");
    }

    #[test]
    fn empty_bvh_misses_everything() {
        let bvh = SceneBvh::build(&[], &[]);
        assert!(
            bvh.closest_hit(Vec3::ZERO, Vec3::X, f32::INFINITY)
                .is_none()
        );
        assert!(!bvh.occluded(Vec3::ZERO, Vec3::X, f32::INFINITY));
    }
}
