//! Smoke test of the real window: `raygun view` under Xvfb (eframe's wgpu on lavapipe) renders
//! several iterations, saves the picture and a screenshot of the whole window, and exits. Needs
//! `xvfb-run` (installed by `.ci/run`); it fails, never skips, without it.

use std::path::Path;
use std::process::Command;

const W: u32 = 124;
const H: u32 = 50;
const N: u32 = 12;

fn gray_exr(path: &Path) -> Vec<f32> {
    let img = exr::prelude::read_first_flat_layer_from_file(path).unwrap();
    img.layer_data.channel_data.list[0]
        .sample_data
        .values_as_f32()
        .collect()
}

#[test]
fn viewer_under_xvfb_renders_and_saves_a_screenshot() {
    let have = Command::new("sh")
        .args(["-c", "command -v xvfb-run"])
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        have,
        "xvfb-run is missing: install the xvfb package (.ci/run does)"
    );
    let dir = std::env::temp_dir().join(format!("raygun-xvfb-{}", std::process::id()));
    let o = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x720x24"])
        .arg(env!("CARGO_BIN_EXE_raygun"))
        .args(["view", "--backend", "cpu", "--size", &format!("{W},{H}")])
        .args([
            "--roi-at",
            "62,25",
            "--roi-radius",
            "1500",
            "--filter",
            "off",
        ])
        .args(["--screenshot-after", &N.to_string(), "--save-dir"])
        .arg(&dir)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{log}");
    // The window: not blank, and showing the picture with its yellow ROI outline.
    let window = image::open(dir.join("screenshot.window.png"))
        .unwrap_or_else(|e| panic!("no window screenshot ({e}): {log}"))
        .to_rgb8();
    let mut colours: Vec<[u8; 3]> = window.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(
        colours.len() > 100,
        "{} colours: blank window",
        colours.len()
    );
    let outline = window
        .pixels()
        .filter(|p| p.0[0] >= 250 && (215..=225).contains(&p.0[1]) && p.0[2] <= 5)
        .count();
    assert!(outline > 20, "{outline} outline pixels in the window");
    // The picture after N iterations: every ROI pixel (d = 0) has N samples, and the periphery
    // (d = 1, p = p_min = 0 there) far fewer.
    let counts = gray_exr(&dir.join("screenshot.counts.exr"));
    let dgi = image::open(dir.join("screenshot.dgi.png"))
        .unwrap()
        .to_luma8();
    assert_eq!(counts.len(), (W * H) as usize);
    let (mut roi, mut far) = (Vec::new(), Vec::new());
    for (i, d) in dgi.pixels().enumerate() {
        match d.0[0] {
            0 => roi.push(counts[i]),
            255 => far.push(counts[i]),
            _ => {}
        }
    }
    assert!(
        !roi.is_empty() && !far.is_empty(),
        "{} ROI, {} far",
        roi.len(),
        far.len()
    );
    let at_least = roi.iter().copied().fold(f32::INFINITY, f32::min);
    assert!(
        at_least >= N as f32,
        "an ROI pixel has {at_least} < {N} samples"
    );
    let far_mean = far.iter().sum::<f32>() / far.len() as f32;
    assert!(
        far_mean < at_least / 2.0,
        "periphery {far_mean} vs ROI {at_least}"
    );
    // The saved image is not blank either.
    let shot = image::open(dir.join("screenshot.png")).unwrap().to_rgb8();
    assert_eq!(shot.dimensions(), (W, H));
    assert!(shot.pixels().any(|p| p.0 != [0, 0, 0]));
    std::fs::remove_dir_all(&dir).ok();
}
