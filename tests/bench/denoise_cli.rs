//! `raygun bench denoise` end to end, tiny, on the CPU twins: the JSON report is whole and
//! consistent, the denoisers help where the guided render leaves the periphery noisy, and the
//! crops PNG has the size the report gives. OIDN must be installed (`bash tools/oidn.sh
//! install`, as CI does): without it this test fails, it does not skip.

use crate::support;
use support::{fails_with, ok, raygun, s, tmp_dir};

#[test]
fn bench_denoise_reports_every_method_and_region_and_the_denoisers_help_in_the_periphery() {
    let dir = tmp_dir("bench-denoise");
    let (json, crops) = (dir.join("report.json"), dir.join("crops.png"));
    let o = raygun(&[
        "bench",
        "denoise",
        "--size",
        "48,27",
        "--iterations",
        "1,4",
        "--reference-spp",
        "64",
        "--timing-sizes",
        "none",
        "--backend",
        "cpu",
        "--json",
        s(&json),
        "--crops",
        s(&crops),
    ]);
    ok(&o);
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(
        v["oidn_loaded"], true,
        "OIDN did not load ({}): run `bash tools/oidn.sh install`",
        v["oidn"]
    );
    let errors = v["errors"].as_array().unwrap();
    // 2 FOVs × 2 counts × 4 methods × 2 regions.
    assert_eq!(errors.len(), 2 * 2 * 4 * 2);
    let get = |fov: f64, n: u64, method: &str, region: &str| {
        let rows: Vec<_> = errors
            .iter()
            .filter(|e| {
                e["fov_deg"] == fov
                    && e["iterations"] == n
                    && e["method"] == method
                    && e["region"] == region
            })
            .collect();
        assert_eq!(rows.len(), 1, "{fov}° {n} {method} {region}");
        rows[0].clone()
    };
    for fov in [10.0, 60.0] {
        for n in [1, 4] {
            let pixels = |region| get(fov, n, "off", region)["pixels"].as_u64().unwrap();
            assert_eq!(pixels("roi") + pixels("periphery"), 48 * 27);
            for method in ["off", "filter", "interactive", "oidn"] {
                for region in ["roi", "periphery"] {
                    let e = get(fov, n, method, region);
                    // A region without pixels has no figure (null); every other is in range.
                    if e["pixels"] != 0 {
                        let flip = e["flip"].as_f64().unwrap();
                        assert!((0.0..=1.0).contains(&flip), "{e}");
                        assert!(e["rel_mse"].as_f64().unwrap() >= 0.0, "{e}");
                    }
                }
            }
            if n == 4 {
                let rel = |m| get(fov, 4, m, "periphery")["rel_mse"].as_f64().unwrap();
                // The denoisers are held to the picture they start from: where the periphery is
                // sampled (60°), below the raw mean's; at 10° on 48×27 it is mostly unsampled,
                // and both take the filter's fill where they have no sample of their own (which
                // spreads the light's radiance over a tiny picture: above the raw mean's black),
                // so there they are held below the filter's picture, what `--denoise off`
                // shows.
                let base = if fov == 60.0 { "off" } else { "filter" };
                for m in ["interactive", "oidn"] {
                    assert!(
                        rel(m) < rel(base),
                        "{fov}°: periphery relMSE {m} {} ≥ {base} {}",
                        rel(m),
                        rel(base)
                    );
                }
            }
        }
    }
    // Equal time: one row per FOV, budget and method; `off` always fits its own budget.
    let eq = v["equal_time"].as_array().unwrap();
    assert_eq!(eq.len(), 2 * 2 * 4);
    for e in eq.iter().filter(|e| e["method"] == "off") {
        assert_eq!(e["iterations"], e["budget_iterations"], "{e}");
    }
    for e in eq.iter().filter(|e| !e["iterations"].is_null()) {
        assert!(
            e["cost_ms"].as_f64().unwrap() <= e["budget_ms"].as_f64().unwrap(),
            "{e}"
        );
    }
    // Timings: the bench size alone.
    let timings = v["timings"].as_array().unwrap();
    assert_eq!(timings.len(), 1);
    assert_eq!(timings[0]["width"], 48);
    assert!(timings[0]["oidn_ms"].as_f64().unwrap() > 0.0);
    assert!(timings[0]["interactive_cpu_ms"].as_f64().unwrap() > 0.0);
    // The crops: the size the report gives, 5 columns and 2 rows of scaled crops.
    let c = &v["crops"];
    let img = image::open(&crops).unwrap();
    assert_eq!(
        [img.width(), img.height()],
        [
            c["width"].as_u64().unwrap() as u32,
            c["height"].as_u64().unwrap() as u32
        ]
    );
    let cell = (c["side"].as_u64().unwrap() * c["scale"].as_u64().unwrap()) as u32;
    assert_eq!(img.width(), 5 * cell + 6 * 4);
    assert_eq!(img.height(), 22 + 2 * cell + 3 * 4);
    assert_eq!(c["iterations"], 4);
    assert!(
        stdout_has_tables(&o),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
}

fn stdout_has_tables(o: &std::process::Output) -> bool {
    let t = String::from_utf8_lossy(&o.stdout);
    t.contains("Equal iterations") && t.contains("Equal time") && t.contains("Targets")
}

#[test]
fn bad_denoise_bench_flags_are_rejected_with_the_flag_named() {
    for (args, flag) in [
        (&["--size", "8,8"][..], "--size"),
        (&["--iterations", "1,300"][..], "--iterations"),
        (&["--timing-sizes", "1920by1080"][..], "--timing-sizes"),
        (&["--timing-sizes", "7680x4320"][..], "--timing-sizes"),
        (&["--crops", "x.exr"][..], "--crops"),
        (
            &["--iterations", "1,2", "--crops-iterations", "4"][..],
            "--crops-iterations",
        ),
    ] {
        let mut all = vec!["bench", "denoise", "--backend", "cpu"];
        all.extend_from_slice(args);
        let o = raygun(&all);
        assert!(!o.status.success(), "{args:?}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(flag), "{args:?}: {e}");
        if flag != "--timing-sizes" || args[1] != "1920by1080" {
            fails_with(&o, &[flag]);
        }
    }
}
