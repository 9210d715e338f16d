//! Dealing an iteration's scheduled pixels across ranks: the list is grouped into its 32×32
//! blocks, and the blocks are dealt in block order, each to the rank with the least work so
//! far, a block's work being its scheduled pixels × the rays per sample it took when it was
//! last traced. With equal costs that is round-robin by block (OSPRay deals its tiles so), and
//! a converging ROI, whose blocks are full, is spread over every rank instead of falling on the
//! one whose tiles it covers.
//!
//! The deal decides only who computes a sample, never its value (a sample depends on the
//! pixel, its sample index and the seed alone), so any deal gives the same image; every rank
//! computes the same deal from the same list and the same cost table.

use super::owners::{block_grid, block_of, block_pixels};
use crate::schedule::{Layout, Order, SlotMask};

/// One iteration's scheduled pixels grouped by block: the blocks that have any, ascending,
/// each with its pixels in list order.
///
/// A list put back from every block's selected slots ([`Self::from_masks`]) knows each block's
/// length (all the deal needs) but holds the pixels only of the blocks [`Self::hold`] asks for:
/// a rank expands the blocks it traces or owns, a 1/N share of the iteration, instead of the
/// whole list on every rank.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BlockList {
    /// Block ids (row-major, as the schedule numbers them), ascending.
    pub blocks: Vec<u32>,
    /// Block `blocks[i]` has pixels `starts[i]..starts[i + 1]` of the whole list.
    pub starts: Vec<u32>,
    /// The held blocks' pixels, block after block.
    pixels: Vec<u32>,
    /// Per listed block: where its pixels begin in `pixels`, or [`NOT_HELD`].
    at: Vec<u32>,
    /// Per listed block of a list from masks: its selected slots, to expand on demand.
    masks: Vec<SlotMask>,
    size: [u32; 2],
}

/// [`BlockList`]'s mark of a block whose pixels were not expanded.
const NOT_HELD: u32 = u32::MAX;

impl BlockList {
    /// A list holding every block's pixels, `pixels` grouped as `starts` says.
    fn held(size: [u32; 2], blocks: Vec<u32>, starts: Vec<u32>, pixels: Vec<u32>) -> Self {
        let at = starts[..blocks.len()].to_vec();
        Self {
            blocks,
            starts,
            pixels,
            at,
            masks: Vec::new(),
            size,
        }
    }

    /// Groups a scheduled list (each pixel at most once) by block, keeping the list's order
    /// inside each block: a counting sort.
    #[must_use]
    pub fn group(list: &[u32], size: [u32; 2]) -> Self {
        let tiles = block_grid(size);
        let nblocks = (tiles[0] * tiles[1]) as usize;
        let mut count = vec![0u32; nblocks + 1];
        for &p in list {
            count[block_of(p, size[0], tiles[0]) as usize + 1] += 1;
        }
        for b in 0..nblocks {
            count[b + 1] += count[b];
        }
        let mut next = count.clone();
        let mut pixels = vec![0u32; list.len()];
        for &p in list {
            let b = block_of(p, size[0], tiles[0]) as usize;
            pixels[next[b] as usize] = p;
            next[b] += 1;
        }
        let mut blocks = Vec::new();
        let mut starts = vec![0u32];
        for b in 0..nblocks {
            if count[b + 1] > count[b] {
                blocks.push(b as u32);
                starts.push(count[b + 1]);
            }
        }
        Self::held(size, blocks, starts, pixels)
    }

    /// A coherent schedule's list from every block's selected slots (`masks[b]` for block
    /// `b`, [`crate::schedule::schedule_cpu_block_masks`]): the blocks with any, ascending,
    /// their lengths from the masks alone and no pixels held yet; once [`Self::hold`] expands a
    /// block, its pixels are in slot order — what [`Self::group`] makes of the whole coherent
    /// list.
    #[must_use]
    pub fn from_masks(size: [u32; 2], masks: &[SlotMask]) -> Self {
        let mut blocks = Vec::new();
        let mut starts = vec![0u32];
        let mut kept = Vec::new();
        let mut total = 0u32;
        for (b, mask) in masks.iter().enumerate() {
            let n: u32 = mask.iter().map(|w| w.count_ones()).sum();
            if n > 0 {
                total += n;
                blocks.push(b as u32);
                starts.push(total);
                kept.push(*mask);
            }
        }
        Self {
            at: vec![NOT_HELD; blocks.len()],
            blocks,
            starts,
            pixels: Vec::new(),
            masks: kept,
            size,
        }
    }

    /// Expands the pixels of every listed block `i` (block id `b`) with `keep(i, b)` that this
    /// list does not hold yet.
    pub fn hold(&mut self, keep: impl Fn(usize, u32) -> bool) {
        if self.masks.is_empty() {
            return;
        }
        let layout = Layout::new(self.size[0], self.size[1]).expect("the schedule's own size");
        for i in 0..self.blocks.len() {
            let b = self.blocks[i];
            if self.at[i] != NOT_HELD || !keep(i, b) {
                continue;
            }
            self.at[i] = self.pixels.len() as u32;
            for (w, &word) in self.masks[i].iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let slot = w as u32 * 32 + bits.trailing_zeros();
                    self.pixels.push(
                        layout
                            .pixel(Order::Coherent, b, slot)
                            .expect("a selected slot lies in the image"),
                    );
                    bits &= bits - 1;
                }
            }
        }
    }

    /// Whether listed block `i`'s pixels are held.
    #[must_use]
    pub fn holds(&self, i: usize) -> bool {
        self.at[i] != NOT_HELD
    }

    /// Every pixel of the image (those `shown` holds, when given: bit `p % 32` of word
    /// `p / 32`): a full frame.
    #[must_use]
    pub fn every(size: [u32; 2], shown: Option<&[u32]>) -> Self {
        let tiles = block_grid(size);
        let mut blocks = Vec::new();
        let mut starts = vec![0u32];
        let mut pixels = Vec::new();
        for b in 0..tiles[0] * tiles[1] {
            let before = pixels.len();
            pixels.extend(
                block_pixels(b, size, tiles[0])
                    .filter(|&p| shown.is_none_or(|m| m[(p / 32) as usize] >> (p % 32) & 1 == 1)),
            );
            if pixels.len() > before {
                blocks.push(b);
                starts.push(pixels.len() as u32);
            }
        }
        Self::held(size, blocks, starts, pixels)
    }

    /// Listed block `i`'s pixels; the block must be held ([`Self::holds`]).
    #[must_use]
    pub fn pixels_of(&self, i: usize) -> &[u32] {
        let at = self.at[i];
        assert!(at != NOT_HELD, "block {} is not held", self.blocks[i]);
        &self.pixels[at as usize..(at + self.len_of(i)) as usize]
    }

    /// How many pixels listed block `i` has.
    #[must_use]
    pub fn len_of(&self, i: usize) -> u32 {
        self.starts[i + 1] - self.starts[i]
    }

    /// Pixels listed, over every block (held or not).
    #[must_use]
    pub fn len(&self) -> u64 {
        u64::from(*self.starts.last().expect("starts begins with 0"))
    }

    /// Whether no pixel is listed.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Pixels held (expanded), over every held block.
    #[must_use]
    pub fn held_len(&self) -> usize {
        self.pixels.len()
    }
}

/// Rays per sample of each block the last time it was traced (1 before that): the weights of
/// the deal. Every rank updates its copy from the same numbers, so all copies agree.
#[derive(Clone, Debug, PartialEq)]
pub struct CostTable {
    pub rays_per_sample: Vec<f32>,
}

impl CostTable {
    #[must_use]
    pub fn new(blocks: usize) -> Self {
        Self {
            rays_per_sample: vec![1.0; blocks],
        }
    }

    /// Records that block `block` took `rays` rays for `samples` samples.
    pub fn record(&mut self, block: u32, rays: u32, samples: u32) {
        if samples > 0 {
            self.rays_per_sample[block as usize] = rays as f32 / samples as f32;
        }
    }
}

/// The rank that traces each listed block (`out[i]` for `list.blocks[i]`): blocks in order,
/// each to the rank with the least estimated work so far, the lowest rank on a tie.
#[must_use]
pub fn deal(list: &BlockList, costs: &CostTable, ranks: usize) -> Vec<u32> {
    let mut load = vec![0f64; ranks.max(1)];
    (0..list.blocks.len())
        .map(|i| {
            let work = f64::from(list.len_of(i))
                * f64::from(costs.rays_per_sample[list.blocks[i] as usize]);
            let mut best = 0;
            for r in 1..load.len() {
                if load[r] < load[best] {
                    best = r;
                }
            }
            load[best] += work;
            best as u32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::schedule::{Order, schedule_cpu};

    fn dgi(size: [u32; 2]) -> Vec<f32> {
        // A ring: inside it every pixel is sampled, outside fewer and fewer.
        let (w, h) = (size[0] as usize, size[1] as usize);
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let r = ((x - 70.0).powi(2) + (y - 40.0).powi(2)).sqrt();
                ((r - 20.0) / 60.0).clamp(0.0, 1.0)
            })
            .collect()
    }

    #[test]
    fn grouping_keeps_every_scheduled_pixel_once_in_its_block() {
        let size = [150, 90];
        for order in [Order::Coherent, Order::Scattered] {
            let list = schedule_cpu(&dgi(size), size[0], size[1], 0.05, 3, 7, order).unwrap();
            let g = BlockList::group(&list, size);
            let mut a: Vec<u32> = (0..g.blocks.len())
                .flat_map(|i| g.pixels_of(i).to_vec())
                .collect();
            let mut b = list.clone();
            a.sort_unstable();
            b.sort_unstable();
            assert_eq!(a, b);
            assert_eq!(g.len(), list.len() as u64);
            for i in 0..g.blocks.len() {
                assert!(g.len_of(i) > 0);
                for &p in g.pixels_of(i) {
                    assert_eq!(block_of(p, size[0], 5), g.blocks[i]);
                }
            }
            assert!(g.blocks.windows(2).all(|w| w[0] < w[1]));
            if order == Order::Coherent {
                // The coherent list is already grouped by block, in block order.
                assert_eq!(g.pixels, list);
                assert_eq!(g.held_len(), list.len());
            }
        }
    }

    /// The split schedule: blocks drawn apart (in any grouping, here every third block on its
    /// own) and put back from their masks give the whole coherent list's grouping exactly,
    /// edge tiles and a shown mask included.
    #[test]
    fn masks_drawn_apart_give_the_whole_schedules_list() {
        use crate::schedule::{DrawInput, schedule_cpu_block_masks, schedule_cpu_shown};
        let size = [150, 90];
        let mut shown = vec![0u32; (150 * 90usize).div_ceil(32)];
        for p in (0..150 * 90u32).filter(|p| p % 7 != 0) {
            shown[(p / 32) as usize] |= 1 << (p % 32);
        }
        let d = dgi(size);
        for mask in [None, Some(&shown[..])] {
            for k in 0..4 {
                let input = DrawInput {
                    dgi: &d,
                    shown: mask,
                    width: 150,
                    height: 90,
                    p_min: 0.05,
                    iteration: k,
                    seed: 7,
                };
                let list = schedule_cpu_shown(&input, Order::Coherent).unwrap();
                let want = BlockList::group(&list, size);
                let n = 5 * 3;
                let mut all = vec![[0u32; 32]; n];
                for part in 0..3u32 {
                    let blocks: Vec<u32> = (part..n as u32).step_by(3).collect();
                    let masks = schedule_cpu_block_masks(&input, &blocks).unwrap();
                    for (b, m) in blocks.into_iter().zip(masks) {
                        all[b as usize] = m;
                    }
                }
                let mut got = BlockList::from_masks(size, &all);
                // The lengths come from the masks alone, before any pixel is expanded.
                assert_eq!((&got.blocks, &got.starts), (&want.blocks, &want.starts));
                assert_eq!(got.held_len(), 0);
                // A rank's share: every third listed block, then the rest.
                got.hold(|i, _| i % 3 == 1);
                for i in 0..got.blocks.len() {
                    assert_eq!(got.holds(i), i % 3 == 1, "iteration {k}, block {i}");
                }
                let share: u32 = (0..got.blocks.len())
                    .filter(|i| i % 3 == 1)
                    .map(|i| got.len_of(i))
                    .sum();
                assert_eq!(got.held_len(), share as usize);
                got.hold(|_, _| true);
                for i in 0..want.blocks.len() {
                    assert_eq!(
                        got.pixels_of(i),
                        want.pixels_of(i),
                        "iteration {k}, block {i}"
                    );
                }
                assert_eq!(got.len(), list.len() as u64);
                assert!(!want.is_empty());
            }
        }
    }

    #[test]
    fn every_lists_each_shown_pixel_once() {
        let size = [70, 33];
        let g = BlockList::every(size, None);
        assert_eq!(g.len(), 70 * 33);
        let mut mask = vec![0u32; (70 * 33usize).div_ceil(32)];
        for p in (0..70 * 33u32).filter(|p| p % 3 == 0) {
            mask[(p / 32) as usize] |= 1 << (p % 32);
        }
        let g = BlockList::every(size, Some(&mask));
        assert_eq!(g.len(), (70 * 33u64).div_ceil(3));
        assert!((0..g.blocks.len()).all(|i| g.pixels_of(i).iter().all(|p| p % 3 == 0)));
    }

    #[test]
    fn equal_costs_deal_round_robin_and_the_roi_is_spread_over_every_rank() {
        let size = [150, 90];
        let g = BlockList::every(size, None);
        let d = deal(&g, &CostTable::new(5 * 3), 3);
        // Full blocks (1024 pixels) and the narrower right column: the first row alternates.
        assert_eq!(&d[..3], &[0, 1, 2]);
        let list = schedule_cpu(&dgi(size), size[0], size[1], 0.0, 0, 1, Order::Coherent).unwrap();
        let g = BlockList::group(&list, size);
        let mut costs = CostTable::new(15);
        // The ROI's blocks cost three times as much per sample.
        for &b in &g.blocks {
            if [1, 2, 6, 7].contains(&b) {
                costs.record(b, 3 * 100, 100);
            }
        }
        for ranks in [2, 3, 4] {
            let d = deal(&g, &costs, ranks);
            let mut work = vec![0f64; ranks];
            let mut biggest: f64 = 0.0;
            for i in 0..g.blocks.len() {
                let w =
                    f64::from(g.len_of(i)) * f64::from(costs.rays_per_sample[g.blocks[i] as usize]);
                work[d[i] as usize] += w;
                biggest = biggest.max(w);
            }
            let (lo, hi) = work
                .iter()
                .fold((f64::MAX, 0f64), |(lo, hi), &w| (lo.min(w), hi.max(w)));
            // Greedy least-loaded: no rank exceeds another by more than one block's work.
            assert!(hi - lo <= biggest, "{ranks} ranks: {work:?}");
            assert!(lo > 0.0, "{ranks} ranks: a rank got nothing: {work:?}");
        }
    }
}
