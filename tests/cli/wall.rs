//! Wall output (`render --tiles DIR`): one image per display tile, cut from the canvas.

use crate::support;
use support::tmp_dir;

use std::path::Path;
use std::process::Command;

fn read_rgb_exr(path: &Path) -> (usize, usize, Vec<[f32; 3]>) {
    let img = exr::prelude::read_first_flat_layer_from_file(path).unwrap();
    let size = img.layer_data.size;
    let ch = &img.layer_data.channel_data.list;
    // Channels are sorted by name: B, G, R.
    let get = |i: usize| -> Vec<f32> { ch[i].sample_data.values_as_f32().collect() };
    let (b, g, r) = (get(0), get(1), get(2));
    let px = (0..r.len()).map(|i| [r[i], g[i], b[i]]).collect();
    (size.0, size.1, px)
}

/// Two 16×9 tiles side by side with 2-pixel bezels (pitch 1 cm): a 40×13 canvas; tile c0r0's
/// active area starts at canvas pixel (2, 2), c1r0's at (22, 2).
const MODEL: &str = r#"{
  "name": "two tiles",
  "generator": {
    "columns": 2, "rows": 1, "resolution": [16, 9],
    "active_size": [0.16, 0.09],
    "bezel": { "left": 0.02, "right": 0.02, "top": 0.02, "bottom": 0.02 },
    "yaw_step_deg": 0.0,
    "center": [0, 0, 0], "normal": [0, 0, 1], "up": [0, 1, 0]
  }
}"#;

#[test]
fn render_tiles_writes_each_tiles_canvas_pixels() {
    let dir = tmp_dir("cli");
    let model = dir.join("two.json");
    std::fs::write(&model, MODEL).unwrap();
    let out = dir.join("canvas.exr");
    let tiles = dir.join("tiles");
    let status = Command::new(env!("CARGO_BIN_EXE_raygun"))
        .args([
            "render",
            "--scene",
            "builtin:cornell-light",
            "--size",
            "40,13",
            "--spp",
            "2",
        ])
        .args(["--backend", "cpu", "--quiet", "--display"])
        .arg(&model)
        .arg("--out")
        .arg(&out)
        .arg("--tiles")
        .arg(&tiles)
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let (w, h, canvas) = read_rgb_exr(&out);
    assert_eq!((w, h), (40, 13));
    let mut names: Vec<String> = std::fs::read_dir(&tiles)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["c0r0.exr", "c1r0.exr"]);
    for (name, x0) in [("c0r0.exr", 2), ("c1r0.exr", 22)] {
        let (tw, th, px) = read_rgb_exr(&tiles.join(name));
        assert_eq!((tw, th), (16, 9));
        for y in 0..9 {
            for x in 0..16 {
                assert_eq!(
                    px[y * 16 + x],
                    canvas[(2 + y) * 40 + x0 + x],
                    "{name} {x},{y}"
                );
            }
        }
    }
    // The image is not uniform, so the comparison above could tell tiles apart.
    assert!(canvas.iter().any(|p| *p != canvas[0]));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn tiles_format_must_be_exr_or_png() {
    let o = Command::new(env!("CARGO_BIN_EXE_raygun"))
        .args([
            "render",
            "--scene",
            "builtin:cornell-light",
            "--out",
            "x.exr",
        ])
        .args(["--tiles", "t", "--tiles-format", "tif"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("exr or png"));
}

/// `--size native` is the canvas's own pixel size: the same files as spelling that size out,
/// no resampling note, and on a curved wall (columns turned 10° apart, like HORNET) every
/// tile written at its own resolution; `dgi` takes it too; a display that cannot be opened is
/// named.
#[test]
fn size_native_is_the_canvas_size_and_cuts_tiles_without_resampling() {
    let dir = tmp_dir("native");
    let model = dir.join("two.json");
    std::fs::write(&model, MODEL).unwrap();
    let render = |size: &str, out: &str, tiles: &str, display: &Path| {
        Command::new(env!("CARGO_BIN_EXE_raygun"))
            .args(["render", "--scene", "builtin:cornell-light", "--size", size])
            .args(["--spp", "2", "--backend", "cpu", "--quiet", "--display"])
            .arg(display)
            .arg("--out")
            .arg(dir.join(out))
            .arg("--tiles")
            .arg(dir.join(tiles))
            .output()
            .unwrap()
    };
    let spelled = render("40,13", "spelled.exr", "spelled", &model);
    let native = render("native", "native.exr", "native", &model);
    for o in [&spelled, &native] {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(!String::from_utf8_lossy(&o.stderr).contains("resampled"));
    }
    let read = |p: &str| std::fs::read(dir.join(p)).unwrap();
    assert_eq!(read("spelled.exr"), read("native.exr"));
    for t in ["c0r0.exr", "c1r0.exr"] {
        assert_eq!(read(&format!("spelled/{t}")), read(&format!("native/{t}")));
    }
    // A curved wall: 3 columns turned 10° apart, 20×10-pixel tiles, 1-pixel bezels.
    let curved = dir.join("curved.json");
    std::fs::write(
        &curved,
        r#"{ "name": "curved", "generator": {
            "columns": 3, "rows": 2, "resolution": [20, 10], "active_size": [0.2, 0.1],
            "bezel": { "left": 0.01, "right": 0.01, "top": 0.01, "bottom": 0.01 },
            "yaw_step_deg": 10.0, "center": [0, 0, 0], "normal": [0, 0, 1], "up": [0, 1, 0] } }"#,
    )
    .unwrap();
    let o = render("native", "curved.exr", "curved", &curved);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (w, h, canvas) = read_rgb_exr(&dir.join("curved.exr"));
    assert_eq!((w, h), (66, 24), "3 × (20 + 2) by 2 × (10 + 2)");
    for (c, r) in [(0, 0), (1, 0), (2, 1)] {
        let (tw, th, px) = read_rgb_exr(&dir.join(format!("curved/c{c}r{r}.exr")));
        assert_eq!((tw, th), (20, 10));
        let (x0, y0) = (22 * c + 1, 12 * r + 1);
        for y in 0..10 {
            for x in 0..20 {
                assert_eq!(
                    px[y * 20 + x],
                    canvas[(y0 + y) * 66 + x0 + x],
                    "c{c}r{r} {x},{y}"
                );
            }
        }
    }
    let dgi = Command::new(env!("CARGO_BIN_EXE_raygun"))
        .args([
            "dgi", "--size", "native", "--origin", "0,0,1", "--dir", "0,0,-1",
        ])
        .args(["--fov", "20,20", "--display"])
        .arg(&curved)
        .arg("--out")
        .arg(dir.join("dgi.exr"))
        .output()
        .unwrap();
    assert!(
        dgi.status.success(),
        "{}",
        String::from_utf8_lossy(&dgi.stderr)
    );
    let img = exr::prelude::read_first_flat_layer_from_file(dir.join("dgi.exr")).unwrap();
    assert_eq!(img.layer_data.size.0, 66);
    assert_eq!(img.layer_data.size.1, 24);
    let missing = render("native", "x.exr", "x", &dir.join("no-such-wall.json"));
    assert!(!missing.status.success());
    let e = String::from_utf8_lossy(&missing.stderr);
    assert!(
        e.contains("--size native is the canvas size of --display")
            && e.contains("no-such-wall.json"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
