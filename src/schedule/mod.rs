//! Scheduling (DESIGN.md §6): which pixels the path tracer samples in an iteration.
//!
//! Pixel i with DGI value d_i is sampled with probability p_i = max(p_min, 1 − d_i) (the paper's
//! preset is p_min = 0), decided by one Bernoulli draw from the counter-based hash of
//! (pixel, iteration, seed, [`stream::SCHEDULE`]) in `src/random.rs`, so this CPU twin and the
//! kernel (`shaders/schedule/`, dispatched by [`gpu`]) select exactly the same pixels. The
//! selected pixels are compacted into a list of pixel indices `y * width + x` that the tracer
//! runs one thread per entry over.
//!
//! # The list's order
//!
//! The image is cut into [`TILE_EDGE`]² blocks of [`BLOCK_PIXELS`] slots, one GPU workgroup
//! each. With [`Order::Coherent`] a block is a 32 × 32 pixel tile and its slots follow the
//! Morton (Z) curve inside the tile, so consecutive list entries are neighbouring pixels: a
//! tracer workgroup of 64 threads over a fully selected tile covers an 8 × 8 pixel square, and
//! over a sparse one still a compact part of one tile (ray coherence, DESIGN.md §6). With
//! [`Order::Scattered`] the slots of the whole image are mapped to pixels by a fixed
//! pseudo-random permutation ([`scatter`]), so consecutive entries are unrelated pixels; it
//! selects the same set and exists only so that benchmarks can measure what coherence buys.
//!
//! Within a block the order is deterministic (slot order). The GPU appends the blocks in the
//! order their workgroups reserve output space, which varies from run to run; this twin
//! appends them in block order (row-major tiles). Both therefore produce the same set, and
//! the GPU list is a permutation of the twin's per-block runs ([`schedule_cpu_blocks`]).

pub mod gpu;

use rayon::prelude::*;

use crate::random::{pcg4d, stream, unit_f32};

/// Edge of a block's tile in pixels (a block holds `TILE_EDGE²` slots).
pub const TILE_EDGE: u32 = 32;
/// Slots per block: one workgroup of [`BLOCK_THREADS`] threads × [`SLOTS_PER_THREAD`].
pub const BLOCK_PIXELS: u32 = TILE_EDGE * TILE_EDGE;
/// Threads per compaction workgroup.
pub const BLOCK_THREADS: u32 = 256;
/// Slots per thread: a 2 × 2 pixel quad in the coherent order.
pub const SLOTS_PER_THREAD: u32 = BLOCK_PIXELS / BLOCK_THREADS;

/// The order of the compacted list (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Order {
    /// 32 × 32 tiles, Morton order inside a tile: neighbouring pixels in neighbouring threads.
    #[default]
    Coherent,
    /// A fixed pseudo-random permutation of the pixels (same set; for measuring coherence).
    Scattered,
}

impl Order {
    /// The value of `Params.order` in `shaders/schedule/compact.wgsl`.
    #[must_use]
    pub fn code(self) -> u32 {
        match self {
            Self::Coherent => 0,
            Self::Scattered => 1,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ScheduleError {
    #[error(
        "p_min {p_min} must be 0 or a normal f32 in [f32::MIN_POSITIVE, 1] (the lowest sampling probability of a pixel)"
    )]
    PMin { p_min: f32 },
    #[error(
        "image size {width}×{height}: both sides must be in 1..={max_side} and the image at most {max_pixels} pixels"
    )]
    Size {
        width: u32,
        height: u32,
        max_side: u32,
        max_pixels: u64,
    },
    #[error("the DGI has {found} values; a {width}×{height} image needs {expected}")]
    DgiLength {
        width: u32,
        height: u32,
        expected: u64,
        found: u64,
    },
    #[error(
        "tracer workgroup size {size} must be in 1..={max} (the adapter's invocations per workgroup)"
    )]
    WorkgroupSize { size: u32, max: u32 },
    #[error(
        "{count} list entries need more than {max_per_dim}² workgroups of {workgroup_size} threads (the indirect grid's limit)"
    )]
    TooManyGroups {
        count: u32,
        workgroup_size: u32,
        max_per_dim: u32,
    },
    #[error(
        "the DGI buffer has {bytes} bytes (storage usage: {storage}); the schedule needs {needed} bytes of f32 with STORAGE usage"
    )]
    DgiBuffer {
        bytes: u64,
        needed: u64,
        storage: bool,
    },
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
}

/// Checks that `p_min` is a probability (NaN is rejected too). Subnormal values are rejected
/// as well: GPUs may flush them to 0, and the twins would then disagree.
pub fn validate_p_min(p_min: f32) -> Result<f32, ScheduleError> {
    if (0.0..=1.0).contains(&p_min) && (p_min == 0.0 || p_min.is_normal()) {
        Ok(p_min)
    } else {
        Err(ScheduleError::PMin { p_min })
    }
}

/// The sampling probability of a pixel with DGI value `d`: `max(p_min, 1 − d)` in f32, the same
/// operations as `probability` in `shaders/schedule/select.wgsl` (bitwise equal; tested).
///
/// The DGI stage keeps d in [0, 1]; d < 0 gives p > 1 (always sampled) and d > 1 gives p_min.
#[inline]
#[must_use]
pub fn probability(d: f32, p_min: f32) -> f32 {
    p_min.max(1.0 - d)
}

/// The Bernoulli decision of `pixel` in `iteration`: a uniform number in [0, 1) from the shared
/// hash below `p`. p ≥ 1 always selects (the number is below 1) and p ≤ 0 never does, so those
/// skip the hash (most pixels of a small ROI's DGI have p = 0).
#[inline]
#[must_use]
pub fn selected(pixel: u32, iteration: u32, seed: u32, p: f32) -> bool {
    if p >= 1.0 {
        return true;
    }
    p > 0.0 && unit_f32(pcg4d([pixel, iteration, seed, stream::SCHEDULE])[0]) < p
}

/// Morton (Z-order) index inside a tile → (x, y): even bits are x, odd bits are y.
#[inline]
#[must_use]
pub fn morton_decode(m: u32) -> (u32, u32) {
    (compact_bits(m), compact_bits(m >> 1))
}

/// Keeps the even bits of `v` and packs them (the inverse of spreading a 16-bit value).
#[inline]
fn compact_bits(v: u32) -> u32 {
    let mut x = v & 0x5555_5555;
    x = (x | (x >> 1)) & 0x3333_3333;
    x = (x | (x >> 2)) & 0x0f0f_0f0f;
    x = (x | (x >> 4)) & 0x00ff_00ff;
    (x | (x >> 8)) & 0x0000_ffff
}

/// Round keys of the scatter permutation (arbitrary fixed odd constants).
const SCATTER_KEYS: [u32; 4] = [0x9e37_79b9, 0x7f4a_7c15, 0xf39c_c060, 0x5ced_c834];

/// The Feistel round function: a 32-bit integer hash (Wellons' lowbias32) of the right half.
#[inline]
fn scatter_round(x: u32, key: u32) -> u32 {
    let mut h = (x ^ key).wrapping_mul(0x7feb_352d);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846c_a68b);
    h ^ (h >> 16)
}

/// Half the bit width of the scatter domain: the smallest h ≥ 1 with 4^h ≥ n (h ≤ 16).
#[must_use]
pub fn scatter_half_bits(n: u32) -> u32 {
    let mut h = 1;
    while h < 16 && (1u64 << (2 * h)) < u64::from(n) {
        h += 1;
    }
    h
}

/// A fixed pseudo-random bijection of [0, n): a 4-round Feistel network on 2h bits, walked
/// along its cycle until the value falls below n (expected fewer than 4 steps, since
/// 4^h < 4n). `half_bits` is [`scatter_half_bits`]`(n)`. Identical to `scatter` in
/// `shaders/schedule/select.wgsl`.
#[must_use]
pub fn scatter(slot: u32, half_bits: u32, n: u32) -> u32 {
    let mask = (1u32 << half_bits) - 1;
    let mut x = slot;
    loop {
        let (mut l, mut r) = (x >> half_bits, x & mask);
        for key in SCATTER_KEYS {
            (l, r) = (r, l ^ (scatter_round(r, key) & mask));
        }
        x = (l << half_bits) | r;
        if x < n {
            return x;
        }
    }
}

/// How an image is cut into blocks; the twin of the kernel's `Params` geometry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    pub width: u32,
    pub height: u32,
    /// Tiles per row and per column (the compaction dispatch's grid).
    pub tiles: [u32; 2],
    /// [`scatter_half_bits`] of the pixel count.
    pub scatter_half_bits: u32,
}

impl Layout {
    /// Largest side: the tile grid must fit one dispatch dimension (65 535 tiles of 32 px).
    pub const MAX_SIDE: u32 = 65_535 * TILE_EDGE;
    /// Most pixels: 2^31 keeps every slot index of the tile grid below 2^32 in the kernel
    /// (a 72-megapixel wall is 30× below it).
    pub const MAX_PIXELS: u64 = 1 << 31;

    pub fn new(width: u32, height: u32) -> Result<Self, ScheduleError> {
        let size_err = ScheduleError::Size {
            width,
            height,
            max_side: Self::MAX_SIDE,
            max_pixels: Self::MAX_PIXELS,
        };
        if width == 0
            || height == 0
            || width > Self::MAX_SIDE
            || height > Self::MAX_SIDE
            || u64::from(width) * u64::from(height) > Self::MAX_PIXELS
        {
            return Err(size_err);
        }
        Ok(Self {
            width,
            height,
            tiles: [width.div_ceil(TILE_EDGE), height.div_ceil(TILE_EDGE)],
            scatter_half_bits: scatter_half_bits(width * height),
        })
    }

    #[must_use]
    pub fn pixels(&self) -> u32 {
        self.width * self.height
    }

    #[must_use]
    pub fn blocks(&self) -> u32 {
        self.tiles[0] * self.tiles[1]
    }

    /// The pixel in slot `slot` (< [`BLOCK_PIXELS`]) of block `block`, or `None` where the
    /// slot lies outside the image (edge tiles; the scattered order's last block).
    #[inline]
    #[must_use]
    pub fn pixel(&self, order: Order, block: u32, slot: u32) -> Option<u32> {
        match order {
            Order::Coherent => {
                let (lx, ly) = morton_decode(slot);
                let x = (block % self.tiles[0]) * TILE_EDGE + lx;
                let y = (block / self.tiles[0]) * TILE_EDGE + ly;
                (x < self.width && y < self.height).then(|| y * self.width + x)
            }
            Order::Scattered => {
                let linear = u64::from(block) * u64::from(BLOCK_PIXELS) + u64::from(slot);
                (linear < u64::from(self.pixels()))
                    .then(|| scatter(linear as u32, self.scatter_half_bits, self.pixels()))
            }
        }
    }
}

fn check_dgi(dgi: &[f32], layout: &Layout) -> Result<(), ScheduleError> {
    let expected = u64::from(layout.pixels());
    if dgi.len() as u64 != expected {
        return Err(ScheduleError::DgiLength {
            width: layout.width,
            height: layout.height,
            expected,
            found: dgi.len() as u64,
        });
    }
    Ok(())
}

/// One iteration's draw over a validated DGI: what a compaction workgroup knows.
struct Draw<'a> {
    dgi: &'a [f32],
    layout: Layout,
    p_min: f32,
    iteration: u32,
    seed: u32,
    order: Order,
    /// Coherent order: `ly · width + lx` of each Morton slot, for tiles inside the image.
    offsets: Vec<u32>,
}

impl<'a> Draw<'a> {
    fn new(
        dgi: &'a [f32],
        (width, height): (u32, u32),
        p_min: f32,
        iteration: u32,
        seed: u32,
        order: Order,
    ) -> Result<Self, ScheduleError> {
        let p_min = validate_p_min(p_min)?;
        let layout = Layout::new(width, height)?;
        check_dgi(dgi, &layout)?;
        let offsets = (0..BLOCK_PIXELS)
            .map(|m| {
                let (x, y) = morton_decode(m);
                y * width + x
            })
            .collect();
        Ok(Self {
            dgi,
            layout,
            p_min,
            iteration,
            seed,
            order,
            offsets,
        })
    }

    #[inline]
    fn take(&self, px: u32) -> bool {
        let p = probability(self.dgi[px as usize], self.p_min);
        selected(px, self.iteration, self.seed, p)
    }

    /// Appends block `block`'s selected pixels to `out` in slot order.
    #[inline]
    fn block(&self, block: u32, out: &mut Vec<u32>) {
        let (tx, ty) = (block % self.layout.tiles[0], block / self.layout.tiles[0]);
        let (x0, y0) = (tx * TILE_EDGE, ty * TILE_EDGE);
        if self.order == Order::Coherent
            && x0 + TILE_EDGE <= self.layout.width
            && y0 + TILE_EDGE <= self.layout.height
        {
            // A tile inside the image: the same slots as `Layout::pixel` without its per-slot
            // Morton decode and bounds checks (3840×2160 on 2 cores: 10° 29 → 18–22 ms,
            // 60° 58 → 41–45 ms; what remains is mostly cache misses of the Z walk).
            let base = y0 * self.layout.width + x0;
            out.extend(
                self.offsets
                    .iter()
                    .map(|&o| base + o)
                    .filter(|&px| self.take(px)),
            );
            return;
        }
        out.extend(
            (0..BLOCK_PIXELS)
                .filter_map(|slot| self.layout.pixel(self.order, block, slot))
                .filter(|&px| self.take(px)),
        );
    }
}

/// The selected pixels of each block, in slot order (blocks in index order; empty blocks
/// included). The GPU list is these runs, non-empty ones only, in some order.
pub fn schedule_cpu_blocks(
    dgi: &[f32],
    width: u32,
    height: u32,
    p_min: f32,
    iteration: u32,
    seed: u32,
    order: Order,
) -> Result<Vec<Vec<u32>>, ScheduleError> {
    let draw = Draw::new(dgi, (width, height), p_min, iteration, seed, order)?;
    Ok((0..draw.layout.blocks())
        .into_par_iter()
        .map(|block| {
            let mut out = Vec::new();
            draw.block(block, &mut out);
            out
        })
        .collect())
}

/// The CPU twin of the GPU schedule: the selected pixel indices (`y * width + x`) of one
/// iteration, blocks in index order, each block in its deterministic slot order.
pub fn schedule_cpu(
    dgi: &[f32],
    width: u32,
    height: u32,
    p_min: f32,
    iteration: u32,
    seed: u32,
    order: Order,
) -> Result<Vec<u32>, ScheduleError> {
    let draw = Draw::new(dgi, (width, height), p_min, iteration, seed, order)?;
    let [tiles_x, tiles_y] = draw.layout.tiles;
    // One task per row of blocks: few allocations, and rows balance well across threads.
    let rows: Vec<Vec<u32>> = (0..tiles_y)
        .into_par_iter()
        .map(|row| {
            let mut out = Vec::new();
            for block in row * tiles_x..(row + 1) * tiles_x {
                draw.block(block, &mut out);
            }
            out
        })
        .collect();
    Ok(rows.concat())
}

/// The indirect dispatch grid for `count` listed pixels and a tracer workgroup of
/// `workgroup_size` threads, with at most `max_per_dim` workgroups per dimension (65 535 in
/// WebGPU's defaults; 3840 × 2160 / 64 = 129 600 groups needs two dimensions).
///
/// Returns `[gx, gy, 1]` with gx·gy ≥ ⌈count / workgroup_size⌉, gx, gy ≤ max_per_dim and fewer
/// than gy idle groups; `[0, 1, 1]` when nothing is listed. The tracer's thread for list entry
/// `(wg.y · gx + wg.x) · workgroup_size + local_index` returns when that is ≥ count. Identical
/// to `shaders/schedule/args.wgsl`.
#[must_use]
pub fn indirect_grid(count: u32, workgroup_size: u32, max_per_dim: u32) -> [u32; 3] {
    let groups = count.div_ceil(workgroup_size);
    if groups == 0 {
        return [0, 1, 1];
    }
    let gy = groups.div_ceil(max_per_dim);
    let gx = groups.div_ceil(gy);
    [gx, gy, 1]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn p_min_outside_the_unit_interval_is_rejected_by_name() {
        for bad in [-0.01, 1.01, f32::NAN, f32::INFINITY, 1e-40] {
            let err = validate_p_min(bad).unwrap_err();
            assert!(err.to_string().contains("p_min"), "{err}");
        }
        for good in [0.0, 0.5, 1.0] {
            assert_eq!(validate_p_min(good).unwrap(), good);
        }
        let err = schedule_cpu(&[0.5; 4], 2, 2, 1.5, 0, 0, Order::Coherent).unwrap_err();
        assert!(matches!(err, ScheduleError::PMin { .. }), "{err}");
    }

    #[test]
    fn a_dgi_of_the_wrong_length_or_an_empty_image_is_rejected() {
        let err = schedule_cpu(&[0.5; 5], 2, 2, 0.0, 0, 0, Order::Coherent).unwrap_err();
        assert!(err.to_string().contains("needs 4"), "{err}");
        let err = schedule_cpu(&[], 0, 2, 0.0, 0, 0, Order::Coherent).unwrap_err();
        assert!(matches!(err, ScheduleError::Size { .. }), "{err}");
        assert!(Layout::new(Layout::MAX_SIDE + 1, 1).is_err());
        assert!(Layout::new(65_536, 32_769).is_err(), "over 2^31 pixels");
        assert!(Layout::new(65_536, 32_768).is_ok());
    }

    #[test]
    fn probability_is_one_minus_d_floored_at_p_min() {
        assert_eq!(probability(0.0, 0.0), 1.0);
        assert_eq!(probability(1.0, 0.0), 0.0);
        assert_eq!(probability(0.25, 0.0), 0.75);
        assert_eq!(probability(0.9, 0.2), 0.2);
        assert_eq!(probability(0.5, 0.2), 0.5);
        assert_eq!(probability(1.0, 0.05), 0.05);
    }

    #[test]
    fn probability_one_always_selects_and_zero_never() {
        for px in 0..5000 {
            for it in [0, 1, 77, u32::MAX] {
                assert!(selected(px, it, 3, 1.0));
                assert!(!selected(px, it, 3, 0.0));
            }
        }
    }

    #[test]
    fn morton_decode_covers_a_tile_once_in_z_order() {
        let mut seen = vec![false; BLOCK_PIXELS as usize];
        for m in 0..BLOCK_PIXELS {
            let (x, y) = morton_decode(m);
            assert!(x < TILE_EDGE && y < TILE_EDGE, "slot {m} → ({x}, {y})");
            let i = (y * TILE_EDGE + x) as usize;
            assert!(!seen[i], "slot {m} revisits ({x}, {y})");
            seen[i] = true;
        }
        // Each thread's four slots are a 2 × 2 quad; 64 consecutive slots an 8 × 8 square.
        assert_eq!(
            (0..4).map(morton_decode).collect::<Vec<_>>(),
            [(0, 0), (1, 0), (0, 1), (1, 1)]
        );
        for start in (0..BLOCK_PIXELS).step_by(64) {
            let (x0, y0) = morton_decode(start);
            for m in start..start + 64 {
                let (x, y) = morton_decode(m);
                assert!(
                    (x0..x0 + 8).contains(&x) && (y0..y0 + 8).contains(&y),
                    "slot {m} leaves its 8×8 square"
                );
            }
        }
    }

    #[test]
    fn scatter_is_a_bijection_for_awkward_sizes() {
        for n in [1u32, 2, 3, 5, 64, 1000, 130 * 70, 4097] {
            let h = scatter_half_bits(n);
            assert!(1u64 << (2 * h) >= u64::from(n));
            assert!(h == 1 || (1u64 << (2 * (h - 1))) < u64::from(n));
            let mut seen = vec![false; n as usize];
            for s in 0..n {
                let p = scatter(s, h, n);
                assert!(p < n && !seen[p as usize], "n {n}: slot {s} → {p}");
                seen[p as usize] = true;
            }
        }
        // Not the identity and not a shift: neighbouring slots land far apart.
        let n = 130 * 70;
        let h = scatter_half_bits(n);
        let jumps: u64 = (0..n - 1)
            .map(|s| u64::from(scatter(s, h, n).abs_diff(scatter(s + 1, h, n))))
            .sum();
        // Two independent uniform indices in [0, n) lie n/3 apart on average.
        let mean = jumps as f64 / f64::from(n - 1);
        assert!(
            mean > f64::from(n) / 4.0,
            "neighbouring slots {mean} apart on average"
        );
    }

    #[test]
    fn the_coherent_list_is_tile_by_tile_in_morton_order() {
        // 40×36: a full tile, and partial tiles on the right and bottom.
        let (w, h) = (40, 36);
        let dgi = vec![0.0; (w * h) as usize];
        let list = schedule_cpu(&dgi, w, h, 0.0, 0, 0, Order::Coherent).unwrap();
        assert_eq!(list.len(), (w * h) as usize, "d = 0 selects every pixel");
        let mut expected = Vec::new();
        for (tx, ty) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            for m in 0..BLOCK_PIXELS {
                let (x, y) = morton_decode(m);
                let (x, y) = (tx * TILE_EDGE + x, ty * TILE_EDGE + y);
                if x < w && y < h {
                    expected.push(y * w + x);
                }
            }
        }
        assert_eq!(list, expected);
        assert_eq!(&list[..4], &[0, 1, w, w + 1]);
    }

    #[test]
    fn both_orders_select_the_same_set() {
        let (w, h) = (130, 70);
        let dgi: Vec<f32> = (0..w * h).map(|i| (i % 17) as f32 / 16.0).collect();
        for it in 0..4 {
            let mut a = schedule_cpu(&dgi, w, h, 0.1, it, 9, Order::Coherent).unwrap();
            let mut b = schedule_cpu(&dgi, w, h, 0.1, it, 9, Order::Scattered).unwrap();
            assert_ne!(a, b, "the orders differ");
            a.sort_unstable();
            b.sort_unstable();
            assert_eq!(a, b);
            assert!(a.windows(2).all(|p| p[0] < p[1]), "no pixel listed twice");
        }
    }

    #[test]
    fn indirect_grid_covers_the_count_within_the_dimension_limit() {
        // Workgroups of one thread cannot cover more than 65 535² pixels; the schedule refuses
        // such images (`ScheduleRun`), so they only meet the smaller counts.
        let wgs = [1u32, 64, 128, 256];
        let counts = [
            0u32,
            1,
            63,
            64,
            65,
            65_535,
            65_535 * 64,
            65_535 * 64 + 1,
            3840 * 2160,
            u32::MAX - 1,
            u32::MAX,
        ];
        for wg in wgs {
            for count in counts {
                if wg == 1 && count > 65_535 * 65_535 {
                    continue;
                }
                let [gx, gy, gz] = indirect_grid(count, wg, 65_535);
                assert_eq!(gz, 1);
                assert!(gx <= 65_535 && gy <= 65_535, "{count}/{wg}: {gx}×{gy}");
                let groups = u64::from(count).div_ceil(u64::from(wg));
                let launched = u64::from(gx) * u64::from(gy);
                assert!(launched >= groups, "{count}/{wg}: {gx}×{gy} < {groups}");
                assert!(
                    launched - groups < u64::from(gy.max(1)),
                    "{count}/{wg}: waste"
                );
            }
        }
        assert_eq!(indirect_grid(0, 64, 65_535), [0, 1, 1]);
        assert_eq!(indirect_grid(64, 64, 65_535), [1, 1, 1]);
        assert_eq!(indirect_grid(3840 * 2160, 64, 65_535), [64_800, 2, 1]);
    }
}
