//! `bench denoise`'s targets and Markdown report ([`super`]).

use super::{DenoiseBenchReport, ErrorRow, SizeTiming, Targets};

fn figure(errors: &[ErrorRow], fov: f64, n: u32, method: &str, region: &str) -> Option<f64> {
    errors
        .iter()
        .find(|e| e.fov_deg == fov && e.iterations == n && e.method == method && e.region == region)
        .map(|e| e.rel_mse)
}

/// The worst ratios over the measured pictures and sizes (NaN-free: a region without pixels
/// is left out).
pub(super) fn targets(errors: &[ErrorRow], timings: &[SizeTiming]) -> Targets {
    let (mut vs_off, mut vs_oidn, mut roi) = (0f64, None::<f64>, 0f64);
    for e in errors.iter().filter(|e| e.method == "interactive") {
        let (fov, n) = (e.fov_deg, e.iterations);
        let ratio = |other: &str| {
            figure(errors, fov, n, other, e.region)
                .map(|o| e.rel_mse / o)
                .filter(|r| r.is_finite())
        };
        match e.region {
            "periphery" => {
                if let Some(r) = ratio("off") {
                    vs_off = vs_off.max(r);
                }
                if let Some(r) = ratio("oidn") {
                    vs_oidn = Some(vs_oidn.map_or(r, |v| v.max(r)));
                }
            }
            _ => {
                if let Some(r) = ratio("off") {
                    roi = roi.max(r);
                }
            }
        }
    }
    let time = timings
        .iter()
        .filter_map(|t| t.interactive_cpu_over_oidn)
        .reduce(f64::max);
    Targets {
        periphery_interactive_over_off: vs_off,
        periphery_interactive_over_off_met: vs_off <= 0.5,
        periphery_interactive_over_oidn: vs_oidn,
        periphery_interactive_over_oidn_met: vs_oidn.map(|v| v <= 1.5),
        time_interactive_cpu_over_oidn: time,
        time_interactive_cpu_over_oidn_met: time.map(|v| v <= 0.1),
        roi_interactive_over_off: roi,
        roi_interactive_over_off_met: roi <= 1.0,
    }
}

fn cell(v: Option<f64>, digits: usize) -> String {
    v.filter(|v| v.is_finite())
        .map_or("–".into(), |v| format!("{v:.digits$}"))
}

/// The report as Markdown: the errors at equal iterations and at equal time, the timings and
/// the targets.
#[must_use]
pub fn markdown(r: &DenoiseBenchReport) -> String {
    let c = &r.config;
    let mut s = format!(
        "Device: {}\nOIDN: {}\n\nSetup: {}, {}×{}, guided (paper's setup, p_min 0), reference {} spp ({:.0} ms); features {:.1} ms once per view.\n\n",
        r.device,
        r.oidn,
        c.scene,
        c.size[0],
        c.size[1],
        c.reference_spp,
        r.reference_ms,
        r.features_ms
    );
    s += "Equal iterations (relMSE; ꟻLIP):\n\n| FOV | iterations | method | render ms | method ms | relMSE ROI | relMSE periphery | FLIP ROI | FLIP periphery |\n|---|---|---|---|---|---|---|---|---|\n";
    for t in &r.times {
        let get = |region: &str| {
            r.errors.iter().find(|e| {
                e.fov_deg == t.fov_deg
                    && e.iterations == t.iterations
                    && e.method == t.method
                    && e.region == region
            })
        };
        let (roi, per) = (get("roi"), get("periphery"));
        let ms = match t.ms_cpu_twin {
            Some(twin) => format!("{} (CPU twin {twin:.2})", cell(Some(t.ms), 2)),
            None => cell(Some(t.ms), 2),
        };
        s += &format!(
            "| {}° | {} | {} | {:.1} | {} | {} | {} | {} | {} |\n",
            t.fov_deg,
            t.iterations,
            t.method,
            t.render_ms,
            ms,
            cell(roi.map(|e| e.rel_mse), 4),
            cell(per.map(|e| e.rel_mse), 4),
            cell(roi.map(|e| e.flip), 4),
            cell(per.map(|e| e.flip), 4),
        );
    }
    s += "\nEqual time (each method at the largest listed iteration count whose render, method and feature time fits the render's time up to the budget's count):\n\n| FOV | budget (iterations, ms) | method | iterations | cost ms | relMSE ROI | relMSE periphery | FLIP ROI | FLIP periphery |\n|---|---|---|---|---|---|---|---|---|\n";
    for e in &r.equal_time {
        s += &format!(
            "| {}° | {}, {:.1} | {} | {} | {} | {} | {} | {} | {} |\n",
            e.fov_deg,
            e.budget_iterations,
            e.budget_ms,
            e.method,
            e.iterations.map_or("–".into(), |n| n.to_string()),
            cell(e.cost_ms, 1),
            cell(e.rel_mse_roi, 4),
            cell(e.rel_mse_periphery, 4),
            cell(e.flip_roi, 4),
            cell(e.flip_periphery, 4),
        );
    }
    s += "\nTime per picture (synthetic scene, median):\n\n| size | interactive CPU twin ms | interactive GPU ms | OIDN ms | CPU twin ÷ OIDN | GPU ÷ OIDN |\n|---|---|---|---|---|---|\n";
    for t in &r.timings {
        s += &format!(
            "| {}×{} | {:.1} | {} | {} | {} | {} |\n",
            t.width,
            t.height,
            t.interactive_cpu_ms,
            cell(t.interactive_gpu_ms, 2),
            cell(t.oidn_ms, 1),
            cell(t.interactive_cpu_over_oidn, 3),
            cell(t.interactive_gpu_over_oidn, 3),
        );
    }
    let t = &r.targets;
    let met = |m: Option<bool>| match m {
        Some(true) => "met",
        Some(false) => "missed",
        None => "not measured",
    };
    s += &format!(
        "\nTargets (worst case over the pictures and sizes):\n\n* periphery relMSE interactive ÷ off ≤ 0.5: {:.3} ({})\n* periphery relMSE interactive ÷ OIDN ≤ 1.5: {} ({})\n* time interactive (CPU twin) ÷ OIDN (CPU) ≤ 0.1: {} ({})\n* ROI relMSE interactive ÷ off ≤ 1: {:.3} ({})\n",
        t.periphery_interactive_over_off,
        met(Some(t.periphery_interactive_over_off_met)),
        cell(t.periphery_interactive_over_oidn, 3),
        met(t.periphery_interactive_over_oidn_met),
        cell(t.time_interactive_cpu_over_oidn, 3),
        met(t.time_interactive_cpu_over_oidn_met),
        t.roi_interactive_over_off,
        met(Some(t.roi_interactive_over_off_met)),
    );
    if let Some(c) = &r.crops {
        s += &format!(
            "\nCrops: {} ({}×{}; {}° at {} iterations; rows: ROI edge at {:?}, periphery at {:?}).\n",
            c.path, c.width, c.height, c.fov_deg, c.iterations, c.roi_edge_at, c.periphery_at
        );
    }
    s
}
