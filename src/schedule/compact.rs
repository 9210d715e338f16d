//! Mask and compaction (DESIGN.md §6): the selected pixels of every block, in slot order, as one
//! list. CPU twin of `shaders/schedule/compact.wgsl`.

use rayon::prelude::*;

use super::select::{morton_decode, probability, scatter, scatter_half_bits, selected};
use super::{BLOCK_PIXELS, Order, ScheduleError, TILE_EDGE, validate_p_min};

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

/// Checks that a shown mask has one bit for each pixel.
pub(crate) fn check_shown(shown: Option<&[u32]>, layout: &Layout) -> Result<(), ScheduleError> {
    let expected = u64::from(layout.pixels()).div_ceil(32);
    match shown {
        Some(m) if m.len() as u64 != expected => Err(ScheduleError::ShownLength {
            width: layout.width,
            height: layout.height,
            expected,
            found: m.len() as u64,
        }),
        _ => Ok(()),
    }
}

/// What one iteration's schedule is drawn from: the DGI of a `width × height` frame, the
/// pixels shown (bit `p % 32` of word `p / 32` for pixel `p`; `None`: every pixel), the
/// probability floor, and the iteration and seed the draw is keyed on.
#[derive(Clone, Copy, Debug)]
pub struct DrawInput<'a> {
    pub dgi: &'a [f32],
    pub shown: Option<&'a [u32]>,
    pub width: u32,
    pub height: u32,
    pub p_min: f32,
    pub iteration: u32,
    pub seed: u32,
}

/// One iteration's draw over a validated DGI: what a compaction workgroup knows.
pub(super) struct Draw<'a> {
    dgi: &'a [f32],
    /// Bit `p % 32` of word `p / 32`: pixel `p` may be selected (`None`: every pixel).
    shown: Option<&'a [u32]>,
    layout: Layout,
    p_min: f32,
    iteration: u32,
    seed: u32,
    order: Order,
    /// Coherent order: `ly · width + lx` of each Morton slot, for tiles inside the image.
    offsets: Vec<u32>,
}

impl<'a> Draw<'a> {
    pub(super) fn new(input: &DrawInput<'a>, order: Order) -> Result<Self, ScheduleError> {
        let DrawInput {
            dgi,
            shown,
            width,
            height,
            p_min,
            iteration,
            seed,
        } = *input;
        let p_min = validate_p_min(p_min)?;
        let layout = Layout::new(width, height)?;
        check_dgi(dgi, &layout)?;
        check_shown(shown, &layout)?;
        let offsets = (0..BLOCK_PIXELS)
            .map(|m| {
                let (x, y) = morton_decode(m);
                y * width + x
            })
            .collect();
        Ok(Self {
            dgi,
            shown,
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
        // A hidden pixel has probability 0 (the kernel's `shown_probability`).
        if let Some(m) = self.shown
            && m[(px / 32) as usize] >> (px % 32) & 1 == 0
        {
            return false;
        }
        let p = probability(self.dgi[px as usize], self.p_min);
        selected(px, self.iteration, self.seed, p)
    }

    /// Appends block `block`'s selected pixels to `out` in slot order.
    #[inline]
    fn block(&self, block: u32, out: &mut Vec<u32>) {
        self.selected(block, |_, px| out.push(px));
    }

    /// Calls `f(slot, pixel)` for each of block `block`'s selected slots, ascending.
    #[inline]
    pub(super) fn selected(&self, block: u32, mut f: impl FnMut(u32, u32)) {
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
            for (slot, &o) in (0..).zip(&self.offsets) {
                if self.take(base + o) {
                    f(slot, base + o);
                }
            }
            return;
        }
        for slot in 0..BLOCK_PIXELS {
            if let Some(px) = self.layout.pixel(self.order, block, slot)
                && self.take(px)
            {
                f(slot, px);
            }
        }
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
    let input = DrawInput {
        dgi,
        shown: None,
        width,
        height,
        p_min,
        iteration,
        seed,
    };
    let draw = Draw::new(&input, order)?;
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
    let input = DrawInput {
        dgi,
        shown: None,
        width,
        height,
        p_min,
        iteration,
        seed,
    };
    schedule_cpu_shown(&input, order)
}

/// [`schedule_cpu`] with a shown mask (bit `p % 32` of word `p / 32` for pixel `p`): pixels
/// whose bit is clear have probability 0 and are never listed (the wall camera's bezels and
/// gaps, DESIGN.md §11). The twin of the kernel with `Params.masked = 1`.
pub fn schedule_cpu_shown(input: &DrawInput, order: Order) -> Result<Vec<u32>, ScheduleError> {
    let draw = Draw::new(input, order)?;
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
