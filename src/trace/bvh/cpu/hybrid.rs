//! Sixteen rays walked together while enough of them go the same way, in AVX-512 lanes:
//! Embree's hybrid traversal (`BVHNIntersectorKHybrid<8, 16>`, the walk Mitsuba's
//! `llvm_ad_rgb` takes on a processor with AVX-512), on the CPU tree, for closest hits and for
//! shadow rays.
//!
//! A node popped for the packet is tested against all its rays that still enter it, child by
//! child, a ray per lane (one child's box against sixteen rays is one set of vector
//! operations, where the one-ray walk spends one on a node's eight boxes for one ray); a leaf's
//! triangles likewise, one triangle against sixteen rays. Once a node is entered by
//! [`SWITCH`] rays or fewer, each of them finishes the subtree alone with the one-ray walk
//! ([`CpuTree::walk_closest`], [`CpuTree::walk_any`]), a closest hit from its closest hit so
//! far. The results are the one-ray walks' to the bit: the same triangle arithmetic lane by
//! lane (no fused operations: glam's cross and dot products, as
//! [`super::intersect_triangle_sided`] computes them), and the same rule for exact ties
//! ([`super::nearer`]), which makes a closest hit independent of the order in which a walk
//! meets the triangles.
//!
//! Where it pays: rays that start near each other — a bounce's or a shadow ray's from
//! neighbouring pixels — share the top of the tree, which a packet visits once (BENCHMARKS.md).
//! Compiled for AVX-512 F and DQ and run only where the processor has them ([`available`]);
//! elsewhere the rays take the one-ray walks.

use std::arch::x86_64::{
    __m512, __m512i, __mmask16, _CMP_EQ_OQ, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ,
    _CMP_NEQ_OQ, _MM_CMPINT_NE, _mm512_abs_ps, _mm512_add_epi32, _mm512_add_ps, _mm512_and_ps,
    _mm512_castps_si512, _mm512_castsi512_ps, _mm512_cmp_epu32_mask, _mm512_cmp_ps_mask,
    _mm512_cmpgt_epu32_mask, _mm512_div_ps, _mm512_fmsub_ps, _mm512_loadu_ps, _mm512_loadu_si512,
    _mm512_mask_blend_epi32, _mm512_mask_blend_ps, _mm512_mask_reduce_min_ps, _mm512_max_ps,
    _mm512_min_ps, _mm512_mul_ps, _mm512_or_ps, _mm512_set1_epi32, _mm512_set1_ps,
    _mm512_setzero_ps, _mm512_storeu_ps, _mm512_storeu_si512, _mm512_sub_ps, _mm512_xor_ps,
};
use std::mem::MaybeUninit;

use glam::Vec3;

use super::{CpuNode, CpuTree, INLINE_STACK, NODE_EPSILON, NodeRay, PRIM_CULL, TraceHit};

/// A node entered by this many of a packet's rays or fewer is walked by each of them alone:
/// below it, testing a child's box for the packet costs more than the rays' own walks.
/// Embree's hybrid switches at 7 of 16 as well (10 measured the same here: BENCHMARKS.md).
pub(crate) const SWITCH: u32 = 7;

/// Whether this processor runs the packets (AVX-512 F and DQ).
pub(crate) fn available() -> bool {
    std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx512dq")
}

/// Sixteen rays in lanes, and each one's own for the walks alone.
struct Rays {
    o: [__m512; 3],
    d: [__m512; 3],
    /// obvhs' guarded reciprocal of the direction, and `origin · inv` (rounded on its own).
    inv: [__m512; 3],
    oi: [__m512; 3],
    /// Lane i: whether ray i's direction is negative on the axis (its near plane is the max).
    neg: [__mmask16; 3],
    /// `inv` and `oi` by lane, for a ray's walk alone ([`Self::alone`]).
    each: [[f32; 16]; 6],
}

impl Rays {
    #[inline]
    #[target_feature(enable = "avx512f,avx512dq")]
    fn new(origins: &[Vec3; 16], dirs: &[Vec3; 16]) -> Self {
        let mut rows = [[0f32; 16]; 6];
        for i in 0..16 {
            for axis in 0..3 {
                rows[axis][i] = origins[i][axis];
                rows[3 + axis][i] = dirs[i][axis];
            }
        }
        // SAFETY: reads the local rows of 16.
        let row = |k: usize| unsafe { _mm512_loadu_ps(rows[k].as_ptr()) };
        let (o, d) = ([row(0), row(1), row(2)], [row(3), row(4), row(5)]);
        // `safe_inverse`: ±1/ε (exact: ε is a power of two) within ε of zero, else 1/x.
        let sign = _mm512_set1_ps(-0.0);
        let inv = d.map(|d| {
            let eps = _mm512_set1_ps(f32::EPSILON);
            let tiny = _mm512_cmp_ps_mask::<_CMP_LE_OQ>(_mm512_abs_ps(d), eps);
            let guarded = _mm512_or_ps(_mm512_and_ps(d, sign), _mm512_set1_ps(1.0 / f32::EPSILON));
            _mm512_mask_blend_ps(tiny, _mm512_div_ps(_mm512_set1_ps(1.0), d), guarded)
        });
        let oi = [0, 1, 2].map(|axis| _mm512_mul_ps(o[axis], inv[axis]));
        let mut each = [[0f32; 16]; 6];
        for (k, v) in inv.into_iter().chain(oi).enumerate() {
            // SAFETY: writes the local row of 16.
            unsafe { _mm512_storeu_ps(each[k].as_mut_ptr(), v) };
        }
        Self {
            o,
            d,
            inv,
            oi,
            neg: inv.map(|inv| _mm512_cmp_ps_mask::<_CMP_LT_OQ>(inv, _mm512_setzero_ps())),
            each,
        }
    }

    /// Ray `i`'s [`NodeRay`] (the same numbers), for its walk alone.
    #[inline(always)]
    fn alone(&self, i: usize) -> NodeRay {
        let e = &self.each;
        NodeRay::from_inverse([e[0][i], e[1][i], e[2][i]], [e[3][i], e[4][i], e[5][i]])
    }

    /// Every slot's box of `node` against the rays `rays` (no branch between them, so that the
    /// eight tests overlap): per slot the rays' entry distances and the rays that enter it no
    /// farther than `bound` — the one-ray walk's slab test per lane: each ray's near and far
    /// planes by its direction's signs, one fused multiply-subtract a plane, [`NODE_EPSILON`]
    /// as the near bound; an empty slot's box is entered by no ray.
    ///
    /// # Safety
    /// The processor must have AVX-512 F (inlined into the packets' walks, which check).
    #[inline(always)]
    unsafe fn enter8(
        &self,
        node: &CpuNode,
        rays: __mmask16,
        bound: __m512,
    ) -> ([__m512; 8], [u16; 8]) {
        // SAFETY: the caller's promise (AVX-512 F); everything else is register arithmetic.
        unsafe {
            let mut nears = [_mm512_setzero_ps(); 8];
            let mut hits = [0u16; 8];
            for c in 0..8 {
                let plane = |axis: usize| {
                    let t = |row: usize| {
                        _mm512_fmsub_ps(
                            _mm512_set1_ps(node.bounds[2 * axis + row][c]),
                            self.inv[axis],
                            self.oi[axis],
                        )
                    };
                    let (lo, hi) = (t(0), t(1));
                    (
                        _mm512_mask_blend_ps(self.neg[axis], lo, hi),
                        _mm512_mask_blend_ps(self.neg[axis], hi, lo),
                    )
                };
                let (x, y, z) = (plane(0), plane(1), plane(2));
                let (max, min) = (_mm512_max_ps, _mm512_min_ps);
                let near = max(max(x.0, y.0), max(z.0, _mm512_set1_ps(NODE_EPSILON)));
                let far = min(min(x.1, y.1), min(z.1, bound));
                nears[c] = near;
                hits[c] = _mm512_cmp_ps_mask::<_CMP_LE_OQ>(near, far) & rays;
            }
            (nears, hits)
        }
    }
}

/// The slots of eight whose rays are not none.
#[inline(always)]
fn entered(hits: &[u16; 8]) -> u32 {
    (0..8).fold(0u32, |m, c| m | (u32::from(hits[c] != 0) << c))
}

/// The closest hits so far of a packet's rays: t (the nodes' bound: +∞ before a hit), u, v,
/// the primitive (`u32::MAX`: none yet) and its triangle.
struct Closest {
    t: __m512,
    u: __m512,
    v: __m512,
    prim: __m512i,
    tri: __m512i,
}

/// A closest-hit packet's stack entry: a node, the rays that enter it and their entry
/// distances.
#[derive(Clone, Copy)]
struct Entry {
    node: u32,
    rays: __mmask16,
    near: __m512,
}

impl CpuTree {
    /// The closest hits of sixteen rays (`0 < t < ∞`) for the lanes set in `active` (the others
    /// get `None`), walked as a hybrid packet that leaves a node entered by `switch` rays or
    /// fewer to each ray alone: `closest_hit`'s hits to the bit.
    ///
    /// # Safety
    /// The processor must have AVX-512 F and DQ ([`available`]), and the tree no alpha-tested
    /// primitives and a stack bound within [`INLINE_STACK`] (`CpuTree::packets`).
    #[target_feature(enable = "avx512f,avx512dq")]
    pub(super) unsafe fn hybrid16(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        active: u16,
        switch: u32,
    ) -> [Option<TraceHit>; 16] {
        let r = Rays::new(origins, dirs);
        let mut best = Closest {
            t: _mm512_set1_ps(f32::INFINITY),
            u: _mm512_setzero_ps(),
            v: _mm512_setzero_ps(),
            prim: _mm512_set1_epi32(-1),
            tri: _mm512_set1_epi32(0),
        };
        let mut stack = [MaybeUninit::<Entry>::uninit(); INLINE_STACK];
        stack[0].write(Entry {
            node: 0,
            rays: active,
            near: _mm512_set1_ps(f32::NEG_INFINITY),
        });
        let mut len = 1;
        while len > 0 {
            len -= 1;
            // SAFETY: every entry below `len` was written by a push.
            let e = unsafe { stack[len].assume_init() };
            // The rays still to enter: their entry is not beyond their closest hit so far.
            let rays = _mm512_cmp_ps_mask::<_CMP_LE_OQ>(e.near, best.t) & e.rays;
            if rays == 0 {
                continue;
            }
            if rays.count_ones() <= switch {
                self.closest_alone(&mut best, e.node as usize, rays, &r, origins, dirs);
                continue;
            }
            let node = &self.nodes[e.node as usize];
            // SAFETY: this runs where AVX-512 F is (the function's features).
            let (nears, hits) = unsafe { r.enter8(node, rays, best.t) };
            let entered = entered(&hits);
            let mut leaves = entered & !node.imask;
            while leaves != 0 {
                let c = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let first = node.child[c];
                for prim in first..first + u32::from(node.count[c]) {
                    self.closest_packet(&mut best, &r, prim, hits[c]);
                }
            }
            let mut inner = entered & node.imask;
            let mut keys = [0u64; 8];
            let mut n_inner = 0;
            while inner != 0 {
                let c = inner.trailing_zeros() as usize;
                inner &= inner - 1;
                // The nearest ray's entry (positive: the bits order as the values) over the slot.
                let nearest = _mm512_mask_reduce_min_ps(hits[c], nears[c]);
                keys[n_inner] = (u64::from(nearest.to_bits()) << 32) | c as u64;
                n_inner += 1;
            }
            // The nearest (by its nearest ray) on top.
            let keys = &mut keys[..n_inner];
            super::sort_farthest_first(keys);
            for &key in keys.iter() {
                let c = key as u32 as usize;
                stack[len].write(Entry {
                    node: node.child[c],
                    rays: hits[c],
                    near: nears[c],
                });
                len += 1;
            }
        }
        let (mut t, mut u, mut v, mut prim) = ([0f32; 16], [0f32; 16], [0f32; 16], [0u32; 16]);
        // SAFETY: the stores write the local arrays of 16.
        unsafe {
            _mm512_storeu_ps(t.as_mut_ptr(), best.t);
            _mm512_storeu_ps(u.as_mut_ptr(), best.u);
            _mm512_storeu_ps(v.as_mut_ptr(), best.v);
            _mm512_storeu_si512(prim.as_mut_ptr().cast(), best.prim);
        }
        std::array::from_fn(|i| {
            (active & (1 << i) != 0 && prim[i] != u32::MAX).then(|| TraceHit {
                t: t[i],
                u: u[i],
                v: v[i],
                triangle: self.triangle(prim[i]),
                prim: prim[i],
            })
        })
    }

    /// Whether something blocks each of sixteen shadow rays `origins[i] + t·dirs[i]`,
    /// `0 < t < tmax[i]`, for the lanes set in `active` (a bit set per blocked ray), walked as
    /// a hybrid packet that leaves a node entered by `switch` rays or fewer to each ray alone:
    /// `occluded`'s answers. A blocked ray leaves the packet.
    ///
    /// # Safety
    /// As [`Self::hybrid16`].
    #[target_feature(enable = "avx512f,avx512dq")]
    pub(super) unsafe fn hybrid_occluded16(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        tmax: &[f32; 16],
        active: u16,
        switch: u32,
    ) -> u16 {
        let r = Rays::new(origins, dirs);
        // SAFETY: reads the array of 16.
        let bound = unsafe { _mm512_loadu_ps(tmax.as_ptr()) };
        let mut blocked: u16 = 0;
        let mut stack = [MaybeUninit::<(u32, u16)>::uninit(); INLINE_STACK];
        stack[0].write((0, active));
        let mut len = 1;
        while len > 0 {
            len -= 1;
            // SAFETY: every entry below `len` was written by a push.
            let (index, rays) = unsafe { stack[len].assume_init() };
            let rays = rays & !blocked;
            if rays == 0 {
                continue;
            }
            if rays.count_ones() <= switch {
                let mut m = rays;
                while m != 0 {
                    let i = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let (o, d) = (origins[i], dirs[i]);
                    if self.walk_any(index as usize, &r.alone(i), o, d, tmax[i], &|_, _, _| true) {
                        blocked |= 1 << i;
                    }
                }
                continue;
            }
            let node = &self.nodes[index as usize];
            // SAFETY: this runs where AVX-512 F is (the function's features).
            let (_, hits) = unsafe { r.enter8(node, rays, bound) };
            let entered = entered(&hits);
            let mut leaves = entered & !node.imask;
            while leaves != 0 {
                let c = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let first = node.child[c];
                for prim in first..first + u32::from(node.count[c]) {
                    let want = hits[c] & !blocked;
                    if want == 0 {
                        break;
                    }
                    let (met, [den, _, _, tn]) = self.meets_packet(&r, prim, want);
                    if met != 0 {
                        let t = _mm512_mul_ps(tn, _mm512_div_ps(_mm512_set1_ps(1.0), den));
                        blocked |= met
                            & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(t, _mm512_setzero_ps())
                            & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(t, bound);
                    }
                }
            }
            if active & !blocked == 0 {
                break;
            }
            let mut inner = entered & node.imask;
            while inner != 0 {
                let c = inner.trailing_zeros() as usize;
                inner &= inner - 1;
                stack[len].write((node.child[c], hits[c]));
                len += 1;
            }
        }
        blocked & active
    }

    /// The rays `rays` of the packet walk below `node` alone ([`CpuTree::walk_closest`]), each
    /// from its closest hit so far, which they update.
    #[target_feature(enable = "avx512f,avx512dq")]
    fn closest_alone(
        &self,
        best: &mut Closest,
        node: usize,
        rays: __mmask16,
        r: &Rays,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
    ) {
        let (mut t, mut u, mut v, mut prim, mut tri) =
            ([0f32; 16], [0f32; 16], [0f32; 16], [0u32; 16], [0u32; 16]);
        // SAFETY: the loads and stores touch the local arrays of 16.
        unsafe {
            _mm512_storeu_ps(t.as_mut_ptr(), best.t);
            _mm512_storeu_ps(u.as_mut_ptr(), best.u);
            _mm512_storeu_ps(v.as_mut_ptr(), best.v);
            _mm512_storeu_si512(prim.as_mut_ptr().cast(), best.prim);
            _mm512_storeu_si512(tri.as_mut_ptr().cast(), best.tri);
        }
        let mut m = rays;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let mut hit = (prim[i] != u32::MAX).then_some((t[i], u[i], v[i], prim[i]));
            let (o, d) = (origins[i], dirs[i]);
            self.walk_closest(
                node,
                &r.alone(i),
                o,
                d,
                f32::INFINITY,
                &mut hit,
                &|_, _, _| true,
            );
            if let Some(h) = hit {
                (t[i], u[i], v[i], prim[i]) = h;
                tri[i] = self.triangle(h.3);
            }
        }
        // SAFETY: as above.
        unsafe {
            best.t = _mm512_loadu_ps(t.as_ptr());
            best.u = _mm512_loadu_ps(u.as_ptr());
            best.v = _mm512_loadu_ps(v.as_ptr());
            best.prim = _mm512_loadu_si512(prim.as_ptr().cast());
            best.tri = _mm512_loadu_si512(tri.as_ptr().cast());
        }
    }

    /// [`super::intersect_triangle_sided`]'s first decision for primitive `prim` against the
    /// rays `rays`, the same operations in the same order per lane: the rays whose line meets
    /// the triangle in front of the origin, and per lane den, e2·r, e1·r and c·n, from which t,
    /// u and v follow. No division.
    #[inline]
    #[target_feature(enable = "avx512f,avx512dq")]
    fn meets_packet(&self, r: &Rays, prim: u32, rays: __mmask16) -> (__mmask16, [__m512; 4]) {
        let (v0, e1, e2) = self.prim(prim as usize);
        let cull = self.flags(prim as usize) & PRIM_CULL != 0;
        let n = e1.cross(e2);
        let splat = |v: Vec3| v.to_array().map(|x| _mm512_set1_ps(x));
        let (n, e1, e2, v0) = (splat(n), splat(e1), splat(e2), splat(v0));
        let (mul, sub, add) = (_mm512_mul_ps, _mm512_sub_ps, _mm512_add_ps);
        let dot = |a: [__m512; 3], b: [__m512; 3]| {
            add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]))
        };
        let d = r.d;
        let c = [sub(v0[0], r.o[0]), sub(v0[1], r.o[1]), sub(v0[2], r.o[2])];
        // glam's cross: y·z' − y'·z, z·x' − z'·x, x·y' − x'·y.
        let cr = [
            sub(mul(c[1], d[2]), mul(d[1], c[2])),
            sub(mul(c[2], d[0]), mul(d[2], c[0])),
            sub(mul(c[0], d[1]), mul(d[0], c[1])),
        ];
        let den = dot(n, d);
        let (a, b, tn) = (dot(e2, cr), dot(e1, cr), dot(c, n));
        let zero = _mm512_setzero_ps();
        let sign = _mm512_set1_ps(-0.0);
        let abs_den = _mm512_abs_ps(den);
        let mut ok = _mm512_cmp_ps_mask::<_CMP_NEQ_OQ>(den, zero)
            & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(abs_den, _mm512_set1_ps(f32::INFINITY))
            & rays;
        if cull {
            ok &= !_mm512_cmp_ps_mask::<_CMP_GT_OQ>(den, zero);
        }
        // The numerators times den's sign (a sign flip, as the scalar test's).
        let den_sign = _mm512_and_ps(den, sign);
        let us = _mm512_xor_ps(a, den_sign);
        let vs = _mm512_xor_ps(_mm512_xor_ps(b, sign), den_sign);
        let ts = _mm512_xor_ps(tn, den_sign);
        let met = ok
            & _mm512_cmp_ps_mask::<_CMP_GE_OQ>(us, zero)
            & _mm512_cmp_ps_mask::<_CMP_GE_OQ>(vs, zero)
            & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(add(us, vs), abs_den)
            & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(ts, zero);
        (met, [den, a, b, tn])
    }

    /// Primitive `prim` against the packet's rays `rays` ([`super::intersect_triangle_sided`]
    /// per lane), each hit kept in `best` where it is nearer ([`super::nearer`]).
    #[inline]
    #[target_feature(enable = "avx512f,avx512dq")]
    fn closest_packet(&self, best: &mut Closest, r: &Rays, prim: u32, rays: __mmask16) {
        let (met, [den, a, b, tn]) = self.meets_packet(r, prim, rays);
        if met == 0 {
            return;
        }
        let (zero, sign) = (_mm512_setzero_ps(), _mm512_set1_ps(-0.0));
        let inv = _mm512_div_ps(_mm512_set1_ps(1.0), den);
        let t = _mm512_mul_ps(tn, inv);
        // The bound of a nearer hit: t itself included once there is a hit (the one-ray
        // walk's `bound`; +∞ before).
        let found = _mm512_cmp_epu32_mask::<_MM_CMPINT_NE>(best.prim, _mm512_set1_epi32(-1));
        let next_up = _mm512_castsi512_ps(_mm512_add_epi32(
            _mm512_castps_si512(best.t),
            _mm512_set1_epi32(1),
        ));
        let bound = _mm512_mask_blend_ps(found, _mm512_set1_ps(f32::INFINITY), next_up);
        let hit = met
            & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(t, zero)
            & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(t, bound);
        let tri = _mm512_set1_epi32(self.triangle(prim) as i32);
        let tie = _mm512_cmpgt_epu32_mask(tri, best.tri) | !found;
        let take = hit
            & (_mm512_cmp_ps_mask::<_CMP_LT_OQ>(t, best.t)
                | (_mm512_cmp_ps_mask::<_CMP_EQ_OQ>(t, best.t) & tie));
        if take == 0 {
            return;
        }
        best.t = _mm512_mask_blend_ps(take, best.t, t);
        best.u = _mm512_mask_blend_ps(take, best.u, _mm512_mul_ps(a, inv));
        best.v = _mm512_mask_blend_ps(take, best.v, _mm512_xor_ps(_mm512_mul_ps(b, inv), sign));
        best.prim = _mm512_mask_blend_epi32(take, best.prim, _mm512_set1_epi32(prim as i32));
        best.tri = _mm512_mask_blend_epi32(take, best.tri, tri);
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::super::super::SceneBvh;
    use super::super::super::tests::{random_triangles, uniforms};
    use super::*;

    /// The packets give each ray the one-ray walk's closest hit to the bit (t, u, v,
    /// primitive's triangle), with the switch to one-ray walks at every threshold — never
    /// (every node and leaf tested for the packet), at 7, and always (every ray alone from the
    /// root) — on rays from one point through a small window (a camera's, where the packet
    /// stays whole down to the leaves), from nearby points in all directions (a bounce's) and
    /// from everywhere, with lanes switched off; single-sided triangles seen from both sides;
    /// triangles given twice, every hit on them an exact tie, which the higher one wins. On a
    /// processor without AVX-512 the public walk (one ray at a time there) is checked alone; the
    /// one-ray fallback is checked everywhere.
    #[test]
    fn packets_find_each_rays_hit() {
        let mut tris = random_triangles(1500, 5);
        tris.extend_from_within(..300);
        // Every third triangle single-sided.
        let sided: Vec<bool> = (0..tris.len()).map(|i| i % 3 == 1).collect();
        let bvh = SceneBvh::build_sided(&tris, &vec![0.0; tris.len()], &sided);
        let mut r = uniforms(23);
        let packets = available();
        let (mut hits, mut ties) = (0, 0);
        for round in 0..1500 {
            let eye = Vec3::new(r(), r(), r()) * 14.0 - 7.0;
            let centre = (Vec3::new(r(), r(), r()) - 0.5).normalize();
            let kind = round % 3;
            let origins: [Vec3; 16] = std::array::from_fn(|_| match kind {
                0 => eye,
                1 => eye + (Vec3::new(r(), r(), r()) - 0.5) * 0.2,
                _ => Vec3::new(r(), r(), r()) * 14.0 - 7.0,
            });
            let dirs: [Vec3; 16] = std::array::from_fn(|_| {
                let spread = if kind == 0 { 0.05 } else { 2.0 };
                (centre + (Vec3::new(r(), r(), r()) - 0.5) * spread).normalize()
            });
            let active = if round % 5 == 0 {
                0b1011_0110_1110_0101
            } else {
                0xffff
            };
            let want: [Option<TraceHit>; 16] = std::array::from_fn(|i| {
                (active & (1 << i) != 0)
                    .then(|| bvh.closest_hit(origins[i], dirs[i], f32::INFINITY))
                    .flatten()
            });
            let bits = |h: Option<TraceHit>| {
                h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.triangle))
            };
            let tree = bvh.cpu();
            let mut got = vec![
                bvh.closest_hits16(&origins, &dirs, active),
                tree.closest_hits16_alone(&origins, &dirs, active),
            ];
            if packets {
                assert!(tree.packets());
                for switch in [0, SWITCH, 16] {
                    // SAFETY: the processor has AVX-512 F and DQ (`available`), the scene no
                    // alpha-tested triangles, and its tree is shallow (asserted by `packets`).
                    got.push(unsafe { tree.hybrid16(&origins, &dirs, active, switch) });
                }
            }
            for (which, got) in got.iter().enumerate() {
                for i in 0..16 {
                    assert_eq!(
                        bits(got[i]),
                        bits(want[i]),
                        "round {round} walk {which} lane {i}"
                    );
                }
            }
            for h in want.iter().flatten() {
                hits += 1;
                if h.triangle < 300 || h.triangle >= 1500 {
                    ties += 1;
                    assert!(
                        h.triangle >= 1500,
                        "round {round}: tie to the lower triangle"
                    );
                }
            }
        }
        assert!(hits > 2000 && ties > 300, "{hits} hits, {ties} ties");
    }

    /// The shadow-ray packets (and their one-ray fallback) answer as the one-ray walk does,
    /// with the switch never, at 7 and always: rays from one point, from nearby points and from everywhere, each with its own
    /// length — unbounded, ending just before its closest hit (not blocked, unless another
    /// triangle is nearer), exactly there (not blocked by it: `t < tmax`), just beyond it, or
    /// far short — and lanes switched off.
    #[test]
    fn shadow_packets_answer_as_one_ray() {
        let tris = random_triangles(1500, 9);
        let sided: Vec<bool> = (0..tris.len()).map(|i| i % 3 == 1).collect();
        let bvh = SceneBvh::build_sided(&tris, &vec![0.0; tris.len()], &sided);
        let mut r = uniforms(31);
        let packets = available();
        let (mut blocked, mut open) = (0, 0);
        for round in 0..1500 {
            let eye = Vec3::new(r(), r(), r()) * 14.0 - 7.0;
            let kind = round % 3;
            let origins: [Vec3; 16] = std::array::from_fn(|_| match kind {
                0 => eye,
                1 => eye + (Vec3::new(r(), r(), r()) - 0.5) * 0.2,
                _ => Vec3::new(r(), r(), r()) * 14.0 - 7.0,
            });
            // Aimed at triangles, give or take: many rays are blocked.
            let dirs: [Vec3; 16] = std::array::from_fn(|i| {
                let k = ((r() * tris.len() as f32) as usize).min(tris.len() - 1);
                let target = (tris[k][0] + tris[k][1] + tris[k][2]) / 3.0;
                (target - origins[i] + (Vec3::new(r(), r(), r()) - 0.5) * 0.3).normalize()
            });
            let tmax: [f32; 16] = std::array::from_fn(|i| {
                let t = bvh
                    .closest_hit(origins[i], dirs[i], f32::INFINITY)
                    .map_or(5.0, |h| h.t);
                match i % 5 {
                    0 => f32::INFINITY,
                    1 => t * 0.9999,
                    2 => t * 1.0001,
                    3 => t,
                    _ => t * 0.3,
                }
            });
            let active = if round % 5 == 0 {
                0b0110_1011_0111_1001
            } else {
                0xffff
            };
            let want = (0..16)
                .filter(|&i| active & (1 << i) != 0 && bvh.occluded(origins[i], dirs[i], tmax[i]))
                .fold(0u16, |m, i| m | (1 << i));
            let mut got = vec![
                bvh.occluded16(&origins, &dirs, &tmax, active),
                bvh.cpu().occluded16_alone(&origins, &dirs, &tmax, active),
            ];
            if packets {
                for switch in [0, SWITCH, 16] {
                    // SAFETY: as in `packets_find_each_rays_hit`.
                    got.push(unsafe {
                        bvh.cpu()
                            .hybrid_occluded16(&origins, &dirs, &tmax, active, switch)
                    });
                }
            }
            for (which, got) in got.iter().enumerate() {
                assert_eq!(
                    *got, want,
                    "round {round} walk {which}: {got:016b} against {want:016b}"
                );
            }
            blocked += want.count_ones();
            open += (active & !want).count_ones();
        }
        assert!(
            blocked > 4000 && open > 4000,
            "{blocked} blocked, {open} open"
        );
    }
}
