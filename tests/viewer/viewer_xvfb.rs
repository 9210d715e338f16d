//! Smoke test of the real window: `raygun view` under Xvfb (eframe's wgpu on lavapipe) renders
//! several iterations on its own GPU backend (lavapipe too: the whole guided GPU frame path), saves the picture and a screenshot of the whole window, and exits. Needs
//! `xvfb-run` (installed by `.ci/run`); it fails, never skips, without it. A build without the
//! window (`--no-default-features`) has nothing to smoke-test.
#![cfg(feature = "viewer")]

use std::path::Path;
use std::process::Command;

use raygun::viewer::diagnostics::{NoiseContrast, NoiseRegions, predicted_noise_ratio};

use crate::xvfb;

const W: u32 = xvfb::SIZE[0];
const H: u32 = xvfb::SIZE[1];
const N: u32 = xvfb::ITERATIONS;

/// What `raygun view` says when its window draws with the renderer's GPU.
const SHARED: &str = "the window draws with the renderer's GPU";

/// Pixels of the ROI outline's yellow in a window screenshot.
fn outline_pixels(window: &image::RgbImage) -> usize {
    window
        .pixels()
        .filter(|p| p.0[0] >= 250 && (215..=225).contains(&p.0[1]) && p.0[2] <= 5)
        .count()
}

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
        // 1280×700: shorter than the side panel, which must then scroll.
        .args(["-a", "-s", "-screen 0 1280x700x24"])
        .arg(env!("CARGO_BIN_EXE_raygun"))
        .args(["view", "--backend", "gpu", "--size", &format!("{W},{H}")])
        .args([
            "--roi-at",
            &format!("{},{}", xvfb::ROI_AT[0], xvfb::ROI_AT[1]),
        ])
        .args(["--roi-radius", &xvfb::ROI_RADIUS.to_string()])
        .args(["--p-min", &xvfb::P_MIN.to_string(), "--filter", "off"])
        .args(["--screenshot-after", &N.to_string(), "--save-dir"])
        .arg(&dir)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{log}");
    // The window draws with the renderer's device (`--window-gpu shared`, the default): the
    // pictures, the screenshot's included, are written into its texture on the GPU.
    assert!(log.contains(SHARED), "{log}");
    // The window: not blank, and showing the picture with its yellow ROI outline (in its
    // exact colour: the texture holds the sRGB bytes egui's own textures hold).
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
    let outline = outline_pixels(&window);
    assert!(outline > 20, "{outline} outline pixels in the window");
    // The side panel is taller than the window: it shows a scroll bar, a column just left of
    // the panel's edge that differs from the panel's background over most of the height.
    let (ww, wh) = window.dimensions();
    let background = window.get_pixel(2, wh / 2).0;
    let edge = (100..ww / 2)
        .find(|&x| (0..wh).all(|y| window.get_pixel(x, y).0 != background))
        .expect("the side panel's edge");
    let bar = (edge.saturating_sub(30)..edge).any(|x| {
        (0..wh)
            .filter(|&y| window.get_pixel(x, y).0 != background)
            .count()
            * 10
            >= wh as usize * 6
    });
    assert!(bar, "no scroll bar left of the panel edge at x = {edge}");
    // The picture after N iterations: every ROI pixel (d = 0) has N samples, and the periphery
    // (d = 1, p = p_min there) far fewer.
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
    // Measured noise: the standard error of each pixel's mean luminance (absolute: see
    // NoiseContrast for why). The ROI is sampled every iteration and the periphery with
    // probability p_min, so its SE should be about √p_min (¼) of the periphery's; the bound
    // allows twice that for the regions' different content and the spread of an SE estimated
    // from ~4 samples. A viewer sampling every pixel alike has a ratio near 1 and fails it
    // (tests/viewer/viewer.rs: the_roi_is_less_noisy_than_the_periphery_and_a_uniform_sampler_is_not).
    let noise = gray_exr(&dir.join("screenshot.noise.exr"));
    for (i, se) in noise.iter().enumerate() {
        assert_eq!(
            se.is_nan(),
            counts[i] < 2.0,
            "pixel {i}: SE {se}, {} samples",
            counts[i]
        );
    }
    let d: Vec<f32> = dgi.pixels().map(|p| f32::from(p.0[0]) / 255.0).collect();
    let regions = NoiseRegions {
        dgi: &d,
        p_min: xvfb::P_MIN,
    };
    let contrast = NoiseContrast::measure(&noise, &regions)
        .expect("the ROI and the periphery have pixels with an SE");
    assert!(
        contrast.roi_pixels > 50 && contrast.periphery_pixels > 50,
        "{contrast:?}"
    );
    let bound = 2.0 * predicted_noise_ratio(xvfb::P_MIN);
    assert!(
        contrast.ratio() <= bound,
        "ROI noise {} vs periphery {}: ratio {} > {bound}",
        contrast.roi,
        contrast.periphery,
        contrast.ratio()
    );
    // The saved image is not blank either.
    let shot = image::open(dir.join("screenshot.png")).unwrap().to_rgb8();
    assert_eq!(shot.dimensions(), (W, H));
    assert!(shot.pixels().any(|p| p.0 != [0, 0, 0]));
    std::fs::remove_dir_all(&dir).ok();
}

/// `view --camera wall` in the real window, its eye following the replay's tracked head: the
/// window opens, renders through the wall camera and saves; bezel pixels are never sampled.
#[test]
fn viewer_under_xvfb_renders_through_the_wall_camera_with_a_tracked_head() {
    let dir = std::env::temp_dir().join(format!("raygun-xvfb-wall-{}", std::process::id()));
    let replay =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tracking-replays/head-1-walk.dtrack.jsonl");
    let o = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x700x24"])
        .arg(env!("CARGO_BIN_EXE_raygun"))
        // 1/10 of HORNET's canvas: image pixels narrower than its gaps, so some lie in a gap
        // no tile shows (smaller images are shown whole).
        .args(["view", "--backend", "cpu", "--size", "1352,546"])
        .args(["--camera", "wall", "--max-depth", "1", "--replay"])
        .arg(&replay)
        .args(["--screenshot-after", "6", "--save-dir"])
        .arg(&dir)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{log}");
    assert!(dir.join("screenshot.window.png").exists(), "{log}");
    let counts = gray_exr(&dir.join("screenshot.counts.exr"));
    let model = raygun::display::DisplayModel::open("hornet").unwrap().0;
    let any = (glam::DVec3::ZERO, glam::DVec3::NEG_Z, glam::DVec3::Y);
    let wall = raygun::trace::wall::WallCamera::new(
        &model,
        [1352, 546],
        glam::DVec3::new(0.0, 0.0, 1.0),
        &raygun::trace::wall::WorldFromRoom::Identity,
        any,
    )
    .unwrap();
    let hidden: Vec<usize> = (0..counts.len())
        .filter(|&p| !wall.is_shown(p as u32))
        .collect();
    assert!(!hidden.is_empty());
    assert!(
        hidden.iter().all(|&p| counts[p] == 0.0),
        "a bezel pixel was sampled"
    );
    assert!(counts.iter().any(|&c| c > 0.0));
    std::fs::remove_dir_all(&dir).ok();
}

/// `--window-gpu own`: the window picks its own device, and the pictures come to it as bytes
/// through the host — the path for a renderer on a GPU that drives no display. The same picture
/// shows, outline and all.
#[test]
fn viewer_under_xvfb_with_its_own_device_shows_the_picture_through_the_host() {
    let dir = std::env::temp_dir().join(format!("raygun-xvfb-own-{}", std::process::id()));
    let o = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x700x24"])
        .arg(env!("CARGO_BIN_EXE_raygun"))
        .args(["view", "--backend", "gpu", "--window-gpu", "own"])
        .args(["--size", &format!("{W},{H}")])
        .args([
            "--roi-at",
            &format!("{},{}", xvfb::ROI_AT[0], xvfb::ROI_AT[1]),
        ])
        .args(["--roi-radius", &xvfb::ROI_RADIUS.to_string()])
        .args(["--filter", "off", "--screenshot-after", "4", "--save-dir"])
        .arg(&dir)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{log}");
    assert!(!log.contains(SHARED), "{log}");
    let window = image::open(dir.join("screenshot.window.png"))
        .unwrap_or_else(|e| panic!("no window screenshot ({e}): {log}"))
        .to_rgb8();
    let outline = outline_pixels(&window);
    assert!(outline > 20, "{outline} outline pixels in the window");
    std::fs::remove_dir_all(&dir).ok();
}
