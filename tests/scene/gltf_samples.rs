//! The Khronos sample models of `tests/data/gltf-samples/` (unmodified; licences in its
//! README) load and render as their authors describe, checked by pixels.

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};
use raygun::scene::{Environment, Scene};
use raygun::trace::accum::{Accumulation, luminance};
use raygun::trace::camera::{LookAt, RenderCamera};
use raygun::trace::pack::PackedScene;
use raygun::trace::path::{TraceSettings, render_cpu};

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/gltf-samples")
        .join(name)
}

fn load(name: &str) -> Scene {
    Scene::load(sample(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The CPU twin's mean image (depth 1: what the camera sees, lit by a white sky).
fn render(scene: &Scene, camera: RenderCamera, w: u32, h: u32, spp: u32) -> Vec<Vec3> {
    // Two vertices: the sky reaches the first hit by NEE and by the BSDF ray (MIS), which is
    // much less noisy than NEE alone.
    let s = TraceSettings {
        width: w,
        height: h,
        seed: 1,
        max_depth: 2,
        camera,
    };
    let packed = PackedScene::new(scene);
    let mut acc = Accumulation::new(w, h);
    for _ in 0..spp {
        render_cpu(&packed, &s, &mut acc, None);
    }
    acc.mean_image()
}

/// A triangle as its vertex set (order-free, rounded to 1e-5) and its winding's normal.
fn key(p: [Vec3; 3]) -> (Vec<[i64; 3]>, [i64; 3]) {
    let q = |v: Vec3| (v * 1e5).round().as_i64vec3().to_array();
    let mut vs: Vec<[i64; 3]> = p.iter().map(|&v| q(v)).collect();
    vs.sort_unstable();
    let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
    (vs, q(n))
}

/// Strips and fans cover the same square as the triangle list (a fan may split it along the
/// other diagonal): the same area, the same front side, and every pixel of an orthographic
/// view hits or misses alike.
#[test]
fn triangle_strips_and_fans_equal_the_triangle_list() {
    let coverage = |scene: &Scene| {
        let mut sc = scene.clone();
        sc.orthographic_cameras = vec![raygun::scene::OrthographicCamera {
            name: "o".into(),
            position: Vec3::new(0.0, 0.0, 2.0),
            forward: Vec3::NEG_Z,
            up: Vec3::Y,
            ymag: 0.75,
        }];
        let cam = RenderCamera::choose(&sc, None, 48, 48).unwrap();
        let bvh = PackedScene::new(&sc).bvh;
        (0..48 * 48)
            .map(|i| {
                let (o, d) = cam.ray((i % 48) as f32 + 0.5, (i / 48) as f32 + 0.5, 48, 48);
                bvh.closest_hit(o, d, f32::INFINITY).is_some()
            })
            .collect::<Vec<bool>>()
    };
    let area = |scene: &Scene| -> f32 {
        scene
            .triangles
            .iter()
            .map(|t| 0.5 * (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).length())
            .sum()
    };
    for (list, strip, fan) in [("06", "04", "05"), ("13", "11", "12")] {
        let path = |n: &str| format!("PrimitiveModes/Mesh_PrimitiveMode_{n}.gltf");
        let want = load(&path(list));
        assert_eq!(want.triangles.len(), 2);
        let want_cover = coverage(&want);
        assert!(want_cover.iter().filter(|&&c| c).count() > 500);
        for other in [strip, fan] {
            let scene = load(&path(other));
            assert!(
                scene.unsupported.is_empty(),
                "{other}: {:?}",
                scene.unsupported
            );
            assert_eq!(scene.triangles.len(), 2, "{other}");
            assert!((area(&scene) - area(&want)).abs() < 1e-6, "{other}: area");
            for t in &scene.triangles {
                assert_eq!(
                    key(t.p).1,
                    key(want.triangles[0].p).1,
                    "{other}: front side"
                );
            }
            assert!(
                coverage(&scene) == want_cover,
                "mode file {other} covers other pixels than {list}"
            );
        }
    }
}

/// Vertex colours: the box's faces come out in colour, not the material's grey.
#[test]
fn box_vertex_colors_renders_in_colour() {
    let scene = load("BoxVertexColors.gltf");
    assert!(scene.unsupported.is_empty(), "{:?}", scene.unsupported);
    assert_eq!(scene.vertex_extras.len(), scene.triangles.len());
    let look = LookAt {
        from: Vec3::new(1.5, 1.2, 2.0),
        at: Vec3::ZERO,
        yfov_deg: 40.0,
    };
    let img = render(
        &scene,
        RenderCamera::look_at(&look, 48, 48).unwrap(),
        48,
        48,
        4,
    );
    let centre = img[24 * 48 + 24];
    let saturated = img
        .iter()
        .filter(|c| {
            c.max_element() > 0.05 && c.max_element() - c.min_element() > 0.3 * c.max_element()
        })
        .count();
    assert!(
        saturated > 200,
        "{saturated} coloured pixels; centre {centre}"
    );
}

/// Cameras.gltf: the unnamed perspective and orthographic cameras are "camera 0" and
/// "camera 1"; the orthographic one sees the 1 m square, tilted 45° about x, as a 1 × 0.707
/// window-space rectangle whatever the distance.
#[test]
fn cameras_gltf_has_a_perspective_and_an_orthographic_camera() {
    let mut scene = load("Cameras.gltf");
    assert!(scene.unsupported.is_empty(), "{:?}", scene.unsupported);
    assert_eq!(scene.cameras[0].name, "camera 0");
    assert_eq!(scene.orthographic_cameras[0].name, "camera 1");
    scene.environment = Environment::Constant(Vec3::ONE);
    let camera = RenderCamera::choose(&scene, Some("camera 1"), 64, 64).unwrap();
    assert_eq!(camera.ortho_half_y, 1.0);
    // Which pixel centres' primary rays meet the square.
    let bvh = PackedScene::new(&scene).bvh;
    let covered = (0..64 * 64)
        .filter(|&i| {
            let (o, d) = camera.ray((i % 64) as f32 + 0.5, (i / 64) as f32 + 0.5, 64, 64);
            assert_eq!(d, camera.forward, "parallel rays");
            bvh.closest_hit(o, d, f32::INFINITY).is_some()
        })
        .count() as f32;
    let want = 1.0 * 0.5f32.sqrt() / 4.0 * 64.0 * 64.0;
    assert!(
        (covered / want - 1.0).abs() < 0.04,
        "{covered} pixels, want {want}"
    );
}

/// TextureCoordinateTest, seen from −Z as its author says: each labelled square sits in the
/// corner its name says (tinted: top left yellow, top right red, bottom left blue, bottom
/// right green).
#[test]
fn texture_coordinate_test_labels_sit_in_their_named_corners() {
    let scene = load("TextureCoordinateTest.gltf");
    let look = LookAt {
        from: Vec3::new(0.0, 0.0, -4.0),
        at: Vec3::ZERO,
        yfov_deg: 40.0,
    };
    let (w, h) = (64usize, 64usize);
    let img = render(
        &scene,
        RenderCamera::look_at(&look, 64, 64).unwrap(),
        64,
        64,
        4,
    );
    // The mean colour of each image quadrant's middle.
    let quadrant = |qx: usize, qy: usize| {
        let mut sum = Vec3::ZERO;
        for y in (qy * h / 2 + 10)..(qy * h / 2 + 22) {
            for x in (qx * w / 2 + 10)..(qx * w / 2 + 22) {
                sum += img[y * w + x];
            }
        }
        sum / 144.0
    };
    let hue = |c: Vec3| -> &'static str {
        let n = c / c.max_element();
        match (n.x > 0.5, n.y > 0.5, n.z > 0.5) {
            (true, true, false) => "yellow",
            (true, false, false) => "red",
            (false, false, true) | (false, true, true) if n.z >= n.y => "blue",
            (false, true, false) => "green",
            _ => "other",
        }
    };
    for (qx, qy, want) in [
        (0, 0, "yellow"),
        (1, 0, "red"),
        (0, 1, "blue"),
        (1, 1, "green"),
    ] {
        let c = quadrant(qx, qy);
        assert_eq!(hue(c), want, "quadrant ({qx}, {qy}): {c}");
    }
}

/// The spec's KHR_texture_transform, written out here independently of the loader.
fn spec_transform(uv: Vec2, offset: Vec2, rotation: f32, scale: Vec2) -> Vec2 {
    let (s, c) = rotation.sin_cos();
    let su = uv * scale;
    Vec2::new(c * su.x + s * su.y, -s * su.x + c * su.y) + offset
}

/// TextureTransformTest as its authors describe: the offset squares show the green U, blue
/// V and cyan UV quadrants and never the yellow "not supported" one; the rotated, scaled and
/// combined arrows are where the specification's transform puts them (pixel by pixel
/// against the arrow image read here), so each points at its green marker.
#[test]
fn texture_transform_test_shows_no_not_supported_or_error_marker() {
    let mut scene = load("TextureTransformTest/TextureTransformTest.gltf");
    assert!(scene.unsupported.is_empty(), "{:?}", scene.unsupported);
    scene.environment = Environment::Constant(Vec3::ONE);
    // An orthographic view of the 3.3 × 2.2 m board from +Z, 100 px per metre.
    let (w, h) = (340u32, 230u32);
    scene.orthographic_cameras = vec![raygun::scene::OrthographicCamera {
        name: "board".into(),
        position: Vec3::new(0.0, 0.0, 5.0),
        forward: Vec3::NEG_Z,
        up: Vec3::Y,
        ymag: 1.15,
    }];
    let camera = RenderCamera::choose(&scene, Some("board"), w, h).unwrap();
    let img = render(&scene, camera, w, h, 16);
    // The mean of the 3 × 3 pixels around a board point.
    let at = |x: f32, y: f32| {
        let px = ((x + 1.7) * 100.0) as usize;
        let py = ((1.15 - y) * 100.0) as usize;
        let mut sum = Vec3::ZERO;
        for dy in 0..3 {
            for dx in 0..3 {
                sum += img[(py + dy - 1) * w as usize + px + dx - 1];
            }
        }
        sum / 9.0
    };
    // Offsets: a point near each square's top-left corner is its quadrant's plain colour.
    for (name, cx, want) in [
        ("Offset U", -1.1, "green"),
        ("Offset V", 0.0, "blue"),
        ("Offset UV", 1.1, "cyan"),
    ] {
        let c = at(cx - 0.42, 0.55 + 0.42);
        let n = c / c.max_element();
        let got = match (n.x > 0.6, n.y > 0.6, n.z > 0.6) {
            (true, true, false) => "yellow (not supported)",
            (false, true, false) if n.z < 0.3 => "green",
            (false, false, true) => "blue",
            (false, true, true) => "cyan",
            _ => "other",
        };
        assert_eq!(got, want, "{name}: {c}");
    }
    // The arrows against the spec, pixel by pixel, inside each square away from its edges
    // and from the marker squares drawn over it.
    let arrow = image::open(sample("TextureTransformTest/Arrow.png"))
        .unwrap()
        .to_luma8();
    let markers: [(f32, f32); 6] = [
        (-1.1 - 0.079, -0.55 - 0.516),
        (-1.1 + 0.278, -0.55 - 0.278),
        (-1.1 + 0.516, -0.55 + 0.079),
        (0.0185, -0.55 - 0.0185),
        (0.278, -0.55 - 0.278),
        (1.1 - 0.07, -0.55 - 0.25),
    ];
    for (name, cx, offset, rotation, scale) in [
        (
            "Rotation",
            -1.1f32,
            Vec2::ZERO,
            std::f32::consts::FRAC_PI_8,
            Vec2::ONE,
        ),
        ("Scale", 0.0, Vec2::ZERO, 0.0, Vec2::splat(1.5)),
        ("All", 1.1, Vec2::new(-0.2, -0.1), 0.3, Vec2::splat(1.5)),
    ] {
        let (mut agree, mut total) = (0, 0);
        for iy in 0..40 {
            for ix in 0..40 {
                let (lx, ly) = (
                    -0.45 + ix as f32 * 0.9 / 39.0,
                    -0.45 + iy as f32 * 0.9 / 39.0,
                );
                let (x, y) = (cx + lx, -0.55 + ly);
                if markers
                    .iter()
                    .any(|m| (m.0 - x).abs() < 0.12 && (m.1 - y).abs() < 0.12)
                {
                    continue;
                }
                // The square's own UVs: u along +x, v down from its top edge.
                let uv = spec_transform(Vec2::new(lx + 0.5, 0.5 - ly), offset, rotation, scale);
                let tx = ((uv.x * 128.0).floor() as i64).clamp(0, 127) as u32;
                let ty = ((uv.y * 128.0).floor() as i64).clamp(0, 127) as u32;
                let dark_tex = arrow.get_pixel(tx, ty)[0] < 128;
                let dark_img =
                    luminance(at(x, y)) < 0.3 * luminance(at(cx - 0.44, -0.55 + 0.44)).max(0.05);
                total += 1;
                if dark_tex == dark_img {
                    agree += 1;
                }
            }
        }
        assert!(
            agree * 100 >= total * 95,
            "{name}: {agree} of {total} samples agree with the spec"
        );
    }
}

/// ClearCoatTest's labels are emissive textures (black text on white) beside emissiveFactor 1:
/// the label quads glow except where the text is (before, the texture was dropped, every
/// label triangle was a uniform white lamp and the text vanished).
#[test]
fn clear_coat_test_labels_glow_only_where_their_text_is() {
    let scene = load("ClearCoatTest/ClearCoatTest.gltf");
    // Everything it uses is modelled: the coat's strength, roughness and normal textures too.
    assert!(scene.unsupported.is_empty(), "{:?}", scene.unsupported);
    let ext_of = |name: &str| {
        let i = scene.materials.iter().position(|m| m.name == name).unwrap();
        scene.material_ext(i as u32)
    };
    assert!(ext_of("Partial_Coated").clearcoat_texture.is_some());
    assert!(
        ext_of("RoughVariations_Coated")
            .clearcoat_roughness_texture
            .is_some()
    );
    assert!(ext_of("CoatNorm_Coated").clearcoat_normal_texture.is_some());
    let label = scene
        .materials
        .iter()
        .position(|m| m.name == "LabelMaterial")
        .unwrap() as u32;
    let labels: Vec<usize> = (0..scene.triangles.len())
        .filter(|&i| scene.triangles[i].material == label)
        .collect();
    let emitting: f32 =
        labels.iter().map(|&i| scene.emission_scale(i)).sum::<f32>() / labels.len() as f32;
    assert!(
        emitting > 0.6 && emitting < 0.97,
        "label quads glow over {:.1} % of their area on average: the text must stay dark",
        100.0 * emitting
    );
    assert_eq!(
        scene.emissive_triangle_count(),
        labels
            .iter()
            .filter(|&&i| scene.emission_scale(i) > 0.0)
            .count()
    );
}
