//! Scheduling (DESIGN.md §6): which pixels the path tracer samples in an iteration.
//!
//! Pixel i with DGI value d_i is sampled with probability p_i = max(p_min, 1 − d_i) (the paper's
//! preset is p_min = 0), decided by one Bernoulli draw from the counter-based hash of
//! (pixel, iteration, seed, [`stream::SCHEDULE`](crate::random::stream::SCHEDULE)) in `src/random.rs`, so this CPU twin and the
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

pub mod args;
pub mod compact;
pub mod gpu;
pub mod masks;
pub mod select;

pub use args::indirect_grid;
pub use compact::{DrawInput, Layout, schedule_cpu, schedule_cpu_blocks, schedule_cpu_shown};
pub use masks::{SlotMask, schedule_cpu_block_masks};
pub use select::{morton_decode, probability, scatter, scatter_half_bits, selected};

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
        "shown mask of {found} words for a {width}×{height} image: expected {expected} (one bit per pixel)"
    )]
    ShownLength {
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
                let [gx, gy, gz] = indirect_grid(count, wg, 0, 65_535);
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
        assert_eq!(indirect_grid(0, 64, 0, 65_535), [0, 1, 1]);
        assert_eq!(indirect_grid(64, 64, 0, 65_535), [1, 1, 1]);
        assert_eq!(indirect_grid(3840 * 2160, 64, 0, 65_535), [64_800, 2, 1]);
        // A regenerating tracer's cap: at most that many groups, however long the list.
        assert_eq!(indirect_grid(3840 * 2160, 64, 2112, 65_535), [2112, 1, 1]);
        assert_eq!(indirect_grid(100, 64, 2112, 65_535), [2, 1, 1]);
        assert_eq!(indirect_grid(0, 64, 2112, 65_535), [0, 1, 1]);
        assert_eq!(indirect_grid(u32::MAX, 32, 65_535, 1000), [993, 66, 1]);
    }
}
