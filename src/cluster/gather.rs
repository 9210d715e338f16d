//! What rank 0 reads of the owners' sums (DESIGN.md §12): the ROI's progress for a stop
//! condition, and the whole accumulation or every k-th pixel of it for a picture — rank 0's
//! console shows a wall larger than itself reduced.

use super::codec::{PIXEL_BYTES, sums_and_counts};
use super::exchange::ExchangeError;
use super::owners::{block_pixels, block_pixels_every};
use super::{ClusterError, ClusterRenderer};
use crate::frame::stop::RoiProgress;
use crate::trace::accum::{Accumulation, every, every_size};

impl ClusterRenderer<'_> {
    /// How far the ROI has come ([`crate::frame::Render::roi_progress`]), on rank 0 (`None`
    /// without ROI pixels, and on the other ranks): every owner sends rank 0 the sums and
    /// counts of its pixels of d = 0 (every pixel of a full frame) that a wall camera's display
    /// shows, [`PIXEL_BYTES`] each, and rank 0 measures them as one process does — pixels no
    /// tile shows are never sampled and would hold the fewest samples at 0 for ever.
    pub(super) fn progress(&mut self) -> Result<Option<RoiProgress>, ClusterError> {
        self.collect()?;
        self.sync_sums()?;
        let size = [self.settings.width, self.settings.height];
        let tiles_x = self.owners.tiles[0];
        // A full frame keeps no DGI: d = 0 everywhere.
        let guided = self.guidance.is_some();
        let wall = self.wall.as_ref();
        let in_roi = |p: &u32| {
            (!guided || self.dgi[*p as usize] == 0.0) && wall.is_none_or(|w| w.is_shown(*p))
        };
        let mut mine = Vec::new();
        for b in self.owners.owned_by(self.rank) {
            for p in block_pixels(b, size, tiles_x).filter(in_roi) {
                self.own_bytes(p, &mut mine);
            }
        }
        let Some(all) = self.link.gather("the ROI's sums", mine)? else {
            return Ok(None);
        };
        let (mut sum, mut count) = (Vec::new(), Vec::new());
        for (src, bytes) in all.iter().enumerate() {
            let pixels: Vec<u32> = self
                .owners
                .owned_by(src)
                .into_iter()
                .flat_map(|b| block_pixels(b, size, tiles_x).filter(in_roi))
                .collect();
            let pixels =
                sums_and_counts(bytes, pixels.len()).ok_or_else(|| ExchangeError::Length {
                    rank: src,
                    what: "the ROI's sums".into(),
                    got: bytes.len(),
                    expected: PIXEL_BYTES * pixels.len(),
                })?;
            for (s, n) in pixels {
                sum.push(s);
                count.push(n);
            }
        }
        let n = sum.len();
        let acc = Accumulation {
            width: n as u32,
            height: 1,
            sum,
            count,
        };
        Ok(RoiProgress::measure(&acc, &vec![0.0; n]))
    }

    /// The accumulation and the DGI the last frame used at every `step`-th column of every
    /// `step`-th row, on rank 0 (`None` on the others), as an image of ⌈W / step⌉ × ⌈H / step⌉:
    /// [`Accumulation::every`] of the whole accumulation (and the DGI's pixels there), for a
    /// picture smaller than the wall — rank 0's console. Each owner sends those of its pixels
    /// ([`PIXEL_BYTES`] each): 1/step² of the whole gather's bytes (step 1: the whole
    /// accumulation, [`crate::frame::Render::gather`]).
    pub fn gather_every(
        &mut self,
        step: u32,
    ) -> Result<Option<(Accumulation, Vec<f32>)>, ClusterError> {
        self.collect()?;
        self.sync_sums()?;
        let size = [self.settings.width, self.settings.height];
        let pixels_of = |rank: usize| {
            let tiles_x = self.owners.tiles[0];
            self.owners
                .owned_by(rank)
                .into_iter()
                .flat_map(move |b| block_pixels_every(b, size, tiles_x, step))
        };
        let mut mine = Vec::new();
        for p in pixels_of(self.rank) {
            self.own_bytes(p, &mut mine);
        }
        let Some(all) = self.link.gather("the owners' sums", mine)? else {
            return Ok(None);
        };
        let [w, h] = every_size(size, step);
        let mut acc = Accumulation::new(w, h);
        for (src, bytes) in all.iter().enumerate() {
            let pixels: Vec<u32> = pixels_of(src).collect();
            let values =
                sums_and_counts(bytes, pixels.len()).ok_or_else(|| ExchangeError::Length {
                    rank: src,
                    what: "the owners' sums".into(),
                    got: bytes.len(),
                    expected: PIXEL_BYTES * pixels.len(),
                })?;
            for (p, (s, n)) in pixels.into_iter().zip(values) {
                let o = ((p / size[0]) / step * w + (p % size[0]) / step) as usize;
                acc.sum[o] = s;
                acc.count[o] = n;
            }
        }
        let dgi = if self.guidance.is_some() {
            every(&self.dgi, size, step)
        } else {
            vec![0.0; w as usize * h as usize]
        };
        Ok(Some((acc, dgi)))
    }
}

/// The most pixels of the picture rank 0's console window shows across ranks (`view
/// --cluster`): a 4K monitor's (the window asks for no more than it shows). A larger wall's picture is reduced to every k-th pixel of every
/// k-th row (`viewer::core::ViewerCore::console_every`), so that the owners send rank 0 those pixels only —
/// 20 bytes each, where HORNET's 73.8 megapixels whole are 1.5 GB a picture — and rank 0
/// filters and draws only what its window can show. Saving takes the whole picture.
pub const CONSOLE_PIXELS: u64 = 3840 * 2160;

/// The least k for which every k-th pixel of every k-th row of a `size` image is at most
/// `max` pixels (at least one).
#[must_use]
pub fn reduction_for(size: [u32; 2], max: u64) -> u32 {
    (1..=size[0].max(size[1]).max(1))
        .find(|&k| {
            let [w, h] = every_size(size, k);
            u64::from(w) * u64::from(h) <= max.max(1)
        })
        .unwrap_or(1)
}
