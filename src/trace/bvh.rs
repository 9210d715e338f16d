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
//! and traversal of the Tray Racing benchmark that `obvhs` was built for. The CPU twin walks
//! the same tree from its own copy of the nodes ([`CpuNode`]: each child box decoded to f32,
//! rounded outwards, and each child's index or leaf primitives ready), visits a node's inner
//! children by entry distance and skips those entered beyond the closest hit so far
//! ([`SceneBvh::closest_hit`]): the same hits, fewer nodes, and on a CPU the culling pays for
//! the sort (BENCHMARKS.md).
//!
//! Primitives are stored in BVH order (`prims`, three `vec4<f32>` each: `v0` and the original
//! triangle index, `e1 = v1 − v0` and the light-selection density, `e2 = v2 − v0` and the
//! primitive's flags as a small float — [`PRIM_CULL`] for a single-sided triangle, whose back
//! face rays pass through, plus [`PRIM_ALPHA`] for one whose material is alpha-masked or
//! blended, where the caller decides per hit whether the surface is there), so a leaf's
//! triangles are contiguous in memory.

use std::mem::MaybeUninit;
use std::time::Duration;

use crate::trace::lanes::V3;
use glam::Vec3;
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, node::CwBvhNode},
    triangle::Triangle as ObvhsTriangle,
};
use wide::{f32x8, u32x8};

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
    /// `cwbvh.nodes` as the CPU traverses them.
    nodes: Vec<CpuNode>,
    /// The most entries a traversal's stack can hold: 7 per level below the root (the
    /// siblings of the child taken), plus one node's 8.
    stack_size: usize,
}

/// The BVH primitives' triangles as ten arrays (v0, e1, e2 by component, then 1.0 for a
/// single-sided one), each padded by `LANE_PAD` zeros, so that the triangles of a node's
/// leaves — contiguous, at most 24 from the node's first primitive — load as 8-wide lanes.
/// `triangle`: each primitive's original triangle. `alpha`: whether any primitive is
/// alpha-tested (then the per-triangle test runs, since coverage is decided per hit).
#[derive(Clone, Debug, Default)]
pub struct PrimLanes {
    stride: usize,
    data: Vec<f32>,
    triangle: Vec<u32>,
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
            triangle: (0..n).map(|i| prims[3 * i][3].to_bits()).collect(),
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

/// A node as the CPU traverses it: one CWBVH node (the same tree, the same children) with its
/// eight child boxes decoded to f32, so that the box test is a subtraction and a product per
/// plane instead of a byte-to-float conversion, a product and a sum, and with each child's
/// node index or leaf primitives ready (the CWBVH finds them from its metadata bytes). 256
/// bytes, four cache lines, against the quantised node's 80: measured faster all the same
/// (BENCHMARKS.md, the CPU twin's traversal). The decoded boxes are rounded outwards, so each
/// contains the quantised box it comes from and with it everything below that child.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug)]
pub struct CpuNode {
    /// The child boxes, a lane per child slot: min x, max x, min y, max y, min z, max z. An
    /// empty slot's box is empty (min +∞, max −∞): no ray enters it.
    bounds: [[f32; 8]; 6],
    /// Per child slot: an inner child's node index; a leaf's primitives as bits of offsets
    /// from `prim_base` (its unary count shifted to its first primitive's offset); 0 for an
    /// empty slot.
    child: [u32; 8],
    /// Bit c: slot c holds an inner node.
    imask: u32,
    /// The first primitive of the node's leaves.
    prim_base: u32,
}

/// `x` rounded to an f32 no greater (`down`) or no smaller than it.
fn f32_outward(x: f64, down: bool) -> f32 {
    let f = x as f32;
    match (down, f64::from(f).partial_cmp(&x)) {
        (true, Some(std::cmp::Ordering::Greater)) => f.next_down(),
        (false, Some(std::cmp::Ordering::Less)) => f.next_up(),
        _ => f,
    }
}

impl CpuNode {
    /// `node` decoded: each child box `p + q · 2^e` per plane, computed exactly in f64 and
    /// rounded outwards to f32.
    fn decode(node: &CwBvhNode) -> Self {
        let extent = node.compute_extent();
        let mut out = Self {
            bounds: [[0.0; 8]; 6],
            child: [0; 8],
            imask: u32::from(node.imask),
            prim_base: node.primitive_base_idx,
        };
        for c in 0..8 {
            let meta = u32::from(node.child_meta[c]);
            let inner = node.imask & (1 << c) != 0;
            if !inner && meta == 0 {
                for axis in 0..3 {
                    out.bounds[2 * axis][c] = f32::INFINITY;
                    out.bounds[2 * axis + 1][c] = f32::NEG_INFINITY;
                }
                continue;
            }
            let planes = [
                (node.child_min_x[c], node.child_max_x[c]),
                (node.child_min_y[c], node.child_max_y[c]),
                (node.child_min_z[c], node.child_max_z[c]),
            ];
            for (axis, (lo, hi)) in planes.into_iter().enumerate() {
                let (p, e) = (f64::from(node.p[axis]), f64::from(extent[axis]));
                out.bounds[2 * axis][c] = f32_outward(p + f64::from(lo) * e, true);
                out.bounds[2 * axis + 1][c] = f32_outward(p + f64::from(hi) * e, false);
            }
            out.child[c] = if inner {
                node.child_node_index(c)
            } else {
                (meta >> 5) << (meta & 0b11111)
            };
        }
        out
    }
}

/// What the box test needs of a ray, computed once per ray: obvhs' guarded reciprocal of the
/// direction (the GPU's `safe_inverse`), the origin times it, and per axis which plane of a
/// box the ray meets first (the near plane is the maximum for a negative direction).
#[derive(Clone, Copy, Debug)]
struct NodeRay {
    inv: [f32; 3],
    origin_inv: [f32; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl NodeRay {
    #[inline(always)]
    fn new(origin: Vec3, dir: Vec3) -> Self {
        let inv = [
            obvhs::ray::safe_inverse(dir.x),
            obvhs::ray::safe_inverse(dir.y),
            obvhs::ray::safe_inverse(dir.z),
        ];
        let negative = inv.map(|i| usize::from(i < 0.0));
        Self {
            inv,
            origin_inv: [origin.x * inv[0], origin.y * inv[1], origin.z * inv[2]],
            near: [negative[0], 2 + negative[1], 4 + negative[2]],
            far: [1 - negative[0], 3 - negative[1], 5 - negative[2]],
        }
    }
}

/// The slab test of `node`'s eight child boxes: bit c of the mask is set when child slot c's
/// box is entered (at `t = plane · inv − origin · inv` on each axis) at or before `tmax` and
/// its far side is not nearer than [`NODE_EPSILON`] (the GPU's near-plane bound); entry c is
/// that box's entry distance. All eight children in one pass of 8-wide AVX2 lanes; the same
/// operations as [`node_hits_scalar`] lane by lane, so the same bits.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
#[inline(always)]
fn node_hits(node: &CpuNode, ray: &NodeRay, tmax: f32) -> (u32, [f32; 8]) {
    use std::arch::x86_64::{
        _CMP_LE_OQ, _mm256_cmp_ps, _mm256_load_ps, _mm256_max_ps, _mm256_min_ps,
        _mm256_movemask_ps, _mm256_mul_ps, _mm256_set1_ps, _mm256_storeu_ps, _mm256_sub_ps,
    };
    let mut entry = [0f32; 8];
    // SAFETY: this is compiled only where AVX and AVX2 are enabled for the whole build
    // (.cargo/config.toml; the `cfg` above), so every intrinsic here is available. The loads
    // read one `[f32; 8]` row of `bounds` each (`CpuNode` is 64-byte aligned and its rows
    // start at multiples of 32 bytes, as `_mm256_load_ps` needs; `near`/`far` index rows
    // 0..6 by construction in `NodeRay::new`); the store writes the local `[f32; 8]`.
    let hit = unsafe {
        let t = |row: usize, axis: usize| {
            _mm256_sub_ps(
                _mm256_mul_ps(
                    _mm256_load_ps(node.bounds[row].as_ptr()),
                    _mm256_set1_ps(ray.inv[axis]),
                ),
                _mm256_set1_ps(ray.origin_inv[axis]),
            )
        };
        let t_near = _mm256_max_ps(
            _mm256_max_ps(t(ray.near[0], 0), t(ray.near[1], 1)),
            _mm256_max_ps(t(ray.near[2], 2), _mm256_set1_ps(NODE_EPSILON)),
        );
        let t_far = _mm256_min_ps(
            _mm256_min_ps(t(ray.far[0], 0), t(ray.far[1], 1)),
            _mm256_min_ps(t(ray.far[2], 2), _mm256_set1_ps(tmax)),
        );
        _mm256_storeu_ps(entry.as_mut_ptr(), t_near);
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, t_far)) as u32
    };
    (hit, entry)
}

/// Without AVX2: [`node_hits_scalar`].
#[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
#[inline(always)]
fn node_hits(node: &CpuNode, ray: &NodeRay, tmax: f32) -> (u32, [f32; 8]) {
    node_hits_scalar(node, ray, tmax)
}

/// [`node_hits`] a child at a time (`maxps`/`minps` semantics: the second operand unless the
/// first is greater / smaller): the build without AVX2, and the lanes' oracle.
#[cfg_attr(all(target_arch = "x86_64", target_feature = "avx2"), allow(dead_code))]
#[inline(always)]
fn node_hits_scalar(node: &CpuNode, ray: &NodeRay, tmax: f32) -> (u32, [f32; 8]) {
    let max = |a: f32, b: f32| if a > b { a } else { b };
    let min = |a: f32, b: f32| if a < b { a } else { b };
    let mut entry = [0f32; 8];
    let mut hit = 0;
    for (c, entry) in entry.iter_mut().enumerate() {
        let t =
            |row: usize, axis: usize| node.bounds[row][c] * ray.inv[axis] - ray.origin_inv[axis];
        let t_near = max(
            max(t(ray.near[0], 0), t(ray.near[1], 1)),
            max(t(ray.near[2], 2), NODE_EPSILON),
        );
        let t_far = min(
            min(t(ray.far[0], 0), t(ray.far[1], 1)),
            min(t(ray.far[2], 2), tmax),
        );
        *entry = t_near;
        if t_near <= t_far {
            hit |= 1 << c;
        }
    }
    (hit, entry)
}

/// The primitives of `node`'s leaf children in `leaves` (a mask of child slots), as bits of
/// offsets from `node.prim_base`: the OR of those slots' `child` words.
#[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
#[inline(always)]
fn leaf_bits(node: &CpuNode, leaves: u32) -> u32 {
    use std::arch::x86_64::{
        _mm_cvtsi128_si32, _mm_or_si128, _mm_shuffle_epi32, _mm256_and_si256,
        _mm256_castsi256_si128, _mm256_cmpeq_epi32, _mm256_extracti128_si256, _mm256_loadu_si256,
        _mm256_set1_epi32, _mm256_setr_epi32,
    };
    // SAFETY: AVX2 is enabled for the whole build (the `cfg`); the one load reads the eight
    // `u32` of `node.child` (unaligned loads are allowed). Eight lanes at once: a loop over
    // the set bits mispredicted its exit on most nodes (BENCHMARKS.md).
    unsafe {
        let slot = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let wanted = _mm256_cmpeq_epi32(
            _mm256_and_si256(_mm256_set1_epi32(leaves as i32), slot),
            slot,
        );
        let words = _mm256_and_si256(_mm256_loadu_si256(node.child.as_ptr().cast()), wanted);
        let x = _mm_or_si128(
            _mm256_castsi256_si128(words),
            _mm256_extracti128_si256::<1>(words),
        );
        let x = _mm_or_si128(x, _mm_shuffle_epi32::<0b01_00_11_10>(x));
        let x = _mm_or_si128(x, _mm_shuffle_epi32::<0b10_11_00_01>(x));
        _mm_cvtsi128_si32(x) as u32
    }
}

/// Without AVX2: the same OR a slot at a time.
#[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
#[inline(always)]
fn leaf_bits(node: &CpuNode, leaves: u32) -> u32 {
    (0..8)
        .filter(|c| leaves & (1 << c) != 0)
        .fold(0, |bits, c| bits | node.child[c])
}

/// The slots of `mask` whose entry distance is at most `tmax`.
#[inline(always)]
fn entered_by(mut mask: u32, entry: &[f32; 8], tmax: f32) -> u32 {
    let mut out = mask;
    while mask != 0 {
        let c = mask.trailing_zeros();
        mask &= mask - 1;
        if !(entry[c as usize] <= tmax) {
            out &= !(1 << c);
        }
    }
    out
}

/// A traversal stack entry: a node's entry distance (a positive f32, so its bits order as the
/// distances do) above its index.
#[inline(always)]
fn stack_entry(t_near: f32, node: u32) -> u64 {
    (u64::from(t_near.to_bits()) << 32) | u64::from(node)
}

/// The entries a traversal stack holds on a thread's own stack; deeper trees (more than 17
/// levels) allocate theirs.
const INLINE_STACK: usize = 128;

/// `f` with a traversal stack of at least `size` entries, uninitialised: the traversals write
/// an entry before they read it.
#[inline(always)]
fn with_stack<R>(size: usize, f: impl FnOnce(&mut [MaybeUninit<u64>]) -> R) -> R {
    if size <= INLINE_STACK {
        f(&mut [MaybeUninit::uninit(); INLINE_STACK])
    } else {
        f(&mut vec![MaybeUninit::uninit(); size])
    }
}

/// `entries` as the values they hold.
///
/// # Safety
/// Every entry must have been written.
#[inline(always)]
unsafe fn written(entries: &mut [MaybeUninit<u64>]) -> &mut [u64] {
    // SAFETY: `MaybeUninit<u64>` has the layout of `u64`, and the caller promises that each
    // entry is initialised.
    unsafe { &mut *(std::ptr::from_mut(entries) as *mut [u64]) }
}

/// Sorts `entries` by distance, the farthest first (so the nearest is popped first): an
/// insertion sort, for the three to eight children a node adds.
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

    /// The primitives `first + k` for the set bits k of `bits` (a node's leaf triangles) hit
    /// with `0 < t < tmax`, each kept in `best` (t, u, v, primitive) where [`nearer`] says so.
    /// Whether `best` changed.
    #[inline(always)]
    fn closest(
        &self,
        first: u32,
        bits: u32,
        o: Vec3,
        d: Vec3,
        tmax: f32,
        best: &mut Option<(f32, f32, f32, u32)>,
    ) -> bool {
        let mut changed = false;
        for chunk in 0..3 {
            let want = (bits >> (8 * chunk)) & 0xff;
            if want == 0 {
                continue;
            }
            let base = first as usize + 8 * chunk;
            let (hit, t, u, v) = self.test8(base, o, d, bound(tmax, best));
            let mut m = hit & want;
            while m != 0 {
                let k = m.trailing_zeros() as usize;
                m &= m - 1;
                let i = (base + k) as u32;
                if nearer(t[k], i, best, |p| self.triangle[p as usize]) {
                    *best = Some((t[k], u[k], v[k], i));
                    changed = true;
                }
            }
        }
        changed
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

/// Whether a hit at `t` on primitive `prim` is the closer one than `best`: nearer, or as near
/// on a higher triangle (`triangle` gives a primitive's; spatial splits make several
/// primitives of one triangle, whose hits are the same hit). The rule picks the same hit
/// whatever order a traversal meets the candidates in, so that the one-ray and the eight-ray
/// traversals agree to the bit.
#[inline(always)]
fn nearer(
    t: f32,
    prim: u32,
    best: &Option<(f32, f32, f32, u32)>,
    triangle: impl Fn(u32) -> u32,
) -> bool {
    best.is_none_or(|b| t < b.0 || (t == b.0 && triangle(prim) > triangle(b.3)))
}

/// The bound a triangle test needs for a hit to be [`nearer`] than `best` within the ray's
/// `tmax`: `best`'s t itself included (the tests keep `t < bound`).
#[inline(always)]
fn bound(tmax: f32, best: &Option<(f32, f32, f32, u32)>) -> f32 {
    best.map_or(tmax, |b| b.0.next_up().min(tmax))
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
                nodes: Vec::new(),
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
        let nodes = cwbvh.nodes.iter().map(CpuNode::decode).collect();
        Self {
            cwbvh,
            prims,
            lanes,
            nodes,
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

    /// The closest hit along `origin + t·dir`, `0 < t < tmax`.
    #[must_use]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<TraceHit> {
        self.closest_hit_filtered(origin, dir, tmax, |_, _, _| true)
    }

    /// [`Self::closest_hit`] where a hit on an alpha-tested primitive ([`PRIM_ALPHA`]) counts
    /// only if `covered(triangle, u, v)` (the CPU twin of `alpha_covered` in path.wgsl).
    ///
    /// The tree is the GPU's; the traversal is the CPU's own ([`CpuNode`]): a node's leaf
    /// triangles first, then its inner children nearest entry first — one child is entered
    /// directly and of two the farther is pushed, without a sort — and a node entered beyond
    /// the closest hit so far is skipped (the GPU's kernel keeps obvhs' order by ray octant,
    /// which suits a GPU's lock-step lanes). The hit is the same — the nearest one, with the
    /// same triangle arithmetic, in boxes that contain the GPU's — except where two triangles
    /// are hit at exactly the same distance (a shared edge): here the higher triangle wins
    /// (`nearer`, whatever the order of the walk), on the GPU whichever its walk meets
    /// first; and where the two box tests round differently for a ray that grazes a box's face.
    #[must_use]
    pub fn closest_hit_filtered(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: impl Fn(u32, f32, f32) -> bool,
    ) -> Option<TraceHit> {
        if self.nodes.is_empty() {
            return None;
        }
        let ray = NodeRay::new(origin, dir);
        let ray_tmax = tmax;
        // The nodes' bound: the closest hit's t once there is one (a node entered exactly there
        // is still visited: it may hold an equally near hit on a higher primitive).
        let mut tmax = tmax;
        let mut best: Option<(f32, f32, f32, u32)> = None;
        with_stack(self.stack_size, |stack| {
            let (mut index, mut len) = (0, 0);
            loop {
                let node = &self.nodes[index];
                let (hit, entry) = node_hits(node, &ray, tmax);
                let leaves = hit & !node.imask;
                let mut inner = hit & node.imask;
                if leaves != 0 {
                    let bits = leaf_bits(node, leaves);
                    if bits != 0
                        && self.leaf_closest(
                            node.prim_base,
                            bits,
                            origin,
                            dir,
                            ray_tmax,
                            &mut best,
                            &covered,
                        )
                        && let Some(b) = best
                    {
                        tmax = b.0;
                        inner = entered_by(inner, &entry, tmax);
                    }
                }
                match inner.count_ones() {
                    0 => {}
                    1 => {
                        index = node.child[inner.trailing_zeros() as usize] as usize;
                        continue;
                    }
                    2 => {
                        let a = inner.trailing_zeros() as usize;
                        let b = (inner & (inner - 1)).trailing_zeros() as usize;
                        let (near, far) = if entry[b] < entry[a] { (b, a) } else { (a, b) };
                        stack[len].write(stack_entry(entry[far], node.child[far]));
                        len += 1;
                        index = node.child[near] as usize;
                        continue;
                    }
                    _ => {
                        let first = len;
                        while inner != 0 {
                            let c = inner.trailing_zeros() as usize;
                            inner &= inner - 1;
                            stack[len].write(stack_entry(entry[c], node.child[c]));
                            len += 1;
                        }
                        // The nearest on top. SAFETY: entries first..len were written just above.
                        sort_farthest_first(unsafe { written(&mut stack[first..len]) });
                    }
                }
                loop {
                    if len == 0 {
                        return;
                    }
                    len -= 1;
                    // SAFETY: every entry below `len` was written by a push.
                    let e = unsafe { stack[len].assume_init() };
                    if f32::from_bits((e >> 32) as u32) <= tmax {
                        index = e as u32 as usize;
                        break;
                    }
                }
            }
        });
        best.map(|(t, u, v, i)| TraceHit {
            t,
            u,
            v,
            triangle: self.prim_triangle(i),
            prim: i,
        })
    }

    /// The closest hits of eight rays at once (`0 < t < ∞`), for the lanes set in `active`
    /// (the others get `None`): [`Self::closest_hit`]'s hits to the bit, for rays that travel
    /// together — a camera's rays through neighbouring pixels. The rays share the walk: a node
    /// is visited once for the rays that enter it, its eight boxes tested against all of them
    /// in lanes (a ray per lane), a leaf's triangles likewise (the same Möller–Trumbore
    /// arithmetic per lane as the one-ray test), and a child is taken for the rays that enter
    /// its box, nearest first by its first ray's entry. One decision per node for eight rays
    /// instead of eight: measured faster for camera rays, and slower for rays that scatter
    /// (BENCHMARKS.md). Scenes with alpha-tested triangles take [`Self::closest_hit`] per ray.
    #[must_use]
    pub fn closest_hits8(
        &self,
        origins: &[Vec3; 8],
        dirs: &[Vec3; 8],
        active: u32,
    ) -> [Option<TraceHit>; 8] {
        let mut out = [None; 8];
        if self.nodes.is_empty() || active & 0xff == 0 {
            return out;
        }
        if self.lanes.alpha {
            for i in (0..8).filter(|i| active & (1 << i) != 0) {
                out[i] = self.closest_hit(origins[i], dirs[i], f32::INFINITY);
            }
            return out;
        }
        let o = V3::from_lanes(origins);
        let d = V3::from_lanes(dirs);
        let inv = V3::from_lanes(&dirs.map(|d| {
            Vec3::new(
                obvhs::ray::safe_inverse(d.x),
                obvhs::ray::safe_inverse(d.y),
                obvhs::ray::safe_inverse(d.z),
            )
        }));
        let oi = o * inv;
        let lane_bits = u32x8::from([1, 2, 4, 8, 16, 32, 64, 128]);
        let lanes_of = |mask: u32| -> f32x8 {
            bytemuck::cast((u32x8::splat(mask) & lane_bits).simd_eq(lane_bits))
        };
        let on = lanes_of(active);
        // Each lane's closest hit so far: t (the nodes' bound: −∞ keeps a lane that does not
        // trace out of every box), u, v, the primitive (u32::MAX: none yet) and its triangle.
        let mut best_t = on.select(f32x8::INFINITY, f32x8::NEG_INFINITY);
        let (mut best_u, mut best_v) = (f32x8::ZERO, f32x8::ZERO);
        let mut best_prim = u32x8::splat(u32::MAX);
        let mut best_tri = u32x8::ZERO;
        let eps = f32x8::splat(NODE_EPSILON);
        with_stack(self.stack_size, |stack| {
            stack[0].write(u64::from(active & 0xff) << 32);
            let mut len = 1;
            while len > 0 {
                len -= 1;
                // SAFETY: every entry below `len` was written by a push.
                let e = unsafe { stack[len].assume_init() };
                let (node, rays) = (&self.nodes[e as u32 as usize], (e >> 32) as u32);
                let mut children = [(0f32, 0u32, 0u32); 8];
                let mut n_inner = 0;
                for c in 0..8 {
                    let inner = node.imask & (1 << c) != 0;
                    if !inner && node.child[c] == 0 {
                        continue;
                    }
                    let t = |row: usize, axis: usize, inv: f32x8, oi: f32x8| {
                        f32x8::splat(node.bounds[2 * axis + row][c]) * inv - oi
                    };
                    let (x0, x1) = (t(0, 0, inv.x, oi.x), t(1, 0, inv.x, oi.x));
                    let (y0, y1) = (t(0, 1, inv.y, oi.y), t(1, 1, inv.y, oi.y));
                    let (z0, z1) = (t(0, 2, inv.z, oi.z), t(1, 2, inv.z, oi.z));
                    let t_near = x0
                        .fast_min(x1)
                        .fast_max(y0.fast_min(y1))
                        .fast_max(z0.fast_min(z1).fast_max(eps));
                    let t_far = x0
                        .fast_max(x1)
                        .fast_min(y0.fast_max(y1))
                        .fast_min(z0.fast_max(z1).fast_min(best_t));
                    let hit = t_near.simd_le(t_far).to_bitmask() & rays;
                    if hit == 0 {
                        continue;
                    }
                    if inner {
                        let entry = t_near.to_array()[hit.trailing_zeros() as usize];
                        children[n_inner] = (entry, node.child[c], hit);
                        n_inner += 1;
                        continue;
                    }
                    // The leaf's triangles against its rays.
                    let want = lanes_of(hit);
                    let mut bits = node.child[c];
                    while bits != 0 {
                        let prim = node.prim_base + bits.trailing_zeros();
                        bits &= bits - 1;
                        let found_u = best_prim.simd_ne(u32x8::splat(u32::MAX));
                        let found: f32x8 = bytemuck::cast(found_u);
                        let next_up: f32x8 =
                            bytemuck::cast(bytemuck::cast::<_, u32x8>(best_t) + u32x8::ONE);
                        let bound = found.select(next_up, f32x8::INFINITY);
                        let (h, t, u, v) = self.test_rays(prim as usize, o, d, bound);
                        let p = u32x8::splat(prim);
                        let tri = u32x8::splat(self.lanes.triangle[prim as usize]);
                        let tie: f32x8 = bytemuck::cast(tri.simd_gt(best_tri) | !found_u);
                        let take = want & h & (t.simd_lt(best_t) | (t.simd_eq(best_t) & tie));
                        if take.any() {
                            best_t = take.select(t, best_t);
                            best_u = take.select(u, best_u);
                            best_v = take.select(v, best_v);
                            let take: u32x8 = bytemuck::cast(take);
                            best_prim = take.select(p, best_prim);
                            best_tri = take.select(tri, best_tri);
                        }
                    }
                }
                // The inner children, the nearest on top.
                let children = &mut children[..n_inner];
                children.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
                for &(_, index, rays) in children.iter() {
                    stack[len].write((u64::from(rays) << 32) | u64::from(index));
                    len += 1;
                }
            }
        });
        let (t, u, v, prim) = (
            best_t.to_array(),
            best_u.to_array(),
            best_v.to_array(),
            best_prim.to_array(),
        );
        for i in 0..8 {
            if active & (1 << i) != 0 && prim[i] != u32::MAX {
                out[i] = Some(TraceHit {
                    t: t[i],
                    u: u[i],
                    v: v[i],
                    triangle: self.prim_triangle(prim[i]),
                    prim: prim[i],
                });
            }
        }
        out
    }

    /// BVH primitive `prim` against eight rays in lanes, [`intersect_triangle_sided`] per lane
    /// (the same operations, so the same t, u, v): the lanes hit with `0 < t < tmax`, and t,
    /// u, v.
    #[inline(always)]
    fn test_rays(&self, prim: usize, o: V3, d: V3, tmax: f32x8) -> (f32x8, f32x8, f32x8, f32x8) {
        let (v0, e1, e2) = self.prim(prim);
        let cull = self.flags(prim) & PRIM_CULL != 0;
        let (e1, e2) = (V3::splat(e1), V3::splat(e2));
        let pv = d.cross(e2);
        let det = e1.dot(pv);
        let zero = f32x8::ZERO;
        let mut ok = det.simd_ne(zero) & det.is_finite();
        if cull {
            ok &= !det.simd_lt(zero);
        }
        let inv_det = f32x8::ONE / det;
        let tv = o - V3::splat(v0);
        let u = tv.dot(pv) * inv_det;
        let qv = tv.cross(e1);
        let v = d.dot(qv) * inv_det;
        let t = e2.dot(qv) * inv_det;
        let inside = u.simd_ge(zero)
            & v.simd_ge(zero)
            & (u + v).simd_le(f32x8::ONE)
            & t.simd_gt(zero)
            & t.simd_lt(tmax);
        (ok & inside, t, u, v)
    }

    /// Whether anything blocks `origin + t·dir` for `0 < t < tmax` (shadow rays).
    #[must_use]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.occluded_filtered(origin, dir, tmax, |_, _, _| true)
    }

    /// [`Self::occluded`] with the coverage test of [`Self::closest_hit_filtered`]. Any hit
    /// ends the search, so the children are not ordered: the first is entered directly, the
    /// others pushed.
    #[must_use]
    pub fn occluded_filtered(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let ray = NodeRay::new(origin, dir);
        with_stack(self.stack_size, |stack| {
            let (mut index, mut len) = (0, 0);
            loop {
                let node = &self.nodes[index];
                let (hit, _) = node_hits(node, &ray, tmax);
                let leaves = hit & !node.imask;
                if leaves != 0 {
                    let bits = leaf_bits(node, leaves);
                    if bits != 0 && self.leaf_any(node.prim_base, bits, origin, dir, tmax, &covered)
                    {
                        return true;
                    }
                }
                let mut inner = hit & node.imask;
                if inner != 0 {
                    index = node.child[inner.trailing_zeros() as usize] as usize;
                    inner &= inner - 1;
                    while inner != 0 {
                        let c = inner.trailing_zeros() as usize;
                        inner &= inner - 1;
                        stack[len].write(u64::from(node.child[c]));
                        len += 1;
                    }
                    continue;
                }
                if len == 0 {
                    return false;
                }
                len -= 1;
                // SAFETY: every entry below `len` was written by a push.
                index = unsafe { stack[len].assume_init() } as usize;
            }
        })
    }

    /// [`PrimLanes::closest`] with alpha-tested primitives asked `covered`, one at a time.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn leaf_closest(
        &self,
        first: u32,
        bits: u32,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        best: &mut Option<(f32, f32, f32, u32)>,
        covered: &impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
        if !self.lanes.alpha {
            return self.lanes.closest(first, bits, origin, dir, tmax, best);
        }
        let (mut changed, mut m) = (false, bits);
        while m != 0 {
            let k = m.trailing_zeros();
            m &= m - 1;
            let i = first + k;
            if let Some((t, u, v)) =
                self.test_prim(i as usize, origin, dir, bound(tmax, best), covered)
                && nearer(t, i, best, |p| self.prim_triangle(p))
            {
                *best = Some((t, u, v, i));
                changed = true;
            }
        }
        changed
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
    fn node_hits_lanes_equal_the_scalar_test() {
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
            let ray = NodeRay::new(o, d);
            for node in &bvh.nodes {
                let (lanes, scalar) = (
                    node_hits(node, &ray, tmax),
                    node_hits_scalar(node, &ray, tmax),
                );
                assert_eq!(lanes.0, scalar.0, "hit masks, ray {o} {d}");
                assert_eq!(lanes.1.map(f32::to_bits), scalar.1.map(f32::to_bits));
                hits += lanes.0.count_ones();
            }
        }
        assert!(hits > 10_000, "the rays must enter boxes ({hits})");
    }

    /// Every decoded child box contains its quantised box exactly (compared in f64), which
    /// contains what is below it (obvhs' quantisation rounds outwards; with spatial splits a
    /// leaf's box bounds only its part of a triangle, so the triangles themselves are not the
    /// test); an empty slot is entered by no ray; and each slot's word is the CWBVH's child
    /// index or leaf primitives.
    #[test]
    fn decoded_nodes_contain_the_quantised_boxes() {
        let tris = random_triangles(3000, 11);
        let bvh = SceneBvh::build(&tris, &vec![0.0; tris.len()]);
        let (mut slots, mut leaf_prims) = (0, 0);
        for (index, (q, node)) in bvh.cwbvh.nodes.iter().zip(&bvh.nodes).enumerate() {
            assert_eq!(node.imask, u32::from(q.imask));
            assert_eq!(node.prim_base, q.primitive_base_idx);
            let extent = q.compute_extent();
            for c in 0..8 {
                let inner = q.imask & (1 << c) != 0;
                if !inner && q.child_meta[c] == 0 {
                    let ray = NodeRay::new(Vec3::ZERO, Vec3::ONE.normalize());
                    assert_eq!(node_hits(node, &ray, f32::INFINITY).0 & (1 << c), 0);
                    assert_eq!(node.child[c], 0, "empty slot {c} of node {index}");
                    continue;
                }
                let quantised = [
                    (q.child_min_x[c], q.child_max_x[c]),
                    (q.child_min_y[c], q.child_max_y[c]),
                    (q.child_min_z[c], q.child_max_z[c]),
                ];
                for (axis, (lo, hi)) in quantised.into_iter().enumerate() {
                    let (p, e) = (f64::from(q.p[axis]), f64::from(extent[axis]));
                    assert!(f64::from(node.bounds[2 * axis][c]) <= p + f64::from(lo) * e);
                    assert!(f64::from(node.bounds[2 * axis + 1][c]) >= p + f64::from(hi) * e);
                }
                if inner {
                    assert_eq!(node.child[c], q.child_node_index(c));
                } else {
                    let meta = u32::from(q.child_meta[c]);
                    assert_eq!(node.child[c], (meta >> 5) << (meta & 31));
                    leaf_prims += node.child[c].count_ones();
                }
                slots += 1;
            }
        }
        assert!(
            slots > 100 && leaf_prims as usize >= tris.len(),
            "{slots} slots, {leaf_prims} leaf primitives"
        );
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

    /// Eight rays at once give each ray's own closest hit to the bit (t, u, v, primitive):
    /// rays from one point through a small window (a camera's), rays from everywhere, lanes
    /// switched off; and triangles given twice (every hit on them an exact tie) resolve the
    /// same way in both walks — the higher primitive.
    #[test]
    fn eight_rays_at_once_find_each_rays_hit() {
        let mut tris = random_triangles(1500, 3);
        tris.extend_from_within(..300);
        let bvh = SceneBvh::build(&tris, &vec![0.0; tris.len()]);
        let mut r = uniforms(17);
        let (mut hits, mut ties) = (0, 0);
        for round in 0..1200 {
            let eye = Vec3::new(r(), r(), r()) * 14.0 - 7.0;
            let centre = (Vec3::new(r(), r(), r()) - 0.5).normalize();
            let spread = if round % 2 == 0 { 0.02 } else { 2.0 };
            let origins: [Vec3; 8] = std::array::from_fn(|_| {
                if round % 3 == 2 {
                    Vec3::new(r(), r(), r()) * 14.0 - 7.0
                } else {
                    eye
                }
            });
            let dirs: [Vec3; 8] = std::array::from_fn(|_| {
                (centre + (Vec3::new(r(), r(), r()) - 0.5) * spread).normalize()
            });
            let active = if round % 5 == 0 { 0b1011_0110 } else { 0xff };
            let got = bvh.closest_hits8(&origins, &dirs, active);
            for i in 0..8 {
                let want = if active & (1 << i) != 0 {
                    bvh.closest_hit(origins[i], dirs[i], f32::INFINITY)
                } else {
                    None
                };
                // The primitive may be another reference of the same triangle (spatial splits).
                let bits = |h: Option<TraceHit>| {
                    h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.triangle))
                };
                assert_eq!(bits(got[i]), bits(want), "round {round} lane {i}");
                if let Some(h) = want {
                    hits += 1;
                    if h.triangle < 300 || h.triangle >= 1500 {
                        ties += 1;
                        // The twin of a duplicated triangle is hit at the same t; the higher
                        // triangle of the two is the one reported.
                        assert!(
                            h.triangle >= 1500,
                            "round {round} lane {i}: tie went to the lower triangle"
                        );
                    }
                }
            }
        }
        assert!(hits > 1000 && ties > 150, "{hits} hits, {ties} ties");
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
