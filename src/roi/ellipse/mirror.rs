//! f32: the mirror of `shaders/roi/ellipse.wgsl`, op for op (same order, same constants), so
//! that CPU tests check the bound the GPU kernel is held to. Keep the two in step.

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
pub const WGSL: &str = include_str!("../../../shaders/roi/ellipse.wgsl");

const NEWTON_TOL_F32: f32 = 4.0 * f32::EPSILON;
/// 2¹⁰⁰, the f32 counterpart of [`FAR_F64`]; equals `ELLIPSE_FAR` in the WGSL.
const FAR_F32: f32 = 1.267_650_6e30;

/// The f32 counterpart of [`ClosestPoint`](super::ClosestPoint), as the WGSL's `EllipseClosest` returns it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPointF32 {
    pub distance: f32,
    pub point: [f32; 2],
    /// At most [`MAX_ITERATIONS_F32`].
    pub iterations: u32,
}

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
