//! `raygun bench all --quick` on the CPU backend at a small size: the files exist and
//! agree with each other, and guided rendering beats full-frame rendering inside a 10° ROI at
//! equal time. Each section is checked for internal consistency: the paper table's rows exist and
//! our values are the benchmarks' own, the closest-point solver meets its stated accuracy, the
//! per-stage times fit inside the measured iteration, and the targets are not judged on a CPU.

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

/// The cells of the Markdown table row whose first cell is `first`, in the section that starts
/// with `heading` (up to the next `## `).
fn row_cells(md: &str, heading: &str, first: &str) -> Vec<String> {
    let section = md
        .split(heading)
        .nth(1)
        .unwrap_or_else(|| panic!("no section {heading}"));
    let section = section.split("\n## ").next().unwrap();
    let row = section
        .lines()
        .find(|l| l.starts_with(&format!("| {first} |")))
        .unwrap_or_else(|| panic!("{heading}: no row '{first}'"));
    row.split('|')
        .map(|c| c.trim().to_string())
        .filter(|c| !c.is_empty())
        .collect()
}

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[test]
fn bench_all_quick_writes_a_consistent_report() {
    let dir = out_dir();
    // No report of no iterations or references: refused before anything runs, naming the flag.
    for flag in ["--iterations", "--reference-spp"] {
        let o = Command::new(env!("CARGO_BIN_EXE_raygun"))
            .args(["bench", "all", "--quick", flag, "0"])
            .arg("--out")
            .arg(&dir)
            .output()
            .unwrap();
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(flag) && err.contains("0"), "{err}");
        assert!(!dir.join("report.md").exists());
    }
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
            "--iterations",
            "64",
            "--reference-spp",
            "512",
        ])
        .arg("--out")
        .arg(&dir)
        .status()
        .unwrap();
    assert!(status.success());
    for f in [
        "report.md",
        "report.json",
        "fig5.png",
        "dgi_metrics.png",
        "convergence.png",
    ] {
        let meta = std::fs::metadata(dir.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
        assert!(meta.len() > 0, "{f} is empty");
    }
    for png in ["fig5.png", "dgi_metrics.png", "convergence.png"] {
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
    // Enough to rerun it: the command line, the build, the processor; no adapter on the CPU.
    let command = header["command"].as_str().unwrap();
    assert!(
        command.contains(
            "bench all --quick --size 128,72 --backend cpu --iterations 64 --reference-spp 512 --out"
        ),
        "{command}"
    );
    assert!(md.contains(&format!("- Command: `{command}`")));
    assert!(header["adapter"].is_null());
    assert!(md.contains("- Adapter: none (CPU twins)"));
    assert_eq!(header["profile"], "debug");
    assert!(header["dirty"].is_boolean());
    assert!(md.contains(header["cpu"].as_str().unwrap()));
    assert_eq!(json["config"]["size"], serde_json::json!([128, 72]));
    assert_eq!(json["config"]["quick"], true);
    // The mode's iterations and reference overridden.
    assert_eq!(json["config"]["iterations"], 64);
    assert_eq!(json["config"]["reference_spp"], 512);
    assert!(md.contains("128×72"));
    for section in [
        "## The paper's table beside ours",
        "## Targets",
        "## DGI",
        "## DGI metrics: time vs error",
        "## Closest-point solver",
        "## Full-frame path tracing",
        "## Guided",
        "## Filter",
        "## Convergence",
        "## Per-stage times per iteration",
    ] {
        assert!(md.contains(section), "missing {section}");
    }
    assert_eq!(json["guided"]["rows"].as_array().unwrap().len(), 2);
    assert!(!json["dgi"]["rows"].as_array().unwrap().is_empty());
    // The report's scene and the paper's city.
    assert_eq!(json["trace"].as_array().unwrap().len(), 2);
    assert!(!json["filter"]["errors"].as_array().unwrap().is_empty());

    let curves = json["convergence"].as_array().unwrap();
    assert_eq!(curves.len(), 2);
    for cv in curves {
        let fov = cv["fov_deg"].as_f64().unwrap();
        let label = format!("{fov}");
        let guided = cv["guided"].as_array().unwrap();
        let full = cv["full_frame"].as_array().unwrap();
        assert_eq!(guided.len(), 64 / 8, "{fov}°: one point every 8 iterations");
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
        // The full-frame point quoted at the guided end is the last one within the guided time.
        let at_end_ms = num(&cv["full_ms_at_guided_end"]);
        let at_end = full
            .iter()
            .find(|p| num(&p["ms"]) == at_end_ms)
            .expect("the quoted full-frame point is on the curve");
        assert!(at_end_ms <= num(&g_end["ms"]) || at_end == &full[0]);
        // Equal time is a wall-clock notion, so which full-frame point it picks varies from run
        // to run. What must hold whatever the clock said: when the guided ROI has at least twice
        // the full frame's samples per pixel (every ROI pixel is traced every guided
        // iteration), its error is lower (noise ∝ 1/√spp).
        let full_spp = at_end["iteration"].as_u64().unwrap();
        let guided_spp = g_end["iteration"].as_u64().unwrap();
        if 2 * full_spp <= guided_spp {
            let g = num(&g_end["rmse_roi"]);
            let f = num(&cv["full_rmse_roi_at_guided_end"]);
            assert!(
                g < f,
                "{fov}°: guided ROI RMSE {g} ({guided_spp} spp) not below full frame {f} ({full_spp} spp)"
            );
        }
    }
    check_paper_table(&md, &json);
    check_dgi_metrics(&md, &json);
    check_solver(&md, &json);
    let stages = check_stages(&md, &json);
    check_targets(&md, &json, &stages);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The paper's five rows exist in both files, in DESIGN.md §9's order with its figures, and our
/// values are the benchmarks' own.
fn check_paper_table(md: &str, json: &serde_json::Value) {
    let rows = json["paper"].as_array().unwrap();
    let measures: Vec<&str> = rows
        .iter()
        .map(|r| r["measure"].as_str().unwrap())
        .collect();
    assert_eq!(
        measures,
        [
            "DGI generation, 3840×2160",
            "full frame, 1 spp, Cornell box",
            "full frame, 1 spp, city (~350k triangles)",
            "10° FOV iteration, Cornell box",
            "60° FOV iteration, Cornell box",
        ]
    );
    let paper_ms = [
        [2.0, 3.0],
        [460.0, 460.0],
        [750.0, 750.0],
        [12.29, 12.29],
        [188.0, 188.0],
    ];
    let paper_mp = 3840.0 * 2160.0 / 1e6;
    let mp = 128.0 * 72.0 / 1e6;
    for (row, want) in rows.iter().zip(paper_ms) {
        let measure = row["measure"].as_str().unwrap();
        let cells = row_cells(md, "## The paper's table beside ours", measure);
        let ours = row["ours_ms"]
            .as_array()
            .unwrap_or_else(|| panic!("{measure}: not run"));
        let (lo, hi) = (num(&ours[0]), num(&ours[1]));
        assert!(lo > 0.0 && lo <= hi, "{measure}");
        for (k, &w) in want.iter().enumerate() {
            assert_eq!(num(&row["paper_ms"][k]), w, "{measure}");
            let per = num(&row["paper_ms_per_megapixel"][k]);
            assert!((per - w / paper_mp).abs() <= 1e-12 * per, "{measure}");
            let ours_per = num(&row["ours_ms_per_megapixel"][k]);
            assert!(
                (ours_per - num(&ours[k]) / mp).abs() <= 1e-9 * ours_per,
                "{measure}"
            );
        }
        // The Markdown's "ours ms" cell is the JSON's.
        let shown = if lo == hi {
            format!("{lo:.3}")
        } else {
            format!("{lo:.3}–{hi:.3}")
        };
        assert_eq!(cells[4], shown, "{measure}");
        assert_eq!(cells[7], "128×72", "{measure}");
        assert!(
            row["note"].as_str().unwrap().contains("not 3840×2160"),
            "{measure}"
        );
    }
    // Sources: the DGI range is the exact metric's CPU medians; the full frames are the trace
    // benchmark's medians; the iterations are the guided benchmark's.
    let exact: Vec<f64> = json["dgi"]["rows"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["metric"] == "exact" && r["backend"] == "cpu")
        .map(|r| num(&r["ms_median"]))
        .collect();
    assert_eq!(exact.len(), 2);
    assert_eq!(
        num(&rows[0]["ours_ms"][0]),
        exact.iter().copied().fold(f64::INFINITY, f64::min)
    );
    assert_eq!(
        num(&rows[0]["ours_ms"][1]),
        exact.iter().copied().fold(0.0, f64::max)
    );
    let trace = json["trace"].as_array().unwrap();
    for (row, key) in [(&rows[1], "cornell"), (&rows[2], "city")] {
        let t = trace
            .iter()
            .find(|t| t["scene"].as_str().unwrap().contains(key))
            .unwrap();
        assert_eq!(row["ours_ms"][0], t["ms_per_frame_median"], "{key}");
        assert_eq!(
            row["ours_ms_per_megapixel"][0], t["ms_per_megasample"],
            "{key}"
        );
    }
    let city = trace.iter().find(|t| t["scene"] == "city").unwrap();
    assert!(
        city["triangles"].as_u64().unwrap() > 300_000,
        "the paper's city is ~350k triangles"
    );
    for (row, fov) in [(&rows[3], 10.0), (&rows[4], 60.0)] {
        let g = json["guided"]["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|g| num(&g["fov_deg"]) == fov)
            .unwrap();
        assert_eq!(row["ours_ms"][0], g["ms_per_iteration"], "{fov}°");
        assert_eq!(row["ours_speedup"], g["speedup"], "{fov}°");
        let cells = row_cells(
            md,
            "## The paper's table beside ours",
            &format!("{fov}° FOV iteration, Cornell box"),
        );
        assert_eq!(cells[6], format!("{:.2}×", num(&g["speedup"])));
    }
    assert_eq!(num(&rows[3]["paper_speedup"]), 37.43);
    assert_eq!(num(&rows[4]["paper_speedup"]), 2.44);
}

/// One row per metric, FOV and backend, errors against the exact metric (0 for itself).
fn check_dgi_metrics(md: &str, json: &serde_json::Value) {
    let rows = json["dgi"]["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2 * 3, "2 FOVs × 3 metrics on the CPU");
    let section = md.split("## DGI metrics: time vs error").nth(1).unwrap();
    let section = section.split("\n## ").next().unwrap();
    for r in rows {
        // JSON spells the metric in lower case, the Markdown as the Rust variant.
        let metric = r["metric"].as_str().unwrap();
        let metric = format!("{}{}", metric[..1].to_uppercase(), &metric[1..]);
        let line = format!(
            "| {}° | {} | {} | {:.3} | {:.4} | {:.3} |",
            num(&r["fov_deg"]),
            metric,
            r["backend"].as_str().unwrap(),
            num(&r["ms_median"]),
            num(&r["err_mean_px"]),
            num(&r["err_max_px"])
        );
        assert!(section.contains(&line), "missing {line}");
        assert!(num(&r["err_mean_px"]) <= num(&r["err_max_px"]));
        if r["metric"] == "exact" {
            assert_eq!(num(&r["err_max_px"]), 0.0);
        }
    }
}

/// f64 within 1e-14 of the scale (DESIGN.md §5's bound), the f32 mirror within its stated 1e-6, on
/// the whole hard-case set; no GPU row on the CPU backend, and the Markdown says why.
fn check_solver(md: &str, json: &serde_json::Value) {
    let s = &json["solver"];
    let rows = s["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    let cases = s["cases"].as_u64().unwrap();
    assert!(cases > 1500, "{cases} hard cases");
    assert_eq!(rows[0]["solver"], "f64 CPU");
    assert_eq!(rows[0]["cases"].as_u64().unwrap(), cases);
    assert!(num(&rows[0]["max_err_of_scale"]) <= 1e-14);
    assert_eq!(rows[1]["solver"], "f32 CPU mirror");
    assert!(rows[1]["cases"].as_u64().unwrap() > 1000);
    assert!(num(&rows[1]["max_err_of_scale"]) <= 1e-6);
    for r in rows {
        let (max, mean) = (
            r["iterations_max"].as_u64().unwrap(),
            num(&r["iterations_mean"]),
        );
        assert!(mean >= 1.0 && mean <= max as f64, "{r}");
        assert!(num(&r["ns_per_solve_min"]) > 0.0);
        assert!(num(&r["ns_per_solve_min"]) <= num(&r["ns_per_solve_median"]));
        let cells = row_cells(md, "## Closest-point solver", r["solver"].as_str().unwrap());
        assert_eq!(cells[1], r["cases"].to_string());
        assert_eq!(cells[2], max.to_string());
        assert_eq!(cells[6], format!("{:.2e}", num(&r["max_err_of_scale"])));
    }
    assert!(
        s["gpu_not_run"]
            .as_str()
            .unwrap()
            .contains("no GPU adapter")
    );
    let cells = row_cells(md, "## Closest-point solver", "f32 WGSL (GPU)");
    assert!(cells[1].starts_with("not run: no GPU adapter"), "{cells:?}");
}

/// Stage times add up to their sum and fit in the iteration's wall clock. On the CPU every stage
/// is timed over a sub-interval of the iteration's own interval, and the sub-intervals are
/// disjoint, so the sum of the means cannot exceed the mean iteration: the only slack is float
/// rounding of the sums (1e-9 ms).
fn check_stages(md: &str, json: &serde_json::Value) -> Vec<serde_json::Value> {
    const SLACK_MS: f64 = 1e-9;
    let rows = json["stages"].as_array().unwrap().clone();
    assert_eq!(rows.len(), 2);
    let iterations = json["config"]["stage_iterations"].as_u64().unwrap();
    for r in &rows {
        let fov = num(&r["fov_deg"]);
        assert_eq!(r["iterations"].as_u64().unwrap(), iterations);
        let dgi = num(&r["dgi_ms_per_change"]);
        assert!(dgi > 0.0, "{fov}°: the CPU twin's DGI is timed");
        assert!((num(&r["dgi_ms_amortised"]) * iterations as f64 - dgi).abs() <= 1e-9 * dgi);
        let parts = [
            "dgi_ms_amortised",
            "schedule_ms",
            "trace_ms",
            "filter_ms",
            "display_ms",
        ];
        for p in parts {
            assert!(num(&r[p]) > 0.0, "{fov}°: {p}");
        }
        let sum: f64 = parts.iter().map(|p| num(&r[p])).sum();
        assert!((sum - num(&r["stage_sum_ms"])).abs() <= SLACK_MS, "{fov}°");
        let mean = num(&r["iteration_ms_mean"]);
        assert!(
            sum <= mean + SLACK_MS,
            "{fov}°: stages {sum} ms > iteration {mean} ms"
        );
        let (readback, transfer) = (num(&r["readback_ms"]), num(&r["filter_transfer_ms"]));
        assert!(readback > 0.0, "{fov}°: the read-back is timed");
        assert!(transfer >= 0.0, "{fov}°");
        assert!(
            sum + readback + transfer <= mean + SLACK_MS,
            "{fov}°: stages and transfers {} ms > iteration {mean} ms",
            sum + readback + transfer
        );
        assert!((num(&r["other_ms"]) - (mean - sum - readback - transfer)).abs() <= SLACK_MS);
        assert!(num(&r["iteration_ms_min"]) <= num(&r["iteration_ms_median"]));
        let target = dgi + num(&r["schedule_ms"]) + num(&r["trace_ms"]) + num(&r["filter_ms"]);
        assert!((num(&r["target_iteration_ms"]) - target).abs() <= SLACK_MS);
        let cells = row_cells(md, "## Per-stage times per iteration", &format!("{fov}°"));
        assert_eq!(cells[10], format!("{:.3}", num(&r["stage_sum_ms"])));
        assert_eq!(cells[13], format!("{:.3}", num(&r["target_iteration_ms"])));
        assert_eq!(cells[14], format!("{:.3}", readback));
        assert_eq!(cells[15], format!("{:.3}", transfer));
    }
    // The 60° ROI samples a larger share of the image than the 10° one.
    assert!(num(&rows[0]["share_sampled"]) < num(&rows[1]["share_sampled"]));
    rows
}

/// Three targets, their figures taken from the convergence and per-stage sections (the
/// iteration on the stages' own times and on the wall clock), not judged on the CPU twins.
fn check_targets(md: &str, json: &serde_json::Value, stages: &[serde_json::Value]) {
    let t = json["targets"].as_array().unwrap();
    assert_eq!(t.len(), 3);
    let cv10 = json["convergence"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| num(&c["fov_deg"]) == 10.0)
        .unwrap();
    let speedup = if cv10["speedup_to_target"].is_null() {
        &cv10["extrapolated_speedup_to_target"]
    } else {
        &cv10["speedup_to_target"]
    };
    assert_eq!(&t[0]["measured"], speedup);
    assert_eq!(t[1]["measured"], stages[0]["target_iteration_ms"]);
    // On the CPU twins the window's picture is the host's: the 10° row's wall clock.
    assert_eq!(stages[0]["picture"], "host");
    assert_eq!(num(&stages[0]["fov_deg"]), 10.0);
    assert_eq!(t[2]["measured"], stages[0]["iteration_ms_median"]);
    assert!(t[2]["note"].as_str().unwrap().contains("host picture row"));
    for row in t {
        assert_eq!(row["status"], "not_measured");
        assert!(
            row["note"]
                .as_str()
                .unwrap()
                .contains("not a datacenter GPU")
        );
    }
    let section = md.split("## Targets").nth(1).unwrap();
    let section = section.split("\n## ").next().unwrap();
    assert_eq!(section.matches("| not measured |").count(), 3);
    assert!(section.contains(&format!("{:.3} ms", num(&t[1]["measured"]))));
    assert!(section.contains(&format!("{:.3} ms", num(&t[2]["measured"]))));
}

/// The WGSL solver through the benchmark's GPU wrapper (lavapipe in CI): every case it runs
/// meets the f32 bound within the f32 iteration cap, and it reports its case count and times.
#[test]
fn solver_bench_runs_the_wgsl_on_the_gpu() {
    use raygun::roi::ellipse::{F32_DISTANCE_BOUND, MAX_ITERATIONS_F32};
    let backend = raygun::gpu::Backend::Gpu(Box::new(raygun::gpu::GpuContext::for_tests()));
    let report = raygun::bench::solver::run(&backend, 2, |_| {}).unwrap();
    assert!(report.gpu_not_run.is_none());
    assert_eq!(report.rows.len(), 3);
    let gpu = &report.rows[2];
    assert_eq!(gpu.solver, "f32 WGSL (GPU)");
    assert!(gpu.cases > 1000, "only {} GPU cases", gpu.cases);
    assert!(
        gpu.cases <= report.rows[1].cases,
        "a subset of the f32 cases"
    );
    assert!(
        gpu.max_err_of_scale <= F32_DISTANCE_BOUND,
        "{}",
        gpu.max_err_of_scale
    );
    assert!(gpu.iterations_max <= MAX_ITERATIONS_F32);
    assert!(gpu.iterations_mean >= 1.0);
    assert!(gpu.ns_per_solve_min > 0.0 && gpu.ns_per_solve_min <= gpu.ns_per_solve_median);
    let md = raygun::bench::solver::markdown(&report);
    assert!(md.contains("| f32 WGSL (GPU)"));
    assert!(!md.contains("not run"));
}

/// Per-stage times on the GPU backend (lavapipe, a tiny image), the three ways a picture is made:
/// every stage is timed, and the stages fit in the iteration's wall clock. GPU timestamps and the CPU clock are different
/// clocks, so the sum may exceed the wall clock by the timestamp period's calibration error:
/// 1 % plus 0.05 ms is allowed.
#[test]
fn stage_times_on_the_gpu_fit_in_the_iteration() {
    use raygun::bench::all::stages::PicturePath;
    let backend = raygun::gpu::Backend::Gpu(Box::new(raygun::gpu::GpuContext::for_tests()));
    let display = raygun::display::DisplayModel::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/display-models/hornet.json"
    ))
    .unwrap();
    let scene = raygun::scene::Scene::open("builtin:cornell").unwrap();
    let filter = raygun::filter::FilterParams {
        kind: raygun::filter::FilterKind::Fast,
        k_max: 1.0,
        ..Default::default()
    };
    for path in [PicturePath::Host, PicturePath::Gpu, PicturePath::Texture] {
        let subject = raygun::bench::paper::Subject {
            backend: &backend,
            display: &display,
            name: "cornell",
            scene: &scene,
        };
        let shot = raygun::bench::paper::Shot {
            size: [48, 27],
            fov: 60.0,
            iterations: 3,
            seed: 1,
        };
        let r = raygun::bench::all::stages::measure(&subject, shot, &filter, 0.0, path).unwrap();
        assert_eq!(r.picture, path, "a one-band frame takes the way asked for");
        assert_eq!(r.iterations, 3);
        assert!(r.share_sampled > 0.0 && r.share_sampled < 1.0);
        for (what, v) in [
            ("filter", r.filter_ms),
            ("display", r.display_ms),
            ("trace", r.trace_ms),
        ] {
            assert!(v > 0.0, "{path:?}: {what}");
        }
        // Kept on the GPU, nothing but the 8-bit picture is read back (and into a texture,
        // not even that).
        assert_eq!(r.readback_ms == 0.0, path != PicturePath::Host, "{path:?}");
        if r.gpu_timestamps {
            assert!(r.dgi_ms_per_change.is_some_and(|v| v > 0.0));
            assert!(r.schedule_ms > 0.0);
        }
        assert!(
            r.stage_sum_ms <= r.iteration_ms_mean * 1.01 + 0.05,
            "{path:?}: stages {} ms > iteration {} ms",
            r.stage_sum_ms,
            r.iteration_ms_mean
        );
    }
}
