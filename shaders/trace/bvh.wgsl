// CWBVH traversal (Ylitie, Karras, Laine 2017), ported from obvhs' `traverse!` macro and
// `CwBvhNode::intersect_ray`; the CPU twin walks a tree of its own over the same triangles and
// finds the same hits (src/trace/bvh/cpu.rs). Node layout: see src/trace/bvh.rs.

struct Node {
    n0: vec4<u32>, // p.xyz (f32 bits), e[0..3] | imask << 24
    n1: vec4<u32>, // child_base_idx, primitive_base_idx, child_meta[0..4], child_meta[4..8]
    n2: vec4<u32>, // child_min_x lo/hi, child_max_x lo/hi
    n3: vec4<u32>, // y
    n4: vec4<u32>, // z
}

struct Hit {
    t: f32,
    u: f32,
    v: f32,
    prim: u32, // BVH primitive, or NO_HIT
}

const NO_HIT: u32 = 0xffffffffu;
// No infinities in WGSL: the largest finite f32 stands for "unbounded".
const T_FAR: f32 = 3.402823e38;
const NODE_EPSILON: f32 = 0.0001;
const STACK_SIZE: u32 = 32u;
// The traversal stack, one an invocation at module scope: WGSL zero-initialises a function's
// variables at every call (256 bytes written a ray), a private variable once an invocation.
// The kernel lab (src/trace/gpu/lab.rs, builds with the `kernel-lab` feature) compiles variants
// with it in `traverse` or in workgroup memory (`TraceStack`); all find the same hits.
var<private> stack: array<vec2<u32>, STACK_SIZE>;

// Triangle postponing (Ylitie, Karras, Laine 2017, §4), the kernel lab's `+vote` variants' (a
// pipeline constant sets the percentage P; 0 by default: off): a lane whose triangles few of
// its subgroup's lanes are testing with it — fewer than P % of those still traversing — keeps
// them aside and walks on into its next node, so that the subgroup's lanes run node tests
// together instead of waiting on each other's triangle loops. Kept in one slot a lane (the
// stack's use stays the default's), they are tested before the lane's next pop. Only the order
// of the tests changes; the closest hit does not depend on it (the tie rule in `traverse`).
override POSTPONE: u32 = 0u;

// How many of the subgroup's lanes that call this together pass `yes`: a subgroup ballot in the
// `+vote` variants (the only ones that need subgroups; a module that names a subgroup operation
// needs them on every adapter, so the lab patches the ballot in), never called in the others.
fn lanes_voting(yes: bool) -> u32 {
    return u32(yes);
}

@group(0) @binding(0) var<storage, read> nodes: array<Node>;
@group(0) @binding(1) var<storage, read> prims: array<vec4<f32>>;

fn safe_inverse(x: f32) -> f32 {
    let eps = 1.1920929e-7;
    if abs(x) <= eps {
        // Rust's signum: +1 for +0, −1 for −0.
        return select(1.0, -1.0, (bitcast<u32>(x) & 0x80000000u) != 0u) / eps;
    }
    return 1.0 / x;
}

fn octant_inv4(d: vec3<f32>) -> u32 {
    return select(0x04040404u, 0u, d.x < 0.0) | select(0x02020202u, 0u, d.y < 0.0)
        | select(0x01010101u, 0u, d.z < 0.0);
}

fn byte_of(lo: u32, hi: u32, c: u32) -> f32 {
    let w = select(lo, hi, c >= 4u);
    return f32((w >> ((c & 3u) * 8u)) & 0xffu);
}

// The hit mask of a node's children (inner children in the high byte, leaf triangles in the
// low 24 bits), ordered by the ray octant.
fn node_hits(node: Node, o: vec3<f32>, d: vec3<f32>, inv_d: vec3<f32>, tmax: f32, oct_inv4: u32) -> u32 {
    let p = bitcast<vec3<f32>>(node.n0.xyz);
    let e = node.n0.w;
    let ext = vec3<f32>(
        bitcast<f32>((e & 0xffu) << 23u),
        bitcast<f32>(((e >> 8u) & 0xffu) << 23u),
        bitcast<f32>(((e >> 16u) & 0xffu) << 23u),
    );
    let adj_dir_inv = ext * inv_d;
    let adj_orig = (p - o) * inv_d;
    var hit_mask = 0u;
    for (var half = 0u; half < 2u; half++) {
        let cm = select(node.n1.z, node.n1.w, half == 1u);
        let is_inner = (cm & (cm << 1u)) & 0x10101010u;
        let inner_mask = (is_inner >> 4u) * 0xffu;
        let bit_index = (cm ^ (oct_inv4 & inner_mask)) & 0x1f1f1f1fu;
        let child_bits = (cm >> 5u) & 0x07070707u;
        for (var b = 0u; b < 4u; b++) {
            let c = half * 4u + b;
            let lo = vec3<f32>(byte_of(node.n2.x, node.n2.y, c), byte_of(node.n3.x, node.n3.y, c), byte_of(node.n4.x, node.n4.y, c));
            let hi = vec3<f32>(byte_of(node.n2.z, node.n2.w, c), byte_of(node.n3.z, node.n3.w, c), byte_of(node.n4.z, node.n4.w, c));
            let neg = d < vec3<f32>(0.0);
            let qmin = select(lo, hi, neg);
            let qmax = select(hi, lo, neg);
            let t0 = qmin * adj_dir_inv + adj_orig;
            let t1 = qmax * adj_dir_inv + adj_orig;
            let tn = max(max(t0.x, t0.y), max(t0.z, NODE_EPSILON));
            let tf = min(min(t1.x, t1.y), min(t1.z, tmax));
            if tn <= tf {
                let s = b * 8u;
                hit_mask |= ((child_bits >> s) & 0xffu) << ((bit_index >> s) & 0xffu);
            }
        }
    }
    return hit_mask;
}

// The ray-triangle test (CPU twin: bvh::intersect_triangle_sided, the same arithmetic):
// Möller-Trumbore rearranged around the normal n = e1 × e2, as Embree's. With c = v0 - o,
// r = c × d and den = d·n: u = (e2·r)/den, v = -(e1·r)/den, t = (c·n)/den. Whether the ray's
// line meets the triangle in front of the origin is decided on the numerators times den's
// sign, against |den|, without a division; only then is t divided out and bounded,
// 0 < t < tmax (the closest hit so far). Returns (t, u, v) or t < 0 for a miss. With
// cull_back (a single-sided glTF material) the back face is no hit: the front face is met when
// d·n < 0.
fn intersect_triangle(o: vec3<f32>, d: vec3<f32>, v0: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>, tmax: f32, cull_back: bool) -> vec3<f32> {
    let miss = vec3<f32>(-1.0, 0.0, 0.0);
    let n = cross(e1, e2);
    let c = v0 - o;
    let r = cross(c, d);
    let den = dot(n, d);
    let a = dot(e2, r);
    let b = dot(e1, r);
    let tn = dot(c, n);
    if den == 0.0 || (cull_back && den > 0.0) {
        return miss;
    }
    let s = select(1.0, -1.0, den < 0.0);
    let us = a * s;
    let vs = -b * s;
    if !(us >= 0.0 && vs >= 0.0 && us + vs <= abs(den) && tn * s > 0.0) {
        return miss;
    }
    let inv = 1.0 / den;
    let t = tn * inv;
    if t > 0.0 && t < tmax {
        return vec3<f32>(t, a * inv, -(b * inv));
    }
    return miss;
}

// Closest hit (any_hit = false) or the first hit found (any_hit = true, shadow rays). Of hits
// at the same t the one on the higher triangle is the closest (the CPU twin's rule,
// bvh/cpu.rs `nearer`), so the hit does not depend on the order the triangles are tested in.
fn traverse(o: vec3<f32>, d: vec3<f32>, tmax_in: f32, any_hit: bool) -> Hit {
    var hit = Hit(tmax_in, 0.0, 0.0, NO_HIT);
    // The triangle of `hit`, and the bound a test needs to find a hit as near: t itself
    // included (the tests keep t < bound), within the ray's own tmax.
    var hit_triangle = 0u;
    var bound = tmax_in;
    rays_traced += 1u;
    if params.node_count == 0u {
        return hit;
    }
    let inv_d = vec3<f32>(safe_inverse(d.x), safe_inverse(d.y), safe_inverse(d.z));
    let oct_inv4 = octant_inv4(d);
    var sp = 0u;
    var current = vec2<u32>(0u, 0x80000000u);
    var prim_group = vec2<u32>(0u, 0u);
    var postponed = vec2<u32>(0u, 0u);
    loop {
        var traversing = 0u;
        if POSTPONE != 0u {
            traversing = lanes_voting(true);
        }
        while prim_group.y != 0u {
            if POSTPONE != 0u {
                let testing = lanes_voting(true);
                if testing * 100u < traversing * POSTPONE && postponed.y == 0u
                    && (current.y & 0xff000000u) != 0u {
                    postponed = prim_group;
                    prim_group.y = 0u;
                    break;
                }
            }
            let local = firstLeadingBit(prim_group.y);
            prim_group.y &= ~(1u << local);
            let pid = prim_group.x + local;
            let a = prims[3u * pid];
            let c = prims[3u * pid + 2u];
            // Flags as a small float (src/trace/bvh.rs): 1 single-sided, 2 alpha-tested.
            let flags = u32(c.w);
            var r = intersect_triangle(o, d, a.xyz, prims[3u * pid + 1u].xyz, c.xyz, bound, (flags & 1u) != 0u);
            let triangle = bitcast<u32>(a.w);
            if r.x > 0.0 && r.x == hit.t && triangle <= hit_triangle {
                r.x = -1.0;
            }
            if r.x > 0.0 && (flags & 2u) != 0u && !alpha_covered(triangle, r.y, r.z) {
                r.x = -1.0;
            }
            if r.x > 0.0 {
                hit = Hit(r.x, r.y, r.z, pid);
                hit_triangle = triangle;
                // The next float up: r.x is positive and finite.
                bound = min(bitcast<f32>(bitcast<u32>(r.x) + 1u), tmax_in);
                if any_hit {
                    return hit;
                }
            }
        }
        if (current.y & 0xff000000u) != 0u {
            let hits_imask = current.y;
            let offset = firstLeadingBit(hits_imask);
            let base = current.x;
            current.y &= ~(1u << offset);
            if (current.y & 0xff000000u) != 0u && sp < STACK_SIZE {
                stack[sp] = current;
                sp += 1u;
            }
            let slot = (offset - 24u) ^ (oct_inv4 & 0xffu);
            let relative = countOneBits(hits_imask & ~(0xffffffffu << slot));
            let node = nodes[base + relative];
            let mask = node_hits(node, o, d, inv_d, hit.t, oct_inv4);
            current = vec2<u32>(node.n1.x, (mask & 0xff000000u) | (node.n0.w >> 24u));
            prim_group = vec2<u32>(node.n1.y, mask & 0x00ffffffu);
        } else {
            current = vec2<u32>(0u, 0u);
        }
        if prim_group.y == 0u && (current.y & 0xff000000u) == 0u {
            if POSTPONE != 0u && postponed.y != 0u {
                prim_group = postponed;
                postponed.y = 0u;
                continue;
            }
            if sp == 0u {
                break;
            }
            sp -= 1u;
            current = stack[sp];
        }
    }
    return hit;
}
