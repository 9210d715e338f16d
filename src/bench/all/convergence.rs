//! Convergence curves: RMSE against a converged reference inside and outside the ROI versus
//! accumulated frame time, guided against full frame, unfiltered against the fast filter, and
//! the time each takes to the quality target.

use glam::{DVec3, Vec3};
use serde::Serialize;

use super::{AllBenchError, AllConfig};
use crate::bench::paper;
use crate::display::DisplayModel;
use crate::filter::FilterParams;
use crate::frame::{GuideConfig, Render, Renderer};
use crate::gpu::Backend;
use crate::scene::Scene;
use crate::trace::accum::Accumulation;
use crate::trace::path::TraceSettings;

/// Target of the time-to-quality figure: RMSE inside the ROI ≤ this share of the reference's
/// mean there.
pub const TARGET_REL_RMSE: f64 = 0.01;

/// One point of a convergence curve.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct CurvePoint {
    pub iteration: u32,
    /// Accumulated frame time (ms), read-backs and RMSE excluded.
    pub ms: f64,
    pub rmse_roi: f64,
    pub rmse_outside: f64,
    pub rmse_roi_filtered: f64,
    pub rmse_outside_filtered: f64,
}

/// Guided and full-frame curves of one FOV.
#[derive(Clone, Debug, Serialize)]
pub struct Convergence {
    pub fov_deg: f64,
    pub roi_pixels: usize,
    /// The reference's mean inside the ROI; the target is [`TARGET_REL_RMSE`] of it.
    pub reference_mean_roi: f64,
    pub target_rmse_roi: f64,
    pub guided: Vec<CurvePoint>,
    pub full_frame: Vec<CurvePoint>,
    /// Unfiltered ROI RMSE of the full frame at the last point not later than the guided
    /// curve's end (equal time, or the first full-frame point when even that is later).
    pub full_rmse_roi_at_guided_end: f64,
    pub full_ms_at_guided_end: f64,
    pub guided_time_to_target: TimeToTarget,
    pub full_time_to_target: TimeToTarget,
    /// Full-frame ÷ guided time to the target, when both reached it.
    pub speedup_to_target: Option<f64>,
    /// The same ratio from the extrapolated times where a curve did not reach the target.
    pub extrapolated_speedup_to_target: Option<f64>,
}

/// When a curve first reached the target (unfiltered, inside the ROI), or how close it got.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TimeToTarget {
    pub reached: bool,
    /// Time of the first point at or below the target, else of the lowest point.
    pub ms: f64,
    /// RMSE at that point.
    pub rmse_roi: f64,
    /// When not reached: the time at which RMSE ∝ 1/√t through the curve's last point would
    /// reach the target (an extrapolation, not a measurement; it ignores the reference's own
    /// noise).
    pub extrapolated_ms: Option<f64>,
}

/// RMSE (linear RGB) over the pixels where `mask` is `inside`; NaN when there are none.
fn rmse(image: &[DVec3], reference: &[Vec3], mask: &[bool], inside: bool) -> f64 {
    let (mut se, mut n) = (0f64, 0usize);
    for ((a, b), &m) in image.iter().zip(reference).zip(mask) {
        if m == inside {
            se += (*a - b.as_dvec3()).length_squared() / 3.0;
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        (se / n as f64).sqrt()
    }
}

pub(super) fn point(
    iteration: u32,
    ms: f64,
    acc: &Accumulation,
    dgi: &[f32],
    reference: &[Vec3],
    mask: &[bool],
    params: &FilterParams,
) -> Result<CurvePoint, AllBenchError> {
    let raw = crate::filter::unfiltered_cpu(acc);
    let filtered = crate::filter::filter_cpu(params, acc, dgi)?;
    Ok(CurvePoint {
        iteration,
        ms,
        rmse_roi: rmse(&raw, reference, mask, true),
        rmse_outside: rmse(&raw, reference, mask, false),
        rmse_roi_filtered: rmse(&filtered, reference, mask, true),
        rmse_outside_filtered: rmse(&filtered, reference, mask, false),
    })
}

fn time_to_target(curve: &[CurvePoint], target: f64) -> TimeToTarget {
    if let Some(p) = curve.iter().find(|p| p.rmse_roi <= target) {
        return TimeToTarget {
            reached: true,
            ms: p.ms,
            rmse_roi: p.rmse_roi,
            extrapolated_ms: None,
        };
    }
    let extrapolated_ms = curve
        .last()
        .filter(|p| p.rmse_roi.is_finite() && target > 0.0)
        .map(|p| p.ms * (p.rmse_roi / target).powi(2));
    let best = curve
        .iter()
        .min_by(|a, b| a.rmse_roi.total_cmp(&b.rmse_roi))
        .copied();
    TimeToTarget {
        reached: false,
        ms: best.map_or(f64::NAN, |p| p.ms),
        rmse_roi: best.map_or(f64::NAN, |p| p.rmse_roi),
        extrapolated_ms,
    }
}

/// The convergence curves of one scene at each FOV of `fovs`: a guided render of
/// `cfg.iterations` iterations, then a full-frame render until its accumulated time reaches the
/// guided one's (at least two iterations). Time is the frames' own (GPU timestamps where the
/// adapter has them, else wall clock); the filtered curves use the fast filter's CPU twin.
pub fn convergence(
    backend: &Backend,
    display: &DisplayModel,
    name: &str,
    scene: &Scene,
    fovs: &[f64],
    cfg: &AllConfig,
    mut progress: impl FnMut(&str),
) -> Result<Vec<Convergence>, AllBenchError> {
    let base = paper::settings(
        scene,
        cfg.size,
        cfg.seed,
        crate::trace::path::DEFAULT_MAX_DEPTH,
    )
    .map_err(|source| AllBenchError::Camera {
        scene: name.to_string(),
        source,
    })?;
    let settings = |seed: u32| TraceSettings { seed, ..base };
    progress(&format!(
        "convergence: reference ({} spp)",
        cfg.reference_spp
    ));
    let reference = paper::reference_image(
        backend,
        scene,
        settings(cfg.seed ^ 0xc0_5eed),
        cfg.reference_spp.max(1),
    )?;
    let every = cfg.sample_every.max(1);
    let mut out = Vec::new();
    for &fov in fovs {
        progress(&format!("convergence: {fov}° guided"));
        let mut g = paper::guided(
            backend,
            scene,
            settings(cfg.seed.wrapping_add(11)),
            display,
            GuideConfig::default(),
            paper::roi(fov)?,
        )?;
        let n = cfg.iterations.max(1);
        let (mut ms, mut guided_curve) = (0.0, Vec::new());
        let (mut dgi, mut mask) = (Vec::new(), Vec::new());
        for i in 1..=n {
            let s = g.run_frame(true)?;
            ms +=
                s.ms_dgi.unwrap_or(0.0) + s.ms_schedule.unwrap_or(0.0) + s.ms_trace.unwrap_or(0.0);
            if i == 1 {
                dgi = g.dgi()?;
                mask = dgi.iter().map(|&d| d == 0.0).collect();
            }
            if i % every == 0 || i == n {
                let acc = g.accumulation()?;
                guided_curve.push(point(i, ms, &acc, &dgi, &reference, &mask, &cfg.filter)?);
            }
        }
        drop(g);
        let guided_ms = ms;
        progress(&format!("convergence: {fov}° full frame"));
        let mut full = Renderer::full(backend, scene, settings(cfg.seed.wrapping_add(12)))?;
        let (mut ms, mut full_curve, mut i) = (0.0, Vec::new(), 0u32);
        let mut stride = 1u32;
        loop {
            ms += full.timed_iterations(1)?.ms[0];
            i += 1;
            if i == 1 {
                // Aim for about as many points as the guided curve.
                let estimate = (guided_ms / ms).ceil().max(1.0) as u32;
                stride = (estimate / (n / every).max(1)).max(1);
            }
            let done = i >= 2 && ms >= guided_ms;
            if i % stride == 0 || done {
                let acc = full.accumulation()?;
                full_curve.push(point(i, ms, &acc, &dgi, &reference, &mask, &cfg.filter)?);
            }
            if done {
                break;
            }
        }
        drop(full);
        let at_end = full_curve
            .iter()
            .rev()
            .find(|p| p.ms <= guided_ms)
            .unwrap_or(&full_curve[0]);
        let mean = {
            let (mut s, mut k) = (0f64, 0usize);
            for (r, &m) in reference.iter().zip(&mask) {
                if m {
                    s += r.as_dvec3().element_sum() / 3.0;
                    k += 1;
                }
            }
            if k == 0 { f64::NAN } else { s / k as f64 }
        };
        let target = TARGET_REL_RMSE * mean;
        let gt = time_to_target(&guided_curve, target);
        let ft = time_to_target(&full_curve, target);
        out.push(Convergence {
            fov_deg: fov,
            roi_pixels: mask.iter().filter(|&&m| m).count(),
            reference_mean_roi: mean,
            target_rmse_roi: target,
            full_rmse_roi_at_guided_end: at_end.rmse_roi,
            full_ms_at_guided_end: at_end.ms,
            guided: guided_curve,
            full_frame: full_curve,
            speedup_to_target: (gt.reached && ft.reached).then(|| ft.ms / gt.ms),
            extrapolated_speedup_to_target: match (
                gt.extrapolated_ms.or(gt.reached.then_some(gt.ms)),
                ft.extrapolated_ms.or(ft.reached.then_some(ft.ms)),
            ) {
                (Some(g), Some(f)) if !(gt.reached && ft.reached) => Some(f / g),
                _ => None,
            },
            guided_time_to_target: gt,
            full_time_to_target: ft,
        });
    }
    Ok(out)
}
