//! The f64 solver on [`LANES`] queries of one ellipse side by side in `f64x4` operations (the
//! method of `mod.rs`, step for step: branches are per-lane selects, every lane does exactly the
//! IEEE operations it would do alone, and a stopped lane keeps its root).

use glam::DVec2;
use wide::f64x4;

use super::*;

/// Queries [`EllipseSolver::closest_hinted_lanes`] solves at once: one `f64x4`.
pub const LANES: usize = 4;

/// The all-ones mask of `f64x4` comparisons where `on`, zero elsewhere.
#[must_use]
#[inline]
pub fn lane_mask(on: [bool; LANES]) -> f64x4 {
    f64x4::new(on.map(|on| f64::from_bits(if on { u64::MAX } else { 0 })))
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
        let axes = Axes {
            a: self.major,
            b: self.minor,
            e: self.e,
            c: self.c,
        };
        let q = first_quadrant_lanes(axes, qx, qy, hint, mask);
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

/// The answers of [`first_quadrant_lanes`], lane by lane: the closest point (x, y) in the
/// caller's units, the iteration count and the secular root (NaN where the answer is
/// closed-form). Lanes that were masked off hold NaN.
pub(super) struct Quadrant {
    pub(super) x: f64x4,
    pub(super) y: f64x4,
    pub(super) iterations: [u32; LANES],
    pub(super) root: f64x4,
}

/// The ellipse the first-quadrant solver works on: the semi-axes `a ≥ b` along x and y, and
/// `e = b/a` and `c = (1 − e)(1 + e)` hoisted (NaN when `a = 0`, which returns before using
/// them).
#[derive(Clone, Copy, Debug)]
pub(super) struct Axes {
    pub(super) a: f64,
    pub(super) b: f64,
    pub(super) e: f64,
    pub(super) c: f64,
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
// Long: the solver's steps 2–8 (module docs) as one chain of per-lane f64x4 operations and
// selects in the one-query order (lane 0 is that solver, bit for bit), read against those steps.
#[inline(always)]
pub(super) fn first_quadrant_lanes(
    axes: Axes,
    x: f64x4,
    y: f64x4,
    hint: f64x4,
    mask: f64x4,
) -> Quadrant {
    let Axes { a, b, e, c } = axes;
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
