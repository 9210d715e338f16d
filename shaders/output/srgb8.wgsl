// The picture as the viewer shows it (DESIGN.md §1, step 4's last part): each pixel of the
// filtered image at `scale` = 2^exposure, the sRGB transfer function, 8 bits a channel, opaque,
// packed as RGBA bytes in one u32; with `masked`, the pixels no wall tile shows are black; with
// `outline`, the ROI's outline (an ROI pixel, d = 0, with a 4-neighbour outside it, d > 0) is
// painted over in the outline colour, so that the window needs no DGI read back. The table's
// integer comparisons give the same byte as the CPU twin for every f32, NaN and infinities
// included: CPU twin `display_rgba` then `paint_outline(roi_outline(..))` in
// src/output/srgb8.rs; dispatch: src/output/gpu.rs.

// Mirrors `GpuDisplayParams` in src/output/gpu.rs (32 bytes).
struct DisplayParams {
    pixels: u32,
    // 2^exposure: every channel is multiplied by it before the conversion.
    scale: f32,
    // 1: a pixel whose bit in `shown` is 0 is black (a wall camera's unshown pixels).
    masked: u32,
    // 1: the ROI's outline in `dgi` (a picture of `width` × `height`) is painted.
    outline: u32,
    width: u32,
    height: u32,
    // Output words a row: `width` (packed), or more where the rows are padded for a copy into
    // a texture (a multiple of 64 pixels: 256 bytes).
    pitch: u32,
    _pad1: u32,
}

// `OUTLINE` in src/output/srgb8.rs (255, 220, 0, 255) as the packed RGBA.
const OUTLINE: u32 = 0xFF00DCFFu;

// Bits dropped from a pattern to index the table (GPU_TABLE_SHIFT in src/output/srgb8.rs).
const SHIFT: u32 = 15u;

@group(0) @binding(0) var<uniform> cfg: DisplayParams;
// The filtered picture, linear RGB (alpha unused), row-major.
@group(0) @binding(1) var<storage, read> image: array<vec4<f32>>;
// Per bucket of 2^SHIFT patterns below 1.0: (code of its first float, pattern of the least
// float with the next code).
@group(0) @binding(2) var<storage, read> table: array<vec2<u32>>;
// Bit p % 32 of word p / 32: whether some tile shows pixel p (read only with `masked`).
@group(0) @binding(3) var<storage, read> shown: array<u32>;
@group(0) @binding(4) var<storage, read_write> rgba: array<u32>;
// The picture's DGI (read only with `outline`).
@group(0) @binding(5) var<storage, read> dgi: array<f32>;

// `roi_outline`: pixel i lies in the ROI and a 4-neighbour does not.
fn on_outline(i: u32) -> bool {
    if dgi[i] != 0.0 {
        return false;
    }
    let x = i % cfg.width;
    let y = i / cfg.width;
    return (x > 0u && dgi[i - 1u] > 0.0)
        || (x + 1u < cfg.width && dgi[i + 1u] > 0.0)
        || (y > 0u && dgi[i - cfg.width] > 0.0)
        || (y + 1u < cfg.height && dgi[i + cfg.width] > 0.0);
}

fn srgb8(v: f32) -> u32 {
    let bits = bitcast<u32>(v);
    // Negative values (sign bit set) and NaN: 0.
    if bits > 0x7F800000u {
        return 0u;
    }
    // 1.0 and above, +inf included: 255.
    if bits >= 0x3F800000u {
        return 255u;
    }
    let t = table[bits >> SHIFT];
    return t.x + select(0u, 1u, bits >= t.y);
}

@compute @workgroup_size(256)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let i = gid.x + gid.y * groups.x * 256u;
    if i >= cfg.pixels {
        return;
    }
    let o = (i / cfg.width) * cfg.pitch + i % cfg.width;
    if cfg.outline != 0u && on_outline(i) {
        rgba[o] = OUTLINE;
        return;
    }
    if cfg.masked != 0u && (shown[i / 32u] & (1u << (i % 32u))) == 0u {
        rgba[o] = 0xFF000000u;
        return;
    }
    let p = image[i].xyz * cfg.scale;
    rgba[o] = srgb8(p.x) | (srgb8(p.y) << 8u) | (srgb8(p.z) << 16u) | 0xFF000000u;
}
