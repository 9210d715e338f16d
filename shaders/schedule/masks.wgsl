// The coherent schedule's selected slots of every block, as bit masks (DESIGN.md §6, §12).
// CPU twin: schedule_cpu_block_masks in src/schedule/compact.rs; dispatch: BlockMasksRun in
// src/schedule/gpu.rs. Concatenated after shaders/random.wgsl and
// shaders/schedule/select.wgsl.
//
// The same decisions as compact.wgsl's coherent order, written as one 32-bit word per 32 slots
// instead of a list: bit s % 32 of word 32·block + s / 32 is slot s of block `block` (its pixel
// is the tile's Morton slot s). A GPU rank of a cluster reads the masks back (128 bytes a block)
// and lists, from them, the blocks it traces or owns; one workgroup of 32 threads per block,
// one word per thread.

// `Params`: shaders/schedule/select.wgsl (`order`, `scatter_half_bits` are not read: the
// masks are the coherent order's).

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> dgi: array<f32>;
@group(0) @binding(2) var<storage, read_write> masks: array<u32>;
// Bit p % 32 of word p / 32: pixel p is shown (read only when params.masked == 1).
@group(0) @binding(3) var<storage, read> shown: array<u32>;

const TILE_EDGE: u32 = 32u;
const WORDS: u32 = 32u;

@compute @workgroup_size(32)
fn main(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(local_invocation_index) t: u32,
) {
    let block = wg.y * params.tiles_x + wg.x;
    var word = 0u;
    for (var j = 0u; j < 32u; j++) {
        let p = wg.xy * TILE_EDGE + morton_decode(32u * t + j);
        if p.x < params.size.x && p.y < params.size.y {
            let px = p.y * params.size.x + p.x;
            var prob = probability(dgi[px], params.p_min);
            if params.masked == 1u && ((shown[px >> 5u] >> (px & 31u)) & 1u) == 0u {
                prob = 0.0;
            }
            if selected(params.pixel_base + px, params.iteration, params.seed, prob) {
                word |= 1u << j;
            }
        }
    }
    masks[block * WORDS + t] = word;
}
