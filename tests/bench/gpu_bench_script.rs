//! `tools/gpu-bench.sh smoke`: the one-call GPU benchmark script, run here on lavapipe at tiny
//! sizes with the test build. What comes back from a GPU machine is at most 8 files, so the
//! script must leave exactly its summary and one tarball, and the tarball must hold every
//! group's log and tables. The groups that time the trace kernel's variants run where the test
//! build has the kernel lab (`--features kernel-lab`); without it the script says they need it.

use std::path::Path;
use std::process::Command;

const GROUPS: [&str; 18] = [
    "adapter",
    "picture",
    "dgi",
    "schedule",
    "trace",
    "kernels",
    "kernels-guided",
    "guided",
    "native",
    "filter",
    "denoise",
    "motion",
    "all-quick",
    "wall",
    "cluster",
    "sizes",
    "readback",
    "all",
];

/// The groups that need a binary with the kernel lab.
const KERNEL_LAB_GROUPS: [&str; 2] = ["kernels", "kernels-guided"];

fn smoke(out: &Path, limit_s: Option<u32>) -> std::process::Output {
    smoke_groups(out, limit_s, None)
}

fn smoke_groups(out: &Path, limit_s: Option<u32>, groups: Option<&str>) -> std::process::Output {
    let mut c = Command::new("bash");
    c.args(["tools/gpu-bench.sh", "smoke"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("OUT", out)
        .env("RAYGUN_BIN", env!("CARGO_BIN_EXE_raygun"))
        .env("XDG_RUNTIME_DIR", std::env::temp_dir());
    match limit_s {
        Some(l) => c.env("GPU_BENCH_LIMIT_S", l.to_string()),
        // Room for a machine whose two cores other builds share: a group stopped by its
        // budget would fail the run's "ok" rows for a reason that is not the script's.
        None => c.env("GPU_BENCH_BUDGET_SCALE", "4"),
    };
    if let Some(g) = groups {
        c.env("GPU_BENCH_GROUPS", g);
    }
    c.output().unwrap()
}

fn fresh(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("raygun-gpu-bench-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn the_smoke_run_leaves_a_summary_and_a_tarball_that_names_every_group() {
    let out = fresh("smoke");
    let o = smoke(&out, None);
    let log = String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{log}");
    let mut files: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert_eq!(files, ["gpu-bench.tar.gz", "summary.md"]);
    let unpacked = out.join("unpacked");
    std::fs::create_dir_all(&unpacked).unwrap();
    let st = Command::new("tar")
        .args(["-xzf"])
        .arg(out.join("gpu-bench.tar.gz"))
        .arg("-C")
        .arg(&unpacked)
        .status()
        .unwrap();
    assert!(st.success());
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(
        summary.contains("llvmpipe"),
        "the adapter is named:\n{summary}"
    );
    for g in GROUPS {
        assert!(
            unpacked.join(g).join(format!("{g}.log")).exists(),
            "{g}: no log"
        );
        let row = summary
            .lines()
            .find(|l| l.starts_with(&format!("| {g} |")))
            .unwrap_or_else(|| panic!("{g} missing from the summary:\n{summary}"));
        // Every group this build has ran to completion; the wall camera may not exist yet; a
        // build without the kernel lab says which groups need it and how to get it.
        if KERNEL_LAB_GROUPS.contains(&g) && !cfg!(feature = "kernel-lab") {
            assert!(
                row.contains("not in this build") && row.contains("kernel-lab feature"),
                "{row}"
            );
            assert!(row.contains("tools/gpu-bench.sh stage"), "{row}");
            continue;
        }
        assert!(
            row.contains("| ok |") || (g == "wall" && row.contains("not in this build")),
            "{row}"
        );
    }
    for table in [
        "dgi/dgi.md",
        "schedule/schedule.md",
        "trace/trace.md",
        "guided/guided.md",
        "native/native.md",
        "filter/filter.md",
        "all/report.md",
        "all-quick/report.md",
        "adapter/adapter.json",
        "cluster/cluster.md",
        "sizes/trace-16x9.md",
        "sizes/trace-8x4.md",
        "readback/readback.md",
        "picture/picture.md",
    ] {
        let p = unpacked.join(table);
        assert!(
            std::fs::metadata(&p).is_ok_and(|m| m.len() > 0),
            "{table} missing or empty"
        );
    }
    assert!(unpacked.join("guided/fig5.png").exists());
    if cfg!(feature = "kernel-lab") {
        kernel_lab_tables(&unpacked);
    } else {
        assert!(!unpacked.join("kernels/kernels.md").exists());
    }
    std::fs::remove_dir_all(&out).ok();
}

/// The tables of the groups that time the trace kernel's variants (a kernel-lab build).
fn kernel_lab_tables(unpacked: &Path) {
    for table in [
        "kernels/kernels.md",
        "kernels/kernels-city.md",
        "kernels-guided/guided-private+regen4.md",
    ] {
        let p = unpacked.join(table);
        assert!(
            std::fs::metadata(&p).is_ok_and(|m| m.len() > 0),
            "{table} missing or empty"
        );
    }
    // Each guided run names the kernel it ran (the default says nothing).
    let regen = unpacked.join("kernels-guided/guided-private+regen4.md");
    let regen = std::fs::read_to_string(regen).unwrap();
    assert!(regen.contains("trace kernel private+regen4"), "{regen}");
    let kernels = std::fs::read_to_string(unpacked.join("kernels/kernels.md")).unwrap();
    for variant in [
        "| private |",
        "| workgroup+unchecked+wg32 |",
        "| private+regen264 |",
        "÷ private",
        // lavapipe's 32 KiB of workgroup memory: named, not run, and the group still ends well.
        "Not run on this adapter: trace kernel workgroup+unchecked+wg128",
    ] {
        assert!(kernels.contains(variant), "{variant}:\n{kernels}");
    }
}

#[test]
fn groups_that_would_overrun_the_budget_are_skipped_and_said_so() {
    let out = fresh("budget");
    // 25 s: the first groups fit, the full report's 60 s budget does not.
    let o = smoke(&out, Some(25));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    let row = |g: &str| {
        summary
            .lines()
            .find(|l| l.starts_with(&format!("| {g} |")))
            .unwrap()
            .to_owned()
    };
    assert!(row("adapter").contains("| ok |"), "{summary}");
    assert!(row("all").contains("skipped"), "{}", row("all"));
    assert!(row("all").contains("budget"), "{}", row("all"));
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn a_rerun_runs_only_the_groups_named_in_the_scripts_order() {
    let out = fresh("subset");
    // Named twice, run once.
    let o = smoke_groups(&out, None, Some("guided adapter guided"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    let rows: Vec<&str> = summary
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| group"))
        .filter(|l| GROUPS.iter().any(|g| l.starts_with(&format!("| {g} |"))))
        .collect();
    assert_eq!(rows.len(), 2, "{summary}");
    assert!(rows[0].starts_with("| adapter | ok |"), "{summary}");
    assert!(rows[1].starts_with("| guided | ok |"), "{summary}");
    std::fs::remove_dir_all(&out).ok();

    // A name that is no group stops the script before any work, naming it.
    let out = fresh("subset-bad");
    let o = smoke_groups(&out, None, Some("adapter trace-sizes"));
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("'trace-sizes'"), "{err}");
    assert!(!out.join("summary.md").exists());
    std::fs::remove_dir_all(&out).ok();
}
