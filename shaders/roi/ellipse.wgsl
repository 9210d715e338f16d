// Closest point on the ellipse (x/a)^2 + (y/b)^2 = 1 and distance to the filled ellipse, in f32.
//
// No bindings and no entry point: prepend or append this file to a kernel's source (WGSL has no
// includes). Every name starts with `ellipse_` / `Ellipse` / `ELLIPSE_`.
//
// CPU twin: src/roi/ellipse.rs (`closest_point_on_ellipse_f32`, `distance_to_filled_ellipse_f32`)
// mirrors this file op for op; the method and its justification are documented there
// (DESIGN.md §5). In short: first quadrant, major axis along x, scale by the major semi-axis,
// Newton on the concave increasing h(w) = S(w)^(-1/2) in the pole-relative unknown w = t + e^2
// (every tangent zero is a lower bound: no overshoot), started at the radial projection's
// multiplier inside a certified bracket, one probe at the frozen-term estimate where Newton would
// crawl, a stop predicted from quadratic convergence, and bisection on the bit pattern of w as the
// guaranteed fallback (at most 31 steps). Pass points relative to the ellipse centre (computed in
// f64 or integer pixels): the subtraction is where f32 loses most.
//
// Iteration bound: ELLIPSE_NEWTON_STEPS + 31 = 47 evaluations of the secular function; the
// hard-case set needs at most 8. Every sqrt argument is clamped, guarded positive, or >= 1.

const ELLIPSE_NEWTON_STEPS: u32 = 16u;
const ELLIPSE_BISECTION_STEPS: u32 = 31u;
// f32 machine epsilon 2^-23; a Newton step below 4 * 2^-23 of w is rounding noise.
const ELLIPSE_EPS: f32 = 1.1920928955078125e-7;
const ELLIPSE_NEWTON_TOL: f32 = 4.76837158203125e-7;
// The smallest normal f32, 2^-126: a root below it is subnormal (or flushed to zero).
const ELLIPSE_MIN_NORMAL: f32 = 1.1754943508222875e-38;
// 2^100: beyond this many semi-axes away the far-field point is exact to f32 rounding.
const ELLIPSE_FAR: f32 = 1.2676506002282294e30;

struct EllipseClosest {
    distance: f32,
    // The closest point on the curve; on the major axis inside the evolute (not unique) the one
    // on the positive side of the minor axis.
    point: vec2<f32>,
    iterations: u32,
}

struct EllipseQuadrant {
    point: vec2<f32>,
    iterations: u32,
}

// hypot without overflow (for finite inputs below f32 max / sqrt 2).
fn ellipse_hypot(x: f32, y: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let m = max(ax, ay);
    if (m == 0.0) {
        return 0.0;
    }
    let r = min(ax, ay) / m;
    return m * sqrt(1.0 + r * r);
}

// Whether p lies in the filled ellipse (boundary included), for a, b >= 0.
fn ellipse_inside(a: f32, b: f32, p: vec2<f32>) -> bool {
    if (a == 0.0 || b == 0.0) {
        if (a == 0.0) {
            return p.x == 0.0 && abs(p.y) <= b;
        }
        return p.y == 0.0 && abs(p.x) <= a;
    }
    let u = p.x / a;
    let v = p.y / b;
    return u * u + v * v <= 1.0;
}

// Closest point for a >= b >= 0 and x, y >= 0, in the caller's units.
fn ellipse_first_quadrant(a: f32, b: f32, x: f32, y: f32) -> EllipseQuadrant {
    if (a == 0.0) {
        return EllipseQuadrant(vec2<f32>(0.0, 0.0), 0u);
    }
    let e = b / a;
    let p = x / a;
    let q = y / a;
    if (!(p <= ELLIPSE_FAR && q <= ELLIPSE_FAR)) {
        // Far field: the point whose normal is parallel to (x, y).
        let m = max(x, y);
        let ux = x / m;
        let uy = y / m;
        let n = ellipse_hypot(ux, e * uy);
        if (!(n > 0.0)) {
            return EllipseQuadrant(vec2<f32>(0.0, 0.0), 0u);
        }
        return EllipseQuadrant(vec2<f32>(a * (ux / n), b * (e * uy / n)), 0u);
    }
    // 1 - e^2 without cancellation near circles.
    let c = (1.0 - e) * (1.0 + e);
    let eq = e * q;
    if (eq == 0.0) {
        if (p <= c) {
            // On the major axis inside the evolute (or a segment's interior).
            var xs = 0.0;
            var cx = 0.0;
            if (c > 0.0) {
                xs = p / c;
                cx = x / c;
            }
            let cy = b * sqrt(max((1.0 - xs) * (1.0 + xs), 0.0));
            return EllipseQuadrant(vec2<f32>(cx, cy), 0u);
        }
        return EllipseQuadrant(vec2<f32>(a, 0.0), 0u);
    }
    let r = ellipse_hypot(p, eq);
    var lo = max(eq, r - c);
    var hi = r;
    var w = lo;
    var probing = false;
    // Start at the Lagrange multiplier of the radial projection when it lies in the bracket.
    // Guarded so that nothing overflows (WGSL may assume no infinities): q/e <= 2^100 and
    // |rho - 1| < den * 2^100 keep every quotient below 2^101.
    if (q <= e * ELLIPSE_FAR) {
        let rho = ellipse_hypot(p, q / e);
        let x0 = p / rho;
        let b0 = q / (e * rho);
        let den = e * e * x0 * x0 + b0 * b0;
        if (abs(rho - 1.0) < den * ELLIPSE_FAR) {
            let est = e * e * ((rho - 1.0) / den + 1.0);
            if (est > lo && est < hi) {
                w = est;
                probing = true;
            }
        }
    }
    var iterations = 0u;
    var converged = false;
    var prev_rel = 1.0;
    for (var k = 0u; k < ELLIPSE_NEWTON_STEPS; k++) {
        iterations += 1u;
        let ga = p / (w + c);
        let gb = eq / w;
        let s = ga * ga + gb * gb;
        if (s <= 1.0 && !probing) {
            // At the root, or past it by rounding only: Newton from below never overshoots.
            converged = true;
            break;
        }
        if (s >= 1.0) {
            lo = max(lo, w);
        } else {
            hi = min(hi, w);
        }
        // Newton on the concave h = S^(-1/2): the tangent's zero is a lower bound.
        let dw = ga * ga * (w / (w + c)) + gb * gb;
        let step = w * s * (sqrt(s) - 1.0) / dw;
        let newton = w + step;
        if (newton > lo) {
            lo = min(newton, hi);
        }
        // Quadratic convergence: the error left after this step is about K * step^2, with K
        // estimated from the last two steps.
        let rel = abs(step) / w;
        if (rel <= ELLIPSE_NEWTON_TOL
            || (!probing && prev_rel <= 1e-3
                && rel * rel * rel <= 0.25 * ELLIPSE_EPS * prev_rel * prev_rel)) {
            w = min(max(newton, lo), hi);
            converged = true;
            break;
        }
        if (probing) {
            prev_rel = 1.0;
        } else {
            prev_rel = rel;
        }
        if (s >= 1.0 && lo <= w) {
            // Rounding stalls the climb: w is the root to working precision.
            w = lo;
            converged = true;
            break;
        }
        let first = w;
        w = lo;
        probing = false;
        if (iterations == 1u && s >= 1.0) {
            // Freeze one term and solve for the other: an estimate from above, exact near a
            // vertex of an eccentric ellipse where Newton alone crawls. Try it once.
            var frozen = hi;
            if (ga < 1.0) {
                frozen = min(frozen, eq / sqrt((1.0 - ga) * (1.0 + ga)));
            }
            if (gb < 1.0) {
                frozen = min(frozen, p / sqrt((1.0 - gb) * (1.0 + gb)) - c);
            }
            if (frozen > lo && lo - first < 0.25 * (frozen - first)) {
                w = frozen;
                probing = true;
            }
        }
    }
    if (!converged) {
        var lb = bitcast<u32>(lo);
        var hb = bitcast<u32>(hi);
        var k = 0u;
        while (k < ELLIPSE_BISECTION_STEPS && hb > lb + 1u) {
            k += 1u;
            iterations += 1u;
            let mb = lb + (hb - lb) / 2u;
            let m = bitcast<f32>(mb);
            let ga = p / (m + c);
            let gb = eq / m;
            if (ga * ga + gb * gb >= 1.0) {
                lb = mb;
            } else {
                hb = mb;
            }
        }
        w = bitcast<f32>(lb);
    }
    // A subnormal root (or one a GPU flushed to zero) carries too few bits for eq / w: near the
    // major axis inside the evolute's span, w is of the order of the tiny minor coordinate.
    // Take y from the ellipse equation there (w << c, so x / (w + c) is exact to rounding).
    var cy = b * (eq / w);
    if (w < ELLIPSE_MIN_NORMAL) {
        let xr = p / (w + c);
        cy = b * sqrt(max((1.0 - xr) * (1.0 + xr), 0.0));
    }
    return EllipseQuadrant(vec2<f32>(x / (w + c), cy), iterations);
}

// The closest point on the curve to p (any quadrant, any a, b).
fn ellipse_closest_point(a_in: f32, b_in: f32, p: vec2<f32>) -> EllipseClosest {
    let a = abs(a_in);
    let b = abs(b_in);
    let swap = b > a;
    var major = a;
    var minor = b;
    var x = abs(p.x);
    var y = abs(p.y);
    if (swap) {
        major = b;
        minor = a;
        x = abs(p.y);
        y = abs(p.x);
    }
    let r = ellipse_first_quadrant(major, minor, x, y);
    var c = r.point;
    let distance = ellipse_hypot(x - c.x, y - c.y);
    if (swap) {
        c = c.yx;
    }
    if (p.x < 0.0) {
        c.x = -c.x;
    }
    if (p.y < 0.0) {
        c.y = -c.y;
    }
    return EllipseClosest(distance, c, r.iterations);
}

// Distance from p to the filled ellipse: 0 inside or on the boundary.
fn ellipse_filled_distance(a: f32, b: f32, p: vec2<f32>) -> f32 {
    if (ellipse_inside(abs(a), abs(b), p)) {
        return 0.0;
    }
    return ellipse_closest_point(a, b, p).distance;
}
