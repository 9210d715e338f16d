//! Closest point on an ellipse and distance to the filled ellipse (DESIGN.md §5), in f64 (the CPU
//! twin, the test oracle: this file, four lanes at once in `lanes.rs`) and in f32 (`mirror.rs`, an
//! op-for-op mirror of `shaders/roi/ellipse.wgsl`).
//!
//! The ellipse is `(x/a)² + (y/b)² = 1`, centred at the origin, axis-aligned, with any
//! `a, b ≥ 0` (`b = 0` or `a = 0` is a segment, `a = b` a circle, `a = b = 0` a point); the query
//! point may lie in any quadrant.
//!
//! # Method
//!
//! DESIGN.md §5 records what was measured: Eberly's bisection is slow and breaks at the extremes
//! (overflow near 1e154, zeros for subnormal inputs, an infinite closest point for inside points
//! near the major axis because `s + 1` cancels); trig-free and angle-Newton methods go wrong for
//! eccentric ellipses; quartic closed forms break in f32. What worked, and what this module does:
//!
//! 1. Reduce to the first quadrant by symmetry (signs are restored at the end) and orient the
//!    major axis along x (swap back at the end).
//! 2. Scale by the major semi-axis `a`: `e = b/a ≤ 1`, `(p, q) = (x, y)/a`.
//! 3. The Lagrange condition gives the closest point `X = p/(t + 1)`, `Y = e²q/(t + e²)` with `t`
//!    the root of `(p/(t+1))² + (eq/(t+e²))² = 1` right of the pole `−e²`. We solve for the
//!    pole-relative unknown `w = t + e²` (DESIGN.md §5's `u = s + 1` times the constant `e²`,
//!    which avoids `e²` under- and overflow): the secular function is
//!    `S(w) = A² + B²` with `A = p/(w + c)`, `B = eq/w`, `c = 1 − e² = (1−e)(1+e)`, and no sum in
//!    it cancels. `Y = e·B`, so the closest point is `(x/(w + c), b·B)` in the caller's units.
//! 4. `h(w) = S(w)^(−1/2)` is increasing and concave for `w > 0` (Cauchy–Schwarz:
//!    `h'' ∝ (Σ A_i² r_i³)² − S·Σ A_i² r_i⁴ ≤ 0`), so the zero of its tangent at *any* `w` is a
//!    lower bound of the root: Newton on `h(w) = 1` never overshoots once it is left of the root,
//!    and climbs monotonically. The certified bracket is `w₀ = max(eq, hypot(p, eq) − c)` (each
//!    makes one term of `S` reach 1 by itself) and `hypot(p, eq)` (`w + c ≥ w`).
//! 5. The first evaluation is at the Lagrange multiplier of the radial projection of the point
//!    onto the ellipse when it lies inside the bracket (else at `w₀`); from either side, the
//!    Newton step lands on a lower bound.
//! 6. Newton alone crawls where one term of `S` hardly varies near the root (near a vertex of an
//!    eccentric ellipse: 16 steps on the hard cases). There, freezing that term at its value at
//!    the first point and solving for the other gives an estimate from above that is nearly
//!    exact. If the first Newton step covers less than a quarter of the way to it, the solver
//!    evaluates there once, and Newton goes on from the best lower bound.
//! 7. Newton stops when its step is below `4ε·w`; when the step predicts, from the last two steps
//!    of quadratic convergence (`K ≈ step/prev²`, only once `prev ≤ 1e-3`), an error below `ε/4`;
//!    when `S ≤ 1` at an iterate (the root reached, or passed by rounding only); or when rounding
//!    stalls the climb. Steps 5–7 took the hard-case set from mean 2.05 / max 16 evaluations to
//!    mean 1.44 / max [`MEASURED_MAX_NEWTON_F64`], and the 4K grid of `examples/ellipse_bench.rs`
//!    from 4.14 to 3.26, with the same accuracy.
//! 8. If Newton has not stopped after [`MAX_NEWTON_STEPS_F64`] steps (never on the hard-case set),
//!    bisection on the bit pattern of `w` inside the bracket finishes in at most 63 steps (31 in
//!    f32), because the bit patterns of two positive finite floats differ by less than 2⁶³ (2³¹).
//!
//! The solver runs [`LANES`] queries on the same ellipse side by side in `f64x4` operations
//! (`EllipseSolver::closest_hinted_lanes`; a single query is lane 0): branches become per-lane
//! selects, every lane does exactly the IEEE operations it would do alone, and a lane that has
//! stopped keeps its root, so lanes never change each other's answers. The CPU DGI passes the
//! pixels of four rows, whose division chains then overlap.
//!
//! Step 3's closed forms need `eq > 0`. When `eq == 0` (the point is on the major axis, or `e·q`
//! underflowed, or the ellipse is a segment) the answer is closed-form: outside the evolute
//! (`p > c`) the vertex `(a, 0)`; inside it (`p ≤ c`), `X = p/c`, `Y = e·√(1 − X²)`.
//!
//! When `eq` is tiny but not zero, inside the evolute's span, the root is `w ≈ eq/√(1 − X²)`:
//! subnormal when `eq` is, with too few bits for `Y = e·B = e·eq/w` (two subnormal ulps over
//! three gave `B = 2/3` and a point 18 % off the ellipse). Where the root is subnormal, `Y` comes
//! from the ellipse equation, `e·√(1 − X²)`, as in the closed form: there `w ≪ c`, so `X` is
//! exact to rounding. The f32 solver does the same below `f32::MIN_POSITIVE` (a GPU may flush
//! the root to zero, which the same branch covers). The DGI never reaches this case: it asks for
//! the curve distance only of points outside the filled conic (its inside test comes first, on
//! both backends), and outside the root exceeds `e²` (the Lagrange multiplier is positive), so a
//! subnormal root there needs `e < 1.5e-154` (f64) or `e < 1.1e-19` (f32): a segment, for which
//! `Y ≤ b` keeps the error below the absolute bound anyway.
//!
//! # Where the closest point is not unique
//!
//! On the part of the major axis inside the evolute (`|x| < (a² − b²)/a` with `y = 0` when
//! `a > b`), the two points `(X, ±Y)` are equally close. We return the one on the **positive side
//! of the minor axis** (`y > 0` when `a ≥ b`, `x > 0` when `b > a`); a query coordinate of `−0.0`
//! counts as positive. The centre of a circle returns `(0, r)`.
//!
//! # Range
//!
//! Every finite input gives a finite, non-NaN result, except that the distance is `+∞` when it
//! exceeds `f64::MAX`. Points farther than 2¹⁰⁰⁰·a (2¹⁰⁰·a in f32), where `x/a` may overflow, take
//! the far-field closest point (the point whose normal is parallel to the query direction),
//! whose error against the true closest point is below `a·(a/b)·2⁻¹⁰⁰⁰`. Negative semi-axes are
//! taken by absolute value; NaN inputs give NaN outputs.

mod lanes;
mod mirror;
#[cfg(test)]
mod tests;

use glam::DVec2;
use wide::f64x4;

use lanes::first_quadrant_lanes;
pub use lanes::{CurveLanes, EllipseSolver, LANES, lane_mask};
pub use mirror::{
    ClosestPointF32, F32_DISTANCE_BOUND, MAX_BISECTION_STEPS_F32, MAX_ITERATIONS_F32,
    MAX_NEWTON_STEPS_F32, WGSL, closest_point_on_ellipse_f32, distance_to_filled_ellipse_f32,
};

/// Newton steps before the bisection fallback (f64). Measured on the hard-case set: at most
/// [`MEASURED_MAX_NEWTON_F64`] were needed.
pub const MAX_NEWTON_STEPS_F64: u32 = 16;
/// Bit-pattern bisection steps that always suffice in f64 (bit patterns differ by < 2⁶³).
pub const MAX_BISECTION_STEPS_F64: u32 = 63;
/// The stated bound on [`ClosestPoint::iterations`] for the f64 solver: every input terminates
/// within it (each iteration is one evaluation of the secular function).
pub const MAX_ITERATIONS_F64: u32 = MAX_NEWTON_STEPS_F64 + MAX_BISECTION_STEPS_F64;
/// The largest Newton step count seen on `tests/data/ellipse_hard_cases.csv`; the hard-case test
/// checks it, so a change to the method that makes convergence slower fails loudly.
pub const MEASURED_MAX_NEWTON_F64: u32 = 8;

/// Newton stops once a step is below this fraction of `w`: the next step would be rounding noise.
const NEWTON_TOL_F64: f64 = 4.0 * f64::EPSILON;
const EPS_F64: f64 = f64::EPSILON;
/// 2¹⁰⁰⁰: beyond this, `x/a` may overflow and the far-field point is exact to rounding.
const FAR_F64: f64 = 1.071_508_607_186_267_3e301;

/// The closest point on the ellipse curve to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPoint {
    /// Euclidean distance from the query point to [`Self::point`].
    pub distance: f64,
    /// The closest point on the curve (see the module docs for the non-unique case).
    pub point: DVec2,
    /// Evaluations of the secular function; at most [`MAX_ITERATIONS_F64`].
    pub iterations: u32,
    /// Whether the query point lies in the filled ellipse (boundary included).
    pub inside: bool,
}

/// The closest point on the ellipse `(x/a)² + (y/b)² = 1` (the curve) to `p`.
#[must_use]
pub fn closest_point_on_ellipse(a: f64, b: f64, p: DVec2) -> ClosestPoint {
    closest_point_on_ellipse_hinted(a, b, p, f64::NAN).0
}

/// [`closest_point_on_ellipse`] started from `hint`, the secular root returned for a nearby
/// query on the same ellipse (NaN: no hint), and that query's own root (NaN where the answer
/// was closed-form). Neighbouring DGI pixels have nearby roots: Newton from the hint lands on a
/// certified lower bound after one step (the concavity argument of the module docs holds from
/// any start), and the hint's step counts towards the quadratic-convergence stop, so a close
/// hint converges in about two evaluations instead of three or four. A hint outside the
/// certified bracket is ignored; the bisection fallback and the iteration bound are unchanged.
#[must_use]
pub fn closest_point_on_ellipse_hinted(a: f64, b: f64, p: DVec2, hint: f64) -> (ClosestPoint, f64) {
    let (a, b) = (a.abs(), b.abs());
    let inside = inside_filled(a, b, p);
    // Orient the major axis along x; the solver needs a ≥ b.
    let swap = b > a;
    let (major, minor, x, y) = if swap {
        (b, a, p.y.abs(), p.x.abs())
    } else {
        (a, b, p.x.abs(), p.y.abs())
    };
    let (cx, cy, iterations, root) = first_quadrant_f64(major, minor, x, y, hint);
    let distance = hypot(x - cx, y - cy);
    let (cx, cy) = if swap { (cy, cx) } else { (cx, cy) };
    // `< 0.0` keeps −0.0 on the positive side: the documented choice for the non-unique case.
    let point = DVec2::new(
        if p.x < 0.0 { -cx } else { cx },
        if p.y < 0.0 { -cy } else { cy },
    );
    (
        ClosestPoint {
            distance,
            point,
            iterations,
            inside,
        },
        root,
    )
}

/// Distance from `p` to the filled ellipse: 0 inside or on the boundary, else the distance to the
/// curve. The inside test runs first, so inside points cost one division per axis.
#[must_use]
pub fn distance_to_filled_ellipse(a: f64, b: f64, p: DVec2) -> f64 {
    if inside_filled(a.abs(), b.abs(), p) {
        0.0
    } else {
        closest_point_on_ellipse(a, b, p).distance
    }
}

/// Whether `p` lies in the filled ellipse with semi-axes `a, b ≥ 0` (boundary included). A
/// degenerate ellipse is its segment (or point).
fn inside_filled(a: f64, b: f64, p: DVec2) -> bool {
    if a == 0.0 || b == 0.0 {
        return if a == 0.0 {
            p.x == 0.0 && p.y.abs() <= b
        } else {
            p.y == 0.0 && p.x.abs() <= a
        };
    }
    // Overflow gives +∞ (outside), underflow 0: both are the right answer.
    let (u, v) = (p.x / a, p.y / b);
    u * u + v * v <= 1.0
}

/// Closest point in the first quadrant for `a ≥ b ≥ 0`, `x, y ≥ 0`, in the caller's units, and
/// the iteration count.
fn first_quadrant_f64(a: f64, b: f64, x: f64, y: f64, hint: f64) -> (f64, f64, u32, f64) {
    let e = b / a;
    // 1 − e² without the cancellation of `1.0 - e * e` near circles.
    let c = (1.0 - e) * (1.0 + e);
    first_quadrant_core(a, b, e, c, x, y, hint)
}

/// [`first_quadrant_f64`] with `e = b/a` and `c = (1 − e)(1 + e)` given (hoisted by
/// [`EllipseSolver`]; NaN when `a = 0`, which returns before using them): lane 0 of
/// [`first_quadrant_lanes`].
#[inline]
fn first_quadrant_core(
    a: f64,
    b: f64,
    e: f64,
    c: f64,
    x: f64,
    y: f64,
    hint: f64,
) -> (f64, f64, u32, f64) {
    let first = |v: f64, rest: f64| f64x4::new([v, rest, rest, rest]);
    let q = first_quadrant_lanes(
        lanes::Axes { a, b, e, c },
        first(x, 0.0),
        first(y, 0.0),
        first(hint, f64::NAN),
        lane_mask([true, false, false, false]),
    );
    (
        q.x.to_array()[0],
        q.y.to_array()[0],
        q.iterations[0],
        q.root.to_array()[0],
    )
}

/// The point whose outward normal is parallel to `(x, y)`: the closest point to within
/// `a·(a/b)·(a/|p|)`, used when `|p|/a > 2¹⁰⁰⁰` so that the error is below rounding.
fn far_field_f64(a: f64, e: f64, b: f64, x: f64, y: f64) -> (f64, f64, u32) {
    let m = x.max(y);
    let (ux, uy) = (x / m, y / m);
    let n = hypot(ux, e * uy);
    if n.is_nan() || n <= 0.0 {
        // A segment seen broadside: its midpoint.
        return (0.0, 0.0, 0);
    }
    (a * (ux / n), b * (e * uy / n), 0)
}

/// `hypot` without overflow or underflow, within ~1 ulp, and several times faster than libm's
/// correctly rounded `f64::hypot`, which took 17 % of the CPU DGI's time (perf, HORNET 60°).
/// Where x² + y² lies in [2⁻⁹⁰⁰, 2⁹⁰⁰] (both squares far from overflow, and any square that
/// rounds into the subnormals below 2⁻¹²² of the sum) it is √(x² + y²) directly; elsewhere
/// max·√(1 + (min/max)²). The direct form drops a division and a multiplication from the
/// solver's critical path (perf at 60°: the division and square root chain of the scaled form
/// took 13 % of the solver's time and 30 % of the rest of the per-pixel path).
#[inline]
fn hypot(x: f64, y: f64) -> f64 {
    let sq = x * x + y * y;
    if (HYPOT_DIRECT_MIN..=HYPOT_DIRECT_MAX).contains(&sq) {
        return sq.sqrt();
    }
    let (ax, ay) = (x.abs(), y.abs());
    let (hi, lo) = if ax >= ay { (ax, ay) } else { (ay, ax) };
    if hi == 0.0 || hi.is_infinite() {
        return hi + lo;
    }
    let r = lo / hi;
    hi * (1.0 + r * r).sqrt()
}

/// 2⁻⁹⁰⁰ and 2⁹⁰⁰: the range of x² + y² where [`hypot`] takes the square root directly.
const HYPOT_DIRECT_MIN: f64 = 1.183_052_186_166_774_7e-271;
const HYPOT_DIRECT_MAX: f64 = 8.452_712_498_170_644e270;
