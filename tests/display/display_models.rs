//! Display-model files: the loader's errors (one test per kind of bad input, each checking that
//! the file, tile and field are named), the generator's expansion, the shipped models, the
//! `display expand` round trip, and a never-panics property for arbitrary input.

use std::path::PathBuf;

use glam::{DVec2, DVec3};
use proptest::prelude::*;
use raygun::cli::display::{ExpandArgs, expand};
use raygun::display::{
    DisplayModel, DisplayModelError, DisplayModelSpec, GeneratorSpec, PITCH_REL_TOL, Problem,
    SEAM_TOL_M,
};
use serde_json::{Value, json};

fn model_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("display-models")
        .join(name)
}

fn load(name: &str) -> DisplayModel {
    DisplayModel::load(model_path(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// Three flat tiles in a row, 100×50 px at 1 cm pitch (1.0 × 0.5 m active), 2 cm bezels (2 px):
/// a valid explicit model that the error tests break one field at a time. Canvas rectangles
/// with bezels are 104 px wide, so tile k's active area starts at canvas x = 104k + 2; in 3D the
/// row spans x ∈ [−1.56, 1.56] m in the plane z = 0 and tile k's outer left edge is at
/// x = −1.56 + 1.04k.
fn three_tiles() -> Value {
    let tile = |k: usize, id: &str| {
        let x0 = -1.56 + 1.04 * k as f64 + 0.02;
        json!({
            "id": id, "column": k, "row": 0, "resolution": [100, 50],
            "top_left": [x0, 0.25, 0.0], "top_right": [x0 + 1.0, 0.25, 0.0],
            "bottom_left": [x0, -0.25, 0.0],
            "bezel": {"left": 0.02, "right": 0.02, "top": 0.02, "bottom": 0.02},
            "canvas": [104.0 * k as f64 + 2.0, 2.0]
        })
    };
    json!({
        "name": "three", "notes": "test rig",
        "tiles": [tile(0, "a"), tile(1, "b"), tile(2, "c")]
    })
}

fn parse(v: &Value) -> Result<DisplayModel, DisplayModelError> {
    DisplayModel::from_json(&serde_json::to_string_pretty(v).unwrap(), "rig.json")
}

/// The (tile, field, problem) of a validation error, after checking that it names the file and
/// that its message shows all three.
fn invalid(r: Result<DisplayModel, DisplayModelError>) -> (Option<String>, String, Problem) {
    let e = r.expect_err("the model should have been rejected");
    assert_eq!(e.file(), "rig.json");
    let text = e.to_string();
    match e {
        DisplayModelError::Invalid {
            tile,
            field,
            problem,
            ..
        } => {
            assert!(text.starts_with("rig.json: "), "{text}");
            assert!(text.contains(&format!("field `{field}`")), "{text}");
            if let Some(id) = &tile {
                assert!(text.contains(&format!("tile {id:?}")), "{text}");
            }
            (tile, field, problem)
        }
        other => panic!("expected a validation error, got {other}"),
    }
}

#[test]
fn rig_is_valid_and_flat() {
    let m = parse(&three_tiles()).unwrap();
    assert_eq!(m.tiles().len(), 3);
    assert!((m.pitch_m() - 0.01).abs() < 1e-15);
    assert_eq!(m.canvas_rect().size(), DVec2::new(312.0, 54.0));
}

#[test]
fn syntax_error_reports_line_and_column() {
    let text = "{\n  \"name\": \"x\",\n  \"tiles\": [\n    {\"id\": \"a\" \"column\": 0}\n  ]\n}";
    match DisplayModel::from_json(text, "bad.json").unwrap_err() {
        DisplayModelError::Json {
            file, line, column, ..
        } => {
            assert_eq!((file.as_str(), line), ("bad.json", 4));
            assert_eq!(column, 16, "column of the unexpected string");
        }
        e => panic!("{e}"),
    }
}

#[test]
fn wrong_type_and_unknown_field_report_line() {
    let mut v = three_tiles();
    v["tiles"][1]["resolution"] = json!("big");
    let e = parse(&v).unwrap_err();
    assert!(matches!(e, DisplayModelError::Json { .. }), "{e}");
    assert!(e.to_string().starts_with("rig.json:"), "{e}");

    let mut v = three_tiles();
    v["tiles"][0]["bezle"] = json!(0.0);
    let e = parse(&v).unwrap_err().to_string();
    assert!(e.contains("unknown field `bezle`"), "{e}");
}

#[test]
fn empty_input_is_a_json_error() {
    let e = DisplayModel::from_json("", "empty.json").unwrap_err();
    assert!(matches!(e, DisplayModelError::Json { line: 1, .. }), "{e}");
}

#[test]
fn missing_file_names_the_file() {
    let e = DisplayModel::load("/nonexistent/wall.json").unwrap_err();
    assert!(matches!(e, DisplayModelError::Io { .. }));
    assert!(e.to_string().contains("/nonexistent/wall.json"), "{e}");
}

#[test]
fn non_finite_corner_names_tile_and_field() {
    // JSON cannot spell NaN, but a spec built in code (or arithmetic) can.
    let mut spec: DisplayModelSpec = serde_json::from_value(three_tiles()).unwrap();
    spec.tiles.as_mut().unwrap()[1].top_right[2] = f64::NAN;
    let (tile, field, problem) = invalid(DisplayModel::from_spec(&spec, "rig.json"));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("b"), "top_right"));
    assert_eq!(problem, Problem::NonFinite);

    let mut spec: DisplayModelSpec = serde_json::from_value(three_tiles()).unwrap();
    spec.tiles.as_mut().unwrap()[2].bezel.top = f64::INFINITY;
    let (tile, field, _) = invalid(DisplayModel::from_spec(&spec, "rig.json"));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("c"), "bezel.top"));
}

#[test]
fn json_number_out_of_f64_range_is_a_json_error() {
    let text = serde_json::to_string(&three_tiles())
        .unwrap()
        .replacen("0.25", "1e400", 1);
    let e = DisplayModel::from_json(&text, "rig.json").unwrap_err();
    assert!(matches!(e, DisplayModelError::Json { .. }), "{e}");
}

#[test]
fn absurdly_large_coordinate_is_rejected() {
    let mut v = three_tiles();
    v["tiles"][0]["canvas"] = json!([1e300, 2.0]);
    let (tile, field, problem) = invalid(parse(&v));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("a"), "canvas"));
    assert!(matches!(problem, Problem::TooLarge { .. }));
}

#[test]
fn zero_and_negative_resolution_name_the_tile() {
    for bad in [0, -1920, 1 << 40] {
        let mut v = three_tiles();
        v["tiles"][2]["resolution"] = json!([100, bad]);
        let (tile, field, problem) = invalid(parse(&v));
        assert_eq!((tile.as_deref(), field.as_str()), (Some("c"), "resolution"));
        assert_eq!(problem, Problem::ResolutionOutOfRange { value: bad });
    }
}

#[test]
fn zero_length_edge_is_degenerate() {
    let mut v = three_tiles();
    v["tiles"][1]["top_right"] = v["tiles"][1]["top_left"].clone();
    let (tile, field, problem) = invalid(parse(&v));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("b"), "top_right"));
    assert!(matches!(problem, Problem::DegenerateEdge { length_m } if length_m == 0.0));
}

#[test]
fn sheared_corners_are_not_perpendicular() {
    let mut v = three_tiles();
    // Bottom-left moved 1 cm sideways over a 0.5 m edge: cos ≈ 0.02, far over 1e-3.
    v["tiles"][0]["bottom_left"][0] = json!(-1.54 + 0.01);
    let (tile, field, problem) = invalid(parse(&v));
    assert_eq!(
        (tile.as_deref(), field.as_str()),
        (Some("a"), "bottom_left")
    );
    assert!(matches!(problem, Problem::NotPerpendicular { cos } if (cos - 0.02).abs() < 1e-3));
}

#[test]
fn pitch_differing_between_axes_is_rejected() {
    let mut v = three_tiles();
    // 1.0 m / 100 px across, 0.5 m / 51 px down: one pixel off, 2 % apart.
    v["tiles"][1]["resolution"] = json!([100, 51]);
    let (tile, field, problem) = invalid(parse(&v));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("b"), "resolution"));
    assert!(matches!(problem, Problem::PitchAxes { .. }));
}

#[test]
fn pitch_differing_between_tiles_blames_the_odd_one() {
    let mut v = three_tiles();
    // Tile c: the same 1.0 × 0.5 m with twice the pixels: square pixels, but half the pitch.
    v["tiles"][2]["resolution"] = json!([200, 100]);
    let (tile, field, problem) = invalid(parse(&v));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("c"), "resolution"));
    let Problem::PitchModel { tile_m, model_m } = problem else {
        panic!("{problem:?}")
    };
    assert!((tile_m - 0.005).abs() < 1e-15 && (model_m - 0.01).abs() < 1e-15);
}

#[test]
fn pitch_within_tolerance_is_accepted() {
    let mut v = three_tiles();
    // Stretch tile c's active area by 1e-4 relative (under PITCH_REL_TOL) about its centre.
    let grow = 0.5 * 1e-4;
    let x0 = -1.56 + 2.08 + 0.02;
    v["tiles"][2]["top_left"][0] = json!(x0 - grow);
    v["tiles"][2]["bottom_left"][0] = json!(x0 - grow);
    v["tiles"][2]["top_right"][0] = json!(x0 + 1.0 + grow);
    const { assert!(1e-4 < PITCH_REL_TOL) };
    parse(&v).unwrap();
}

#[test]
fn overlapping_canvas_rectangles_are_rejected() {
    let mut v = three_tiles();
    v["tiles"][1]["canvas"] = json!([100.0, 2.0]); // 6 px into tile a's rectangle
    let (tile, field, problem) = invalid(parse(&v));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("b"), "canvas"));
    let Problem::CanvasOverlap { other, overlap_px } = &problem else {
        panic!("{problem:?}")
    };
    assert_eq!(other, "a");
    // 6 px along x, the full 54 px height along y.
    assert!(DVec2::from_array(*overlap_px).abs_diff_eq(DVec2::new(6.0, 54.0), 1e-9));
}

#[test]
fn canvas_contradicting_3d_geometry_is_a_seam_mismatch() {
    // Tile b moved 5 mm back in 3D while its canvas still says it touches a and c.
    let mut v = three_tiles();
    for corner in ["top_left", "top_right", "bottom_left"] {
        v["tiles"][1][corner][2] = json!(-0.005);
    }
    let (tile, field, problem) = invalid(parse(&v));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("b"), "canvas"));
    let Problem::SeamMismatch { other, gap_m } = &problem else {
        panic!("{problem:?}")
    };
    assert_eq!(other, "a");
    assert!((gap_m - 0.005).abs() < 1e-9, "{gap_m}");
}

#[test]
fn near_touching_canvas_placement_still_gets_the_3d_check() {
    // Tile c shifted 0.3 px right on the canvas (not touching, not overlapping) and 5 mm right
    // in 3D: the half-pixel gap tolerance still pairs it with b, and the 3D gap is caught.
    let mut v = three_tiles();
    v["tiles"][2]["canvas"][0] = json!(210.3);
    for corner in ["top_left", "top_right", "bottom_left"] {
        let x = v["tiles"][2][corner][0].as_f64().unwrap();
        v["tiles"][2][corner][0] = json!(x + 0.005);
    }
    let (tile, _, problem) = invalid(parse(&v));
    assert_eq!(tile.as_deref(), Some("c"));
    assert!(matches!(problem, Problem::SeamMismatch { gap_m, .. } if gap_m > SEAM_TOL_M));
}

#[test]
fn seam_within_a_millimetre_is_accepted() {
    let mut v = three_tiles();
    for corner in ["top_left", "top_right", "bottom_left"] {
        v["tiles"][1][corner][2] = json!(-0.0009);
    }
    parse(&v).unwrap();
}

#[test]
fn duplicate_id_and_grid_position() {
    let mut v = three_tiles();
    v["tiles"][2]["id"] = json!("a");
    let (tile, field, problem) = invalid(parse(&v));
    assert_eq!(
        (tile.as_deref(), field.as_str(), problem),
        (Some("a"), "id", Problem::DuplicateId)
    );

    let mut v = three_tiles();
    v["tiles"][2]["column"] = json!(0);
    let (tile, field, problem) = invalid(parse(&v));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("c"), "column"));
    assert_eq!(
        problem,
        Problem::DuplicateGridPosition { other: "a".into() }
    );

    let mut v = three_tiles();
    v["tiles"][1]["id"] = json!("");
    let (tile, field, _) = invalid(parse(&v));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("#1"), "id"));
}

#[test]
fn negative_bezel_is_rejected() {
    let mut v = three_tiles();
    v["tiles"][0]["bezel"]["left"] = json!(-0.001);
    let (tile, field, _) = invalid(parse(&v));
    assert_eq!((tile.as_deref(), field.as_str()), (Some("a"), "bezel.left"));
}

#[test]
fn model_level_problems() {
    let mut v = three_tiles();
    v["name"] = json!("  ");
    assert_eq!(invalid(parse(&v)).1, "name");

    let mut v = three_tiles();
    v["tiles"] = json!([]);
    assert_eq!(invalid(parse(&v)).2, Problem::Empty);

    let v = json!({"name": "nothing"});
    assert_eq!(invalid(parse(&v)).2, Problem::FormAmbiguous { both: false });

    let mut v = three_tiles();
    v["generator"] = hornet_generator_json();
    assert_eq!(invalid(parse(&v)).2, Problem::FormAmbiguous { both: true });
}

fn hornet_generator_json() -> Value {
    let text = std::fs::read_to_string(model_path("hornet.json")).unwrap();
    serde_json::from_str::<Value>(&text).unwrap()["generator"].clone()
}

#[test]
fn generator_errors_name_the_generator_field() {
    let cases: [(&str, Value, &str); 7] = [
        ("columns", json!(0), "generator.columns"),
        ("rows", json!(100_000), "generator.columns"),
        ("yaw_step_deg", json!(180.0), "generator.yaw_step_deg"),
        ("active_size", json!([-1.0, 0.5]), "generator.active_size"),
        ("active_size", json!([1.0181, 0.6]), "generator.active_size"),
        ("up", json!([0.0, 0.0, -2.0]), "generator.up"),
        ("normal", json!([0.0, 0.0, 0.0]), "generator.normal"),
    ];
    for (key, value, field) in cases {
        let mut g = hornet_generator_json();
        g[key] = value.clone();
        let v = json!({"name": "g", "generator": g});
        let (tile, got, problem) = invalid(parse(&v));
        assert_eq!(
            (tile, got.as_str()),
            (None, field),
            "{key} = {value}: {problem}"
        );
    }
}

// ---- the generator and the shipped models -------------------------------------------------

const HORNET_W: f64 = 1.0181;
const HORNET_H: f64 = 0.5727;
const HORNET_BEZEL: f64 = 0.003;

/// Bezel canvas widths use the model pitch while each tile's map uses its own (they differ by
/// 1.7e-5 relative on HORNET), so 3 mm of bezel lands 3 mm · 1.7e-5 ≈ 5e-8 m off; 1e-6 m bounds
/// that with margin and is still a thousand times below the loader's seam tolerance.
const HINGE_TOL_M: f64 = 1e-6;

#[test]
fn hornet_expands_to_35_tiles_with_one_pitch() {
    let m = load("hornet.json");
    assert_eq!(m.tiles().len(), 35);
    assert!(
        m.notes().contains("ASSUMPTIONS"),
        "HORNET's panel size must be marked as assumed"
    );
    let expected_pitch = (HORNET_W / 1920.0 + HORNET_H / 1080.0) / 2.0;
    assert!((m.pitch_m() - expected_pitch).abs() < 1e-15);
    for (i, t) in m.tiles().iter().enumerate() {
        let (c, r) = (i as u32 % 7, i as u32 / 7);
        assert_eq!(
            (t.column(), t.row(), t.id()),
            (c, r, format!("c{c}r{r}").as_str())
        );
        assert_eq!(t.resolution(), [1920, 1080]);
        let p = t.pitch();
        assert!((p.x - HORNET_W / 1920.0).abs() < 1e-15 && (p.y - HORNET_H / 1080.0).abs() < 1e-15);
    }
    // Canvas: 7 × (1920 + 2 bezels) by 5 × (1080 + 2 bezels), bezels at the model pitch.
    let bezel_px = HORNET_BEZEL / m.pitch_m();
    let size = m.canvas_rect().size();
    assert!((size.x - 7.0 * (1920.0 + 2.0 * bezel_px)).abs() < 1e-9);
    assert!((size.y - 5.0 * (1080.0 + 2.0 * bezel_px)).abs() < 1e-9);
    // The canvas starts at 0 (up to rounding of bezel/pitch, computed once by the generator and
    // once by the loader).
    assert!(m.canvas_rect().min.abs_diff_eq(DVec2::ZERO, 1e-9));
}

#[test]
fn hornet_centre_tile_is_at_the_origin_facing_the_viewer() {
    let m = load("hornet.json");
    let i = m.tile_index("c3r2").unwrap();
    let t = &m.tiles()[i];
    assert!(t.normal().abs_diff_eq(DVec3::Z, 1e-15));
    let centre = t.tile_px_to_point(DVec2::new(960.0, 540.0));
    assert!(centre.abs_diff_eq(DVec3::ZERO, 1e-12), "{centre}");
    for p in t.corners() {
        assert!(p.z.abs() < 1e-12, "central column plane is z = 0");
    }
    // Every other column of the central row curves towards the viewer (z > 0 at its centre).
    for c in [0, 1, 2, 4, 5, 6] {
        let t = &m.tiles()[m.tile_index(&format!("c{c}r2")).unwrap()];
        assert!(t.tile_px_to_point(DVec2::new(960.0, 540.0)).z > 0.0);
    }
}

#[test]
fn hornet_neighbouring_columns_are_10_degrees_apart_and_mirror_symmetric() {
    let m = load("hornet.json");
    let tile = |c: u32, r: u32| &m.tiles()[(r * 7 + c) as usize];
    for r in 0..5 {
        for c in 0..6 {
            let angle = tile(c, r).normal().angle_between(tile(c + 1, r).normal());
            assert!(
                (angle.to_degrees() - 10.0).abs() < 1e-9,
                "c{c}r{r}: {angle}"
            );
        }
        for c in 0..7 {
            // Mirror in x: the top-left of column c is the top-right of column 6 − c.
            let a = tile(c, r).corners()[0];
            let b = tile(6 - c, r).corners()[1];
            assert!(
                a.abs_diff_eq(b * DVec3::new(-1.0, 1.0, 1.0), 1e-12),
                "{a} vs {b}"
            );
        }
    }
}

#[test]
fn hornet_shared_edges_coincide_in_3d() {
    let m = load("hornet.json");
    let n = m.tiles().len();
    let mut shared = 0;
    for i in 0..n {
        for j in 0..n {
            let (ri, rj) = (m.tile_canvas_rect(i), m.tile_canvas_rect(j));
            let (ti, tj) = (&m.tiles()[i], &m.tiles()[j]);
            // i's right edge against j's left, and i's bottom against j's top.
            let pairs: Vec<(DVec2, DVec2)> =
                if (ri.max.x - rj.min.x).abs() < 1e-6 && (ri.min.y - rj.min.y).abs() < 1e-6 {
                    vec![
                        (ri.max, DVec2::new(rj.min.x, rj.max.y)),
                        (DVec2::new(ri.max.x, ri.min.y), rj.min),
                    ]
                } else if (ri.max.y - rj.min.y).abs() < 1e-6 && (ri.min.x - rj.min.x).abs() < 1e-6 {
                    vec![
                        (ri.max, DVec2::new(rj.max.x, rj.min.y)),
                        (DVec2::new(ri.min.x, ri.max.y), rj.min),
                    ]
                } else {
                    continue;
                };
            shared += 1;
            for (ci, cj) in pairs {
                let gap = ti.canvas_to_point(ci).distance(tj.canvas_to_point(cj));
                assert!(gap < HINGE_TOL_M, "{} / {}: {gap} m", ti.id(), tj.id());
            }
        }
    }
    // 6 hinges × 5 rows + 4 row seams × 7 columns.
    assert_eq!(shared, 6 * 5 + 4 * 7);
}

#[test]
fn hornet_canvas_distance_is_distance_along_the_wall() {
    // From the centre of c2r2 to the centre of c4r2 along the wall: half a panel, two bezels,
    // a panel, two bezels, half a panel = 2 × (1018.1 + 6) mm, crossing two 10° hinges.
    let m = load("hornet.json");
    let (i2, i3, i4) = (14 + 2, 14 + 3, 14 + 4);
    let y = m.tile_canvas_rect(i3).center().y;
    let a = DVec2::new(m.tile_canvas_rect(i2).center().x, y);
    let h23 = DVec2::new(m.tile_canvas_rect(i3).min.x, y);
    let h34 = DVec2::new(m.tile_canvas_rect(i3).max.x, y);
    let b = DVec2::new(m.tile_canvas_rect(i4).center().x, y);
    let t = m.tiles();
    let path_3d = t[i2]
        .canvas_to_point(a)
        .distance(t[i2].canvas_to_point(h23))
        + t[i3]
            .canvas_to_point(h23)
            .distance(t[i3].canvas_to_point(h34))
        + t[i4]
            .canvas_to_point(h34)
            .distance(t[i4].canvas_to_point(b));
    assert!(
        (path_3d - 2.0 * (HORNET_W + 2.0 * HORNET_BEZEL)).abs() < HINGE_TOL_M,
        "{path_3d}"
    );
    // The straight line is shorter: the wall is not flat.
    assert!(t[i2].canvas_to_point(a).distance(t[i4].canvas_to_point(b)) < path_3d - 0.01);
    // On the canvas the same path is a straight line, as long as the wall path up to the model
    // pitch: HORNET's assumed panel has x and y pitches 3.3e-5 apart (relative), and the model
    // pitch is their mean, 1.65e-5 from the x pitch that measures this path.
    let along_canvas = (b - a).length() * m.pitch_m();
    assert!(
        ((along_canvas - path_3d) / path_3d).abs() < 2e-5,
        "{along_canvas} vs {path_3d}"
    );
}

#[test]
fn even_column_count_puts_the_centre_on_the_middle_hinge() {
    let mut g = hornet_generator_json();
    g["columns"] = json!(2);
    g["rows"] = json!(1);
    let m = parse(&json!({"name": "two", "generator": g})).unwrap();
    let (a, b) = (&m.tiles()[0], &m.tiles()[1]);
    let mid = m.canvas_rect().center();
    assert!(a.canvas_to_point(mid).abs_diff_eq(DVec3::ZERO, HINGE_TOL_M));
    assert!(b.canvas_to_point(mid).abs_diff_eq(DVec3::ZERO, HINGE_TOL_M));
    // Symmetric about the hinge: each column turned 5° towards the viewer.
    assert!((a.normal().x - 5f64.to_radians().sin()).abs() < 1e-12);
    assert!((b.normal().x + 5f64.to_radians().sin()).abs() < 1e-12);
}

#[test]
fn single_displays_load_with_their_stated_sizes() {
    for (file, w, h) in [
        ("desktop-27in-4k.json", 0.5979, 0.3363),
        ("projection-4m-4k.json", 4.0, 2.25),
    ] {
        let m = load(file);
        assert_eq!(m.tiles().len(), 1);
        let t = &m.tiles()[0];
        assert_eq!(t.resolution(), [3840, 2160]);
        assert!((t.pitch() * DVec2::new(3840.0, 2160.0)).abs_diff_eq(DVec2::new(w, h), 1e-12));
        assert!(t.normal().abs_diff_eq(DVec3::Z, 1e-15));
        assert!(
            t.tile_px_to_point(DVec2::new(1920.0, 1080.0))
                .abs_diff_eq(DVec3::ZERO, 1e-12)
        );
        assert_eq!(
            m.canvas_rect().size(),
            DVec2::new(3840.0, 2160.0),
            "{file}: no bezels"
        );
    }
}

#[test]
fn expand_round_trips_through_the_loader() {
    for file in [
        "hornet.json",
        "desktop-27in-4k.json",
        "projection-4m-4k.json",
    ] {
        let model = load(file);
        let text = expand(&ExpandArgs {
            model: model_path(file).display().to_string(),
        })
        .unwrap();
        // A built-in model's name gives the same text, from any folder.
        let name = file.trim_end_matches(".json");
        assert_eq!(
            expand(&ExpandArgs {
                model: name.to_owned()
            })
            .unwrap(),
            text,
            "{name}"
        );
        let spec: DisplayModelSpec = serde_json::from_str(&text).unwrap();
        assert!(
            spec.generator.is_none() && spec.tiles.is_some(),
            "{file}: explicit form"
        );
        let back = DisplayModel::from_json(&text, "expanded").unwrap();
        assert_eq!(back, model, "{file}");
        // And serde on the model itself is the same explicit form.
        let via_serde = serde_json::to_value(&model).unwrap();
        assert_eq!(via_serde, serde_json::from_str::<Value>(&text).unwrap());
    }
}

#[test]
fn model_deserialises_through_validation() {
    let m: DisplayModel = serde_json::from_value(three_tiles()).unwrap();
    assert_eq!(m, parse(&three_tiles()).unwrap());
    let mut v = three_tiles();
    v["tiles"][1]["canvas"] = json!([100.0, 2.0]);
    let e = serde_json::from_value::<DisplayModel>(v)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("<serde>") && e.contains("tile \"b\"") && e.contains("overlaps"),
        "{e}"
    );
}

#[test]
fn expand_error_names_the_file() {
    let e = expand(&ExpandArgs {
        model: "/nonexistent/x.json".to_owned(),
    })
    .unwrap_err();
    assert!(format!("{e:#}").contains("/nonexistent/x.json"), "{e:#}");
    // Bounded reads: a device is refused unread, naming what it is.
    let e = expand(&ExpandArgs {
        model: "/dev/zero".to_owned(),
    })
    .unwrap_err();
    assert!(
        format!("{e:#}").contains(
            "/dev/zero: cannot read the display model: is a character device, not a file"
        ),
        "{e:#}"
    );
}

/// Generator placement with a random centre, normal and up must give the default wall moved by
/// that rigid motion.
fn placed(center: [f64; 3], normal: DVec3, up: DVec3) -> DisplayModel {
    let mut g: GeneratorSpec = serde_json::from_value(hornet_generator_json()).unwrap();
    g.center = center;
    g.normal = normal.to_array();
    g.up = up.to_array();
    DisplayModel::from_spec(
        &DisplayModelSpec {
            name: "placed".into(),
            notes: String::new(),
            tiles: None,
            generator: Some(g),
        },
        "placed",
    )
    .unwrap()
}

proptest! {
    #[test]
    fn generator_placement_is_a_rigid_motion(
        cx in -5.0..5.0f64, cy in -5.0..5.0f64, cz in -5.0..5.0f64,
        yaw in -3.1..3.1f64, tilt in -1.2..1.2f64,
    ) {
        let normal = DVec3::new(yaw.sin() * tilt.cos(), tilt.sin(), yaw.cos() * tilt.cos());
        let z = normal;
        let y = (DVec3::Y - z * DVec3::Y.dot(z)).normalize();
        let x = y.cross(z);
        let base = load("hornet.json");
        let moved = placed([cx, cy, cz], normal, DVec3::Y);
        let c = DVec3::new(cx, cy, cz);
        for (a, b) in base.tiles().iter().zip(moved.tiles()) {
            for (p, q) in a.corners().iter().zip(b.corners()) {
                let expect = c + x * p.x + y * p.y + z * p.z;
                prop_assert!(q.abs_diff_eq(expect, 1e-9), "{} vs {}", q, expect);
            }
            prop_assert_eq!(a.canvas_origin(), b.canvas_origin());
        }
    }
}

// ---- never panics -------------------------------------------------------------------------

fn desktop_text() -> String {
    std::fs::read_to_string(model_path("desktop-27in-4k.json")).unwrap()
}

/// Replaces numeric leaf number `k` (in document order) of `v` by `x`.
fn replace_number(v: &mut Value, k: &mut usize, x: f64) {
    match v {
        Value::Number(_) => {
            if *k == 0 {
                *v = serde_json::Number::from_f64(x).map_or(Value::Null, Value::Number);
            }
            *k = k.wrapping_sub(1);
        }
        Value::Array(a) => a.iter_mut().for_each(|e| replace_number(e, k, x)),
        Value::Object(o) => o.values_mut().for_each(|e| replace_number(e, k, x)),
        _ => {}
    }
}

fn extreme_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        Just(-0.0),
        Just(f64::MIN_POSITIVE),
        Just(5e-324),
        Just(1e308),
        Just(-1e308),
        Just(1e6),
        Just(4294967296.0),
        -1e3..1e3f64,
    ]
}

proptest! {
    #[test]
    fn from_json_never_panics_on_arbitrary_text(s in "\\PC{0,200}") {
        let _ = DisplayModel::from_json(&s, "fuzz");
    }

    #[test]
    fn from_json_never_panics_on_mutated_models(
        pos in 0usize..10_000, len in 0usize..8, insert in "[-0-9eE.,\\[\\]{}\":a-z ]{0,6}",
    ) {
        for text in [desktop_text(), std::fs::read_to_string(model_path("hornet.json")).unwrap()] {
            let mut bytes = text.into_bytes();
            let at = pos % (bytes.len() + 1);
            let end = (at + len).min(bytes.len());
            bytes.splice(at..end, insert.bytes());
            let mutated = String::from_utf8_lossy(&bytes);
            let _ = DisplayModel::from_json(&mutated, "fuzz");
        }
    }

    #[test]
    fn any_number_in_a_model_gives_a_sane_model_or_an_error(
        which in 0usize..40, x in extreme_f64(), generator in any::<bool>(),
    ) {
        let file = if generator { "hornet.json" } else { "desktop-27in-4k.json" };
        let mut v: Value =
            serde_json::from_str(&std::fs::read_to_string(model_path(file)).unwrap()).unwrap();
        let mut k = which;
        replace_number(&mut v, &mut k, x);
        if let Ok(m) = DisplayModel::from_json(&v.to_string(), "fuzz") {
            prop_assert!(m.pitch_m().is_finite() && m.pitch_m() > 0.0);
            for t in m.tiles() {
                prop_assert!((t.normal().length() - 1.0).abs() < 1e-12);
                prop_assert!(t.pitch().is_finite());
            }
            prop_assert!(m.canvas_rect().size().min_element() > 0.0);
        }
    }
}
