// PLACEHOLDER (replaced by the ellipse branch): filled-ellipse distance and nearest point.
fn ellipse_filled_closest(a: f32, b: f32, p: vec2<f32>) -> vec3<f32> {
    let x = abs(p.x);
    let y = abs(p.y);
    if (x / a) * (x / a) + (y / b) * (y / b) <= 1.0 {
        return vec3<f32>(0.0, p);
    }
    var lo = 0.0;
    var hi = length(vec2<f32>(x, y)) * max(a, b) + 1.0;
    for (var i = 0u; i < 200u; i++) {
        let t = 0.5 * (lo + hi);
        let f = (a * x / (t + a * a)) * (a * x / (t + a * a)) + (b * y / (t + b * b)) * (b * y / (t + b * b)) - 1.0;
        if f > 0.0 { lo = t; } else { hi = t; }
    }
    let t = 0.5 * (lo + hi);
    let q = vec2<f32>(sign(p.x) * a * a * x / (t + a * a), sign(p.y) * b * b * y / (t + b * b));
    return vec3<f32>(length(q - p), q);
}
