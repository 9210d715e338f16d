//! Sixteen closest-hit rays walked together while enough of them go the same way, in AVX-512
//! lanes: Embree's hybrid traversal (`BVHNIntersectorKHybrid<8, 16>`, the walk Mitsuba's
//! `llvm_ad_rgb` takes on a processor with AVX-512), on the CPU tree.
//!
//! A node popped for the packet is tested against all its rays that still enter it, child by
//! child, a ray per lane (one child's box against sixteen rays is one set of vector
//! operations, where the one-ray walk spends one on a node's eight boxes for one ray); a leaf's
//! triangles likewise, one triangle against sixteen rays. Once a node is entered by
//! [`SWITCH`] rays or fewer, each of them finishes the subtree alone with the one-ray walk
//! ([`CpuTree::walk_closest`]), starting from its closest hit so far. The hits are the one-ray
//! walk's to the bit: the same triangle arithmetic lane by lane (no fused operations: glam's
//! cross and dot products, as [`super::intersect_triangle_sided`] computes them), and the same
//! rule for exact ties ([`super::nearer`]), which makes the hit independent of the order in
//! which a walk meets the triangles.
//!
//! Where it pays: rays that start near each other — a bounce's rays from neighbouring pixels
//! leave from nearby points — share the top of the tree, which a packet visits once
//! (BENCHMARKS.md). Compiled for AVX-512 F and DQ and run only where the processor has them
//! ([`available`]); elsewhere the rays take the one-ray walk.

use std::arch::x86_64::{
    __m512, __m512i, __mmask16, _CMP_EQ_OQ, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ,
    _CMP_NEQ_OQ, _MM_CMPINT_NE, _mm512_abs_ps, _mm512_add_epi32, _mm512_add_ps, _mm512_and_ps,
    _mm512_cmp_epu32_mask, _mm512_cmp_ps_mask, _mm512_cmpgt_epu32_mask, _mm512_div_ps,
    _mm512_fmsub_ps, _mm512_loadu_ps, _mm512_loadu_si512, _mm512_mask_blend_epi32,
    _mm512_mask_blend_ps, _mm512_mask_reduce_min_ps, _mm512_mul_ps, _mm512_or_ps,
    _mm512_set1_epi32, _mm512_set1_ps, _mm512_setzero_ps, _mm512_storeu_ps, _mm512_storeu_si512,
    _mm512_sub_ps, _mm512_xor_ps,
};
use std::mem::MaybeUninit;

use glam::Vec3;

use super::{CpuNode, CpuTree, INLINE_STACK, NODE_EPSILON, NodeRay, PRIM_CULL, TraceHit};

/// A node entered by this many of a packet's rays or fewer is walked by each of them alone:
/// below it, testing a child's box for the packet costs more than the rays' own walks.
/// Embree's hybrid switches at 7 of 16 as well (measured here: BENCHMARKS.md).
pub(crate) const SWITCH: u32 = 7;

/// Whether this processor runs the packets (AVX-512 F and DQ).
pub(crate) fn available() -> bool {
    std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx512dq")
}

/// Sixteen rays in lanes, and each one's closest hit so far.
struct Packet {
    o: [__m512; 3],
    d: [__m512; 3],
    inv: [__m512; 3],
    oi: [__m512; 3],
    /// Lane i: whether ray i's direction is negative on the axis (its near plane is the max).
    neg: [__mmask16; 3],
    /// The closest hit so far: t (the nodes' bound: +∞ before a hit), u, v, the primitive
    /// (`u32::MAX`: none yet) and its triangle.
    t: __m512,
    u: __m512,
    v: __m512,
    prim: __m512i,
    tri: __m512i,
}

/// A packet's stack entry: a node, the rays that enter it and their entry distances.
#[derive(Clone, Copy)]
struct Entry {
    node: u32,
    rays: __mmask16,
    near: __m512,
}

impl CpuTree {
    /// The closest hits of sixteen rays (`0 < t < ∞`) for the lanes set in `active` (the others
    /// get `None`), walked as a hybrid packet: `closest_hit`'s hits to the bit.
    ///
    /// # Safety
    /// The processor must have AVX-512 F and DQ ([`available`]), and the tree no alpha-tested
    /// primitives and a stack bound within [`INLINE_STACK`] (the caller checks both).
    #[target_feature(enable = "avx512f,avx512dq")]
    pub(super) unsafe fn hybrid16(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        active: u16,
        switch: u32,
    ) -> [Option<TraceHit>; 16] {
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
        // obvhs' guarded reciprocal of the direction (`safe_inverse`: ±1/ε within ε of zero),
        // and the one-ray walk's `origin · inv` (a product rounded on its own).
        let sign = _mm512_set1_ps(-0.0);
        let inv = d.map(|d| {
            let tiny =
                _mm512_cmp_ps_mask::<_CMP_LE_OQ>(_mm512_abs_ps(d), _mm512_set1_ps(f32::EPSILON));
            let guarded = _mm512_or_ps(_mm512_and_ps(d, sign), _mm512_set1_ps(1.0 / f32::EPSILON));
            _mm512_mask_blend_ps(tiny, _mm512_div_ps(_mm512_set1_ps(1.0), d), guarded)
        });
        let oi = [0, 1, 2].map(|axis| _mm512_mul_ps(o[axis], inv[axis]));
        let mut p = Packet {
            o,
            d,
            inv,
            oi,
            neg: inv.map(|inv| _mm512_cmp_ps_mask::<_CMP_LT_OQ>(inv, _mm512_setzero_ps())),
            t: _mm512_set1_ps(f32::INFINITY),
            u: _mm512_setzero_ps(),
            v: _mm512_setzero_ps(),
            prim: _mm512_set1_epi32(-1),
            tri: _mm512_set1_epi32(0),
        };
        // The same per ray, for the rays that finish alone.
        let mut alone = [[0f32; 16]; 6];
        for (k, v) in inv.into_iter().chain(oi).enumerate() {
            // SAFETY: writes the local row of 16.
            unsafe { _mm512_storeu_ps(alone[k].as_mut_ptr(), v) };
        }
        let rays_alone: [NodeRay; 16] = std::array::from_fn(|i| {
            NodeRay::from_inverse(
                [alone[0][i], alone[1][i], alone[2][i]],
                [alone[3][i], alone[4][i], alone[5][i]],
            )
        });
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
            let rays = _mm512_cmp_ps_mask::<_CMP_LE_OQ>(e.near, p.t) & e.rays;
            if rays == 0 {
                continue;
            }
            if rays.count_ones() <= switch {
                self.finish_alone(&mut p, e.node as usize, rays, &rays_alone, origins, dirs);
                continue;
            }
            let node = &self.nodes[e.node as usize];
            // Every slot's box against the rays first, without a branch between them (an empty
            // slot's box is entered by no ray), so that the eight tests overlap.
            let mut nears = [_mm512_setzero_ps(); 8];
            let mut hits = [0u16; 8];
            for c in 0..8 {
                (nears[c], hits[c]) = enter(node, c, &p, rays);
            }
            let entered = (0..8).fold(0u32, |m, c| m | (u32::from(hits[c] != 0) << c));
            let mut leaves = entered & !node.imask;
            while leaves != 0 {
                let c = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let first = node.child[c];
                for prim in first..first + u32::from(node.count[c]) {
                    self.test_packet(&mut p, prim, hits[c]);
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
            _mm512_storeu_ps(t.as_mut_ptr(), p.t);
            _mm512_storeu_ps(u.as_mut_ptr(), p.u);
            _mm512_storeu_ps(v.as_mut_ptr(), p.v);
            _mm512_storeu_si512(prim.as_mut_ptr().cast(), p.prim);
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

    /// The rays `rays` of the packet walk below `node` alone ([`CpuTree::walk_closest`]), each
    /// from its closest hit so far, which they update.
    #[target_feature(enable = "avx512f,avx512dq")]
    fn finish_alone(
        &self,
        p: &mut Packet,
        node: usize,
        rays: __mmask16,
        alone: &[NodeRay; 16],
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
    ) {
        let (mut t, mut u, mut v, mut prim, mut tri) =
            ([0f32; 16], [0f32; 16], [0f32; 16], [0u32; 16], [0u32; 16]);
        // SAFETY: the loads and stores touch the local arrays of 16.
        unsafe {
            _mm512_storeu_ps(t.as_mut_ptr(), p.t);
            _mm512_storeu_ps(u.as_mut_ptr(), p.u);
            _mm512_storeu_ps(v.as_mut_ptr(), p.v);
            _mm512_storeu_si512(prim.as_mut_ptr().cast(), p.prim);
            _mm512_storeu_si512(tri.as_mut_ptr().cast(), p.tri);
        }
        let mut m = rays;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let mut best = (prim[i] != u32::MAX).then_some((t[i], u[i], v[i], prim[i]));
            self.walk_closest(
                node,
                &alone[i],
                origins[i],
                dirs[i],
                f32::INFINITY,
                &mut best,
                &|_, _, _| true,
            );
            if let Some(b) = best {
                (t[i], u[i], v[i], prim[i]) = b;
                tri[i] = self.triangle(b.3);
            }
        }
        // SAFETY: as above.
        unsafe {
            p.t = _mm512_loadu_ps(t.as_ptr());
            p.u = _mm512_loadu_ps(u.as_ptr());
            p.v = _mm512_loadu_ps(v.as_ptr());
            p.prim = _mm512_loadu_si512(prim.as_ptr().cast());
            p.tri = _mm512_loadu_si512(tri.as_ptr().cast());
        }
    }

    /// Primitive `prim` against the packet's rays `rays` ([`super::intersect_triangle_sided`]
    /// per lane, the same operations in the same order), each hit kept where it is nearer
    /// ([`super::nearer`]).
    #[target_feature(enable = "avx512f,avx512dq")]
    fn test_packet(&self, p: &mut Packet, prim: u32, rays: __mmask16) {
        let (v0, e1, e2) = self.prim(prim as usize);
        let cull = self.flags(prim as usize) & PRIM_CULL != 0;
        let n = e1.cross(e2);
        let splat = |v: Vec3| v.to_array().map(|x| _mm512_set1_ps(x));
        let (n, e1, e2, v0) = (splat(n), splat(e1), splat(e2), splat(v0));
        let (mul, sub, add) = (_mm512_mul_ps, _mm512_sub_ps, _mm512_add_ps);
        let dot = |a: [__m512; 3], b: [__m512; 3]| {
            add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]))
        };
        let d = p.d;
        let c = [sub(v0[0], p.o[0]), sub(v0[1], p.o[1]), sub(v0[2], p.o[2])];
        // glam's cross: y·z' − y'·z, z·x' − z'·x, x·y' − x'·y.
        let r = [
            sub(mul(c[1], d[2]), mul(d[1], c[2])),
            sub(mul(c[2], d[0]), mul(d[2], c[0])),
            sub(mul(c[0], d[1]), mul(d[0], c[1])),
        ];
        let den = dot(n, d);
        let (a, b, tn) = (dot(e2, r), dot(e1, r), dot(c, n));
        let zero = _mm512_setzero_ps();
        let sign = _mm512_set1_ps(-0.0);
        let abs_den = _mm512_abs_ps(den);
        let mut ok = _mm512_cmp_ps_mask::<_CMP_NEQ_OQ>(den, zero)
            & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(abs_den, _mm512_set1_ps(f32::INFINITY))
            & rays;
        if cull {
            ok &= !_mm512_cmp_ps_mask::<_CMP_GT_OQ>(den, zero);
        }
        let den_sign = _mm512_and_ps(den, sign);
        let us = _mm512_xor_ps(a, den_sign);
        let vs = _mm512_xor_ps(_mm512_xor_ps(b, sign), den_sign);
        let ts = _mm512_xor_ps(tn, den_sign);
        let met = ok
            & _mm512_cmp_ps_mask::<_CMP_GE_OQ>(us, zero)
            & _mm512_cmp_ps_mask::<_CMP_GE_OQ>(vs, zero)
            & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(add(us, vs), abs_den)
            & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(ts, zero);
        if met == 0 {
            return;
        }
        let inv = _mm512_div_ps(_mm512_set1_ps(1.0), den);
        let t = mul(tn, inv);
        // The bound of a nearer hit: t itself included once there is a hit (the one-ray
        // walk's `bound`; +∞ before).
        let found = _mm512_cmp_epu32_mask::<_MM_CMPINT_NE>(p.prim, _mm512_set1_epi32(-1));
        let next_up = std::arch::x86_64::_mm512_castsi512_ps(_mm512_add_epi32(
            std::arch::x86_64::_mm512_castps_si512(p.t),
            _mm512_set1_epi32(1),
        ));
        let bound = _mm512_mask_blend_ps(found, _mm512_set1_ps(f32::INFINITY), next_up);
        let hit = met
            & _mm512_cmp_ps_mask::<_CMP_GT_OQ>(t, zero)
            & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(t, bound);
        let tri = _mm512_set1_epi32(self.triangle(prim) as i32);
        let tie = _mm512_cmpgt_epu32_mask(tri, p.tri) | !found;
        let take = hit
            & (_mm512_cmp_ps_mask::<_CMP_LT_OQ>(t, p.t)
                | (_mm512_cmp_ps_mask::<_CMP_EQ_OQ>(t, p.t) & tie));
        if take == 0 {
            return;
        }
        p.t = _mm512_mask_blend_ps(take, p.t, t);
        p.u = _mm512_mask_blend_ps(take, p.u, mul(a, inv));
        p.v = _mm512_mask_blend_ps(take, p.v, _mm512_xor_ps(mul(b, inv), sign));
        p.prim = _mm512_mask_blend_epi32(take, p.prim, _mm512_set1_epi32(prim as i32));
        p.tri = _mm512_mask_blend_epi32(take, p.tri, tri);
    }
}

/// Child slot `c`'s box against the rays `rays`: their entry distances and the rays that
/// enter it no farther than their closest hit so far (the one-ray walk's slab test per lane:
/// each ray's near and far planes by its direction's signs, one fused multiply-subtract a
/// plane, [`NODE_EPSILON`] as the near bound).
#[target_feature(enable = "avx512f,avx512dq")]
fn enter(node: &CpuNode, c: usize, p: &Packet, rays: __mmask16) -> (__m512, __mmask16) {
    let plane = |axis: usize| {
        let lo = _mm512_fmsub_ps(
            _mm512_set1_ps(node.bounds[2 * axis][c]),
            p.inv[axis],
            p.oi[axis],
        );
        let hi = _mm512_fmsub_ps(
            _mm512_set1_ps(node.bounds[2 * axis + 1][c]),
            p.inv[axis],
            p.oi[axis],
        );
        (
            _mm512_mask_blend_ps(p.neg[axis], lo, hi),
            _mm512_mask_blend_ps(p.neg[axis], hi, lo),
        )
    };
    let (x, y, z) = (plane(0), plane(1), plane(2));
    let max = std::arch::x86_64::_mm512_max_ps;
    let min = std::arch::x86_64::_mm512_min_ps;
    let near = max(max(x.0, y.0), max(z.0, _mm512_set1_ps(NODE_EPSILON)));
    let far = min(min(x.1, y.1), min(z.1, p.t));
    (near, _mm512_cmp_ps_mask::<_CMP_LE_OQ>(near, far) & rays)
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
    /// processor without AVX-512 the public walk (one ray at a time there) is checked alone.
    #[test]
    fn packets_find_each_rays_hit() {
        let mut tris = random_triangles(1500, 5);
        tris.extend_from_within(..300);
        // Every third triangle single-sided.
        let sided: Vec<bool> = (0..tris.len()).map(|i| i % 3 == 1).collect();
        let bvh = SceneBvh::build_sided(&tris, &vec![0.0; tris.len()], &sided);
        let mut r = uniforms(23);
        let packets = available();
        let (mut hits, mut ties, mut packet_rounds) = (0, 0, 0);
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
            let mut got = vec![bvh.closest_hits16(&origins, &dirs, active)];
            if packets {
                let tree = bvh.cpu();
                assert!(tree.packets());
                for switch in [0, SWITCH, 16] {
                    // SAFETY: the processor has AVX-512 F and DQ (`available`), the scene no
                    // alpha-tested triangles, and its tree is shallow (asserted by `packets`).
                    got.push(unsafe { tree.hybrid16(&origins, &dirs, active, switch) });
                }
                packet_rounds += 1;
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
        eprintln!("packets compared in {packet_rounds} of 1500 rounds");
    }
}
