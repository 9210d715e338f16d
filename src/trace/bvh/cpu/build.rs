//! How [`CpuTree`] is built: obvhs' BVH2 of the triangles, collapsed into eight-wide nodes
//! at the least surface-area cost, and the triangles laid out in lanes.

use std::time::Duration;

use glam::Vec3;
use obvhs::{BvhBuildParams, bvh2::Bvh2, triangle::Triangle as ObvhsTriangle};

use super::{ARRAYS, CpuNode, CpuTree, LANE_PAD, PRIM_ALPHA, PRIM_CULL, PrimLanes};

/// obvhs' `slow_build` with leaves of one triangle: the collapse ([`Collapse`]) chooses the
/// leaves. (Over obvhs' own collapse into leaves of up to eight, the walks visited 4.93 nodes a
/// closest-hit ray in the small city against 4.48.) The BVH2 of one triangle a leaf takes longer
/// to build: the 343 740-triangle city's start, tree included, 1.4–1.6 s → 1.9–2.1 s here.
pub(super) const BVH2_PARAMS: BvhBuildParams = BvhBuildParams {
    max_prims_per_leaf: 1,
    ..BvhBuildParams::slow_build()
};

/// The most triangles a leaf holds: one 8-wide triangle test.
pub(super) const LEAF_PRIMS: u32 = 8;

/// The collapse's cost of testing a node's eight boxes, per unit of its box's area ([`Collapse`]).
pub(super) const NODE_COST: f32 = 1.0;

/// The collapse's cost of a leaf's 8-wide triangle test, per unit of its box's area: twice a
/// node's (measured against 0.5, 1 and 3: the small city's ms per sample ×0.935–0.95 against
/// the greedy opening's, the others ×0.93–1.0; BENCHMARKS.md, *CPU traversal*).
pub(super) const LEAF_COST: f32 = 2.0;

/// How far the boxes are widened, relative to the magnitude of the coordinates: a box test
/// computes `plane · (1/d) − origin · (1/d)` (the product and the difference fused into one
/// rounding where the processor has FMA, two roundings without), off by a few units in the
/// last place of the larger of the plane and the origin (2⁻²⁴ relative each); this is 8× that.
const WIDEN: f64 = 1.0 / (1u64 << 21) as f64;

impl CpuTree {
    /// The tree over the triangles of the GPU's primitives `gpu_prims` (three entries each, as
    /// [`super::SceneBvh::prims`]; spatial splits repeat some triangles there: each is taken
    /// once).
    pub(in crate::trace::bvh) fn build(gpu_prims: &[[f32; 4]]) -> Self {
        let n = gpu_prims.len() / 3;
        // One reference (a GPU primitive) for each triangle, in triangle order.
        let mut first = Vec::new();
        for i in 0..n {
            let triangle = gpu_prims[3 * i][3].to_bits() as usize;
            if first.len() <= triangle {
                first.resize(triangle + 1, u32::MAX);
            }
            if first[triangle] == u32::MAX {
                first[triangle] = i as u32;
            }
        }
        let refs: Vec<usize> = first
            .into_iter()
            .filter(|&r| r != u32::MAX)
            .map(|r| r as usize)
            .collect();
        if refs.is_empty() {
            return Self::default();
        }
        let vec = |p: [f32; 4]| Vec3::new(p[0], p[1], p[2]);
        let mut magnitude = 0f32;
        let tris: Vec<ObvhsTriangle> = refs
            .iter()
            .map(|&r| {
                let v0 = vec(gpu_prims[3 * r]);
                let (v1, v2) = (
                    v0 + vec(gpu_prims[3 * r + 1]),
                    v0 + vec(gpu_prims[3 * r + 2]),
                );
                for v in [v0, v1, v2] {
                    magnitude = magnitude.max(v.abs().max_element());
                }
                ObvhsTriangle {
                    v0: v0.into(),
                    v1: v1.into(),
                    v2: v2.into(),
                }
            })
            .collect();
        let (nodes, order, _) = collapsed(&tris, f64::from(magnitude));
        assert!(
            nodes.len() < 1 << 28,
            "{} nodes: the CPU tree's stack entries name fewer than 2^28",
            nodes.len()
        );
        let prims: Vec<[f32; 4]> = order
            .iter()
            .flat_map(|&t| {
                let r = refs[t as usize];
                gpu_prims[3 * r..3 * r + 3].iter().copied()
            })
            .collect();
        let stack_size = 7 * depth(&nodes, 0) + 8;
        Self {
            lanes: PrimLanes::new(&prims),
            nodes,
            prims,
            stack_size,
        }
    }
}

/// The collapse of obvhs' BVH2 into eight-wide nodes that minimises the surface-area cost of a
/// walk (Ylitie, Karras and Laine 2017, "Efficient incoherent ray traversal on GPUs through
/// compressed wide BVHs", §3.1): a node or a leaf costs the area of its box times its test's
/// cost; for each BVH2 node and each number of slots j ≤ 8, the cheapest forest of at most j
/// subtrees and leaves that covers it.
struct Collapse<'a> {
    bvh2: &'a Bvh2,
    /// The primitives below each BVH2 node.
    count: Vec<u32>,
    /// `best[n][j − 1]`: the cost of the cheapest forest of at most j for node n.
    best: Vec<[f32; 8]>,
    /// `split[n][j − 1]`: 0 when that forest is the one of at most j − 1 (for j = 1: n itself,
    /// as a leaf or a node, see `leaf`), else the slots its left child gets (the right j − k).
    split: Vec<[u8; 8]>,
    /// Whether n by itself is cheapest as a leaf.
    leaf: Vec<bool>,
    /// The slots n's left child gets in n's own node.
    node_split: Vec<u8>,
}

impl<'a> Collapse<'a> {
    /// The costs of every node of `bvh2`, solved from the leaves up.
    fn new(bvh2: &'a Bvh2) -> Self {
        let n = bvh2.nodes.len();
        let mut c = Self {
            bvh2,
            count: vec![0; n],
            best: vec![[0.0; 8]; n],
            split: vec![[0; 8]; n],
            leaf: vec![false; n],
            node_split: vec![0; n],
        };
        if n > 0 {
            c.solve(0);
        }
        c
    }

    /// Fills n's entries (its subtree's first).
    fn solve(&mut self, n: usize) {
        let node = &self.bvh2.nodes[n];
        let area = node.aabb.half_area();
        if node.prim_count > 0 {
            self.count[n] = node.prim_count;
            let tests = node.prim_count.div_ceil(LEAF_PRIMS) as f32;
            self.best[n] = [area * LEAF_COST * tests; 8];
            self.leaf[n] = true;
            return;
        }
        let (l, r) = (node.first_index as usize, node.first_index as usize + 1);
        self.solve(l);
        self.solve(r);
        self.count[n] = self.count[l] + self.count[r];
        // For j = 2..=8 slots: the cheapest split of j between the two children, and its k.
        let dist: [(f32, u8); 7] = std::array::from_fn(|i| {
            let j = i + 2;
            (1..j)
                .map(|k| (self.best[l][k - 1] + self.best[r][j - k - 1], k as u8))
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .expect("j ≥ 2")
        });
        let (d8, k8) = dist[6];
        let as_node = area * NODE_COST + d8;
        let as_leaf = if self.count[n] <= LEAF_PRIMS {
            area * LEAF_COST
        } else {
            f32::INFINITY
        };
        let mut best = [0f32; 8];
        let mut split = [0u8; 8];
        best[0] = as_leaf.min(as_node);
        for j in 2..=8 {
            let (d, k) = dist[j - 2];
            if d < best[j - 2] {
                best[j - 1] = d;
                split[j - 1] = k;
            } else {
                best[j - 1] = best[j - 2];
            }
        }
        self.best[n] = best;
        self.split[n] = split;
        // Only a node of at most eight triangles can be a leaf, whatever the costs (both are +∞
        // where the boxes' areas overflow f32: coordinates beyond ~10¹⁹).
        self.leaf[n] = self.count[n] <= LEAF_PRIMS && as_leaf <= as_node;
        self.node_split[n] = k8;
    }

    /// The slots (a BVH2 node each, and whether it is a leaf) of n's cheapest forest of at
    /// most j.
    fn slots(&self, n: usize, mut j: usize, out: &mut Vec<(usize, bool)>) {
        while j > 1 && self.split[n][j - 1] == 0 {
            j -= 1;
        }
        if j == 1 {
            out.push((n, self.leaf[n]));
            return;
        }
        let k = usize::from(self.split[n][j - 1]);
        let l = self.bvh2.nodes[n].first_index as usize;
        self.slots(l, k, out);
        self.slots(l + 1, j - k, out);
    }

    /// The primitives below n, in the BVH2's order, appended to `order`.
    fn gather(&self, n: usize, order: &mut Vec<u32>) {
        let node = &self.bvh2.nodes[n];
        if node.prim_count > 0 {
            let first = node.first_index as usize;
            order.extend_from_slice(
                &self.bvh2.primitive_indices[first..first + node.prim_count as usize],
            );
        } else {
            self.gather(node.first_index as usize, order);
            self.gather(node.first_index as usize + 1, order);
        }
    }

    /// Appends the eight-wide node of BVH2 node `root` (its subtree after it, depth first) and
    /// returns its index; each leaf's primitives are appended to `order` (obvhs' primitive
    /// indices) where the leaf starts.
    fn open(
        &self,
        root: usize,
        magnitude: f64,
        nodes: &mut Vec<CpuNode>,
        order: &mut Vec<u32>,
    ) -> u32 {
        let index = nodes.len();
        nodes.push(CpuNode {
            bounds: [
                [f32::INFINITY; 8],
                [f32::NEG_INFINITY; 8],
                [f32::INFINITY; 8],
                [f32::NEG_INFINITY; 8],
                [f32::INFINITY; 8],
                [f32::NEG_INFINITY; 8],
            ],
            child: [0; 8],
            count: [0; 8],
            imask: 0,
        });
        let node = &self.bvh2.nodes[root];
        let mut kids = Vec::new();
        if node.prim_count > 0 {
            kids.push((root, true));
        } else {
            let k = usize::from(self.node_split[root]);
            self.slots(node.first_index as usize, k, &mut kids);
            self.slots(node.first_index as usize + 1, 8 - k, &mut kids);
        }
        let mut inner = Vec::new();
        for (c, &(k, leaf)) in kids.iter().enumerate() {
            let kid = &self.bvh2.nodes[k];
            for axis in 0..3 {
                let (lo, hi) = (f64::from(kid.aabb.min[axis]), f64::from(kid.aabb.max[axis]));
                nodes[index].bounds[2 * axis][c] =
                    f32_outward(lo - WIDEN * (lo.abs() + magnitude), true);
                nodes[index].bounds[2 * axis + 1][c] =
                    f32_outward(hi + WIDEN * (hi.abs() + magnitude), false);
            }
            if leaf {
                let first = order.len();
                self.gather(k, order);
                let count = u8::try_from(order.len() - first).expect("leaves hold at most 255");
                nodes[index].child[c] = first as u32;
                nodes[index].count[c] = count;
            } else {
                nodes[index].imask |= 1 << c;
                inner.push((c, k));
            }
        }
        for (c, k) in inner {
            let child = self.open(k, magnitude, nodes, order);
            nodes[index].child[c] = child;
        }
        index as u32
    }
}

/// The eight-wide nodes over `tris` ([`Collapse`] of obvhs' BVH2 of them, boxes widened for
/// coordinates up to `magnitude`), the leaves' triangles (indices into `tris`, spatial splits
/// repeating some) in the order the nodes' leaves refer to, and the collapse's cost of the tree.
pub(super) fn collapsed(tris: &[ObvhsTriangle], magnitude: f64) -> (Vec<CpuNode>, Vec<u32>, f32) {
    let bvh2 =
        obvhs::bvh2::builder::build_bvh2_from_tris(tris, BVH2_PARAMS, &mut Duration::default());
    let collapse = Collapse::new(&bvh2);
    let (mut nodes, mut order) = (Vec::new(), Vec::new());
    collapse.open(0, magnitude, &mut nodes, &mut order);
    let cost = collapse.best.first().map_or(0.0, |b| b[0]);
    (nodes, order, cost)
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

/// The depth of the tree below `root` (0 for a node whose children are all leaves).
pub(super) fn depth(nodes: &[CpuNode], root: usize) -> usize {
    let node = &nodes[root];
    (0..8)
        .filter(|&c| node.imask & (1 << c) != 0)
        .map(|c| 1 + depth(nodes, node.child[c] as usize))
        .max()
        .unwrap_or(0)
}

impl PrimLanes {
    fn new(prims: &[[f32; 4]]) -> Self {
        let n = prims.len() / 3;
        let stride = n + LANE_PAD;
        let mut data = vec![0.0; ARRAYS * stride];
        let mut alpha = false;
        for i in 0..n {
            let row = |r: usize| Vec3::from_slice(&prims[3 * i + r][..3]);
            let normal = row(1).cross(row(2));
            let values = [row(0), row(1), row(2)].map(|v| v.to_array());
            for (k, value) in values.as_flattened().iter().enumerate() {
                data[k * stride + i] = *value;
            }
            let flags = prims[3 * i + 2][3] as u32;
            data[9 * stride + i] = if flags & PRIM_CULL != 0 { 1.0 } else { 0.0 };
            for (k, value) in normal.to_array().into_iter().enumerate() {
                data[(10 + k) * stride + i] = value;
            }
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
