//! Sixteen rays walked together while enough of them go the same way, in AVX-512 lanes or in
//! pairs of AVX2 registers: Embree's hybrid traversal (`BVHNIntersectorKHybrid<8, 16>`, the
//! walk Mitsuba's `llvm_ad_rgb` takes on a processor with AVX-512), on the CPU tree, for
//! closest hits and for shadow rays. The walks are written once over the lanes
//! ([`lanes::Lanes`]).
//!
//! A node popped for the packet is tested against all its rays that still enter it, child by
//! child, a ray per lane (one child's box against sixteen rays is one set of vector
//! operations, two in AVX2, where the one-ray walk spends one on a node's eight boxes for one
//! ray); a leaf's triangles likewise, one triangle against sixteen rays. Once a node is entered
//! by [`SWITCH`] rays or fewer, each of them finishes the subtree alone with the one-ray walk
//! ([`CpuTree::walk_closest`], [`CpuTree::walk_any`]), a closest hit from its closest hit so
//! far. The results are the one-ray walks' to the bit: the same triangle arithmetic lane by
//! lane (no fused operations: glam's cross and dot products, as
//! [`super::intersect_triangle_sided`] computes them), and the same rule for exact ties
//! ([`super::nearer`]), which makes a closest hit independent of the order in which a walk
//! meets the triangles.
//!
//! Where it pays: rays that start near each other — a bounce's or a shadow ray's from
//! neighbouring pixels — share the top of the tree, which a packet visits once (×0.815–0.878 a
//! whole render against one-ray walks: BENCHMARKS.md, *CPU traversal*).
//! The AVX-512 walks are compiled for AVX-512 F and DQ and run only where the processor has
//! them ([`available`]); the AVX2 walks need only what the whole build targets (AVX2 and FMA).
//! `CpuTree::packet_walks` says which a process takes.

use std::arch::x86_64::{_CMP_EQ_OQ, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_NEQ_OQ};
use std::mem::MaybeUninit;

use glam::Vec3;

#[cfg(all(target_feature = "avx2", target_feature = "fma"))]
use self::lanes::Avx2Pair;
use self::lanes::{Avx512, Lanes};
use super::{CpuNode, CpuTree, INLINE_STACK, NODE_EPSILON, NodeRay, PRIM_CULL, Segment, TraceHit};

mod lanes;

/// A node entered by this many of a packet's sixteen rays or fewer is walked by each of them
/// alone: below it, testing a child's box for the packet costs more than the rays' own walks.
/// Embree's hybrid switches at 7 of 16 as well (in AVX-512, 4 measured the same and 10 slower,
/// ×1.04; in AVX2, 5 and 10 the same: BENCHMARKS.md, *CPU traversal*).
pub(crate) const SWITCH: u32 = 7;

/// Whether this processor runs the sixteen-ray packets (AVX-512 F and DQ).
pub(crate) fn available() -> bool {
    std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx512dq")
}

/// A packet's rays in lanes, and each one's own for the walks alone.
struct Rays<L: Lanes> {
    o: [L::F; 3],
    d: [L::F; 3],
    /// obvhs' guarded reciprocal of the direction, and `origin · inv` (rounded on its own).
    inv: [L::F; 3],
    oi: [L::F; 3],
    /// The lanes whose direction is negative on the axis (their near plane is the max).
    neg: [L::M; 3],
    /// `inv` and `oi` by lane, for a ray's walk alone ([`alone`]).
    each: [[f32; 16]; 6],
}

impl<L: Lanes> Rays<L> {
    /// The rays `origins[i] + t·dirs[i]`, in lanes of sixteen.
    #[inline(always)]
    fn new(l: L, origins: &[Vec3; 16], dirs: &[Vec3; 16]) -> Self {
        const { assert!(L::WIDTH == 16, "the walks take sixteen rays") };
        let mut rows = [[0f32; 16]; 6];
        for i in 0..16 {
            for axis in 0..3 {
                rows[axis][i] = origins[i][axis];
                rows[3 + axis][i] = dirs[i][axis];
            }
        }
        let row = |k: usize| l.load(&rows[k]);
        let (o, d) = ([row(0), row(1), row(2)], [row(3), row(4), row(5)]);
        // `safe_inverse`: ±1/ε (exact: ε is a power of two) within ε of zero, else 1/x. (No
        // `array::map` here or below: its closures are functions of their own, compiled without
        // the caller's AVX-512, and were not inlined — measured 20 % slower.)
        let sign = l.splat(-0.0);
        let safe_inverse = |d: L::F| {
            let tiny = l.cmp::<_CMP_LE_OQ>(l.abs(d), l.splat(f32::EPSILON));
            let guarded = l.or(l.and(d, sign), l.splat(1.0 / f32::EPSILON));
            l.blend(tiny, l.div(l.splat(1.0), d), guarded)
        };
        let inv = [safe_inverse(d[0]), safe_inverse(d[1]), safe_inverse(d[2])];
        let oi = [
            l.mul(o[0], inv[0]),
            l.mul(o[1], inv[1]),
            l.mul(o[2], inv[2]),
        ];
        let mut each = [[0f32; 16]; 6];
        for k in 0..3 {
            l.store(inv[k], &mut each[k]);
            l.store(oi[k], &mut each[3 + k]);
        }
        let negative = |inv: L::F| l.cmp::<_CMP_LT_OQ>(inv, l.splat(0.0));
        Self {
            o,
            d,
            inv,
            oi,
            neg: [negative(inv[0]), negative(inv[1]), negative(inv[2])],
            each,
        }
    }

    /// Every slot's box of `node` against the rays `rays` (no branch between them, so that the
    /// eight tests overlap): per slot the rays' entry distances and the rays that enter it no
    /// farther than `bound` — the one-ray walk's slab test per lane: each ray's near and far
    /// planes by its direction's signs, one fused multiply-subtract a plane, [`NODE_EPSILON`]
    /// as the near bound; an empty slot's box is entered by no ray.
    #[inline(always)]
    fn enter8(&self, l: L, node: &CpuNode, rays: u32, bound: L::F) -> ([L::F; 8], [u32; 8]) {
        let mut nears = [l.splat(0.0); 8];
        let mut hits = [0u32; 8];
        for c in 0..8 {
            let plane = |axis: usize| {
                let t = |row: usize| {
                    l.fmsub(
                        l.splat(node.bounds[2 * axis + row][c]),
                        self.inv[axis],
                        self.oi[axis],
                    )
                };
                let (lo, hi) = (t(0), t(1));
                (
                    l.blend(self.neg[axis], lo, hi),
                    l.blend(self.neg[axis], hi, lo),
                )
            };
            let (x, y, z) = (plane(0), plane(1), plane(2));
            let near = l.max(l.max(x.0, y.0), l.max(z.0, l.splat(NODE_EPSILON)));
            let far = l.min(l.min(x.1, y.1), l.min(z.1, bound));
            nears[c] = near;
            hits[c] = l.bits(l.cmp::<_CMP_LE_OQ>(near, far)) & rays;
        }
        (nears, hits)
    }
}

/// Lane `i`'s [`NodeRay`] from the packet's reciprocal directions and `origin · inv` by lane.
#[inline(always)]
fn alone(each: &[[f32; 16]; 6], i: usize) -> NodeRay {
    NodeRay::from_inverse(
        [each[0][i], each[1][i], each[2][i]],
        [each[3][i], each[4][i], each[5][i]],
    )
}

/// The slots of eight whose rays are not none.
#[inline(always)]
fn entered(hits: &[u32; 8]) -> u32 {
    (0..8).fold(0u32, |m, c| m | (u32::from(hits[c] != 0) << c))
}

/// The closest hits so far of a packet's rays: t (the nodes' bound: +∞ before a hit), u, v,
/// the primitive (`u32::MAX`: none yet) and its triangle.
struct Closest<L: Lanes> {
    t: L::F,
    u: L::F,
    v: L::F,
    prim: L::I,
    tri: L::I,
}

/// [`Closest`] lane by lane, for the rays' walks alone.
struct ClosestLanes {
    t: [f32; 16],
    u: [f32; 16],
    v: [f32; 16],
    prim: [u32; 16],
    tri: [u32; 16],
}

impl<L: Lanes> Closest<L> {
    #[inline(always)]
    fn lanes(&self, l: L) -> ClosestLanes {
        let mut out = ClosestLanes {
            t: [0.0; 16],
            u: [0.0; 16],
            v: [0.0; 16],
            prim: [0; 16],
            tri: [0; 16],
        };
        l.store(self.t, &mut out.t);
        l.store(self.u, &mut out.u);
        l.store(self.v, &mut out.v);
        l.store_i(self.prim, &mut out.prim);
        l.store_i(self.tri, &mut out.tri);
        out
    }

    #[inline(always)]
    fn from_lanes(l: L, c: &ClosestLanes) -> Self {
        Self {
            t: l.load(&c.t),
            u: l.load(&c.u),
            v: l.load(&c.v),
            prim: l.load_i(&c.prim),
            tri: l.load_i(&c.tri),
        }
    }
}

/// A closest-hit packet's stack entry: a node, the rays that enter it and their entry
/// distances.
#[derive(Clone, Copy)]
struct Entry<F: Copy> {
    node: u32,
    rays: u32,
    near: F,
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
        // SAFETY: the caller's promise.
        let l = unsafe { Avx512::assume() };
        self.packet_closest(l, origins, dirs, u32::from(active), switch)
    }

    /// [`Self::hybrid16`] in pairs of AVX2 registers, on any processor this build runs on. The
    /// tree must have no alpha-tested primitives and a stack bound within [`INLINE_STACK`]
    /// (`CpuTree::packets`; checked in debug builds).
    #[cfg(all(target_feature = "avx2", target_feature = "fma"))]
    pub(super) fn hybrid16_avx2(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        active: u16,
        switch: u32,
    ) -> [Option<TraceHit>; 16] {
        debug_assert!(!self.lanes.alpha && self.stack_size <= INLINE_STACK);
        self.packet_closest(Avx2Pair::new(), origins, dirs, u32::from(active), switch)
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
        // SAFETY: the caller's promise.
        let l = unsafe { Avx512::assume() };
        self.packet_occluded(l, origins, dirs, tmax, u32::from(active), switch) as u16
    }

    /// [`Self::hybrid_occluded16`] in pairs of AVX2 registers, as [`Self::hybrid16_avx2`].
    #[cfg(all(target_feature = "avx2", target_feature = "fma"))]
    pub(super) fn hybrid_occluded16_avx2(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        tmax: &[f32; 16],
        active: u16,
        switch: u32,
    ) -> u16 {
        debug_assert!(!self.lanes.alpha && self.stack_size <= INLINE_STACK);
        let l = Avx2Pair::new();
        self.packet_occluded(l, origins, dirs, tmax, u32::from(active), switch) as u16
    }

    /// The hybrid walk for closest hits in `L`'s lanes: each ray's hit.
    #[inline(always)]
    fn packet_closest<L: Lanes>(
        &self,
        l: L,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        active: u32,
        switch: u32,
    ) -> [Option<TraceHit>; 16] {
        let r = Rays::new(l, origins, dirs);
        let mut best = Closest::<L> {
            t: l.splat(f32::INFINITY),
            u: l.splat(0.0),
            v: l.splat(0.0),
            prim: l.splat_i(u32::MAX),
            tri: l.splat_i(0),
        };
        let mut stack = [const { MaybeUninit::<Entry<L::F>>::uninit() }; INLINE_STACK];
        stack[0].write(Entry {
            node: 0,
            rays: active,
            near: l.splat(f32::NEG_INFINITY),
        });
        let mut len = 1;
        while len > 0 {
            len -= 1;
            // SAFETY: every entry below `len` was written by a push.
            let e = unsafe { stack[len].assume_init() };
            // The rays still to enter: their entry is not beyond their closest hit so far.
            let rays = l.bits(l.cmp::<_CMP_LE_OQ>(e.near, best.t)) & e.rays;
            if rays == 0 {
                continue;
            }
            if rays.count_ones() <= switch {
                let mut lanes = best.lanes(l);
                self.closest_alone(&mut lanes, e.node as usize, rays, &r.each, origins, dirs);
                best = Closest::from_lanes(l, &lanes);
                continue;
            }
            let node = &self.nodes[e.node as usize];
            let (nears, hits) = r.enter8(l, node, rays, best.t);
            let entered = entered(&hits);
            let mut leaves = entered & !node.imask;
            while leaves != 0 {
                let c = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let first = node.child[c];
                for prim in first..first + u32::from(node.count[c]) {
                    self.closest_packet(l, &mut best, &r, prim, hits[c]);
                }
            }
            let mut inner = entered & node.imask;
            let mut keys = [0u64; 8];
            let mut n_inner = 0;
            while inner != 0 {
                let c = inner.trailing_zeros() as usize;
                inner &= inner - 1;
                // The nearest ray's entry (positive: the bits order as the values) over the slot.
                let nearest = l.reduce_min(hits[c], nears[c]);
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
        let found = best.lanes(l);
        std::array::from_fn(|i| {
            (active & (1 << i) != 0 && found.prim[i] != u32::MAX).then(|| TraceHit {
                t: found.t[i],
                u: found.u[i],
                v: found.v[i],
                triangle: found.tri[i],
                prim: found.prim[i],
            })
        })
    }

    /// The hybrid walk for shadow rays in `L`'s lanes: a bit set per blocked ray.
    #[inline(always)]
    fn packet_occluded<L: Lanes>(
        &self,
        l: L,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        tmax: &[f32; 16],
        active: u32,
        switch: u32,
    ) -> u32 {
        let r = Rays::new(l, origins, dirs);
        let bound = l.load(tmax);
        let mut blocked = 0u32;
        let mut stack = [MaybeUninit::<(u32, u32)>::uninit(); INLINE_STACK];
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
                    if self.walk_any(
                        index as usize,
                        &alone(&r.each, i),
                        o,
                        d,
                        tmax[i],
                        &|_, _, _| true,
                    ) {
                        blocked |= 1 << i;
                    }
                }
                continue;
            }
            let node = &self.nodes[index as usize];
            let (_, hits) = r.enter8(l, node, rays, bound);
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
                    let (met, [den, _, _, tn]) = self.meets_packet(l, &r, prim, want);
                    if l.bits(met) != 0 {
                        let t = l.mul(tn, l.div(l.splat(1.0), den));
                        let ahead = l.and_m(
                            l.cmp::<_CMP_GT_OQ>(t, l.splat(0.0)),
                            l.cmp::<_CMP_LT_OQ>(t, bound),
                        );
                        blocked |= l.bits(l.and_m(met, ahead));
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

    /// The rays `rays` of a packet (their node rays in `each`) walk below `node` alone
    /// ([`CpuTree::walk_closest`]), each from its closest hit so far in `best`, which they
    /// update.
    fn closest_alone(
        &self,
        best: &mut ClosestLanes,
        node: usize,
        rays: u32,
        each: &[[f32; 16]; 6],
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
    ) {
        let mut m = rays;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let mut hit = (best.prim[i] != u32::MAX).then_some((
                best.t[i],
                best.u[i],
                best.v[i],
                best.prim[i],
            ));
            let segment = Segment {
                origin: origins[i],
                dir: dirs[i],
                tmax: f32::INFINITY,
            };
            self.walk_closest(node, &alone(each, i), segment, &mut hit, &|_, _, _| true);
            if let Some(h) = hit {
                (best.t[i], best.u[i], best.v[i], best.prim[i]) = h;
                best.tri[i] = self.triangle(h.3);
            }
        }
    }

    /// [`super::intersect_triangle_sided`]'s first decision for primitive `prim` against the
    /// rays `rays`, the same operations in the same order per lane: the rays whose line meets
    /// the triangle in front of the origin, and per lane den, e2·r, e1·r and c·n, from which t,
    /// u and v follow. No division.
    #[inline(always)]
    fn meets_packet<L: Lanes>(&self, l: L, r: &Rays<L>, prim: u32, rays: u32) -> (L::M, [L::F; 4]) {
        let (v0, e1, e2) = self.prim(prim as usize);
        let cull = self.flags(prim as usize) & PRIM_CULL != 0;
        let n = e1.cross(e2);
        let splat = |v: Vec3| [l.splat(v.x), l.splat(v.y), l.splat(v.z)];
        let (n, e1, e2, v0) = (splat(n), splat(e1), splat(e2), splat(v0));
        let mul = |a: L::F, b: L::F| l.mul(a, b);
        let sub = |a: L::F, b: L::F| l.sub(a, b);
        let add = |a: L::F, b: L::F| l.add(a, b);
        let dot = |a: [L::F; 3], b: [L::F; 3]| {
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
        let zero = l.splat(0.0);
        let sign = l.splat(-0.0);
        let abs_den = l.abs(den);
        let mut ok = l.and_m(
            l.and_m(
                l.cmp::<_CMP_NEQ_OQ>(den, zero),
                l.cmp::<_CMP_LT_OQ>(abs_den, l.splat(f32::INFINITY)),
            ),
            l.mask(rays),
        );
        if cull {
            ok = l.andnot_m(l.cmp::<_CMP_GT_OQ>(den, zero), ok);
        }
        // The numerators times den's sign (a sign flip, as the scalar test's).
        let den_sign = l.and(den, sign);
        let us = l.xor(a, den_sign);
        let vs = l.xor(l.xor(b, sign), den_sign);
        let ts = l.xor(tn, den_sign);
        let inside = l.and_m(
            l.and_m(l.cmp::<_CMP_GE_OQ>(us, zero), l.cmp::<_CMP_GE_OQ>(vs, zero)),
            l.and_m(
                l.cmp::<_CMP_LE_OQ>(add(us, vs), abs_den),
                l.cmp::<_CMP_GT_OQ>(ts, zero),
            ),
        );
        (l.and_m(ok, inside), [den, a, b, tn])
    }

    /// Primitive `prim` against the packet's rays `rays` ([`super::intersect_triangle_sided`]
    /// per lane), each hit kept in `best` where it is nearer ([`super::nearer`]).
    #[inline(always)]
    fn closest_packet<L: Lanes>(
        &self,
        l: L,
        best: &mut Closest<L>,
        r: &Rays<L>,
        prim: u32,
        rays: u32,
    ) {
        let (met, [den, a, b, tn]) = self.meets_packet(l, r, prim, rays);
        if l.bits(met) == 0 {
            return;
        }
        let zero = l.splat(0.0);
        let inv = l.div(l.splat(1.0), den);
        let t = l.mul(tn, inv);
        // The bound of a nearer hit: t itself included once there is a hit (the one-ray
        // walk's `bound`; +∞ before).
        let none = l.eq_i(best.prim, l.splat_i(u32::MAX));
        let next_up = l.as_f(l.add_i(l.as_i(best.t), l.splat_i(1)));
        let bound = l.blend(none, next_up, l.splat(f32::INFINITY));
        let hit = l.and_m(
            met,
            l.and_m(l.cmp::<_CMP_GT_OQ>(t, zero), l.cmp::<_CMP_LT_OQ>(t, bound)),
        );
        let tri = l.splat_i(self.triangle(prim));
        let tie = l.or_m(l.gt_u(tri, best.tri), none);
        let nearer = l.or_m(
            l.cmp::<_CMP_LT_OQ>(t, best.t),
            l.and_m(l.cmp::<_CMP_EQ_OQ>(t, best.t), tie),
        );
        let take = l.and_m(hit, nearer);
        if l.bits(take) == 0 {
            return;
        }
        best.t = l.blend(take, best.t, t);
        best.u = l.blend(take, best.u, l.mul(a, inv));
        best.v = l.blend(take, best.v, l.xor(l.mul(b, inv), l.splat(-0.0)));
        best.prim = l.blend_i(take, best.prim, l.splat_i(prim));
        best.tri = l.blend_i(take, best.tri, tri);
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::super::super::tests::{random_triangles, uniforms};
    use super::super::super::{CpuPackets, SceneBvh};
    use super::*;

    /// The packets give each ray the one-ray walk's closest hit to the bit (t, u, v,
    /// primitive's triangle), with the switch to one-ray walks at every threshold — never
    /// (every node and leaf tested for the packet), at 7, and always (every ray alone from the
    /// root) — on rays from one point through a small window (a camera's, where the packet
    /// stays whole down to the leaves), from nearby points in all directions (a bounce's) and
    /// from everywhere, with lanes switched off; single-sided triangles seen from both sides;
    /// triangles given twice, every hit on them an exact tie, which the higher one wins. The
    /// AVX2 packets directly and through the public walk, the AVX-512 ones where the processor
    /// has AVX-512, the one-ray fallback everywhere.
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
            #[cfg(all(target_feature = "avx2", target_feature = "fma"))]
            {
                got.push(CpuPackets::Avx2.during(|| bvh.closest_hits16(&origins, &dirs, active)));
                for switch in [0, SWITCH, 16] {
                    got.push(tree.hybrid16_avx2(&origins, &dirs, active, switch));
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

    /// The shadow-ray packets in AVX-512 and in AVX2 (and their one-ray fallback) answer as the
    /// one-ray walk does, with the switch never, at [`SWITCH`] and always: rays
    /// from one point, from nearby points and from everywhere, each with its own length —
    /// unbounded, ending just before its closest hit (not blocked, unless another triangle is
    /// nearer), exactly there (not blocked by it: `t < tmax`), just beyond it, or far short —
    /// and lanes switched off.
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
            #[cfg(all(target_feature = "avx2", target_feature = "fma"))]
            {
                got.push(
                    CpuPackets::Avx2.during(|| bvh.occluded16(&origins, &dirs, &tmax, active)),
                );
                for switch in [0, SWITCH, 16] {
                    let tree = bvh.cpu();
                    got.push(tree.hybrid_occluded16_avx2(&origins, &dirs, &tmax, active, switch));
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
