//! Closest point on an ellipse and distance to the filled ellipse (DESIGN.md §5), in f64 (the CPU
//! twin, the test oracle) and in f32 (an op-for-op mirror of `shaders/roi/ellipse.wgsl`).
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
//!    pole-relative unknown `w = t + e²` (DESIGN's `u = s + 1` times the constant `e²`, which
//!    avoids `e²` under- and overflow): the secular function is
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

use glam::DVec2;
use wide::f64x4;

/// Queries [`EllipseSolver::closest_hinted_lanes`] solves at once: one `f64x4`.
pub const LANES: usize = 4;

/// The all-ones mask of `f64x4` comparisons where `on`, zero elsewhere.
#[must_use]
#[inline]
pub fn lane_mask(on: [bool; LANES]) -> f64x4 {
    f64x4::new(on.map(|on| f64::from_bits(if on { u64::MAX } else { 0 })))
}

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

/// Newton steps before the bisection fallback in f32; equals `ELLIPSE_NEWTON_STEPS` in the WGSL.
pub const MAX_NEWTON_STEPS_F32: u32 = 16;
/// Bit-pattern bisection steps that always suffice in f32 (bit patterns differ by < 2³¹).
pub const MAX_BISECTION_STEPS_F32: u32 = 31;
/// The stated bound on the iterations of the f32 solver (CPU mirror and WGSL).
pub const MAX_ITERATIONS_F32: u32 = MAX_NEWTON_STEPS_F32 + MAX_BISECTION_STEPS_F32;

/// The f32 solver's distance error bound, relative to the scale `max(a, b, |p|)`, for inputs that
/// are f32-normal: `|d_f32 − d| ≤ F32_DISTANCE_BOUND · scale`. DESIGN.md §5 says about 1e-6 is
/// reachable. Measured on the hard-case set: 1.38e-7 for the CPU mirror and for lavapipe (a
/// couple of f32 ulps at the scale); GPU division and square root may be 2.5 ulp off instead of
/// 0.5 (WGSL spec), so 1e-6 keeps a margin of seven. At a 4K canvas scale (4000 px) this is 0.004 px.
pub const F32_DISTANCE_BOUND: f64 = 1e-6;

/// The WGSL source of the f32 solver (no bindings, no entry point): prepend or append it to a
/// kernel's source.
pub const WGSL: &str = include_str!("../../shaders/roi/ellipse.wgsl");

/// Newton stops once a step is below this fraction of `w`: the next step would be rounding noise.
const NEWTON_TOL_F64: f64 = 4.0 * f64::EPSILON;
const EPS_F64: f64 = f64::EPSILON;
/// 2¹⁰⁰⁰: beyond this, `x/a` may overflow and the far-field point is exact to rounding.
const FAR_F64: f64 = 1.071_508_607_186_267_3e301;

const NEWTON_TOL_F32: f32 = 4.0 * f32::EPSILON;
/// 2¹⁰⁰, the f32 counterpart of [`FAR_F64`]; equals `ELLIPSE_FAR` in the WGSL.
const FAR_F32: f32 = 1.267_650_6e30;

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

/// The f32 counterpart of [`ClosestPoint`], as the WGSL's `EllipseClosest` returns it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPointF32 {
    pub distance: f32,
    pub point: [f32; 2],
    /// At most [`MAX_ITERATIONS_F32`].
    pub iterations: u32,
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

/// One ellipse's solver constants, hoisted out of the per-query path for callers that query the
/// same ellipse many times (the CPU DGI: millions of pixels per piece). Every query gives results
/// bit-identical to [`closest_point_on_ellipse_hinted`] (the same operations in the same order;
/// only the per-ellipse ones are done once).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EllipseSolver {
    /// |a| and |b| as given.
    a: f64,
    b: f64,
    /// Whether the major axis is y (the solver works with it along x).
    swap: bool,
    major: f64,
    minor: f64,
    /// e = minor/major and c = 1 − e² = (1 − e)(1 + e), as `first_quadrant_f64` computes them.
    e: f64,
    c: f64,
}

impl EllipseSolver {
    #[must_use]
    pub fn new(a: f64, b: f64) -> Self {
        let (a, b) = (a.abs(), b.abs());
        let swap = b > a;
        let (major, minor) = if swap { (b, a) } else { (a, b) };
        let e = minor / major;
        Self {
            a,
            b,
            swap,
            major,
            minor,
            e,
            c: (1.0 - e) * (1.0 + e),
        }
    }

    /// Whether `p` lies in the filled ellipse (boundary included), as `inside_filled`.
    #[must_use]
    #[inline]
    pub fn contains(&self, p: DVec2) -> bool {
        inside_filled(self.a, self.b, p)
    }

    /// The distance from `p` to the ellipse curve, its closest point and this query's secular
    /// root, started from `hint`: [`closest_point_on_ellipse_hinted`] without the inside test
    /// (the caller has made it) and the iteration count.
    #[must_use]
    #[inline]
    pub fn closest_hinted(&self, p: DVec2, hint: f64) -> (f64, DVec2, f64) {
        let first = |v: f64, rest: f64| f64x4::new([v, rest, rest, rest]);
        let lanes = self.closest_hinted_lanes(
            first(p.x, 0.0),
            first(p.y, 0.0),
            first(hint, f64::NAN),
            lane_mask([true, false, false, false]),
        );
        let lane0 = |v: f64x4| v.to_array()[0];
        (
            lane0(lanes.distance),
            DVec2::new(lane0(lanes.x), lane0(lanes.y)),
            lane0(lanes.root),
        )
    }

    /// [`Self::closest_hinted`] for [`LANES`] queries at once, points `(x, y)` and hints given
    /// lane by lane, lanes whose `mask` is off skipped (they answer NaN). Each lane's answer is
    /// bit-identical to asking it alone (see `first_quadrant_lanes`).
    #[must_use]
    #[inline]
    pub fn closest_hinted_lanes(&self, x: f64x4, y: f64x4, hint: f64x4, mask: f64x4) -> CurveLanes {
        let (qx, qy) = if self.swap {
            (y.abs(), x.abs())
        } else {
            (x.abs(), y.abs())
        };
        let q = first_quadrant_lanes(self.major, self.minor, self.e, self.c, qx, qy, hint, mask);
        let distance = hypot_lanes(qx - q.x, qy - q.y, mask);
        let (cx, cy) = if self.swap { (q.y, q.x) } else { (q.x, q.y) };
        // The query's signs back, by flipping sign bits as `-c` does (`< 0` keeps −0.0 on the
        // positive side: the documented choice for the non-unique case).
        let sign = |v: f64x4| v.simd_lt(f64x4::ZERO) & f64x4::splat(-0.0);
        CurveLanes {
            distance,
            x: cx ^ sign(x),
            y: cy ^ sign(y),
            root: q.root,
        }
    }
}

/// The answers of [`EllipseSolver::closest_hinted_lanes`], lane by lane: the distance, the
/// closest point (x, y) and the secular root (NaN where the answer was closed-form, and in every
/// field of a lane that was masked off).
#[derive(Clone, Copy, Debug)]
pub struct CurveLanes {
    pub distance: f64x4,
    pub x: f64x4,
    pub y: f64x4,
    pub root: f64x4,
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
        a,
        b,
        e,
        c,
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

/// The answers of [`first_quadrant_lanes`], lane by lane: the closest point (x, y) in the
/// caller's units, the iteration count and the secular root (NaN where the answer is
/// closed-form). Lanes that were masked off hold NaN.
struct Quadrant {
    x: f64x4,
    y: f64x4,
    iterations: [u32; LANES],
    root: f64x4,
}

/// The first-quadrant solver (steps 2–8 of the module docs) for [`LANES`] queries on the same
/// ellipse at once, lanes whose `mask` is off skipped.
///
/// The lanes run side by side in `f64x4` operations (two SSE2 registers, or one AVX register).
/// That is the point: one query's Newton evaluations form a chain of dependent divisions and
/// square roots, and the DGI's warm starts chain each pixel to the one before it, so one query
/// at a time leaves the core waiting on that chain, while four independent queries (the DGI
/// passes pixels of four rows) share every instruction. Every lane does exactly the IEEE
/// operations a query alone would (division and square root are correctly rounded, no fused
/// multiply-add), branches become per-lane selects, and a lane that has stopped computes along
/// but keeps its root, so a lane's answer never depends on its neighbours
/// (`lanes_are_bit_identical_to_one_at_a_time`). The one-query solver is lane 0 of this one.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn first_quadrant_lanes(
    a: f64,
    b: f64,
    e: f64,
    c: f64,
    x: f64x4,
    y: f64x4,
    hint: f64x4,
    mask: f64x4,
) -> Quadrant {
    let nan = f64x4::splat(f64::NAN);
    if a == 0.0 {
        // The point ellipse.
        let zero = mask.select(f64x4::ZERO, nan);
        return Quadrant {
            x: zero,
            y: zero,
            iterations: [0; LANES],
            root: nan,
        };
    }
    let (one, cv) = (f64x4::ONE, f64x4::splat(c));
    let (p, q) = (x / f64x4::splat(a), y / f64x4::splat(a));
    let eq = f64x4::splat(e) * q;
    // `!(..)` also routes NaN to the far field, where it stays NaN.
    let far = !(p.simd_le(f64x4::splat(FAR_F64)) & q.simd_le(f64x4::splat(FAR_F64)));
    // Step 3's closed forms need eq > 0.
    let secular = mask & !far & !eq.simd_eq(f64x4::ZERO);
    // The certified bracket (step 4) and the start (step 5): a warm start from a nearby query's
    // root (see `closest_point_on_ellipse_hinted`) when it lies in the bracket, else the
    // Lagrange multiplier of the radial projection when that does, else the bracket's low end.
    let r = hypot_lanes(p, eq, secular);
    let mut lo = eq.max(r - cv);
    let mut hi = r;
    let hinted = secular & hint.simd_gt(lo) & hint.simd_lt(hi);
    let mut w = hinted.select(hint, lo);
    let mut probing = hinted;
    let cold = secular & !hinted;
    if cold.any() {
        let rho = hypot_lanes(p, q / f64x4::splat(e), cold);
        let (x0, b0) = (p / rho, q / (f64x4::splat(e) * rho));
        let e2 = f64x4::splat(e * e);
        let est = e2 * ((rho - one) / (e2 * x0 * x0 + b0 * b0) + one);
        let start = cold & est.simd_gt(lo) & est.simd_lt(hi);
        w = start.select(est, w);
        probing |= start;
    }
    // Steps 6–7. The updates of lo, hi and the flags in lanes that have stopped are never read
    // again.
    let mut warm = hinted;
    let mut prev_rel = one;
    let mut running = secular;
    let mut iterations = [0u32; LANES];
    let mut step_count = 0;
    while step_count < MAX_NEWTON_STEPS_F64 && running.any() {
        step_count += 1;
        let wc = w + cv;
        let (ga, gb) = (p / wc, eq / w);
        let s = ga * ga + gb * gb;
        // At the root, or past it by rounding only: Newton from below never overshoots.
        let at_root = s.simd_le(one) & !probing;
        let above = s.simd_ge(one);
        let lo1 = above.select(lo.max(w), lo);
        let hi1 = above.select(hi, hi.min(w));
        // Newton on h = S^(-1/2): Δw = (1 − h)/h' = w·S(√S − 1)/(w·(A²/(w+c) + B²/w)); the
        // denominator is written bounded (≤ 2) so that tiny w cannot overflow it. h is concave,
        // so the tangent's zero is a lower bound from either side.
        let dw = ga * ga * (w / wc) + gb * gb;
        let step = w * s * (s.sqrt() - one) / dw;
        let newton = w + step;
        let lo2 = newton.simd_gt(lo1).select(newton.min(hi1), lo1);
        // Quadratic convergence: the error left after this step is about K·step² with
        // K ≈ step/prev_step² measured from the last two steps.
        let rel = step.abs() / w;
        let converged = rel.simd_le(f64x4::splat(NEWTON_TOL_F64))
            | (!probing
                & prev_rel.simd_le(f64x4::splat(1e-3))
                & (rel * rel * rel).simd_le(f64x4::splat(0.25 * EPS_F64) * prev_rel * prev_rel));
        // Rounding stalls the climb: w is the root to working precision.
        let stalled = above & lo2.simd_le(w);
        let next = at_root.select(w, converged.select(newton.max(lo2).min(hi1), lo2));
        let first = w;
        w = running.select(next, w);
        let stepped = running.to_bitmask();
        for (l, it) in iterations.iter_mut().enumerate() {
            if stepped & (1 << l) != 0 {
                *it = step_count;
            }
        }
        running &= !(at_root | converged | stalled);
        (lo, hi) = (lo2, hi1);
        prev_rel = (probing & !warm).select(one, rel);
        (warm, probing) = (f64x4::ZERO, f64x4::ZERO);
        let probe = (running & above & !hinted).to_bitmask();
        if step_count == 1 && probe != 0 {
            // Freezing one term at its value at `first` (a lower bound: S ≥ 1 there) and solving
            // for the other gives an estimate from above that is exact where one term hardly
            // varies: near a vertex of an eccentric ellipse, where Newton alone crawls (module
            // docs, step 6). Evaluate there once when Newton's first step covers less than a
            // quarter of the way.
            let (ga, gb, first) = (ga.to_array(), gb.to_array(), first.to_array());
            let (p, eq, lo, hi) = (p.to_array(), eq.to_array(), lo.to_array(), hi.to_array());
            let (mut wl, mut probes) = (w.to_array(), probing.to_array());
            for l in (0..LANES).filter(|l| probe & (1 << l) != 0) {
                let mut frozen = hi[l];
                if ga[l] < 1.0 {
                    frozen = frozen.min(eq[l] / ((1.0 - ga[l]) * (1.0 + ga[l])).sqrt());
                }
                if gb[l] < 1.0 {
                    frozen = frozen.min(p[l] / ((1.0 - gb[l]) * (1.0 + gb[l])).sqrt() - c);
                }
                if frozen > lo[l] && lo[l] - first[l] < 0.25 * (frozen - first[l]) {
                    wl[l] = frozen;
                    probes[l] = f64::from_bits(u64::MAX);
                }
            }
            (w, probing) = (f64x4::new(wl), f64x4::new(probes));
        }
    }
    // Step 8: bisection on the bit pattern of w for lanes Newton has not finished.
    let unfinished = running.to_bitmask();
    if unfinished != 0 {
        let (p, eq, lo, hi) = (p.to_array(), eq.to_array(), lo.to_array(), hi.to_array());
        let mut wl = w.to_array();
        for l in (0..LANES).filter(|l| unfinished & (1 << l) != 0) {
            let (mut lb, mut hb) = (lo[l].to_bits(), hi[l].to_bits());
            while hb > lb + 1 {
                iterations[l] += 1;
                let mb = lb + (hb - lb) / 2;
                let wm = f64::from_bits(mb);
                let (ga, gb) = (p[l] / (wm + c), eq[l] / wm);
                if ga * ga + gb * gb >= 1.0 {
                    lb = mb;
                } else {
                    hb = mb;
                }
            }
            wl[l] = f64::from_bits(lb);
        }
        w = f64x4::new(wl);
    }
    let wc = w + cv;
    let mut y_out = f64x4::splat(b) * (eq / w);
    // A subnormal root carries few bits (inside the evolute's span on the major axis with a
    // tiny minor coordinate, w ≈ eq/√(1 − X²) is of the order of that coordinate), so eq/w
    // would be off by up to half (two subnormal ulps over three): take Y from the ellipse
    // equation instead. There w ≪ c, so X = p/(w + c) is exact to rounding, and the point is
    // on the curve; near the evolute's cusp (X → 1) it moves along the curve, which changes the
    // distance only to second order.
    let subnormal = secular & w.simd_lt(f64x4::splat(f64::MIN_POSITIVE));
    if subnormal.any() {
        let xr = p / wc;
        let on_curve = f64x4::splat(b) * ((one - xr) * (one + xr)).max(f64x4::ZERO).sqrt();
        y_out = subnormal.select(on_curve, y_out);
    }
    let mut out = Quadrant {
        x: secular.select(x / wc, nan),
        y: secular.select(y_out, nan),
        iterations,
        root: secular.select(w, nan),
    };
    // The closed forms: the far field, and points on the major axis.
    let closed = (mask & !secular).to_bitmask();
    if closed != 0 {
        let (xs, ys, p) = (x.to_array(), y.to_array(), p.to_array());
        let (mut cx, mut cy, far) = (out.x.to_array(), out.y.to_array(), far.to_bitmask());
        for l in (0..LANES).filter(|l| closed & (1 << l) != 0) {
            (cx[l], cy[l]) = if far & (1 << l) != 0 {
                let (cx, cy, _) = far_field_f64(a, e, b, xs[l], ys[l]);
                (cx, cy)
            } else if p[l] <= c {
                // Inside the evolute on the major axis (or a segment's interior): the pole root.
                let (xr, cx) = if c > 0.0 {
                    (p[l] / c, xs[l] / c)
                } else {
                    (0.0, 0.0)
                };
                (cx, b * ((1.0 - xr) * (1.0 + xr)).max(0.0).sqrt())
            } else {
                (a, 0.0)
            };
        }
        (out.x, out.y) = (f64x4::new(cx), f64x4::new(cy));
    }
    out
}

/// [`hypot`] lane by lane: the direct square root where every lane in `lanes` is in its range,
/// the scaled form for those that are not.
#[inline(always)]
fn hypot_lanes(x: f64x4, y: f64x4, lanes: f64x4) -> f64x4 {
    let sq = x * x + y * y;
    let direct =
        sq.simd_ge(f64x4::splat(HYPOT_DIRECT_MIN)) & sq.simd_le(f64x4::splat(HYPOT_DIRECT_MAX));
    let scaled = (lanes & !direct).to_bitmask();
    let root = sq.sqrt();
    if scaled == 0 {
        return root;
    }
    let (xs, ys, mut h) = (x.to_array(), y.to_array(), root.to_array());
    for l in (0..LANES).filter(|l| scaled & (1 << l) != 0) {
        h[l] = hypot(xs[l], ys[l]);
    }
    f64x4::new(h)
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

// ---------------------------------------------------------------------------------------------
// f32: mirror of shaders/roi/ellipse.wgsl, op for op (same order, same constants), so that CPU
// tests check the bound the GPU kernel is held to. Keep the two in step.
// ---------------------------------------------------------------------------------------------

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

/// `hypot` without overflow for finite inputs below `f32::MAX/√2` (WGSL has no `hypot`).
/// Mirrors `ellipse_hypot`.
fn hypot_f32(x: f32, y: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let m = ax.max(ay);
    if m == 0.0 {
        return 0.0;
    }
    let r = ax.min(ay) / m;
    m * (1.0 + r * r).sqrt()
}

/// Mirrors `ellipse_inside`.
fn inside_filled_f32(a: f32, b: f32, p: [f32; 2]) -> bool {
    if a == 0.0 || b == 0.0 {
        if a == 0.0 {
            return p[0] == 0.0 && p[1].abs() <= b;
        }
        return p[1] == 0.0 && p[0].abs() <= a;
    }
    let u = p[0] / a;
    let v = p[1] / b;
    u * u + v * v <= 1.0
}

/// Mirrors `ellipse_first_quadrant`.
fn first_quadrant_f32(a: f32, b: f32, x: f32, y: f32) -> ([f32; 2], u32) {
    if a == 0.0 {
        return ([0.0, 0.0], 0);
    }
    let e = b / a;
    let p = x / a;
    let q = y / a;
    if !(p <= FAR_F32 && q <= FAR_F32) {
        let m = x.max(y);
        let ux = x / m;
        let uy = y / m;
        let n = hypot_f32(ux, e * uy);
        if n.is_nan() || n <= 0.0 {
            return ([0.0, 0.0], 0);
        }
        return ([a * (ux / n), b * (e * uy / n)], 0);
    }
    let c = (1.0 - e) * (1.0 + e);
    let eq = e * q;
    if eq == 0.0 {
        if p <= c {
            let mut xs = 0.0;
            let mut cx = 0.0;
            if c > 0.0 {
                xs = p / c;
                cx = x / c;
            }
            let cy = b * ((1.0 - xs) * (1.0 + xs)).max(0.0).sqrt();
            return ([cx, cy], 0);
        }
        return ([a, 0.0], 0);
    }
    let r = hypot_f32(p, eq);
    let mut lo = eq.max(r - c);
    let mut hi = r;
    let mut w = lo;
    let mut probing = false;
    // WGSL may assume no infinities, so the estimate is guarded instead of checked afterwards:
    // q/e ≤ 2¹⁰⁰ and |rho − 1| < den·2¹⁰⁰ keep every quotient below 2¹⁰¹.
    if q <= e * FAR_F32 {
        let rho = hypot_f32(p, q / e);
        let x0 = p / rho;
        let b0 = q / (e * rho);
        let den = e * e * x0 * x0 + b0 * b0;
        if (rho - 1.0).abs() < den * FAR_F32 {
            let est = e * e * ((rho - 1.0) / den + 1.0);
            if est > lo && est < hi {
                w = est;
                probing = true;
            }
        }
    }
    let mut iterations = 0u32;
    let mut converged = false;
    let mut prev_rel = 1.0f32;
    for _ in 0..MAX_NEWTON_STEPS_F32 {
        iterations += 1;
        let ga = p / (w + c);
        let gb = eq / w;
        let s = ga * ga + gb * gb;
        if s <= 1.0 && !probing {
            converged = true;
            break;
        }
        if s >= 1.0 {
            lo = lo.max(w);
        } else {
            hi = hi.min(w);
        }
        let dw = ga * ga * (w / (w + c)) + gb * gb;
        let step = w * s * (s.sqrt() - 1.0) / dw;
        let newton = w + step;
        if newton > lo {
            lo = newton.min(hi);
        }
        let rel = step.abs() / w;
        if rel <= NEWTON_TOL_F32
            || (!probing
                && prev_rel <= 1e-3
                && rel * rel * rel <= 0.25 * f32::EPSILON * prev_rel * prev_rel)
        {
            w = newton.max(lo).min(hi);
            converged = true;
            break;
        }
        if probing {
            prev_rel = 1.0;
        } else {
            prev_rel = rel;
        }
        if s >= 1.0 && lo <= w {
            w = lo;
            converged = true;
            break;
        }
        let first = w;
        w = lo;
        probing = false;
        if iterations == 1 && s >= 1.0 {
            let mut frozen = hi;
            if ga < 1.0 {
                frozen = frozen.min(eq / ((1.0 - ga) * (1.0 + ga)).sqrt());
            }
            if gb < 1.0 {
                frozen = frozen.min(p / ((1.0 - gb) * (1.0 + gb)).sqrt() - c);
            }
            if frozen > lo && lo - first < 0.25 * (frozen - first) {
                w = frozen;
                probing = true;
            }
        }
    }
    if !converged {
        let mut lb = lo.to_bits();
        let mut hb = hi.to_bits();
        let mut k = 0;
        while k < MAX_BISECTION_STEPS_F32 && hb > lb + 1 {
            k += 1;
            iterations += 1;
            let mb = lb + (hb - lb) / 2;
            let m = f32::from_bits(mb);
            let ga = p / (m + c);
            let gb = eq / m;
            if ga * ga + gb * gb >= 1.0 {
                lb = mb;
            } else {
                hb = mb;
            }
        }
        w = f32::from_bits(lb);
    }
    // As the f64 solver: a subnormal root (or zero) carries too few bits for eq/w.
    let mut cy = b * (eq / w);
    if w < f32::MIN_POSITIVE {
        let xr = p / (w + c);
        cy = b * ((1.0 - xr) * (1.0 + xr)).max(0.0).sqrt();
    }
    ([x / (w + c), cy], iterations)
}

/// The f32 closest point on the curve: the CPU mirror of the WGSL `ellipse_closest_point`.
#[must_use]
pub fn closest_point_on_ellipse_f32(a: f32, b: f32, p: [f32; 2]) -> ClosestPointF32 {
    let a = a.abs();
    let b = b.abs();
    let swap = b > a;
    let mut major = a;
    let mut minor = b;
    let mut x = p[0].abs();
    let mut y = p[1].abs();
    if swap {
        major = b;
        minor = a;
        x = p[1].abs();
        y = p[0].abs();
    }
    let (mut c, iterations) = first_quadrant_f32(major, minor, x, y);
    let distance = hypot_f32(x - c[0], y - c[1]);
    if swap {
        c = [c[1], c[0]];
    }
    if p[0] < 0.0 {
        c[0] = -c[0];
    }
    if p[1] < 0.0 {
        c[1] = -c[1];
    }
    ClosestPointF32 {
        distance,
        point: c,
        iterations,
    }
}

/// The f32 distance to the filled ellipse: the CPU mirror of the WGSL `ellipse_filled_distance`.
#[must_use]
pub fn distance_to_filled_ellipse_f32(a: f32, b: f32, p: [f32; 2]) -> f32 {
    if inside_filled_f32(a.abs(), b.abs(), p) {
        return 0.0;
    }
    closest_point_on_ellipse_f32(a, b, p).distance
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A warm start never changes the answer beyond rounding, whatever the hint: the root
    /// itself, near and far guesses, and invalid ones (ignored), over a grid of ellipses and
    /// points in every quadrant, inside and out.
    #[test]
    fn hinted_solver_agrees_with_the_cold_one_for_any_hint() {
        for (a, b) in [
            (1.0, 1.0),
            (3.0, 1.0),
            (1.0, 7.0),
            (900.0, 1.0),
            (1e3, 999.0),
        ] {
            for k in 0..400 {
                let t = f64::from(k) * 0.0731;
                let r = 0.05 + 3.0 * f64::from(k % 17) / 16.0;
                let p = DVec2::new(a * r * t.cos(), b * r * t.sin()) + DVec2::new(0.3, -0.2);
                let (cold, root) = closest_point_on_ellipse_hinted(a, b, p, f64::NAN);
                assert_eq!(cold, closest_point_on_ellipse(a, b, p));
                let scale = a.max(b).max(p.length());
                for hint in [
                    root,
                    root * (1.0 + 1e-3),
                    root * (1.0 - 1e-6),
                    0.5 * root,
                    2.0 * root,
                    -1.0,
                    f64::INFINITY,
                    f64::NAN,
                ] {
                    let (warm, _) = closest_point_on_ellipse_hinted(a, b, p, hint);
                    assert!(
                        (warm.distance - cold.distance).abs() <= 1e-14 * scale,
                        "a={a} b={b} p={p} hint={hint}: {} vs {}",
                        warm.distance,
                        cold.distance
                    );
                    assert!(warm.iterations <= MAX_ITERATIONS_F64);
                }
            }
        }
    }
    /// The hoisted solver does the same operations as the free function: bit-identical
    /// distances, points and roots, cold and warm, for both orientations and degenerate ellipses.
    #[test]
    fn hoisted_solver_is_bit_identical_to_the_free_function() {
        for (a, b) in [
            (1.0, 1.0),
            (3.0, 1.0),
            (1.0, 7.0),
            (900.0, 1.0),
            (2.0, 0.0),
            (0.0, 0.0),
        ] {
            let solver = EllipseSolver::new(a, b);
            for k in 0..300 {
                let t = f64::from(k) * 0.0731;
                let r = 0.05 + 3.0 * f64::from(k % 17) / 16.0;
                let p = DVec2::new(a * r * t.cos() + 0.3, b * r * t.sin() - 0.2);
                assert_eq!(solver.contains(p), closest_point_on_ellipse(a, b, p).inside);
                for hint in [f64::NAN, 0.5, 2.0] {
                    let (cp, root) = closest_point_on_ellipse_hinted(a, b, p, hint);
                    let (d, q, w) = solver.closest_hinted(p, hint);
                    assert_eq!(d.to_bits(), cp.distance.to_bits(), "a={a} b={b} p={p}");
                    assert_eq!(
                        (q.x.to_bits(), q.y.to_bits()),
                        (cp.point.x.to_bits(), cp.point.y.to_bits())
                    );
                    assert_eq!(w.to_bits(), root.to_bits(), "a={a} b={b} p={p}");
                }
            }
        }
    }

    /// Points a hair off the major axis inside the evolute, where the secular root w is
    /// subnormal (1/w would overflow: a Newton loop that multiplied by 1/w instead of dividing
    /// stalled at its start and answered b instead of b·√(1 − X²)). The reference is the
    /// on-axis closed form, which the point is within y ≤ 1e-300 of.
    #[test]
    fn subnormal_roots_divide() {
        for (a, b, x, y) in [
            (1.0_f64, 1e-10_f64, 0.5_f64, 1e-300_f64),
            (1.0, 1e-10, 0.5, 1e-305),
            (1.0, 1e-3, 0.3, 1e-306),
            (2.0, 1e-5, -0.7, -3e-304),
            (1e-5, 3.0, 1e-303, 2.5),
        ] {
            let (major, minor, u, v) = if b > a { (b, a, y, x) } else { (a, b, x, y) };
            let c = 1.0 - (minor / major).powi(2);
            let xr = u.abs() / major / c;
            let want = hypot(
                u.abs() - major * xr,
                v.abs() - minor * ((1.0 - xr) * (1.0 + xr)).sqrt(),
            );
            let got = closest_point_on_ellipse(a, b, DVec2::new(x, y));
            assert!(
                (got.distance - want).abs() <= 1e-14 * a.max(b).max(x.hypot(y)),
                "({a:e}, {b:e}, {x:e}, {y:e}): {:e} vs {want:e}",
                got.distance
            );
        }
    }

    /// Asserts that every masked lane of one `closest_hinted_lanes` call is bit-identical to
    /// solving that lane alone (and that unmasked lanes answer NaN).
    fn assert_lanes_match(
        solver: &EllipseSolver,
        p: [DVec2; LANES],
        hint: [f64; LANES],
        mask: [bool; LANES],
    ) {
        let lanes = solver.closest_hinted_lanes(
            f64x4::new(p.map(|p| p.x)),
            f64x4::new(p.map(|p| p.y)),
            f64x4::new(hint),
            lane_mask(mask),
        );
        let [d, x, y, w] = [lanes.distance, lanes.x, lanes.y, lanes.root].map(f64x4::to_array);
        for l in 0..LANES {
            let (d, q, w) = (d[l], DVec2::new(x[l], y[l]), w[l]);
            if !mask[l] {
                assert!(
                    d.is_nan() && q.is_nan() && w.is_nan(),
                    "lane {l} is masked off: {lanes:?}"
                );
                continue;
            }
            let (d1, q1, w1) = solver.closest_hinted(p[l], hint[l]);
            let bits = |d: f64, q: DVec2, w: f64| [d, q.x, q.y, w].map(f64::to_bits);
            assert_eq!(
                bits(d, q, w),
                bits(d1, q1, w1),
                "lane {l} of {solver:?}: p={:?} hint={:?} mask={mask:?}",
                p[l],
                hint[l]
            );
        }
    }

    /// Each hard case shares its lanes with three other queries on the same ellipse (the point
    /// reflected, halved and pushed out), cold, warm from the case's own root, and warm from a
    /// neighbour's: the lanes must not change any query's answer.
    #[test]
    fn lanes_are_bit_identical_to_one_at_a_time() {
        let csv = include_str!("../../tests/data/ellipse_hard_cases.csv");
        let mut cases = 0;
        for line in csv.lines().filter(|l| !l.starts_with('#')).skip(1) {
            let v: Vec<f64> = line
                .split(',')
                .take(4)
                .map(|s| s.parse().unwrap())
                .collect();
            let (a, b, p) = (v[0], v[1], DVec2::new(v[2], v[3]));
            let solver = EllipseSolver::new(a, b);
            let points = [p, -p, 0.5 * p, p * 1.5 + DVec2::new(a, b)];
            let roots = points.map(|q| solver.closest_hinted(q, f64::NAN).2);
            for hint in [
                [f64::NAN; 4],
                roots,
                [roots[1], roots[2], roots[3], roots[0]],
                [0.5, 2.0, f64::INFINITY, -1.0],
            ] {
                assert_lanes_match(&solver, points, hint, [true; 4]);
                assert_lanes_match(&solver, points, hint, [true, false, true, false]);
                assert_lanes_match(&solver, points, hint, [false, false, false, true]);
            }
            cases += 1;
        }
        assert!(cases > 1900, "read {cases} hard cases");
    }

    proptest! {
        #[test]
        fn lanes_are_bit_identical_for_any_input(
            a in any_finite(), b in any_finite(),
            xy in prop::array::uniform8(any_finite()),
            hint in prop::array::uniform4(any_finite()),
            mask in prop::array::uniform4(any::<bool>()),
        ) {
            let p = [0, 1, 2, 3].map(|l| DVec2::new(xy[2 * l], xy[2 * l + 1]));
            let solver = EllipseSolver::new(a, b);
            assert_lanes_match(&solver, p, hint, mask);
            // Warm from each other's roots, as the DGI's neighbouring pixels are.
            let roots = p.map(|q| solver.closest_hinted(q, f64::NAN).2);
            assert_lanes_match(&solver, p, [roots[3], roots[0], roots[1], roots[2]], mask);
        }

        #[test]
        fn lanes_are_bit_identical_near_eccentric_boundaries(
            a in 1.0f64..4000.0, k in 0.0f64..8.0,
            t in prop::array::uniform4(0.0f64..std::f64::consts::TAU),
            off in prop::array::uniform4(-1e-3f64..1e-3),
        ) {
            // Where the start estimate, the frozen-term probe and the stopping rule all act.
            let b = a * 10f64.powf(-k);
            let solver = EllipseSolver::new(a, b);
            let p = [0, 1, 2, 3].map(|l| {
                let (c, s) = (t[l].cos(), t[l].sin());
                DVec2::new(a * c, b * s) + off[l] * a * DVec2::new(c / a, s / b).normalize()
            });
            assert_lanes_match(&solver, p, [f64::NAN; 4], [true; 4]);
            let roots = p.map(|q| solver.closest_hinted(q, f64::NAN).2);
            assert_lanes_match(&solver, p, [roots[1], roots[2], roots[3], roots[0]], [true; 4]);
        }
    }

    /// The direct and the scaled forms of `hypot` agree to an ulp or two, and the scaled one
    /// takes over where squaring would overflow or reach the subnormals.
    #[test]
    fn hypot_is_accurate_in_and_out_of_the_direct_range() {
        for (x, y, want) in [
            (3.0, 4.0, 5.0),
            (3e200, 4e200, 5e200),
            (3e-200, 4e-200, 5e-200),
            (f64::MAX, 0.0, f64::MAX),
            (5e-324, 0.0, 5e-324),
            (0.0, 0.0, 0.0),
            (f64::INFINITY, 1.0, f64::INFINITY),
        ] {
            let got = hypot(x, y);
            assert!(
                got == want || (got - want).abs() <= 2.0 * EPS * want,
                "hypot({x}, {y}) = {got}, want {want}"
            );
        }
        assert!(hypot(f64::NAN, 1.0).is_nan());
        for k in 1..2000 {
            let (x, y) = (f64::from(k) * 0.37, 1000.0 / f64::from(k));
            let direct = hypot(x, y);
            let scaled = {
                let (hi, lo) = (x.max(y), x.min(y));
                hi * (1.0 + (lo / hi) * (lo / hi)).sqrt()
            };
            assert!((direct - scaled).abs() <= 4.0 * EPS * direct, "{x} {y}");
        }
    }

    use proptest::prelude::*;

    const EPS: f64 = f64::EPSILON;

    fn cp(a: f64, b: f64, x: f64, y: f64) -> ClosestPoint {
        closest_point_on_ellipse(a, b, DVec2::new(x, y))
    }

    fn close(got: f64, want: f64, tol: f64) -> bool {
        (got - want).abs() <= tol
    }

    #[test]
    fn circle_point_outside_projects_radially() {
        let c = cp(2.0, 2.0, 3.0, -4.0);
        assert!(close(c.distance, 3.0, 4.0 * EPS), "{c:?}");
        assert!(
            (c.point - DVec2::new(1.2, -1.6)).length() <= 4.0 * EPS,
            "{c:?}"
        );
        assert!(!c.inside);
    }

    #[test]
    fn circle_centre_returns_the_top_point() {
        let c = cp(0.5, 0.5, 0.0, 0.0);
        assert_eq!(
            (c.distance, c.point, c.inside),
            (0.5, DVec2::new(0.0, 0.5), true)
        );
    }

    #[test]
    fn ellipse_centre_returns_the_minor_vertex_on_the_positive_side() {
        assert_eq!(cp(3.0, 1.0, 0.0, 0.0).point, DVec2::new(0.0, 1.0));
        assert_eq!(cp(3.0, 1.0, -0.0, -0.0).point, DVec2::new(0.0, 1.0));
        // b > a: the major axis is y, so the tie is broken towards +x.
        assert_eq!(cp(1.0, 3.0, 0.0, 0.0).point, DVec2::new(1.0, 0.0));
    }

    #[test]
    fn major_axis_outside_the_evolute_goes_to_the_vertex() {
        // Evolute reach (a² − b²)/a = 8/3; x = 2.9 is past it, inside the ellipse.
        let c = cp(3.0, 1.0, -2.9, 0.0);
        assert_eq!(c.point, DVec2::new(-3.0, 0.0));
        assert!(close(c.distance, 0.1, 4.0 * EPS), "{c:?}");
        let c = cp(3.0, 1.0, 7.0, -0.0);
        assert_eq!((c.point, c.distance), (DVec2::new(3.0, 0.0), 4.0));
    }

    #[test]
    fn major_axis_inside_the_evolute_picks_the_positive_minor_side() {
        // X = a²x/(a² − b²), Y = b√(1 − X²/a²): the two closest points (X, ±Y).
        let (a, b, x) = (3.0_f64, 1.0_f64, 1.6_f64);
        let cx = a * a * x / (a * a - b * b);
        let cy = b * (1.0 - (cx / a).powi(2)).sqrt();
        for y in [0.0, -0.0] {
            let c = cp(a, b, x, y);
            assert!(
                (c.point - DVec2::new(cx, cy)).length() <= 4.0 * EPS,
                "{c:?}"
            );
            assert!(close(c.distance, (x - cx).hypot(cy), 4.0 * EPS), "{c:?}");
            assert_eq!(c.iterations, 0);
        }
    }

    #[test]
    fn minor_axis_points_go_to_the_minor_vertex() {
        let c = cp(3.0, 1.0, 0.0, -0.25);
        assert_eq!(
            (c.point, c.distance, c.inside),
            (DVec2::new(0.0, -1.0), 0.75, true)
        );
        let c = cp(3.0, 1.0, 0.0, 5.0);
        assert_eq!(
            (c.point, c.distance, c.inside),
            (DVec2::new(0.0, 1.0), 4.0, false)
        );
    }

    #[test]
    fn segment_clamps_along_its_length() {
        let c = cp(1.0, 0.0, 0.3, 2.0);
        assert_eq!((c.point, c.distance), (DVec2::new(0.3, 0.0), 2.0));
        let c = cp(1.0, 0.0, -5.0, 2.0);
        assert_eq!(c.point, DVec2::new(-1.0, 0.0));
        assert!(close(c.distance, 4.0_f64.hypot(2.0), 4.0 * EPS));
        let c = cp(0.0, 2.5, 0.0, -1.0);
        assert_eq!(
            (c.point, c.distance, c.inside),
            (DVec2::new(0.0, -1.0), 0.0, true)
        );
        assert_eq!(
            distance_to_filled_ellipse(1.0, 0.0, DVec2::new(0.5, 1e-300)),
            1e-300
        );
    }

    #[test]
    fn point_ellipse_is_its_centre() {
        let c = cp(0.0, 0.0, 3.0, -4.0);
        assert_eq!((c.point, c.distance), (DVec2::ZERO, 5.0));
    }

    #[test]
    fn tiny_ellipse_seen_from_1e300_uses_the_far_field_without_overflow() {
        let c = cp(1e-300, 5e-301, 1e300, 0.0);
        assert_eq!(c.point, DVec2::new(1e-300, 0.0));
        assert_eq!(c.distance, 1e300);
        let c = cp(1e-300, 1e-300, 1e300, 1e300);
        assert!(c.distance.is_finite() && c.point.is_finite(), "{c:?}");
        assert!(
            close(c.point.x.hypot(c.point.y), 1e-300, 4.0 * EPS * 1e-300),
            "{c:?}"
        );
    }

    #[test]
    fn negative_semi_axes_mean_the_same_ellipse() {
        assert_eq!(cp(-3.0, -1.0, 2.0, 2.0), cp(3.0, 1.0, 2.0, 2.0));
    }

    #[test]
    fn subnormal_inputs_scale_like_normal_ones() {
        // The same case at scale 1 and at 2^-1070: the answer scales exactly up to the
        // subnormal spacing.
        let s = 2.0_f64.powi(-1070);
        let big = cp(12.0, 5.0, 17.0, 9.0);
        let small = cp(12.0 * s, 5.0 * s, 17.0 * s, 9.0 * s);
        assert!(
            close(small.distance, big.distance * s, 4.0 * f64::from_bits(1)),
            "{small:?}"
        );
    }

    #[test]
    fn f32_mirror_agrees_with_f64_on_pixel_scale_points() {
        for (a, b, x, y) in [(600.0, 250.0, 800.0, 300.0), (250.0, 600.0, -3.5, 610.0)] {
            let d64 = cp(a, b, x, y).distance;
            let d32 = closest_point_on_ellipse_f32(a as f32, b as f32, [x as f32, y as f32]);
            let scale = 800.0_f64.hypot(300.0);
            assert!(
                close(f64::from(d32.distance), d64, F32_DISTANCE_BOUND * scale),
                "{d32:?}"
            );
        }
        assert_eq!(
            distance_to_filled_ellipse_f32(600.0, 250.0, [100.0, -100.0]),
            0.0
        );
    }

    /// Any finite f64, sign included: normal, subnormal, zero.
    fn any_finite() -> impl Strategy<Value = f64> {
        prop::num::f64::NORMAL | prop::num::f64::SUBNORMAL | prop::num::f64::ZERO
    }

    proptest! {
        #[test]
        fn finite_inputs_never_give_nan(a in any_finite(), b in any_finite(),
                                        x in any_finite(), y in any_finite()) {
            let c = closest_point_on_ellipse(a, b, DVec2::new(x, y));
            prop_assert!(!c.distance.is_nan() && c.distance >= 0.0, "{:?}", c);
            prop_assert!(c.point.is_finite(), "{:?}", c);
            prop_assert!(c.iterations <= MAX_ITERATIONS_F64);
            let filled = distance_to_filled_ellipse(a, b, DVec2::new(x, y));
            prop_assert_eq!(filled, if c.inside { 0.0 } else { c.distance });
        }

        #[test]
        fn finite_f32_inputs_never_give_nan(a in -1e30f32..1e30, b in -1e30f32..1e30,
                                            x in -1e30f32..1e30, y in -1e30f32..1e30) {
            let c = closest_point_on_ellipse_f32(a, b, [x, y]);
            prop_assert!(c.distance.is_finite() && c.point.iter().all(|v| v.is_finite()), "{:?}", c);
            prop_assert!(c.iterations <= MAX_ITERATIONS_F32);
        }

        #[test]
        fn distance_is_attained_and_no_sampled_point_is_closer(
            a in 1e-3f64..1e3, b in 1e-3f64..1e3, x in -1e4f64..1e4, y in -1e4f64..1e4,
        ) {
            let p = DVec2::new(x, y);
            let c = closest_point_on_ellipse(a, b, p);
            let scale = a.max(b).max(p.length());
            prop_assert!((c.distance - (p - c.point).length()).abs() <= 8.0 * EPS * scale);
            let (u, v) = (c.point.x / a, c.point.y / b);
            prop_assert!((u * u + v * v - 1.0).abs() <= 16.0 * EPS, "{:?}", c);
            for i in 0..256 {
                let t = std::f64::consts::TAU * f64::from(i) / 256.0;
                let s = DVec2::new(a * t.cos(), b * t.sin());
                prop_assert!(c.distance <= (p - s).length() + 1e-12 * scale, "{:?} vs {:?}", c, s);
            }
        }

        #[test]
        fn filled_distance_is_zero_inside(a in 1e-3f64..1e3, b in 1e-3f64..1e3,
                                          r in 0.0f64..0.999_999, t in 0.0f64..std::f64::consts::TAU) {
            let p = DVec2::new(r * a * t.cos(), r * b * t.sin());
            prop_assert_eq!(distance_to_filled_ellipse(a, b, p), 0.0);
            prop_assert_eq!(distance_to_filled_ellipse_f32(a as f32, b as f32,
                                                           [p.x as f32, p.y as f32]), 0.0);
            prop_assert!(closest_point_on_ellipse(a, b, p).inside);
        }

        #[test]
        fn f32_mirror_is_within_its_bound_near_eccentric_boundaries(
            a in 1.0f64..4000.0, k in 0.0f64..8.0, t in 0.0f64..std::f64::consts::TAU,
            off in -1e-3f64..1e-3, swap in any::<bool>(),
        ) {
            // Points near the boundary of ellipses with a/b up to 1e8: where the start estimate,
            // the frozen-term probe and the stopping rule all come into play.
            let b = a * 10f64.powf(-k);
            let (c, s) = (t.cos(), t.sin());
            let n = DVec2::new(c / a, s / b).normalize();
            let p = DVec2::new(a * c, b * s) + off * a * n;
            let (a, b, p) = if swap { (b, a, DVec2::new(p.y, p.x)) } else { (a, b, p) };
            let v = [a as f32, b as f32, p.x as f32, p.y as f32];
            let got = closest_point_on_ellipse_f32(v[0], v[1], [v[2], v[3]]);
            let w = v.map(f64::from);
            let want = closest_point_on_ellipse(w[0], w[1], DVec2::new(w[2], w[3]));
            let scale = w[0].max(w[1]).max(w[2].hypot(w[3]));
            prop_assert!(got.point.iter().all(|x| x.is_finite()), "{:?}", got);
            prop_assert!((f64::from(got.distance) - want.distance).abs() <= F32_DISTANCE_BOUND * scale,
                         "{:?} vs {:?}", got, want);
            prop_assert!(got.iterations <= MAX_ITERATIONS_F32);
        }

        #[test]
        fn f32_mirror_is_within_its_bound_at_pixel_scale(
            a in 0.0f32..4000.0, b in 0.0f32..4000.0, x in -4000.0f32..4000.0, y in -4000.0f32..4000.0,
        ) {
            let got = distance_to_filled_ellipse_f32(a, b, [x, y]);
            let p = DVec2::new(f64::from(x), f64::from(y));
            let want = distance_to_filled_ellipse(f64::from(a), f64::from(b), p);
            let scale = f64::from(a.max(b)).max(p.length());
            prop_assert!((f64::from(got) - want).abs() <= F32_DISTANCE_BOUND * scale,
                         "{} vs {}", got, want);
        }
    }
}
