//! `raygun bench all --quick` (issue 8) on the CPU backend at a small size: the files exist and
//! agree with each other, and guided rendering beats full-frame rendering inside a 10° ROI at
//! equal time.

use std::path::PathBuf;
use std::process::Command;

fn out_dir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("raygun-bench-all-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The number in the Markdown row for `fov` at column `col` (0 = FOV) of the convergence table.
fn convergence_cell(md: &str, fov: &str, col: usize) -> String {
    let table = md
        .split("## Convergence")
        .nth(1)
        .expect("convergence section");
    let row = table
        .lines()
        .find(|l| l.starts_with(&format!("| {fov}° |")))
        .unwrap_or_else(|| panic!("no convergence row for {fov}°"));
    row.split('|')
        .map(str::trim)
        .nth(col + 1)
        .unwrap()
        .to_string()
}

#[test]
fn bench_all_quick_writes_a_consistent_report() {
    let dir = out_dir();
    let status = Command::new(env!("CARGO_BIN_EXE_raygun"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "bench",
            "all",
            "--quick",
            "--size",
            "128,72",
            "--backend",
            "cpu",
        ])
        .arg("--out")
        .arg(&dir)
        .status()
        .unwrap();
    assert!(status.success());
    for f in ["report.md", "report.json", "fig5.png", "convergence.png"] {
        let meta = std::fs::metadata(dir.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert!(meta.len() > 0, "{f} is empty");
    }
    for png in ["fig5.png", "convergence.png"] {
        let bytes = std::fs::read(dir.join(png)).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{png} is not a PNG");
    }
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();

    // Header: device, commit, date and settings, the same in both.
    let header = &json["header"];
    for key in ["device", "commit", "date"] {
        let v = header[key].as_str().unwrap();
        assert!(!v.is_empty());
        assert!(md.contains(v), "Markdown lacks the {key} '{v}'");
    }
    assert!(header["device"].as_str().unwrap().starts_with("CPU twins"));
    assert_eq!(json["config"]["size"], serde_json::json!([128, 72]));
    assert_eq!(json["config"]["quick"], true);
    assert!(md.contains("128×72"));
    for section in [
        "## DGI",
        "## Full-frame path tracing",
        "## Guided",
        "## Filter",
    ] {
        assert!(md.contains(section), "missing {section}");
    }
    assert_eq!(json["guided"]["rows"].as_array().unwrap().len(), 2);
    assert!(!json["dgi"]["rows"].as_array().unwrap().is_empty());
    assert_eq!(json["trace"].as_array().unwrap().len(), 1);
    assert!(!json["filter"]["errors"].as_array().unwrap().is_empty());

    let curves = json["convergence"].as_array().unwrap();
    assert_eq!(curves.len(), 2);
    for cv in curves {
        let fov = cv["fov_deg"].as_f64().unwrap();
        let label = format!("{fov}");
        let guided = cv["guided"].as_array().unwrap();
        let full = cv["full_frame"].as_array().unwrap();
        assert_eq!(
            guided.len(),
            128 / 8,
            "{fov}°: one point every 8 iterations"
        );
        assert!(full.len() >= 2);
        // Time accumulates; the full-frame render ran at least as long as the guided one.
        for c in [guided, full] {
            for w in c.windows(2) {
                assert!(w[1]["ms"].as_f64().unwrap() > w[0]["ms"].as_f64().unwrap());
                assert!(w[1]["iteration"].as_u64() > w[0]["iteration"].as_u64());
            }
        }
        let g_end = guided.last().unwrap();
        assert!(full.last().unwrap()["ms"].as_f64() >= g_end["ms"].as_f64());
        // The Markdown shows the JSON's figures.
        let num = |v: &serde_json::Value| v.as_f64().unwrap();
        assert_eq!(
            convergence_cell(&md, &label, 1),
            cv["roi_pixels"].as_u64().unwrap().to_string()
        );
        assert_eq!(
            convergence_cell(&md, &label, 2),
            format!("{:.4}", num(&cv["target_rmse_roi"]))
        );
        assert_eq!(
            convergence_cell(&md, &label, 7),
            format!("{:.4}", num(&g_end["rmse_roi"]))
        );
        assert!(
            convergence_cell(&md, &label, 8)
                .starts_with(&format!("{:.4}", num(&cv["full_rmse_roi_at_guided_end"])))
        );
        // The target is 1 % of the reference's mean in the ROI.
        let target = num(&cv["target_rmse_roi"]);
        assert!((target - 0.01 * num(&cv["reference_mean_roi"])).abs() <= 1e-12 * target.abs());
        for (who, t) in [
            ("guided", &cv["guided_time_to_target"]),
            ("full", &cv["full_time_to_target"]),
        ] {
            let reached = t["reached"].as_bool().unwrap();
            assert_eq!(reached, num(&t["rmse_roi"]) <= target, "{fov}° {who}");
            // Extrapolated exactly when not reached, and then beyond the measured time.
            assert_eq!(t["extrapolated_ms"].is_null(), reached, "{fov}° {who}");
            if !reached {
                assert!(num(&t["extrapolated_ms"]) > num(&t["ms"]), "{fov}° {who}");
            }
        }
        if fov == 10.0 {
            // At 10° a guided iteration traces a few percent of the pixels: at equal time the
            // ROI has many more samples per pixel than the full frame's (noise ∝ 1/√spp).
            let g = num(&g_end["rmse_roi"]);
            let f = num(&cv["full_rmse_roi_at_guided_end"]);
            assert!(g < f, "10°: guided ROI RMSE {g} not below full frame {f}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
