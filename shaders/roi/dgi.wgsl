// The distance-guide image (DESIGN.md §5). CPU twin: src/roi/dgi.rs (f64); dispatch:
// src/roi/gpu.rs. Concatenated after shaders/roi/ellipse.wgsl (WGSL has no includes).
//
// One thread per image pixel. Pixel positions are formed relative to each piece's rectangle
// centre from an integer part and a fraction precomputed in f64, so f32 keeps ~1e-7 of the
// local distance rather than of the canvas size (HORNET's canvas is 13.5k px wide: absolute f32
// canvas coordinates would lose 1e-3 px).

struct Params {
    size: vec2<u32>,
    // 0: pieces (exact, ellipse, mouse), 1: angular.
    mode: u32,
    count: u32,
    // Canvas pixels per image pixel.
    scale: vec2<f32>,
    // 1 / L; 0 writes the raw canvas distance.
    inv_falloff: f32,
    px_per_radian: f32,
    tan_hv: vec2<f32>,
    // L in canvas px (distances are capped there), or f32 max for raw distances.
    cap: f32,
    _pad: u32,
}

// Layout mirrored by `GpuPiece` in src/roi/gpu.rs (80 bytes).
struct Piece {
    // Rectangle centre in image-pixel-index space: integer part and fraction.
    center_i: vec2<i32>,
    center_f: vec2<f32>,
    half: vec2<f32>,
    // Conic origin minus rectangle centre, canvas px.
    to_origin: vec2<f32>,
    axis_u: vec2<f32>,
    // (a, b) ellipse | (B², s) hyperbola | (c, 0) parabola.
    shape: vec2<f32>,
    kind: u32,
    edge_start: u32,
    edge_count: u32,
    _pad: u32,
    // Bounding box of the piece relative to the rectangle centre: (min.xy, max.xy).
    bounds: vec4<f32>,
}

// Layout mirrored by `GpuAngularTile` (80 bytes): w(l) = w0 + l.x·ex + l.y·ey in the cone's
// (R, U, D) frame, l relative to the rectangle centre.
struct AngularTile {
    center_i: vec2<i32>,
    center_f: vec2<f32>,
    half: vec2<f32>,
    _pad: vec2<f32>,
    w0: vec4<f32>,
    ex: vec4<f32>,
    ey: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> pieces: array<Piece>;
@group(0) @binding(2) var<storage, read> edges: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> tiles: array<AngularTile>;
@group(0) @binding(4) var<storage, read_write> dgi: array<f32>;

const KIND_EMPTY: u32 = 0u;
const KIND_ELLIPSE: u32 = 1u;
const KIND_HYPERBOLA: u32 = 2u;
const KIND_PARABOLA: u32 = 3u;
// Safeguarded Newton on the epigraph problem: bisection alone needs 24 halvings for f32's
// mantissa from a bracket that the Newton steps shrink; 40 bounds the worst case.
const EPIGRAPH_ITERATIONS: u32 = 40u;

// Distance from p to the filled ellipse and the nearest point of it: (distance, point).
fn ellipse_filled_closest(a: f32, b: f32, p: vec2<f32>) -> vec3<f32> {
    if ellipse_inside(a, b, p) {
        return vec3<f32>(0.0, p);
    }
    let c = ellipse_closest_point(a, b, p);
    return vec3<f32>(c.distance, c.point);
}

fn perp(v: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(-v.y, v.x);
}

// f(u) = sqrt(B² + s²u²) (kind 2) or c·u² (kind 3) and derivatives.
fn epi_f(kind: u32, shape: vec2<f32>, u: f32) -> vec3<f32> {
    if kind == KIND_HYPERBOLA {
        let s = shape.y;
        let r2 = shape.x + s * s * u * u;
        let r = sqrt(max(r2, 0.0));
        var df = s;
        var d2f = 0.0;
        if r > 0.0 {
            df = s * s * u / r;
            d2f = s * s * shape.x / (r2 * r);
        }
        return vec3<f32>(r, df, d2f);
    }
    let c = shape.x;
    return vec3<f32>(c * u * u, 2.0 * c * u, 2.0 * c);
}

// Nearest point of the epigraph {v ≥ f(u)} to p: (distance, point). Twin of
// `closest_on_epigraph` in src/roi/conic.rs.
fn epigraph_closest(kind: u32, shape: vec2<f32>, p: vec2<f32>) -> vec3<f32> {
    let pu = abs(p.x);
    let pv = p.y;
    if pv >= epi_f(kind, shape, pu).x {
        return vec3<f32>(0.0, p);
    }
    var lo = 0.0;
    if pv > epi_f(kind, shape, 0.0).x {
        var a = 0.0;
        var b = pu;
        for (var i = 0u; i < 32u; i++) {
            let m = 0.5 * (a + b);
            if m <= a || m >= b {
                break;
            }
            if epi_f(kind, shape, m).x < pv {
                a = m;
            } else {
                b = m;
            }
        }
        lo = a;
    }
    var hi = pu;
    var u = lo;
    for (var i = 0u; i < EPIGRAPH_ITERATIONS; i++) {
        let f = epi_f(kind, shape, u);
        let h = (u - pu) + (f.x - pv) * f.y;
        if h == 0.0 {
            break;
        }
        if h < 0.0 {
            lo = u;
        } else {
            hi = u;
        }
        let dh = 1.0 + f.y * f.y + max(f.x - pv, 0.0) * f.z;
        var next = u - h / dh;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if next == u || hi - lo <= 1.2e-7 * abs(hi) {
            u = next;
            break;
        }
        u = next;
    }
    let q = vec2<f32>(select(u, -u, p.x < 0.0), epi_f(kind, shape, u).x);
    return vec3<f32>(length(q - p), q);
}

// Distance from `rel` (canvas px relative to the piece's rectangle centre) to the piece.
fn piece_distance(pc: Piece, rel: vec2<f32>, best_in: f32) -> f32 {
    var best = best_in;
    let o = rel - pc.to_origin;
    let v_axis = perp(pc.axis_u);
    let l = vec2<f32>(dot(o, pc.axis_u), dot(o, v_axis));
    var r: vec3<f32>;
    if pc.kind == KIND_ELLIPSE {
        r = ellipse_filled_closest(pc.shape.x, pc.shape.y, l);
    } else {
        r = epigraph_closest(pc.kind, pc.shape, l);
    }
    var q = rel;
    if r.x > 0.0 {
        q = pc.to_origin + r.y * pc.axis_u + r.z * v_axis;
    }
    if all(abs(q) <= pc.half) {
        best = min(best, r.x);
    }
    if best == 0.0 {
        return 0.0;
    }
    for (var e = 0u; e < pc.edge_count; e++) {
        let s = edges[pc.edge_start + e];
        let ab = s.zw - s.xy;
        let len2 = dot(ab, ab);
        var t = 0.0;
        if len2 > 0.0 {
            t = clamp(dot(rel - s.xy, ab) / len2, 0.0, 1.0);
        }
        best = min(best, length(s.xy + t * ab - rel));
    }
    return best;
}

fn relative(gid: vec2<u32>, center_i: vec2<i32>, center_f: vec2<f32>) -> vec2<f32> {
    return (vec2<f32>(vec2<i32>(gid) - center_i) - center_f) * params.scale;
}

// Distance from the pixel to piece k's bounding box: a lower bound of its distance. Reads only
// the three fields it needs (a whole-struct copy per piece and pixel is what software
// rasterisers pay for most).
fn box_distance(k: u32, gid: vec2<u32>) -> f32 {
    let rel = relative(gid, pieces[k].center_i, pieces[k].center_f);
    let b = pieces[k].bounds;
    return length(max(max(b.xy - rel, rel - b.zw), vec2<f32>(0.0)));
}

fn angular_excess(w: vec3<f32>) -> f32 {
    let lateral = length(w.xy);
    if lateral == 0.0 {
        return select(3.14159265, 0.0, w.z >= 0.0);
    }
    let rho = atan2(lateral, w.z);
    let cs = w.xy / lateral;
    let inv = length(cs / params.tan_hv);
    return max(rho - atan(1.0 / inv), 0.0);
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.size.x || gid.y >= params.size.y {
        return;
    }
    var best = params.cap;
    if params.mode == 0u {
        // Solve the piece with the nearest bounding box first (it usually holds the nearest
        // point), then prune the others by their boxes. Twin: `Guide::distance_capped`.
        var first = params.count;
        var first_box = best;
        for (var k = 0u; k < params.count; k++) {
            let b = box_distance(k, gid.xy);
            if b < first_box {
                first = k;
                first_box = b;
            }
        }
        if first < params.count {
            let pf = pieces[first];
            best = piece_distance(pf, relative(gid.xy, pf.center_i, pf.center_f), best);
            for (var k = 0u; k < params.count && best > 0.0; k++) {
                if k == first || box_distance(k, gid.xy) >= best {
                    continue;
                }
                let pc = pieces[k];
                best = piece_distance(pc, relative(gid.xy, pc.center_i, pc.center_f), best);
            }
        }
    } else {
        for (var k = 0u; k < params.count; k++) {
            let rel = relative(gid.xy, tiles[k].center_i, tiles[k].center_f);
            if all(abs(rel) <= tiles[k].half) {
                let t = tiles[k];
                let w = t.w0.xyz + rel.x * t.ex.xyz + rel.y * t.ey.xyz;
                best = min(angular_excess(w) * params.px_per_radian, params.cap);
                break;
            }
        }
    }
    var d = best;
    if params.inv_falloff > 0.0 {
        d = clamp(best * params.inv_falloff, 0.0, 1.0);
    }
    dgi[gid.y * params.size.x + gid.x] = d;
}
