//! `report.md`: the run's figures as Markdown tables.

use super::AllReport;
use super::convergence::{TARGET_REL_RMSE, TimeToTarget};
use super::plots::equal_time_point;
use super::stages;
use super::tables::{PaperRow, TargetRow, TargetStatus};
use crate::bench::dgi::DgiBenchReport;
use crate::bench::guided;
use crate::bench::solver;
use crate::bench::trace;

fn fmt_ttt(t: &TimeToTarget) -> String {
    if t.reached {
        format!("{:.1} ms (RMSE {:.4})", t.ms, t.rmse_roi)
    } else {
        format!(
            "not reached (closest: RMSE {:.4} at {:.1} ms; extrapolated {} ms)",
            t.rmse_roi,
            t.ms,
            t.extrapolated_ms.map_or("–".into(), |x| format!("{x:.0}"))
        )
    }
}

/// The report as Markdown: header, settings, each benchmark's own tables and the convergence
/// figures.
#[must_use]
pub fn markdown(r: &AllReport) -> String {
    let h = &r.header;
    let c = &r.config;
    let mut s = format!(
        "# raygun benchmark report\n\n- Command: `{}`\n- Commit: {}{}\n- Build: {}\n- Date: {} (UTC)\n- Device: {}\n- Adapter: {}\n- CPU: {}\n- Scene: {}; display: {}\n- Mode: {}\n- Settings: {}×{}, FOVs {:?}°, {} guided iterations, reference {} spp, curve point every {} iterations, {} trace frames{}, DGI reps {} GPU / {} CPU, filter reps {}, filter {:?} k_max {:.2} c {}, solver reps {}, per-stage iterations {}, seed {}\n\n",
        h.command,
        h.commit,
        if h.dirty {
            " (working tree modified)"
        } else {
            ""
        },
        h.profile,
        h.date,
        h.device,
        h.adapter.as_deref().unwrap_or("none (CPU twins)"),
        h.cpu,
        h.scene,
        h.display,
        if c.quick { "quick" } else { "full" },
        c.size[0],
        c.size[1],
        c.fovs_deg,
        c.iterations,
        c.reference_spp,
        c.sample_every,
        c.trace_frames,
        if c.city { " (plus builtin:city)" } else { "" },
        c.dgi_gpu_reps,
        c.dgi_cpu_reps,
        c.filter_reps,
        c.filter.kind,
        c.filter.k_max,
        c.filter.c,
        c.solver_reps,
        c.stage_iterations,
        c.seed,
    );
    s += &paper_markdown(&r.paper);
    s += "\n## Targets\n\n";
    s += &targets_markdown(&r.targets);
    s += "\n";
    s += "## DGI\n\n";
    s += &r.dgi.to_markdown();
    s += "\n\n## DGI metrics: time vs error\n\n![DGI metrics](dgi_metrics.png)\n\n";
    s += &dgi_metrics_markdown(&r.dgi);
    s += "\n## Closest-point solver\n\n";
    s += &solver::markdown(&r.solver);
    s += "\n\n## Full-frame path tracing\n\n";
    s += &trace::markdown(&r.trace, &h.device);
    s += "\n\n## Guided vs full frame (the paper's benchmark)\n\n![Figure 5](fig5.png)\n\n";
    s += &guided::markdown(&r.guided);
    s += "\n\n## Filter\n\n";
    s += &r.filter.to_markdown();
    s += &format!(
        "\n\n## Convergence\n\n![convergence](convergence.png)\n\nRMSE (linear RGB) against a converged reference ({} spp full frame) versus accumulated frame time (RMSE and read-backs excluded); filtered = the fast filter's CPU twin. Target: ROI RMSE ≤ {} % of the reference's mean in the ROI; where a curve did not reach it, the time is extrapolated with RMSE ∝ 1/√t through its last point (not measured).\n\n| FOV | ROI px | target RMSE | guided: time to target | full frame: time to target | speed-up to target | guided end ms | guided ROI RMSE at end | full-frame ROI RMSE at equal time (ms) | guided outside RMSE at end (unfiltered / filtered) | full-frame outside RMSE at equal time (unfiltered / filtered) |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
        c.reference_spp,
        100.0 * TARGET_REL_RMSE
    );
    for cv in &r.convergence {
        let (Some(g), Some(f)) = (cv.guided.last(), equal_time_point(cv)) else {
            continue;
        };
        s += &format!(
            "| {}° | {} | {:.4} | {} | {} | {} | {:.1} | {:.4} | {:.4} ({:.1}) | {:.4} / {:.4} | {:.4} / {:.4} |\n",
            cv.fov_deg,
            cv.roi_pixels,
            cv.target_rmse_roi,
            fmt_ttt(&cv.guided_time_to_target),
            fmt_ttt(&cv.full_time_to_target),
            match (cv.speedup_to_target, cv.extrapolated_speedup_to_target) {
                (Some(x), _) => format!("{x:.2}×"),
                (None, Some(x)) => format!("{x:.2}× (extrapolated)"),
                (None, None) => "–".into(),
            },
            g.ms,
            g.rmse_roi,
            cv.full_rmse_roi_at_guided_end,
            cv.full_ms_at_guided_end,
            g.rmse_outside,
            g.rmse_outside_filtered,
            f.rmse_outside,
            f.rmse_outside_filtered,
        );
    }
    s += "\n## Per-stage times per iteration\n\n";
    s += &stages::markdown(&r.stages, &h.device);
    s
}

fn fmt_range(v: [f64; 2], digits: usize) -> String {
    if v[0] == v[1] {
        format!("{:.*}", digits, v[0])
    } else {
        format!("{:.*}–{:.*}", digits, v[0], digits, v[1])
    }
}

/// The paper's table with ours beside it.
#[must_use]
pub fn paper_markdown(rows: &[PaperRow]) -> String {
    let mut s = String::from(
        "## The paper's table beside ours\n\nThe paper (Roth et al., ISVC 2015): HORNET, viewer 1 m in front of the wall centre, 3840×2160, GTX 980 with OptiX. Per megapixel = ms ÷ the image's megapixels (for a 1-spp full frame the paper's ms per megasample); where our size is not 3840×2160 it is the comparable figure, and nothing is scaled. Speed-up = full frame ÷ guided iteration on the same device.\n\n| measure | paper ms | paper ms/megapixel | paper speed-up | ours ms | ours ms/megapixel | ours speed-up | our size | our device | note |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let sp = |v: Option<f64>| v.map_or("–".into(), |v| format!("{v:.2}×"));
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {}×{} | {} | {} |\n",
            r.measure,
            fmt_range(r.paper_ms, 2),
            fmt_range(r.paper_ms_per_megapixel, 3),
            sp(r.paper_speedup),
            r.ours_ms.map_or("not run".into(), |v| fmt_range(v, 3)),
            r.ours_ms_per_megapixel
                .map_or("–".into(), |v| fmt_range(v, 3)),
            sp(r.ours_speedup),
            r.ours_size[0],
            r.ours_size[1],
            r.ours_device,
            r.note,
        );
    }
    s
}

/// The targets table.
#[must_use]
pub fn targets_markdown(rows: &[TargetRow]) -> String {
    let mut s = String::from("| target | measured | status | note |\n|---|---|---|---|\n");
    for t in rows {
        s += &format!(
            "| {} | {} | {} | {} |\n",
            t.target,
            t.measured
                .map_or("not run".into(), |v| format!("{v:.3} {}", t.unit)),
            match t.status {
                TargetStatus::Met => "**met**",
                TargetStatus::Missed => "**missed**",
                TargetStatus::NotMeasured => "not measured",
            },
            t.note
        );
    }
    s
}

/// The DGI metrics' time against their error (the plot's points as a table).
#[must_use]
pub fn dgi_metrics_markdown(r: &DgiBenchReport) -> String {
    let mut s = String::from(
        "Each cheaper metric's raw distance against the exact metric's (f64, canvas px) over the pixels the falloff reaches; time = median DGI time on each backend.\n\n| FOV | metric | backend | ms (median) | mean error px | max error px |\n|---|---|---|---|---|---|\n",
    );
    for d in &r.rows {
        s += &format!(
            "| {}° | {:?} | {} | {:.3} | {:.4} | {:.3} |\n",
            d.fov_deg, d.metric, d.backend, d.ms_median, d.err_mean_px, d.err_max_px
        );
    }
    s
}
