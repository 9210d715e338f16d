//! The projected ROI on one planar patch of the wall, and the exact canvas distance to it.
//!
//! A tile's plane maps canvas points affinely to room points, P(c) = P₀ + c.x·e_x + c.y·e_y, so the
//! cone inequality of DESIGN.md §4 becomes a quadratic inequality in canvas coordinates: the
//! projected region on a planar tile is the inside of a conic section. Because the forward cone
//! is convex (its opening is below 180°) and a plane section of a convex set is convex, the
//! region is convex: an ellipse, one branch of a hyperbola, or a parabola (and in the limit of a
//! plane through the apex, a wedge).
//!
//! Each conic is brought into a canonical frame (u, v) on the canvas:
//! * ellipse: (u/a)² + (v/b)² ≤ 1;
//! * hyperbola branch: v ≥ √(B² + s²u²) (B = 0 is the wedge v ≥ s|u|);
//! * parabola: v ≥ c·u².
//!
//! The distance from a canvas point to the piece of region on a tile, rect ∩ K, is exact:
//! the minimiser over a convex intersection either lies inside the rectangle (then it is the
//! minimiser over K, found by the closest-point solvers) or on one of the rectangle's edges
//! (then it is the nearest point of the edge's sub-segment inside K, found in closed form).

use glam::{DMat2, DVec2, DVec3};

pub use crate::display::Rect;

use super::cone::Cone;
use super::ellipse::{self, LANES, lane_mask};
use wide::f64x4;

/// A planar part of the display surface: canvas point c ↦ room point
/// `origin + c.x·ex + c.y·ey`, for canvas points in `rect` (a tile's active area with its
/// bezels, which lie in the tile's plane).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    pub rect: Rect,
    /// Room point of canvas point (0, 0) on this patch's plane.
    pub origin: DVec3,
    /// Room displacement per canvas pixel along x.
    pub ex: DVec3,
    /// Room displacement per canvas pixel along y.
    pub ey: DVec3,
}

impl Patch {
    #[must_use]
    pub fn point(&self, c: DVec2) -> DVec3 {
        self.origin + c.x * self.ex + c.y * self.ey
    }
}

/// A canonical convex conic region in its own frame (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConicKind {
    /// The cone does not reach this plane on its forward side.
    Empty,
    /// (u/a)² + (v/b)² ≤ 1.
    Ellipse { a: f64, b: f64 },
    /// v ≥ √(B² + s²u²); `b2` is B².
    Hyperbola { b2: f64, s: f64 },
    /// v ≥ c·u².
    Parabola { c: f64 },
}

/// A conic region placed on the canvas: local (u, v) = ((c − origin)·axis_u, (c − origin)·axis_v)
/// with axis_v = axis_u rotated by +90° (canvas x → y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacedConic {
    pub kind: ConicKind,
    pub origin: DVec2,
    pub axis_u: DVec2,
}

/// |λ_small| / λ_large below which a section is treated as a parabola. An estimate, not a
/// measurement: for a parabola-like section with focal scale f (~1000 px on a wall tile) the
/// centred form puts the centre about f/ratio away, so in f64 it loses ~1e-16·f/ratio ≈ 1e-4 px
/// to cancellation at this ratio, while dropping the λ_small term moves the boundary by about
/// ratio·(patch size)²/f ≈ 1e-6 px over a 2000 px patch. Exact tangency (a generator parallel to
/// the tile) is the case that needs it; the `grazing_cone_…` and `parabola_at_exact_tangency`
/// tests cover both sides.
pub const PARABOLA_RATIO: f64 = 1e-9;

impl PlacedConic {
    #[must_use]
    pub fn axis_v(&self) -> DVec2 {
        self.axis_u.perp()
    }

    #[must_use]
    pub fn to_local(&self, c: DVec2) -> DVec2 {
        let d = c - self.origin;
        DVec2::new(d.dot(self.axis_u), d.dot(self.axis_v()))
    }

    #[must_use]
    pub fn to_canvas(&self, l: DVec2) -> DVec2 {
        self.origin + l.x * self.axis_u + l.y * self.axis_v()
    }

    /// Whether a local point lies in the region.
    #[must_use]
    pub fn contains_local(&self, l: DVec2) -> bool {
        match self.kind {
            ConicKind::Empty => false,
            ConicKind::Ellipse { a, b } => {
                // Degenerate (segment or point) ellipses contain only their own points.
                if a == 0.0 || b == 0.0 {
                    return (a == 0.0 && l.x == 0.0 && l.y.abs() <= b)
                        || (b == 0.0 && l.y == 0.0 && l.x.abs() <= a);
                }
                let (s, t) = (l.x / a, l.y / b);
                s * s + t * t <= 1.0
            }
            ConicKind::Hyperbola { b2, s } => l.y >= 0.0 && l.y * l.y >= b2 + (s * l.x).powi(2),
            ConicKind::Parabola { c } => l.y >= c * l.x * l.x,
        }
    }

    /// The distance from a local point to the region and the nearest region point (local), or
    /// `None` when the region is empty.
    #[must_use]
    pub fn closest_local(&self, l: DVec2) -> Option<(f64, DVec2)> {
        match self.kind {
            ConicKind::Empty => None,
            ConicKind::Ellipse { a, b } => {
                if self.contains_local(l) {
                    return Some((0.0, l));
                }
                let cp = ellipse::closest_point_on_ellipse(a, b, l);
                Some((cp.distance, cp.point))
            }
            ConicKind::Hyperbola { b2, s } => {
                let f = Even {
                    f: |u: f64| (b2 + (s * u).powi(2)).sqrt(),
                    df: |u: f64| {
                        let r = (b2 + (s * u).powi(2)).sqrt();
                        if r == 0.0 { s } else { s * s * u / r }
                    },
                    d2f: |u: f64| {
                        let r2 = b2 + (s * u).powi(2);
                        if r2 == 0.0 {
                            0.0
                        } else {
                            s * s * b2 / (r2 * r2.sqrt())
                        }
                    },
                };
                Some(closest_on_epigraph(&f, l))
            }
            ConicKind::Parabola { c } => {
                let f = Even {
                    f: |u: f64| c * u * u,
                    df: |u: f64| 2.0 * c * u,
                    d2f: |_| 2.0 * c,
                };
                Some(closest_on_epigraph(&f, l))
            }
        }
    }
}

/// An even convex function on ℝ, increasing on u ≥ 0, with its first two derivatives.
struct Even<F, D, D2> {
    f: F,
    df: D,
    d2f: D2,
}

/// Maximum iterations of the safeguarded Newton iteration in `closest_on_epigraph`. Bisection
/// alone halves the bracket, so 200 steps reduce any f64 bracket below one ulp; Newton usually
/// stops after 3–8 (measured on the tests' cases).
pub const EPIGRAPH_MAX_ITERATIONS: u32 = 200;

/// Distance and nearest point from `p` to the epigraph {v ≥ f(u)} of an even convex `f`.
///
/// For p outside, the nearest point is (u*, f(u*)) with u* the root of
/// h(u) = (u − p_u) + (f(u) − p_v)·f′(u) on the bracket [u_lo, |p_u|], where u_lo is where
/// f reaches p_v (or 0). On that bracket f − p_v ≥ 0 and f″ ≥ 0, so
/// h′ = 1 + f′² + (f − p_v)·f″ > 0: h is strictly increasing, h(u_lo) ≤ 0 ≤ h(|p_u|), and the
/// root is unique. Newton steps that leave the bracket are replaced by bisection.
fn closest_on_epigraph<F, D, D2>(f: &Even<F, D, D2>, p: DVec2) -> (f64, DVec2)
where
    F: Fn(f64) -> f64,
    D: Fn(f64) -> f64,
    D2: Fn(f64) -> f64,
{
    let (pu, pv) = (p.x.abs(), p.y);
    if pv >= (f.f)(pu) {
        return (0.0, p);
    }
    let h = |u: f64| (u - pu) + ((f.f)(u) - pv) * (f.df)(u);
    // u_lo: f(u_lo) = p_v when p_v > f(0); found by bisection on [0, pu] (f increasing there).
    let mut lo = 0.0;
    if pv > (f.f)(0.0) {
        let (mut a, mut b) = (0.0, pu);
        for _ in 0..EPIGRAPH_MAX_ITERATIONS {
            let m = 0.5 * (a + b);
            if m <= a || m >= b {
                break;
            }
            if (f.f)(m) < pv { a = m } else { b = m }
        }
        lo = a;
    }
    let mut hi = pu;
    let mut u = lo;
    for _ in 0..EPIGRAPH_MAX_ITERATIONS {
        let hu = h(u);
        if hu == 0.0 {
            break;
        }
        if hu < 0.0 {
            lo = u
        } else {
            hi = u
        }
        let dh = 1.0 + (f.df)(u).powi(2) + ((f.f)(u) - pv).max(0.0) * (f.d2f)(u);
        let mut next = u - hu / dh;
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if next == u || hi - lo <= f64::EPSILON * hi.abs().max(f64::MIN_POSITIVE) {
            u = next;
            break;
        }
        u = next;
    }
    let q = DVec2::new(u.copysign(p.x), (f.f)(u));
    ((q - DVec2::new(p.x, p.y)).length(), q)
}

/// The region of `cone` on the plane of `patch`, in canvas coordinates (unbounded: the patch's
/// rectangle is applied by [`Piece`]).
#[must_use]
pub fn section(cone: &Cone, patch: &Patch) -> PlacedConic {
    // Work relative to the rectangle's centre so the numbers stay of the patch's size.
    let c0 = patch.rect.center();
    let w0 = patch.point(c0) - cone.apex;
    let (th, tv) = (cone.tan_h, cone.tan_v);
    let a_r = DVec2::new(patch.ex.dot(cone.right), patch.ey.dot(cone.right)) / th;
    let a_u = DVec2::new(patch.ex.dot(cone.up), patch.ey.dot(cone.up)) / tv;
    let a_d = DVec2::new(patch.ex.dot(cone.axis), patch.ey.dot(cone.axis));
    let (r, u, d) = (
        w0.dot(cone.right) / th,
        w0.dot(cone.up) / tv,
        w0.dot(cone.axis),
    );
    // Q(q) = qᵀMq + 2gᵀq + k with q = c − c0.
    let outer = |v: DVec2| DMat2::from_cols(v * v.x, v * v.y);
    let m = outer(a_r) + outer(a_u) - outer(a_d);
    let g = r * a_r + u * a_u - d * a_d;
    let k = r * r + u * u - d * d;
    // The linear form (P − O)·D in local coordinates: forward-nappe test.
    let l_d = |q: DVec2| d + a_d.dot(q);
    let empty = PlacedConic {
        kind: ConicKind::Empty,
        origin: c0,
        axis_u: DVec2::X,
    };

    // Eigen-decomposition of the symmetric 2×2 M: e1 for the larger eigenvalue.
    let (m00, m01, m11) = (m.x_axis.x, m.y_axis.x, m.y_axis.y);
    let theta = 0.5 * (2.0 * m01).atan2(m00 - m11);
    let e1 = DVec2::new(theta.cos(), theta.sin());
    let e2 = e1.perp();
    let l1 = e1.dot(m * e1);
    let l2 = e2.dot(m * e2);
    let (h1, h2) = (g.dot(e1), g.dot(e2));
    if !(l1 > 0.0) || !l1.is_finite() || !k.is_finite() {
        // Never happens for a real cone (the plane section of a cone of signature (+,+,−) has a
        // positive direction); guards against non-finite input.
        return empty;
    }
    let scale = l1;
    if l2.abs() <= PARABOLA_RATIO * scale {
        // Parabola: λ1 z1² + 2h1 z1 + 2h2 z2 + k ≤ 0.
        if h2 == 0.0 {
            return empty; // plane through the apex and parallel to a generator: a line at most
        }
        let z1c = -h1 / l1;
        let kk = k - h1 * h1 / l1;
        let sgn = -h2.signum(); // the region lies towards z2·sgn → +∞
        let vertex = c0 + z1c * e1 + (-kk / (2.0 * h2)) * e2;
        let axis_v = e2 * sgn;
        let placed = PlacedConic {
            kind: ConicKind::Parabola {
                c: l1 / (2.0 * h2.abs()),
            },
            origin: vertex,
            axis_u: -axis_v.perp(),
        };
        // A point a little inside along the axis must be on the forward nappe.
        let probe = vertex + axis_v - c0;
        return if l_d(probe) > 0.0 { placed } else { empty };
    }
    // Centred forms: Q = λ1 Z1² + λ2 Z2² + k', Z = z − z0.
    let z0 = DVec2::new(-h1 / l1, -h2 / l2);
    let centre = c0 + z0.x * e1 + z0.y * e2;
    let kk = k - h1 * h1 / l1 - h2 * h2 / l2;
    if l2 > 0.0 {
        if !(kk < 0.0) {
            return empty;
        }
        if l_d(centre - c0) <= 0.0 {
            return empty; // the ellipse is the backward nappe's
        }
        PlacedConic {
            kind: ConicKind::Ellipse {
                a: (-kk / l1).sqrt(),
                b: (-kk / l2).sqrt(),
            },
            origin: centre,
            axis_u: e1,
        }
    } else {
        // Hyperbola: |λ2| Z2² ≥ λ1 Z1² + k'; branches open along ±e2.
        let kk = kk.max(0.0);
        let b2 = kk / -l2;
        let s = (l1 / -l2).sqrt();
        let probe_len = b2.sqrt().max(1.0);
        let axis_v = if l_d(centre - c0 + 2.0 * probe_len * e2) > 0.0 {
            e2
        } else {
            -e2
        };
        PlacedConic {
            kind: ConicKind::Hyperbola { b2, s },
            origin: centre,
            axis_u: -axis_v.perp(),
        }
    }
}

/// A line segment on the canvas.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    pub a: DVec2,
    pub b: DVec2,
}

impl Segment {
    /// Distance from `p` to the segment and the segment's nearest point.
    #[must_use]
    pub fn closest(&self, p: DVec2) -> (f64, DVec2) {
        let ab = self.b - self.a;
        let len2 = ab.length_squared();
        let t = if len2 > 0.0 {
            ((p - self.a).dot(ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = self.a + t * ab;
        ((q - p).length(), q)
    }
}

/// The projected region on one patch: the conic clipped to the patch's rectangle, with the
/// parts of the rectangle's edges that lie inside the conic (the candidates for nearest points
/// on the rectangle's boundary).
#[derive(Clone, Debug, PartialEq)]
pub struct Piece {
    pub rect: Rect,
    pub conic: PlacedConic,
    pub edges: Vec<Segment>,
    /// A box around the piece (inside `rect`): its distance bounds the piece's from below, so
    /// pixels far from every piece skip the solvers.
    pub bounds: Rect,
}

impl Piece {
    /// Clips `conic` to `rect`. Returns `None` when the clipped region is empty.
    #[must_use]
    pub fn new(rect: Rect, conic: PlacedConic) -> Option<Self> {
        if conic.kind == ConicKind::Empty {
            return None;
        }
        let corners = rect.corners();
        let mut edges = Vec::new();
        for i in 0..4 {
            let (p0, p1) = (corners[i], corners[(i + 1) % 4]);
            if let Some((t0, t1)) = inside_interval(&conic, p0, p1) {
                let d = p1 - p0;
                edges.push(Segment {
                    a: p0 + t0 * d,
                    b: p0 + t1 * d,
                });
            }
        }
        // The region meets the rectangle iff an edge enters it or the region lies wholly inside
        // (then its nearest point to the rectangle's centre is inside the rectangle).
        let inside_somewhere = !edges.is_empty() || {
            let l = conic.to_local(rect.center());
            conic
                .closest_local(l)
                .is_some_and(|(_, q)| rect.contains(conic.to_canvas(q)))
        };
        let bounds = tight_bounds(&rect, &conic, &edges);
        inside_somewhere.then_some(Self {
            rect,
            conic,
            edges,
            bounds,
        })
    }

    /// Exact canvas distance from `c` to this piece (rect ∩ conic region).
    #[must_use]
    pub fn distance(&self, c: DVec2) -> f64 {
        self.closest(c).0
    }

    /// The per-query constants of [`Prepared::distance_hinted`], computed once.
    #[must_use]
    pub fn prepare(&self) -> Prepared<'_> {
        let solver = match self.conic.kind {
            ConicKind::Ellipse { a, b } => Some(ellipse::EllipseSolver::new(a, b)),
            _ => None,
        };
        Prepared {
            piece: self,
            axis_v: self.conic.axis_v(),
            solver,
        }
    }

    /// Exact canvas distance from `c` to this piece and the nearest point of the piece.
    #[must_use]
    pub fn closest(&self, c: DVec2) -> (f64, DVec2) {
        let mut best = (f64::INFINITY, c);
        if let Some((d, q)) = self.conic.closest_local(self.conic.to_local(c)) {
            let qc = if d == 0.0 { c } else { self.conic.to_canvas(q) };
            if self.rect.contains(qc) {
                best = (d, qc);
            }
        }
        if best.0 == 0.0 {
            return best;
        }
        for e in &self.edges {
            let (d, q) = e.closest(c);
            if d < best.0 {
                best = (d, q);
            }
        }
        best
    }
}

/// A piece with its per-query constants hoisted (the ellipse solver's, the local frame's second
/// axis), for the CPU DGI's many queries per piece.
#[derive(Clone, Copy, Debug)]
pub struct Prepared<'a> {
    pub piece: &'a Piece,
    axis_v: DVec2,
    solver: Option<ellipse::EllipseSolver>,
}

impl Prepared<'_> {
    /// [`Piece::distance`] with the ellipse solver warm-started from `root`, a nearby query's
    /// secular root ([`ellipse::closest_point_on_ellipse_hinted`]; NaN for none), which is
    /// replaced by this query's (NaN where there is none; other kinds ignore it). One inside
    /// test per query, and no edge distances when the nearest curve point lies in the
    /// rectangle: then the query is outside the convex region K, whose nearest point to it is
    /// that curve point, which lies in the piece rect ∩ K ⊆ K, so it is the piece's nearest
    /// point too (each edge, a subset of the piece, is no nearer). The results differ from
    /// [`Piece::distance`] only by the solvers' rounding (`prepared_distance_matches_the_reference`).
    #[must_use]
    #[inline]
    pub fn distance_hinted(&self, c: DVec2, root: &mut f64) -> f64 {
        let first = |v: f64| f64x4::new([v; LANES]);
        let mut roots = first(*root);
        let need = lane_mask([true, false, false, false]);
        let d = self.distance_hinted_lanes(first(c.x), first(c.y), &mut roots, need);
        *root = roots.to_array()[0];
        d.to_array()[0]
    }

    /// [`Self::distance_hinted`] for the points `(x, y)` whose `need` lane is set, each the
    /// value that point gives alone: the ellipse solves run as lanes of one
    /// [`ellipse::EllipseSolver::closest_hinted_lanes`] call. Lanes not needed answer +∞ and
    /// keep their root.
    #[must_use]
    #[inline]
    pub fn distance_hinted_lanes(
        &self,
        x: f64x4,
        y: f64x4,
        roots: &mut f64x4,
        need: f64x4,
    ) -> f64x4 {
        let p = self.piece;
        let (xs, ys) = (x.to_array(), y.to_array());
        let point = |l: usize| DVec2::new(xs[l], ys[l]);
        let edges = |c: DVec2| {
            p.edges
                .iter()
                .fold(f64::INFINITY, |d, e| d.min(e.closest(c).0))
        };
        let lanes = |m: f64x4| {
            let bits = m.to_bitmask();
            (0..LANES).filter(move |l| bits & (1 << l) != 0)
        };
        let mut out = [f64::INFINITY; LANES];
        let Some(solver) = &self.solver else {
            for l in lanes(need) {
                out[l] = p.distance(point(l));
            }
            return f64x4::new(out);
        };
        // The local frame, as `PlacedConic::to_local` computes it.
        let splat = f64x4::splat;
        let (o, u, v) = (p.conic.origin, p.conic.axis_u, self.axis_v);
        let (dx, dy) = (x - splat(o.x), y - splat(o.y));
        let (lu, lv) = (
            dx * splat(u.x) + dy * splat(u.y),
            dx * splat(v.x) + dy * splat(v.y),
        );
        let inside = match p.conic.kind {
            // `PlacedConic::contains_local` of a proper ellipse, lane by lane.
            ConicKind::Ellipse { a, b } if a != 0.0 && b != 0.0 => {
                let (s, t) = (lu / splat(a), lv / splat(b));
                (s * s + t * t).simd_le(f64x4::ONE)
            }
            _ => {
                let (lu, lv) = (lu.to_array(), lv.to_array());
                lane_mask(std::array::from_fn(|l| {
                    p.conic.contains_local(DVec2::new(lu[l], lv[l]))
                }))
            }
        };
        for l in lanes(need & inside) {
            let c = point(l);
            out[l] = if p.rect.contains(c) { 0.0 } else { edges(c) };
        }
        let solve = need & !inside;
        if solve.none() {
            return f64x4::new(out);
        }
        let curve = solver.closest_hinted_lanes(lu, lv, *roots, solve);
        *roots = solve.select(curve.root, *roots);
        // The curve point on the canvas, as `PlacedConic::to_canvas` computes it, and whether it
        // lies in the piece's rectangle (`Rect::contains`).
        let qx = splat(o.x) + curve.x * splat(u.x) + curve.y * splat(v.x);
        let qy = splat(o.y) + curve.x * splat(u.y) + curve.y * splat(v.y);
        let (lo, hi) = (p.rect.min, p.rect.max);
        let in_rect = qx.simd_ge(splat(lo.x))
            & qx.simd_le(splat(hi.x))
            & qy.simd_ge(splat(lo.y))
            & qy.simd_le(splat(hi.y));
        let distance = curve.distance.to_array();
        for l in lanes(solve & in_rect) {
            out[l] = distance[l];
        }
        for l in lanes(solve & !in_rect) {
            out[l] = edges(point(l));
        }
        f64x4::new(out)
    }
}

/// Relative padding of `tight_bounds` (times the rectangle's diagonal): covers the rounding of
/// the extreme points (a few ulps of the canvas coordinates) and the GPU's f32 copy of the box
/// (relative to the rectangle's centre: ~1e-7 of the half-size), with margin to spare.
pub const BOUNDS_PAD: f64 = 1e-6;

/// The axis-aligned box of the clipped region rect ∩ K, padded by [`BOUNDS_PAD`] and kept inside
/// `rect`.
///
/// rect ∩ K is compact and convex, so each coordinate's extremes over it are attained at extreme
/// points: either vertices of its boundary (the endpoints of the rectangle's edge pieces inside K,
/// which include the rectangle's corners inside K, and the apex of a wedge) or points of the conic
/// curve inside the rectangle where its tangent is parallel to a canvas axis. All of these are
/// collected, so the box is the region's own box (before padding), also for the unbounded
/// hyperbola and parabola pieces, which the rectangle alone would bound far less tightly.
fn tight_bounds(rect: &Rect, conic: &PlacedConic, edges: &[Segment]) -> Rect {
    let (u, v) = (conic.axis_u, conic.axis_v());
    let mut points: Vec<DVec2> = edges.iter().flat_map(|e| [e.a, e.b]).collect();
    let mut curve = |l: DVec2| {
        let c = conic.to_canvas(l);
        if c.is_finite() && rect.contains(c) {
            points.push(c);
        }
    };
    match conic.kind {
        ConicKind::Empty => return *rect,
        ConicKind::Ellipse { a, b } => {
            // Canvas coordinate k of (a cos t, b sin t) is extreme at t = atan2(b·v_k, a·u_k).
            for k in 0..2 {
                let t = (b * v[k]).atan2(a * u[k]);
                let l = DVec2::new(a * t.cos(), b * t.sin());
                curve(l);
                curve(-l);
            }
        }
        ConicKind::Hyperbola { b2, s } => {
            curve(DVec2::new(0.0, b2.sqrt()));
            // Along (w, f(w)), canvas coordinate k is extreme where f'(w) = m = −u_k / v_k;
            // f' = s²w/√(B² + s²w²) takes the value m (|m| < s) at w = m·B / (s·√(s² − m²)).
            for k in 0..2 {
                let m = -u[k] / v[k];
                if m.is_finite() && m.abs() < s {
                    let w = m * b2.sqrt() / (s * ((s - m.abs()) * (s + m.abs())).sqrt());
                    curve(DVec2::new(w, (b2 + (s * w).powi(2)).sqrt()));
                }
            }
        }
        ConicKind::Parabola { c } => {
            curve(DVec2::ZERO);
            // f' = 2cw = m at w = m / (2c).
            for k in 0..2 {
                let m = -u[k] / v[k];
                if m.is_finite() && c > 0.0 {
                    let w = m / (2.0 * c);
                    curve(DVec2::new(w, c * w * w));
                }
            }
        }
    }
    let Some(first) = points.first() else {
        return *rect;
    };
    let (mut lo, mut hi) = (*first, *first);
    for p in &points {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let pad = BOUNDS_PAD * rect.size().length().min(f64::MAX) + f64::MIN_POSITIVE;
    Rect {
        min: (lo - pad).max(rect.min),
        max: (hi + pad).min(rect.max),
    }
}

/// The parameter interval [t0, t1] ⊆ [0, 1] of the segment p0 → p1 that lies inside the region,
/// or `None`. The region is convex, so the inside set of a segment is one interval; it is found
/// from the breakpoints of the region's defining (quadratic and linear) conditions along the
/// segment, testing each sub-interval's midpoint with the exact inside predicate.
fn inside_interval(conic: &PlacedConic, p0: DVec2, p1: DVec2) -> Option<(f64, f64)> {
    let l0 = conic.to_local(p0);
    let dl = conic.to_local(p1) - l0;
    // The boundary condition along the line as α t² + β t + γ = 0.
    let (alpha, beta, gamma, lin) = match conic.kind {
        ConicKind::Empty => return None,
        ConicKind::Ellipse { a, b } => {
            if a == 0.0 || b == 0.0 {
                return None; // a segment or point region meets an edge in a point at most
            }
            let (ia, ib) = (1.0 / (a * a), 1.0 / (b * b));
            (
                dl.x * dl.x * ia + dl.y * dl.y * ib,
                2.0 * (l0.x * dl.x * ia + l0.y * dl.y * ib),
                l0.x * l0.x * ia + l0.y * l0.y * ib - 1.0,
                None,
            )
        }
        ConicKind::Hyperbola { b2, s } => {
            let s2 = s * s;
            (
                dl.y * dl.y - s2 * dl.x * dl.x,
                2.0 * (l0.y * dl.y - s2 * l0.x * dl.x),
                l0.y * l0.y - s2 * l0.x * l0.x - b2,
                // v(t) = 0 separates the two branches.
                (dl.y != 0.0).then(|| -l0.y / dl.y),
            )
        }
        ConicKind::Parabola { c } => (
            -c * dl.x * dl.x,
            dl.y - 2.0 * c * l0.x * dl.x,
            l0.y - c * l0.x * l0.x,
            None,
        ),
    };
    let mut ts = vec![0.0, 1.0];
    ts.extend(quadratic_roots(alpha, beta, gamma));
    ts.extend(lin);
    ts.retain(|t| t.is_finite() && (0.0..=1.0).contains(t));
    ts.sort_by(f64::total_cmp);
    ts.dedup();
    let mut range: Option<(f64, f64)> = None;
    for w in ts.windows(2) {
        let mid = 0.5 * (w[0] + w[1]);
        if conic.contains_local(l0 + mid * dl) {
            range = Some(match range {
                None => (w[0], w[1]),
                Some((t0, _)) => (t0, w[1]),
            });
        }
    }
    range
}

/// Real roots of α t² + β t + γ (numerically stable form; linear when α = 0).
fn quadratic_roots(alpha: f64, beta: f64, gamma: f64) -> Vec<f64> {
    if alpha == 0.0 {
        return if beta == 0.0 {
            vec![]
        } else {
            vec![-gamma / beta]
        };
    }
    let disc = beta * beta - 4.0 * alpha * gamma;
    if disc < 0.0 {
        return vec![];
    }
    let q = -0.5 * (beta + disc.sqrt().copysign(beta));
    if q == 0.0 {
        return vec![0.0];
    }
    vec![q / alpha, gamma / q]
}

#[cfg(test)]
mod tests;
