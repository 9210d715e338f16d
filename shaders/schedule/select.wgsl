// Per-pixel scheduling decisions (DESIGN.md §6) and the schedule kernels' uniform, shared by the
// compaction and block-masks kernels and tests.
// CPU twin: src/schedule/mod.rs (`probability`, `selected`, `morton_decode`, `scatter`).
// Concatenated after shaders/random.wgsl (pcg4d, unit_f32).

// The schedule kernels' uniform; mirrors `GpuParams` in src/schedule/gpu.rs (48 bytes).
struct Params {
    size: vec2<u32>,
    // Tiles per row; the dispatch is (tiles_x, tiles_y).
    tiles_x: u32,
    // 0 coherent (Morton order in 32 × 32 tiles), 1 scattered (a fixed pixel permutation).
    order: u32,
    iteration: u32,
    seed: u32,
    p_min: f32,
    scatter_half_bits: u32,
    // 1: a pixel whose bit in `shown` is clear has probability 0 (the wall camera's bezels).
    masked: u32,
    // The image's index of this schedule's pixel 0 (a frame split into bands of rows): the coin
    // of list pixel p is the image pixel pixel_base + p's.
    pixel_base: u32,
    _pad1: u32,
    _pad2: u32,
}

// random::stream::SCHEDULE in src/random.rs (a test checks they agree).
const STREAM_SCHEDULE: u32 = 0x5c4ed01eu;

// The sampling probability of a pixel with DGI value d: max(p_min, 1 − d), the twin's f32 ops.
fn probability(d: f32, p_min: f32) -> f32 {
    return max(p_min, 1.0 - d);
}

// The Bernoulli decision: a number in [0, 1) below p. p ≥ 1 always selects and p ≤ 0 never,
// so those skip the hash (the same results; most pixels of a small ROI's DGI have p = 0).
fn selected(pixel: u32, iteration: u32, seed: u32, p: f32) -> bool {
    if p >= 1.0 {
        return true;
    }
    if p <= 0.0 {
        return false;
    }
    return unit_f32(pcg4d(vec4<u32>(pixel, iteration, seed, STREAM_SCHEDULE)).x) < p;
}

// Keeps the even bits of v and packs them.
fn compact_bits(v: u32) -> u32 {
    var x = v & 0x55555555u;
    x = (x | (x >> 1u)) & 0x33333333u;
    x = (x | (x >> 2u)) & 0x0f0f0f0fu;
    x = (x | (x >> 4u)) & 0x00ff00ffu;
    return (x | (x >> 8u)) & 0x0000ffffu;
}

// Morton (Z-order) index inside a tile → (x, y): even bits x, odd bits y.
fn morton_decode(m: u32) -> vec2<u32> {
    return vec2<u32>(compact_bits(m), compact_bits(m >> 1u));
}

// Feistel round: Wellons' lowbias32 of the right half with a round key.
fn scatter_round(x: u32, key: u32) -> u32 {
    var h = (x ^ key) * 0x7feb352du;
    h ^= h >> 15u;
    h *= 0x846ca68bu;
    return h ^ (h >> 16u);
}

const SCATTER_KEYS = array<u32, 4>(0x9e3779b9u, 0x7f4a7c15u, 0xf39cc060u, 0x5cedc834u);

// A fixed bijection of [0, n): a 4-round Feistel network on 2·half_bits bits, cycle-walked
// until the value is below n (4^half_bits < 4n, so fewer than 4 steps are expected).
fn scatter(slot: u32, half_bits: u32, n: u32) -> u32 {
    let mask = (1u << half_bits) - 1u;
    var x = slot;
    loop {
        var l = x >> half_bits;
        var r = x & mask;
        for (var i = 0u; i < 4u; i++) {
            let next = l ^ (scatter_round(r, SCATTER_KEYS[i]) & mask);
            l = r;
            r = next;
        }
        x = (l << half_bits) | r;
        if x < n {
            break;
        }
    }
    return x;
}
