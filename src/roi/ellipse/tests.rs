use wide::f64x4;

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
    let csv = include_str!("../../../tests/data/ellipse_hard_cases.csv");
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
