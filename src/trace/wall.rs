//! The wall camera (DESIGN.md §11): the primary ray of image pixel c starts at the eye and
//! passes through c's own point on the display surface (DESIGN.md §3), jittered over the
//! pixel's footprint on its tile (the box filter of the pinhole).
//!
//! # What is uploaded, and why no per-pixel table
//!
//! Each tile's map from tile pixels to room points is affine (`top_left + step_x·x +
//! step_y·y`), and the image covers the canvas by a per-axis scale, so the map from *image*
//! pixels to room points is affine per tile too. [`WallCamera`] keeps, per tile, the range of
//! image pixels whose centres lie on the tile's active area (integers: every backend agrees on
//! which pixel belongs to which tile, bit for bit) and that affine map, already turned into the
//! scene's frame and taken relative to the eye. The kernel (`shaders/trace/path.wgsl`,
//! `wall_ray`) and the CPU twin ([`WallCamera::ray`]) compute the same f32 expression from
//! these 16 floats per tile, so the wall is exact at any image size (HORNET's 73.8 MP canvas
//! included) for 64 bytes a tile.
//!
//! # Pixels no display shows
//!
//! An image pixel is shown when its centre falls on a tile's active area or when a tile's own
//! pixel shows it (the wall output's nearest-neighbour cut: below the canvas's resolution the
//! pixel at a tile's edge may have its centre on the bezel). Every other pixel (bezels, gaps,
//! the corners of a canvas that is no full rectangle) is not shown: it is never scheduled (the
//! schedule reads the [`WallCamera::shown_mask`] bitmask, 1 bit a pixel, 9.2 MB at 73.8 MP),
//! never traced, keeps zero samples and comes out black.
//!
//! # Room and scene
//!
//! The eye is in the room frame (DESIGN.md §2, metres). [`WorldFromRoom`] places the room in
//! the scene: `identity` (the room frame is the scene frame), an explicit translation, yaw
//! about +Y and scale, or `auto`: the scene's chosen camera sits at the eye and looks at the
//! wall's centre (its up vector kept as up).
//!
//! # A moving eye
//!
//! A tracked head (or a desktop user's orbit) moves the eye while the room stays where it was
//! put: [`WallCamera::with_eye`] keeps the room→scene similarity, the tiles' pixel ranges and
//! the shown mask (none depends on the eye), and recomputes only each tile's vector from the
//! eye to its anchor point, from the same f64 room points as [`WallCamera::new`] — so a moved
//! camera equals one built afresh at that eye with that placement, bit for bit. Whether a move
//! restarts the accumulation is the tracked head's rule ([`WallCamera::eye_moved`],
//! [`crate::tracking::head::eye_moved`]): more than a threshold
//! ([`crate::tracking::head::DEFAULT_EYE_THRESHOLD_M`], 1 cm) from the eye the accumulation
//! started with.

use glam::{DMat3, DVec2, DVec3, Vec3};

use super::camera::RenderCamera;
use crate::display::DisplayModel;

/// The eye must be at least this far (metres) in front of every tile's plane: closer, the rays
/// through that tile graze it (and on or behind it they would leave through the panel's back).
pub const MIN_EYE_DISTANCE_M: f64 = 1e-3;

/// A tile index no pixel has (the kernel's `NO_TILE`).
pub const NO_TILE: u32 = u32::MAX;

/// Vec4s per tile in the GPU table (`wall` in shaders/trace/path.wgsl).
pub const TILE_VEC4S: usize = 4;

/// A wall camera's inputs: an image with pixels, and a finite eye in front of every tile.
fn check_inputs(
    model: &DisplayModel,
    [width, height]: [u32; 2],
    eye: DVec3,
) -> Result<(), WallCameraError> {
    if width == 0 || height == 0 {
        return Err(WallCameraError::Size { width, height });
    }
    if !eye.is_finite() {
        return Err(WallCameraError::EyeNotFinite { eye });
    }
    check_eye(
        model.name(),
        eye,
        model
            .tiles()
            .iter()
            .map(|t| (t.id(), t.corners()[0], t.normal())),
    )
}

/// Where the room frame sits in the scene (`--world-from-room`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WorldFromRoom {
    /// The scene's chosen camera at the eye, looking at the wall's centre.
    Auto,
    /// The room frame is the scene's frame.
    Identity,
    /// `scene = translation + R_y(yaw) · scale · room` (scene units per metre: `scale`).
    Explicit {
        translation: DVec3,
        yaw_deg: f64,
        scale: f64,
    },
}

/// Why a wall camera could not be built.
#[derive(Debug, thiserror::Error)]
pub enum WallCameraError {
    #[error("--eye {eye}: not a finite point")]
    EyeNotFinite { eye: DVec3 },
    #[error(
        "--eye {eye}: the eye is {distance_m:.4} m in front of tile {tile}'s plane (on it or behind it when ≤ 0); it must be at least {MIN_EYE_DISTANCE_M} m in front of every tile of {model}"
    )]
    EyeBehindTile {
        eye: DVec3,
        tile: String,
        model: String,
        distance_m: f64,
    },
    #[error(
        "--world-from-room: scale {scale} must be a finite number above 0 (scene units per metre)"
    )]
    Scale { scale: f64 },
    #[error("--world-from-room: the translation and yaw must be finite numbers")]
    NotFinite,
    #[error(
        "--world-from-room auto: the scene camera looks straight up or down, or the eye looks at the wall's centre along ±Y: no up direction to keep"
    )]
    AutoDegenerate,
    #[error("image size {width}×{height} has no pixels")]
    Size { width: u32, height: u32 },
}

/// The room → scene similarity: `scene = translation + rotation · room` (`rotation` includes
/// the scale).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneFromRoom {
    pub rotation: DMat3,
    pub translation: DVec3,
}

impl SceneFromRoom {
    #[must_use]
    pub fn point(&self, p: DVec3) -> DVec3 {
        self.translation + self.rotation * p
    }

    #[must_use]
    pub fn vector(&self, v: DVec3) -> DVec3 {
        self.rotation * v
    }
}

/// Right, up and backward of a viewing direction with `up` as the up hint (columns of a
/// camera-to-frame rotation looking along −Z); `None` when they are parallel.
fn view_basis(forward: DVec3, up: DVec3) -> Option<DMat3> {
    let f = forward.try_normalize()?;
    let r = f.cross(up).try_normalize()?;
    let u = r.cross(f);
    Some(DMat3::from_cols(r, u, -f))
}

impl WorldFromRoom {
    /// The similarity for an eye and the wall's centre (room frame), and the scene camera's
    /// position, forward and up (scene frame) for `auto`.
    pub fn resolve(
        &self,
        eye: DVec3,
        wall_centre: DVec3,
        camera: (DVec3, DVec3, DVec3),
    ) -> Result<SceneFromRoom, WallCameraError> {
        match *self {
            Self::Identity => Ok(SceneFromRoom {
                rotation: DMat3::IDENTITY,
                translation: DVec3::ZERO,
            }),
            Self::Explicit {
                translation,
                yaw_deg,
                scale,
            } => {
                if !(scale.is_finite() && scale > 0.0) {
                    return Err(WallCameraError::Scale { scale });
                }
                if !translation.is_finite() || !yaw_deg.is_finite() {
                    return Err(WallCameraError::NotFinite);
                }
                Ok(SceneFromRoom {
                    rotation: DMat3::from_rotation_y(yaw_deg.to_radians()) * scale,
                    translation,
                })
            }
            Self::Auto => {
                let (pos, fwd, up) = camera;
                let room = view_basis(wall_centre - eye, DVec3::Y)
                    .ok_or(WallCameraError::AutoDegenerate)?;
                let scene = view_basis(fwd, up).ok_or(WallCameraError::AutoDegenerate)?;
                let rotation = scene * room.transpose();
                Ok(SceneFromRoom {
                    rotation,
                    translation: pos - rotation * eye,
                })
            }
        }
    }
}

/// What the command line asks for (`--camera wall --eye … --world-from-room …` with a
/// display): a wall camera once the image size and the scene camera are known.
#[derive(Clone, Debug, PartialEq)]
pub struct WallSpec {
    pub model: DisplayModel,
    /// Room frame, metres.
    pub eye: DVec3,
    pub placement: WorldFromRoom,
}

impl WallSpec {
    /// Checks what needs no scene: the eye in front of every tile, the placement's numbers.
    pub fn check(&self) -> Result<(), WallCameraError> {
        let any = (DVec3::ZERO, DVec3::NEG_Z, DVec3::Y);
        WallCamera::new(&self.model, [1, 1], self.eye, &self.placement, any).map(|_| ())
    }

    /// The wall camera for a `size` image, `auto` placing `scene_camera` at the eye.
    pub fn camera(
        &self,
        size: [u32; 2],
        scene_camera: &RenderCamera,
    ) -> Result<WallCamera, WallCameraError> {
        let c = scene_camera;
        WallCamera::new(
            &self.model,
            size,
            self.eye,
            &self.placement,
            (c.position.as_dvec3(), c.forward.as_dvec3(), c.up.as_dvec3()),
        )
    }
}

/// One tile as the tracer sees it: the image pixels it shows and its affine map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WallTile {
    /// Image pixels `x0..x1` × `y0..y1` have their centres on this tile's active area.
    pub x0: u32,
    pub x1: u32,
    pub y0: u32,
    pub y1: u32,
    /// Scene frame: the vector from the eye to the wall point of image point `(x0, y0)` (the
    /// corner of pixel `(x0, y0)`, extended in the tile's plane), and the steps of one image
    /// pixel along x and y.
    pub origin: Vec3,
    pub step_x: Vec3,
    pub step_y: Vec3,
}

/// The wall camera for one display model, image size, eye and placement.
#[derive(Clone, Debug, PartialEq)]
pub struct WallCamera {
    pub width: u32,
    pub height: u32,
    /// Room frame, metres.
    pub eye_room: DVec3,
    /// The eye in the scene's frame: every primary ray's origin.
    pub eye: Vec3,
    pub scene_from_room: SceneFromRoom,
    /// Two entries per tile, every tile's first before any second ([`Self::placed`]): the
    /// pixels whose centres lie on its active area, then the box of the pixels its own pixels
    /// show. A pixel is traced through the first entry that holds it ([`Self::tile_of`]).
    pub tiles: Vec<WallTile>,
    /// Bit `p % 32` of word `p / 32`: image pixel `p = y·width + x` is shown by some tile (its
    /// centre lies on the tile's active area, or one of the tile's pixels shows it).
    shown: Vec<u32>,
    shown_count: u64,
    /// Per entry of `tiles`, room frame: the wall point of image point `(x0, y0)`, a point of
    /// the tile's plane and its normal, and its id — what a moved eye needs
    /// ([`Self::with_eye`]).
    anchors: Vec<TileAnchor>,
    /// The display model's name, for errors.
    model_name: String,
}

/// What [`WallCamera::with_eye`] keeps of a tile: its anchor point and plane (room frame).
#[derive(Clone, Debug, PartialEq)]
struct TileAnchor {
    id: String,
    anchor: DVec3,
    plane_point: DVec3,
    normal: DVec3,
}

/// The first image pixel whose centre `(i + 0.5)·scale + min` is at or past canvas coordinate
/// `c`, clamped to `0..=n`.
fn first_pixel_at(c: f64, min: f64, scale: f64, n: u32) -> u32 {
    let i = ((c - min) / scale - 0.5).ceil();
    i.clamp(0.0, f64::from(n)) as u32
}

impl WallCamera {
    /// The wall camera of `model` for a `width × height` image covering its canvas, with the
    /// eye at `eye` (room frame) and the room placed in the scene by `placement`. `camera` is the
    /// scene camera `auto` puts at the eye: position, forward, up (scene frame).
    pub fn new(
        model: &DisplayModel,
        size: [u32; 2],
        eye: DVec3,
        placement: &WorldFromRoom,
        camera: (DVec3, DVec3, DVec3),
    ) -> Result<Self, WallCameraError> {
        // Checked before the placement resolves, whose errors would otherwise come first.
        check_inputs(model, size, eye)?;
        let xf = placement.resolve(eye, wall_centre(model), camera)?;
        Self::placed(model, size, eye, xf)
    }

    /// The wall camera of `model` for a `width × height` image with the eye at `eye` (room
    /// frame) and the room placed in the scene by the resolved similarity `xf`.
    pub fn placed(
        model: &DisplayModel,
        [width, height]: [u32; 2],
        eye: DVec3,
        xf: SceneFromRoom,
    ) -> Result<Self, WallCameraError> {
        check_inputs(model, [width, height], eye)?;
        let canvas = model.canvas_rect();
        let scale = canvas.size() / DVec2::new(f64::from(width), f64::from(height));
        let n = u64::from(width) * u64::from(height);
        let mut shown = vec![0u32; n.div_ceil(32) as usize];
        let mut shown_count = 0u64;
        let mut show = |x: u32, y: u32| {
            let p = u64::from(y) * u64::from(width) + u64::from(x);
            let (w, b) = ((p / 32) as usize, p % 32);
            if shown[w] & (1 << b) == 0 {
                shown[w] |= 1 << b;
                shown_count += 1;
            }
        };
        // Each tile has two entries, all first entries before all second ones (the kernel takes
        // the first entry that holds a pixel): the image pixels whose centres lie on its active
        // area, then the box of every image pixel its own pixels show (the wall output's
        // nearest-neighbour cut, `display::cut::tile_axes`). Below the canvas's resolution a
        // pixel at a tile's edge can have its centre on the bezel and still be the pixel the
        // tile's outermost pixels show: it is traced through that tile, its footprint on the
        // tile's plane, where the bezel lies too (DESIGN.md §3).
        let mut centre = Vec::with_capacity(model.tiles().len());
        let mut cut = Vec::with_capacity(model.tiles().len());
        for (i, t) in model.tiles().iter().enumerate() {
            let a = t.active_rect();
            let x0 = first_pixel_at(a.min.x, canvas.min.x, scale.x, width);
            let x1 = first_pixel_at(a.max.x, canvas.min.x, scale.x, width);
            let y0 = first_pixel_at(a.min.y, canvas.min.y, scale.y, height);
            let y1 = first_pixel_at(a.max.y, canvas.min.y, scale.y, height);
            for y in y0..y1 {
                for x in x0..x1 {
                    show(x, y);
                }
            }
            let (xs, ys) = crate::display::cut::tile_axes(model, i, [width, height]);
            for &y in &ys {
                for &x in &xs {
                    show(x as u32, y as u32);
                }
            }
            let span = |v: &[usize]| (v[0] as u32, v[v.len() - 1] as u32 + 1);
            let ((cx0, cx1), (cy0, cy1)) = (span(&xs), span(&ys));
            centre.push([x0, x1, y0, y1]);
            cut.push([cx0.min(x0), cx1.max(x1), cy0.min(y0), cy1.max(y1)]);
        }
        let mut tiles = Vec::with_capacity(2 * model.tiles().len());
        let mut anchors = Vec::with_capacity(2 * model.tiles().len());
        for (t, [x0, x1, y0, y1]) in model
            .tiles()
            .iter()
            .cycle()
            .zip(centre.into_iter().chain(cut))
        {
            // Image point (x0, y0) on the canvas, and its wall point in the tile's plane.
            let c0 = canvas.min + DVec2::new(f64::from(x0), f64::from(y0)) * scale;
            let p0 = t.canvas_to_point(c0);
            let sx = t.canvas_to_point(c0 + DVec2::new(scale.x, 0.0)) - p0;
            let sy = t.canvas_to_point(c0 + DVec2::new(0.0, scale.y)) - p0;
            tiles.push(WallTile {
                x0,
                x1,
                y0,
                y1,
                origin: xf.vector(p0 - eye).as_vec3(),
                step_x: xf.vector(sx).as_vec3(),
                step_y: xf.vector(sy).as_vec3(),
            });
            anchors.push(TileAnchor {
                id: t.id().to_owned(),
                anchor: p0,
                plane_point: t.corners()[0],
                normal: t.normal(),
            });
        }
        Ok(Self {
            width,
            height,
            eye_room: eye,
            eye: xf.point(eye).as_vec3(),
            scene_from_room: xf,
            tiles,
            shown,
            shown_count,
            anchors,
            model_name: model.name().to_owned(),
        })
    }

    /// This camera with the eye moved to `eye` (room frame): the placement, the pixel ranges
    /// and the shown mask are kept; equal to [`Self::placed`] at `eye` with this placement.
    /// An eye on or behind a tile's plane is an error naming the tile, as at the start.
    pub fn with_eye(&self, eye: DVec3) -> Result<Self, WallCameraError> {
        if !eye.is_finite() {
            return Err(WallCameraError::EyeNotFinite { eye });
        }
        check_eye(
            &self.model_name,
            eye,
            self.anchors
                .iter()
                .map(|a| (a.id.as_str(), a.plane_point, a.normal)),
        )?;
        let xf = self.scene_from_room;
        let mut moved = self.clone();
        for (t, a) in moved.tiles.iter_mut().zip(&self.anchors) {
            t.origin = xf.vector(a.anchor - eye).as_vec3();
        }
        moved.eye_room = eye;
        moved.eye = xf.point(eye).as_vec3();
        Ok(moved)
    }

    /// Whether moving the eye to `eye` restarts the accumulation under `threshold_m`
    /// (the tracked head's rule, [`crate::tracking::head::eye_moved`], from this camera's eye,
    /// the one its accumulation started with).
    #[must_use]
    pub fn eye_moved(&self, eye: DVec3, threshold_m: f64) -> bool {
        crate::tracking::head::eye_moved(self.eye_room, eye, threshold_m)
    }

    /// The entry of [`Self::tiles`] through which image pixel `(x, y)` is traced (the first
    /// that holds it), else `None`: the twin of `wall_tile` in path.wgsl.
    #[inline]
    #[must_use]
    pub fn tile_of(&self, x: u32, y: u32) -> Option<usize> {
        self.tiles
            .iter()
            .position(|t| x >= t.x0 && x < t.x1 && y >= t.y0 && y < t.y1)
    }

    /// The display model's tile of entry `entry` of [`Self::tiles`] (what [`Self::tile_of`]
    /// returns): each tile has two entries, all first ones before the second ones.
    #[must_use]
    pub fn model_tile(&self, entry: usize) -> usize {
        entry % (self.tiles.len() / 2).max(1)
    }

    /// Whether pixel `p = y·width + x` is shown by some tile (reads the bitmask).
    #[inline]
    #[must_use]
    pub fn is_shown(&self, p: u32) -> bool {
        shown_bit(&self.shown, p)
    }

    /// The bitmask the schedule reads (bit `p % 32` of word `p / 32`).
    #[must_use]
    pub fn shown_mask(&self) -> &[u32] {
        &self.shown
    }

    /// How many image pixels some tile shows.
    #[must_use]
    pub fn shown_count(&self) -> u64 {
        self.shown_count
    }

    /// The primary ray (origin, unit direction) through image point `(x + jx, y + jy)` of the
    /// shown pixel `(x, y)` on tile `tile`: the same f32 operations as `wall_ray` in path.wgsl.
    #[inline]
    #[must_use]
    pub fn ray(&self, tile: usize, x: u32, y: u32, jx: f32, jy: f32) -> (Vec3, Vec3) {
        let t = &self.tiles[tile];
        let fx = (x - t.x0) as f32 + jx;
        let fy = (y - t.y0) as f32 + jy;
        let d = t.origin + t.step_x * fx + t.step_y * fy;
        (self.eye, d.normalize())
    }

    /// The image point (pixels, y down) whose primary ray runs along `toward` from the eye,
    /// and the shown pixel that holds it, traced through the entry whose map gives it
    /// ([`Self::tile_of`]): entry `hint` when it does (a neighbour's entry: most points fall on
    /// it), else the first that does; `None` where no pixel's ray does. The inverse of
    /// [`Self::ray`] (motion reuse, [`crate::trace::reuse`]); the twin of `project` in
    /// reuse.wgsl.
    #[must_use]
    pub fn project(&self, toward: Vec3, hint: Option<usize>) -> Option<([f32; 2], u32)> {
        let at = |i: usize| {
            let t = &self.tiles[i];
            let [fx, fy] = tile_point(t.origin, t.step_x, t.step_y, toward)?;
            let (w, h) = ((t.x1 - t.x0) as f32, (t.y1 - t.y0) as f32);
            if !(fx >= 0.0 && fy >= 0.0 && fx < w && fy < h) {
                return None;
            }
            let (x, y) = (t.x0 + fx as u32, t.y0 + fy as u32);
            (self.tile_of(x, y) == Some(i))
                .then(|| ([t.x0 as f32 + fx, t.y0 as f32 + fy], y * self.width + x))
        };
        hint.filter(|&h| h < self.tiles.len())
            .and_then(at)
            .or_else(|| (0..self.tiles.len()).find_map(at))
    }

    /// Sets every pixel no tile shows to black (a filtered picture spreads neighbours' light
    /// into unsampled pixels; those on bezels must stay dark).
    pub fn blank_unshown<T: Copy + Default>(&self, image: &mut [T]) {
        for (p, v) in image.iter_mut().enumerate() {
            if !self.is_shown(p as u32) {
                *v = T::default();
            }
        }
    }

    /// The GPU table: [`TILE_VEC4S`] vec4s per tile — `(x0, x1, y0, y1)` as u32 bits, then
    /// origin, step_x and step_y (w = 0).
    #[must_use]
    pub fn gpu_table(&self) -> Vec<[f32; 4]> {
        let mut out = Vec::with_capacity(self.tiles.len() * TILE_VEC4S);
        for t in &self.tiles {
            out.push([t.x0, t.x1, t.y0, t.y1].map(f32::from_bits));
            out.push(t.origin.extend(0.0).to_array());
            out.push(t.step_x.extend(0.0).to_array());
            out.push(t.step_y.extend(0.0).to_array());
        }
        out
    }
}

/// Where the line from the eye along `toward` crosses the plane of a tile entry whose map is
/// `origin + step_x·fx + step_y·fy` (relative to the eye): `(fx, fy)`, or `None` where it
/// runs parallel to the plane or crosses it behind the eye. The twin of `tile_point` in
/// reuse.wgsl (the same f32 operations).
#[inline]
#[must_use]
pub fn tile_point(origin: Vec3, step_x: Vec3, step_y: Vec3, toward: Vec3) -> Option<[f32; 2]> {
    let n = step_x.cross(step_y);
    let denom = toward.dot(n);
    let s = origin.dot(n) / denom;
    if !(s > 0.0 && s <= f32::MAX) {
        return None;
    }
    let p = toward * s - origin;
    let (bx, by) = (step_y.cross(n), n.cross(step_x));
    Some([p.dot(bx) / step_x.dot(bx), p.dot(by) / step_y.dot(by)])
}

/// The room point at the centre of `model`'s canvas (on the nearest tile's plane where the
/// centre falls on no tile): what `auto` looks at, and what the viewer orbits about.
#[must_use]
pub fn wall_centre(model: &DisplayModel) -> DVec3 {
    let c = model.canvas_rect().center();
    model
        .canvas_to_point(c)
        .unwrap_or_else(|| model.tiles()[model.nearest_tile(c)].canvas_to_point(c))
}

/// The eye must lie at least [`MIN_EYE_DISTANCE_M`] in front of every tile's plane (`tiles`:
/// id, a point of the plane, its normal).
fn check_eye<'t>(
    model: &str,
    eye: DVec3,
    tiles: impl Iterator<Item = (&'t str, DVec3, DVec3)>,
) -> Result<(), WallCameraError> {
    for (id, point, normal) in tiles {
        let distance_m = (eye - point).dot(normal);
        if !(distance_m >= MIN_EYE_DISTANCE_M) {
            return Err(WallCameraError::EyeBehindTile {
                eye,
                tile: id.to_owned(),
                model: model.to_owned(),
                distance_m,
            });
        }
    }
    Ok(())
}

/// Bit `p` of a shown-pixel bitmask.
#[inline]
#[must_use]
pub fn shown_bit(mask: &[u32], p: u32) -> bool {
    mask[(p / 32) as usize] >> (p % 32) & 1 != 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::head::DEFAULT_EYE_THRESHOLD_M;

    fn cam() -> (DVec3, DVec3, DVec3) {
        (DVec3::new(1.0, 2.0, 3.0), DVec3::NEG_X, DVec3::Y)
    }

    #[test]
    fn auto_puts_the_scene_camera_at_the_eye_looking_at_the_centre() {
        let eye = DVec3::new(0.2, 0.1, 1.5);
        let centre = DVec3::new(0.0, 0.0, 0.0);
        let xf = WorldFromRoom::Auto.resolve(eye, centre, cam()).unwrap();
        assert!(xf.point(eye).abs_diff_eq(cam().0, 1e-12));
        let f = xf.vector((centre - eye).normalize());
        assert!(f.abs_diff_eq(DVec3::NEG_X, 1e-12), "{f}");
    }

    #[test]
    fn a_moved_eye_equals_a_camera_built_there_and_keeps_the_placement() {
        let model = DisplayModel::open("hornet").unwrap().0;
        let size = [331, 134];
        let a = WallCamera::new(
            &model,
            size,
            DVec3::new(0.0, 0.0, 1.0),
            &WorldFromRoom::Auto,
            cam(),
        )
        .unwrap();
        let eye = DVec3::new(0.3, -0.1, 1.4);
        let moved = a.with_eye(eye).unwrap();
        let fresh = WallCamera::placed(&model, size, eye, a.scene_from_room).unwrap();
        assert_eq!(moved, fresh);
        assert_eq!(moved.scene_from_room, a.scene_from_room);
        assert_eq!(moved.shown_mask(), a.shown_mask());
        assert!(!a.eye_moved(DVec3::new(0.0, 0.009, 1.0), DEFAULT_EYE_THRESHOLD_M));
        assert!(a.eye_moved(DVec3::new(0.0, 0.011, 1.0), DEFAULT_EYE_THRESHOLD_M));
        assert!(!a.eye_moved(DVec3::NAN, DEFAULT_EYE_THRESHOLD_M));
        let behind = a.with_eye(DVec3::new(0.0, 0.0, -0.5)).unwrap_err();
        assert!(
            matches!(behind, WallCameraError::EyeBehindTile { .. }),
            "{behind}"
        );
    }

    #[test]
    fn explicit_placement_turns_about_y_and_scales() {
        let xf = WorldFromRoom::Explicit {
            translation: DVec3::new(1.0, 0.0, 0.0),
            yaw_deg: 90.0,
            scale: 2.0,
        }
        .resolve(DVec3::ZERO, DVec3::NEG_Z, cam())
        .unwrap();
        // +X turned 90° about +Y is −Z; doubled, then shifted.
        assert!(
            xf.point(DVec3::X)
                .abs_diff_eq(DVec3::new(1.0, 0.0, -2.0), 1e-12)
        );
    }
}
