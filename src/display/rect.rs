//! Axis-aligned rectangles on the canvas (pixels, x right, y down).

use glam::DVec2;
use serde::{Deserialize, Serialize};

/// A closed axis-aligned rectangle `[min, max]`. Canvas rectangles of neighbouring tiles share
/// edges, so containment is closed on both sides; whoever needs a unique owner for a shared edge
/// breaks the tie explicitly (see [`super::DisplayModel::tile_at_canvas`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rect {
    pub min: DVec2,
    pub max: DVec2,
}

impl Rect {
    #[must_use]
    pub const fn new(min: DVec2, max: DVec2) -> Self {
        Self { min, max }
    }

    #[must_use]
    pub fn size(&self) -> DVec2 {
        self.max - self.min
    }

    #[must_use]
    pub fn center(&self) -> DVec2 {
        (self.min + self.max) * 0.5
    }

    /// Whether `p` lies in the closed rectangle (false for NaN).
    #[must_use]
    pub fn contains(&self, p: DVec2) -> bool {
        p.x >= self.min.x && p.x <= self.max.x && p.y >= self.min.y && p.y <= self.max.y
    }

    /// The rectangle grown by `margin` on every side (shrunk for a negative margin).
    #[must_use]
    pub fn expand(&self, margin: f64) -> Self {
        Self::new(
            self.min - DVec2::splat(margin),
            self.max + DVec2::splat(margin),
        )
    }

    /// Euclidean distance from `p` to the rectangle; 0 inside and on the boundary.
    #[must_use]
    pub fn distance_to(&self, p: DVec2) -> f64 {
        let d = (self.min - p).max(p - self.max).max(DVec2::ZERO);
        d.length()
    }

    /// The smallest rectangle holding both.
    #[must_use]
    pub fn union(&self, other: &Self) -> Self {
        Self::new(self.min.min(other.min), self.max.max(other.max))
    }

    /// Width and height of the intersection; a component ≤ 0 means the rectangles are apart
    /// along that axis (0: touching).
    #[must_use]
    pub fn overlap(&self, other: &Self) -> DVec2 {
        self.max.min(other.max) - self.min.max(other.min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit() -> Rect {
        Rect::new(DVec2::ZERO, DVec2::ONE)
    }

    #[test]
    fn contains_is_closed_and_rejects_nan() {
        let r = unit();
        assert!(r.contains(DVec2::ZERO));
        assert!(r.contains(DVec2::ONE));
        assert!(!r.contains(DVec2::new(1.0 + 1e-12, 0.5)));
        assert!(!r.contains(DVec2::new(f64::NAN, 0.5)));
    }

    #[test]
    fn distance_to_corner_region_is_euclidean() {
        // (4, 5) is 3 right of and 4 below the corner (1, 1): a 3-4-5 triangle.
        assert_eq!(unit().distance_to(DVec2::new(4.0, 5.0)), 5.0);
        assert_eq!(unit().distance_to(DVec2::new(0.5, -2.0)), 2.0);
        assert_eq!(unit().distance_to(DVec2::new(0.5, 0.5)), 0.0);
    }

    #[test]
    fn overlap_of_touching_rects_is_zero_wide() {
        let right = Rect::new(DVec2::new(1.0, 0.0), DVec2::new(2.0, 1.0));
        assert_eq!(unit().overlap(&right), DVec2::new(0.0, 1.0));
        let far = Rect::new(DVec2::new(3.0, 0.0), DVec2::new(4.0, 1.0));
        assert_eq!(unit().overlap(&far).x, -2.0);
    }

    #[test]
    fn union_and_expand() {
        let far = Rect::new(DVec2::new(3.0, -1.0), DVec2::new(4.0, 0.5));
        let u = unit().union(&far);
        assert_eq!(u, Rect::new(DVec2::new(0.0, -1.0), DVec2::new(4.0, 1.0)));
        assert_eq!(unit().expand(0.5).size(), DVec2::splat(2.0));
        assert_eq!(u.center(), DVec2::new(2.0, 0.0));
    }
}
