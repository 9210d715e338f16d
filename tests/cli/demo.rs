//! `raygun demo` headless: the embedded Cornell box on HORNET, guided by the bundled replay.

use std::process::Command;

#[test]
fn headless_demo_writes_images_and_a_report() {
    let out = std::env::temp_dir().join(format!("raygun-demo-{}", std::process::id()));
    let o = Command::new(env!("CARGO_BIN_EXE_raygun"))
        .args(["demo", "--headless", "--quiet", "--backend", "cpu"])
        .args(["--size", "62,25", "--iterations", "8", "--out"])
        .arg(&out)
        // Run from elsewhere: the demo's inputs are embedded, not read from the checkout.
        .current_dir(std::env::temp_dir())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "image.png",
        "image.exr",
        "dgi.png",
        "counts.exr",
        "report.md",
        "denoisers.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    // The denoisers' crops: four columns (raw, filter, interactive, OIDN) of two crops each.
    let crops = image::open(out.join("denoisers.png")).unwrap();
    let want = raygun::bench::denoise::crops_png_size([62, 25], 4);
    assert_eq!([crops.width(), crops.height()], want);
    let img = image::open(out.join("image.png")).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (62, 25));
    assert!(img.pixels().any(|p| p.0 != [0, 0, 0]), "blank image");
    // The counts add up to the report's samples, and the guide saved some of them.
    let counts = exr::prelude::read_first_flat_layer_from_file(out.join("counts.exr")).unwrap();
    let total: f64 = counts.layer_data.channel_data.list[0]
        .sample_data
        .values_as_f32()
        .map(f64::from)
        .sum();
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        report.contains(&format!("| samples | {total} |")),
        "{report}"
    );
    let full = 62.0 * 25.0 * 8.0;
    assert!(total > 0.0 && total < full, "{total} of {full}");
    assert!(report.contains("| iterations | 8 |"));
    // The one-time work is reported apart from the render time of the iterations.
    for row in ["scene load", "BVH build", "upload"] {
        assert!(
            report.contains(&format!("| {row} (one-time) | ")),
            "{report}"
        );
    }
    assert!(report.contains("`builtin:cornell-light`"));
    // The demo's picture is denoised by default, and the report says by what.
    assert!(
        report.contains("| denoiser | raygun's interactive denoiser on the CPU |"),
        "{report}"
    );
    std::fs::remove_dir_all(&out).ok();
}
