//! The owners' pictures (DESIGN.md §12): every rank filters and cuts the display tiles it owns,
//! as a wall's PC shows the screens it drives, without rank 0 assembling the whole picture.
//!
//! A tile shows a rectangle of image pixels ([`tile_rect`]); the filter's value there depends on
//! the accumulation within [`crate::filter::halo`] pixels around it. The owner has its own
//! blocks' sums; the blocks in that margin that other ranks own (a neighbour column's edge, a
//! block whose centre lies on another tile) come from their owners in one all-to-all, 20 bytes
//! a pixel (RGB sum, Σ luminance² and the count: the DGI every rank has). The owner then
//! filters each tile's rectangle with its margin on its own — an image whose origin is on every
//! pyramid level's grid ([`crate::filter::halo`]'s alignment) — and keeps the inside: the values
//! of the whole image's filter, bit for bit (the CPU twin computes each pixel from the same
//! taps in the same order; the tests compare them).

use std::collections::HashMap;

use glam::Vec3;

use super::codec::{PIXEL_BYTES, sums_and_counts};
use super::exchange::ExchangeError;
use super::owners::{BlockOwners, TileOwners, block_of};
use super::{ClusterError, ClusterRenderer};
use crate::display::DisplayModel;
use crate::filter::denoise::{DenoiseParams, Features};
use crate::filter::{Denoiser, Filter, FilterParams};
use crate::gpu::Backend;
use crate::schedule::TILE_EDGE;
use crate::trace::accum::Accumulation;
use crate::trace::features::pixel_features;

/// Image pixels `[x0, x1) × [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Rect {
    #[must_use]
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    #[must_use]
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    #[must_use]
    pub fn pixels(&self) -> usize {
        self.width() as usize * self.height() as usize
    }

    /// The rectangle with `halo` pixels more on every side, its origin moved down to a multiple
    /// of `align`, clipped to a `size` image.
    #[must_use]
    pub fn grown(&self, halo: u32, align: u32, size: [u32; 2]) -> Self {
        let down = |v: u32| v.saturating_sub(halo) / align * align;
        Self {
            x0: down(self.x0),
            y0: down(self.y0),
            x1: (self.x1 + halo).min(size[0]),
            y1: (self.y1 + halo).min(size[1]),
        }
    }
}

/// The image pixels tile `tile` of `model` shows in a `size` image: the bounding rectangle of
/// its cut ([`crate::output::tiles::tile_axes`]).
#[must_use]
pub fn tile_rect(model: &DisplayModel, tile: usize, size: [u32; 2]) -> Rect {
    let (xs, ys) = crate::output::tiles::tile_axes(model, tile, size);
    let span = |v: &[usize]| {
        let lo = v.iter().copied().min().unwrap_or(0) as u32;
        let hi = v.iter().copied().max().map_or(lo, |m| m as u32 + 1);
        (lo, hi)
    };
    let ((x0, x1), (y0, y1)) = (span(&xs), span(&ys));
    Rect { x0, y0, x1, y1 }
}

/// One tile an owner makes the picture of: the pixels it shows and those its filter reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileRegion {
    pub tile: usize,
    pub shows: Rect,
    pub reads: Rect,
}

/// The tiles `rank` owns, in the model's order, each with the rectangle its filter reads
/// (`halo` = [`crate::filter::halo`]'s pair).
#[must_use]
pub fn regions(
    model: &DisplayModel,
    tiles: &TileOwners,
    rank: usize,
    size: [u32; 2],
    halo: (u32, u32),
) -> Vec<TileRegion> {
    (0..model.tiles().len())
        .filter(|&t| tiles.ranks[t] == rank)
        .map(|tile| {
            let shows = tile_rect(model, tile, size);
            TileRegion {
                tile,
                shows,
                reads: shows.grown(halo.0, halo.1, size),
            }
        })
        .collect()
}

/// The union of `rects` as disjoint row spans `(y, x0, x1)`, rows ascending and each row's
/// spans left to right: the union's pixels in ascending index order, each once.
fn union_spans(rects: &[Rect], mut f: impl FnMut(u32, u32, u32)) {
    let (Some(y0), Some(y1)) = (
        rects.iter().map(|r| r.y0).min(),
        rects.iter().map(|r| r.y1).max(),
    ) else {
        return;
    };
    let mut spans: Vec<(u32, u32)> = Vec::new();
    for y in y0..y1 {
        spans.clear();
        spans.extend(
            rects
                .iter()
                .filter(|r| (r.y0..r.y1).contains(&y))
                .map(|r| (r.x0, r.x1)),
        );
        spans.sort_unstable();
        let mut next = 0;
        for &(a, b) in &spans {
            let a = a.max(next);
            next = next.max(b);
            if a < b {
                f(y, a, b);
            }
        }
    }
}

/// The pixels in the union of `rects`, ascending, whose block `src` owns.
#[must_use]
pub fn pixels_owned_by(rects: &[Rect], owners: &BlockOwners, src: usize) -> Vec<u32> {
    let (w, tiles_x) = (owners.width, owners.tiles[0]);
    let mut out = Vec::new();
    union_spans(rects, |y, a, b| {
        out.extend(
            (y * w + a..y * w + b)
                .filter(|&p| owners.owner[block_of(p, w, tiles_x) as usize] as usize == src),
        );
    });
    out
}

/// A tile's picture as its owner made it: the tile's pixels, row by row at its resolution.
#[derive(Clone, Debug, PartialEq)]
pub struct TilePicture {
    pub tile: usize,
    pub pixels: Vec<Vec3>,
}

impl ClusterRenderer<'_> {
    /// This rank's sums and count of pixel `p`, if its block is this rank's.
    fn own_sum(&self, p: u32) -> Option<([f32; 4], u32)> {
        self.own_index(p).map(|k| (self.sums[k], self.counts[k]))
    }

    /// The pictures of the tiles of `model` that `tiles` gives this rank, filtered by `params`
    /// (a full frame: [`crate::filter::FilterKind::Off`], the mean image), on every rank at
    /// once: each sends the others the sums their tiles' margins need, then filters its own
    /// tiles on the CPU twin. Every rank must pass the same `tiles` (usually the map the block
    /// owners were made from, so that a tile's own pixels are mostly its owner's; the sums come
    /// from whichever rank owns each block). The pictures are the whole image's, filtered by
    /// one process, cut as [`crate::output::tiles::cut_tile`] cuts it.
    ///
    /// With `denoise`, each tile's picture is then denoised by raygun's interactive denoiser
    /// (DESIGN.md §8) with the features of its rectangle (the CPU twin's, pixel by pixel), the
    /// margin grown to the denoiser's reach too: the one process's denoised picture on the CPU,
    /// bit for bit.
    pub fn tile_pictures(
        &mut self,
        model: &DisplayModel,
        tiles: &TileOwners,
        params: &FilterParams,
        denoise: Option<&DenoiseParams>,
    ) -> Result<Vec<TilePicture>, ClusterError> {
        let (mut halo, align) = crate::filter::halo(params);
        if let Some(d) = denoise {
            d.validate().map_err(crate::frame::FrameError::from)?;
            halo = halo.max(crate::filter::denoise::halo(d));
        }
        self.tile_pictures_with(model, tiles, params, denoise, (halo, align))
    }

    /// [`Self::tile_pictures`] with the margin given (the tests cut it to show it matters).
    pub(super) fn tile_pictures_with(
        &mut self,
        model: &DisplayModel,
        tiles: &TileOwners,
        params: &FilterParams,
        denoise: Option<&DenoiseParams>,
        halo: (u32, u32),
    ) -> Result<Vec<TilePicture>, ClusterError> {
        self.collect()?;
        self.sync_sums()?;
        let size = [self.settings.width, self.settings.height];
        let (me, n) = (self.rank, self.ranks);
        let reads = |rank: usize| -> Vec<Rect> {
            regions(model, tiles, rank, size, halo)
                .iter()
                .map(|r| r.reads)
                .collect()
        };
        let what = "the sums around the owners' tiles";
        let mut parts = vec![Vec::new(); n];
        for (r, part) in parts.iter_mut().enumerate() {
            if r != me {
                for p in pixels_owned_by(&reads(r), &self.owners, me) {
                    self.own_bytes(p, part);
                }
            }
        }
        let got = self.link.all_to_all(what, parts)?;
        let own_regions = regions(model, tiles, me, size, halo);
        let mine: Vec<Rect> = own_regions.iter().map(|r| r.reads).collect();
        let mut theirs: HashMap<u32, ([f32; 4], u32)> = HashMap::new();
        for (src, bytes) in got.iter().enumerate().filter(|(s, _)| *s != me) {
            let pixels = pixels_owned_by(&mine, &self.owners, src);
            let values =
                sums_and_counts(bytes, pixels.len()).ok_or_else(|| ExchangeError::Length {
                    rank: src,
                    what: what.into(),
                    got: bytes.len(),
                    expected: PIXEL_BYTES * pixels.len(),
                })?;
            theirs.extend(pixels.into_iter().zip(values));
        }
        let guided = self.guidance.is_some();
        let filter = Filter::new(&Backend::Cpu);
        let mut out = Vec::new();
        for region in own_regions {
            let r = region.reads;
            let mut acc = Accumulation::new(r.width(), r.height());
            let mut dgi = vec![0.0; r.pixels()];
            let mut k = 0;
            for y in r.y0..r.y1 {
                for x in r.x0..r.x1 {
                    let p = y * size[0] + x;
                    (acc.sum[k], acc.count[k]) = match self.own_sum(p) {
                        Some(v) => v,
                        None => *theirs.get(&p).expect("every margin pixel was received"),
                    };
                    if guided {
                        dgi[k] = self.dgi[p as usize];
                    }
                    k += 1;
                }
            }
            let mut image = filter.image(params, &acc, &dgi)?;
            if let Some(d) = denoise {
                image = self.denoised_region(r, d, &acc, &image)?;
            }
            // A denoised full frame too: the denoiser fills bezel pixels from their neighbours.
            let blank = guided || denoise.is_some();
            let pixels = crate::output::tiles::tile_source_indices(model, region.tile, size)
                .into_iter()
                .map(|i| {
                    let (x, y) = (i as u32 % size[0], i as u32 / size[0]);
                    let shown = !blank || self.wall.as_ref().is_none_or(|w| w.is_shown(i as u32));
                    if shown {
                        image[((y - r.y0) * r.width() + x - r.x0) as usize]
                    } else {
                        Vec3::ZERO
                    }
                })
                .collect();
            out.push(TilePicture {
                tile: region.tile,
                pixels,
            });
        }
        Ok(out)
    }
}

impl ClusterRenderer<'_> {
    /// `filled` (the filter's picture of `acc`, the image pixels of `r`) denoised with the
    /// features of those pixels, as one process denoises them on the CPU.
    fn denoised_region(
        &self,
        r: Rect,
        params: &DenoiseParams,
        acc: &Accumulation,
        filled: &[Vec3],
    ) -> Result<Vec<Vec3>, ClusterError> {
        let width = self.settings.width;
        let (albedo, normal_depth) = (r.y0..r.y1)
            .flat_map(|y| (r.x0..r.x1).map(move |x| y * width + x))
            .map(|p| pixel_features(&self.packed, &self.settings, self.wall.as_ref(), p))
            .unzip();
        let features = Features {
            width: r.width(),
            height: r.height(),
            albedo,
            normal_depth,
        };
        let (image, _dropped) = crate::frame::denoise_picture(
            &Backend::Cpu,
            Denoiser::Interactive(*params),
            acc,
            &features,
            filled,
            None,
        )?;
        Ok(image)
    }
}

/// Bytes each rank sends and receives in [`ClusterRenderer::tile_pictures`] ([`PIXEL_BYTES`] a pixel, per
/// rank: `(sent, received)`), counted from the geometry alone: what a picture of the whole wall
/// costs the links, whatever was sampled.
#[must_use]
pub fn margin_traffic(
    model: &DisplayModel,
    tiles: &TileOwners,
    owners: &BlockOwners,
    halo: (u32, u32),
    ranks: usize,
) -> Vec<(u64, u64)> {
    let size = [owners.width, owners.height];
    let mut out = vec![(0u64, 0u64); ranks];
    for dst in 0..ranks {
        let reads: Vec<Rect> = regions(model, tiles, dst, size, halo)
            .iter()
            .map(|r| r.reads)
            .collect();
        union_spans(&reads, |y, a, b| {
            let row = (y / TILE_EDGE) * owners.tiles[0];
            // Whole runs of a block's pixels at a time.
            for bx in a / TILE_EDGE..=(b - 1) / TILE_EDGE {
                let src = owners.owner[(row + bx) as usize] as usize;
                if src != dst {
                    let n = b.min((bx + 1) * TILE_EDGE) - a.max(bx * TILE_EDGE);
                    let bytes = PIXEL_BYTES as u64 * u64::from(n);
                    out[src].0 += bytes;
                    out[dst].1 += bytes;
                }
            }
        });
    }
    out
}
