//! Display geometry: canvas ↔ tile ↔ 3D ↔ image mappings and ray–display intersection on the
//! shipped models, with analytic truths (the viewer 1 m in front of the wall centre) and
//! property tests (every tile, every pixel, bezels included), plus `raygun pick`'s JSON.

use std::path::PathBuf;
use std::sync::LazyLock;

use glam::{DVec2, DVec3};
use proptest::prelude::*;
use raygun::cli::display::{PickArgs, pick, pick_on};
use raygun::display::DisplayModel;

fn load(name: &str) -> DisplayModel {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("display-models")
        .join(name);
    DisplayModel::load(path).unwrap_or_else(|e| panic!("{e}"))
}

static HORNET: LazyLock<DisplayModel> = LazyLock::new(|| load("hornet.json"));
static DESKTOP: LazyLock<DisplayModel> = LazyLock::new(|| load("desktop-27in-4k.json"));
static PROJECTION: LazyLock<DisplayModel> = LazyLock::new(|| load("projection-4m-4k.json"));

/// Round trips compose a handful of f64 operations on canvas coordinates up to 1.4e4 px:
/// errors are around 1e-11 px; 1e-8 px leaves margin and is still far below anything visible.
const ROUND_TRIP_PX: f64 = 1e-8;

const VIEWER: DVec3 = DVec3::new(0.0, 0.0, 1.0);

fn tile_index(m: &DisplayModel, id: &str) -> usize {
    m.tile_index(id).unwrap()
}

// ---- mappings -----------------------------------------------------------------------------

proptest! {
    #[test]
    fn canvas_point_round_trip_on_every_tile_including_bezels(
        tile in 0usize..35, u in -0.01..1.01f64, v in -0.01..1.01f64,
    ) {
        // u, v span the canvas rectangle with bezels and 1 % beyond: bezels and the plane past
        // them map through the same affine map.
        let m = &*HORNET;
        let t = &m.tiles()[tile];
        let r = m.tile_canvas_rect(tile);
        let c = r.min + r.size() * DVec2::new(u, v);
        let p = t.canvas_to_point(c);
        prop_assert!((p - t.corners()[0]).dot(t.normal()).abs() < 1e-12, "in the tile's plane");
        let back = t.point_to_canvas(p);
        prop_assert!(back.abs_diff_eq(c, ROUND_TRIP_PX), "{} -> {} -> {}", c, p, back);
        // Projection: a point off the plane along the normal lands on the same canvas point.
        let off = t.point_to_canvas(p + t.normal() * 0.25);
        prop_assert!(off.abs_diff_eq(c, ROUND_TRIP_PX));
    }

    #[test]
    fn model_canvas_to_point_uses_the_tile_under_the_point(
        x in 0.0..1.0f64, y in 0.0..1.0f64,
    ) {
        let m = &*HORNET;
        let c = m.canvas_rect().min + m.canvas_rect().size() * DVec2::new(x, y);
        // HORNET is a full grid: every canvas point is on some tile (active area or bezel).
        let i = m.tile_at_canvas(c).unwrap();
        prop_assert!(m.tile_canvas_rect(i).contains(c));
        prop_assert_eq!(m.canvas_to_point(c), Some(m.tiles()[i].canvas_to_point(c)));
        prop_assert_eq!(m.nearest_tile(c), i);
    }

    #[test]
    fn image_canvas_round_trip(
        x in -10.0..3850.0f64, y in -10.0..2170.0f64, w in 1u32..8000, h in 1u32..5000,
    ) {
        for m in [&*HORNET, &*DESKTOP] {
            let img = DVec2::new(x, y);
            let c = m.image_to_canvas(img, [w, h]);
            let back = m.canvas_to_image(c, [w, h]);
            prop_assert!(back.abs_diff_eq(img, 1e-9 * (1.0 + img.length())), "{} vs {}", back, img);
        }
    }
}

#[test]
fn image_corners_are_canvas_corners_and_pixel_centres_are_half_pixels_in() {
    let m = &*HORNET;
    let r = m.canvas_rect();
    let size = [3840, 2160];
    assert_eq!(m.image_to_canvas(DVec2::ZERO, size), r.min);
    assert!(
        m.image_to_canvas(DVec2::new(3840.0, 2160.0), size)
            .abs_diff_eq(r.max, 1e-9)
    );
    // Pixel (0, 0)'s centre is half an image pixel in: each axis scaled on its own.
    let first = m.image_to_canvas(DVec2::splat(0.5), size);
    let scale = r.size() / DVec2::new(3840.0, 2160.0);
    assert!(first.abs_diff_eq(r.min + 0.5 * scale, 1e-12));
    // The image centre is the canvas centre, which on HORNET is the centre of c3r2.
    let mid = m.image_to_canvas(DVec2::new(1920.0, 1080.0), size);
    let i = m.tile_at_canvas(mid).unwrap();
    assert_eq!(m.tiles()[i].id(), "c3r2");
    assert!(
        m.canvas_to_point(mid)
            .unwrap()
            .abs_diff_eq(DVec3::ZERO, 1e-12)
    );
    // The desktop's canvas is its pixel grid: a 4K image maps 1:1.
    assert_eq!(
        DESKTOP.image_to_canvas(DVec2::new(0.5, 0.5), size),
        DVec2::new(0.5, 0.5)
    );
}

#[test]
fn tile_at_canvas_on_a_shared_edge_takes_the_first_listed_tile() {
    let m = &*HORNET;
    let (a, b) = (tile_index(m, "c3r2"), tile_index(m, "c4r2"));
    let edge = DVec2::new(
        m.tile_canvas_rect(a).max.x,
        m.tile_canvas_rect(a).center().y,
    );
    assert!(m.tile_canvas_rect(b).contains(edge), "the edge is shared");
    assert_eq!(m.tile_at_canvas(edge), Some(a));
}

#[test]
fn canvas_outside_the_wall_has_no_point_but_a_nearest_tile() {
    let m = &*HORNET;
    let above_left = m.canvas_rect().min - DVec2::splat(100.0);
    assert_eq!(m.tile_at_canvas(above_left), None);
    assert_eq!(m.canvas_to_point(above_left), None);
    assert_eq!(m.nearest_tile(above_left), tile_index(m, "c0r0"));
    assert_eq!(m.tile_at_canvas(DVec2::NAN), None);
}

// ---- intersection: analytic cases -----------------------------------------------------------

#[test]
fn viewer_looking_at_the_centre_hits_the_centre_at_one_metre() {
    for (m, id, px) in [
        (&*HORNET, "c3r2", DVec2::new(960.0, 540.0)),
        (&*DESKTOP, "screen", DVec2::new(1920.0, 1080.0)),
        (&*PROJECTION, "screen", DVec2::new(1920.0, 1080.0)),
    ] {
        let hit = m.intersect(VIEWER, DVec3::NEG_Z).unwrap();
        assert_eq!(hit.tile_id, id);
        assert_eq!(hit.tile, tile_index(m, id));
        assert!((hit.t - 1.0).abs() < 1e-12, "{}", hit.t);
        assert!(hit.point.abs_diff_eq(DVec3::ZERO, 1e-12));
        assert!(hit.tile_px.abs_diff_eq(px, 1e-9), "{}", hit.tile_px);
        assert!(!hit.on_bezel);
        assert_eq!(
            hit.canvas_px,
            m.tiles()[hit.tile].tile_px_to_canvas(hit.tile_px)
        );
    }
}

#[test]
fn direction_length_does_not_change_t_in_metres() {
    let hit = HORNET
        .intersect(VIEWER, DVec3::new(0.0, 0.0, -1e-3))
        .unwrap();
    assert!((hit.t - 1.0).abs() < 1e-12);
    let hit = HORNET
        .intersect(DVec3::new(0.0, 0.0, 3.0), DVec3::new(0.0, 0.0, -50.0))
        .unwrap();
    assert!((hit.t - 3.0).abs() < 1e-12);
}

#[test]
fn oblique_ray_on_the_planar_screen_matches_the_analytic_hit() {
    // From (1, 0.5, 2) towards (−0.5, 0.25, 0): on the 4 m screen (1.0417 mm pitch, canvas
    // origin at its top-left (−2, 1.125)) that point is pixel (1.5 / 4 · 3840, 0.875 / 2.25 ·
    // 2160) = (1440, 840), 2.5125 m away.
    let o = DVec3::new(1.0, 0.5, 2.0);
    let target = DVec3::new(-0.5, 0.25, 0.0);
    let hit = PROJECTION.intersect(o, target - o).unwrap();
    assert!(
        hit.tile_px.abs_diff_eq(DVec2::new(1440.0, 840.0), 1e-9),
        "{}",
        hit.tile_px
    );
    assert!((hit.t - (target - o).length()).abs() < 1e-12);
}

#[test]
fn rays_into_a_bezel_report_on_bezel() {
    let m = &*HORNET;
    let (a, b) = (tile_index(m, "c3r2"), tile_index(m, "c4r2"));
    let ra = m.tile_canvas_rect(a);
    // 1.5 mm into c3r2's right bezel (3 mm wide), and 1.5 mm into c4r2's left bezel.
    let y = ra.center().y;
    let bezel_px = 0.0015 / m.pitch_m();
    for (tile, c) in [
        (a, DVec2::new(ra.max.x - bezel_px, y)),
        (b, DVec2::new(ra.max.x + bezel_px, y)),
    ] {
        let target = m.tiles()[tile].canvas_to_point(c);
        let hit = m.intersect(VIEWER, target - VIEWER).unwrap();
        assert_eq!(hit.tile, tile);
        assert!(hit.on_bezel);
        assert!(
            hit.canvas_px.abs_diff_eq(c, 1e-6),
            "{} vs {c}",
            hit.canvas_px
        );
    }
    let hit_a = m
        .intersect(
            VIEWER,
            m.tiles()[a].canvas_to_point(DVec2::new(ra.max.x - bezel_px, y)) - VIEWER,
        )
        .unwrap();
    assert!(
        hit_a.tile_px.x > 1920.0,
        "right of the active area: {}",
        hit_a.tile_px
    );
    // Top bezel of the top row: still the wall.
    let top = tile_index(m, "c3r0");
    let c = DVec2::new(
        m.tile_canvas_rect(top).center().x,
        0.5 * 0.003 / m.pitch_m(),
    );
    let hit = m
        .intersect(VIEWER, m.tiles()[top].canvas_to_point(c) - VIEWER)
        .unwrap();
    assert!(
        hit.on_bezel && hit.tile == top && hit.tile_px.y < 0.0,
        "{hit:?}"
    );
}

#[test]
fn ray_through_a_hinge_takes_the_first_listed_tile() {
    let m = &*HORNET;
    let (a, b) = (tile_index(m, "c3r2"), tile_index(m, "c4r2"));
    let ra = m.tile_canvas_rect(a);
    let hinge = m.tiles()[a].canvas_to_point(DVec2::new(ra.max.x, ra.center().y));
    let hit = m.intersect(VIEWER, hinge - VIEWER).unwrap();
    assert_eq!(hit.tile, a.min(b));
    assert!(hit.on_bezel);
    assert!(hit.point.abs_diff_eq(hinge, 1e-9));
}

#[test]
fn ray_above_the_wall_misses() {
    // The wall's top edge is at y = 2.5 × (572.7 + 6) mm = 1.447 m; this ray crosses z = 0 at
    // y = 2 m and only climbs from there.
    assert_eq!(HORNET.intersect(VIEWER, DVec3::new(0.0, 2.0, -1.0)), None);
    // Just inside the top bezel it hits; just above the bezel's outer edge it misses.
    let top = 2.5 * (0.5727 + 0.006);
    assert!(
        HORNET
            .intersect(VIEWER, DVec3::new(0.0, top - 1e-6, -1.0))
            .is_some()
    );
    assert_eq!(
        HORNET.intersect(VIEWER, DVec3::new(0.0, top + 1e-6, -1.0)),
        None
    );
}

#[test]
fn rays_from_behind_meet_the_panel_backs_and_miss() {
    // Behind the centre, looking at the wall's back.
    assert_eq!(HORNET.intersect(DVec3::new(0.0, 0.0, -1.0), DVec3::Z), None);
    assert_eq!(
        DESKTOP.intersect(DVec3::new(0.0, 0.0, -1.0), DVec3::Z),
        None
    );
    // Behind, looking away from the wall.
    assert_eq!(
        HORNET.intersect(DVec3::new(0.0, 0.0, -1.0), DVec3::NEG_Z),
        None
    );
}

#[test]
fn ray_pointing_away_misses() {
    assert_eq!(HORNET.intersect(VIEWER, DVec3::Z), None);
    assert_eq!(
        PROJECTION.intersect(VIEWER, DVec3::new(0.3, 0.2, 1.0)),
        None
    );
}

#[test]
fn parallel_rays_miss() {
    // Parallel to the screen in front of it, and inside its plane.
    assert_eq!(DESKTOP.intersect(VIEWER, DVec3::X), None);
    assert_eq!(
        DESKTOP.intersect(DVec3::new(-1.0, 0.0, 0.0), DVec3::X),
        None
    );
    assert_eq!(
        PROJECTION.intersect(DVec3::new(0.0, 5.0, 0.0), DVec3::NEG_Y),
        None
    );
}

#[test]
fn origin_on_a_tile_does_not_hit_itself() {
    // On the desktop screen, pointing out or in: nothing else to hit.
    assert_eq!(DESKTOP.intersect(DVec3::ZERO, DVec3::Z), None);
    assert_eq!(DESKTOP.intersect(DVec3::ZERO, DVec3::NEG_Z), None);
    // On HORNET's centre, aiming at the far right column: the curve faces back at us.
    let m = &*HORNET;
    let right = tile_index(m, "c6r2");
    let target = m.tiles()[right].tile_px_to_point(DVec2::new(960.0, 540.0));
    let hit = m.intersect(DVec3::ZERO, target).unwrap();
    assert_eq!(hit.tile, right);
    assert!(hit.tile_px.abs_diff_eq(DVec2::new(960.0, 540.0), 1e-6));
}

#[test]
fn non_finite_and_zero_rays_miss() {
    let m = &*HORNET;
    for (o, d) in [
        (VIEWER, DVec3::ZERO),
        (VIEWER, DVec3::new(f64::NAN, 0.0, -1.0)),
        (VIEWER, DVec3::new(0.0, 0.0, f64::NEG_INFINITY)),
        (DVec3::new(f64::INFINITY, 0.0, 1.0), DVec3::NEG_Z),
        (DVec3::splat(f64::NAN), DVec3::NEG_Z),
        (VIEWER, DVec3::new(0.0, 0.0, -1e-320)), // subnormal: normalising fails
        (DVec3::new(1e300, 0.0, 1.0), DVec3::NEG_Z), // overflows on the way: a miss, no NaN
    ] {
        assert_eq!(m.intersect(o, d), None, "{o} {d}");
    }
}

// ---- intersection: every pixel --------------------------------------------------------------

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// From a viewer anywhere in front of every tile's plane, a ray aimed at a pixel centre of
    /// any tile hits that tile at that pixel (the wall is concave towards such a viewer, so
    /// nothing occludes).
    #[test]
    fn ray_at_any_pixel_centre_hits_that_pixel(
        tile in 0usize..35, px in 0u32..1920, py in 0u32..1080,
        ox in -1.5..1.5f64, oy in -1.2..1.2f64, oz in 0.3..4.0f64,
    ) {
        let m = &*HORNET;
        let o = DVec3::new(ox, oy, oz);
        for t in m.tiles() {
            prop_assume!((o - t.corners()[0]).dot(t.normal()) > 0.05);
        }
        let t = &m.tiles()[tile];
        let centre = DVec2::new(f64::from(px) + 0.5, f64::from(py) + 0.5);
        let target = t.tile_px_to_point(centre);
        let hit = m.intersect(o, target - o).unwrap();
        prop_assert_eq!(hit.tile, tile);
        prop_assert!(hit.tile_px.abs_diff_eq(centre, 1e-6), "{} vs {}", hit.tile_px, centre);
        prop_assert_eq!(hit.tile_px.floor(), centre.floor());
        prop_assert!(!hit.on_bezel);
        prop_assert!((hit.t - (target - o).length()).abs() < 1e-9);
    }

    /// Any ray at all: a defined result, never NaN.
    #[test]
    fn any_ray_gives_a_finite_hit_or_a_miss(
        o in prop::array::uniform3(-10.0..10.0f64), d in prop::array::uniform3(-1.0..1.0f64),
    ) {
        for m in [&*HORNET, &*DESKTOP] {
            if let Some(hit) = m.intersect(DVec3::from_array(o), DVec3::from_array(d)) {
                prop_assert!(hit.t > 0.0 && hit.t.is_finite());
                prop_assert!(hit.point.is_finite() && hit.canvas_px.is_finite());
                prop_assert!(m.tile_canvas_rect(hit.tile).expand(1e-6).contains(hit.canvas_px));
                // The hit is the first: the ray's point at t is the reported point.
                let along = DVec3::from_array(o) + DVec3::from_array(d).normalize() * hit.t;
                prop_assert!(along.abs_diff_eq(hit.point, 1e-9));
            }
        }
    }
}

// ---- raygun pick --------------------------------------------------------------------------

#[test]
fn pick_reports_the_centre_hit_as_json() {
    let v = pick_on(&HORNET, VIEWER, DVec3::NEG_Z, [3840, 2160]).unwrap();
    assert_eq!(v["hit"], true);
    assert_eq!(v["tile"], "c3r2");
    assert_eq!(v["on_bezel"], false);
    let num = |key: &str, i: usize| v[key][i].as_f64().unwrap();
    assert!((v["t"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    // The wall centre is the image centre.
    assert!(
        (num("image_px", 0) - 1920.0).abs() < 1e-9 && (num("image_px", 1) - 1080.0).abs() < 1e-9
    );
    assert!((num("tile_px", 0) - 960.0).abs() < 1e-9 && (num("tile_px", 1) - 540.0).abs() < 1e-9);
    for i in 0..3 {
        assert!(num("point", i).abs() < 1e-12);
    }
    let c = HORNET.canvas_rect().center();
    assert!((num("canvas_px", 0) - c.x).abs() < 1e-9);
}

#[test]
fn pick_loads_the_model_file() {
    let args = PickArgs {
        display: concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/display-models/desktop-27in-4k.json"
        )
        .to_owned(),
        origin: DVec3::new(0.1, 0.0, 0.6),
        dir: DVec3::NEG_Z,
        size: [1920, 1080],
    };
    let v = pick(&args).unwrap();
    // 0.1 m right of centre on a 597.9 mm / 3840 px screen: 0.1 / 0.5979 · 3840 px right of
    // pixel column 1920, and half that on the half-size image.
    let x = 1920.0 + 0.1 / 0.5979 * 3840.0;
    assert!((v["tile_px"][0].as_f64().unwrap() - x).abs() < 1e-6, "{v}");
    assert!(
        (v["image_px"][0].as_f64().unwrap() - x / 2.0).abs() < 1e-6,
        "{v}"
    );
    assert!((v["t"].as_f64().unwrap() - 0.6).abs() < 1e-12);
    let missing = PickArgs {
        display: "/nonexistent/m.json".to_owned(),
        ..args
    };
    assert!(format!("{:#}", pick(&missing).unwrap_err()).contains("/nonexistent/m.json"));
}

#[test]
fn pick_miss_is_hit_false_only() {
    let v = pick_on(&HORNET, VIEWER, DVec3::Z, [3840, 2160]).unwrap();
    assert_eq!(v, serde_json::json!({"hit": false}));
}

#[test]
fn pick_rejects_a_zero_direction() {
    let e = pick_on(&HORNET, VIEWER, DVec3::ZERO, [3840, 2160]).unwrap_err();
    assert!(e.to_string().contains("--dir"), "{e}");
}
