//! `raygun bench motion` end to end, tiny, on the CPU twins: every walk, policy and FOV has its
//! series, reuse carries most of the picture at each move and keeps the ROI's error below
//! restart's over the walk, the step recovers sooner with reuse, and the plot and tables are
//! written whole.

use crate::support;
use support::{fails_with, ok, raygun, s, tmp_dir};

#[test]
fn bench_motion_measures_both_policies_on_both_walks() {
    let dir = tmp_dir("bench-motion");
    let (json, plot, md) = (
        dir.join("motion.json"),
        dir.join("motion.svg"),
        dir.join("motion.md"),
    );
    let o = raygun(&[
        "bench",
        "motion",
        "--scene",
        "builtin:cornell",
        "--size",
        "62,25",
        "--fov",
        "60",
        "--fps",
        "1",
        "--every",
        "4",
        "--reference-spp",
        "32",
        "--max-depth",
        "2",
        "--backend",
        "cpu",
        "--json",
        s(&json),
        "--plot",
        s(&plot),
        "--out",
        s(&md),
    ]);
    ok(&o);
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let rep = &v[0];
    assert_eq!(rep["scene"], "cornell");
    let series = rep["series"].as_array().unwrap();
    // One FOV × 2 policies × 2 walks.
    assert_eq!(series.len(), 4);
    let get = |walk: &str, policy: &str| {
        series
            .iter()
            .find(|x| x["walk"] == walk && x["policy"] == policy)
            .unwrap_or_else(|| panic!("{walk} {policy}"))
    };
    for walk in ["head walk", "sway"] {
        let (a, b) = (get(walk, "reuse"), get(walk, "restart"));
        assert!(a["moves"].as_u64().unwrap() > 0, "{a}");
        assert_eq!(a["moves"], b["moves"], "the same moves either way");
        // 20 s at 1 iteration a second, compared every 4.
        assert_eq!(a["points"].as_array().unwrap().len(), 5);
        assert!(a["mean_share_carried"].as_f64().unwrap() > 0.5, "{a}");
        assert_eq!(b["mean_share_carried"], 0.0);
    }
    let steps = rep["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 2);
    let after = |p: &str| {
        steps.iter().find(|x| x["policy"] == p).unwrap()["after"]
            .as_f64()
            .unwrap()
    };
    assert!(after("reuse") < after("restart"), "{steps:?}");
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert_eq!(svg.matches("<polyline").count(), 2);
    let table = std::fs::read_to_string(&md).unwrap();
    assert!(table.contains("| cornell | 60° | head walk |"), "{table}");
}

#[test]
fn bench_motion_names_bad_numbers_and_a_replay_without_a_head() {
    let o = raygun(&["bench", "motion", "--every", "0", "--backend", "cpu"]);
    fails_with(&o, &["--every 0"]);
    let o = raygun(&[
        "bench",
        "motion",
        "--replay",
        "tracking-replays/flystick-1-centre-sweeps.dtrack.jsonl",
        "--backend",
        "cpu",
    ]);
    fails_with(&o, &["names no tracked head"]);
}
