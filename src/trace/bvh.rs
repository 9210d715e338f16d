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
//! and traversal of the Tray Racing benchmark that `obvhs` was built for. The CPU twin walks a
//! tree of its own over the same triangles (`bvh/cpu.rs`: eight-wide nodes of f32 boxes, leaves
//! of up to eight triangles, one 8-wide test each), built from `prims` the first time a ray is
//! traced on the CPU; it finds the same hits ([`SceneBvh::closest_hit`]), in 15–20 % less time a
//! ray than walking this tree (BENCHMARKS.md, *CPU traversal*).
//!
//! Primitives are stored in BVH order (`prims`, three `vec4<f32>` each: `v0` and the original
//! triangle index, `e1 = v1 − v0` and the light-selection density, `e2 = v2 − v0` and the
//! primitive's flags as a small float — [`PRIM_CULL`] for a single-sided triangle, whose back
//! face rays pass through, plus [`PRIM_ALPHA`] for one whose material is alpha-masked or
//! blended, where the caller decides per hit whether the surface is there), so a leaf's
//! triangles are contiguous in memory.

use std::sync::OnceLock;

use glam::Vec3;
use obvhs::{BvhBuildParams, cwbvh::CwBvh, triangle::Triangle as ObvhsTriangle};

/// Primitive flag: single-sided (rays pass the back face).
pub const PRIM_CULL: u32 = 1;
/// Primitive flag: alpha-tested (MASK or BLEND): a hit counts only where the traversal's
/// coverage test says the surface is there.
pub const PRIM_ALPHA: u32 = 2;

/// The GPU's BVH and its primitives in BVH order, and the CPU's tree over the same triangles
/// (built when a ray is first traced on the CPU: a GPU render never needs it).
#[derive(Clone, Debug)]
pub struct SceneBvh {
    pub cwbvh: CwBvh,
    /// Three entries per BVH primitive: `[v0, orig]`, `[e1, light_density]`, `[e2, flags]`.
    pub prims: Vec<[f32; 4]>,
    cpu: OnceLock<cpu::CpuTree>,
}

/// A closest hit.
/// How the CPU twin walks the rays of neighbouring paths ([`SceneBvh::closest_hits16`],
/// [`SceneBvh::occluded16`]): each alone, or sixteen at a time as Embree's hybrid packets, in
/// AVX2 or AVX-512 lanes — the same hits to the bit. The fastest the processor runs unless
/// `RAYGUN_CPU_PACKETS` says otherwise ([`CpuPackets::from_env`]), to compare them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum CpuPackets {
    /// One ray at a time (`RAYGUN_CPU_PACKETS=0`).
    One,
    /// Packets of sixteen in pairs of AVX2 registers (`avx2`).
    Avx2,
    /// Packets of sixteen in AVX-512 lanes (`avx512`).
    Avx512,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceHit {
    pub t: f32,
    /// Barycentrics of `v1` and `v2`.
    pub u: f32,
    pub v: f32,
    /// The original triangle index (into `Scene::triangles`).
    pub triangle: u32,
    /// The primitive hit, in the CPU tree's order: [`SceneBvh::hit_prim`] gives its data.
    pub prim: u32,
}

/// The ray–triangle test: [`intersect_triangle_sided`] with both faces hit.
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

/// The ray–triangle test of the triangle `v0`, `v0 + e1`, `v0 + e2`, the same arithmetic as
/// `intersect_triangle` in `shaders/trace/bvh.wgsl`: (t, u, v) where `origin + t·dir = v0 +
/// u·e1 + v·e2` inside the triangle with `0 < t < tmax`. With `cull_back` (a single-sided glTF
/// material) the back face is no hit: the front face is the one `n = e1 × e2` points out of
/// (counter-clockwise winding), met when `dir·n < 0`.
///
/// Möller–Trumbore rearranged around the normal, as Embree's triangle test: with
/// `c = v0 − origin`, `r = c × dir` and `den = dir·n`, Cramer's rule gives `u = (e2·r)/den`,
/// `v = −(e1·r)/den`, `t = (c·n)/den`. Whether the ray's line meets the triangle in front of
/// the origin is decided on the numerators times den's sign, against `|den|` (`0 ≤ u`,
/// `0 ≤ v`, `u + v ≤ 1`, `0 < t`), with no division: a miss — most tests — costs none, and no
/// reciprocal sits on the chain to the decision (the walks ×0.94–0.98 in `cargo bench --bench
/// traversal`; the whole render unchanged within the noise: BENCHMARKS.md, *CPU traversal*). Only
/// then is t divided out and bounded, `0 < t < tmax`, in its own value: a closest-hit search
/// passes its nearest hit so far as `tmax`, so a triangle counts exactly when its own t beats
/// that hit, whatever order a traversal meets it in.
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
    let n = e1.cross(e2);
    let c = v0 - origin;
    let r = c.cross(dir);
    let den = n.dot(dir);
    let (a, b, tn) = (e2.dot(r), e1.dot(r), c.dot(n));
    let abs_den = den.abs();
    if den == 0.0 || !(abs_den < f32::INFINITY) || (cull_back && den > 0.0) {
        return None;
    }
    // The numerators times den's sign (a sign flip: exact).
    let sign = den.to_bits() & 0x8000_0000;
    let signed = |x: f32| f32::from_bits(x.to_bits() ^ sign);
    let (us, vs, ts) = (signed(a), signed(-b), signed(tn));
    if !(us >= 0.0 && vs >= 0.0 && us + vs <= abs_den && ts > 0.0) {
        return None;
    }
    let inv = 1.0 / den;
    let t = tn * inv;
    (t > 0.0 && t < tmax).then_some((t, a * inv, -(b * inv)))
}

/// obvhs' near-plane bound of the node test (`NODE_EPSILON` in bvh.wgsl).
pub(crate) const NODE_EPSILON: f32 = 0.0001;

mod cpu;

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
                cpu: OnceLock::new(),
            };
        }
        let tris = obvhs_triangles(triangles);
        let cwbvh = cwbvh_of(&tris);
        let mut prims = Vec::with_capacity(cwbvh.primitive_indices.len() * 3);
        for &orig in &cwbvh.primitive_indices {
            let t = &triangles[orig as usize];
            let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
            prims.push([t[0].x, t[0].y, t[0].z, f32::from_bits(orig)]);
            prims.push([e1.x, e1.y, e1.z, light_density[orig as usize]]);
            let f = flags.get(orig as usize).copied().unwrap_or(0);
            prims.push([e2.x, e2.y, e2.z, f as f32]);
        }
        Self {
            cwbvh,
            prims,
            cpu: OnceLock::new(),
        }
    }

    /// The most entries the GPU kernel's walk can hold on its stack in this tree: on its way
    /// down it pushes one (the children still to visit) at a node where it entered two or more
    /// inner children, so no more than the most such nodes above any node. A disc of 200 000
    /// slivers, 202 levels deep, needs 24; the kernel's stack holds 32.
    #[must_use]
    pub fn stack_entries(&self) -> u32 {
        let nodes = &self.cwbvh.nodes;
        if nodes.is_empty() {
            return 0;
        }
        let (mut most, mut todo) = (0u32, vec![(0usize, 0u32)]);
        while let Some((n, above)) = todo.pop() {
            most = most.max(above);
            let node = &nodes[n];
            let inner = node.imask.count_ones();
            let below = above + u32::from(inner >= 2);
            for k in 0..inner as usize {
                todo.push((node.child_base_idx as usize + k, below));
            }
        }
        most
    }

    /// Builds the CPU's tree now if it is not built yet: a renderer on the CPU twin does this
    /// before its first frame, so that no frame's time holds the one-time build.
    pub fn prepare_cpu(&self) {
        self.cpu();
    }

    /// Whether the CPU's tree has been built.
    #[must_use]
    pub fn cpu_ready(&self) -> bool {
        self.cpu.get().is_some()
    }

    /// The CPU's tree, built on first use.
    fn cpu(&self) -> &cpu::CpuTree {
        self.cpu.get_or_init(|| cpu::CpuTree::build(&self.prims))
    }

    /// The three entries (`[v0, triangle]`, `[e1, light density]`, `[e2, flags]`) of the
    /// primitive a [`TraceHit`] names (`prim`: in the CPU tree's order).
    #[must_use]
    pub fn hit_prim(&self, prim: u32) -> &[[f32; 4]] {
        let p = 3 * prim as usize;
        &self.cpu().prims[p..p + 3]
    }

    /// The closest hit along `origin + t·dir`, `0 < t < tmax`.
    #[must_use]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<TraceHit> {
        self.closest_hit_filtered(origin, dir, tmax, |_, _, _| true)
    }

    /// [`Self::closest_hit`] where a hit on an alpha-tested primitive ([`PRIM_ALPHA`]) counts
    /// only if `covered(triangle, u, v)` (the CPU twin of `alpha_covered` in path.wgsl).
    ///
    /// The walk is the CPU's, on its own tree (`bvh/cpu.rs`): a node's leaves first, then its
    /// inner children nearest entry first, and a node entered beyond the closest hit so far
    /// skipped (the GPU's kernel keeps obvhs' order by ray octant, which suits a GPU's
    /// lock-step lanes). The hit is the GPU's — the nearest one, with the same triangle
    /// arithmetic — except where two triangles are hit at exactly the same distance (a shared
    /// edge): here the higher triangle wins, whatever the order of the walk, on the GPU
    /// whichever its walk meets first; and where the two box tests round differently for a ray
    /// that grazes a box's face (the CPU's boxes are widened against that).
    #[must_use]
    pub fn closest_hit_filtered(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        covered: impl Fn(u32, f32, f32) -> bool,
    ) -> Option<TraceHit> {
        self.cpu().closest_hit_filtered(origin, dir, tmax, covered)
    }

    /// The closest hits of eight rays at once (`0 < t < ∞`), for the lanes set in `active`
    /// (the others get `None`): [`Self::closest_hit`]'s hits to the bit, for rays that travel
    /// together — a camera's rays through neighbouring pixels. The rays share the walk: a node
    /// is visited once for the rays that enter it, its eight boxes tested against all of them
    /// in lanes (a ray per lane), a leaf's triangles likewise (the same triangle test's
    /// arithmetic per lane as the one-ray test's), and a child is taken for the rays that
    /// enter its box, nearest first by its first ray's entry. One decision per node for eight rays
    /// instead of eight: measured faster for camera rays (×0.91–0.94 a whole render:
    /// BENCHMARKS.md, *CPU traversal*). Scenes with alpha-tested triangles take
    /// [`Self::closest_hit`] per ray.
    #[must_use]
    pub fn closest_hits8(
        &self,
        origins: &[Vec3; 8],
        dirs: &[Vec3; 8],
        active: u32,
    ) -> [Option<TraceHit>; 8] {
        self.cpu().closest_hits8(origins, dirs, active)
    }

    /// Whether [`Self::closest_hits16`] walks its rays as packets here ([`CpuPackets::current`]
    /// is not one ray at a time, and the scene has no alpha-tested triangles); otherwise it
    /// walks them one at a time, as [`Self::closest_hit`].
    #[must_use]
    pub fn packets(&self) -> bool {
        self.cpu().packets()
    }

    /// The closest hits of sixteen rays (`0 < t < ∞`) for the lanes set in `active` (the
    /// others get `None`): [`Self::closest_hit`]'s hits to the bit. Where the processor has
    /// AVX-512, the rays are walked together as long as more than seven of them enter a node,
    /// then each alone (Embree's hybrid traversal, `bvh/cpu/hybrid.rs`): for rays that start
    /// near each other, such as a bounce's from neighbouring pixels; with AVX2 alone, the same
    /// packets in pairs of AVX2 registers. With `RAYGUN_CPU_PACKETS=0` ([`CpuPackets`]), and for
    /// scenes with alpha-tested triangles, one ray at a time.
    #[must_use]
    pub fn closest_hits16(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        active: u16,
    ) -> [Option<TraceHit>; 16] {
        self.cpu().closest_hits16(origins, dirs, active)
    }

    /// Whether something blocks each of sixteen shadow rays `origins[i] + t·dirs[i]`, `0 < t <
    /// tmax[i]`, for the lanes set in `active`: a bit set per blocked ray, [`Self::occluded`]'s
    /// answers. Walked as a hybrid packet where [`Self::packets`] says so (rays from
    /// neighbouring points share the top of the tree), elsewhere one ray at a time.
    #[must_use]
    pub fn occluded16(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        tmax: &[f32; 16],
        active: u16,
    ) -> u16 {
        self.cpu().occluded16(origins, dirs, tmax, active)
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
        self.cpu().occluded_filtered(origin, dir, tmax, covered)
    }
}

/// The GPU's tree over `tris`: obvhs' `build_cwbvh_from_tris` with its `slow_build` preset —
/// spatial pre-splits, PLOC, reinsertion, collapsed into eight-wide nodes of up to three
/// triangles a leaf — step for step (the same tree), without its debug builds' validation.
/// That asserts the tree is under 32 levels deep — obvhs' own traversal pushes every level —
/// where raygun's kernel pushes only where it enters two inner children
/// ([`SceneBvh::stack_entries`]), and real meshes are deeper: a disc of 10 000 slivers about a
/// centre, as CAD tessellates a fine circle, is 32 levels, 20 000 are 48, so a debug build
/// panicked on loading them. The tests check this tree's hits against brute force, and the
/// tree against obvhs' own build.
fn cwbvh_of(tris: &[ObvhsTriangle]) -> CwBvh {
    let config = BvhBuildParams::slow_build();
    let (mut largest_half_area, mut avg_area) = (0.0f32, 0.0f32);
    let mut aabbs: Vec<_> = tris
        .iter()
        .map(|t| {
            let aabb = t.aabb();
            let half_area = aabb.half_area();
            largest_half_area = half_area.max(largest_half_area);
            avg_area += half_area;
            aabb
        })
        .collect();
    let mut indices: Vec<u32> = (0..tris.len() as u32).collect();
    avg_area /= tris.len() as f32;
    obvhs::splits::split_aabbs_preset(&mut aabbs, &mut indices, tris, avg_area, largest_half_area);
    let mut bvh2 = obvhs::ploc::PlocBuilder::with_capacity(aabbs.len()).build(
        config.ploc_search_distance,
        &aabbs,
        indices,
        config.sort_precision,
        config.search_depth_threshold,
    );
    bvh2.uses_spatial_splits = config.pre_split;
    obvhs::bvh2::reinsertion::ReinsertionOptimizer::default().run(
        &mut bvh2,
        config.reinsertion_batch_ratio,
        None,
    );
    obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh(
        &bvh2,
        config.max_prims_per_leaf.clamp(1, 3),
        true,
        false,
    )
}

/// `triangles` as obvhs' triangles.
fn obvhs_triangles(triangles: &[[Vec3; 3]]) -> Vec<ObvhsTriangle> {
    triangles
        .iter()
        .map(|t| ObvhsTriangle {
            v0: t[0].into(),
            v1: t[1].into(),
            v2: t[2].into(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A brute-force oracle over the same triangles.
    pub(super) fn brute(tris: &[[Vec3; 3]], o: Vec3, d: Vec3) -> Option<(f32, u32)> {
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
    pub(super) fn uniforms(seed: u32) -> impl FnMut() -> f32 {
        let mut k = 0u32;
        move || {
            k += 1;
            crate::random::unit_f32(crate::random::pcg4d([k, seed, 0, 0])[0])
        }
    }

    pub(super) fn random_triangles(n: usize, seed: u32) -> Vec<[Vec3; 3]> {
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

    /// The triangle test against Cramer's rule in f64: wherever the exact answer is clear of
    /// the test's edges (the barycentrics, t against 0 and tmax) by a margin, the f32 test
    /// agrees whether the ray hits and gives t, u, v to 1e-4; a single-sided triangle is hit
    /// from the front only; a ray in the triangle's plane misses.
    #[test]
    fn the_triangle_test_agrees_with_an_exact_solve() {
        let mut r = uniforms(5);
        let (mut hits, mut misses, mut culled) = (0, 0, 0);
        for _ in 0..20_000 {
            let v0 = Vec3::new(r(), r(), r()) * 4.0 - 2.0;
            let (e1, e2) = (
                Vec3::new(r(), r(), r()) - 0.5,
                Vec3::new(r(), r(), r()) - 0.5,
            );
            let o = Vec3::new(r(), r(), r()) * 6.0 - 3.0;
            // Towards a point near the triangle, so that about half the rays hit.
            let aim = v0 + e1 * (1.6 * r() - 0.3) + e2 * (1.6 * r() - 0.3);
            let d = (aim - o).normalize();
            let tmax = 0.5 + 6.0 * r();
            let f = |v: Vec3| v.as_dvec3();
            let (dd, de1, de2, tv) = (f(d), f(e1), f(e2), f(o) - f(v0));
            let det = -dd.dot(de1.cross(de2));
            if det.abs() < 1e-3 {
                continue;
            }
            // o + t·d = v0 + u·e1 + v·e2: [−d e1 e2]·(t, u, v) = o − v0.
            let col = |a: glam::DVec3, b: glam::DVec3, c: glam::DVec3| a.dot(b.cross(c));
            let t = col(tv, de1, de2) / det;
            let u = col(-dd, tv, de2) / det;
            let v = col(-dd, de1, tv) / det;
            let margin = u.min(v).min(1.0 - u - v).min(t).min(f64::from(tmax) - t);
            let got = intersect_triangle(o, d, v0, e1, e2, tmax);
            if margin > 1e-4 {
                let (gt, gu, gv) = got.expect("a clear hit is found");
                for (g, w) in [(gt, t), (gu, u), (gv, v)] {
                    assert!(
                        (f64::from(g) - w).abs() < 1e-4 * w.abs().max(1.0),
                        "{g} vs {w}"
                    );
                }
                hits += 1;
                // Single-sided: the front face is the one e1 × e2 points out of.
                let front = d.dot(e1.cross(e2)) < 0.0;
                let sided = intersect_triangle_sided(o, d, v0, e1, e2, tmax, true);
                assert_eq!(sided.is_some(), front);
                culled += usize::from(!front);
            } else if margin < -1e-4 {
                assert!(got.is_none(), "a clear miss is missed: t {t} u {u} v {v}");
                misses += 1;
            }
        }
        assert!(
            hits > 1000 && misses > 3000 && culled > 300,
            "{hits} {misses} {culled}"
        );
        // In the triangle's plane: no hit, however the edges lie.
        let (v0, e1, e2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        assert!(intersect_triangle(Vec3::new(-1.0, 0.2, 0.0), Vec3::X, v0, e1, e2, 9.0).is_none());
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

    /// The GPU's tree is obvhs' own `slow_build`, node for node and primitive for primitive.
    #[test]
    fn the_gpu_tree_is_obvhs_own_build() {
        let tris = random_triangles(1500, 5);
        let ours = SceneBvh::build(&tris, &vec![0.0; tris.len()]).cwbvh;
        let theirs = obvhs::cwbvh::builder::build_cwbvh_from_tris(
            &obvhs_triangles(&tris),
            BvhBuildParams::slow_build(),
            &mut std::time::Duration::default(),
        );
        let bytes = |n: &[obvhs::cwbvh::node::CwBvhNode]| bytemuck::cast_slice::<_, u8>(n).to_vec();
        assert!(bytes(&ours.nodes) == bytes(&theirs.nodes));
        assert_eq!(ours.primitive_indices, theirs.primitive_indices);
    }

    /// A disc of thin slivers about its centre, as CAD tessellates a fine circle.
    pub(crate) fn fan(n: usize) -> Vec<[Vec3; 3]> {
        let at = |i: usize| {
            let a = i as f32 / n as f32 * std::f32::consts::TAU;
            Vec3::new(a.cos(), a.sin(), 0.0) * 100.0
        };
        (0..n).map(|i| [Vec3::ZERO, at(i), at(i + 1)]).collect()
    }

    /// A tree deeper than obvhs' own traversal allows (its debug builds asserted under 32
    /// levels): it builds, says how deep its GPU walks push, and finds every hit.
    #[test]
    fn a_fan_of_slivers_builds_a_deep_tree_that_finds_every_hit() {
        let tris = fan(20_000);
        let bvh = SceneBvh::build(&tris, &vec![0.0; tris.len()]);
        let mut levels = 0;
        let mut todo = vec![(0usize, 1)];
        while let Some((n, level)) = todo.pop() {
            levels = levels.max(level);
            let node = &bvh.cwbvh.nodes[n];
            for k in 0..node.imask.count_ones() as usize {
                todo.push((node.child_base_idx as usize + k, level + 1));
            }
        }
        assert!(
            levels > 40,
            "the test needs a tree over 32 levels deep ({levels})"
        );
        // Its walks push far fewer entries than it has levels.
        let entries = bvh.stack_entries();
        assert!((1..=24).contains(&entries), "{entries} entries");
        let mut r = uniforms(23);
        let mut hits = 0;
        for _ in 0..300 {
            let o = Vec3::new(r() * 220.0 - 110.0, r() * 220.0 - 110.0, 5.0);
            let d = Vec3::new(r() - 0.5, r() - 0.5, -4.0).normalize();
            let want = brute(&tris, o, d);
            let got = bvh.closest_hit(o, d, f32::INFINITY);
            assert_eq!(got.map(|h| (h.t, h.triangle)), want, "ray {o} {d}");
            hits += usize::from(want.is_some());
        }
        assert!(hits > 100, "the test must exercise hits ({hits})");
    }

    /// A spine of `k` nodes, each but the last with two inner children — the next spine node
    /// and a childless node: a walk down it pushes at every spine node but the last.
    fn spine(k: usize) -> Vec<obvhs::cwbvh::node::CwBvhNode> {
        use obvhs::cwbvh::node::CwBvhNode;
        let mut nodes = vec![CwBvhNode::default(); 2 * k - 1];
        for j in 0..k - 1 {
            nodes[2 * j].imask = 0b11;
            // A childless node, then the next spine node.
            nodes[2 * j].child_base_idx = 2 * j as u32 + 1;
        }
        nodes
    }

    #[test]
    fn stack_entries_count_the_branching_nodes_above_the_deepest() {
        let mut bvh = SceneBvh::build(&random_triangles(10, 1), &[0.0; 10]);
        for k in [1, 2, 5, 40] {
            bvh.cwbvh.nodes = spine(k);
            assert_eq!(bvh.stack_entries(), k as u32 - 1, "a spine of {k}");
        }
        // One child a level pushes nothing, however deep.
        bvh.cwbvh.nodes = vec![obvhs::cwbvh::node::CwBvhNode::default(); 50];
        for j in 0..49 {
            bvh.cwbvh.nodes[j].imask = 0b1;
            bvh.cwbvh.nodes[j].child_base_idx = j as u32 + 1;
        }
        assert_eq!(bvh.stack_entries(), 0);
        assert_eq!(SceneBvh::build(&[], &[]).stack_entries(), 0);
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
