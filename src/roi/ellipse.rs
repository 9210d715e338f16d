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
//!    `h'' ∝ (Σ A_i² r_i³)² − S·Σ A_i² r_i⁴ ≤ 0`), so Newton on `h(w) = 1` started left of the root
//!    never overshoots and climbs monotonically. The start is the certified lower bound
//!    `w₀ = max(eq, hypot(p, eq) − c)` (each makes one term of `S` reach 1 by itself) and
//!    `hypot(p, eq)` is a certified upper bound (`w + c ≥ w`).
//! 5. If Newton has not converged after [`MAX_NEWTON_STEPS_F64`] steps (never seen on the
//!    hard-case set, but guaranteed termination is the point), bisection on the bit pattern of
//!    `w` inside the bracket finishes in at most 63 steps (31 in f32), because the bit patterns of
//!    two positive finite floats differ by less than 2⁶³ (2³¹).
//!
//! Step 3's closed forms need `eq > 0`. When `eq == 0` (the point is on the major axis, or `e·q`
//! underflowed, or the ellipse is a segment) the answer is closed-form: outside the evolute
//! (`p > c`) the vertex `(a, 0)`; inside it (`p ≤ c`), `X = p/c`, `Y = e·√(1 − X²)`.
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
pub const MEASURED_MAX_NEWTON_F64: u32 = 12;

/// Newton steps before the bisection fallback in f32; equals `ELLIPSE_NEWTON_STEPS` in the WGSL.
pub const MAX_NEWTON_STEPS_F32: u32 = 16;
/// Bit-pattern bisection steps that always suffice in f32 (bit patterns differ by < 2³¹).
pub const MAX_BISECTION_STEPS_F32: u32 = 31;
/// The stated bound on the iterations of the f32 solver (CPU mirror and WGSL).
pub const MAX_ITERATIONS_F32: u32 = MAX_NEWTON_STEPS_F32 + MAX_BISECTION_STEPS_F32;

/// The f32 solver's distance error bound, relative to the scale `max(a, b, |p|)`, for inputs that
/// are f32-normal: `|d_f32 − d| ≤ F32_DISTANCE_BOUND · scale`. DESIGN.md §5 says about 1e-6 is
/// reachable; the measured maximum on the hard-case set is about 2.4e-7 (two f32 ulps at the
/// scale), and GPU division and square root may be 2.5 ulp off instead of 0.5, so 1e-6 keeps a
/// margin of four. At a 4K canvas scale (4000 px) this is 0.004 px.
pub const F32_DISTANCE_BOUND: f64 = 1e-6;

/// The WGSL source of the f32 solver (no bindings, no entry point): prepend or append it to a
/// kernel's source.
pub const WGSL: &str = include_str!("../../shaders/roi/ellipse.wgsl");

/// Newton stops once a step is below this fraction of `w`: the next step would be rounding noise.
const NEWTON_TOL_F64: f64 = 4.0 * f64::EPSILON;
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
    let (a, b) = (a.abs(), b.abs());
    let inside = inside_filled(a, b, p);
    // Orient the major axis along x; the solver needs a ≥ b.
    let swap = b > a;
    let (major, minor, x, y) = if swap {
        (b, a, p.y.abs(), p.x.abs())
    } else {
        (a, b, p.x.abs(), p.y.abs())
    };
    let (cx, cy, iterations) = first_quadrant_f64(major, minor, x, y);
    let distance = (x - cx).hypot(y - cy);
    let (cx, cy) = if swap { (cy, cx) } else { (cx, cy) };
    // `< 0.0` keeps −0.0 on the positive side: the documented choice for the non-unique case.
    let point = DVec2::new(
        if p.x < 0.0 { -cx } else { cx },
        if p.y < 0.0 { -cy } else { cy },
    );
    ClosestPoint {
        distance,
        point,
        iterations,
        inside,
    }
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
fn first_quadrant_f64(a: f64, b: f64, x: f64, y: f64) -> (f64, f64, u32) {
    if a == 0.0 {
        return (0.0, 0.0, 0);
    }
    let e = b / a;
    let (p, q) = (x / a, y / a);
    // `!(..)` also routes NaN here, where it stays NaN.
    if !(p <= FAR_F64 && q <= FAR_F64) {
        return far_field_f64(a, e, b, x, y);
    }
    // 1 − e² without the cancellation of `1.0 - e * e` near circles.
    let c = (1.0 - e) * (1.0 + e);
    let eq = e * q;
    if eq == 0.0 {
        if p <= c {
            // Inside the evolute on the major axis (or a segment's interior): the pole root.
            let (xs, cx) = if c > 0.0 { (p / c, x / c) } else { (0.0, 0.0) };
            let cy = b * ((1.0 - xs) * (1.0 + xs)).max(0.0).sqrt();
            return (cx, cy, 0);
        }
        return (a, 0.0, 0);
    }
    let secular = |w: f64| {
        let (ga, gb) = (p / (w + c), eq / w);
        (ga, gb, ga * ga + gb * gb)
    };
    let r = p.hypot(eq);
    let mut lo = eq.max(r - c);
    let mut hi = r;
    let mut w = lo;
    let mut iterations = 0;
    let mut converged = false;
    let mut probing = false;
    while iterations < MAX_NEWTON_STEPS_F64 {
        iterations += 1;
        let (ga, gb, s) = secular(w);
        if s <= 1.0 && !probing {
            // At the root, or past it by rounding only: Newton from below never overshoots.
            converged = true;
            break;
        }
        if s >= 1.0 {
            lo = lo.max(w);
        } else {
            hi = hi.min(w);
        }
        // Newton on h = S^(-1/2): Δw = (1 − h)/h' = w·S(√S − 1)/(w·(A²/(w+c) + B²/w)); the
        // denominator is written bounded (≤ 2) so that tiny w cannot overflow it. h is concave,
        // so the tangent's zero is a lower bound from either side.
        let dw = ga * ga * (w / (w + c)) + gb * gb;
        let step = w * s * (s.sqrt() - 1.0) / dw;
        let newton = w + step;
        if newton > lo {
            lo = newton.min(hi);
        }
        if step.abs() <= NEWTON_TOL_F64 * w {
            w = newton.max(lo).min(hi);
            converged = true;
            break;
        }
        if s >= 1.0 && lo <= w {
            // Rounding stalls the climb: w is the root to working precision.
            w = lo;
            converged = true;
            break;
        }
        let first = w;
        w = lo;
        probing = false;
        if iterations == 1 {
            // Freezing one term at its value at `first` and solving for the other gives an
            // estimate from above that is exact where one term hardly varies: near a vertex of
            // an eccentric ellipse, where Newton alone crawls (11 more steps on the hard cases).
            // Evaluate there once when Newton's first step covers less than a quarter of the way.
            let mut frozen = hi;
            if ga < 1.0 {
                frozen = frozen.min(eq / ((1.0 - ga) * (1.0 + ga)).sqrt());
            }
            if gb < 1.0 {
                frozen = frozen.min(p / ((1.0 - gb) * (1.0 + gb)).sqrt() - c);
            }
            if lo - first < 0.25 * (frozen - first) {
                w = frozen;
                probing = true;
            }
        }
    }
    if !converged {
        let (mut lb, mut hb) = (lo.to_bits(), hi.to_bits());
        while hb > lb + 1 {
            iterations += 1;
            let mb = lb + (hb - lb) / 2;
            if secular(f64::from_bits(mb)).2 >= 1.0 {
                lb = mb;
            } else {
                hb = mb;
            }
        }
        w = f64::from_bits(lb);
    }
    (x / (w + c), b * (eq / w), iterations)
}

/// The point whose outward normal is parallel to `(x, y)`: the closest point to within
/// `a·(a/b)·(a/|p|)`, used when `|p|/a > 2¹⁰⁰⁰` so that the error is below rounding.
fn far_field_f64(a: f64, e: f64, b: f64, x: f64, y: f64) -> (f64, f64, u32) {
    let m = x.max(y);
    let (ux, uy) = (x / m, y / m);
    let n = ux.hypot(e * uy);
    if !(n > 0.0) {
        // A segment seen broadside: its midpoint.
        return (0.0, 0.0, 0);
    }
    (a * (ux / n), b * (e * uy / n), 0)
}

// ---------------------------------------------------------------------------------------------
// f32: mirror of shaders/roi/ellipse.wgsl, op for op (same order, same constants), so that CPU
// tests check the bound the GPU kernel is held to. Keep the two in step.
// ---------------------------------------------------------------------------------------------

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
        if !(n > 0.0) {
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
    let mut iterations = 0u32;
    let mut converged = false;
    let mut probing = false;
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
        if step.abs() <= NEWTON_TOL_F32 * w {
            w = newton.max(lo).min(hi);
            converged = true;
            break;
        }
        if s >= 1.0 && lo <= w {
            w = lo;
            converged = true;
            break;
        }
        let first = w;
        w = lo;
        probing = false;
        if iterations == 1 {
            let mut frozen = hi;
            if ga < 1.0 {
                frozen = frozen.min(eq / ((1.0 - ga) * (1.0 + ga)).sqrt());
            }
            if gb < 1.0 {
                frozen = frozen.min(p / ((1.0 - gb) * (1.0 + gb)).sqrt() - c);
            }
            if lo - first < 0.25 * (frozen - first) {
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
    ([x / (w + c), b * (eq / w)], iterations)
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
