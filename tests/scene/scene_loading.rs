//! Scene loading: the generated paper scenes round-trip through GLB, node transforms, materials
//! and textures arrive as the file says, every unsupported feature is named, bad files give
//! errors naming the file and element, and bad data never reaches the tracer.

use crate::support;
use support::tmp_dir;

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};
use raygun::scene::generate::{self, CORNELL_CAMERA_POSITION, CityParams, cornell_camera_yfov};
use raygun::scene::{MAX_ABSORPTION, MAX_COORDINATE, Scene, SceneError, Triangle};
use serde_json::{Value, json};

/// Positions and directions written by the generator pass through f32 TRS transforms.
const POS_TOL: f32 = 1e-5;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/scenes")
        .join(name)
}

fn geometric_normal(t: &Triangle) -> Vec3 {
    (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).normalize()
}

/// Every triangle's shading normals lie on the front (counter-clockwise) side.
fn assert_normals_follow_winding(scene: &Scene) {
    for (i, t) in scene.triangles.iter().enumerate() {
        let g = geometric_normal(t);
        for n in t.n {
            assert!(n.dot(g) > 0.99, "triangle {i}: normal {n} vs geometric {g}");
            assert!((n.length() - 1.0).abs() < 1e-5);
        }
    }
}

fn material_named<'a>(scene: &'a Scene, name: &str) -> (u32, &'a raygun::scene::Material) {
    let i = scene
        .materials
        .iter()
        .position(|m| m.name == name)
        .unwrap_or_else(|| panic!("no material '{name}'"));
    (i as u32, &scene.materials[i])
}

// ---------------------------------------------------------------------------------------------
// A small glTF JSON writer for hand-made test files (buffers as data URIs).

#[derive(Default)]
struct Doc {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Doc {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()
        }));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    /// A float accessor; `ty` is "VEC3", "VEC2" or "SCALAR". POSITION needs min/max, which the
    /// loader ignores, so every VEC3 gets a nominal pair.
    fn floats(&mut self, values: &[f32], ty: &str) -> usize {
        let n = match ty {
            "VEC3" => 3,
            "VEC2" => 2,
            _ => 1,
        };
        let view = self.view(bytemuck::cast_slice(values));
        let mut acc = json!({
            "bufferView": view, "componentType": 5126, "count": values.len() / n, "type": ty
        });
        if ty == "VEC3" {
            acc["min"] = json!([-1.0, -1.0, -1.0]);
            acc["max"] = json!([1.0, 1.0, 1.0]);
        }
        self.accessors.push(acc);
        self.accessors.len() - 1
    }

    fn indices(&mut self, values: &[u16]) -> usize {
        let view = self.view(bytemuck::cast_slice(values));
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5123, "count": values.len(), "type": "SCALAR"
        }));
        self.accessors.len() - 1
    }

    /// The document: `extra`'s keys are merged in (meshes, nodes, scenes, materials, …).
    fn finish(self, extra: Value) -> Vec<u8> {
        let mut root = json!({
            "asset": { "version": "2.0" },
            "buffers": [{
                "byteLength": self.bin.len(),
                "uri": format!("data:application/octet-stream;base64,{}", base64::encode(&self.bin)),
            }],
            "bufferViews": self.views,
            "accessors": self.accessors,
        });
        for (k, v) in extra.as_object().unwrap() {
            root[k] = v.clone();
        }
        serde_json::to_vec(&root).unwrap()
    }
}

/// One triangle in the z = 0 plane facing +Z, with NORMAL (0, 0, 1).
const TRI: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
const TRI_NORMALS: [f32; 9] = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0];

fn load(bytes: &[u8]) -> Result<Scene, SceneError> {
    Scene::from_glb_bytes(bytes, "test.gltf")
}

fn err(bytes: &[u8]) -> String {
    load(bytes)
        .expect_err("the file must be rejected")
        .to_string()
}

// ---------------------------------------------------------------------------------------------
// Generated scenes

#[test]
fn cornell_round_trips_with_metric_frame_and_front_camera() {
    let scene = Scene::builtin("cornell").unwrap();
    assert_eq!(scene.triangles.len(), 30);
    assert_eq!(scene.materials.len(), 3);
    assert!(scene.unsupported.is_empty(), "{:?}", scene.unsupported);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.emissive_triangle_count(), 0);
    let b = scene.bounds().unwrap();
    // Cornell data: 556 × 548.8 × 559.2 mm, opening at z = 0, centred on x = 0.
    assert!(
        (b.min - Vec3::new(-0.278, 0.0, -0.5592))
            .abs()
            .max_element()
            < POS_TOL,
        "{b:?}"
    );
    assert!(
        (b.max - Vec3::new(0.278, 0.5488, 0.0)).abs().max_element() < POS_TOL,
        "{b:?}"
    );
    let cam = scene.camera("front").unwrap();
    assert!((cam.position - CORNELL_CAMERA_POSITION).length() < POS_TOL);
    assert!((cam.forward - Vec3::NEG_Z).length() < POS_TOL);
    assert!((cam.up - Vec3::Y).length() < POS_TOL);
    assert!((cam.yfov - cornell_camera_yfov()).abs() < 1e-6);
    assert_normals_follow_winding(&scene);
    // Red on the camera's left (−X), green on its right, every wall facing into the room.
    let (red, m) = material_named(&scene, "red");
    assert_eq!(m.base_color.truncate(), Vec3::new(0.63, 0.065, 0.05));
    assert_eq!((m.metallic, m.roughness), (0.0, 1.0));
    let (green, _) = material_named(&scene, "green");
    for t in &scene.triangles {
        let centroid = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        if t.material == red {
            assert!(centroid.x < -0.27 && t.n[0].x > 0.99);
        }
        if t.material == green {
            assert!(centroid.x > 0.27 && t.n[0].x < -0.99);
        }
        // Nothing closes the front: no triangle faces the camera from z = 0.
        assert!(t.p.iter().any(|p| p.z < -1e-3));
    }
}

#[test]
fn cornell_light_emits_17_12_4_from_two_triangles_under_the_ceiling() {
    let scene = Scene::builtin("cornell-light").unwrap();
    assert_eq!(scene.triangles.len(), 32);
    assert_eq!(scene.emissive_triangle_count(), 2);
    let (light, m) = material_named(&scene, "light");
    assert!(
        (m.emission - Vec3::new(17.0, 12.0, 4.0))
            .abs()
            .max_element()
            < 1e-5
    );
    for t in scene.triangles.iter().filter(|t| t.material == light) {
        assert!(t.p.iter().all(|p| (p.y - 0.5478).abs() < POS_TOL));
        assert!(t.n[0].y < -0.99, "the light faces down");
    }
}

#[test]
fn small_city_round_trips_with_textures_and_cameras() {
    let generated = generate::city(CityParams::SMALL).unwrap();
    let scene = Scene::from_glb_bytes(&generated.glb, "city-small").unwrap();
    assert_eq!(scene.triangles.len(), generated.triangles);
    assert!(scene.unsupported.is_empty() && scene.warnings.is_empty());
    assert_eq!(scene.materials.len(), 7);
    assert_eq!(scene.textures.len(), 2);
    for t in &scene.textures {
        assert_eq!((t.width, t.height, t.texels.len()), (64, 64, 64 * 64));
    }
    let textured = scene
        .materials
        .iter()
        .filter(|m| m.base_color_texture.is_some())
        .count();
    assert_eq!(textured, 2, "asphalt and brick");
    assert_normals_follow_winding(&scene);
    let street = scene.camera("street").unwrap();
    assert!((street.position.y - 1.7).abs() < POS_TOL);
    let aerial = scene.camera("aerial").unwrap();
    let b = scene.bounds().unwrap();
    assert!(
        aerial.position.y > b.max.y,
        "the aerial camera is above the roofs"
    );
    // It looks at the city's centre.
    let to_centre = (Vec3::ZERO - aerial.position).normalize();
    assert!(aerial.forward.dot(to_centre) > 0.9999);
    assert!(b.min.y >= 0.0);
}

#[test]
fn paper_city_has_about_350k_triangles_and_loads_without_losses() {
    let generated = generate::city(CityParams::PAPER).unwrap();
    // DESIGN.md §7: "a city model of about 350k triangles" — within 5 %.
    assert!(
        (332_500..=367_500).contains(&generated.triangles),
        "{}",
        generated.triangles
    );
    let scene = Scene::from_glb_bytes(&generated.glb, "city").unwrap();
    assert_eq!(scene.triangles.len(), generated.triangles);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}

#[test]
fn city_seed_changes_the_layout_and_blocks_are_checked() {
    let a = generate::city(CityParams { blocks: 2, seed: 1 }).unwrap();
    let b = generate::city(CityParams { blocks: 2, seed: 2 }).unwrap();
    assert_ne!(a.glb, b.glb);
    assert!(generate::city(CityParams { blocks: 0, seed: 1 }).is_err());
    let too_many = CityParams::MAX_BLOCKS + 1;
    let e = generate::city(CityParams {
        blocks: too_many,
        seed: 1,
    })
    .unwrap_err()
    .to_string();
    assert!(e.contains("--blocks"), "{e}");
}

#[test]
fn shipped_scenes_are_byte_identical_to_the_generator() {
    // If this fails after a deliberate generator change (or a png crate update that changes
    // its compressed output), regenerate with:
    //   raygun scene cornell --out tests/data/scenes/cornell.glb
    //   raygun scene cornell-light --out tests/data/scenes/cornell-light.glb
    //   raygun scene city --blocks 4 --out tests/data/scenes/city-small.glb
    for (file, generated) in [
        ("cornell.glb", generate::cornell(false)),
        ("cornell-light.glb", generate::cornell(true)),
        ("city-small.glb", generate::city(CityParams::SMALL)),
    ] {
        let golden = std::fs::read(data(file)).unwrap();
        assert!(golden.len() < 1 << 20, "{file} must stay well under 1 MB");
        assert!(
            generated.unwrap().glb == golden,
            "{file} differs from the generator's output"
        );
        let scene = Scene::load(data(file)).unwrap();
        assert!(!scene.triangles.is_empty());
    }
}

#[test]
fn open_accepts_paths_and_builtins() {
    let from_file = Scene::open(data("cornell.glb").to_str().unwrap()).unwrap();
    let builtin = Scene::open("builtin:cornell").unwrap();
    assert_eq!(from_file.triangles, builtin.triangles);
    assert_eq!(
        Scene::open("builtin:city-small").unwrap().triangles.len(),
        3862
    );
    let e = Scene::open("builtin:moon").unwrap_err().to_string();
    assert!(e.contains("'moon'") && e.contains("cornell-light"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Node transforms and geometry

#[test]
fn node_transforms_compose_and_mirroring_keeps_the_front_side() {
    let mut d = Doc::default();
    let pos = d.floats(&TRI, "VEC3");
    let nor = d.floats(&TRI_NORMALS, "VEC3");
    let bytes = d.finish(json!({
        "meshes": [{ "name": "tri", "primitives": [{ "attributes": { "POSITION": pos, "NORMAL": nor } }] }],
        "nodes": [
            // parent: translate (10, 0, 0); child: rotate 90° about +Y, scale 2.
            { "name": "parent", "translation": [10.0, 0.0, 0.0], "children": [1] },
            { "name": "child", "mesh": 0, "scale": [2.0, 2.0, 2.0],
              "rotation": [0.0, std::f32::consts::FRAC_1_SQRT_2, 0.0, std::f32::consts::FRAC_1_SQRT_2] },
            // mirrored in x
            { "name": "mirror", "mesh": 0, "scale": [-1.0, 1.0, 1.0] },
            // a matrix (column-major): translate (0, 5, 0)
            { "name": "matrix", "mesh": 0, "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,5,0,1] },
        ],
        "scenes": [{ "nodes": [0, 2, 3] }],
        "scene": 0,
    }));
    let scene = load(&bytes).unwrap();
    assert_eq!(scene.triangles.len(), 3);
    assert_normals_follow_winding(&scene);
    // Rotation by 90° about +Y maps +X → −Z and +Z → +X.
    let t = &scene.triangles[0];
    let expect = [
        Vec3::new(10.0, 0.0, 0.0),
        Vec3::new(10.0, 0.0, -2.0),
        Vec3::new(10.0, 2.0, 0.0),
    ];
    for (p, e) in t.p.iter().zip(expect) {
        assert!((*p - e).length() < POS_TOL, "{p} vs {e}");
    }
    assert!((t.n[0] - Vec3::X).length() < POS_TOL);
    // The mirrored copy: still facing +Z (a mirror in x keeps z normals), winding swapped so
    // the geometric normal agrees.
    let m = &scene.triangles[1];
    assert!((m.n[0] - Vec3::Z).length() < POS_TOL);
    assert!((geometric_normal(m) - Vec3::Z).length() < POS_TOL);
    assert!(m.p.contains(&Vec3::new(-1.0, 0.0, 0.0)));
    assert!(scene.triangles[2].p.contains(&Vec3::new(0.0, 5.0, 0.0)));
}

#[test]
fn missing_normals_become_flat_normals_and_uvs_zero() {
    let mut d = Doc::default();
    let pos = d.floats(&[0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0], "VEC3");
    let bytes = d.finish(json!({
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": pos } }] }],
        "nodes": [{ "mesh": 0 }],
        "scenes": [{ "nodes": [0] }],
    }));
    let scene = load(&bytes).unwrap();
    let t = &scene.triangles[0];
    assert_eq!(t.n, [Vec3::Y; 3]);
    assert_eq!(t.uv, [Vec2::ZERO; 3]);
    // No material: glTF's default material.
    assert_eq!(scene.materials, vec![raygun::scene::Material::default()]);
}

#[test]
fn indexed_and_sparse_accessors_read_correctly() {
    let mut d = Doc::default();
    // A quad as 4 vertices + 6 indices; a sparse accessor moves vertex 3 from (9,9,9) to (0,1,0).
    let pos = d.floats(
        &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 9.0, 9.0, 9.0],
        "VEC3",
    );
    let idx = d.indices(&[0, 1, 2, 0, 2, 3]);
    let sparse_idx = d.view(bytemuck::cast_slice(&[3u16]));
    let sparse_val = d.view(bytemuck::cast_slice(&[0.0f32, 1.0, 0.0]));
    d.accessors[pos]["sparse"] = json!({
        "count": 1,
        "indices": { "bufferView": sparse_idx, "componentType": 5123 },
        "values": { "bufferView": sparse_val },
    });
    let bytes = d.finish(json!({
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": pos }, "indices": idx }] }],
        "nodes": [{ "mesh": 0 }],
        "scenes": [{ "nodes": [0] }],
    }));
    let scene = load(&bytes).unwrap();
    assert_eq!(scene.triangles.len(), 2);
    assert_eq!(scene.triangles[1].p[2], Vec3::new(0.0, 1.0, 0.0));
    assert_eq!(scene.bounds().unwrap().max, Vec3::new(1.0, 1.0, 0.0));
}

#[test]
fn degenerate_nan_and_huge_triangles_are_dropped_and_counted_per_mesh() {
    let mut d = Doc::default();
    let nan = f32::NAN;
    let triangles: [[f32; 9]; 7] = [
        [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],  // good
        [0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0],  // collinear: zero area
        [0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0],  // repeated vertex: zero area
        [0.0, 0.0, 0.0, nan, 0.0, 0.0, 0.0, 1.0, 0.0],  // NaN
        [0.0, 0.0, 0.0, 1e30, 0.0, 0.0, 0.0, 1.0, 0.0], // beyond MAX_COORDINATE
        [f32::INFINITY, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], // inf
        [0.0, 0.0, 0.0, 1e-20, 0.0, 0.0, 0.0, 1e-20, 0.0], // |e1×e2|² underflows: zero area
    ];
    let pos = d.floats(triangles.as_flattened(), "VEC3");
    let small = d.floats(&TRI, "VEC3");
    let bytes = d.finish(json!({
        "meshes": [
            { "name": "Junk", "primitives": [{ "attributes": { "POSITION": pos } }] },
            { "name": "Blown up", "primitives": [{ "attributes": { "POSITION": small } }] },
        ],
        "nodes": [
            { "mesh": 0 },
            // A finite mesh scaled past f32: its vertices become inf or exceed the limit.
            { "mesh": 1, "scale": [1e30, 1e30, 1e30] },
            { "mesh": 1, "scale": [3e38, 3e38, 3e38], "translation": [3e38, 0.0, 0.0] },
        ],
        "scenes": [{ "nodes": [0, 1, 2] }],
    }));
    let scene = load(&bytes).unwrap();
    assert_eq!(scene.triangles.len(), 1);
    for t in &scene.triangles {
        assert!(
            t.p.iter()
                .all(|p| p.is_finite() && p.abs().max_element() <= MAX_COORDINATE)
        );
    }
    let w = scene.warnings.join("\n");
    assert!(
        w.contains("mesh 'Junk': 3 zero-area triangles dropped"),
        "{w}"
    );
    assert!(
        w.contains("mesh 'Junk': 2 triangles with non-finite vertices dropped"),
        "{w}"
    );
    assert!(
        w.contains("mesh 'Junk': 1 triangles beyond the coordinate limit"),
        "{w}"
    );
    assert!(
        w.contains("mesh 'Blown up': 1 triangles beyond the coordinate limit"),
        "{w}"
    );
    assert!(
        w.contains("mesh 'Blown up': 1 triangles with non-finite vertices dropped"),
        "{w}"
    );
}

#[test]
fn bad_normals_and_uvs_are_repaired_not_passed_on() {
    let mut d = Doc::default();
    let pos = d.floats(&TRI, "VEC3");
    // Zero, NaN, and a tiny but usable normal (squaring it would underflow).
    let nor = d.floats(
        &[0.0, 0.0, 0.0, f32::NAN, 0.0, 1.0, 0.0, 0.0, 1e-30],
        "VEC3",
    );
    let uv = d.floats(&[f32::INFINITY, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC2");
    let bytes = d.finish(json!({
        "meshes": [{ "name": "M", "primitives": [{ "attributes": { "POSITION": pos, "NORMAL": nor, "TEXCOORD_0": uv } }] }],
        "nodes": [{ "mesh": 0 }],
        "scenes": [{ "nodes": [0] }],
    }));
    let scene = load(&bytes).unwrap();
    let t = scene.triangles[0];
    assert_eq!(t.n, [Vec3::Z; 3]);
    assert_eq!(t.uv[0], Vec2::ZERO);
    assert_eq!(t.uv[1], Vec2::new(1.0, 0.0));
    let w = scene.warnings.join("\n");
    assert!(w.contains("mesh 'M': 2 unusable vertex normals"), "{w}");
    assert!(
        w.contains("mesh 'M': 1 non-finite texture coordinates"),
        "{w}"
    );
}

#[test]
fn empty_scenes_load_with_nothing_to_draw() {
    let none = load(br#"{"asset":{"version":"2.0"}}"#).unwrap();
    assert!(none.triangles.is_empty() && none.cameras.is_empty());
    assert_eq!(none.bounds(), None);
    assert!(none.warnings[0].contains("no scene"), "{:?}", none.warnings);
    let empty = load(br#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[]}],"scene":0}"#).unwrap();
    assert!(empty.triangles.is_empty() && empty.warnings.is_empty());
}

#[test]
fn cameras_follow_their_nodes_and_bad_ones_are_rejected() {
    let camera = |node: Value| {
        let mut n = node;
        n["camera"] = json!(0);
        n["name"] = json!("cam");
        Doc::default().finish(json!({
            "cameras": [{ "type": "perspective", "perspective": { "yfov": 0.5, "znear": 0.1 } }],
            "nodes": [n],
            "scenes": [{ "nodes": [0] }],
        }))
    };
    // Rotated 90° about +X (y → z, z → −y): the view direction −Z becomes +Y, up +Y becomes
    // +Z; the node's scale must not leak into the unit vectors.
    let s = load(&camera(json!({
        "translation": [1.0, 2.0, 3.0],
        "rotation": [std::f32::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f32::consts::FRAC_1_SQRT_2],
        "scale": [3.0, 3.0, 3.0],
    })))
    .unwrap();
    let c = s.camera("cam").unwrap();
    assert!((c.position - Vec3::new(1.0, 2.0, 3.0)).length() < POS_TOL);
    assert!((c.forward - Vec3::Y).length() < POS_TOL, "{}", c.forward);
    assert!((c.up - Vec3::Z).length() < POS_TOL, "{}", c.up);
    assert_eq!(c.yfov, 0.5);
    let e = err(&camera(json!({ "scale": [0.0, 0.0, 0.0] })));
    assert!(
        e.contains("test.gltf: camera 'cam'") && e.contains("degenerate"),
        "{e}"
    );
    let e = err(&camera(json!({ "translation": [1e30, 0.0, 0.0] })));
    assert!(e.contains("camera 'cam'") && e.contains("beyond"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Materials and textures

fn png_bytes(img: &image::DynamicImage) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// A textured triangle whose material has `material` merged in and whose image is `image`.
fn textured(image: Value, material: Value) -> Vec<u8> {
    let mut d = Doc::default();
    let pos = d.floats(&TRI, "VEC3");
    let uv = d.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC2");
    let mut m = json!({
        "name": "painted",
        "pbrMetallicRoughness": {
            "baseColorFactor": [0.5, 0.5, 0.5, 1.0],
            "baseColorTexture": { "index": 0 },
        },
    });
    for (k, v) in material.as_object().unwrap() {
        m[k] = v.clone();
    }
    d.finish(json!({
        "images": [image],
        "textures": [{ "name": "tex", "source": 0 }],
        "materials": [m],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": pos, "TEXCOORD_0": uv }, "material": 0 }] }],
        "nodes": [{ "mesh": 0 }],
        "scenes": [{ "nodes": [0] }],
    }))
}

#[test]
fn textures_decode_from_data_uris_and_external_files_into_rgba8() {
    // 2×1 RGB: red, then blue; RGB expands to opaque RGBA.
    let rgb = image::DynamicImage::ImageRgb8(
        image::RgbImage::from_raw(2, 1, vec![255, 0, 0, 0, 0, 255]).unwrap(),
    );
    let uri = format!("data:image/png;base64,{}", base64::encode(png_bytes(&rgb)));
    let scene = load(&textured(json!({ "uri": uri }), json!({}))).unwrap();
    let t = &scene.textures[0];
    assert_eq!((t.name.as_str(), t.width, t.height), ("tex", 2, 1));
    assert_eq!(t.texels, vec![[255, 0, 0, 255], [0, 0, 255, 255]]);
    assert_eq!(scene.materials[0].base_color_texture, Some(0));

    // A 16-bit grey PNG next to a .gltf file: 0xFFFF → 255, 0x8080 → 128.
    let dir = tmp_dir("textures");
    let grey = image::DynamicImage::ImageLuma16(
        image::ImageBuffer::from_raw(2, 1, vec![0xFFFF, 0x8080]).unwrap(),
    );
    std::fs::write(dir.join("grey 16.png"), png_bytes(&grey)).unwrap();
    let gltf = dir.join("scene.gltf");
    std::fs::write(
        &gltf,
        textured(json!({ "uri": "grey%2016.png" }), json!({})),
    )
    .unwrap();
    let scene = Scene::load(&gltf).unwrap();
    assert_eq!(
        scene.textures[0].texels,
        vec![[255, 255, 255, 255], [128, 128, 128, 255]]
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn undecodable_images_fall_back_to_the_factor_and_are_named() {
    let garbage = format!(
        "data:image/png;base64,{}",
        base64::encode(b"not a png at all")
    );
    let scene = load(&textured(
        json!({ "uri": garbage, "name": "broken" }),
        json!({}),
    ))
    .unwrap();
    assert!(scene.textures.is_empty());
    let m = &scene.materials[0];
    assert_eq!(m.base_color_texture, None);
    assert_eq!(m.base_color.x, 0.5);
    let w = scene.warnings.join("\n");
    assert!(
        w.contains("texture 'tex': cannot decode the Png image"),
        "{w}"
    );

    let webp = format!("data:image/webp;base64,{}", base64::encode(b"RIFF....WEBP"));
    let scene = load(&textured(json!({ "uri": webp }), json!({}))).unwrap();
    assert_eq!(scene.materials[0].base_color_texture, None);
    assert!(
        scene
            .unsupported
            .iter()
            .any(|u| u.contains("image format image/webp (texture 'tex'")),
        "{:?}",
        scene.unsupported
    );
}

/// A scene from anywhere reads only files in its own folder and below: absolute paths,
/// `file:` URIs and `../` out of the folder are refused, naming the URI and the rule, unless
/// the scene is trusted (`--trust-scene`). Devices are never read, trusted or not, and a
/// buffer is read to its declared length only, which its file must have.
#[test]
fn a_scene_reads_only_files_in_its_own_folder() {
    let root = tmp_dir("confined");
    let folder = root.join("scene");
    std::fs::create_dir_all(folder.join("bin")).unwrap();
    // One triangle's positions (36 bytes), inside and outside the scene's folder.
    let tri: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    std::fs::write(folder.join("bin/tri.bin"), &tri).unwrap();
    std::fs::write(root.join("outside.bin"), &tri).unwrap();
    let gltf = folder.join("scene.gltf");
    let write = |uri: &str, len: usize| {
        let doc = json!({
            "asset": { "version": "2.0" },
            "buffers": [{ "byteLength": len, "uri": uri }],
            "bufferViews": [{ "buffer": 0, "byteLength": 36 }],
            "accessors": [{ "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                            "min": [0, 0, 0], "max": [1, 1, 0] }],
            "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 } }] }],
            "nodes": [{ "mesh": 0 }],
            "scenes": [{ "nodes": [0] }]
        });
        std::fs::write(&gltf, doc.to_string()).unwrap();
    };
    write("bin/tri.bin", 36);
    assert_eq!(Scene::load(&gltf).unwrap().triangles.len(), 1);
    let outside = root.join("outside.bin");
    for uri in [
        "../outside.bin".to_owned(),
        outside.display().to_string(),
        format!("file://{}", outside.display()),
        "bin/../../outside.bin".to_owned(),
    ] {
        write(&uri, 36);
        let e = Scene::load(&gltf).unwrap_err().to_string();
        assert!(
            e.contains(&format!("buffer 0: cannot read '{uri}'"))
                && e.contains("outside the scene's folder")
                && e.contains("--trust-scene"),
            "{uri}: {e}"
        );
        let trusted = Scene::load_with(&gltf, raygun::scene::UriAccess::Anywhere).unwrap();
        assert_eq!(trusted.triangles.len(), 1, "{uri}");
    }
    // /dev/zero once grew without bound: a device is refused unread.
    write("/dev/zero", 36);
    let e = Scene::load_with(&gltf, raygun::scene::UriAccess::Anywhere)
        .unwrap_err()
        .to_string();
    assert!(e.contains("character device, not a file"), "{e}");
    // A byteLength beyond the file is refused before anything is allocated.
    write("bin/tri.bin", 1 << 40);
    let e = Scene::load(&gltf).unwrap_err().to_string();
    assert!(
        e.contains("has 36 bytes, fewer than the 1099511627776"),
        "{e}"
    );
    // The scene file itself: a device is no scene.
    let e = Scene::load("/dev/zero").unwrap_err();
    assert!(
        raygun::messages::chain(&e).contains("character device"),
        "{}",
        raygun::messages::chain(&e)
    );
    // The command line's switch.
    write(&outside.display().to_string(), 36);
    let info = |extra: &[&str]| {
        let mut args = vec!["scene", "info", support::s(&gltf)];
        args.extend_from_slice(extra);
        support::raygun(&args)
    };
    support::fails_with(&info(&[]), &["outside the scene's folder", "--trust-scene"]);
    let o = info(&["--trust-scene"]);
    assert!(o.status.success(), "{}", support::stderr(&o));
}

#[test]
fn missing_texture_and_buffer_files_are_errors_naming_the_uri() {
    let dir = tmp_dir("missing");
    let gltf = dir.join("scene.gltf");
    std::fs::write(
        &gltf,
        textured(json!({ "uri": "nowhere/bricks.png" }), json!({})),
    )
    .unwrap();
    let e = Scene::load(&gltf).unwrap_err().to_string();
    assert!(
        e.contains("scene.gltf: texture 'tex': cannot read 'nowhere/bricks.png'"),
        "{e}"
    );

    let buffer =
        br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":12,"uri":"geometry.bin"}]}"#;
    std::fs::write(&gltf, buffer).unwrap();
    let e = Scene::load(&gltf).unwrap_err().to_string();
    assert!(
        e.contains("scene.gltf: buffer 0: cannot read 'geometry.bin'"),
        "{e}"
    );
    // In memory there is no directory to look in.
    let e = load(buffer).unwrap_err().to_string();
    assert!(
        e.contains("'geometry.bin'") && e.contains("in-memory"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn emission_is_factor_times_strength_and_factors_are_checked() {
    let bytes = |material: Value| {
        let mut d = Doc::default();
        let p = d.floats(&TRI, "VEC3");
        d.finish(json!({
            "extensionsUsed": ["KHR_materials_emissive_strength"],
            "materials": [material],
            "meshes": [{ "primitives": [{ "attributes": { "POSITION": p }, "material": 0 }] }],
            "nodes": [{ "mesh": 0 }],
            "scenes": [{ "nodes": [0] }],
        }))
    };
    let s = load(&bytes(json!({
        "name": "lamp",
        "emissiveFactor": [1.0, 0.5, 0.25],
        "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": 8.0 } },
        "pbrMetallicRoughness": { "metallicFactor": 0.25, "roughnessFactor": 0.5 },
    })))
    .unwrap();
    let m = &s.materials[0];
    assert_eq!(m.emission, Vec3::new(8.0, 4.0, 2.0));
    assert_eq!((m.metallic, m.roughness), (0.25, 0.5));
    assert_eq!(s.emissive_triangle_count(), 1);
    assert!(
        s.unsupported.is_empty(),
        "the strength extension is supported"
    );
    // Without the extension the factor alone is the radiance.
    let s = load(&bytes(json!({ "emissiveFactor": [0.5, 0.5, 0.5] }))).unwrap();
    assert_eq!(s.materials[0].emission, Vec3::splat(0.5));
    // Out-of-range factors are clamped and reported; a negative strength is an error.
    let s = load(&bytes(json!({ "name": "hot", "pbrMetallicRoughness": { "baseColorFactor": [2.0, 0.5, 0.5, 1.0] } }))).unwrap();
    assert_eq!(s.materials[0].base_color.x, 1.0);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("material 'hot': baseColorFactor 2 clamped")),
        "{:?}",
        s.warnings
    );
    let e = err(&bytes(json!({
        "name": "dark",
        "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": -1.0 } },
    })));
    assert!(
        e.contains("test.gltf: material 'dark': emissiveStrength -1"),
        "{e}"
    );
}

/// A one-triangle file with `material` (its extensions listed as used) and one texture, a
/// 1 × 1 PNG, for the material to name.
fn material_with(material: Value) -> Vec<u8> {
    let png = format!(
        "data:image/png;base64,{}",
        base64::encode(png_bytes(&image::DynamicImage::new_rgba8(1, 1)))
    );
    let used: Vec<&String> = material["extensions"]
        .as_object()
        .map(|e| e.keys().collect())
        .unwrap_or_default();
    let mut d = Doc::default();
    let p = d.floats(&TRI, "VEC3");
    d.finish(json!({
        "extensionsUsed": used,
        "images": [{ "uri": png }],
        "textures": [{ "source": 0 }],
        "materials": [material],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": p }, "material": 0 }] }],
        "nodes": [{ "mesh": 0 }],
        "scenes": [{ "nodes": [0] }],
    }))
}

/// KHR_materials_volume: a medium of attenuationColor c at attenuationDistance d absorbs
/// σ = −ln(c)/d per unit length; a thin-walled material (thicknessFactor 0, the default) and a
/// clear medium absorb nothing; bad values are clamped and said, or refused by name.
#[test]
fn a_volume_absorbs_as_its_attenuation_says_and_bad_ones_are_named() {
    let bytes = |volume: Value| {
        material_with(json!({ "name": "amber", "extensions": {
            "KHR_materials_transmission": { "transmissionFactor": 1.0 },
            "KHR_materials_volume": volume } }))
    };
    let s = load(&bytes(json!({
        "thicknessFactor": 0.5, "attenuationDistance": 2.0, "attenuationColor": [0.5, 0.25, 1.0],
    })))
    .unwrap();
    let want = Vec3::new(2f32.ln() / 2.0, 4f32.ln() / 2.0, 0.0);
    let got = s.material_ext(0).absorption;
    assert!((got - want).abs().max_element() < 1e-6, "{got} vs {want}");
    assert!(s.unsupported.is_empty() && s.notes.is_empty(), "{s:?}");
    // Thin-walled (the default thickness) with an attenuation: none, and said.
    let s = load(&bytes(
        json!({ "attenuationDistance": 2.0, "attenuationColor": [0.5, 0.5, 0.5] }),
    ))
    .unwrap();
    assert_eq!(s.material_ext(0).absorption, Vec3::ZERO);
    assert!(
        s.notes
            .iter()
            .any(|n| n.starts_with("material 'amber'") && n.contains("thin-walled")),
        "{:?}",
        s.notes
    );
    // A clear medium (no attenuation given): none, nothing said; a thickness map is not used.
    let s = load(&bytes(
        json!({ "thicknessFactor": 1.0, "thicknessTexture": { "index": 0 } }),
    ))
    .unwrap();
    assert_eq!(s.material_ext(0).absorption, Vec3::ZERO);
    assert_eq!(s.notes.len(), 1, "{:?}", s.notes);
    assert!(s.notes[0].starts_with("thicknessTexture (material 'amber') not used"));
    // A black channel absorbs everything, capped to stay finite; colours beyond [0, 1] are
    // clamped and said.
    let s = load(&bytes(json!({
        "thicknessFactor": 1.0, "attenuationDistance": 1.0, "attenuationColor": [0.0, 1.5, -0.5],
    })))
    .unwrap();
    assert_eq!(
        s.material_ext(0).absorption,
        Vec3::new(MAX_ABSORPTION, 0.0, MAX_ABSORPTION)
    );
    assert!(
        s.warnings.iter().any(|w| w
            .starts_with("material 'amber': KHR_materials_volume attenuationColor")
            && w.contains("clamped")),
        "{:?}",
        s.warnings
    );
    // A thickness map that names no texture (validated by the gltf crate, with its path).
    let e = err(&bytes(
        json!({ "thicknessFactor": 1.0, "thicknessTexture": { "index": 5 } }),
    ));
    assert!(
        e.starts_with("test.gltf: invalid glTF: materials[0]")
            && e.ends_with("thicknessTexture.index: Index out of bounds"),
        "{e}"
    );
    for (volume, problem) in [
        (
            json!({ "thicknessFactor": 1.0, "attenuationDistance": 0.0 }),
            "attenuationDistance 0 is not a number > 0",
        ),
        (
            json!({ "thicknessFactor": 1.0, "attenuationDistance": -2.0 }),
            "attenuationDistance -2 is not a number > 0",
        ),
        (
            json!({ "thicknessFactor": -1.0 }),
            "thicknessFactor -1 is not a finite number ≥ 0",
        ),
    ] {
        assert_eq!(
            err(&bytes(volume)),
            format!("test.gltf: material 'amber': KHR_materials_volume: {problem}")
        );
    }
}

/// KHR_materials_sheen: colour and roughness factors, the colour texture in sRGB and the
/// roughness texture linear (one image may serve both); out-of-range factors clamped and said;
/// malformed ones refused naming the material.
#[test]
fn a_sheen_loads_as_the_file_says_and_bad_ones_are_named() {
    let bytes = |sheen: Value| {
        material_with(json!({ "name": "velvet", "extensions": { "KHR_materials_sheen": sheen } }))
    };
    let s = load(&bytes(json!({
        "sheenColorFactor": [0.9, 0.5, 0.25], "sheenRoughnessFactor": 0.75,
        "sheenColorTexture": { "index": 0 },
        "sheenRoughnessTexture": { "index": 0, "texCoord": 1 },
    })))
    .unwrap();
    let e = s.material_ext(0);
    assert_eq!(
        (e.sheen_color, e.sheen_roughness),
        (Vec3::new(0.9, 0.5, 0.25), 0.75)
    );
    let (colour, rough) = (
        e.sheen_color_texture.unwrap(),
        e.sheen_roughness_texture.unwrap(),
    );
    assert_eq!((colour.uv.tex_coord, rough.uv.tex_coord), (0, 1));
    assert!(
        s.textures[colour.texture as usize].srgb,
        "sheen colour is sRGB"
    );
    assert!(
        !s.textures[rough.texture as usize].srgb,
        "sheen roughness is linear data"
    );
    assert!(s.unsupported.is_empty(), "{:?}", s.unsupported);
    // Defaults: no sheen.
    let e = load(&bytes(json!({}))).unwrap().material_ext(0);
    assert_eq!((e.sheen_color, e.sheen_roughness), (Vec3::ZERO, 0.0));
    // Out of range: clamped and said.
    let s = load(&bytes(
        json!({ "sheenColorFactor": [2.0, 0.5, 0.5], "sheenRoughnessFactor": -1.0 }),
    ))
    .unwrap();
    let e = s.material_ext(0);
    assert_eq!(
        (e.sheen_color, e.sheen_roughness),
        (Vec3::new(1.0, 0.5, 0.5), 0.0)
    );
    for what in [
        "sheenColorFactor 2 clamped",
        "sheenRoughnessFactor -1 clamped",
    ] {
        assert!(
            s.warnings
                .iter()
                .any(|w| w == &format!("material 'velvet': {what} to [0, 1]")),
            "{what}: {:?}",
            s.warnings
        );
    }
    for (sheen, problem) in [
        (
            json!({ "sheenColorFactor": [1.0, 1.0] }),
            "sheenColorFactor [1.0,1.0] is not three numbers",
        ),
        (
            json!({ "sheenColorFactor": "red" }),
            "sheenColorFactor \"red\" is not three numbers",
        ),
        (
            json!({ "sheenRoughnessFactor": [0.5] }),
            "sheenRoughnessFactor [0.5] is not a number",
        ),
        (
            json!({ "sheenColorTexture": { "index": 3 } }),
            "sheenColorTexture: index 3 names no texture (the file has 1)",
        ),
    ] {
        assert_eq!(
            err(&bytes(sheen)),
            format!("test.gltf: material 'velvet': {problem}")
        );
    }
}

/// KHR_materials_anisotropy: strength (clamped to [0, 1] and said), rotation, the texture
/// (linear); the material's primitives get tangents (from TEXCOORD_0 where the file has none);
/// malformed values refused naming the material.
#[test]
fn an_anisotropy_loads_as_the_file_says_with_tangents() {
    let bytes = |anisotropy: Value| {
        material_with(json!({ "name": "brushed", "extensions": {
            "KHR_materials_anisotropy": anisotropy } }))
    };
    let s = load(&bytes(json!({
        "anisotropyStrength": 0.6, "anisotropyRotation": 1.25,
        "anisotropyTexture": { "index": 0, "texCoord": 1 },
    })))
    .unwrap();
    let e = s.material_ext(0);
    assert_eq!((e.anisotropy_strength, e.anisotropy_rotation), (0.6, 1.25));
    let t = e.anisotropy_texture.unwrap();
    assert_eq!(t.uv.tex_coord, 1);
    assert!(
        !s.textures[t.texture as usize].srgb,
        "a direction is linear data"
    );
    assert!(s.unsupported.is_empty(), "{:?}", s.unsupported);
    let s = load(&bytes(json!({ "anisotropyStrength": 2.0 }))).unwrap();
    assert_eq!(s.material_ext(0).anisotropy_strength, 1.0);
    assert!(
        s.warnings
            .iter()
            .any(|w| w == "material 'brushed': anisotropyStrength 2 clamped to [0, 1]"),
        "{:?}",
        s.warnings
    );
    assert_eq!(s.vertex_extras.len(), 1, "the triangle has extras");
    // Without a texture or TANGENT: tangents from TEXCOORD_0 (u along +x here).
    let mut d = Doc::default();
    let p = d.floats(&TRI, "VEC3");
    let uv = d.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC2");
    let s = load(&d.finish(json!({
        "extensionsUsed": ["KHR_materials_anisotropy"],
        "materials": [{ "extensions": { "KHR_materials_anisotropy": { "anisotropyStrength": 1.0 } } }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": p, "TEXCOORD_0": uv }, "material": 0 }] }],
        "nodes": [{ "mesh": 0 }],
        "scenes": [{ "nodes": [0] }],
    })))
    .unwrap();
    for t in s.vertex_extras[0].tangent {
        assert!((t.truncate() - Vec3::X).length() < 1e-6, "{t}");
    }
    // No anisotropy: no tangents.
    assert!(load(&bytes(json!({}))).unwrap().vertex_extras.is_empty());
    for (anisotropy, problem) in [
        (
            json!({ "anisotropyStrength": "strong" }),
            "anisotropyStrength \"strong\" is not a number",
        ),
        (
            json!({ "anisotropyRotation": [1.0] }),
            "anisotropyRotation [1.0] is not a number",
        ),
        (
            json!({ "anisotropyTexture": { "index": 2 } }),
            "anisotropyTexture: index 2 names no texture (the file has 1)",
        ),
    ] {
        assert_eq!(
            err(&bytes(anisotropy)),
            format!("test.gltf: material 'brushed': {problem}")
        );
    }
}

/// KHR_materials_dispersion: the value (20 / Abbe number) on a transmitting material; on one
/// that transmits nothing it changes nothing and is said; malformed values are refused naming
/// the material.
#[test]
fn a_dispersion_loads_on_glass_and_is_said_to_do_nothing_elsewhere() {
    let bytes = |transmission: f64, dispersion: Value| {
        material_with(json!({ "name": "diamond", "extensions": {
            "KHR_materials_transmission": { "transmissionFactor": transmission },
            "KHR_materials_ior": { "ior": 2.42 },
            "KHR_materials_volume": { "thicknessFactor": 1.0 },
            "KHR_materials_dispersion": dispersion } }))
    };
    let s = load(&bytes(1.0, json!({ "dispersion": 0.36 }))).unwrap();
    let e = s.material_ext(0);
    assert_eq!((e.dispersion, e.ior, e.transmission), (0.36, 2.42, 1.0));
    assert!(s.unsupported.is_empty(), "{:?}", s.unsupported);
    assert!(
        s.notes.iter().all(|n| !n.contains("dispersion")),
        "{:?}",
        s.notes
    );
    // Packed with its flag where it transmits; the default is none.
    let packed = raygun::trace::pack::PackedScene::new(&s);
    let flags = packed.materials[1][3] as u32;
    assert_ne!(flags & raygun::trace::pack::MAT_DISPERSION, 0);
    assert_eq!(
        packed.materials[raygun::trace::pack::MATERIAL_ANISO_ROW][3],
        0.36
    );
    assert_eq!(
        load(&bytes(1.0, json!({})))
            .unwrap()
            .material_ext(0)
            .dispersion,
        0.0
    );
    // Opaque: nothing refracts, so nothing disperses (no noise for nothing), and it is said.
    let s = load(&bytes(0.0, json!({ "dispersion": 0.5 }))).unwrap();
    assert_eq!(s.material_ext(0).dispersion, 0.0);
    assert!(
        s.notes.iter().any(|n| n
            == "material 'diamond': KHR_materials_dispersion without transmission changes \
                nothing (only refracted light is dispersed)"),
        "{:?}",
        s.notes
    );
    for (dispersion, problem) in [
        (
            json!({ "dispersion": -0.1 }),
            "KHR_materials_dispersion: dispersion -0.1 is not a finite number ≥ 0",
        ),
        (
            json!({ "dispersion": 1e300 }),
            "KHR_materials_dispersion: dispersion 1e+300 is not a finite number ≥ 0",
        ),
        (
            json!({ "dispersion": "strong" }),
            "dispersion \"strong\" is not a number",
        ),
    ] {
        assert_eq!(
            err(&bytes(1.0, dispersion)),
            format!("test.gltf: material 'diamond': {problem}")
        );
    }
}

/// KHR_materials_diffuse_transmission: the factor and colour (clamped to [0, 1] and said), the
/// strength texture linear and the colour texture sRGB; malformed values refused naming the
/// material.
#[test]
fn a_diffuse_transmission_loads_as_the_file_says_and_bad_ones_are_named() {
    let bytes = |dt: Value| {
        material_with(json!({ "name": "leaf", "extensions": {
            "KHR_materials_diffuse_transmission": dt } }))
    };
    let s = load(&bytes(json!({
        "diffuseTransmissionFactor": 0.7, "diffuseTransmissionColorFactor": [0.9, 0.6, 0.1],
        "diffuseTransmissionTexture": { "index": 0, "texCoord": 1 },
        "diffuseTransmissionColorTexture": { "index": 0 },
    })))
    .unwrap();
    let e = s.material_ext(0);
    assert_eq!(
        (e.diffuse_transmission, e.diffuse_transmission_color),
        (0.7, Vec3::new(0.9, 0.6, 0.1))
    );
    let (strength, colour) = (
        e.diffuse_transmission_texture.unwrap(),
        e.diffuse_transmission_color_texture.unwrap(),
    );
    assert_eq!((strength.uv.tex_coord, colour.uv.tex_coord), (1, 0));
    assert!(
        !s.textures[strength.texture as usize].srgb,
        "a strength is linear data"
    );
    assert!(s.textures[colour.texture as usize].srgb, "a colour is sRGB");
    assert!(s.unsupported.is_empty(), "{:?}", s.unsupported);
    let packed = raygun::trace::pack::PackedScene::new(&s);
    assert_eq!(
        packed.materials[raygun::trace::pack::MATERIAL_DIFFUSE_ROW],
        [0.9, 0.6, 0.1, 0.7]
    );
    // Defaults: none, white.
    let e = load(&bytes(json!({}))).unwrap().material_ext(0);
    assert_eq!(
        (e.diffuse_transmission, e.diffuse_transmission_color),
        (0.0, Vec3::ONE)
    );
    let s = load(&bytes(json!({ "diffuseTransmissionFactor": 1.5,
        "diffuseTransmissionColorFactor": [1.0, -0.5, 0.5] })))
    .unwrap();
    let e = s.material_ext(0);
    assert_eq!(
        (e.diffuse_transmission, e.diffuse_transmission_color),
        (1.0, Vec3::new(1.0, 0.0, 0.5))
    );
    for what in [
        "diffuseTransmissionFactor 1.5 clamped",
        "diffuseTransmissionColorFactor -0.5 clamped",
    ] {
        assert!(
            s.warnings
                .iter()
                .any(|w| w == &format!("material 'leaf': {what} to [0, 1]")),
            "{what}: {:?}",
            s.warnings
        );
    }
    for (dt, problem) in [
        (
            json!({ "diffuseTransmissionFactor": "half" }),
            "diffuseTransmissionFactor \"half\" is not a number",
        ),
        (
            json!({ "diffuseTransmissionColorFactor": [1.0, 1.0] }),
            "diffuseTransmissionColorFactor [1.0,1.0] is not three numbers",
        ),
        (
            json!({ "diffuseTransmissionColorTexture": { "index": 4 } }),
            "diffuseTransmissionColorTexture: index 4 names no texture (the file has 1)",
        ),
    ] {
        assert_eq!(
            err(&bytes(dt)),
            format!("test.gltf: material 'leaf': {problem}")
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Unsupported features

#[test]
fn every_unsupported_feature_is_named_once() {
    let mut d = Doc::default();
    let pos = d.floats(&TRI, "VEC3");
    let times = d.floats(&[0.0, 1.0], "SCALAR");
    let moves = d.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0], "VEC3");
    let png = format!(
        "data:image/png;base64,{}",
        base64::encode(png_bytes(&image::DynamicImage::new_rgba8(1, 1)))
    );
    let tri = |material: usize| json!({ "attributes": { "POSITION": pos }, "material": material });
    let bytes = d.finish(json!({
        "extensionsUsed": ["KHR_lights_punctual", "KHR_texture_transform", "KHR_materials_iridescence", "KHR_materials_variants"],
        "images": [{ "uri": png }],
        "textures": [{ "name": "t", "source": 0 }],
        "materials": [
            { "name": "full",
              "occlusionTexture": { "index": 0 },
              "pbrMetallicRoughness": {
                  "baseColorTexture": { "index": 0, "texCoord": 2 } } },
        ],
        "meshes": [
            { "name": "wire", "primitives": [{ "attributes": { "POSITION": pos }, "mode": 1 }] },
            { "name": "morph", "primitives": [{ "attributes": { "POSITION": pos }, "targets": [{ "POSITION": pos }] }] },
            { "name": "painted", "primitives": [tri(0)] },
        ],
        "skins": [{ "name": "arm", "joints": [3] }],
        "animations": [{ "name": "wave",
            "samplers": [{ "input": times, "output": moves }],
            "channels": [{ "sampler": 0, "target": { "node": 3, "path": "translation" } }] }],
        "nodes": [
            { "mesh": 0 }, { "mesh": 1 }, { "mesh": 2, "skin": 0 }, { "name": "joint" },
        ],
        "scenes": [{ "nodes": [0, 1, 2, 3] }],
    }));
    let scene = load(&bytes).unwrap();
    let expected = [
        "KHR_materials_iridescence",
        "KHR_materials_variants",
        "animation 'wave'",
        "primitive mode LINES (mesh 'wire')",
        "morph targets (mesh 'morph')",
        "skin 'arm'",
        "texCoord 2 (material 'full' baseColorTexture",
    ];
    for e in expected {
        let hits = scene
            .unsupported
            .iter()
            .filter(|u| u.starts_with(e) && (e.len() > 20 || u.len() == e.len()))
            .count();
        assert_eq!(hits, 1, "'{e}' in {:#?}", scene.unsupported);
    }
    assert_eq!(
        scene.unsupported.len(),
        expected.len(),
        "{:#?}",
        scene.unsupported
    );
    // Occlusion maps are not unsupported: a path tracer computes occlusion, and says so.
    assert_eq!(scene.notes.len(), 1, "{:?}", scene.notes);
    assert!(scene.notes[0].contains("occlusionTexture (material 'full') not used"));
    // Reported, not dropped: the triangles are drawn with what is modelled.
    assert_eq!(scene.triangles.len(), 1 + 1);
}

/// What the loader reads beyond the core material, read as the file says: vertex colours (VEC3 float and
/// VEC4 normalized u8), TEXCOORD_1, texture transforms with their texCoord override, samplers,
/// alpha modes, the texture maps, glass, clear coat, specular colour, punctual lights,
/// orthographic and unnamed cameras.
#[test]
fn material_textures_vertex_colours_lights_and_cameras_load_as_the_file_says() {
    let mut d = Doc::default();
    let pos = d.floats(&TRI, "VEC3");
    let nor = d.floats(&TRI_NORMALS, "VEC3");
    let uv0 = d.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC2");
    let uv1 = d.floats(&[0.5, 0.5, 1.0, 0.5, 0.5, 1.0], "VEC2");
    let rgb = d.floats(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], "VEC3");
    let rgba8 = d.view(&[255, 0, 0, 255, 0, 255, 0, 128, 0, 0, 255, 0]);
    d.accessors.push(json!({ "bufferView": rgba8, "componentType": 5121, "normalized": true, "count": 3, "type": "VEC4" }));
    let rgba = d.accessors.len() - 1;
    let png = format!(
        "data:image/png;base64,{}",
        base64::encode(png_bytes(&image::DynamicImage::new_rgba8(2, 2)))
    );
    let bytes = d.finish(json!({
        "extensionsUsed": ["KHR_lights_punctual", "KHR_texture_transform", "KHR_materials_transmission",
                           "KHR_materials_ior", "KHR_materials_clearcoat", "KHR_materials_specular"],
        "extensions": { "KHR_lights_punctual": { "lights": [
            { "type": "point", "color": [1.0, 0.5, 0.25], "intensity": 4.0 },
            { "name": "cone", "type": "spot", "intensity": 2.0, "spot": { "innerConeAngle": 0.1, "outerConeAngle": 0.5 } },
            { "name": "sun", "type": "directional", "intensity": 3.0 },
        ] } },
        "images": [{ "uri": png }],
        "samplers": [{ "wrapS": 33071, "wrapT": 33648, "magFilter": 9728 }],
        "textures": [{ "name": "t", "source": 0, "sampler": 0 }],
        "materials": [
            { "name": "maps",
              "alphaMode": "MASK", "alphaCutoff": 0.25,
              "normalTexture": { "index": 0, "scale": 0.5, "texCoord": 1 },
              "emissiveTexture": { "index": 0 },
              "emissiveFactor": [1.0, 1.0, 1.0],
              "pbrMetallicRoughness": {
                  "metallicRoughnessTexture": { "index": 0 },
                  "baseColorTexture": { "index": 0, "extensions": { "KHR_texture_transform": {
                      "offset": [0.5, 0.25], "rotation": 0.5, "scale": [2.0, 3.0], "texCoord": 1 } } } } },
            { "name": "glass", "alphaMode": "BLEND",
              "extensions": {
                  "KHR_materials_transmission": { "transmissionFactor": 0.9, "transmissionTexture": { "index": 0 } },
                  "KHR_materials_ior": { "ior": 1.7 },
                  "KHR_materials_clearcoat": { "clearcoatFactor": 0.6, "clearcoatRoughnessFactor": 0.2,
                      "clearcoatTexture": { "index": 0, "texCoord": 1 },
                      "clearcoatRoughnessTexture": { "index": 0, "extensions": { "KHR_texture_transform": {
                          "offset": [0.25, 0.0], "texCoord": 1 } } },
                      "clearcoatNormalTexture": { "index": 0, "scale": 0.75 } },
                  "KHR_materials_specular": { "specularColorFactor": [1.0, 0.5, 0.25],
                      "specularTexture": { "index": 0 }, "specularColorTexture": { "index": 0 } } } },
        ],
        "meshes": [{ "primitives": [
            { "attributes": { "POSITION": pos, "NORMAL": nor, "TEXCOORD_0": uv0, "TEXCOORD_1": uv1, "COLOR_0": rgb }, "material": 0 },
            { "attributes": { "POSITION": pos, "COLOR_0": rgba }, "material": 1 },
        ] }],
        "cameras": [
            { "type": "perspective", "perspective": { "yfov": 0.5, "znear": 0.1 } },
            { "type": "orthographic", "orthographic": { "xmag": 2.0, "ymag": 1.5, "znear": 0.1, "zfar": 10.0 } },
        ],
        "nodes": [
            { "mesh": 0 },
            { "camera": 0, "translation": [0.0, 0.0, 5.0] },
            { "camera": 1, "translation": [0.0, 0.0, 6.0] },
            { "extensions": { "KHR_lights_punctual": { "light": 0 } }, "translation": [1.0, 2.0, 3.0] },
            { "extensions": { "KHR_lights_punctual": { "light": 1 } },
              "rotation": [-std::f32::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f32::consts::FRAC_1_SQRT_2] },
            { "extensions": { "KHR_lights_punctual": { "light": 2 } } },
        ],
        "scenes": [{ "nodes": [0, 1, 2, 3, 4, 5] }],
    }));
    let scene = load(&bytes).unwrap();
    assert!(scene.unsupported.is_empty(), "{:?}", scene.unsupported);
    // Unnamed cameras are named by their index in the file's cameras (what --camera takes).
    assert_eq!(scene.cameras[0].name, "camera 0");
    let ortho = scene.orthographic_camera("camera 1").unwrap();
    assert_eq!((ortho.ymag, ortho.position.z), (1.5, 6.0));
    // Lights: colour × intensity, the node's position and −Z.
    assert_eq!(scene.lights.len(), 3);
    assert_eq!(scene.lights[0].intensity, Vec3::new(4.0, 2.0, 1.0));
    assert_eq!(scene.lights[0].position, Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(scene.lights[1].name, "cone");
    assert!((scene.lights[1].direction - Vec3::NEG_Y).length() < POS_TOL);
    assert_eq!(
        scene.lights[1].kind,
        raygun::scene::LightKind::Spot {
            inner: 0.1,
            outer: 0.5
        }
    );
    assert_eq!(scene.lights[2].kind, raygun::scene::LightKind::Directional);
    // Vertex colours and TEXCOORD_1.
    let e = scene.vertex_extras(0);
    assert_eq!(e.color[0], glam::Vec4::new(1.0, 0.0, 0.0, 1.0));
    assert_eq!(e.uv1[1], Vec2::new(1.0, 0.5));
    assert!(
        (e.tangent[0].truncate() - Vec3::X).length() < POS_TOL,
        "{}",
        e.tangent[0]
    );
    let e = scene.vertex_extras(1);
    assert!((e.color[1].w - 128.0 / 255.0).abs() < 1e-6);
    assert_eq!(e.color[2], glam::Vec4::new(0.0, 0.0, 1.0, 0.0));
    // Textures: one colour (sRGB) and one data copy of the same glTF texture, its sampler.
    let maps = scene.material_ext(0);
    assert_eq!(maps.alpha, raygun::scene::AlphaMode::Mask(0.25));
    assert_eq!(maps.base_color_uv.tex_coord, 1);
    assert_eq!(maps.base_color_uv.transform.offset, Vec2::new(0.5, 0.25));
    assert_eq!(maps.base_color_uv.transform.scale, Vec2::new(2.0, 3.0));
    assert_eq!(maps.normal_texture.unwrap().uv.tex_coord, 1);
    assert_eq!(maps.normal_scale, 0.5);
    let colour = &scene.textures[scene.materials[0].base_color_texture.unwrap() as usize];
    let data = &scene.textures[maps.normal_texture.unwrap().texture as usize];
    assert!(colour.srgb && !data.srgb);
    assert_eq!(
        maps.metallic_roughness_texture.unwrap().texture,
        maps.normal_texture.unwrap().texture
    );
    assert_eq!(scene.textures.len(), 2);
    assert_eq!(
        colour.sampler,
        raygun::scene::Sampler {
            wrap_s: raygun::scene::Wrap::ClampToEdge,
            wrap_t: raygun::scene::Wrap::MirroredRepeat,
            nearest: true
        }
    );
    // The emissive texture is black: factor 1 beside it makes no lamp.
    assert!(maps.emissive_texture.is_some());
    assert_eq!(scene.emissive_triangle_count(), 0);
    let glass = scene.material_ext(1);
    assert_eq!(glass.alpha, raygun::scene::AlphaMode::Blend);
    assert_eq!((glass.transmission, glass.ior), (0.9, 1.7));
    assert_eq!((glass.clearcoat, glass.clearcoat_roughness), (0.6, 0.2));
    assert_eq!(glass.specular_color, Vec3::new(1.0, 0.5, 0.25));
    // The extensions' textures: data copies, but the specular colour (sRGB), with their UVs.
    let data_index = maps.normal_texture.unwrap().texture;
    let colour_index = scene.materials[0].base_color_texture.unwrap();
    for (t, want) in [
        (glass.transmission_texture, data_index),
        (glass.specular_texture, data_index),
        (glass.specular_color_texture, colour_index),
        (glass.clearcoat_texture, data_index),
        (glass.clearcoat_roughness_texture, data_index),
        (glass.clearcoat_normal_texture, data_index),
    ] {
        assert_eq!(t.unwrap().texture, want);
    }
    assert_eq!(glass.clearcoat_texture.unwrap().uv.tex_coord, 1);
    let rough = glass.clearcoat_roughness_texture.unwrap().uv;
    assert_eq!(rough.tex_coord, 1);
    assert_eq!(rough.transform.offset, Vec2::new(0.25, 0.0));
    assert_eq!(glass.clearcoat_normal_scale, 0.75);
}

/// Quantized geometry (KHR_mesh_quantization: normalized i16 positions under a node scale)
/// loads; Draco and WebP are clean errors naming the extension.
#[test]
fn quantized_meshes_load_and_compressed_ones_are_named() {
    let mut d = Doc::default();
    let q: [i16; 9] = [0, 0, 0, 32767, 0, 0, 0, 32767, 0];
    let view = d.view(bytemuck::cast_slice(&q));
    d.accessors.push(
        json!({ "bufferView": view, "componentType": 5122, "normalized": true,
        "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0] }),
    );
    let bytes = d.finish(json!({
        "extensionsUsed": ["KHR_mesh_quantization"], "extensionsRequired": ["KHR_mesh_quantization"],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 } }] }],
        "nodes": [{ "mesh": 0, "scale": [2.0, 2.0, 2.0] }],
        "scenes": [{ "nodes": [0] }],
    }));
    let scene = load(&bytes).unwrap();
    assert_eq!(scene.triangles[0].p[1], Vec3::new(2.0, 0.0, 0.0));
    for ext in ["KHR_draco_mesh_compression", "EXT_texture_webp"] {
        let doc = format!(
            r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["{ext}"],"extensionsRequired":["{ext}"]}}"#
        );
        assert_eq!(
            err(doc.as_bytes()),
            format!("test.gltf: requires extension {ext}, which raygun does not implement")
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Errors name the file and the element

#[test]
fn errors_name_the_file_and_the_element() {
    let e = Scene::load("no/such/city.glb").unwrap_err();
    assert!(
        e.to_string().starts_with("no/such/city.glb: cannot read"),
        "{e}"
    );

    let mut d = Doc::default();
    let nor = d.floats(&TRI_NORMALS, "VEC3");
    let bytes = d.finish(json!({
        "meshes": [{ "name": "Tower", "primitives": [
            { "attributes": { "NORMAL": nor } }, { "attributes": { "NORMAL": nor } }, { "attributes": { "NORMAL": nor } }] }],
    }));
    assert_eq!(
        err(&bytes),
        "test.gltf: mesh 'Tower' primitive 0: POSITION accessor is missing"
    );

    let e = err(
        br#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":9}}]}]}"#,
    );
    assert_eq!(
        e,
        "test.gltf: mesh 0 primitive 0: POSITION accessor 9 does not exist"
    );

    // An extension's texture reference (JSON to the gltf crate, so not validated by it) that
    // names no texture, a texCoord that is no set, a normal map's scale that is no number; in
    // a file with one texture or none.
    let cases = [
        (
            1,
            "clearcoatTexture",
            json!({ "index": 0, "texCoord": "one" }),
            "clearcoatTexture: texCoord \"one\" is not a number ≥ 0",
        ),
        (
            1,
            "clearcoatNormalTexture",
            json!({ "index": 0, "scale": [1.0] }),
            "clearcoatNormalTexture: scale [1.0] is not a finite number",
        ),
        (
            0,
            "clearcoatTexture",
            json!({ "index": 3 }),
            "clearcoatTexture: index 3 names no texture (the file has 0)",
        ),
        (
            0,
            "clearcoatTexture",
            json!({ "texCoord": 0 }),
            "clearcoatTexture: index missing names no texture (the file has 0)",
        ),
        (
            0,
            "clearcoatTexture",
            json!({ "index": -1 }),
            "clearcoatTexture: index -1 names no texture (the file has 0)",
        ),
    ];
    for (textures, key, info, problem) in cases {
        let mut d = Doc::default();
        let pos = d.floats(&TRI, "VEC3");
        let png = format!(
            "data:image/png;base64,{}",
            base64::encode(png_bytes(&image::DynamicImage::new_rgba8(1, 1)))
        );
        let (images, texture_list) = if textures == 1 {
            (json!([{ "uri": png }]), json!([{ "source": 0 }]))
        } else {
            (json!([]), json!([]))
        };
        let bytes = d.finish(json!({
            "extensionsUsed": ["KHR_materials_clearcoat"],
            "images": images,
            "textures": texture_list,
            "materials": [{ "name": "Paint", "extensions": { "KHR_materials_clearcoat": {
                "clearcoatFactor": 1.0, key: info } } }],
            "meshes": [{ "primitives": [{ "attributes": { "POSITION": pos }, "material": 0 }] }],
            "nodes": [{ "mesh": 0 }],
            "scenes": [{ "nodes": [0] }],
        }));
        assert_eq!(
            err(&bytes),
            format!("test.gltf: material 'Paint': {problem}")
        );
    }

    // glTF 2.0 §5.18: an image is a uri or a bufferView with a mimeType.
    let e = err(br#"{"asset":{"version":"2.0"},"images":[{"name":"Label"}]}"#);
    assert_eq!(
        e,
        "test.gltf: image 'Label': has neither a uri nor a bufferView"
    );
    let e = err(
        br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"data:application/octet-stream;base64,AAAAAA=="}],"bufferViews":[{"buffer":0,"byteLength":4}],"images":[{"bufferView":0}]}"#,
    );
    assert_eq!(e, "test.gltf: image 0: has a bufferView but no mimeType");

    let e = err(b"{\"asset\": {\"version\": \"2.0\"}, ");
    assert!(
        e.starts_with("test.gltf: not a glTF 2.0 file:") && e.contains("line 1"),
        "{e}"
    );

    let e = err(br#"{"asset":{"version":"2.0"},"extensionsRequired":["KHR_draco_mesh_compression"],"extensionsUsed":["KHR_draco_mesh_compression"]}"#);
    assert_eq!(
        e,
        "test.gltf: requires extension KHR_draco_mesh_compression, which raygun does not implement"
    );

    let e = err(br#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[4]}]}"#);
    assert!(
        e.starts_with("test.gltf: invalid glTF:") && e.contains("scenes[0].nodes[0]"),
        "{e}"
    );

    // An index past the vertices.
    let mut d = Doc::default();
    let pos = d.floats(&TRI, "VEC3");
    let idx = d.indices(&[0, 1, 7]);
    let bytes = d.finish(json!({
        "meshes": [{ "name": "Tower", "primitives": [{ "attributes": { "POSITION": pos }, "indices": idx }] }],
        "nodes": [{ "mesh": 0 }], "scenes": [{ "nodes": [0] }],
    }));
    assert_eq!(
        err(&bytes),
        "test.gltf: mesh 'Tower' primitive 0: index 7 at position 2 is past the 3 vertices"
    );

    // An accessor reaching past its buffer view.
    let mut d = Doc::default();
    let pos = d.floats(&TRI, "VEC3");
    d.accessors[pos]["count"] = json!(4);
    let bytes = d.finish(json!({
        "meshes": [{ "name": "Tower", "primitives": [{ "attributes": { "POSITION": pos } }] }],
        "nodes": [{ "mesh": 0 }], "scenes": [{ "nodes": [0] }],
    }));
    let e = err(&bytes);
    assert!(e.starts_with("test.gltf: mesh 'Tower' primitive 0: POSITION: accessor 0: bytes 0..48 run past the end of buffer view 0 (36)"), "{e}");

    // A node reached twice (a cycle).
    let e = err(br#"{"asset":{"version":"2.0"},"nodes":[{"name":"loop","children":[0]}],"scenes":[{"nodes":[0]}]}"#);
    assert_eq!(
        e,
        "test.gltf: node 'loop': is reached twice: the node hierarchy must be a tree"
    );
}

/// EXT_meshopt_compression (gltfpack's output): positions and octahedral-filtered normals
/// encoded by meshoptimizer, indices by its triangle codec, decoded into the fallback buffer:
/// the same triangles as the uncompressed file; broken streams are errors naming the view.
#[test]
fn meshopt_compressed_meshes_load_as_their_uncompressed_originals() {
    // A 2 × 2 grid of quads (9 vertices, 8 triangles) in z = 0.
    let positions: Vec<[f32; 3]> = (0..9)
        .map(|i| [(i % 3) as f32, (i / 3) as f32, 0.0])
        .collect();
    let indices: Vec<u32> = (0..4)
        .flat_map(|q| {
            let (x, y) = (q % 2, q / 2);
            let a = y * 3 + x;
            [a, a + 1, a + 4, a, a + 4, a + 3]
        })
        .collect();
    let normals = meshopt::encode_filter_oct::<i8>(&[[0.0, 0.0, 1.0, 0.0]; 9], 8);
    let vb = meshopt::encode_vertex_buffer(&positions).unwrap();
    let nb = meshopt::encode_vertex_buffer(&normals).unwrap();
    let ib = meshopt::encode_index_buffer(&indices, 9).unwrap();
    let mut compressed = Vec::new();
    let mut place = |bytes: &[u8]| {
        while compressed.len() % 4 != 0 {
            compressed.push(0);
        }
        let at = compressed.len();
        compressed.extend_from_slice(bytes);
        (at, bytes.len())
    };
    let (vo, vl) = place(&vb);
    let (no, nl) = place(&nb);
    let (io, il) = place(&ib);
    let ext = |offset: usize,
               length: usize,
               stride: usize,
               count: usize,
               mode: &str,
               filter: &str| {
        json!({ "EXT_meshopt_compression": { "buffer": 0, "byteOffset": offset, "byteLength": length,
            "byteStride": stride, "count": count, "mode": mode, "filter": filter } })
    };
    let doc = |index_stream: &[u8]| {
        let mut c = compressed.clone();
        c[io..io + il].copy_from_slice(&index_stream[..il]);
        let root = json!({
            "asset": { "version": "2.0" },
            "extensionsUsed": ["EXT_meshopt_compression"],
            "extensionsRequired": ["EXT_meshopt_compression"],
            "buffers": [
                { "byteLength": c.len(), "uri": format!("data:application/octet-stream;base64,{}", base64::encode(&c)) },
                { "byteLength": 108 + 36 + 96, "extensions": { "EXT_meshopt_compression": { "fallback": true } } },
            ],
            "bufferViews": [
                { "buffer": 1, "byteOffset": 0, "byteLength": 108, "byteStride": 12, "extensions": ext(vo, vl, 12, 9, "ATTRIBUTES", "NONE") },
                { "buffer": 1, "byteOffset": 108, "byteLength": 36, "byteStride": 4, "extensions": ext(no, nl, 4, 9, "ATTRIBUTES", "OCTAHEDRAL") },
                { "buffer": 1, "byteOffset": 144, "byteLength": 96, "extensions": ext(io, il, 4, 24, "TRIANGLES", "NONE") },
            ],
            "accessors": [
                { "bufferView": 0, "componentType": 5126, "count": 9, "type": "VEC3", "min": [0, 0, 0], "max": [2, 2, 0] },
                { "bufferView": 1, "componentType": 5120, "normalized": true, "count": 9, "type": "VEC3" },
                { "bufferView": 2, "componentType": 5125, "count": 24, "type": "SCALAR" },
            ],
            "meshes": [{ "name": "packed", "primitives": [{ "attributes": { "POSITION": 0, "NORMAL": 1 }, "indices": 2 }] }],
            "nodes": [{ "mesh": 0 }],
            "scenes": [{ "nodes": [0] }],
        });
        serde_json::to_vec(&root).unwrap()
    };
    let scene = load(&doc(&ib)).unwrap();
    assert!(scene.unsupported.is_empty(), "{:?}", scene.unsupported);
    assert_eq!(scene.triangles.len(), 8);
    // The index codec may rotate a triangle's vertices (keeping its winding).
    for (t, tri) in scene.triangles.iter().zip(indices.chunks(3)) {
        let want: Vec<[f32; 3]> = tri.iter().map(|&i| positions[i as usize]).collect();
        let got: Vec<[f32; 3]> = t.p.iter().map(|p| p.to_array()).collect();
        assert!(
            (0..3).any(|r| (0..3).all(|k| got[k] == want[(k + r) % 3])),
            "{got:?} is no rotation of {want:?}"
        );
        for n in t.n {
            assert!((n - Vec3::Z).length() < 1e-2, "{n}");
        }
    }
    // A corrupted index stream is an error naming the view, not garbage triangles.
    let e = err(&doc(&vec![0xff; il]));
    assert!(
        e.starts_with("test.gltf: buffer view 2: EXT_meshopt_compression:"),
        "{e}"
    );
}
