//! Who owns which part of the wall: the rank that accumulates a display tile's pixels (and, on
//! a wall, would show them), and from that the owner of every 32×32 block of the image.
//!
//! # The `--tile-owners` file
//!
//! Plain text, one tile per line: the tile's id (as the display model names it) and the rank
//! that owns it, separated by white space. `#` starts a comment; blank lines are ignored.
//! Every tile of the model is listed exactly once, and every rank is below the job's size:
//!
//! ```text
//! # HORNET on 3 ranks: columns 0–1 on rank 0, 2–4 on rank 1, 5–6 on rank 2
//! c0r0 0
//! c0r1 0
//! …
//! ```
//!
//! Without a file, whole columns are dealt evenly ([`TileOwners::columns`]): column `i` of `m`
//! (left to right) goes to rank `⌊i·N/m⌋`, so with more ranks than columns some ranks only
//! trace. A block belongs to the owner of the tile nearest its centre on the canvas; an image
//! with no display (a plain full-frame render) is cut into vertical strips of blocks instead.

use std::path::{Path, PathBuf};

use glam::DVec2;

use crate::display::DisplayModel;
use crate::schedule::TILE_EDGE;

/// One line of a tile-owners file: tile id, rank, line number (from 1).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OwnerLine {
    pub tile: String,
    pub rank: usize,
    pub line: usize,
}

/// A tile-owners file that does not fit (the file and line are named).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TileOwnersError {
    #[error("{}: {reason}", file.display())]
    Read { file: PathBuf, reason: String },
    #[error("{}:{line}: {reason}", file.display())]
    Line {
        file: PathBuf,
        line: usize,
        reason: String,
    },
    #[error("{}: tiles without an owner: {missing} (every tile of {model} is listed once)", file.display())]
    Missing {
        file: PathBuf,
        model: String,
        missing: String,
    },
}

/// Parses a tile-owners file's text (`file` names it in errors); checks the form only.
pub fn parse_tile_owners(text: &str, file: &Path) -> Result<Vec<OwnerLine>, TileOwnersError> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let err = |reason: String| TileOwnersError::Line {
            file: file.to_owned(),
            line,
            reason,
        };
        let content = raw.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let fields: Vec<&str> = content.split_whitespace().collect();
        let [tile, rank] = fields[..] else {
            return Err(err(format!(
                "expected `TILE_ID RANK`, found {} field(s): {}",
                fields.len(),
                crate::messages::quote(content)
            )));
        };
        let rank = rank.parse::<usize>().map_err(|_| {
            err(format!(
                "rank {} is not a whole number from 0",
                crate::messages::quote(rank)
            ))
        })?;
        out.push(OwnerLine {
            tile: tile.to_owned(),
            rank,
            line,
        });
    }
    Ok(out)
}

/// The largest tile-owners file read: a line a tile, a few dozen bytes each.
pub const MAX_OWNERS_BYTES: u64 = 1 << 20;

/// The owner rank of each tile of a display model (the model's tile order).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TileOwners {
    pub ranks: Vec<usize>,
}

impl TileOwners {
    /// Whole columns dealt evenly over `ranks` ranks: column `i` of `m` to rank `⌊i·ranks/m⌋`.
    #[must_use]
    pub fn columns(model: &DisplayModel, ranks: usize) -> Self {
        let mut cols: Vec<u32> = model.tiles().iter().map(|t| t.column()).collect();
        cols.sort_unstable();
        cols.dedup();
        let m = cols.len().max(1);
        let ranks = model
            .tiles()
            .iter()
            .map(|t| {
                let i = cols.binary_search(&t.column()).unwrap_or(0);
                i * ranks / m
            })
            .collect();
        Self { ranks }
    }

    /// The owners a file's lines give `model` in a job of `ranks` ranks: every tile listed
    /// once, each rank below `ranks`.
    pub fn from_lines(
        lines: &[OwnerLine],
        file: &Path,
        model: &DisplayModel,
        ranks: usize,
    ) -> Result<Self, TileOwnersError> {
        let n = model.tiles().len();
        let mut owner: Vec<Option<(usize, usize)>> = vec![None; n];
        for l in lines {
            let err = |reason: String| TileOwnersError::Line {
                file: file.to_owned(),
                line: l.line,
                reason,
            };
            let Some(t) = model.tile_index(&l.tile) else {
                return Err(err(format!(
                    "{} is not a tile of {} (its tiles: {})",
                    crate::messages::quote(&l.tile),
                    model.name(),
                    tile_names(model, 0..n)
                )));
            };
            if l.rank >= ranks {
                return Err(err(format!(
                    "rank {} for tile {}: the job has {ranks} rank(s), 0 to {}",
                    l.rank,
                    l.tile,
                    ranks - 1
                )));
            }
            if let Some((_, first)) = owner[t] {
                return Err(err(format!(
                    "tile {} is listed twice (first on line {first})",
                    l.tile
                )));
            }
            owner[t] = Some((l.rank, l.line));
        }
        let missing: Vec<usize> = (0..n).filter(|&t| owner[t].is_none()).collect();
        if !missing.is_empty() {
            return Err(TileOwnersError::Missing {
                file: file.to_owned(),
                model: model.name().to_owned(),
                missing: tile_names(model, missing.into_iter()),
            });
        }
        Ok(Self {
            ranks: owner.into_iter().map(|o| o.map_or(0, |(r, _)| r)).collect(),
        })
    }

    /// Reads and checks a tile-owners file (at most [`MAX_OWNERS_BYTES`]).
    pub fn load(file: &Path, model: &DisplayModel, ranks: usize) -> Result<Self, TileOwnersError> {
        let text =
            crate::input::read_text(file, MAX_OWNERS_BYTES, "a tile-owners file").map_err(|e| {
                TileOwnersError::Read {
                    file: file.to_owned(),
                    reason: e.to_string(),
                }
            })?;
        Self::from_lines(&parse_tile_owners(&text, file)?, file, model, ranks)
    }

    /// `id=rank` for every tile, in the model's order (what the start-up check compares).
    #[must_use]
    pub fn describe(&self, model: &DisplayModel) -> String {
        model
            .tiles()
            .iter()
            .zip(&self.ranks)
            .map(|(t, r)| format!("{}={r}", t.id()))
            .collect::<Vec<_>>()
            .join(" ")
    }
}

/// Tile ids, the first eight and a count of the rest.
fn tile_names(model: &DisplayModel, tiles: impl Iterator<Item = usize>) -> String {
    let all: Vec<usize> = tiles.collect();
    let mut s: Vec<String> = all
        .iter()
        .take(8)
        .map(|&t| model.tiles()[t].id().to_owned())
        .collect();
    if all.len() > 8 {
        s.push(format!("and {} more", all.len() - 8));
    }
    s.join(", ")
}

/// The owner rank of every 32×32 block of a `width × height` image (blocks row-major, as the
/// schedule numbers them).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BlockOwners {
    pub width: u32,
    pub height: u32,
    /// Blocks per row and per column.
    pub tiles: [u32; 2],
    pub owner: Vec<u32>,
}

impl BlockOwners {
    /// Each block to the owner of the tile nearest its centre on `model`'s canvas.
    #[must_use]
    pub fn of_display(model: &DisplayModel, owners: &TileOwners, size: [u32; 2]) -> Self {
        let tiles = block_grid(size);
        let mut owner = Vec::with_capacity((tiles[0] * tiles[1]) as usize);
        for by in 0..tiles[1] {
            for bx in 0..tiles[0] {
                let centre = |b: u32, n: u32| {
                    let x0 = b * TILE_EDGE;
                    f64::from(x0) + f64::from((x0 + TILE_EDGE).min(n) - x0) / 2.0
                };
                let px = DVec2::new(centre(bx, size[0]), centre(by, size[1]));
                let c = model.image_to_canvas(px, size);
                let t = model
                    .tile_at_canvas(c)
                    .unwrap_or_else(|| model.nearest_tile(c));
                owner.push(owners.ranks[t] as u32);
            }
        }
        Self {
            width: size[0],
            height: size[1],
            tiles,
            owner,
        }
    }

    /// No display: `ranks` vertical strips of whole block columns, left to right.
    #[must_use]
    pub fn strips(size: [u32; 2], ranks: usize) -> Self {
        let tiles = block_grid(size);
        let owner = (0..tiles[1])
            .flat_map(|_| {
                (0..tiles[0]).map(move |bx| (bx as usize * ranks / tiles[0] as usize) as u32)
            })
            .collect();
        Self {
            width: size[0],
            height: size[1],
            tiles,
            owner,
        }
    }

    /// The blocks `rank` owns, ascending.
    #[must_use]
    pub fn owned_by(&self, rank: usize) -> Vec<u32> {
        (0..self.owner.len() as u32)
            .filter(|&b| self.owner[b as usize] as usize == rank)
            .collect()
    }
}

/// Blocks per row and column of a `size` image.
#[must_use]
pub fn block_grid(size: [u32; 2]) -> [u32; 2] {
    [size[0].div_ceil(TILE_EDGE), size[1].div_ceil(TILE_EDGE)]
}

/// The block of pixel `p` of a `width`-wide image with `tiles_x` blocks per row.
#[inline]
#[must_use]
pub fn block_of(p: u32, width: u32, tiles_x: u32) -> u32 {
    let (x, y) = (p % width, p / width);
    (y / TILE_EDGE) * tiles_x + x / TILE_EDGE
}

/// The image pixels of block `b`, row-major inside the block.
pub fn block_pixels(b: u32, size: [u32; 2], tiles_x: u32) -> impl Iterator<Item = u32> {
    let (x0, y0) = ((b % tiles_x) * TILE_EDGE, (b / tiles_x) * TILE_EDGE);
    let (x1, y1) = ((x0 + TILE_EDGE).min(size[0]), (y0 + TILE_EDGE).min(size[1]));
    (y0..y1).flat_map(move |y| (x0..x1).map(move |x| y * size[0] + x))
}

/// The pixels of block `b` at x and y multiples of `step` (row-major): [`block_pixels`]
/// filtered to that grid, visiting only the grid's pixels.
pub fn block_pixels_every(
    b: u32,
    size: [u32; 2],
    tiles_x: u32,
    step: u32,
) -> impl Iterator<Item = u32> {
    let (x0, y0) = ((b % tiles_x) * TILE_EDGE, (b / tiles_x) * TILE_EDGE);
    let (x1, y1) = ((x0 + TILE_EDGE).min(size[0]), (y0 + TILE_EDGE).min(size[1]));
    // The first multiple of `step` at or after each block edge.
    let (gx, gy) = (x0.div_ceil(step) * step, y0.div_ceil(step) * step);
    let step = step as usize;
    (gy..y1)
        .step_by(step)
        .flat_map(move |y| (gx..x1).step_by(step).map(move |x| y * size[0] + x))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hornet() -> DisplayModel {
        DisplayModel::open("hornet").unwrap().0
    }

    fn file() -> &'static Path {
        Path::new("owners.txt")
    }

    /// The grid's pixels of a block are its pixels filtered to the grid, edge blocks too.
    #[test]
    fn a_blocks_grid_pixels_are_its_pixels_on_the_grid() {
        let size = [100, 70];
        for step in [1, 3, 7, 32, 40] {
            for b in 0..4 * 3 {
                let want: Vec<u32> = block_pixels(b, size, 4)
                    .filter(|p| (p % 100).is_multiple_of(step) && (p / 100).is_multiple_of(step))
                    .collect();
                assert_eq!(
                    block_pixels_every(b, size, 4, step).collect::<Vec<_>>(),
                    want,
                    "block {b}, every {step}"
                );
            }
        }
    }

    #[test]
    fn columns_are_dealt_evenly_and_whole() {
        let m = hornet();
        let o = TileOwners::columns(&m, 2);
        for (t, &r) in m.tiles().iter().zip(&o.ranks) {
            assert_eq!(r, if t.column() < 4 { 0 } else { 1 }, "{}", t.id());
        }
        // More ranks than columns: each column still has one owner.
        let o = TileOwners::columns(&m, 35);
        for t in 0..m.tiles().len() {
            assert_eq!(o.ranks[t], m.tiles()[t].column() as usize * 5);
        }
    }

    #[test]
    fn a_file_that_lists_every_tile_once_gives_those_owners() {
        let m = hornet();
        let text: String = m
            .tiles()
            .iter()
            .map(|t| format!("{}  {} # col {}\n\n", t.id(), t.row() % 3, t.column()))
            .collect();
        let lines = parse_tile_owners(&format!("# owners\n{text}"), file()).unwrap();
        let o = TileOwners::from_lines(&lines, file(), &m, 3).unwrap();
        for (t, &r) in m.tiles().iter().zip(&o.ranks) {
            assert_eq!(r, t.row() as usize % 3);
        }
    }

    #[test]
    fn bad_files_are_rejected_naming_file_and_line() {
        let m = hornet();
        let all: Vec<String> = m.tiles().iter().map(|t| format!("{} 0", t.id())).collect();
        let check = |text: String, ranks: usize, want: &str| {
            let e = parse_tile_owners(&text, file())
                .and_then(|l| TileOwners::from_lines(&l, file(), &m, ranks))
                .unwrap_err();
            assert!(e.to_string().contains(want), "{e} (wanted {want})");
        };
        check("c0r0\n".into(), 2, "owners.txt:1: expected `TILE_ID RANK`");
        check("\nc0r0 x\n".into(), 2, "owners.txt:2: rank \"x\"");
        check("c0r0 -1\n".into(), 2, "owners.txt:1: rank \"-1\"");
        check(
            "c9r9 0\n".into(),
            2,
            "owners.txt:1: \"c9r9\" is not a tile of",
        );
        check("c0r0 2\n".into(), 2, "owners.txt:1: rank 2 for tile c0r0");
        check(
            format!("{}\nc0r0 1\n", all.join("\n")),
            2,
            "owners.txt:36: tile c0r0 is listed twice (first on line 1)",
        );
        check(
            all[1..].join("\n"),
            2,
            "owners.txt: tiles without an owner: c0r0",
        );
    }

    #[test]
    fn blocks_follow_the_tile_under_their_centre_and_strips_cover_the_image() {
        let m = hornet();
        let size = [700, 280];
        let o = TileOwners::columns(&m, 2);
        let b = BlockOwners::of_display(&m, &o, size);
        assert_eq!(b.tiles, [22, 9]);
        // The left column of blocks lies on column 0 (rank 0), the right one on column 6.
        assert!((0..9).all(|y| b.owner[y * 22] == 0 && b.owner[y * 22 + 21] == 1));
        let mut seen = vec![0u32; 700 * 280];
        for blk in 0..b.owner.len() as u32 {
            for p in block_pixels(blk, size, 22) {
                assert_eq!(block_of(p, 700, 22), blk);
                seen[p as usize] += 1;
            }
        }
        assert!(seen.iter().all(|&c| c == 1));
        let s = BlockOwners::strips(size, 3);
        assert_eq!(
            s.owned_by(0).len() + s.owned_by(1).len() + s.owned_by(2).len(),
            22 * 9
        );
        assert_eq!(s.owner[21], 2);
        assert_eq!(s.owner[0], 0);
    }
}
