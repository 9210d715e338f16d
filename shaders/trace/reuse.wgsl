// Motion reuse (CPU twin: src/trace/reuse.rs, whose module docs define it exactly): one thread a
// pixel of the new view takes the accumulation of the old pixel that saw the same surface, or
// starts from nothing. Whole-image buffers: the new view's primary-hit records (each carried
// pixel's anchor is replaced by its source's), the old view's records and accumulation, the
// new accumulation written for every pixel, and [carried, shown] counted.

const NOTHING: u32 = 0xffffffffu;
const MISS: u32 = 0xfffffffeu;
const NEVER_REUSE: u32 = 0x80000000u;
const COS_NORMAL: f32 = 0.9848078;
const PLANE_TOLERANCE: f32 = 0.01;
const ANGLE_PER_ALPHA: f32 = 0.5;
const DIFFUSE_ALPHA: f32 = 0.25;
const HISTORY_LENGTH: u32 = 32u;
const EDGE_HISTORY: u32 = 4u;
const MAX_MISREGISTRATION_PX: f32 = 0.75;
const LOOSE_MISREGISTRATION_PX: f32 = 1.5;
const LOOSE_HISTORY: u32 = 4u;
const MAX_JUMP: f32 = 0.25;
const F32_MAX: f32 = 3.40282347e38;
const ALL: u32 = 0xffffffffu;

// A view: the eye, and a pinhole's basis (tan_half_y = 0: orthographic, nothing projects) or,
// with tiles > 0, the wall camera's table (`old_wall` / `new_wall`).
struct View {
    eye: vec3<f32>,
    tan_half_y: f32,
    fwd: vec3<f32>,
    aspect: f32,
    right: vec3<f32>,
    tiles: u32,
    up: vec3<f32>,
    pad: u32,
}

struct ReuseParams {
    size: vec2<u32>,
    pad0: u32,
    pad1: u32,
    old_view: View,
    new_view: View,
}

@group(0) @binding(0) var<uniform> params: ReuseParams;
@group(0) @binding(1) var<storage, read> old_wall: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> new_wall: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> new_records: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> old_records: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> old_accum: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> old_counts: array<u32>;
@group(0) @binding(7) var<storage, read_write> accum: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> counts: array<u32>;
@group(0) @binding(9) var<storage, read_write> stats: array<atomic<u32>, 2>;

// A projected point: the image point (pixels, y down) and its pixel; pixel NOTHING: none.
struct Projected {
    at: vec2<f32>,
    pixel: u32,
}

// Where the line from the eye along `toward` crosses a tile entry's plane (twin:
// wall.rs, `tile_point`); x < 0 where it does not.
fn tile_point(origin: vec3<f32>, step_x: vec3<f32>, step_y: vec3<f32>, toward: vec3<f32>) -> vec2<f32> {
    let n = cross(step_x, step_y);
    let denom = dot(toward, n);
    let s = dot(origin, n) / denom;
    if !(s > 0.0 && s <= F32_MAX) {
        return vec2<f32>(-1.0);
    }
    let p = toward * s - origin;
    let bx = cross(step_y, n);
    let by = cross(n, step_x);
    return vec2<f32>(dot(p, bx) / dot(step_x, bx), dot(p, by) / dot(step_y, by));
}

// The first wall entry that holds pixel (x, y) (twin: WallCamera::tile_of).
fn tile_of(old: bool, count: u32, x: u32, y: u32) -> u32 {
    for (var i = 0u; i < count; i++) {
        var b: vec4<u32>;
        if old {
            b = bitcast<vec4<u32>>(old_wall[4u * i]);
        } else {
            b = bitcast<vec4<u32>>(new_wall[4u * i]);
        }
        if x >= b.x && x < b.y && y >= b.z && y < b.w {
            return i;
        }
    }
    return NOTHING;
}

// Wall entry i's image point along `toward` when its map gives one it traces (twin: the
// closure in WallCamera::project).
fn project_entry(old: bool, count: u32, i: u32, toward: vec3<f32>) -> Projected {
    var e: array<vec4<f32>, 4>;
    for (var k = 0u; k < 4u; k++) {
        if old {
            e[k] = old_wall[4u * i + k];
        } else {
            e[k] = new_wall[4u * i + k];
        }
    }
    let b = bitcast<vec4<u32>>(e[0]);
    let f = tile_point(e[1].xyz, e[2].xyz, e[3].xyz, toward);
    let tw = f32(b.y - b.x);
    let th = f32(b.w - b.z);
    if !(f.x >= 0.0 && f.y >= 0.0 && f.x < tw && f.y < th) {
        return Projected(vec2<f32>(0.0), NOTHING);
    }
    let x = b.x + u32(f.x);
    let y = b.z + u32(f.y);
    if tile_of(old, count, x, y) != i {
        return Projected(vec2<f32>(0.0), NOTHING);
    }
    return Projected(vec2<f32>(f32(b.x) + f.x, f32(b.z) + f.y), y * params.size.x + x);
}

// The view's image point along `toward` from its eye; through the wall camera the entry of
// pixel `near` first (twin: reuse.rs, View::project).
fn project(old: bool, toward: vec3<f32>, near: u32) -> Projected {
    var v = params.new_view;
    if old {
        v = params.old_view;
    }
    let none = Projected(vec2<f32>(0.0), NOTHING);
    let w = params.size.x;
    if v.tiles > 0u {
        let hint = tile_of(old, v.tiles, near % w, near / w);
        if hint != NOTHING {
            let at = project_entry(old, v.tiles, hint, toward);
            if at.pixel != NOTHING {
                return at;
            }
        }
        for (var i = 0u; i < v.tiles; i++) {
            let at = project_entry(old, v.tiles, i, toward);
            if at.pixel != NOTHING {
                return at;
            }
        }
        return none;
    }
    if v.tan_half_y == 0.0 {
        return none;
    }
    let z = dot(toward, v.fwd);
    if !(z > 0.0) {
        return none;
    }
    let sx = dot(toward, v.right) / (z * v.tan_half_y * v.aspect);
    let sy = dot(toward, v.up) / (z * v.tan_half_y);
    let fx = (sx + 1.0) * 0.5 * f32(w);
    let fy = (1.0 - sy) * 0.5 * f32(params.size.y);
    if !(fx >= 0.0 && fy >= 0.0 && fx < f32(w) && fy < f32(params.size.y)) {
        return none;
    }
    return Projected(vec2<f32>(fx, fy), u32(fy) * w + u32(fx));
}

// Whether one of the eight neighbours of pixel p has a word other than w (twin: reuse.rs,
// `on_edge`). The kernel writes the records' anchors, never their words.
fn on_edge(p: u32, w: u32) -> bool {
    let width = params.size.x;
    let x = i32(p % width);
    let y = i32(p / width);
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let nx = x + dx;
            let ny = y + dy;
            if (dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= i32(width) || ny >= i32(params.size.y) {
                continue;
            }
            if bitcast<u32>(new_records[2u * (u32(ny) * width + u32(nx)) + 1u].w) != w {
                return true;
            }
        }
    }
    return false;
}

// The old pixel pixel p takes and its cap (twin: reuse.rs, `reuse_source`); x = NOTHING: none.
fn reuse_source(p: u32, n0: vec4<f32>, n1: vec4<f32>) -> vec2<u32> {
    let none = vec2<u32>(NOTHING, 0u);
    let w = bitcast<u32>(n1.w);
    if w == NOTHING || (w != MISS && (w & NEVER_REUSE) != 0u) {
        return none;
    }
    let miss = w == MISS;
    let e0 = params.old_view.eye;
    let e1 = params.new_view.eye;
    let a = n0.xyz;
    if !miss && length(e1 - e0) > MAX_JUMP * length(a - e0) {
        return none;
    }
    var toward_old = a - e0;
    if miss {
        toward_old = a;
    }
    let q0 = project(true, toward_old, p);
    if q0.pixel == NOTHING {
        return none;
    }
    let width = params.size.x;
    let height = params.size.y;
    let qx = i32(q0.pixel % width);
    let qy = i32(q0.pixel / width);
    let centre = vec2<f32>(f32(p % width) + 0.5, f32(p / width) + 0.5);
    var best_d = 0.0;
    var best = NOTHING;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let x = qx + dx;
            let y = qy + dy;
            if x < 0 || y < 0 || x >= i32(width) || y >= i32(height) {
                continue;
            }
            let q = u32(y) * width + u32(x);
            if bitcast<u32>(old_records[2u * q + 1u].w) != w {
                continue;
            }
            let b = old_records[2u * q].xyz;
            var toward_new = b - e1;
            if miss {
                toward_new = b;
            }
            let pr = project(false, toward_new, p);
            if pr.pixel == NOTHING {
                continue;
            }
            let dist = max(abs(pr.at.x - centre.x), abs(pr.at.y - centre.y));
            if dist <= LOOSE_MISREGISTRATION_PX && (best == NOTHING || dist < best_d) {
                best_d = dist;
                best = q;
            }
        }
    }
    if best == NOTHING {
        return none;
    }
    var loose = ALL;
    if best_d > MAX_MISREGISTRATION_PX {
        loose = LOOSE_HISTORY;
    }
    if on_edge(p, w) {
        loose = min(loose, EDGE_HISTORY);
    }
    if miss {
        return vec2<u32>(best, loose);
    }
    let on = old_records[2u * best + 1u].xyz;
    let b = old_records[2u * best].xyz;
    let depth = length(a - e1);
    if dot(n1.xyz, on) < COS_NORMAL || abs(dot(n1.xyz, b - a)) > PLANE_TOLERANCE * depth {
        return none;
    }
    let alpha = n0.w;
    let c = clamp(dot(normalize(e0 - a), normalize(e1 - a)), -1.0, 1.0);
    if acos(c) > ANGLE_PER_ALPHA * alpha {
        return none;
    }
    if alpha < DIFFUSE_ALPHA {
        return vec2<u32>(best, min(HISTORY_LENGTH, loose));
    }
    return vec2<u32>(best, loose);
}

@compute @workgroup_size(64)
fn reuse(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let p = gid.x + gid.y * groups.x * 64u;
    if p >= params.size.x * params.size.y {
        return;
    }
    let n0 = new_records[2u * p];
    let n1 = new_records[2u * p + 1u];
    if bitcast<u32>(n1.w) != NOTHING {
        atomicAdd(&stats[1], 1u);
    }
    let src = reuse_source(p, n0, n1);
    if src.x == NOTHING {
        accum[p] = vec4<f32>(0.0);
        counts[p] = 0u;
        return;
    }
    var sum = old_accum[src.x];
    var count = old_counts[src.x];
    if count > src.y {
        sum = sum * (f32(src.y) / f32(count));
        count = src.y;
    }
    accum[p] = sum;
    counts[p] = count;
    new_records[2u * p] = vec4<f32>(old_records[2u * src.x].xyz, n0.w);
    atomicAdd(&stats[0], 1u);
}
