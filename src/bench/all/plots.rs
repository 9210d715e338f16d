//! `dgi_metrics.png` and `convergence.png` (`fig5.png` is the guided benchmark's own plot).

use std::path::Path;

use super::convergence::{Convergence, CurvePoint, TARGET_REL_RMSE};
use super::{AllBenchError, AllReport};
use crate::bench::dgi::DgiBenchReport;

/// DGI metrics as a PNG: time (x) against mean and max error (y, canvas px), one point per
/// metric, FOV and backend (filled: GPU, hollow: CPU), labelled with the FOV.
pub fn plot_dgi_metrics(r: &DgiBenchReport, path: &Path) -> Result<(), AllBenchError> {
    use crate::roi::dgi::Metric;
    use plotters::prelude::*;
    let err = |e: String| AllBenchError::Output {
        path: path.display().to_string(),
        reason: e,
    };
    crate::bench::font::register().map_err(|e| err(e.to_string()))?;
    let root = BitMapBackend::new(path, (1200, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
    let (left, right) = root.split_horizontally(600);
    let xmax = r.rows.iter().map(|d| d.ms_median).fold(0.0, f64::max) * 1.15 + 1e-9;
    type Pick = fn(&crate::bench::dgi::DgiBenchRow) -> f64;
    let panels: [(&DrawingArea<BitMapBackend, _>, &str, Pick); 2] = [
        (&left, "mean error (canvas px)", |d| d.err_mean_px),
        (&right, "max error (canvas px)", |d| d.err_max_px),
    ];
    for (area, label, pick) in panels {
        let ymax = r.rows.iter().map(pick).fold(0.0, f64::max) * 1.15 + 1e-3;
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("DGI metrics: time vs {label}; filled GPU, hollow CPU"),
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..xmax, 0.0..ymax)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("DGI time (ms, median)")
            .y_desc(label)
            .draw()
            .map_err(|e| err(e.to_string()))?;
        for (metric, colour) in [
            (Metric::Exact, BLACK),
            (Metric::Ellipse, BLUE),
            (Metric::Angular, RED),
        ] {
            let pts: Vec<_> = r.rows.iter().filter(|d| d.metric == metric).collect();
            if pts.is_empty() {
                continue;
            }
            chart
                .draw_series(pts.iter().map(|d| {
                    let style = if d.backend == "gpu" {
                        colour.filled()
                    } else {
                        colour.stroke_width(2)
                    };
                    Circle::new((d.ms_median, pick(d)), 5, style)
                }))
                .map_err(|e| err(e.to_string()))?
                .label(format!("{metric:?}"))
                .legend(move |(x, y)| Circle::new((x + 10, y), 5, colour.filled()));
            chart
                .draw_series(pts.iter().map(|d| {
                    Text::new(
                        format!("{}°", d.fov_deg),
                        (d.ms_median, pick(d)),
                        ("sans-serif", 12).into_font().color(&colour),
                    )
                }))
                .map_err(|e| err(e.to_string()))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperMiddle)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(e.to_string()))?;
    }
    root.present().map_err(|e| err(e.to_string()))?;
    Ok(())
}

pub(super) fn equal_time_point(cv: &Convergence) -> Option<&CurvePoint> {
    let end = cv.guided.last()?.ms;
    cv.full_frame
        .iter()
        .rev()
        .find(|p| p.ms <= end)
        .or(cv.full_frame.first())
}

/// The convergence curves as a PNG: one panel per FOV, RMSE (log scale) against time, guided
/// and full frame, inside and outside the ROI, unfiltered (solid) and filtered (dashed).
pub fn plot_convergence(r: &AllReport, path: &Path) -> Result<(), AllBenchError> {
    use plotters::prelude::*;
    let err = |e: String| AllBenchError::Output {
        path: path.display().to_string(),
        reason: e,
    };
    crate::bench::font::register().map_err(|e| err(e.to_string()))?;
    let n = r.convergence.len().max(1);
    let root = BitMapBackend::new(path, (600 * n as u32, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
    let panels = root.split_evenly((1, n));
    for (area, cv) in panels.iter().zip(&r.convergence) {
        let all = cv.guided.iter().chain(&cv.full_frame);
        let xmax = all.clone().map(|p| p.ms).fold(0.0, f64::max) * 1.05 + 1e-9;
        let ys = all
            .flat_map(|p| {
                [
                    p.rmse_roi,
                    p.rmse_outside,
                    p.rmse_roi_filtered,
                    p.rmse_outside_filtered,
                ]
            })
            .chain([cv.target_rmse_roi])
            .filter(|v| v.is_finite() && *v > 0.0);
        let (ymin, ymax) = ys.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        let (ymin, ymax) = if ymin.is_finite() {
            (ymin * 0.8, ymax * 1.25)
        } else {
            (1e-3, 1.0)
        };
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("Convergence, FOV {}°", cv.fov_deg),
                ("sans-serif", 22),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..xmax, (ymin..ymax).log_scale())
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("accumulated frame time (ms)")
            .y_desc("RMSE vs reference")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        type Pick = fn(&CurvePoint) -> f64;
        let lines: [(&str, &[CurvePoint], Pick, RGBColor, bool); 8] = [
            ("guided ROI", &cv.guided, |p| p.rmse_roi, RED, false),
            (
                "guided ROI filtered",
                &cv.guided,
                |p| p.rmse_roi_filtered,
                RED,
                true,
            ),
            (
                "guided outside",
                &cv.guided,
                |p| p.rmse_outside,
                MAGENTA,
                false,
            ),
            (
                "guided outside filtered",
                &cv.guided,
                |p| p.rmse_outside_filtered,
                MAGENTA,
                true,
            ),
            ("full ROI", &cv.full_frame, |p| p.rmse_roi, BLUE, false),
            (
                "full ROI filtered",
                &cv.full_frame,
                |p| p.rmse_roi_filtered,
                BLUE,
                true,
            ),
            (
                "full outside",
                &cv.full_frame,
                |p| p.rmse_outside,
                CYAN,
                false,
            ),
            (
                "full outside filtered",
                &cv.full_frame,
                |p| p.rmse_outside_filtered,
                CYAN,
                true,
            ),
        ];
        for (label, pts, pick, colour, dashed) in lines {
            let data: Vec<(f64, f64)> = pts
                .iter()
                .map(|p| (p.ms, pick(p)))
                .filter(|p| p.1.is_finite() && p.1 > 0.0)
                .collect();
            if data.is_empty() {
                continue;
            }
            let style = colour.stroke_width(2);
            if dashed {
                chart
                    .draw_series(DashedLineSeries::new(data, 6, 4, style))
                    .map_err(|e| err(e.to_string()))?
                    .label(format!("{label} (dashed)"))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            } else {
                chart
                    .draw_series(LineSeries::new(data, style))
                    .map_err(|e| err(e.to_string()))?
                    .label(label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            }
        }
        chart
            .draw_series(LineSeries::new(
                [(0.0, cv.target_rmse_roi), (xmax, cv.target_rmse_roi)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| err(e.to_string()))?
            .label(format!("target ({} %)", 100.0 * TARGET_REL_RMSE))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(|e| err(e.to_string()))?;
    }
    root.present().map_err(|e| err(e.to_string()))?;
    Ok(())
}
