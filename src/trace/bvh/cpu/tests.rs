use super::super::SceneBvh;
use super::super::obvhs_triangles;
use super::super::tests::{brute, random_triangles, uniforms};
use super::build::{BVH2_PARAMS, LEAF_COST, LEAF_PRIMS, NODE_COST, collapsed, depth};
use super::*;
use std::time::Duration;

/// `RAYGUN_CPU_PACKETS`' values: 0, avx2 and avx512 (with surrounding blanks) where this
/// processor runs them, avx512 refused without AVX-512, anything else refused with the
/// values it takes; the fastest is AVX-512 exactly where the processor has AVX-512 F and DQ
/// (and AVX2 in this AVX2 build otherwise); a test's own walks stay on its thread.
#[test]
fn packet_widths_parse_and_are_checked_against_the_processor() {
    let avx2 = cfg!(all(target_feature = "avx2", target_feature = "fma"));
    #[cfg(target_arch = "x86_64")]
    let avx512 = hybrid::available();
    #[cfg(not(target_arch = "x86_64"))]
    let avx512 = false;
    assert_eq!(CpuPackets::parse("0"), Ok(CpuPackets::One));
    assert_eq!(CpuPackets::parse(" avx2\n").is_ok(), avx2);
    assert_eq!(CpuPackets::parse("avx512").is_ok(), avx512);
    let widest = match (avx512, avx2) {
        (true, _) => CpuPackets::Avx512,
        (false, true) => CpuPackets::Avx2,
        _ => CpuPackets::One,
    };
    assert_eq!(CpuPackets::widest(), widest);
    if !cfg!(target_arch = "x86_64") {
        let e = CpuPackets::parse("avx2").unwrap_err().to_string();
        assert!(e.contains(std::env::consts::ARCH), "{e}");
    }
    for bad in ["", "1", "8", "16", "AVX2", "avx", "avx2,avx512"] {
        let e = CpuPackets::parse(bad).unwrap_err().to_string();
        assert!(e.contains("expected 0"), "{bad:?}: {e}");
    }
    let outside = CpuPackets::current();
    CpuPackets::One.during(|| {
        assert_eq!(CpuPackets::current(), CpuPackets::One);
        CpuPackets::widest().during(|| assert_eq!(CpuPackets::current(), widest));
        assert_eq!(CpuPackets::current(), CpuPackets::One);
    });
    assert_eq!(CpuPackets::current(), outside);
}

/// The slab test in lanes gives the scalar test's mask and entry distances to the bit,
/// on every node of a real tree and rays from everywhere (inside boxes, grazing, axis
/// parallel, short).
#[test]
fn node_hits_lanes_equal_the_scalar_test() {
    let tris = random_triangles(2000, 7);
    let bvh = SceneBvh::build(&tris, &vec![0.0; tris.len()]);
    let tree = bvh.cpu();
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
        for node in &tree.nodes {
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

/// The slab test on the distances' bits as integers decides as the float test does and
/// gives its entry distances, to the bit: rays starting inside boxes and behind them
/// (negative distances), along a box's faces, parallel to slabs, with short and infinite
/// bounds, and empty slots (±∞ planes).
#[test]
fn node_hits_equal_the_float_slab_test() {
    let float = |node: &CpuNode, ray: &NodeRay, tmax: f32| {
        let mut entry = [0f32; 8];
        let mut hit = 0;
        for (c, entry) in entry.iter_mut().enumerate() {
            let t = |row: usize, axis: usize| {
                node.bounds[row][c].mul_add(ray.inv[axis], -ray.origin_inv[axis])
            };
            let near = t(ray.near[0], 0)
                .max(t(ray.near[1], 1))
                .max(t(ray.near[2], 2))
                .max(NODE_EPSILON);
            let far = t(ray.far[0], 0)
                .min(t(ray.far[1], 1))
                .min(t(ray.far[2], 2))
                .min(tmax);
            *entry = near;
            if near <= far {
                hit |= 1 << c;
            }
        }
        (hit, entry)
    };
    let tris = random_triangles(2000, 3);
    let bvh = SceneBvh::build(&tris, &vec![0.0; tris.len()]);
    let tree = bvh.cpu();
    let mut r = uniforms(9);
    let (mut hits, mut behind) = (0, 0);
    for i in 0..3000 {
        let node = &tree.nodes[i % tree.nodes.len()];
        // Origins on the nodes' own corners and faces as well as anywhere.
        let c = i % 8;
        let corner = Vec3::new(node.bounds[0][c], node.bounds[2][c], node.bounds[4][c]);
        let o = match i % 3 {
            0 if corner.is_finite() => corner,
            1 if corner.is_finite() => corner + Vec3::new(r(), r(), r()) * 0.5,
            _ => Vec3::new(r(), r(), r()) * 14.0 - 7.0,
        };
        let mut d = (Vec3::new(r(), r(), r()) - 0.5).normalize();
        if i % 7 == 0 {
            d.x = 0.0;
        }
        let tmax = [f32::INFINITY, r() * 3.0, 1e-6][i % 3];
        let ray = NodeRay::new(o, d);
        for node in &tree.nodes {
            let (ints, floats) = (node_hits_scalar(node, &ray, tmax), float(node, &ray, tmax));
            assert_eq!(ints.0, floats.0, "masks, ray {o} {d} tmax {tmax}");
            assert_eq!(ints.1.map(f32::to_bits), floats.1.map(f32::to_bits));
            assert_eq!(node_hits(node, &ray, tmax), ints);
            hits += ints.0.count_ones();
            for c in 0..8 {
                let t = node.bounds[ray.far[0]][c].mul_add(ray.inv[0], -ray.origin_inv[0]);
                behind += u32::from(t < 0.0);
            }
        }
    }
    assert!(
        hits > 10_000 && behind > 10_000,
        "{hits} entered, {behind} planes behind"
    );
}

/// The tree's shape: every triangle is in some leaf, each leaf holds one to eight
/// primitives of the tree's arrays, each node's children are later nodes (so the walk
/// ends), empty slots are entered by no ray, and the primitives are the GPU's.
#[test]
fn the_cpu_tree_covers_every_triangle() {
    let tris = random_triangles(3000, 11);
    let bvh = SceneBvh::build(&tris, &vec![0.0; tris.len()]);
    let tree = bvh.cpu();
    let mut seen = vec![false; tris.len()];
    let ray = NodeRay::new(Vec3::ZERO, Vec3::ONE.normalize());
    for (index, node) in tree.nodes.iter().enumerate() {
        for c in 0..8 {
            if node.imask & (1 << c) != 0 {
                assert!(
                    node.child[c] as usize > index && (node.child[c] as usize) < tree.nodes.len()
                );
                assert_eq!(node.count[c], 0);
            } else if node.count[c] == 0 {
                assert_eq!(
                    node_hits(node, &ray, f32::INFINITY).0 & (1 << c),
                    0,
                    "empty slot {c} of node {index}"
                );
            } else {
                assert!(u32::from(node.count[c]) <= LEAF_PRIMS);
                for i in node.child[c]..node.child[c] + u32::from(node.count[c]) {
                    seen[tree.triangle(i) as usize] = true;
                }
            }
        }
    }
    assert!(seen.iter().all(|&s| s), "a triangle is in no leaf");
    for i in 0..tree.prims.len() / 3 {
        let t = tree.triangle(i as u32) as usize;
        let gpu = bvh
            .prims
            .chunks(3)
            .find(|p| p[0][3].to_bits() as usize == t)
            .unwrap();
        assert_eq!(&tree.prims[3 * i..3 * i + 3], gpu, "primitive {i}");
    }
}

/// The collapse makes the tree its costs describe: the surface-area cost of the nodes and
/// leaves it builds, from their boxes, is the minimum it computed for the root (to the
/// boxes' widening); each node has two to eight slots, each leaf one to eight triangles,
/// and every primitive of the BVH2 is in exactly one leaf.
#[test]
fn the_collapse_builds_the_tree_it_costs() {
    for (n, seed) in [(1, 1), (2, 2), (9, 3), (3000, 4)] {
        let tris = obvhs_triangles(&random_triangles(n, seed));
        let (nodes, order, computed) = collapsed(&tris, 8.0);
        let bvh2 = obvhs::bvh2::builder::build_bvh2_from_tris(
            &tris,
            BVH2_PARAMS,
            &mut Duration::default(),
        );
        let half_area = |node: &CpuNode, c: usize| {
            let e = |axis: usize| {
                f64::from(node.bounds[2 * axis + 1][c]) - f64::from(node.bounds[2 * axis][c])
            };
            e(0) * e(1) + e(1) * e(2) + e(2) * e(0)
        };
        let root = &bvh2.nodes[0];
        let mut built = if root.prim_count > 0 {
            0.0
        } else {
            f64::from(root.aabb.half_area()) * f64::from(NODE_COST)
        };
        let mut seen = vec![0u32; tris.len()];
        for node in &nodes {
            let slots = (0..8)
                .filter(|&c| node.imask & (1 << c) != 0 || node.count[c] > 0)
                .count();
            assert!(
                (2..=8).contains(&slots) || (root.prim_count > 0 && slots == 1),
                "{slots} slots (n = {n})"
            );
            for c in 0..8 {
                if node.imask & (1 << c) != 0 {
                    built += half_area(node, c) * f64::from(NODE_COST);
                } else if node.count[c] > 0 {
                    assert!(u32::from(node.count[c]) <= LEAF_PRIMS);
                    built += half_area(node, c) * f64::from(LEAF_COST);
                    let first = node.child[c] as usize;
                    for &p in &order[first..first + usize::from(node.count[c])] {
                        seen[p as usize] += 1;
                    }
                }
            }
        }
        let mut expected = vec![0u32; tris.len()];
        for &p in &bvh2.primitive_indices {
            expected[p as usize] += 1;
        }
        assert_eq!(seen, expected, "n = {n}: each primitive in one leaf");
        let computed = f64::from(computed);
        assert!(
            (built - computed).abs() <= 1e-3 * computed,
            "n = {n}: the tree costs {built}, the collapse computed {computed}"
        );
    }
}

/// Triangles spread so far that the boxes' areas overflow f32 (the collapse's costs are +∞
/// at the top of the tree): the CPU's tree still builds, its leaves hold at most eight
/// triangles, and every hit is the brute-force one. (Built from the primitives directly:
/// obvhs' compressed GPU tree asserts on such boxes in a debug build; the loader keeps
/// coordinates within 1e9, where neither overflows.)
#[test]
fn coordinates_whose_areas_overflow_still_build_a_tree() {
    let tris: Vec<[Vec3; 3]> = (0..3000)
        .map(|i| {
            let s = 1.02f32.powi(i);
            let c = Vec3::new(s, 0.3 * (i % 7) as f32, -0.001 * i as f32);
            [
                c,
                c + Vec3::new(0.5 * s, 0.0, 0.0),
                c + Vec3::new(0.0, 0.5 * s, 0.0),
            ]
        })
        .collect();
    assert!(
        tris[2999][1].x.powi(2).is_infinite(),
        "the areas must overflow"
    );
    let prims: Vec<[f32; 4]> = tris
        .iter()
        .enumerate()
        .flat_map(|(i, t)| {
            let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
            [
                [t[0].x, t[0].y, t[0].z, f32::from_bits(i as u32)],
                [e1.x, e1.y, e1.z, 0.0],
                [e2.x, e2.y, e2.z, 0.0],
            ]
        })
        .collect();
    let tree = CpuTree::build(&prims);
    assert!(
        tree.nodes
            .iter()
            .all(|n| n.count.iter().all(|&c| u32::from(c) <= LEAF_PRIMS))
    );
    for i in 0..400 {
        let x = 1.02f32.powf(i as f32 / 2.0);
        let o = Vec3::new(x, 0.2 * (i % 13) as f32, 5.0);
        let d = Vec3::new(0.01 * ((i % 9) as f32 - 4.0), 0.0, -1.0).normalize();
        let got = tree.closest_hit_filtered(o, d, f32::INFINITY, |_, _, _| true);
        assert_eq!(
            got.map(|h| (h.t, h.triangle)),
            brute(&tris, o, d),
            "ray {o} {d}"
        );
    }
}

/// A deep tree (triangles whose sizes and places grow geometrically, so the tree cannot
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
    let tree = bvh.cpu();
    let depth = depth(&tree.nodes, 0);
    assert!(depth >= 3, "the test needs a deep tree ({depth})");
    assert_eq!(tree.stack_size, 7 * depth + 8);
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
