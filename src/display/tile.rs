//! One planar tile: its pixel grid, its place in the room, and its place on the canvas.

use glam::{DVec2, DVec3};

use super::rect::Rect;
use super::spec::{Bezel, TileSpec};

/// A validated tile. Built only by [`super::DisplayModel`] (which checks it), so the derived
/// frame below is always finite and non-degenerate.
///
/// Coordinates: *tile pixels* run from (0, 0) at the active area's top-left corner to
/// (width, height) at its bottom-right, x right, y down; pixel `(i, j)` covers
/// `[i, i+1) × [j, j+1)` and has its centre at `(i + 0.5, j + 0.5)`. On the canvas the active
/// area covers exactly `resolution` canvas pixels starting at `canvas_origin`, so canvas and
/// tile pixels differ by a translation only; bezels extend the tile's affine map beyond the
/// active area (they lie in the tile's plane).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(into = "TileSpec")]
pub struct Tile {
    id: String,
    column: u32,
    row: u32,
    resolution: [u32; 2],
    top_left: DVec3,
    top_right: DVec3,
    bottom_left: DVec3,
    bezel: Bezel,
    canvas_origin: DVec2,
    // Derived: the room-frame step of one tile pixel along x and y.
    step_x: DVec3,
    step_y: DVec3,
    normal: DVec3,
    // Inverse Gram matrix of (step_x, step_y): projects a point into tile pixels exactly even
    // when the edges are not perfectly perpendicular (they may be off by the validator's
    // tolerance).
    gram_inv: [f64; 3],
}

impl Tile {
    /// Builds the derived frame. The caller (the validator) has checked that the numbers are
    /// finite, the resolution positive and the edges non-degenerate.
    pub(crate) fn from_checked(spec: &TileSpec, resolution: [u32; 2]) -> Self {
        let top_left = DVec3::from_array(spec.top_left);
        let top_right = DVec3::from_array(spec.top_right);
        let bottom_left = DVec3::from_array(spec.bottom_left);
        let step_x = (top_right - top_left) / f64::from(resolution[0]);
        let step_y = (bottom_left - top_left) / f64::from(resolution[1]);
        // Tile x runs right and y down as seen from the front, so y × x points at the viewer.
        let normal = step_y.cross(step_x).normalize();
        let (a, b, c) = (
            step_x.length_squared(),
            step_x.dot(step_y),
            step_y.length_squared(),
        );
        let det = a * c - b * b;
        Self {
            id: spec.id.clone(),
            column: spec.column,
            row: spec.row,
            resolution,
            top_left,
            top_right,
            bottom_left,
            bezel: spec.bezel,
            canvas_origin: DVec2::from_array(spec.canvas),
            step_x,
            step_y,
            normal,
            gram_inv: [c / det, -b / det, a / det],
        }
    }

    #[must_use]
    pub fn id(&self) -> &str {
        &self.id
    }

    #[must_use]
    pub fn column(&self) -> u32 {
        self.column
    }

    #[must_use]
    pub fn row(&self) -> u32 {
        self.row
    }

    /// Pixels `[width, height]`.
    #[must_use]
    pub fn resolution(&self) -> [u32; 2] {
        self.resolution
    }

    /// Active-area corners in the room frame: top-left, top-right, bottom-left.
    #[must_use]
    pub fn corners(&self) -> [DVec3; 3] {
        [self.top_left, self.top_right, self.bottom_left]
    }

    #[must_use]
    pub fn bezel(&self) -> Bezel {
        self.bezel
    }

    /// Canvas position of the active area's top-left corner.
    #[must_use]
    pub fn canvas_origin(&self) -> DVec2 {
        self.canvas_origin
    }

    /// Metres per pixel along the tile's x and y.
    #[must_use]
    pub fn pitch(&self) -> DVec2 {
        DVec2::new(self.step_x.length(), self.step_y.length())
    }

    /// Unit normal, towards the viewer (the side the pixels are seen from).
    #[must_use]
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// The active area on the canvas: `resolution` pixels from the canvas origin.
    #[must_use]
    pub fn active_rect(&self) -> Rect {
        let size = DVec2::new(f64::from(self.resolution[0]), f64::from(self.resolution[1]));
        Rect::new(self.canvas_origin, self.canvas_origin + size)
    }

    /// Active area plus bezels on the canvas; bezel widths are converted at `pitch` (metres per
    /// canvas pixel: pass the model's pitch, [`super::DisplayModel::pitch_m`], so every tile's
    /// bezels use the same scale).
    #[must_use]
    pub fn canvas_rect(&self, pitch: f64) -> Rect {
        let a = self.active_rect();
        Rect::new(
            a.min - DVec2::new(self.bezel.left, self.bezel.top) / pitch,
            a.max + DVec2::new(self.bezel.right, self.bezel.bottom) / pitch,
        )
    }

    /// Canvas → tile pixels (a translation).
    #[must_use]
    pub fn canvas_to_tile_px(&self, c: DVec2) -> DVec2 {
        c - self.canvas_origin
    }

    /// Tile pixels → canvas.
    #[must_use]
    pub fn tile_px_to_canvas(&self, px: DVec2) -> DVec2 {
        px + self.canvas_origin
    }

    /// The room-frame point of a canvas point, through this tile's affine map. Valid anywhere:
    /// on the active area, on the bezels and beyond (the tile's plane, extended).
    #[must_use]
    pub fn canvas_to_point(&self, c: DVec2) -> DVec3 {
        self.tile_px_to_point(self.canvas_to_tile_px(c))
    }

    /// The room-frame point of a tile-pixel position.
    #[must_use]
    pub fn tile_px_to_point(&self, px: DVec2) -> DVec3 {
        self.top_left + self.step_x * px.x + self.step_y * px.y
    }

    /// Orthogonal projection of `p` into the tile's plane, in canvas pixels. The inverse of
    /// [`Self::canvas_to_point`] for points in the plane.
    #[must_use]
    pub fn point_to_canvas(&self, p: DVec3) -> DVec2 {
        self.tile_px_to_canvas(self.point_to_tile_px(p))
    }

    /// Orthogonal projection of `p` into the tile's plane, in tile pixels.
    #[must_use]
    pub fn point_to_tile_px(&self, p: DVec3) -> DVec2 {
        let d = p - self.top_left;
        let (u, v) = (d.dot(self.step_x), d.dot(self.step_y));
        let [g00, g01, g11] = self.gram_inv;
        DVec2::new(g00 * u + g01 * v, g01 * u + g11 * v)
    }

    /// The file form of this tile.
    #[must_use]
    pub fn to_spec(&self) -> TileSpec {
        TileSpec {
            id: self.id.clone(),
            column: self.column,
            row: self.row,
            resolution: self.resolution.map(i64::from),
            top_left: self.top_left.to_array(),
            top_right: self.top_right.to_array(),
            bottom_left: self.bottom_left.to_array(),
            bezel: self.bezel,
            canvas: self.canvas_origin.to_array(),
        }
    }
}

impl From<Tile> for TileSpec {
    fn from(t: Tile) -> Self {
        t.to_spec()
    }
}
