//! The paper's table (DESIGN.md §9) and the targets (DESIGN.md §15) beside this run's figures.

use serde::Serialize;

use super::AllReport;
use super::stages::PicturePath;

/// The paper's image size, at which its figures were measured.
pub const PAPER_SIZE: [u32; 2] = [3840, 2160];

/// One row of the paper's table (DESIGN.md §9) and ours. Times are ms; a range is `[low, high]`
/// (equal bounds for a single figure). "Per megapixel" divides by the image's megapixels: for a
/// full frame at one sample per pixel that is the paper's ms per megasample, and it is the
/// figure to compare where our run is not at 3840×2160 (nothing is scaled).
#[derive(Clone, Debug, Serialize)]
pub struct PaperRow {
    pub measure: String,
    pub paper_ms: [f64; 2],
    pub paper_ms_per_megapixel: [f64; 2],
    pub paper_speedup: Option<f64>,
    pub ours_ms: Option<[f64; 2]>,
    pub ours_ms_per_megapixel: Option<[f64; 2]>,
    pub ours_speedup: Option<f64>,
    pub ours_size: [u32; 2],
    pub ours_device: String,
    /// Where ours comes from, or why it is missing.
    pub note: String,
}

/// Whether a target was met.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TargetStatus {
    Met,
    Missed,
    NotMeasured,
}

/// One of raygun's targets.
#[derive(Clone, Debug, Serialize)]
pub struct TargetRow {
    pub target: String,
    /// Our figure on this run's device and size (None: not run).
    pub measured: Option<f64>,
    pub unit: String,
    pub status: TargetStatus,
    /// What the figure is, and why the status is what it is.
    pub note: String,
}

pub(super) fn megapixels(size: [u32; 2]) -> f64 {
    f64::from(size[0]) * f64::from(size[1]) / 1e6
}

pub(super) fn same(v: f64) -> [f64; 2] {
    [v, v]
}

/// DESIGN.md §9's rows with ours beside them.
#[must_use]
pub fn paper_rows(r: &AllReport) -> Vec<PaperRow> {
    let size = r.config.size;
    let mp = megapixels(size);
    let paper_mp = megapixels(PAPER_SIZE);
    let size_note = if size == PAPER_SIZE {
        String::new()
    } else {
        format!(
            "; ours at {}×{}, not 3840×2160: compare per megapixel (nothing scaled)",
            size[0], size[1]
        )
    };
    let mut rows = Vec::new();
    // DGI: the exact metric on the GPU when there is one, else on the CPU twin; min–max over FOVs.
    let backend = if r.dgi.adapter.is_some() {
        "gpu"
    } else {
        "cpu"
    };
    let dgi_ms: Vec<f64> = r
        .dgi
        .rows
        .iter()
        .filter(|d| d.metric == crate::roi::dgi::Metric::Exact && d.backend == backend)
        .map(|d| d.ms_median)
        .collect();
    let dgi_range = (!dgi_ms.is_empty()).then(|| {
        [
            dgi_ms.iter().copied().fold(f64::INFINITY, f64::min),
            dgi_ms.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ]
    });
    rows.push(PaperRow {
        measure: "DGI generation, 3840×2160".into(),
        paper_ms: [2.0, 3.0],
        paper_ms_per_megapixel: [2.0 / paper_mp, 3.0 / paper_mp],
        paper_speedup: None,
        ours_ms: dgi_range,
        ours_ms_per_megapixel: dgi_range.map(|[a, b]| [a / mp, b / mp]),
        ours_speedup: None,
        ours_size: size,
        ours_device: match (&r.dgi.adapter, backend) {
            (Some(a), "gpu") => a.clone(),
            _ => format!("CPU twin (f64), {}", r.dgi.cpu),
        },
        note: format!(
            "exact metric, median per FOV, min–max over FOVs {:?}°{size_note}",
            r.config.fovs_deg
        ),
    });
    for (label, key, paper) in [
        ("full frame, 1 spp, Cornell box", "cornell", 460.0),
        ("full frame, 1 spp, city (~350k triangles)", "city", 750.0),
    ] {
        let row = r.trace.iter().find(|t| t.scene.contains(key));
        rows.push(PaperRow {
            measure: label.into(),
            paper_ms: same(paper),
            paper_ms_per_megapixel: same(paper / paper_mp),
            paper_speedup: None,
            ours_ms: row.map(|t| same(t.ms_per_frame_median)),
            ours_ms_per_megapixel: row.map(|t| same(t.ms_per_megasample)),
            ours_speedup: None,
            ours_size: size,
            ours_device: r.header.device.clone(),
            note: match row {
                Some(t) => format!(
                    "scene '{}' ({} triangles), median of {} frames{size_note}",
                    t.scene, t.triangles, r.config.trace_frames
                ),
                None => format!("not run: no '{key}' scene in this report"),
            },
        });
    }
    for (fov, paper, speedup) in [(10.0, 12.29, 37.43), (60.0, 188.0, 2.44)] {
        let row = r
            .guided
            .rows
            .iter()
            .find(|g| g.fov_deg == fov && g.scene == r.header.scene);
        rows.push(PaperRow {
            measure: format!("{fov}° FOV iteration, Cornell box"),
            paper_ms: same(paper),
            paper_ms_per_megapixel: same(paper / paper_mp),
            paper_speedup: Some(speedup),
            ours_ms: row.map(|g| same(g.ms_per_iteration)),
            ours_ms_per_megapixel: row.map(|g| same(g.ms_per_iteration / mp)),
            ours_speedup: row.map(|g| g.speedup),
            ours_size: size,
            ours_device: r.guided.device.clone(),
            note: match row {
                Some(g) => format!(
                    "scene '{}', schedule + trace, median of {} iterations, {:.2} % of the pixels per iteration; speed-up over our full frame on the same device{size_note}",
                    g.scene,
                    r.config.iterations,
                    100.0 * g.share_sampled
                ),
                None => format!("not run: {fov}° is not among the FOVs {:?}", r.config.fovs_deg),
            },
        });
    }
    rows
}

/// raygun's targets, judged only on a datacenter GPU at 3840×2160.
#[must_use]
pub fn target_rows(r: &AllReport, datacenter: Option<String>) -> Vec<TargetRow> {
    let size = r.config.size;
    let why_not = match (&datacenter, size == PAPER_SIZE) {
        (Some(_), true) => None,
        (None, _) => Some(format!(
            "device is not a datacenter GPU ({})",
            r.header.device
        )),
        (Some(_), false) => Some(format!("run at {}×{}, not 3840×2160", size[0], size[1])),
    };
    let judge = |value: Option<f64>, ok: &dyn Fn(f64) -> bool| match (&why_not, value) {
        (None, Some(v)) if v.is_finite() => {
            if ok(v) {
                TargetStatus::Met
            } else {
                TargetStatus::Missed
            }
        }
        _ => TargetStatus::NotMeasured,
    };
    let cv10 = r.convergence.iter().find(|c| c.fov_deg == 10.0);
    let (speedup, how) = match cv10 {
        Some(c) => match (c.speedup_to_target, c.extrapolated_speedup_to_target) {
            (Some(x), _) => (Some(x), "both curves reached the target".to_string()),
            (None, Some(x)) => (
                Some(x),
                "extrapolated (RMSE ∝ 1/√t) where a curve did not reach the target".to_string(),
            ),
            (None, None) => (None, "no time to target".to_string()),
        },
        None => (None, "10° not among the FOVs".to_string()),
    };
    let st10 = r.stages.iter().find(|s| s.fov_deg == 10.0);
    let iteration = st10.map(|s| s.target_iteration_ms);
    let reason = |s: &TargetStatus| match (s, &why_not) {
        (TargetStatus::NotMeasured, Some(w)) => format!("; not judged: {w}"),
        _ => String::new(),
    };
    // The same iteration on the wall clock, as the window runs it: the 10° row of the way the
    // picture reaches the window (a texture on the GPU where measured, else read back, else
    // the host's), whole iterations waited for.
    let window = [PicturePath::Texture, PicturePath::Gpu, PicturePath::Host]
        .into_iter()
        .find_map(|p| {
            r.stages
                .iter()
                .find(|s| s.fov_deg == 10.0 && s.picture == p)
        });
    let s1 = judge(speedup, &|v| v >= 30.0);
    let s2 = judge(iteration, &|v| v <= 8.0);
    let s3 = judge(window.map(|s| s.iteration_ms_median), &|v| v <= 8.0);
    vec![
        TargetRow {
            target: "guided reaches the ROI target RMSE (1 % of the reference mean) ≥ 30× sooner than full frame at 10° FOV".into(),
            measured: speedup,
            unit: "×".into(),
            status: s1,
            note: format!("full-frame ÷ guided time to target, {how}{}", reason(&s1)),
        },
        TargetRow {
            target: "3840×2160 guided iteration at 10° FOV incl. DGI-if-changed, scheduling, tracing and the fast filter ≤ 8 ms (≥ 120 iterations/s)".into(),
            measured: iteration,
            unit: "ms".into(),
            status: s2,
            note: format!(
                "the per-stage table's target iteration (the iteration with an ROI change: the \
                 stages' own times, the GPU's clock where it has timestamps) at {}×{}{}",
                size[0],
                size[1],
                reason(&s2)
            ),
        },
        TargetRow {
            target: "3840×2160 guided iterations at 10° FOV on the wall clock, as the window runs them (frame, fast filter, display, picture to the window), median ≤ 8 ms (≥ 120 iterations/s)".into(),
            measured: window.map(|s| s.iteration_ms_median),
            unit: "ms".into(),
            status: s3,
            note: match window {
                Some(w) => format!(
                    "median wall clock of whole iterations at 10° (the ROI set on the first: \
                     the median's have no DGI), the per-stage table's {} picture row, at \
                     {}×{}{}",
                    w.picture.name(),
                    size[0],
                    size[1],
                    reason(&s3)
                ),
                None => "10° not among the FOVs".to_string(),
            },
        },
    ]
}
