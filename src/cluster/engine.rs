//! A rank's renderer set up (DESIGN.md §12): the image's blocks and the ones this rank owns,
//! where each owned pixel's sums and count lie, and what the renderer was built with.

use std::time::Instant;

use super::codec::f32_bytes;
use super::deal::CostTable;
use super::gpu_rank::block_masks;
use super::owners::{BlockOwners, block_grid, block_of};
use super::{Cluster, ClusterError, ClusterRenderer, DgiMode, Guidance};
use crate::display::DisplayModel;
use crate::frame::{FrameError, GuideConfig};
use crate::roi::dgi::Surface;
use crate::scene::Scene;
use crate::schedule::{BLOCK_PIXELS, TILE_EDGE};
use crate::trace::pack::PackedScene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

/// What a render across ranks renders: the same on every rank of a job (the start-up check
/// compares the ranks' settings).
#[derive(Clone, Debug)]
pub struct ClusterSetup<'m> {
    pub settings: TraceSettings,
    /// The display and how the ROI steers sampling: a guided render (`None`: a full frame).
    pub guide: Option<(&'m DisplayModel, GuideConfig)>,
    /// The wall camera the frames trace through, if any (DESIGN.md §11).
    pub wall: Option<WallCamera>,
    /// Which rank owns each block.
    pub owners: BlockOwners,
    /// How the DGI of a new ROI reaches every rank.
    pub dgi_mode: DgiMode,
}

impl<'c> ClusterRenderer<'c> {
    /// This rank's part of the job `link`'s render of `scene` as `setup` says; it holds `link`
    /// until it is dropped.
    pub fn new(
        link: &'c mut Cluster,
        scene: &Scene,
        setup: ClusterSetup<'_>,
    ) -> Result<Self, ClusterError> {
        let ClusterSetup {
            settings,
            guide,
            wall,
            owners,
            dgi_mode,
        } = setup;
        let (rank, ranks) = (link.rank(), link.ranks());
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
            link,
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

    /// The job this rank renders in.
    #[must_use]
    pub fn cluster(&self) -> &Cluster {
        self.link
    }

    /// The job, for the collectives of the loop that drives this renderer (rank 0's control of
    /// each frame, a benchmark's numbers). Every rank must call them at the same points.
    pub fn cluster_mut(&mut self) -> &mut Cluster {
        self.link
    }

    /// Starts again from nothing with `settings` (the same image) and the guide `config`, as a
    /// new renderer of this one's scene, link, owners, wall camera and backend would: no ROI,
    /// the accumulation and the deal's costs empty. The samples in flight are collected first;
    /// the scene is neither packed nor uploaded again (`view --cluster`'s rebuild when its
    /// settings change or a reset is asked for: seconds for a large scene). A collective.
    pub fn rebuild(
        &mut self,
        settings: TraceSettings,
        config: GuideConfig,
    ) -> Result<(), ClusterError> {
        let size = [settings.width, settings.height];
        if size != [self.settings.width, self.settings.height] {
            return Err(ClusterError::MapSize {
                map: [self.owners.width, self.owners.height],
                image: size,
            });
        }
        crate::schedule::validate_p_min(config.p_min)?;
        if self.guidance.is_none() {
            return Err(FrameError::NotGuided.into());
        }
        self.finish()?;
        if let Some(g) = &mut self.guidance {
            g.config = config;
        }
        self.settings = settings;
        self.pending = None;
        self.roi = None;
        self.dgi.fill(0.0);
        self.costs = CostTable::new(self.owners.owner.len());
        if let Some(g) = self.gpu.as_deref_mut() {
            g.run.set_settings(&g.ctx, &self.packed, &self.settings);
            g.masks = block_masks(
                &g.ctx,
                self.guidance.as_ref(),
                self.wall.as_ref(),
                &self.settings,
                &self.dgi,
            )?;
        }
        self.restart();
        Ok(())
    }

    /// Samples taken so far, over the whole image (every rank knows every block's length).
    #[must_use]
    pub fn samples(&self) -> u64 {
        self.total
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
