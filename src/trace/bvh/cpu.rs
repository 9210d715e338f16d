//! The CPU's own tree over the scene's triangles, and its walks: closest hits one ray at a time
//! and eight at once, shadow rays.
//!
//! The GPU walks obvhs' compressed CWBVH (`super`'s doc): 80-byte nodes of quantised boxes and
//! at most three triangles a leaf, the layout that suits a GPU's memory traffic. The CPU walks a
//! tree built for it from the same triangles ([`CpuTree`]): obvhs' BVH2 (the same `slow_build`
//! preset: spatial pre-splits, PLOC, reinsertion) of one triangle a leaf, collapsed into
//! eight-wide nodes and leaves of up to eight triangles by the collapse of least surface-area
//! cost ([`Collapse`](build::Collapse); it replaced taking apart the largest child until eight
//! over obvhs' own leaves: the small city's ms per sample ×0.935–0.95,
//! BENCHMARKS.md, *CPU traversal*), each node's boxes as f32 in lanes (building it: `build.rs`). A leaf's
//! triangles are contiguous in the tree's own arrays (`prims`, and [`PrimLanes`] for the 8-wide test), so a leaf of up to
//! eight is one test. Measured against walking the GPU's tree with the same code: 15–20 %
//! fewer nanoseconds a ray in the cities (BENCHMARKS.md, *CPU traversal*).
//!
//! The hit is the GPU tree's: the same triangles, the same triangle arithmetic, the nearest
//! hit, and exact ties resolved by a rule that does not depend on the walk ([`nearer`]). The
//! boxes are widened by a few units in the last place of the scene's coordinates, so that the
//! rounding of a box test cannot drop a hit that the triangle test finds.

use std::mem::MaybeUninit;

use glam::Vec3;
use wide::{f32x8, u32x8};

use super::{CpuPackets, NODE_EPSILON, PRIM_ALPHA, PRIM_CULL, TraceHit, intersect_triangle_sided};
use crate::trace::lanes::V3x8;

mod build;
#[cfg(target_arch = "x86_64")]
mod hybrid;
mod packets;

/// The CPU's tree ([`CpuNode`]s, the root first) and its primitives in leaf order.
#[derive(Clone, Debug, Default)]
pub(super) struct CpuTree {
    nodes: Vec<CpuNode>,
    /// Three entries per primitive, as the GPU's `prims`: `[v0, triangle]`, `[e1, light
    /// density]`, `[e2, flags]`.
    pub(super) prims: Vec<[f32; 4]>,
    lanes: PrimLanes,
    /// The most entries a traversal's stack can hold: 7 per level below the root (the
    /// siblings of the child taken), plus one node's 8.
    stack_size: usize,
}

/// A node of the CPU's tree: eight child boxes as f32 lanes and what each child is.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug)]
pub(super) struct CpuNode {
    /// The child boxes, a lane per child slot: min x, max x, min y, max y, min z, max z. An
    /// empty slot's box is empty (min +∞, max −∞): no ray enters it.
    bounds: [[f32; 8]; 6],
    /// Per child slot: an inner child's node index, a leaf's first primitive.
    child: [u32; 8],
    /// Per child slot: a leaf's primitive count (1 to 255); 0 for an inner child or an empty
    /// slot.
    count: [u8; 8],
    /// Bit c: slot c holds an inner node.
    imask: u32,
}

impl CpuTree {
    /// Primitive `i`'s flags ([`PRIM_CULL`], [`PRIM_ALPHA`]).
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

    /// The original triangle of primitive `i`.
    #[inline]
    pub(super) fn triangle(&self, i: u32) -> u32 {
        self.prims[3 * i as usize][3].to_bits()
    }
}

/// The tree's triangles as [`ARRAYS`] arrays — v0, e1, e2 by component, 1.0 for a
/// single-sided one, and the normal `e1 × e2` by component (glam's cross, as the scalar test
/// computes it) — each padded by `LANE_PAD` zeros, so that a leaf's triangles load as 8-wide
/// lanes; `triangle`: each primitive's original triangle; `alpha`: whether any primitive is
/// alpha-tested (then the per-triangle test runs, since coverage is decided per hit).
#[derive(Clone, Debug, Default)]
struct PrimLanes {
    stride: usize,
    data: Vec<f32>,
    triangle: Vec<u32>,
    alpha: bool,
}

/// The arrays of [`PrimLanes`].
const ARRAYS: usize = 13;

/// Zeros after each array of [`PrimLanes`]: the lanes of a leaf's last eight may run past the
/// last primitive (such lanes are masked off, and a zero triangle is no hit anyway).
const LANE_PAD: usize = 8;

/// A ray's segment: from `origin` along `dir` (not normalised: `t` counts `dir`s) up to
/// `tmax`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Segment {
    pub(super) origin: Vec3,
    pub(super) dir: Vec3,
    pub(super) tmax: f32,
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
        Self::from_inverse(
            inv,
            [origin.x * inv[0], origin.y * inv[1], origin.z * inv[2]],
        )
    }

    /// The ray of the reciprocal direction `inv` and `origin · inv` (rounded per axis).
    #[inline(always)]
    fn from_inverse(inv: [f32; 3], origin_inv: [f32; 3]) -> Self {
        let negative = inv.map(|i| usize::from(i < 0.0));
        Self {
            inv,
            origin_inv,
            near: [negative[0], 2 + negative[1], 4 + negative[2]],
            far: [1 - negative[0], 3 - negative[1], 5 - negative[2]],
        }
    }
}

/// The slab test of `node`'s eight child boxes: bit c of the mask is set when child slot c's
/// box is entered (at `t = plane · inv − origin · inv` on each axis) at or before `tmax` and
/// its far side is not nearer than [`NODE_EPSILON`] (the GPU's near-plane bound); entry c is
/// that box's entry distance. All eight children in one pass of 8-wide AVX2 lanes, each
/// plane's distance one fused multiply-subtract (a shorter chain of dependent operations from
/// a node's load to its children: measured, ms per sample ×0.90–0.95 on the small city,
/// BENCHMARKS.md, *CPU traversal*; only which nodes are visited, and in which order, depends
/// on it, never the hit); the same operations as [`node_hits_scalar`] lane by lane, so the
/// same bits.
///
/// The maxima, minima and the comparison are taken on the distances' bits as signed integers
/// (Embree's `maxi`/`mini`): one cycle each on the integer units where the float forms take
/// four on Intel cores (measured on an Intel Xeon: the one-ray bounces' walk ×0.92–0.97, the
/// small city's whole render ×0.98, BENCHMARKS.md, *CPU traversal*). The same values as the float
/// forms: the entry's maximum includes [`NODE_EPSILON`] > 0, and a non-negative float's bits
/// order as its value and above every negative one, so the maximum is the float maximum; the
/// exit's minimum is the float minimum when every term is non-negative and negative when one
/// is, and a negative exit fails the comparison against the positive entry either way. (A
/// plane's distance is never NaN: finite planes, guarded reciprocals; an empty slot's ±∞
/// planes give ±∞.)
#[cfg(all(
    target_arch = "x86_64",
    target_feature = "avx2",
    target_feature = "fma"
))]
#[inline(always)]
fn node_hits(node: &CpuNode, ray: &NodeRay, tmax: f32) -> (u32, [f32; 8]) {
    use std::arch::x86_64::{
        __m256i, _mm256_castps_si256, _mm256_castsi256_ps, _mm256_cmpgt_epi32, _mm256_fmsub_ps,
        _mm256_load_ps, _mm256_max_epi32, _mm256_min_epi32, _mm256_movemask_ps, _mm256_set1_ps,
        _mm256_storeu_ps,
    };
    let mut entry = [0f32; 8];
    // SAFETY: this is compiled only where AVX, AVX2 and FMA are enabled for the whole build
    // (.cargo/config.toml; the `cfg` above), so every intrinsic here is available. The loads
    // read one `[f32; 8]` row of `bounds` each (`CpuNode` is 64-byte aligned and its rows
    // start at multiples of 32 bytes, as `_mm256_load_ps` needs; `near`/`far` index rows
    // 0..6 by construction in `NodeRay::new`); the store writes the local `[f32; 8]`.
    let hit = unsafe {
        let t = |row: usize, axis: usize| -> __m256i {
            _mm256_castps_si256(_mm256_fmsub_ps(
                _mm256_load_ps(node.bounds[row].as_ptr()),
                _mm256_set1_ps(ray.inv[axis]),
                _mm256_set1_ps(ray.origin_inv[axis]),
            ))
        };
        let bits = |v: f32| _mm256_castps_si256(_mm256_set1_ps(v));
        let t_near = _mm256_max_epi32(
            _mm256_max_epi32(t(ray.near[0], 0), t(ray.near[1], 1)),
            _mm256_max_epi32(t(ray.near[2], 2), bits(NODE_EPSILON)),
        );
        let t_far = _mm256_min_epi32(
            _mm256_min_epi32(t(ray.far[0], 0), t(ray.far[1], 1)),
            _mm256_min_epi32(t(ray.far[2], 2), bits(tmax)),
        );
        _mm256_storeu_ps(entry.as_mut_ptr(), _mm256_castsi256_ps(t_near));
        // Entered where not (near > far); the movemask reads each lane's sign bit.
        !(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(t_near, t_far))) as u32) & 0xff
    };
    (hit, entry)
}

/// Without AVX2 and FMA: [`node_hits_scalar`].
#[cfg(not(all(
    target_arch = "x86_64",
    target_feature = "avx2",
    target_feature = "fma"
)))]
#[inline(always)]
fn node_hits(node: &CpuNode, ray: &NodeRay, tmax: f32) -> (u32, [f32; 8]) {
    node_hits_scalar(node, ray, tmax)
}

/// [`node_hits`] a child at a time (maxima, minima and the comparison on the distances'
/// bits as signed integers, [`node_hits`] says why they equal the float ones; `mul_add`: one
/// rounding, as `vfmsub`): the build without AVX2 and FMA, and the lanes' oracle.
#[cfg_attr(
    all(
        target_arch = "x86_64",
        target_feature = "avx2",
        target_feature = "fma"
    ),
    allow(dead_code)
)]
#[inline(always)]
fn node_hits_scalar(node: &CpuNode, ray: &NodeRay, tmax: f32) -> (u32, [f32; 8]) {
    let key = |a: f32| a.to_bits() as i32;
    let max = |a: f32, b: f32| if key(a) > key(b) { a } else { b };
    let min = |a: f32, b: f32| if key(a) < key(b) { a } else { b };
    let mut entry = [0f32; 8];
    let mut hit = 0;
    for (c, entry) in entry.iter_mut().enumerate() {
        let t = |row: usize, axis: usize| {
            node.bounds[row][c].mul_add(ray.inv[axis], -ray.origin_inv[axis])
        };
        let t_near = max(
            max(t(ray.near[0], 0), t(ray.near[1], 1)),
            max(t(ray.near[2], 2), NODE_EPSILON),
        );
        let t_far = min(
            min(t(ray.far[0], 0), t(ray.far[1], 1)),
            min(t(ray.far[2], 2), tmax),
        );
        *entry = t_near;
        if key(t_near) <= key(t_far) {
            hit |= 1 << c;
        }
    }
    (hit, entry)
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

/// A closest-hit stack entry's leaf: this bit over its node's index times 8 plus its slot (so
/// a tree holds fewer than 2^28 nodes, [`CpuTree::build`] checks; an inner child's entry holds
/// its node's index).
const LEAF_REF: u32 = 1 << 31;

/// The entries a traversal stack holds on a thread's own stack; deeper trees (more than 17
/// levels) allocate theirs.
const INLINE_STACK: usize = 128;

/// A walk's traversal stack of at least `size` entries, uninitialised (the walks write an entry
/// before they read it): `local` (on the walk's own stack) where it is large enough, else `heap`
/// grown to `size`. The walks set it up with this, not through a closure handed the stack, which
/// the compiler kept as a function of its own that read the ray, the bound and the node's index
/// through memory on every node (measured on an Intel Xeon: ×0.98 on the small city and the
/// Cornell boxes, BENCHMARKS.md, *CPU traversal*).
#[inline(always)]
fn traversal_stack<'a>(
    size: usize,
    local: &'a mut [MaybeUninit<u64>; INLINE_STACK],
    heap: &'a mut Vec<MaybeUninit<u64>>,
) -> &'a mut [MaybeUninit<u64>] {
    if size <= INLINE_STACK {
        local
    } else {
        heap.resize(size, MaybeUninit::uninit());
        heap
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
impl PrimLanes {
    /// Lanes `first..first + 8` of array `k < ARRAYS`, where `first + 8 ≤ stride` (which
    /// [`Self::meets8`] asserts once for its thirteen loads).
    #[inline(always)]
    fn load(&self, k: usize, first: usize) -> f32x8 {
        debug_assert!(k < ARRAYS && first + 8 <= self.stride);
        // SAFETY: `data[k·stride + first .. k·stride + first + 8]` lies inside array k
        // (`first + 8 ≤ stride`) and so inside `data` (`ARRAYS · stride` long, k < `ARRAYS`);
        // an unaligned read of eight `f32`s. Unchecked because the thirteen bounds checks cost
        // ×1.03 on the small city's whole render (BENCHMARKS.md, *CPU traversal*).
        unsafe {
            let at = self.data.as_ptr().add(k * self.stride + first);
            f32x8::new(at.cast::<[f32; 8]>().read_unaligned())
        }
    }

    /// [`intersect_triangle_sided`]'s first decision on the eight primitives `first..first +
    /// 8` at once, the same operations in the same order per lane (no FMA: glam's cross and
    /// dot products, so each lane's numbers are the scalar test's to the bit): the mask of the
    /// lanes whose triangle the ray's line meets in front of the origin, and per lane den,
    /// e2·r, e1·r and c·n, from which t, u, v follow ([`Self::test8`]). No division: the
    /// decision is made on the numerators. One AVX instruction an operation on x86-64, two
    /// NEON ones on AArch64 (`wide`). A leaf of up to eight triangles is one such test (a
    /// bounce ray in the small city tests 1.2–1.7 leaves, 6–8 triangles:
    /// BENCHMARKS.md, *CPU traversal*).
    #[inline(always)]
    fn meets8(&self, first: usize, o: Vec3, d: Vec3) -> (u32, [f32x8; 4]) {
        assert!(first + 8 <= self.stride, "lanes past the padding");
        let ld = |k: usize| self.load(k, first);
        // glam's dot: (x·x' + y·y') + z·z'
        let dot = |a: [f32x8; 3], b: [f32x8; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let zero = f32x8::ZERO;
        let sign = f32x8::splat(-0.0);
        let d = [d.x, d.y, d.z].map(f32x8::splat);
        let c = [ld(0) - o.x, ld(1) - o.y, ld(2) - o.z];
        let n = [ld(10), ld(11), ld(12)];
        // r = c × d (glam's cross: y·z' − y'·z, z·x' − z'·x, x·y' − x'·y)
        let r = [
            c[1] * d[2] - d[1] * c[2],
            c[2] * d[0] - d[2] * c[0],
            c[0] * d[1] - d[0] * c[1],
        ];
        let den = dot(n, d);
        let a = dot([ld(6), ld(7), ld(8)], r);
        let b = dot([ld(3), ld(4), ld(5)], r);
        let tn = dot(c, n);
        let den_sign = den & sign;
        let abs_den = den.abs();
        let us = a ^ den_sign;
        let vs = b ^ den_sign ^ sign;
        let ts = tn ^ den_sign;
        // Ordered comparisons: a NaN lane is never met (`finite` is false for a NaN `den`,
        // so `nonzero`'s unordered `!=` cannot let one through).
        let finite = abs_den.simd_lt(f32x8::splat(f32::INFINITY));
        let nonzero = den.simd_ne(zero);
        let culled = ld(9).simd_ne(zero) & den.simd_gt(zero);
        let ok = finite & nonzero & !culled;
        let inside =
            us.simd_ge(zero) & vs.simd_ge(zero) & (us + vs).simd_le(abs_den) & ts.simd_gt(zero);
        ((ok & inside).to_bitmask(), [den, a, b, tn])
    }

    /// [`intersect_triangle_sided`] on the eight primitives `first..first + 8` at once (to
    /// the bit, as [`Self::meets8`]): the mask of the lanes hit with `0 < t < tmax`, and t, u,
    /// v per lane (only the masked lanes' are meaningful). The division only when a lane is
    /// met.
    #[inline(always)]
    fn test8(
        &self,
        first: usize,
        o: Vec3,
        d: Vec3,
        tmax: f32,
    ) -> (u32, [f32; 8], [f32; 8], [f32; 8]) {
        let (met, [den, a, b, tn]) = self.meets8(first, o, d);
        if met == 0 {
            return (0, [0.0; 8], [0.0; 8], [0.0; 8]);
        }
        let inv = f32x8::ONE / den;
        let t = tn * inv;
        let below = t.simd_gt(f32x8::ZERO) & t.simd_lt(f32x8::splat(tmax));
        let v = -(b * inv);
        (
            met & below.to_bitmask(),
            t.to_array(),
            (a * inv).to_array(),
            v.to_array(),
        )
    }

    /// The primitives `first..first + count` (a leaf) hit with `0 < t < tmax`, each kept in
    /// `best` (t, u, v, primitive) where [`nearer`] says so. Whether `best` changed.
    #[inline(always)]
    fn closest(
        &self,
        first: u32,
        count: u32,
        o: Vec3,
        d: Vec3,
        tmax: f32,
        best: &mut Option<(f32, f32, f32, u32)>,
    ) -> bool {
        let mut changed = false;
        for start in (first..first + count).step_by(8) {
            let want = u32::MAX >> (32 - (first + count - start).min(8));
            let (hit, t, u, v) = self.test8(start as usize, o, d, bound(tmax, best));
            let mut m = hit & want;
            while m != 0 {
                let k = m.trailing_zeros() as usize;
                m &= m - 1;
                let i = start + k as u32;
                if nearer(t[k], i, best, |p| self.triangle[p as usize]) {
                    *best = Some((t[k], u[k], v[k], i));
                    changed = true;
                }
            }
        }
        changed
    }

    /// Whether any of the primitives `first..first + count` is hit with `0 < t < tmax`.
    #[inline(always)]
    fn any(&self, first: u32, count: u32, o: Vec3, d: Vec3, tmax: f32) -> bool {
        (first..first + count).step_by(8).any(|start| {
            let want = u32::MAX >> (32 - (first + count - start).min(8));
            self.test8(start as usize, o, d, tmax).0 & want != 0
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

impl CpuTree {
    /// The closest hit along `origin + t·dir`, `0 < t < tmax`, where a hit on an alpha-tested
    /// primitive ([`PRIM_ALPHA`]) counts only if `covered(triangle, u, v)`: a node's leaves
    /// first, then its inner children nearest entry first — one child entered directly, of two
    /// the farther pushed without a sort — and a node entered beyond the closest hit so far
    /// skipped. A leaf entered beyond the node's nearest inner child waits on the stack among
    /// the inner children, to be skipped if a hit in them comes first. (Counted: a third of the
    /// small city's leaf tests were of leaves entered beyond the ray's hit; every child taken
    /// nearest first, leaves included, measured ×1.04–1.12 slower on the Cornell boxes, whose
    /// root's leaves were then all sorted and pushed: BENCHMARKS.md, *CPU traversal*.)
    pub(super) fn closest_hit_filtered(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: impl Fn(u32, f32, f32) -> bool,
    ) -> Option<TraceHit> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut best = None;
        let ray = NodeRay::new(origin, dir);
        let segment = Segment { origin, dir, tmax };
        self.walk_closest(0, &ray, segment, &mut best, &covered);
        best.map(|(t, u, v, i)| TraceHit {
            t,
            u,
            v,
            triangle: self.triangle(i),
            prim: i,
        })
    }

    /// The closest hit's walk below node `root` for the ray of `segment` (`ray`: its reciprocal
    /// direction) whose closest hit so far is `best` (t, u, v, primitive), kept in `best`
    /// ([`Self::closest_hit_filtered`]'s walk; the hybrid packets finish their rays' walks
    /// with it).
    #[inline(always)]
    fn walk_closest(
        &self,
        root: usize,
        ray: &NodeRay,
        segment: Segment,
        best: &mut Option<(f32, f32, f32, u32)>,
        covered: &impl Fn(u32, f32, f32) -> bool,
    ) {
        let tmax = segment.tmax;
        // The nodes' bound: the closest hit's t once there is one (a node entered exactly there
        // is still visited: it may hold an equally near hit on a higher triangle).
        let mut tmax = best.map_or(tmax, |b| b.0);
        let (mut local, mut heap) = ([MaybeUninit::uninit(); INLINE_STACK], Vec::new());
        let stack = traversal_stack(self.stack_size, &mut local, &mut heap);
        let (mut index, mut len) = (root, 0);
        loop {
            let node = &self.nodes[index];
            let (hit, entry) = node_hits(node, ray, tmax);
            let mut leaves = hit & !node.imask;
            let mut inner = hit & node.imask;
            // Leaves entered beyond the nearest inner child wait on the stack with the
            // inner children: a hit in that child may make them needless.
            let mut deferred = 0;
            if inner != 0 && leaves != 0 {
                let mut near = f32::INFINITY;
                let mut m = inner;
                while m != 0 {
                    near = near.min(entry[m.trailing_zeros() as usize]);
                    m &= m - 1;
                }
                let mut m = leaves;
                while m != 0 {
                    let c = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if entry[c] > near {
                        deferred |= 1 << c;
                    }
                }
                leaves &= !deferred;
            }
            let mut changed = false;
            while leaves != 0 {
                let c = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                changed |= self.leaf_closest(
                    node.child[c],
                    u32::from(node.count[c]),
                    segment,
                    best,
                    covered,
                );
            }
            if changed && let Some(b) = *best {
                tmax = b.0;
                inner = entered_by(inner, &entry, tmax);
                deferred = entered_by(deferred, &entry, tmax);
            }
            if deferred != 0 {
                let first = len;
                let mut m = inner | deferred;
                while m != 0 {
                    let c = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let r = if inner & (1 << c) != 0 {
                        node.child[c]
                    } else {
                        LEAF_REF | ((index as u32) << 3) | c as u32
                    };
                    stack[len].write(stack_entry(entry[c], r));
                    len += 1;
                }
                // SAFETY: entries first..len were written just above.
                sort_farthest_first(unsafe { written(&mut stack[first..len]) });
                inner = 0;
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
                    let r = e as u32;
                    if r & LEAF_REF == 0 {
                        index = r as usize;
                        break;
                    }
                    // A deferred leaf: its triangles, and the bound tightened by a hit.
                    let node = &self.nodes[((r & !LEAF_REF) >> 3) as usize];
                    let c = (r & 7) as usize;
                    let count = u32::from(node.count[c]);
                    if self.leaf_closest(node.child[c], count, segment, best, covered)
                        && let Some(b) = *best
                    {
                        tmax = b.0;
                    }
                }
            }
        }
    }

    /// The closest hits of eight rays at once (`0 < t < ∞`), for the lanes set in `active`
    /// (the others get `None`): `closest_hit`'s hits to the bit, for rays that travel
    /// together — a camera's rays through neighbouring pixels. The rays share the walk: a node
    /// is visited once for the rays that enter it, its eight boxes tested against all of them
    /// in lanes (a ray per lane), a leaf's triangles likewise (the same triangle test's
    /// arithmetic per lane as the one-ray test's), and a child is taken for the rays that
    /// enter its box, nearest first by its first ray's entry. One decision per node for eight rays
    /// instead of eight: measured faster for camera rays (×0.91–0.94 a whole render), and
    /// slower for rays that scatter (BENCHMARKS.md, *CPU traversal*). Scenes with alpha-tested
    /// triangles take `closest_hit` per ray.
    pub(super) fn closest_hits8(
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
                out[i] =
                    self.closest_hit_filtered(origins[i], dirs[i], f32::INFINITY, |_, _, _| true);
            }
            return out;
        }
        let o = V3x8::from_lanes(origins);
        let d = V3x8::from_lanes(dirs);
        let inv = V3x8::from_lanes(&dirs.map(|d| {
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
        let (mut local, mut heap) = ([MaybeUninit::uninit(); INLINE_STACK], Vec::new());
        let stack = traversal_stack(self.stack_size, &mut local, &mut heap);
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
                if !inner && node.count[c] == 0 {
                    continue;
                }
                let t = |row: usize, axis: usize, inv: f32x8, oi: f32x8| {
                    f32x8::splat(node.bounds[2 * axis + row][c]).mul_sub(inv, oi)
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
                let first = node.child[c];
                for prim in first..first + u32::from(node.count[c]) {
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
                    triangle: self.triangle(prim[i]),
                    prim: prim[i],
                });
            }
        }
        out
    }

    /// Primitive `prim` against eight rays in lanes, [`intersect_triangle_sided`] per lane
    /// (the same operations, so the same t, u, v): the lanes hit with `0 < t < tmax`, and t,
    /// u, v.
    #[inline(always)]
    fn test_rays(
        &self,
        prim: usize,
        o: V3x8,
        d: V3x8,
        tmax: f32x8,
    ) -> (f32x8, f32x8, f32x8, f32x8) {
        let (v0, e1, e2) = self.prim(prim);
        let cull = self.flags(prim) & PRIM_CULL != 0;
        let (n, e1, e2) = (V3x8::splat(e1.cross(e2)), V3x8::splat(e1), V3x8::splat(e2));
        let c = V3x8::splat(v0) - o;
        let r = c.cross(d);
        let den = n.dot(d);
        let (a, b, tn) = (e2.dot(r), e1.dot(r), c.dot(n));
        let zero = f32x8::ZERO;
        let abs_den = den.abs();
        let mut ok = den.simd_ne(zero) & abs_den.simd_lt(f32x8::INFINITY);
        if cull {
            ok &= !den.simd_gt(zero);
        }
        // The numerators times den's sign (a sign flip, as the scalar test's).
        let den_sign = den & f32x8::splat(-0.0);
        let (us, vs, ts) = (a ^ den_sign, -b ^ den_sign, tn ^ den_sign);
        let met =
            us.simd_ge(zero) & vs.simd_ge(zero) & (us + vs).simd_le(abs_den) & ts.simd_gt(zero);
        let inv = f32x8::ONE / den;
        let t = tn * inv;
        let hit = ok & met & t.simd_gt(zero) & t.simd_lt(tmax);
        (hit, t, a * inv, -(b * inv))
    }

    /// Whether anything blocks `origin + t·dir` for `0 < t < tmax`, with the coverage test of
    /// `closest_hit_filtered`. Any hit ends the search, so the children are not ordered: the
    /// first is entered directly, the others pushed.
    pub(super) fn occluded_filtered(
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
        self.walk_any(0, &ray, origin, dir, tmax, &covered)
    }

    /// The shadow ray's walk below node `root` (`ray`: the reciprocal direction of `origin`
    /// and `dir`): whether a primitive there blocks it ([`Self::occluded_filtered`]'s walk;
    /// the hybrid packets finish their rays' walks with it).
    #[inline(always)]
    fn walk_any(
        &self,
        root: usize,
        ray: &NodeRay,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: &impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        let (mut local, mut heap) = ([MaybeUninit::uninit(); INLINE_STACK], Vec::new());
        let stack = traversal_stack(self.stack_size, &mut local, &mut heap);
        let (mut index, mut len) = (root, 0);
        loop {
            let node = &self.nodes[index];
            let (hit, _) = node_hits(node, ray, tmax);
            let mut leaves = hit & !node.imask;
            while leaves != 0 {
                let c = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let (first, count) = (node.child[c], u32::from(node.count[c]));
                if self.leaf_any(first, count, origin, dir, tmax, covered) {
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
    }

    /// The leaf `first..first + count`'s hits kept in `best` ([`PrimLanes::closest`]), with
    /// alpha-tested primitives asked `covered`, one at a time. Whether `best` changed.
    #[inline(always)]
    fn leaf_closest(
        &self,
        first: u32,
        count: u32,
        segment: Segment,
        best: &mut Option<(f32, f32, f32, u32)>,
        covered: &impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        let Segment { origin, dir, tmax } = segment;
        if !self.lanes.alpha {
            return self.lanes.closest(first, count, origin, dir, tmax, best);
        }
        let mut changed = false;
        for i in first..first + count {
            if let Some((t, u, v)) =
                self.test_prim(i as usize, origin, dir, bound(tmax, best), covered)
                && nearer(t, i, best, |p| self.triangle(p))
            {
                *best = Some((t, u, v, i));
                changed = true;
            }
        }
        changed
    }

    /// Whether any of the leaf `first..first + count`'s primitives is hit with `0 < t < tmax`.
    #[inline(always)]
    fn leaf_any(
        &self,
        first: u32,
        count: u32,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: &impl Fn(u32, f32, f32) -> bool,
    ) -> bool {
        if !self.lanes.alpha {
            return self.lanes.any(first, count, origin, dir, tmax);
        }
        (first..first + count).any(|i| {
            self.test_prim(i as usize, origin, dir, tmax, covered)
                .is_some()
        })
    }

    /// Primitive `i` against the ray, its flags obeyed (a culled back face, coverage).
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
mod tests;
