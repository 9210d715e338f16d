use super::*;

/// A 2000×1000 px patch in the plane z = 0 with 1 mm pixels, canvas (0,0) at room (−1, 0.5, 0).
fn flat_patch() -> Patch {
    Patch {
        rect: Rect {
            min: DVec2::ZERO,
            max: DVec2::new(2000.0, 1000.0),
        },
        origin: DVec3::new(-1.0, 0.5, 0.0),
        ex: DVec3::new(1e-3, 0.0, 0.0),
        ey: DVec3::new(0.0, -1e-3, 0.0),
    }
}

/// Brute-force distance: densely sample the region inside the rect via the cone predicate.
fn brute_distance(cone: &Cone, patch: &Patch, c: DVec2, step: f64) -> f64 {
    let mut best = f64::INFINITY;
    let r = patch.rect;
    let mut y = r.min.y;
    while y <= r.max.y {
        let mut x = r.min.x;
        while x <= r.max.x {
            let q = DVec2::new(x, y);
            if cone.contains(patch.point(q)) {
                best = best.min((q - c).length());
            }
            x += step;
        }
        y += step;
    }
    best
}

/// The exact answer is feasible (its point is in the rect and, up to rounding, in the cone)
/// and no sampled region point is nearer.
fn check_against_brute_force(cone: &Cone, patch: &Patch, piece: &Piece, c: DVec2) {
    let (exact, q) = piece.closest(c);
    assert!(((q - c).length() - exact).abs() < 1e-9);
    assert!(
        patch.rect.contains(q),
        "{c}: nearest point {q} outside the rect"
    );
    // On the boundary: the cone's normalised radius there is 1 up to rounding.
    let w = patch.point(q) - cone.apex;
    let z = w.dot(cone.axis);
    let rad = ((w.dot(cone.right) / (z * cone.tan_h)).powi(2)
        + (w.dot(cone.up) / (z * cone.tan_v)).powi(2))
    .sqrt();
    assert!(
        z > 0.0 && rad <= 1.0 + 1e-9,
        "{c}: nearest point {q} not in the cone ({rad})"
    );
    let brute = brute_distance(cone, patch, c, 2.0);
    assert!(exact <= brute + 1e-9, "{c}: {exact} > sampled {brute}");
}

#[test]
fn head_on_circle_is_a_circle_of_the_right_radius() {
    let patch = flat_patch();
    let cone = Cone::from_pose(
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::NEG_Z,
        DVec3::Y,
        20.0,
        20.0,
    )
    .unwrap();
    let conic = section(&cone, &patch);
    let r_px = (10f64).to_radians().tan() * 1000.0;
    match conic.kind {
        ConicKind::Ellipse { a, b } => {
            assert!(
                (a - r_px).abs() < 1e-9 && (b - r_px).abs() < 1e-9,
                "{a} {b}"
            );
        }
        k => panic!("expected an ellipse, got {k:?}"),
    }
    assert!((conic.origin - DVec2::new(1000.0, 500.0)).length() < 1e-9);
    let piece = Piece::new(patch.rect, conic).unwrap();
    assert_eq!(piece.distance(DVec2::new(1000.0, 500.0)), 0.0);
    let d = piece.distance(DVec2::new(1000.0 + r_px + 50.0, 500.0));
    assert!((d - 50.0).abs() < 1e-9, "{d}");
}

#[test]
fn pointing_away_gives_nothing() {
    let patch = flat_patch();
    let cone = Cone::from_pose(DVec3::new(0.0, 0.0, 1.0), DVec3::Z, DVec3::Y, 60.0, 60.0).unwrap();
    assert_eq!(section(&cone, &patch).kind, ConicKind::Empty);
}

#[test]
fn grazing_cone_is_a_hyperbola_and_matches_brute_force() {
    let patch = flat_patch();
    // 70° off the normal with a 60° cone: the cone's far generator never meets the plane.
    let dir = DVec3::new((70f64).to_radians().sin(), 0.0, -(70f64).to_radians().cos());
    let cone = Cone::from_pose(DVec3::new(-1.2, 0.0, 0.4), dir, DVec3::Y, 60.0, 40.0).unwrap();
    let conic = section(&cone, &patch);
    assert!(
        matches!(conic.kind, ConicKind::Hyperbola { .. }),
        "{conic:?}"
    );
    let piece = Piece::new(patch.rect, conic).unwrap();
    for c in [
        DVec2::new(10.0, 500.0),
        DVec2::new(1990.0, 20.0),
        DVec2::new(-300.0, 1200.0),
        DVec2::new(1500.0, 900.0),
        DVec2::new(2500.0, -100.0),
    ] {
        check_against_brute_force(&cone, &patch, &piece, c);
    }
}

#[test]
fn parabola_at_exact_tangency() {
    let patch = flat_patch();
    // Axis 60° off the normal with a 60° cone: one generator is parallel to the plane.
    let dir = DVec3::new((60f64).to_radians().sin(), 0.0, -(60f64).to_radians().cos());
    let cone = Cone::from_pose(DVec3::new(-1.5, 0.0, 0.6), dir, DVec3::Y, 60.0, 60.0).unwrap();
    let conic = section(&cone, &patch);
    assert!(
        matches!(conic.kind, ConicKind::Parabola { .. }),
        "expected a parabola, got {conic:?}"
    );
    let piece = Piece::new(patch.rect, conic).unwrap();
    for c in [
        DVec2::new(10.0, 500.0),
        DVec2::new(300.0, 100.0),
        DVec2::new(1900.0, 990.0),
    ] {
        check_against_brute_force(&cone, &patch, &piece, c);
    }
}

/// A big oblique ROI overlapping the right edge of [`flat_patch`].
fn oblique_cone() -> Cone {
    Cone::from_pose(
        DVec3::new(0.9, 0.2, 1.0),
        DVec3::new(0.2, -0.1, -1.0),
        DVec3::Y,
        50.0,
        30.0,
    )
    .unwrap()
}

#[test]
fn clipped_ellipse_matches_brute_force_off_the_rect() {
    let patch = flat_patch();
    let cone = oblique_cone();
    let conic = section(&cone, &patch);
    assert!(matches!(conic.kind, ConicKind::Ellipse { .. }), "{conic:?}");
    let piece = Piece::new(patch.rect, conic).unwrap();
    assert!(!piece.edges.is_empty(), "the ROI crosses the patch's edge");
    for c in [
        DVec2::new(2600.0, 500.0),
        DVec2::new(2100.0, -300.0),
        DVec2::new(500.0, 500.0),
        DVec2::new(1999.0, 999.0),
    ] {
        check_against_brute_force(&cone, &patch, &piece, c);
    }
}

/// The prepared piece's distance (one inside test, no edges when the curve point is in the
/// rectangle) equals the reference `Piece::distance` to rounding, on a grid around an
/// ellipse piece clipped by the patch's edge, warm-started along each row as the DGI does.
#[test]
fn prepared_distance_matches_the_reference() {
    let patch = flat_patch();
    let cone = oblique_cone();
    let piece = Piece::new(patch.rect, section(&cone, &patch)).unwrap();
    assert!(!piece.edges.is_empty());
    let prepared = piece.prepare();
    let (mut zero, mut edge, mut curve) = (0, 0, 0);
    for j in 0..60 {
        let mut root = f64::NAN;
        for i in 0..80 {
            let c = DVec2::new(-500.0 + 50.0 * f64::from(i), -400.0 + 35.0 * f64::from(j));
            let got = prepared.distance_hinted(c, &mut root);
            let want = piece.distance(c);
            assert!((got - want).abs() <= 1e-14 * 4000.0, "{c}: {got} vs {want}");
            let (_, q) = piece.closest(c);
            if want == 0.0 {
                zero += 1;
            } else if piece.edges.iter().any(|e| e.closest(c).1 == q) {
                edge += 1;
            } else {
                curve += 1;
            }
        }
    }
    assert!(zero > 0 && edge > 0 && curve > 0, "{zero} {edge} {curve}");
}

/// Four rows at once, warm-started along each row as the DGI does, with some lanes switched
/// off: every needed lane is bit-identical to the one-query path with the same roots, and
/// the others keep their roots. Covers zero, curve and edge answers and a hyperbola piece
/// (no ellipse solver).
#[test]
fn prepared_lanes_are_bit_identical_to_one_at_a_time() {
    let patch = flat_patch();
    let ellipse = oblique_cone();
    let hyperbola = PlacedConic {
        kind: ConicKind::Hyperbola { b2: 4e4, s: 0.7 },
        origin: DVec2::new(900.0, 300.0),
        axis_u: DVec2::new(0.8, 0.6),
    };
    for piece in [
        Piece::new(patch.rect, section(&ellipse, &patch)).unwrap(),
        Piece::new(patch.rect, hyperbola).unwrap(),
    ] {
        let prepared = piece.prepare();
        for j0 in (0..60).step_by(4) {
            let (mut roots, mut alone) = (f64x4::splat(f64::NAN), [f64::NAN; 4]);
            for i in 0..80 {
                let c = [0, 1, 2, 3].map(|l| {
                    DVec2::new(
                        -500.0 + 50.0 * f64::from(i),
                        -400.0 + 35.0 * f64::from(j0 + l),
                    )
                });
                let need = [i % 7 != 3, true, (i + j0) % 5 != 0, i % 2 == 0];
                let before = roots.to_array();
                let got = prepared
                    .distance_hinted_lanes(
                        f64x4::new(c.map(|c| c.x)),
                        f64x4::new(c.map(|c| c.y)),
                        &mut roots,
                        lane_mask(need),
                    )
                    .to_array();
                let after = roots.to_array();
                for l in 0..4 {
                    if !need[l] {
                        assert_eq!(got[l], f64::INFINITY);
                        assert_eq!(after[l].to_bits(), before[l].to_bits());
                        continue;
                    }
                    let want = prepared.distance_hinted(c[l], &mut alone[l]);
                    assert_eq!(
                        got[l].to_bits(),
                        want.to_bits(),
                        "{}: {} vs {want}",
                        c[l],
                        got[l]
                    );
                    assert_eq!(after[l].to_bits(), alone[l].to_bits(), "{}", c[l]);
                }
            }
        }
    }
}

/// Every sampled point of rect ∩ K lies in the piece's box, and the box is tight: each
/// side is within a sampling step (plus the padding) of a sampled point.
fn check_bounds(piece: &Piece, step: f64) {
    let (r, b) = (piece.rect, piece.bounds);
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    let mut y = r.min.y;
    while y <= r.max.y {
        let mut x = r.min.x;
        while x <= r.max.x {
            let q = DVec2::new(x, y);
            if piece.conic.contains_local(piece.conic.to_local(q)) {
                assert!(b.contains(q), "{q} in the piece but not in its box {b:?}");
                lo = lo.min(q);
                hi = hi.max(q);
            }
            x += step;
        }
        y += step;
    }
    let slack = 1.5 * step + BOUNDS_PAD * r.size().length();
    assert!(
        (lo - b.min).max_element() <= slack && (b.max - hi).max_element() <= slack,
        "box {b:?} is loose around the samples {lo}..{hi}"
    );
}

#[test]
fn piece_boxes_are_tight_for_every_kind() {
    let patch = flat_patch();
    let poses = [
        // Clipped ellipse, hyperbola, parabola (the poses of the tests above).
        (
            DVec3::new(0.9, 0.2, 1.0),
            DVec3::new(0.2, -0.1, -1.0),
            50.0,
            30.0,
        ),
        (
            DVec3::new(-1.2, 0.0, 0.4),
            DVec3::new((70f64).to_radians().sin(), 0.0, -(70f64).to_radians().cos()),
            60.0,
            40.0,
        ),
        (
            DVec3::new(-1.5, 0.0, 0.6),
            DVec3::new((60f64).to_radians().sin(), 0.0, -(60f64).to_radians().cos()),
            60.0,
            60.0,
        ),
        // A rotated hyperbola reaching into the patch from a corner.
        (
            DVec3::new(-1.3, 0.7, 0.3),
            DVec3::new(0.8, -0.5, -0.45),
            50.0,
            30.0,
        ),
    ];
    let mut kinds = Vec::new();
    for (o, d, fh, fv) in poses {
        let cone = Cone::from_pose(o, d, DVec3::Y, fh, fv).unwrap();
        let piece = Piece::new(patch.rect, section(&cone, &patch)).unwrap();
        check_bounds(&piece, 4.0);
        kinds.push(std::mem::discriminant(&piece.conic.kind));
    }
    assert!(kinds.contains(&std::mem::discriminant(&ConicKind::Parabola { c: 1.0 })));
    assert!(
        kinds.contains(&std::mem::discriminant(&ConicKind::Hyperbola {
            b2: 1.0,
            s: 1.0
        }))
    );
}

#[test]
fn epigraph_solver_hits_known_answers() {
    // Parabola v ≥ u²: the nearest point to (0, −1) is the vertex.
    let par = PlacedConic {
        kind: ConicKind::Parabola { c: 1.0 },
        origin: DVec2::ZERO,
        axis_u: DVec2::X,
    };
    let (d, q) = par.closest_local(DVec2::new(0.0, -1.0)).unwrap();
    assert!((d - 1.0).abs() < 1e-15 && q == DVec2::ZERO);
    // Wedge v ≥ |u| (B = 0, s = 1): nearest point to (2, 0) is (1, 1) at √2.
    let wedge = PlacedConic {
        kind: ConicKind::Hyperbola { b2: 0.0, s: 1.0 },
        origin: DVec2::ZERO,
        axis_u: DVec2::X,
    };
    let (d, q) = wedge.closest_local(DVec2::new(2.0, 0.0)).unwrap();
    assert!((d - 2f64.sqrt()).abs() < 1e-14, "{d}");
    assert!((q - DVec2::ONE).length() < 1e-14);
    // Mirror symmetry.
    let (d2, q2) = wedge.closest_local(DVec2::new(-2.0, 0.0)).unwrap();
    assert_eq!(d, d2);
    assert_eq!(q2, DVec2::new(-q.x, q.y));
    // Hyperbola v ≥ √(1 + u²): nearest point to the origin is (0, 1).
    let hyp = PlacedConic {
        kind: ConicKind::Hyperbola { b2: 1.0, s: 1.0 },
        origin: DVec2::ZERO,
        axis_u: DVec2::X,
    };
    let (d, _) = hyp.closest_local(DVec2::ZERO).unwrap();
    assert!((d - 1.0).abs() < 1e-15);
}

#[test]
fn quadratic_roots_are_stable() {
    let r = quadratic_roots(1.0, -1e8, 1.0);
    let small = r.iter().copied().fold(f64::INFINITY, f64::min);
    assert!((small - 1e-8).abs() < 1e-22, "{small}");
    assert!(quadratic_roots(1.0, 0.0, 1.0).is_empty());
    assert_eq!(quadratic_roots(0.0, 2.0, -1.0), vec![0.5]);
}
