//! `render --denoise interactive|oidn`: raygun's own denoiser and Intel Open Image Denoise
//! through the command line, against a converged reference of the same view (the denoiser is
//! tested in `src/filter/denoise/`, the library in `src/filter/oidn.rs`).

use std::path::Path;
use std::process::Command;

use crate::support::{ROOT, fails_with, ok, s, stderr, tmp_dir};

const SIZE: &str = "64,36";

fn render(dir: &Path, out: &str, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_raygun"));
    c.current_dir(ROOT)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .args([
            "render",
            "--scene",
            "builtin:cornell",
            "--backend",
            "cpu",
            "--size",
            SIZE,
        ])
        .args(extra)
        .arg("--out")
        .arg(dir.join(out));
    c
}

/// Every channel of every pixel, in the file's channel order (the same for every file here).
fn values(path: &Path) -> Vec<f32> {
    let img = exr::prelude::read_first_flat_layer_from_file(path).unwrap();
    img.layer_data
        .channel_data
        .list
        .iter()
        .flat_map(|c| c.sample_data.values_as_f32().collect::<Vec<_>>())
        .collect()
}

fn mse(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(a, b)| f64::from(a - b).powi(2))
        .sum::<f64>()
        / a.len() as f64
}

#[test]
fn both_denoisers_bring_a_noisy_picture_closer_to_the_reference_and_say_what_ran() {
    let dir = tmp_dir("denoise-oidn");
    ok(&render(&dir, "ref.exr", &["--spp", "512"]).output().unwrap());
    let reference = values(&dir.join("ref.exr"));
    // A full frame of 4 samples a pixel, and a guided render whose periphery is sparse (the
    // filter fills what the denoisers cannot reach or OIDN sees where a pixel has no sample).
    let cases: [&[&str]; 2] = [
        &["--spp", "4"],
        &["--guide", "mouse:32,18:8,8", "--iterations", "8"],
    ];
    let denoisers = [
        (
            "oidn",
            "denoise: Intel Open Image Denoise 2.5.1 on its CPU device",
        ),
        (
            "interactive",
            "denoise: raygun's interactive denoiser on the CPU",
        ),
    ];
    for (k, case) in cases.iter().enumerate() {
        let off = format!("off-{k}.exr");
        ok(&render(&dir, &off, case)
            .args(["--denoise", "off"])
            .output()
            .unwrap());
        let raw = mse(&values(&dir.join(&off)), &reference);
        for (name, says) in denoisers {
            let on = format!("{name}-{k}.exr");
            let o = render(&dir, &on, case)
                .args(["--denoise", name])
                .output()
                .unwrap();
            ok(&o);
            let err = stderr(&o);
            assert!(err.contains(says), "{err}");
            let denoised = mse(&values(&dir.join(&on)), &reference);
            assert!(
                denoised < 0.5 * raw,
                "{case:?} {name}: MSE {denoised} denoised against {raw} without"
            );
        }
    }
}

#[test]
fn without_the_library_denoise_oidn_says_how_to_get_it_and_writes_nothing() {
    let dir = tmp_dir("denoise-missing");
    let o = render(&dir, "out.png", &["--spp", "1", "--denoise", "oidn"])
        .env("OIDN_DIR", dir.join("no-oidn"))
        .output()
        .unwrap();
    fails_with(
        &o,
        &[
            "--denoise oidn",
            "was not found",
            "tools/oidn.sh install",
            "OIDN_DIR",
            s(&dir.join("no-oidn")),
        ],
    );
    assert!(!dir.join("out.png").exists());
}
