//! `raygun bench filter` end to end, small, on the CPU twins.

use crate::support;
use support::raygun;

#[test]
fn bench_filter_json_has_every_timing_and_variant_and_filtering_helps_in_the_band() {
    let o = raygun(&[
        "bench",
        "filter",
        "--size",
        "96,54",
        "--fov",
        "60",
        "--time-k-max",
        "8,16",
        "--reps",
        "1",
        "--backend",
        "cpu",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["timings"].as_array().unwrap().len(), 4);
    let errors = v["errors"].as_array().unwrap();
    let variants: Vec<&str> = errors
        .iter()
        .map(|e| e["variant"].as_str().unwrap())
        .collect();
    assert_eq!(
        variants,
        ["unfiltered", "paper (exact)", "fast", "variance (fast)"]
    );
    // In the falloff band, unsampled pixels make the unfiltered image darker than the
    // reference; the paper's filter repairs most of that brightness error.
    let band = |i: usize| errors[i]["brightness_err_band"].as_f64().unwrap();
    assert!(band(0) < -0.02, "unfiltered band brightness {}", band(0));
    assert!(
        band(1).abs() < band(0).abs() / 2.0,
        "paper {} vs unfiltered {}",
        band(1),
        band(0)
    );
    assert!(v["input"].as_str().unwrap().starts_with("synthetic"));
}

#[test]
fn bad_filter_flags_are_rejected_with_the_flag_named() {
    let o = raygun(&["bench", "filter", "--size", "8,8", "--k-max", "80"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--k-max"), "{err}");
}
