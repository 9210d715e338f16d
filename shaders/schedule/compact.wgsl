// Mask and compaction in one pass (DESIGN.md §6). CPU twin: schedule_cpu_blocks in
// src/schedule/mod.rs; dispatch: src/schedule/gpu.rs. Concatenated after
// shaders/random.wgsl and shaders/schedule/select.wgsl.
//
// One workgroup per block of 1024 slots (a 32 × 32 tile in the coherent order), one 2 × 2 quad
// of slots per thread. Each thread draws its four Bernoulli decisions, the workgroup scans the
// per-thread counts in shared memory, one thread reserves the block's output range with a
// single atomicAdd (none when the block selected nothing), and every thread writes its selected
// pixels in slot order. A block's run in the list is therefore deterministic; the order of the
// runs follows the atomics. One atomic per 1024 pixels keeps contention low (8 160 at
// 3840 × 2160), and no pass waits on another workgroup (WGSL gives no forward-progress
// guarantee, which a decoupled look-back scan would need for a deterministic order).
// The scan is plain shared memory (8 steps of two barriers); subgroup operations could shorten
// it behind a Features::SUBGROUP check, but whether that pays on a real GPU is unmeasured (no
// GPU was available when this was written), so the portable version is the only one.

// `Params` (the kernels' shared uniform): shaders/schedule/select.wgsl.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> dgi: array<f32>;
@group(0) @binding(2) var<storage, read_write> list: array<u32>;
// The append position; shaders/schedule/args.wgsl reads it and resets it to 0.
@group(0) @binding(3) var<storage, read_write> counter: atomic<u32>;
// Bit p % 32 of word p / 32: pixel p is shown (read only when params.masked == 1).
@group(0) @binding(4) var<storage, read> shown: array<u32>;

const TILE_EDGE: u32 = 32u;
const THREADS: u32 = 256u;
const SLOTS: u32 = 4u;
const OUTSIDE: u32 = 0xffffffffu;

var<workgroup> scan: array<u32, THREADS>;
var<workgroup> block_base: u32;

// The pixel in slot `slot` of block `block`, or OUTSIDE (twin: Layout::pixel).
fn slot_pixel(block: u32, tile: vec2<u32>, slot: u32) -> u32 {
    let n = params.size.x * params.size.y;
    if params.order == 0u {
        let p = tile * TILE_EDGE + morton_decode(slot);
        if p.x < params.size.x && p.y < params.size.y {
            return p.y * params.size.x + p.x;
        }
        return OUTSIDE;
    }
    // No wrap: images have at most 2^31 pixels and fewer than 2^31 / 1024 + 2^17 tiles
    // (Layout::new).
    let linear = block * (TILE_EDGE * TILE_EDGE) + slot;
    if linear >= n {
        return OUTSIDE;
    }
    return scatter(linear, params.scatter_half_bits, n);
}

// The pixel's probability: 0 where the mask hides it, else max(p_min, 1 − d)
// (twin: Draw::take in src/schedule/compact.rs).
fn shown_probability(px: u32) -> f32 {
    if params.masked == 1u && ((shown[px >> 5u] >> (px & 31u)) & 1u) == 0u {
        return 0.0;
    }
    return probability(dgi[px], params.p_min);
}

@compute @workgroup_size(256)
fn main(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(local_invocation_index) t: u32,
) {
    let block = wg.y * params.tiles_x + wg.x;
    var pixels: array<u32, SLOTS>;
    var flags = 0u;
    for (var j = 0u; j < SLOTS; j++) {
        let px = slot_pixel(block, wg.xy, SLOTS * t + j);
        pixels[j] = px;
        if px != OUTSIDE
            && selected(params.pixel_base + px, params.iteration, params.seed,
                shown_probability(px)) {
            flags |= 1u << j;
        }
    }
    let count = countOneBits(flags);

    // Inclusive Hillis–Steele scan of the per-thread counts.
    var inclusive = count;
    for (var offset = 1u; offset < THREADS; offset <<= 1u) {
        scan[t] = inclusive;
        workgroupBarrier();
        if t >= offset {
            inclusive += scan[t - offset];
        }
        workgroupBarrier();
    }
    if t == THREADS - 1u {
        var base = 0u;
        if inclusive > 0u {
            base = atomicAdd(&counter, inclusive);
        }
        block_base = base;
    }
    var out = workgroupUniformLoad(&block_base) + inclusive - count;
    for (var j = 0u; j < SLOTS; j++) {
        if (flags & (1u << j)) != 0u {
            list[out] = pixels[j];
            out += 1u;
        }
    }
}
