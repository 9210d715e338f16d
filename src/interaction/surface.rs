//! What the interaction needs from a display: ray intersection and canvas look-ups.
//!
//! The real implementation is [`DisplayModel`] (display models with bezels and an exact
//! canvas); the state machine is written against [`RaySurface`] so that its tests can use
//! [`HingedWall`], an analytic wall of planar columns hinged along vertical edges whose answers
//! are easy to write down, and so that the synthetic-session generator can aim without a file.

use glam::{DVec2, DVec3};

use crate::display::DisplayModel;

/// Where a ray (or a canvas point) lands on a display.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Room-frame point, metres.
    pub point: DVec3,
    /// Canvas pixel (x right, y down, origin at the canvas's top-left corner).
    pub canvas_px: DVec2,
    /// Index of the tile in the display's tile list.
    pub tile: usize,
    /// The tile's id as the display names it.
    pub tile_id: String,
    /// Ray parameter (distance along the unit direction); 0 for canvas look-ups.
    pub t: f64,
}

/// A display surface as the interaction sees it.
pub trait RaySurface {
    /// First hit of the ray `origin + t·dir`, t > 0 (`dir` need not be unit length).
    fn hit(&self, origin: DVec3, dir: DVec3) -> Option<SurfaceHit>;
    /// The surface point of a canvas pixel, `None` outside the canvas.
    fn locate(&self, canvas_px: DVec2) -> Option<SurfaceHit>;
    /// Canvas pixel → rendered-image pixel (the image covers the canvas).
    fn canvas_to_image(&self, canvas_px: DVec2, image_size: [u32; 2]) -> DVec2;
}

/// A wall of `columns` planar columns of equal width, each turned by `yaw_step_deg` against its
/// left neighbour towards the viewer, hinged at shared vertical edges, centred on the origin
/// with its middle in the plane z = 0 facing +Z. The canvas is the unrolled wall at
/// `px_per_m` pixels per metre (no bezels: a stand-in, not a display model).
#[derive(Clone, Debug, PartialEq)]
pub struct HingedWall {
    pub columns: u32,
    pub rows: u32,
    pub column_width_m: f64,
    pub height_m: f64,
    pub yaw_step_deg: f64,
    pub px_per_m: f64,
    /// Left edge point (at y = 0) and unit direction along each column.
    edges: Vec<(DVec3, DVec3)>,
}

impl HingedWall {
    /// Builds the wall; panics on non-positive sizes (the presets are the intended callers).
    #[must_use]
    pub fn new(
        columns: u32,
        rows: u32,
        column_width_m: f64,
        height_m: f64,
        yaw_step_deg: f64,
        px_per_m: f64,
    ) -> Self {
        assert!(
            columns > 0 && rows > 0 && column_width_m > 0.0 && height_m > 0.0 && px_per_m > 0.0
        );
        let mid = f64::from(columns - 1) / 2.0;
        let dir = |c: u32| {
            let a = ((f64::from(c) - mid) * yaw_step_deg).to_radians();
            DVec3::new(a.cos(), 0.0, a.sin())
        };
        // Walk out from the middle so the middle column (or middle hinge) sits at x = 0, z = 0.
        let mut left = vec![DVec3::ZERO; columns as usize];
        let m = columns / 2;
        left[m as usize] = if columns % 2 == 1 {
            -dir(m) * column_width_m / 2.0
        } else {
            DVec3::ZERO
        };
        for c in m + 1..columns {
            left[c as usize] = left[c as usize - 1] + dir(c - 1) * column_width_m;
        }
        for c in (0..m).rev() {
            left[c as usize] = left[c as usize + 1] - dir(c) * column_width_m;
        }
        let edges = (0..columns).map(|c| (left[c as usize], dir(c))).collect();
        Self {
            columns,
            rows,
            column_width_m,
            height_m,
            yaw_step_deg,
            px_per_m,
            edges,
        }
    }

    /// HORNET-like: 7 × 5 columns/rows of 46-inch 1080p panels (1018.1 × 572.7 mm active,
    /// 3 mm bezels: 1.0241 m per column, 2.8935 m high), 10° between columns, at the panels'
    /// pixel pitch (1920 px / 1.0181 m).
    #[must_use]
    pub fn hornet() -> Self {
        Self::new(7, 5, 1.0241, 5.0 * 0.5787, 10.0, 1920.0 / 1.0181)
    }

    /// A flat 27-inch 16:9 desktop monitor with 3840 px across (0.5977 × 0.3362 m).
    #[must_use]
    pub fn desktop() -> Self {
        Self::new(1, 1, 0.5977, 0.3362, 0.0, 3840.0 / 0.5977)
    }

    /// A preset by name (`hornet`, `desktop`).
    #[must_use]
    pub fn preset(name: &str) -> Option<Self> {
        match name {
            "hornet" => Some(Self::hornet()),
            "desktop" => Some(Self::desktop()),
            _ => None,
        }
    }

    /// Canvas size in pixels.
    #[must_use]
    pub fn canvas_size(&self) -> DVec2 {
        DVec2::new(f64::from(self.columns) * self.column_width_m, self.height_m) * self.px_per_m
    }

    /// Room point of column `c` at distance `u` along it and height `y`.
    fn point(&self, c: usize, u: f64, y: f64) -> DVec3 {
        let (left, d) = self.edges[c];
        left + d * u + DVec3::Y * y
    }

    fn make_hit(&self, c: usize, u: f64, y: f64, t: f64) -> SurfaceHit {
        let canvas_px = DVec2::new(
            (c as f64 * self.column_width_m + u) * self.px_per_m,
            (self.height_m / 2.0 - y) * self.px_per_m,
        );
        let row_h = self.height_m / f64::from(self.rows);
        let row = (((self.height_m / 2.0 - y) / row_h).floor() as u32).min(self.rows - 1);
        SurfaceHit {
            point: self.point(c, u, y),
            canvas_px,
            tile: (row * self.columns) as usize + c,
            // Named like the display models name their generated tiles.
            tile_id: format!("c{c}r{row}"),
            t,
        }
    }
}

impl RaySurface for HingedWall {
    fn hit(&self, origin: DVec3, dir: DVec3) -> Option<SurfaceHit> {
        let len = dir.length();
        if !(len > 0.0 && len.is_finite() && origin.is_finite()) {
            return None;
        }
        let dir = dir / len;
        let mut best: Option<SurfaceHit> = None;
        for (c, &(left, d)) in self.edges.iter().enumerate() {
            let n = d.cross(DVec3::Y);
            let denom = dir.dot(n);
            if denom.abs() < 1e-12 {
                continue;
            }
            let t = (left - origin).dot(n) / denom;
            if t.is_nan() || t <= 1e-9 || best.as_ref().is_some_and(|b| b.t <= t) {
                continue;
            }
            let p = origin + dir * t;
            let u = (p - left).dot(d);
            let y = p.y;
            if (0.0..=self.column_width_m).contains(&u) && y.abs() <= self.height_m / 2.0 {
                best = Some(self.make_hit(c, u, y, t));
            }
        }
        best
    }

    fn locate(&self, canvas_px: DVec2) -> Option<SurfaceHit> {
        let size = self.canvas_size();
        if !(canvas_px.x >= 0.0
            && canvas_px.y >= 0.0
            && canvas_px.x <= size.x
            && canvas_px.y <= size.y)
        {
            return None;
        }
        let along = canvas_px.x / self.px_per_m;
        let c = ((along / self.column_width_m).floor() as usize).min(self.edges.len() - 1);
        let u = along - c as f64 * self.column_width_m;
        let y = self.height_m / 2.0 - canvas_px.y / self.px_per_m;
        Some(self.make_hit(c, u, y, 0.0))
    }

    fn canvas_to_image(&self, canvas_px: DVec2, image_size: [u32; 2]) -> DVec2 {
        let img = DVec2::new(f64::from(image_size[0]), f64::from(image_size[1]));
        canvas_px / self.canvas_size() * img
    }
}

impl RaySurface for DisplayModel {
    fn hit(&self, origin: DVec3, dir: DVec3) -> Option<SurfaceHit> {
        self.intersect(origin, dir).map(|h| SurfaceHit {
            point: h.point,
            canvas_px: h.canvas_px,
            tile: h.tile,
            tile_id: h.tile_id,
            t: h.t,
        })
    }

    fn locate(&self, canvas_px: DVec2) -> Option<SurfaceHit> {
        let i = self.tile_at_canvas(canvas_px)?;
        let tile = &self.tiles()[i];
        Some(SurfaceHit {
            point: tile.canvas_to_point(canvas_px),
            canvas_px,
            tile: i,
            tile_id: tile.id().to_owned(),
            t: 0.0,
        })
    }

    fn canvas_to_image(&self, canvas_px: DVec2, image_size: [u32; 2]) -> DVec2 {
        DisplayModel::canvas_to_image(self, canvas_px, image_size)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_from_the_viewer_hits_the_canvas_centre() {
        let w = HingedWall::hornet();
        let h = w.hit(DVec3::new(0.0, 0.0, 1.0), DVec3::NEG_Z).unwrap();
        assert!((h.point - DVec3::ZERO).length() < 1e-12);
        assert!((h.canvas_px - w.canvas_size() / 2.0).length() < 1e-9);
        assert!((h.t - 1.0).abs() < 1e-12);
        // Column 3 (the middle), row 2 (the middle).
        assert_eq!((h.tile, h.tile_id.as_str()), (2 * 7 + 3, "c3r2"));
    }

    #[test]
    fn columns_are_hinged_and_turned_by_the_yaw_step() {
        let w = HingedWall::hornet();
        for c in 0..6 {
            let end = w.edges[c].0 + w.edges[c].1 * w.column_width_m;
            assert!(
                (end - w.edges[c + 1].0).length() < 1e-12,
                "gap after column {c}"
            );
            let turn = w.edges[c].1.angle_between(w.edges[c + 1].1).to_degrees();
            assert!((turn - 10.0).abs() < 1e-9);
        }
        // Outer columns come towards the viewer (+Z): the wall is concave as seen from z > 0.
        assert!(w.edges[6].0.z > 0.0 && w.edges[0].0.z > 0.0);
    }

    #[test]
    fn canvas_distance_equals_distance_along_the_wall() {
        let w = HingedWall::hornet();
        // A point in column 5 at u = 0.3 m, y = 0.4 m: canvas x = (5·w + 0.3)·ppm.
        let p = w.point(5, 0.3, 0.4);
        let origin = DVec3::new(0.0, 0.0, 1.0);
        let h = w.hit(origin, p - origin).unwrap();
        assert!((h.point - p).length() < 1e-9);
        let expect = DVec2::new(
            (5.0 * w.column_width_m + 0.3) * w.px_per_m,
            (w.height_m / 2.0 - 0.4) * w.px_per_m,
        );
        assert!((h.canvas_px - expect).length() < 1e-6);
        let back = w.locate(h.canvas_px).unwrap();
        assert!((back.point - p).length() < 1e-9);
        assert_eq!(back.tile_id, h.tile_id);
    }

    #[test]
    fn rays_that_miss_return_none() {
        let w = HingedWall::hornet();
        let o = DVec3::new(0.0, 0.0, 1.0);
        assert!(w.hit(o, DVec3::Z).is_none(), "pointing away");
        assert!(
            w.hit(o, DVec3::new(0.0, 3.0, -1.0)).is_none(),
            "above the wall"
        );
        assert!(w.hit(o, DVec3::ZERO).is_none(), "no direction");
        assert!(w.hit(DVec3::splat(f64::NAN), DVec3::NEG_Z).is_none());
        assert!(w.locate(DVec2::new(-1.0, 5.0)).is_none());
    }

    #[test]
    fn canvas_to_image_scales_each_axis() {
        let w = HingedWall::desktop();
        let s = w.canvas_size();
        assert!((s.x - 3840.0).abs() < 1e-9);
        let i = w.canvas_to_image(s / 2.0, [1920, 1080]);
        assert!((i - DVec2::new(960.0, 540.0)).length() < 1e-9);
    }

    #[test]
    fn hinged_wall_agrees_with_the_shipped_hornet_model() {
        // The stand-in and display-models/hornet.json describe the same wall: rays hit the same
        // points on the same tiles (canvas pixels differ: the model's canvas has bezel pixels).
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/display-models/hornet.json");
        let model = DisplayModel::load(path).unwrap();
        let wall = HingedWall::hornet();
        let eye = DVec3::new(0.0, 0.0, 1.0);
        for (x, y) in [
            (0.1, 0.2),
            (-2.5, 1.0),
            (3.0, -1.2),
            (-3.3, 0.0),
            (1.7, 0.9),
        ] {
            let target = wall.hit(eye, DVec3::new(x, y, -1.0)).unwrap();
            let h = RaySurface::hit(&model, eye, target.point - eye).unwrap();
            assert!((h.point - target.point).length() < 1e-9, "{x} {y}");
            assert_eq!(h.tile_id, target.tile_id, "{x} {y}");
        }
    }
}
