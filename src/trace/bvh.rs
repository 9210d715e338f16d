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
//! and traversal of the Tray Racing benchmark that `obvhs` was built for. The CPU twin reads
//! the same nodes with the same box arithmetic but visits a node's inner children by entry
//! distance and skips those entered beyond the closest hit so far ([`SceneBvh::closest_hit`]):
//! the same hits, fewer nodes, and on a CPU the culling pays for the sort (BENCHMARKS.md).
//!
//! Primitives are stored in BVH order (`prims`, three `vec4<f32>` each: `v0` and the original
//! triangle index, `e1 = v1 − v0` and the light-selection density, `e2 = v2 − v0` and the
//! primitive's flags as a small float — [`PRIM_CULL`] for a single-sided triangle, whose back
//! face rays pass through, plus [`PRIM_ALPHA`] for one whose material is alpha-masked or
//! blended, where the caller decides per hit whether the surface is there), so a leaf's
//! triangles are contiguous in memory.

use std::time::Duration;

use glam::{Vec3, Vec3A};
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
    /// The most entries a traversal's stack can hold: 7 per level below the root (the
    /// siblings of the child taken), plus one node's 8.
    stack_size: usize,
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

/// The slab test of `node`'s eight child boxes against `ray`: bit c of the mask is set when
/// child slot c's box is entered at or before `ray.tmax` (and its far side is not nearer than
/// [`NODE_EPSILON`]), and entry c is that box's entry distance. The arithmetic of obvhs'
/// `intersect_ray` and of `node_hits` in bvh.wgsl — the same products, sums, maxima and minima
/// in the same order, so the same children are hit — here for all eight children in one pass
/// of 8-wide AVX2 lanes (obvhs tests four at a time, two passes, building the lanes with scalar
/// conversions); DESIGN.md §7. Empty slots may report a hit: their metadata says they hold
/// nothing.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
#[inline(always)]
fn child_entries(node: &CwBvhNode, ray: &Ray) -> (u32, [f32; 8]) {
    use std::arch::x86_64::{
        _CMP_LE_OQ, _mm_loadl_epi64, _mm256_add_ps, _mm256_cmp_ps, _mm256_cvtepi32_ps,
        _mm256_cvtepu8_epi32, _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps,
        _mm256_set1_ps, _mm256_storeu_ps,
    };
    let adj_dir_inv = node.compute_extent() * ray.inv_direction;
    let adj_orig = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    let mut entry = [0f32; 8];
    // SAFETY: this is compiled only where AVX and AVX2 are enabled for the whole build
    // (.cargo/config.toml; the `cfg` above), so every intrinsic here is available; the memory
    // accesses are `_mm_loadl_epi64` of the 8 bytes of a `[u8; 8]` (unaligned loads are
    // allowed) and one store of 8 lanes into the local `[f32; 8]`. Why it pays: see the doc
    // comment and BENCHMARKS.md.
    let hit = unsafe {
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
        _mm256_storeu_ps(entry.as_mut_ptr(), t_near);
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, t_far)) as u32
    };
    (hit, entry)
}

/// Without AVX2: [`child_entries_scalar`].
#[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
#[inline(always)]
fn child_entries(node: &CwBvhNode, ray: &Ray) -> (u32, [f32; 8]) {
    child_entries_scalar(node, ray)
}

/// [`child_entries`] a child at a time (`maxps`/`minps` semantics: the second operand unless
/// the first is greater / smaller): the build without AVX2, and the lanes' oracle.
#[cfg_attr(all(target_arch = "x86_64", target_feature = "avx2"), allow(dead_code))]
#[inline(always)]
fn child_entries_scalar(node: &CwBvhNode, ray: &Ray) -> (u32, [f32; 8]) {
    let max = |a: f32, b: f32| if a > b { a } else { b };
    let min = |a: f32, b: f32| if a < b { a } else { b };
    let adj_dir_inv = node.compute_extent() * ray.inv_direction;
    let adj_orig = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    let d = ray.direction;
    let slab = |lo: u8, hi: u8, negative: bool, scale: f32, offset: f32| {
        let (near, far) = if negative { (hi, lo) } else { (lo, hi) };
        (
            f32::from(near) * scale + offset,
            f32::from(far) * scale + offset,
        )
    };
    let mut entry = [0f32; 8];
    let mut hit = 0;
    for (c, entry) in entry.iter_mut().enumerate() {
        let (x0, x1) = slab(
            node.child_min_x[c],
            node.child_max_x[c],
            d.x < 0.0,
            adj_dir_inv.x,
            adj_orig.x,
        );
        let (y0, y1) = slab(
            node.child_min_y[c],
            node.child_max_y[c],
            d.y < 0.0,
            adj_dir_inv.y,
            adj_orig.y,
        );
        let (z0, z1) = slab(
            node.child_min_z[c],
            node.child_max_z[c],
            d.z < 0.0,
            adj_dir_inv.z,
            adj_orig.z,
        );
        let t_near = max(max(x0, max(y0, z0)), NODE_EPSILON);
        let t_far = min(min(x1, min(y1, z1)), ray.tmax);
        *entry = t_near;
        if t_near <= t_far {
            hit |= 1 << c;
        }
    }
    (hit, entry)
}

/// The primitives of `node`'s leaf children in `leaves` (a mask of child slots), as bits of
/// offsets from `node.primitive_base_idx`: each leaf's unary primitive count (metadata bits
/// 5–7) shifted to its first primitive's offset (bits 0–4). An empty slot adds nothing.
#[inline(always)]
fn leaf_primitive_bits(node: &CwBvhNode, mut leaves: u32) -> u32 {
    let mut bits = 0;
    while leaves != 0 {
        let c = leaves.trailing_zeros() as usize;
        leaves &= leaves - 1;
        let meta = u32::from(node.child_meta[c]);
        bits |= (meta >> 5) << (meta & 0b11111);
    }
    bits
}

/// A traversal stack entry: a node's entry distance (a positive f32, so its bits order as the
/// distances do) above its index.
#[inline(always)]
fn stack_entry(t_near: f32, node: u32) -> u64 {
    (u64::from(t_near.to_bits()) << 32) | u64::from(node)
}

thread_local! {
    /// Each thread's traversal stack, kept between rays (taken while a ray uses it), so that
    /// no ray zeroes or allocates one.
    static STACK: std::cell::Cell<Vec<u64>> = const { std::cell::Cell::new(Vec::new()) };
}

/// `f` with this thread's traversal stack, at least `size` entries (their values are left
/// from earlier rays: the traversal writes an entry before it reads it).
#[inline(always)]
fn with_stack<R>(size: usize, f: impl FnOnce(&mut [u64]) -> R) -> R {
    let mut stack = STACK.take();
    if stack.len() < size {
        stack.resize(size, 0);
    }
    let r = f(&mut stack);
    STACK.set(stack);
    r
}

/// Sorts `entries` by distance, the farthest first (so the nearest is popped first): an
/// insertion sort, for the one to eight children a node adds.
#[inline(always)]
fn sort_farthest_first(entries: &mut [u64]) {
    for i in 1..entries.len() {
        let e = entries[i];
        let mut j = i;
        while j > 0 && entries[j - 1] < e {
            entries[j] = entries[j - 1];
            j -= 1;
        }
        entries[j] = e;
    }
}

/// The depth of the BVH below `root` (0 for a node whose children are all leaves).
fn depth(nodes: &[CwBvhNode], root: usize) -> usize {
    let node = &nodes[root];
    (0..8)
        .filter(|&c| node.imask & (1 << c) != 0)
        .map(|c| 1 + depth(nodes, node.child_node_index(c) as usize))
        .max()
        .unwrap_or(0)
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

/// obvhs' near-plane bound of the node test (`NODE_EPSILON` in bvh.wgsl).
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
                stack_size: 0,
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
        let stack_size = 7 * depth(&cwbvh.nodes, 0) + 8;
        Self {
            cwbvh,
            prims,
            lanes,
            stack_size,
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
    ///
    /// The traversal visits a node's children nearest entry first and skips a node whose box
    /// is entered beyond the closest hit found so far (the GPU's kernel keeps obvhs' order by
    /// ray octant, which suits a GPU's lock-step lanes; on a CPU the culling pays, BENCHMARKS.md).
    /// The hit is the same — the nearest one, with the same box and triangle arithmetic — except
    /// where two triangles are hit at exactly the same distance (a shared edge), which either
    /// may win.
    #[must_use]
    pub fn closest_hit_filtered(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: impl Fn(u32, f32, f32) -> bool,
    ) -> Option<TraceHit> {
        let nodes = &self.cwbvh.nodes;
        if nodes.is_empty() {
            return None;
        }
        let mut ray = Self::ray(origin, dir, tmax);
        let mut best: Option<TraceHit> = None;
        with_stack(self.stack_size, |stack| {
            let (mut index, mut len) = (0, 0);
            loop {
                let node: &CwBvhNode = &nodes[index];
                let (hit, entry) = child_entries(node, &ray);
                let imask = u32::from(node.imask);
                // A node's leaf triangles at once, then its inner children by distance.
                let bits = leaf_primitive_bits(node, hit & !imask);
                if bits != 0
                    && let Some((t, u, v, i)) = self.leaf_closest(
                        node.primitive_base_idx,
                        bits,
                        origin,
                        dir,
                        ray.tmax,
                        &covered,
                    )
                {
                    ray.tmax = t;
                    best = Some(TraceHit {
                        t,
                        u,
                        v,
                        triangle: self.prim_triangle(i),
                        prim: i,
                    });
                }
                let first = len;
                let mut inner = hit & imask;
                while inner != 0 {
                    let c = inner.trailing_zeros() as usize;
                    inner &= inner - 1;
                    if entry[c] <= ray.tmax {
                        stack[len] = stack_entry(entry[c], node.child_node_index(c));
                        len += 1;
                    }
                }
                // The nearest on top.
                sort_farthest_first(&mut stack[first..len]);
                loop {
                    if len == 0 {
                        return;
                    }
                    len -= 1;
                    let e = stack[len];
                    if f32::from_bits((e >> 32) as u32) <= ray.tmax {
                        index = e as u32 as usize;
                        break;
                    }
                }
            }
        });
        best
    }

    /// Whether anything blocks `origin + t·dir` for `0 < t < tmax` (shadow rays).
    #[must_use]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.occluded_filtered(origin, dir, tmax, |_, _, _| true)
    }

    /// [`Self::occluded`] with the coverage test of [`Self::closest_hit_filtered`]. Any hit
    /// ends the search, so the children are not ordered.
    #[must_use]
    pub fn occluded_filtered(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        let nodes = &self.cwbvh.nodes;
        if nodes.is_empty() {
            return false;
        }
        let ray = Self::ray(origin, dir, tmax);
        with_stack(self.stack_size, |stack| {
            let (mut index, mut len) = (0, 0);
            loop {
                let node: &CwBvhNode = &nodes[index];
                let (hit, _) = child_entries(node, &ray);
                let imask = u32::from(node.imask);
                let bits = leaf_primitive_bits(node, hit & !imask);
                if bits != 0
                    && self.leaf_any(node.primitive_base_idx, bits, origin, dir, tmax, &covered)
                {
                    return true;
                }
                let mut inner = hit & imask;
                while inner != 0 {
                    let c = inner.trailing_zeros() as usize;
                    inner &= inner - 1;
                    stack[len] = u64::from(node.child_node_index(c));
                    len += 1;
                }
                if len == 0 {
                    return false;
                }
                len -= 1;
                index = stack[len] as usize;
            }
        })
    }

    /// The closest hit among the primitives `first + k` for the set bits k of `bits` (a node's
    /// leaf triangles) with `0 < t < tmax`: (t, u, v, primitive). Of equal t the highest bit
    /// wins (obvhs' order: highest first, a later hit only if strictly nearer).
    #[inline(always)]
    fn leaf_closest(
        &self,
        first: u32,
        bits: u32,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: &impl Fn(u32, f32, f32) -> bool,
    ) -> Option<(f32, f32, f32, u32)> {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        if !self.lanes.alpha {
            return self.lanes.closest(first, bits, origin, dir, tmax);
        }
        let (mut best, mut bound, mut m) = (None, tmax, bits);
        while m != 0 {
            let k = 31 - m.leading_zeros();
            m &= !(1 << k);
            let i = (first + k) as usize;
            if let Some((t, u, v)) = self.test_prim(i, origin, dir, bound, covered) {
                bound = t;
                best = Some((t, u, v, i as u32));
            }
        }
        best
    }

    /// Whether any of the primitives `first + k` (set bits k of `bits`) is hit with
    /// `0 < t < tmax`.
    #[inline(always)]
    fn leaf_any(
        &self,
        first: u32,
        bits: u32,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: &impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        if !self.lanes.alpha {
            return self.lanes.any(first, bits, origin, dir, tmax);
        }
        let mut m = bits;
        while m != 0 {
            let k = m.trailing_zeros();
            m &= m - 1;
            if self
                .test_prim((first + k) as usize, origin, dir, tmax, covered)
                .is_some()
            {
                return true;
            }
        }
        false
    }

    /// BVH primitive `i` against the ray, its flags obeyed (a culled back face, coverage).
    #[inline(always)]
    fn test_prim(
        &self,
        i: usize,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: &impl Fn(u32, f32, f32) -> bool,
    ) -> Option<(f32, f32, f32)> {
        let (v0, e1, e2) = self.prim(i);
        let flags = self.flags(i);
        intersect_triangle_sided(origin, dir, v0, e1, e2, tmax, flags & PRIM_CULL != 0).filter(
            |&(_, u, v)| flags & PRIM_ALPHA == 0 || covered(self.prims[3 * i][3].to_bits(), u, v),
        )
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

    /// Uniform numbers in [0, 1) from stream `seed`.
    fn uniforms(seed: u32) -> impl FnMut() -> f32 {
        let mut k = 0u32;
        move || {
            k += 1;
            crate::random::unit_f32(crate::random::pcg4d([k, seed, 0, 0])[0])
        }
    }

    fn random_triangles(n: usize, seed: u32) -> Vec<[Vec3; 3]> {
        let mut r = uniforms(seed);
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
        let mut r = uniforms(99);
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

    /// The slab test in lanes gives the scalar test's mask and entry distances to the bit,
    /// on every node of a real BVH and rays from everywhere (inside boxes, grazing, axis
    /// parallel, short).
    #[test]
    fn child_entries_lanes_equal_the_scalar_test() {
        let tris = random_triangles(2000, 7);
        let bvh = SceneBvh::build(&tris, &vec![0.0; tris.len()]);
        let mut r = uniforms(5);
        let mut hits = 0;
        for i in 0..3000 {
            let o = Vec3::new(r(), r(), r()) * 14.0 - 7.0;
            let mut d = (Vec3::new(r(), r(), r()) - 0.5).normalize();
            if i % 5 == 0 {
                d.y = 0.0; // parallel to a slab: the guarded inverse
            }
            let tmax = if i % 3 == 0 { r() * 4.0 } else { f32::INFINITY };
            let ray = SceneBvh::ray(o, d, tmax);
            for node in &bvh.cwbvh.nodes {
                let (lanes, scalar) = (child_entries(node, &ray), child_entries_scalar(node, &ray));
                assert_eq!(lanes.0, scalar.0, "hit masks, ray {o} {d}");
                assert_eq!(lanes.1.map(f32::to_bits), scalar.1.map(f32::to_bits));
                hits += lanes.0.count_ones();
            }
        }
        assert!(hits > 10_000, "the rays must enter boxes ({hits})");
    }

    /// A deep BVH (triangles whose sizes and places grow geometrically, so the tree cannot
    /// be balanced): the stack bound holds and every hit is the brute-force one.
    #[test]
    fn deep_trees_find_every_hit() {
        let tris: Vec<[Vec3; 3]> = (0..400)
            .map(|i| {
                let s = 1.05f32.powi(i);
                let c = Vec3::new(s, 0.3 * (i % 7) as f32, -0.001 * i as f32);
                [
                    c,
                    c + Vec3::new(0.5 * s, 0.0, 0.0),
                    c + Vec3::new(0.0, 0.5 * s, 0.0),
                ]
            })
            .collect();
        let bvh = SceneBvh::build(&tris, &vec![0.0; tris.len()]);
        let depth = depth(&bvh.cwbvh.nodes, 0);
        assert!(depth >= 3, "the test needs a deep tree ({depth})");
        assert_eq!(bvh.stack_size, 7 * depth + 8);
        let mut hits = 0;
        for i in 0..4000 {
            let x = 1.05f32.powf(i as f32 / 10.0);
            let o = Vec3::new(x, 0.2 * (i % 13) as f32, 5.0);
            let d = Vec3::new(0.01 * ((i % 9) as f32 - 4.0), 0.0, -1.0).normalize();
            let got = bvh.closest_hit(o, d, f32::INFINITY);
            let want = brute(&tris, o, d);
            assert_eq!(got.map(|h| (h.t, h.triangle)), want, "ray {o} {d}");
            assert_eq!(bvh.occluded(o, d, f32::INFINITY), want.is_some());
            hits += usize::from(want.is_some());
        }
        assert!(hits > 1000, "the test must exercise hits ({hits})");
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
