//! Ray–display intersection: exact per tile (ray against the tile's plane, bounded by its canvas
//! rectangle with bezels), nearest hit first.

use glam::{DVec2, DVec3};
use serde::Serialize;

use super::DisplayModel;

/// Hits closer than this to the ray origin (metres) are ignored, so a ray that starts on a tile
/// (a pointer resting on the screen, or a ray re-cast from a hit point) does not hit that tile at
/// its own origin through rounding.
pub const T_MIN_M: f64 = 1e-9;
/// Hits this close in distance (metres) are the same point: on a hinge both tiles are hit at
/// once, and the first listed tile wins, so the result does not depend on rounding.
pub const T_TIE_M: f64 = 1e-9;
/// Rays with |cos| between direction and tile normal below this are parallel to the tile and
/// miss it (the hit would be at a distance beyond 1e12 times the origin's distance).
pub const PARALLEL_COS: f64 = 1e-12;
/// Canvas-rectangle slack (pixels) for a hit: a ray through a hinge or the outer edge of a bezel
/// computes the edge coordinate with rounding error around 1e-12 px; 1e-7 px (about 50 pm at
/// HORNET's pitch) keeps such rays from slipping between two tiles.
pub const EDGE_SLACK_PX: f64 = 1e-7;

/// The first place a ray meets the display.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Hit {
    /// Index into [`DisplayModel::tiles`].
    pub tile: usize,
    pub tile_id: String,
    /// Tile pixel coordinates (pixel centres at `i + 0.5`); outside `[0, resolution]` on a bezel.
    pub tile_px: DVec2,
    pub canvas_px: DVec2,
    /// Room frame, metres.
    pub point: DVec3,
    /// Distance from the origin, metres (along the normalised direction).
    pub t: f64,
    /// The hit is on the tile's bezel, not its active area.
    pub on_bezel: bool,
}

impl DisplayModel {
    /// The first hit of the ray `origin + t·dir` (t > [`T_MIN_M`]) with any tile's active area or
    /// bezels. `dir` need not be unit length; `t` is reported in metres.
    ///
    /// Misses (`None`): no tile in the way; a ray parallel to every tile it would meet; a
    /// non-finite origin or direction, or a zero direction; and a ray whose first hit is a tile's
    /// *back* (from behind the wall, the panels' backs show no picture and block the view).
    #[must_use]
    pub fn intersect(&self, origin: DVec3, dir: DVec3) -> Option<Hit> {
        if !origin.is_finite() || !dir.is_finite() {
            return None;
        }
        let dir = dir.try_normalize()?;
        // (t, tile, front-facing, canvas point)
        let mut best: Option<(f64, usize, bool, DVec2)> = None;
        for (i, tile) in self.tiles.iter().enumerate() {
            let n = tile.normal();
            let cos = dir.dot(n);
            if cos.abs() < PARALLEL_COS {
                continue;
            }
            let t = (tile.corners()[0] - origin).dot(n) / cos;
            // `!(t > ..)` also drops a NaN.
            if !(t > T_MIN_M) {
                continue;
            }
            if best.is_some_and(|(bt, ..)| t >= bt - T_TIE_M) {
                continue;
            }
            let c = tile.point_to_canvas(origin + dir * t);
            if self.rects[i].expand(EDGE_SLACK_PX).contains(c) {
                best = Some((t, i, cos < 0.0, c));
            }
        }
        let (t, i, front, c) = best?;
        if !front {
            return None;
        }
        let tile = &self.tiles[i];
        let tile_px = tile.canvas_to_tile_px(c);
        let res = tile.resolution();
        let on_bezel = !(0.0..=f64::from(res[0])).contains(&tile_px.x)
            || !(0.0..=f64::from(res[1])).contains(&tile_px.y);
        Some(Hit {
            tile: i,
            tile_id: tile.id().to_owned(),
            tile_px,
            canvas_px: c,
            // Reported on the tile's plane (through its map) rather than `origin + dir·t`, so the
            // point and the canvas coordinates agree exactly.
            point: tile.canvas_to_point(c),
            t,
            on_bezel,
        })
    }
}
