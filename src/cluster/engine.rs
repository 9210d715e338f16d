//! A rank's renderer set up (DESIGN.md §12): the image's blocks and the ones this rank owns,
//! where each owned pixel's sums and count lie, and what the renderer was built with.

use std::time::Instant;

use super::codec::f32_bytes;
use super::deal::CostTable;
use super::owners::{BlockOwners, block_grid, block_of};
use super::{ClusterError, ClusterRenderer, DgiMode, Guidance};
use crate::display::DisplayModel;
use crate::frame::{FrameError, GuideConfig};
use crate::roi::dgi::{Roi, Surface};
use crate::scene::Scene;
use crate::schedule::{BLOCK_PIXELS, TILE_EDGE};
use crate::trace::pack::PackedScene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

impl ClusterRenderer {
    /// Rank `rank` of `ranks`: a render of `scene` (guided when `guide` gives the display and
    /// how the ROI steers; a full frame otherwise), through `wall` when given, with the blocks
    /// owned as `owners` says.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        scene: &Scene,
        settings: TraceSettings,
        guide: Option<(&DisplayModel, GuideConfig)>,
        wall: Option<WallCamera>,
        owners: BlockOwners,
        dgi_mode: DgiMode,
        rank: usize,
        ranks: usize,
    ) -> Result<Self, ClusterError> {
        let size = [settings.width, settings.height];
        if [owners.width, owners.height] != size {
            return Err(ClusterError::MapSize {
                map: [owners.width, owners.height],
                image: size,
            });
        }
        if let Some(wc) = &wall
            && [wc.width, wc.height] != size
        {
            return Err(FrameError::WallSize {
                wall: [wc.width, wc.height],
                image: size,
            }
            .into());
        }
        let guidance = match guide {
            Some((model, config)) => {
                crate::schedule::validate_p_min(config.p_min)?;
                Some(Guidance {
                    config,
                    surface: Surface::from_model(model),
                    pitch_m: model.pitch_m(),
                })
            }
            None => None,
        };
        let t0 = Instant::now();
        let packed = PackedScene::new(scene);
        let build_seconds = t0.elapsed().as_secs_f64();
        let n = size[0] as usize * size[1] as usize;
        let mine = owners.owned_by(rank);
        let mut slot = vec![u32::MAX; owners.owner.len()];
        for (i, &b) in mine.iter().enumerate() {
            slot[b as usize] = i as u32;
        }
        Ok(Self {
            packed,
            settings,
            build_seconds,
            wall,
            dgi: if guidance.is_some() {
                vec![0.0; n]
            } else {
                Vec::new()
            },
            guidance,
            dgi_mode,
            rank,
            ranks,
            iteration: 0,
            pending: None,
            roi: None,
            pixels: n,
            total: 0,
            counts: vec![0; mine.len() * BLOCK_PIXELS as usize],
            costs: CostTable::new(owners.owner.len()),
            sums: vec![[0.0; 4]; mine.len() * BLOCK_PIXELS as usize],
            sums_stale: false,
            owners,
            slot,
            full_list: None,
            gpu: None,
            overlap: true,
            in_flight: None,
        })
    }

    /// How the ROI steers sampling (`None`: a full frame).
    #[must_use]
    pub fn guide_config(&self) -> Option<&GuideConfig> {
        self.guidance.as_ref().map(|g| &g.config)
    }

    /// Samples taken so far, over the whole image (every rank knows every block's length).
    #[must_use]
    pub fn samples(&self) -> u64 {
        self.total
    }

    /// Iterations run so far.
    #[must_use]
    pub fn iteration(&self) -> u32 {
        self.iteration
    }

    /// The ROI set last (`None` also for a full frame).
    #[must_use]
    pub fn roi(&self) -> Option<&Roi> {
        self.roi.as_ref()
    }

    /// The wall camera, if the frames trace through one.
    #[must_use]
    pub fn wall(&self) -> Option<&WallCamera> {
        self.wall.as_ref()
    }

    /// Where pixel `p`'s sums and count are in `sums` and `counts`, if its block is this
    /// rank's.
    pub(super) fn own_index(&self, p: u32) -> Option<usize> {
        let b = block_of(p, self.settings.width, self.owners.tiles[0]);
        self.own_base(b).map(|base| base + self.local(p))
    }

    /// Where block `b`'s pixels begin in `sums` and `counts`, if the block is this rank's (the
    /// loops over a block's pixels look it up once, not per pixel).
    pub(super) fn own_base(&self, b: u32) -> Option<usize> {
        own_base_of(&self.slot, b)
    }

    /// Pixel `p`'s place inside its block (row-major).
    pub(super) fn local(&self, p: u32) -> usize {
        local_in_block(p, self.settings.width)
    }

    /// The owned blocks' slots (`BLOCK_PIXELS` entries of `sums` and `counts` each).
    pub(super) fn slots(&self) -> usize {
        self.counts.len() / BLOCK_PIXELS as usize
    }

    /// An owned pixel's sums and count as they travel: 16 bytes of sums (f32), 4 of count.
    pub(super) fn own_bytes(&self, p: u32, out: &mut Vec<u8>) {
        let k = self.own_index(p).expect("a pixel of this rank");
        out.extend(f32_bytes(&self.sums[k]));
        out.extend(self.counts[k].to_le_bytes());
    }

    /// The blocks per row and column of the image.
    #[must_use]
    pub fn block_grid(&self) -> [u32; 2] {
        block_grid([self.settings.width, self.settings.height])
    }
}

/// Where block `b`'s pixels begin in a rank's sums and counts, by its `slot` table.
pub(super) fn own_base_of(slot: &[u32], b: u32) -> Option<usize> {
    let slot = slot[b as usize];
    if slot == u32::MAX {
        None
    } else {
        Some((slot * BLOCK_PIXELS) as usize)
    }
}

/// Pixel `p`'s place inside its block (row-major) in an image `width` pixels wide.
pub(super) fn local_in_block(p: u32, width: u32) -> usize {
    let (x, y) = (p % width, p / width);
    ((y % TILE_EDGE) * TILE_EDGE + x % TILE_EDGE) as usize
}
