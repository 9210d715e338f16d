//! `raygun scene …` end to end: the generators write what the library generates, and `info`
//! summarises files and built-ins.

use crate::support;
use support::{raygun, tmp_file};

#[test]
fn scene_generators_write_the_shipped_files_and_print_triangle_counts() {
    for (cmd, golden, triangles) in [
        (vec!["scene", "cornell"], "cornell.glb", 30),
        (vec!["scene", "cornell-light"], "cornell-light.glb", 32),
        (
            vec!["scene", "city", "--blocks", "4"],
            "city-small.glb",
            3862,
        ),
    ] {
        let out = tmp_file(golden);
        let mut args = cmd.clone();
        args.extend(["--out", out.to_str().unwrap()]);
        let o = raygun(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stdout = String::from_utf8(o.stdout).unwrap();
        assert!(
            stdout.contains(&format!(": {triangles} triangles")),
            "{stdout}"
        );
        let shipped = std::fs::read(format!("tests/data/scenes/{golden}")).unwrap();
        assert!(std::fs::read(&out).unwrap() == shipped, "{golden}");
    }
    let o = raygun(&["scene", "city", "--blocks", "0", "--out", "x.glb"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--blocks must be in 1..="));
}

#[test]
fn scene_info_prints_counts_bounds_cameras_and_problems() {
    let o = raygun(&[
        "scene",
        "info",
        "tests/data/scenes/cornell-light.glb",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["triangles"], 32);
    assert_eq!(v["emissive_triangles"], 2);
    assert_eq!(v["materials"], 4);
    assert_eq!(v["textures"], 0);
    assert_eq!(v["cameras"][0]["name"], "front");
    assert_eq!(v["bounds"]["max"][1].as_f64().unwrap() as f32, 0.5488);
    assert_eq!(v["unsupported"], serde_json::json!([]));

    let o = raygun(&["scene", "info", "builtin:city-small"]);
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(
        text.starts_with("builtin:city-small: 3862 triangles"),
        "{text}"
    );
    assert!(
        text.contains("camera 'street'") && text.contains("camera 'aerial'"),
        "{text}"
    );
    assert!(!text.contains("cameras: none"), "{text}");
    // Numbers as the f32 they are, not their f64 widening.
    assert!(text.contains("bounds: [-170, 0, -170] .. [170, "), "{text}");
    assert!(text.contains("position [3.5, 1.7, 117]"), "{text}");
    // A file without a camera says what a render will see.
    let o = raygun(&[
        "scene",
        "info",
        "tests/data/gltf-samples/TextureCoordinateTest.gltf",
    ]);
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(
        text.contains("cameras: none (renders frame the bounds from +Z"),
        "{text}"
    );

    // What the loader understood of the materials, by feature, with the materials' names.
    let glass = "tests/data/peers/scenes/coloured-glass.glb";
    let o = raygun(&["scene", "info", glass, "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let both = serde_json::json!(["smooth glass", "rough glass"]);
    assert_eq!(v["material_features"]["volume"], both);
    assert_eq!(v["material_features"]["transmission"], both);
    assert_eq!(
        v["material_features"]["specular"],
        serde_json::json!(["red", "blue"])
    );
    assert_eq!(v["material_features"].as_object().unwrap().len(), 3, "{v}");
    let text = String::from_utf8(raygun(&["scene", "info", glass]).stdout).unwrap();
    assert!(
        text.contains("\nvolume: 'smooth glass', 'rough glass'\n"),
        "{text}"
    );
    // Long lists are cut after four names.
    let coats = "tests/data/gltf-samples/ClearCoatTest/ClearCoatTest.gltf";
    let text = String::from_utf8(raygun(&["scene", "info", coats]).stdout).unwrap();
    let first = "'Simple_Coated', 'Partial_Coated', 'RoughVariations_Coated', 'BaseNorm_Coated'";
    assert!(
        text.contains(&format!("\nclearcoat: {first} and 2 more\n")),
        "{text}"
    );

    let o = raygun(&["scene", "info", "tests/data/scenes/missing.glb"]);
    assert_eq!(o.status.code(), Some(1));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("tests/data/scenes/missing.glb: cannot read the file"),
        "{e}"
    );
}

/// `render` takes an orthographic camera by name, a viewpoint from `--look-from/--look-at/
/// --yfov` for files without one, and says which cameras exist when the name is wrong.
#[test]
fn render_takes_orthographic_cameras_and_look_from_viewpoints() {
    let file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/gltf-samples/Cameras.gltf"
    );
    let png = tmp_file("cameras.png");
    let png = png.to_str().unwrap();
    let common = [
        "--size",
        "16,16",
        "--spp",
        "1",
        "--backend",
        "cpu",
        "--quiet",
    ];
    let ok = |extra: &[&str]| {
        let mut args = vec!["render", "--scene", file, "--out", png];
        args.extend_from_slice(&common);
        args.extend_from_slice(extra);
        raygun(&args)
    };
    let o = ok(&["--camera", "camera 1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = ok(&[
        "--look-from",
        "0.5,0.5,3",
        "--look-at",
        "0.5,0.5,0",
        "--yfov",
        "30",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = ok(&["--look-from", "0.5,0.5,3"]);
    assert!(!o.status.success(), "--look-from needs --look-at");
    let o = ok(&["--camera", "nope"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("'camera 0', 'camera 1' (orthographic)"),
        "{e}"
    );
}

/// `scene info` names the materials with a dispersion, an anisotropy and a diffuse
/// transmission, as the loader read them from a file (a dispersion on an opaque material is
/// read as none, and said), and prints a light's intensity as the f32 it is.
#[test]
fn scene_info_names_dispersive_brushed_and_translucent_materials() {
    let positions: Vec<u8> = [0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let buffer = base64::encode(&positions);
    let triangle = |material: u32| serde_json::json!({ "attributes": { "POSITION": 0 }, "material": material });
    let gltf = serde_json::json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_dispersion",
            "KHR_materials_anisotropy", "KHR_materials_diffuse_transmission",
            "KHR_lights_punctual"],
        "buffers": [{ "byteLength": 36,
            "uri": format!("data:application/octet-stream;base64,{buffer}") }],
        "bufferViews": [{ "buffer": 0, "byteLength": 36 }],
        "accessors": [{ "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
            "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0] }],
        "materials": [
            { "name": "prism", "extensions": {
                "KHR_materials_transmission": { "transmissionFactor": 1.0 },
                "KHR_materials_dispersion": { "dispersion": 0.33 } } },
            { "name": "brushed", "extensions": {
                "KHR_materials_anisotropy": { "anisotropyStrength": 0.5 } } },
            { "name": "painted", "extensions": {
                "KHR_materials_dispersion": { "dispersion": 0.5 } } },
            { "name": "leaf", "extensions": {
                "KHR_materials_diffuse_transmission": { "diffuseTransmissionFactor": 0.5 } } },
        ],
        "meshes": [{ "primitives": [triangle(0), triangle(1), triangle(2), triangle(3)] }],
        "extensions": { "KHR_lights_punctual": { "lights": [
            { "name": "warm", "type": "point", "color": [1.0, 0.9, 0.8] }] } },
        "nodes": [{ "mesh": 0 },
            { "extensions": { "KHR_lights_punctual": { "light": 0 } }, "translation": [0.0, 0.0, 2.0] }],
        "scenes": [{ "nodes": [0, 1] }],
    });
    let file = tmp_file("features.gltf");
    std::fs::write(&file, gltf.to_string()).unwrap();
    let path = file.to_str().unwrap();
    let o = raygun(&["scene", "info", path, "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let features = &v["material_features"];
    assert_eq!(features["dispersion"], serde_json::json!(["prism"]), "{v}");
    assert_eq!(features["anisotropy"], serde_json::json!(["brushed"]));
    assert_eq!(
        features["diffuse transmission"],
        serde_json::json!(["leaf"])
    );
    assert_eq!(v["unsupported"], serde_json::json!([]), "{v}");
    let text = String::from_utf8(raygun(&["scene", "info", path]).stdout).unwrap();
    assert!(text.contains("\ndispersion: 'prism'\n"), "{text}");
    // A light's intensity as the f32 it is, as positions are.
    assert!(
        text.contains("light 'warm': Point at [0, 0, 2], intensity [1, 0.9, 0.8]\n"),
        "{text}"
    );
    assert!(
        text.contains("'painted': KHR_materials_dispersion without transmission changes nothing"),
        "{text}"
    );
}
