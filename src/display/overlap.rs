//! Whether two tiles overlap in the room: a wall whose panels pass through or lie on top of each
//! other (a generator with a 90° yaw step and seven columns folds column 4 onto column 0; two
//! explicit tiles with the same corners) cannot be built, and a ray would meet two tiles at once.
//!
//! Each tile is its canvas rectangle (active area and bezels) mapped into the room, shrunk by
//! [`OVERLAP_3D_TOL_M`] on every side so that neighbours meeting along a hinge or a seam only
//! touch. Two such rectangles overlap when they are coplanar (within the tolerance) and their
//! interiors intersect, or when one crosses the other's plane inside it.

use glam::{DVec2, DVec3};

use super::rect::Rect;
use super::tile::Tile;

/// Metres each tile is shrunk by, and the distance within which two planes count as one: the
/// same millimetre as [`super::SEAM_TOL_M`], far below any real overlap (a panel is
/// 100 mm or more) and above the rounding of corners written to the millimetre.
pub const OVERLAP_3D_TOL_M: f64 = 1e-3;

/// One tile's shrunk rectangle in the room: a corner and its two edge vectors.
struct Panel {
    origin: DVec3,
    u: DVec3,
    v: DVec3,
    normal: DVec3,
}

impl Panel {
    /// `None` when the shrunk rectangle is empty (a tile thinner than the tolerance).
    fn new(tile: &Tile, rect: &Rect, pitch_m: f64) -> Option<Self> {
        let r = rect.expand(-OVERLAP_3D_TOL_M / pitch_m);
        if !(r.size().x > 0.0 && r.size().y > 0.0) {
            return None;
        }
        let [tl, tr, _, bl] = r.corners().map(|c| tile.canvas_to_point(c));
        Some(Self {
            origin: tl,
            u: tr - tl,
            v: bl - tl,
            normal: tile.normal(),
        })
    }

    fn corners(&self) -> [DVec3; 4] {
        [
            self.origin,
            self.origin + self.u,
            self.origin + self.u + self.v,
            self.origin + self.v,
        ]
    }

    /// Coordinates of `p` in the panel's (u, v) frame, [0, 1]² on the panel.
    fn local(&self, p: DVec3) -> DVec2 {
        let d = p - self.origin;
        let (uu, uv, vv) = (self.u.dot(self.u), self.u.dot(self.v), self.v.dot(self.v));
        let (du, dv) = (d.dot(self.u), d.dot(self.v));
        let det = uu * vv - uv * uv;
        DVec2::new((vv * du - uv * dv) / det, (uu * dv - uv * du) / det)
    }

    fn centre(&self) -> DVec3 {
        self.origin + (self.u + self.v) * 0.5
    }

    fn radius(&self) -> f64 {
        (self.u + self.v).length() * 0.5
    }
}

/// Whether tiles `a` and `b` (with their canvas rectangles at the model pitch) overlap in the
/// room.
#[must_use]
pub fn tiles_overlap(a: &Tile, ra: &Rect, b: &Tile, rb: &Rect, pitch_m: f64) -> bool {
    let (Some(pa), Some(pb)) = (Panel::new(a, ra, pitch_m), Panel::new(b, rb, pitch_m)) else {
        return false;
    };
    if pa.centre().distance(pb.centre()) > pa.radius() + pb.radius() {
        return false;
    }
    let s = pb.corners().map(|q| pa.normal.dot(q - pa.origin));
    if s.iter().all(|&d| d > OVERLAP_3D_TOL_M) || s.iter().all(|&d| d < -OVERLAP_3D_TOL_M) {
        return false;
    }
    if pa.normal.cross(pb.normal).length() < 1e-9 {
        // Parallel and within the tolerance of one plane: the rectangles overlap in that plane.
        let quad = pb.corners().map(|q| pa.local(q));
        let unit = [DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
        return convex_quads_overlap(&unit, &quad);
    }
    // B meets A's plane along a segment (B is convex): clip it to A.
    let corners = pb.corners();
    let mut points = Vec::with_capacity(4);
    for i in 0..4 {
        let j = (i + 1) % 4;
        let (si, sj) = (s[i], s[j]);
        if si == 0.0 {
            points.push(corners[i]);
        }
        if (si < 0.0 && sj > 0.0) || (si > 0.0 && sj < 0.0) {
            points.push(corners[i] + (corners[j] - corners[i]) * (si / (si - sj)));
        }
    }
    let mut best: Option<(DVec3, DVec3)> = None;
    for (k, &p) in points.iter().enumerate() {
        for &q in &points[k..] {
            if best.is_none_or(|(a, b)| p.distance(q) > a.distance(b)) {
                best = Some((p, q));
            }
        }
    }
    let Some((p, q)) = best else {
        return false;
    };
    segment_crosses_unit_square(pa.local(p), pa.local(q))
}

/// Whether two convex quadrilaterals (corners in order) share interior points: no separating
/// axis among their edge normals.
fn convex_quads_overlap(a: &[DVec2; 4], b: &[DVec2; 4]) -> bool {
    let separated_by = |edges: &[DVec2; 4]| {
        (0..4).any(|i| {
            let e = edges[(i + 1) % 4] - edges[i];
            let axis = DVec2::new(-e.y, e.x);
            let (amin, amax) = extent(a, axis);
            let (bmin, bmax) = extent(b, axis);
            // Touching (or nearly) is not overlapping.
            let eps = 1e-9 * axis.length();
            amax <= bmin + eps || bmax <= amin + eps
        })
    };
    !(separated_by(a) || separated_by(b))
}

fn extent(quad: &[DVec2; 4], axis: DVec2) -> (f64, f64) {
    quad.iter()
        .map(|p| p.dot(axis))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), d| {
            (lo.min(d), hi.max(d))
        })
}

/// Whether the segment p–q passes through the open unit square (Liang–Barsky clipping).
fn segment_crosses_unit_square(p: DVec2, q: DVec2) -> bool {
    let d = q - p;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (start, delta) in [(p.x, d.x), (p.y, d.y)] {
        for (num, den) in [(start, -delta), (1.0 - start, delta)] {
            // Inside where num + t·(−den)… written as the classic p·t ≤ q form.
            if den == 0.0 {
                if num <= 0.0 {
                    return false;
                }
            } else {
                let t = num / den;
                if den < 0.0 {
                    t0 = t0.max(t);
                } else {
                    t1 = t1.min(t);
                }
            }
        }
    }
    // A segment of positive length inside (a single touching point is not an overlap).
    t1 - t0 > 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_segment_through_the_square_crosses_it_and_one_beside_it_does_not() {
        let s = |a: [f64; 2], b: [f64; 2]| {
            segment_crosses_unit_square(DVec2::from_array(a), DVec2::from_array(b))
        };
        assert!(s([-1.0, 0.5], [2.0, 0.5]));
        assert!(s([0.2, 0.2], [0.3, 0.4]), "inside entirely");
        assert!(!s([-1.0, 1.5], [2.0, 1.5]));
        assert!(!s([1.0, -1.0], [1.0, 2.0]), "along an edge only");
        assert!(!s([-1.0, -1.0], [0.0, 0.0]), "touching a corner");
    }

    #[test]
    fn quads_that_share_an_edge_do_not_overlap() {
        let unit = [DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
        let right = unit.map(|p| p + DVec2::X);
        let shifted = unit.map(|p| p + DVec2::splat(0.5));
        assert!(!convex_quads_overlap(&unit, &right));
        assert!(convex_quads_overlap(&unit, &shifted));
        assert!(convex_quads_overlap(&unit, &unit));
    }
}
