//! The coherent schedule as every block's selected slots (DESIGN.md §6, §12): bit masks
//! instead of a list, for ranks that draw an iteration apart (a share of the blocks each on
//! their CPUs) or whole on a GPU. CPU twin of `shaders/schedule/masks.wgsl`.

use rayon::prelude::*;

use super::compact::{Draw, DrawInput};
use super::{BLOCK_PIXELS, Order, ScheduleError};

/// A block's selected slots: bit `s % 32` of word `s / 32` for slot `s` ([`super::Layout::pixel`]).
pub type SlotMask = [u32; (BLOCK_PIXELS / 32) as usize];

/// The draw of [`super::schedule_cpu_shown`] in coherent order for `blocks` alone, each block's
/// selected slots as a [`SlotMask`]: its pixels in list order are its set bits ascending,
/// through [`super::Layout::pixel`]. Ranks split an iteration's schedule so (DESIGN.md §12): each
/// draws a share of the blocks and sends the others 128 bytes a non-empty block.
pub fn schedule_cpu_block_masks(
    input: &DrawInput,
    blocks: &[u32],
) -> Result<Vec<SlotMask>, ScheduleError> {
    let draw = Draw::new(input, Order::Coherent)?;
    Ok(blocks
        .par_iter()
        .map(|&block| {
            let mut mask = [0u32; (BLOCK_PIXELS / 32) as usize];
            draw.selected(block, |slot, _| {
                mask[(slot / 32) as usize] |= 1 << (slot % 32)
            });
            mask
        })
        .collect())
}
