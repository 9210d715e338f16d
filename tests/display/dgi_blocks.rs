//! The block-pruned CPU DGI (`compute_cpu`) against the straightforward per-pixel reference
//! (`compute_cpu_reference`) on many walls, poses, FOVs and metrics, raw and normalised.

use crate::walls;

use glam::DVec2;
use raygun::display::DisplayModel;
use raygun::roi::conic::ConicKind;
use raygun::roi::dgi::{
    BLOCK, DgiParams, Falloff, Guide, Metric, Roi, Surface, compute_cpu, compute_cpu_f64,
    compute_cpu_reference, roi_radius_m,
};

fn model(name: &str) -> DisplayModel {
    DisplayModel::load(format!(
        "{}/display-models/{name}",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
}

/// Three columns of 1000×600 px at 1 mm pitch, 30° between neighbours (as in dgi_twins.rs):
/// its grazing poses give hyperbola and parabola pieces.
fn curved_wall() -> Surface {
    let json = r#"{"name": "test wall", "notes": "built in tests/dgi_blocks.rs",
        "generator": {"columns": 3, "rows": 1, "resolution": [1000, 600],
        "active_size": [1.0, 0.6],
        "bezel": {"left": 0.0, "right": 0.0, "top": 0.0, "bottom": 0.0},
        "yaw_step_deg": 30.0, "center": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0],
        "up": [0.0, 1.0, 0.0]}}"#;
    Surface::from_model(&DisplayModel::from_json(json, "curved_wall").unwrap())
}

fn cone(o: [f64; 3], d: [f64; 3], fh: f64, fv: f64) -> Roi {
    Roi::Cone(walls::cone(o, d, fh, fv))
}

/// The pruned DGI may differ from the reference only by the solvers' rounding: which pieces are
/// solved, and in which order, changes, but a pruned piece is provably no nearer. Allowed:
/// 1e-14 of the canvas scale (the solvers' backward error bound, tests/display/ellipse_hard_cases.rs), in
/// raw canvas px, divided by L for normalised values.
const REL_TO_SCALE: f64 = 1e-14;

/// Compares the pruned and the reference DGI (f64 and f32 outputs), raw and with falloff `l`.
fn check(surface: &Surface, roi: &Roi, metric: Metric, size: [u32; 2], l: f64, what: &str) {
    let guide = match Guide::new(surface, roi, metric) {
        Ok(g) => g,
        Err(e) => panic!("{what} {metric:?}: {e}"),
    };
    let c = surface.canvas;
    let scale = c
        .min
        .abs()
        .max(c.max.abs())
        .max_element()
        .max(c.size().length());
    for falloff_px in [None, Some(l)] {
        let p = DgiParams {
            width: size[0],
            height: size[1],
            falloff_px,
        };
        let reference = compute_cpu_reference(surface, &guide, &p);
        let fast = compute_cpu_f64(surface, &guide, &p);
        let fast32 = compute_cpu(surface, &guide, &p);
        let tol = REL_TO_SCALE * scale / falloff_px.unwrap_or(1.0);
        for (i, ((r, f), f32v)) in reference.iter().zip(&fast).zip(&fast32).enumerate() {
            assert!(
                (r - f).abs() <= tol || r == f,
                "{what} {metric:?} L={falloff_px:?}: pixel ({}, {}): reference {r}, blocked {f}",
                i % size[0] as usize,
                i / size[0] as usize
            );
            assert_eq!(
                *f32v, *f as f32,
                "{what}: f32 output is the f64 one rounded"
            );
        }
    }
}

fn kinds(surface: &Surface, roi: &Roi) -> Vec<&'static str> {
    match Guide::new(surface, roi, Metric::Exact).unwrap() {
        Guide::Pieces(pieces) => pieces
            .iter()
            .map(|p| match p.conic.kind {
                ConicKind::Empty => "empty",
                ConicKind::Ellipse { .. } => "ellipse",
                ConicKind::Hyperbola { .. } => "hyperbola",
                ConicKind::Parabola { .. } => "parabola",
            })
            .collect(),
        Guide::Angular { .. } => vec![],
    }
}

/// Image sizes that are not multiples of the block (partial blocks at the right and bottom).
const SIZE: [u32; 2] = [150, 85];

#[test]
fn block_size_leaves_partial_blocks_in_these_tests() {
    assert!(!(SIZE[0] as usize).is_multiple_of(BLOCK) && !(SIZE[1] as usize).is_multiple_of(BLOCK));
}

#[test]
fn pruned_matches_reference_on_hornet_paper_setup_and_hard_poses() {
    let surface = Surface::from_model(&model("hornet.json"));
    let poses = [
        (
            "paper 10°",
            cone([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 10.0, 10.0),
        ),
        (
            "paper 30°",
            cone([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 30.0, 30.0),
        ),
        (
            "paper 60°",
            cone([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 60.0, 60.0),
        ),
        (
            "oblique, several columns",
            cone([0.5, 0.2, 1.5], [-0.4, -0.1, -1.0], 70.0, 40.0),
        ),
        (
            "partly off the top",
            cone([0.0, 0.0, 1.0], [0.0, 1.4, -1.0], 30.0, 30.0),
        ),
        (
            "grazing along the wall",
            cone([-3.6, 0.0, 0.05], [1.0, 0.0, 0.0], 40.0, 40.0),
        ),
        (
            "FOV near 0°",
            cone([0.0, 0.0, 1.0], [0.1, 0.0, -1.0], 1e-4, 1e-4),
        ),
        (
            "FOV near 180°",
            cone([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 179.9, 179.9),
        ),
        (
            "behind the wall",
            cone([0.0, 0.0, -1.0], [0.0, 0.0, 1.0], 30.0, 30.0),
        ),
    ];
    for (what, roi) in poses {
        let l = Falloff::default().length_px(roi_radius_m(&surface, &roi), surface.pitch_m);
        let l = if l > 0.0 { l } else { 1000.0 };
        for metric in [Metric::Exact, Metric::Ellipse, Metric::Angular] {
            if Guide::new(&surface, &roi, metric).is_err() {
                assert_ne!(metric, Metric::Exact, "{what}");
                continue;
            }
            check(&surface, &roi, metric, SIZE, l, what);
        }
    }
}

#[test]
fn pruned_matches_reference_on_hyperbola_and_parabola_pieces() {
    let surface = curved_wall();
    let poses = [
        (
            "oblique",
            cone([0.2, 0.1, 0.8], [0.6, 0.0, -1.0], 60.0, 40.0),
        ),
        (
            "grazing",
            cone([-0.4, 0.0, 0.3], [1.0, 0.0, -0.35], 60.0, 60.0),
        ),
        (
            "generator parallel to the centre column",
            cone(
                [-0.9, 0.0, 0.6],
                [60f64.to_radians().sin(), 0.0, -60f64.to_radians().cos()],
                60.0,
                60.0,
            ),
        ),
    ];
    let mut seen = std::collections::BTreeSet::new();
    for (what, roi) in poses {
        seen.extend(kinds(&surface, &roi));
        for l in [50.0, 400.0, 3000.0] {
            check(&surface, &roi, Metric::Exact, [211, 67], l, what);
        }
    }
    for kind in ["ellipse", "hyperbola", "parabola"] {
        assert!(seen.contains(kind), "no {kind} piece among {seen:?}");
    }
}

#[test]
fn pruned_matches_reference_for_the_mouse_ellipse_and_other_walls() {
    for name in ["desktop-27in-4k.json", "projection-4m-4k.json"] {
        let surface = Surface::from_model(&model(name));
        let mid = surface.canvas.center();
        for (center, axes) in [
            (mid, DVec2::new(300.0, 150.0)),
            // Partly off the canvas's corner.
            (
                surface.canvas.min + DVec2::new(50.0, 20.0),
                DVec2::new(400.0, 90.0),
            ),
            // A segment-thin ellipse.
            (mid, DVec2::new(500.0, 0.0)),
        ] {
            let roi = Roi::CanvasEllipse {
                center,
                semi_axes: axes,
            };
            check(&surface, &roi, Metric::Exact, SIZE, 700.0, name);
        }
        let roi = cone([0.1, -0.05, 0.9], [0.0, 0.0, -1.0], 25.0, 15.0);
        for metric in [Metric::Exact, Metric::Ellipse, Metric::Angular] {
            check(&surface, &roi, metric, SIZE, 900.0, name);
        }
    }
}

/// The pruning's shortcuts are exercised: on the paper's 60° setup the normalised image has
/// whole blocks of exact zeros (inside) and exact ones (beyond L) as well as values between.
#[test]
fn paper_setup_has_inside_far_and_band_pixels() {
    let surface = Surface::from_model(&model("hornet.json"));
    let roi = cone([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 60.0, 60.0);
    let l = Falloff::default().length_px(roi_radius_m(&surface, &roi), surface.pitch_m);
    let guide = Guide::new(&surface, &roi, Metric::Exact).unwrap();
    let d = compute_cpu(
        &surface,
        &guide,
        &DgiParams {
            width: 384,
            height: 216,
            falloff_px: Some(l),
        },
    );
    let zeros = d.iter().filter(|&&v| v == 0.0).count();
    let ones = d.iter().filter(|&&v| v == 1.0).count();
    let between = d.len() - zeros - ones;
    assert!(
        zeros > 4 * BLOCK * BLOCK && ones > 4 * BLOCK * BLOCK && between > d.len() / 2,
        "zeros {zeros}, ones {ones}, between {between}"
    );
}
