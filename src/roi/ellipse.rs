//! PLACEHOLDER for local testing only: replaced by the ellipse branch on merge.
use glam::DVec2;
pub struct ClosestPoint {
    pub distance: f64,
    pub point: DVec2,
    pub iterations: u32,
    pub inside: bool,
}
#[must_use]
pub fn closest_point_on_ellipse(a: f64, b: f64, p: DVec2) -> ClosestPoint {
    let (sx, sy) = (p.x.signum(), p.y.signum());
    let (x, y) = (p.x.abs(), p.y.abs());
    let inside = (x / a).powi(2) + (y / b).powi(2) <= 1.0;
    // bisection on t in the Lagrange form q = (a²x/(t+a²), b²y/(t+b²)), t > -min(a²,b²)
    let f = |t: f64| (a * x / (t + a * a)).powi(2) + (b * y / (t + b * b)).powi(2) - 1.0;
    let m = (a * a).min(b * b);
    let (mut lo, mut hi) = (-m, 1e300f64);
    if !inside { lo = 0.0; hi = (x * x + y * y).sqrt() * a.max(b) + 1.0; } else { hi = 0.0; }
    let mut it = 0;
    for _ in 0..2000 { it += 1; let mid = 0.5 * (lo + hi); if mid <= lo || mid >= hi { break; } if f(mid) > 0.0 { lo = mid } else { hi = mid } }
    let t = 0.5 * (lo + hi);
    let q = DVec2::new(sx * a * a * x / (t + a * a), sy * b * b * y / (t + b * b));
    ClosestPoint { distance: (q - p).length(), point: q, iterations: it, inside }
}
#[must_use]
pub fn distance_to_filled_ellipse(a: f64, b: f64, p: DVec2) -> f64 {
    if (p.x / a).powi(2) + (p.y / b).powi(2) <= 1.0 { 0.0 } else { closest_point_on_ellipse(a, b, p).distance }
}
