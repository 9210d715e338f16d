//! `raygun bench motion`: what a moving eye does to the picture, with motion reuse and with
//! restarts (DESIGN.md §11).
//!
//! A guided render through HORNET's wall camera (the paper's ROI: a square cone from 1 m in
//! front of the wall's centre, p_min 0) follows an eye that moves along a *walk*, one eye an
//! iteration, under the tracked head's rule (a move past the threshold moves the camera):
//!
//! * `head walk`: the shipped session `tracking-replays/head-1-walk` (20 s: right, in, left,
//!   back), `--fps` iterations a second of it;
//! * `sway`: a person standing still, swaying sideways by ± `--sway-cm` at `--sway-hz`, from
//!   the walk's first eye, as long as the walk.
//!
//! Each walk runs twice, with `--on-eye-move reuse` and `restart`. Every `--every` iterations
//! the picture the filter makes (as `render` shows it) is compared with a full-frame reference
//! of `--reference-spp` samples a pixel at the camera's eye of that moment: relative MSE inside
//! the ROI (DGI distance 0) and in the periphery (the other shown pixels). Each move's share of
//! shown pixels carried and its time (the records, the carry; restart: the clear) are kept.
//!
//! **The step:** after half the iterations at the first eye, the eye steps 2 cm sideways
//! (`--step-cm`); the iterations until the ROI's error is back to what it was just before the
//! step, for each policy.
//!
//! The figures go to a Markdown table, a JSON report and a plot of error over time (SVG).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use glam::{DVec3, Vec3};
use serde::Serialize;

use super::paper;
use crate::bench::denoise::rel_mse;
use crate::display::DisplayModel;
use crate::filter::FilterParams;
use crate::frame::{EyeFollow, EyeMove, FrameError, GuideConfig, Render, Renderer};
use crate::gpu::Backend;
use crate::roi::cone::ConeError;
use crate::scene::Scene;
use crate::trace::camera::CameraError;
use crate::trace::path::TraceSettings;
use crate::trace::wall::{WallCamera, WallCameraError, WorldFromRoom};

/// The most iterations a walk may run.
pub const MAX_ITERATIONS: u32 = 2000;

/// What the benchmark measures.
#[derive(Clone, Debug, Serialize)]
pub struct MotionBenchConfig {
    pub size: [u32; 2],
    pub fovs_deg: Vec<f64>,
    /// Iterations a second of the walk.
    pub fps: f64,
    /// The head walk's length, seconds (the sway runs as long).
    pub seconds: f64,
    /// Compare with the reference every this many iterations.
    pub every: u32,
    pub reference_spp: u32,
    pub sway_amplitude_m: f64,
    pub sway_hz: f64,
    pub step_m: f64,
    pub threshold_m: f64,
    pub max_depth: u32,
    pub seed: u32,
}

impl Default for MotionBenchConfig {
    fn default() -> Self {
        Self {
            size: [248, 100],
            fovs_deg: vec![10.0, 60.0],
            fps: 4.0,
            seconds: 20.0,
            every: 8,
            reference_spp: 256,
            sway_amplitude_m: 0.015,
            sway_hz: 0.75,
            step_m: 0.02,
            threshold_m: crate::tracking::head::DEFAULT_EYE_THRESHOLD_M,
            max_depth: 4,
            seed: 1,
        }
    }
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum MotionBenchError {
    #[error("bench motion: {0}")]
    Config(String),
    #[error("bench motion: the scene's camera: {0}")]
    Camera(#[from] CameraError),
    #[error("bench motion: the ROI: {0}")]
    Cone(#[from] ConeError),
    #[error("bench motion: the wall camera: {0}")]
    Wall(#[from] WallCameraError),
    #[error(transparent)]
    Frame(#[from] FrameError),
}

impl MotionBenchConfig {
    /// The iterations of a walk.
    #[must_use]
    pub fn iterations(&self) -> u32 {
        (self.seconds * self.fps).round() as u32
    }

    /// Checks the numbers before any work.
    pub fn validate(&self) -> Result<(), MotionBenchError> {
        let bad = |m: String| Err(MotionBenchError::Config(m));
        if self.size[0] < 16 || self.size[1] < 16 {
            return bad(format!(
                "--size {}×{}: at least 16 a side",
                self.size[0], self.size[1]
            ));
        }
        if self.fovs_deg.is_empty() || self.fovs_deg.iter().any(|f| !(*f > 0.0 && *f < 180.0)) {
            return bad("--fov: one or more angles between 0° and 180°".into());
        }
        if !(self.fps > 0.0 && self.fps.is_finite()) {
            return bad(format!("--fps {}: a positive number", self.fps));
        }
        let n = self.iterations();
        if !(2..=MAX_ITERATIONS).contains(&n) {
            return bad(format!(
                "{} s at {} iterations a second is {n} iterations: 2 to {MAX_ITERATIONS}",
                self.seconds, self.fps
            ));
        }
        if self.every == 0 || self.every > n {
            return bad(format!(
                "--every {}: 1 to the walk's {n} iterations",
                self.every
            ));
        }
        if self.reference_spp == 0 {
            return bad("--reference-spp: at least 1".into());
        }
        for (name, v) in [
            ("--sway-cm", self.sway_amplitude_m),
            ("--sway-hz", self.sway_hz),
            ("--step-cm", self.step_m),
        ] {
            if !(v > 0.0 && v.is_finite() && v < 10.0) {
                return bad(format!("{name}: a positive number (below 10 m or Hz)"));
            }
        }
        Ok(())
    }
}

/// An eye per iteration (room frame).
#[derive(Clone, Debug)]
pub struct Walk {
    pub name: &'static str,
    pub eyes: Vec<DVec3>,
}

/// The sway: ± `amplitude` along x at `hz`, about `centre`, `fps` iterations a second.
#[must_use]
pub fn sway(centre: DVec3, amplitude: f64, hz: f64, fps: f64, iterations: u32) -> Walk {
    let eyes = (0..iterations)
        .map(|k| {
            let t = f64::from(k) / fps;
            centre + DVec3::X * amplitude * (std::f64::consts::TAU * hz * t).sin()
        })
        .collect();
    Walk { name: "sway", eyes }
}

/// One comparison with the reference.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Point {
    /// Iterations done.
    pub iteration: u32,
    pub roi_rel_mse: f64,
    pub periphery_rel_mse: f64,
}

/// A walk with one policy.
#[derive(Clone, Debug, Serialize)]
pub struct Series {
    pub fov_deg: f64,
    pub walk: &'static str,
    pub policy: EyeMove,
    pub points: Vec<Point>,
    /// Moves of the camera (past the threshold).
    pub moves: u32,
    /// The mean share of shown pixels a move carried (0 for restart).
    pub mean_share_carried: f64,
    /// The median time of a move, ms.
    pub ms_per_move: f64,
}

impl Series {
    /// The median of the ROI's relative MSE over the points.
    #[must_use]
    pub fn median_roi(&self) -> f64 {
        median(self.points.iter().map(|p| p.roi_rel_mse).collect())
    }

    /// The median of the periphery's relative MSE over the points.
    #[must_use]
    pub fn median_periphery(&self) -> f64 {
        median(self.points.iter().map(|p| p.periphery_rel_mse).collect())
    }
}

/// The step with one policy.
#[derive(Clone, Debug, Serialize)]
pub struct Step {
    pub fov_deg: f64,
    pub policy: EyeMove,
    /// The ROI's relative MSE just before the step.
    pub before: f64,
    /// Just after it (before any new iteration).
    pub after: f64,
    /// Iterations after the step until the ROI's error is back to `before` (`None`: not within
    /// the walk's length).
    pub recovered_after: Option<u32>,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct MotionReport {
    pub scene: String,
    pub backend: String,
    pub config: MotionBenchConfig,
    pub series: Vec<Series>,
    pub steps: Vec<Step>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// References by eye: a full-frame render through the wall camera at each eye asked for.
struct References<'a> {
    backend: &'a Backend,
    scene: &'a Scene,
    settings: TraceSettings,
    spp: u32,
    images: HashMap<[u64; 3], Vec<Vec3>>,
}

impl References<'_> {
    fn at(&mut self, wall: &WallCamera) -> Result<&[Vec3], FrameError> {
        let key = wall.eye_room.to_array().map(f64::to_bits);
        if !self.images.contains_key(&key) {
            let image = paper::reference_image_wall(
                self.backend,
                self.scene,
                self.settings,
                self.spp,
                Some(wall),
                &mut |_| {},
            )?;
            self.images.insert(key, image);
        }
        Ok(&self.images[&key])
    }
}

/// The ROI's and the periphery's masks of a DGI (shown pixels only).
fn regions(dgi: &[f32], wall: &WallCamera) -> (Vec<bool>, Vec<bool>) {
    let roi = (0..dgi.len())
        .map(|p| wall.is_shown(p as u32) && dgi[p] == 0.0)
        .collect();
    let periphery = (0..dgi.len())
        .map(|p| wall.is_shown(p as u32) && dgi[p] > 0.0)
        .collect();
    (roi, periphery)
}

/// The filter's picture of `r` against the reference at its eye.
fn compare(
    r: &Renderer<'_>,
    refs: &mut References<'_>,
    iteration: u32,
) -> Result<Point, FrameError> {
    let wall = r.wall().expect("a wall camera").clone();
    let picture = r.picture(&FilterParams::default())?;
    let (roi, periphery) = regions(&r.dgi()?, &wall);
    let reference = refs.at(&wall)?;
    Ok(Point {
        iteration,
        roi_rel_mse: rel_mse(&picture, reference, &roi),
        periphery_rel_mse: rel_mse(&picture, reference, &periphery),
    })
}

/// What a run needs beside the walk.
struct Setup<'a> {
    backend: &'a Backend,
    scene: &'a Scene,
    display: &'a DisplayModel,
    settings: TraceSettings,
    start: WallCamera,
}

impl Setup<'_> {
    fn renderer(&self, fov: f64, policy: EyeMove) -> Result<Renderer<'_>, MotionBenchError> {
        let mut r = paper::guided_wall(
            self.backend,
            self.scene,
            self.settings,
            self.display,
            GuideConfig::default(),
            paper::roi(fov)?,
            Some(&self.start),
        )?;
        r.set_on_eye_move(policy);
        Ok(r)
    }
}

/// One walk with one policy.
fn run_walk(
    setup: &Setup<'_>,
    refs: &mut References<'_>,
    cfg: &MotionBenchConfig,
    (fov, policy): (f64, EyeMove),
    walk: &Walk,
    progress: &mut dyn FnMut(&str, u32),
) -> Result<Series, MotionBenchError> {
    let mut r = setup.renderer(fov, policy)?;
    let (mut points, mut shares, mut ms) = (Vec::new(), Vec::new(), Vec::new());
    let mut moves = 0;
    let label = format!("{fov}° {} {policy:?}", walk.name);
    for (k, &eye) in walk.eyes.iter().enumerate() {
        let t = Instant::now();
        match r.follow_eye(eye, cfg.threshold_m)? {
            EyeFollow::Kept | EyeFollow::Refused(_) => {}
            EyeFollow::Restarted => {
                ms.push(t.elapsed().as_secs_f64() * 1e3);
                moves += 1;
            }
            EyeFollow::Reused(s) => {
                ms.push(t.elapsed().as_secs_f64() * 1e3);
                shares.push(s.share());
                moves += 1;
            }
        }
        r.run_frame(false)?;
        let done = k as u32 + 1;
        if done.is_multiple_of(cfg.every) {
            r.wait()?;
            points.push(compare(&r, refs, done)?);
        }
        progress(&label, 1);
    }
    Ok(Series {
        fov_deg: fov,
        walk: walk.name,
        policy,
        points,
        moves,
        mean_share_carried: if shares.is_empty() {
            0.0
        } else {
            shares.iter().sum::<f64>() / shares.len() as f64
        },
        ms_per_move: median(ms),
    })
}

/// The step with one policy: half the iterations at the first eye, the step, then as many
/// again, comparing the ROI after each.
fn run_step(
    setup: &Setup<'_>,
    refs: &mut References<'_>,
    cfg: &MotionBenchConfig,
    (fov, policy): (f64, EyeMove),
    progress: &mut dyn FnMut(&str, u32),
) -> Result<Step, MotionBenchError> {
    let mut r = setup.renderer(fov, policy)?;
    let half = cfg.iterations() / 2;
    r.iterate(half)?;
    let label = format!("{fov}° step {policy:?}");
    progress(&label, half);
    let before = compare(&r, refs, half)?.roi_rel_mse;
    let eye = setup.start.eye_room + DVec3::X * cfg.step_m;
    r.follow_eye(eye, 0.0)?;
    let after = compare(&r, refs, half)?.roi_rel_mse;
    let mut recovered_after = (after <= before).then_some(0);
    for k in 1..=half {
        if recovered_after.is_some() {
            break;
        }
        r.iterate(1)?;
        progress(&label, 1);
        if compare(&r, refs, half + k)?.roi_rel_mse <= before {
            recovered_after = Some(k);
        }
    }
    Ok(Step {
        fov_deg: fov,
        policy,
        before,
        after,
        recovered_after,
    })
}

/// Iterations every walk and step renders (for a progress bar).
#[must_use]
pub fn planned_iterations(cfg: &MotionBenchConfig) -> u64 {
    let n = u64::from(cfg.iterations());
    // Two walks and a step (at most the walk's length) for each policy and FOV.
    cfg.fovs_deg.len() as u64 * 2 * 3 * n
}

/// Runs the benchmark on `scene` (named `name`) with the head walk `head_walk` (its eyes, one
/// an iteration of the config's length).
pub fn run(
    backend: &Backend,
    display: &DisplayModel,
    (name, scene): (&str, &Scene),
    cfg: &MotionBenchConfig,
    head_walk: &Walk,
    mut progress: impl FnMut(&str, u32),
) -> Result<MotionReport, MotionBenchError> {
    cfg.validate()?;
    let n = cfg.iterations();
    if head_walk.eyes.len() != n as usize {
        return Err(MotionBenchError::Config(format!(
            "the head walk has {} eyes for {n} iterations",
            head_walk.eyes.len()
        )));
    }
    let settings = paper::settings(scene, cfg.size, cfg.seed, cfg.max_depth)?;
    let c = &settings.camera;
    let start = WallCamera::new(
        display,
        cfg.size,
        head_walk.eyes[0],
        &WorldFromRoom::Auto,
        (c.position.as_dvec3(), c.forward.as_dvec3(), c.up.as_dvec3()),
    )?;
    let setup = Setup {
        backend,
        scene,
        display,
        settings,
        start,
    };
    let mut refs = References {
        backend,
        scene,
        settings: TraceSettings {
            seed: cfg.seed ^ 0x5eed,
            ..settings
        },
        spp: cfg.reference_spp,
        images: HashMap::new(),
    };
    let sway = sway(
        head_walk.eyes[0],
        cfg.sway_amplitude_m,
        cfg.sway_hz,
        cfg.fps,
        n,
    );
    let (mut series, mut steps) = (Vec::new(), Vec::new());
    for &fov in &cfg.fovs_deg {
        for policy in [EyeMove::Reuse, EyeMove::Restart] {
            for walk in [head_walk, &sway] {
                series.push(run_walk(
                    &setup,
                    &mut refs,
                    cfg,
                    (fov, policy),
                    walk,
                    &mut progress,
                )?);
            }
            steps.push(run_step(
                &setup,
                &mut refs,
                cfg,
                (fov, policy),
                &mut progress,
            )?);
        }
    }
    Ok(MotionReport {
        scene: name.to_owned(),
        backend: backend.describe(),
        config: cfg.clone(),
        series,
        steps,
    })
}

/// The series of `walk`, `fov` and `policy` in `report`.
fn find<'r>(report: &'r MotionReport, fov: f64, walk: &str, policy: EyeMove) -> Option<&'r Series> {
    report
        .series
        .iter()
        .find(|s| s.fov_deg == fov && s.walk == walk && s.policy == policy)
}

fn step_of(report: &MotionReport, fov: f64, policy: EyeMove) -> Option<&Step> {
    report
        .steps
        .iter()
        .find(|s| s.fov_deg == fov && s.policy == policy)
}

/// The report as Markdown: one row per FOV and walk (medians over the walk, reuse against
/// restart, the share carried, ms a move), then the step.
#[must_use]
pub fn markdown(reports: &[MotionReport]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "| scene | FOV | walk | moves | ROI relMSE reuse | restart | ratio | periphery reuse | restart | carried | ms a move reuse / restart |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|");
    for rep in reports {
        for &fov in &rep.config.fovs_deg {
            for walk in ["head walk", "sway"] {
                let (Some(a), Some(b)) = (
                    find(rep, fov, walk, EyeMove::Reuse),
                    find(rep, fov, walk, EyeMove::Restart),
                ) else {
                    continue;
                };
                let _ = writeln!(
                    out,
                    "| {} | {fov}° | {walk} | {} | {:.5} | {:.5} | ×{:.2} | {:.5} | {:.5} | {:.0} % | {:.2} / {:.2} |",
                    rep.scene,
                    a.moves,
                    a.median_roi(),
                    b.median_roi(),
                    a.median_roi() / b.median_roi(),
                    a.median_periphery(),
                    b.median_periphery(),
                    100.0 * a.mean_share_carried,
                    a.ms_per_move,
                    b.ms_per_move
                );
            }
        }
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "| scene | FOV | ROI relMSE before the step | right after: reuse / restart | back after (iterations): reuse / restart |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|");
    let it = |s: &Step| {
        s.recovered_after
            .map_or("not within the run".into(), |k| k.to_string())
    };
    for rep in reports {
        for &fov in &rep.config.fovs_deg {
            let (Some(a), Some(b)) = (
                step_of(rep, fov, EyeMove::Reuse),
                step_of(rep, fov, EyeMove::Restart),
            ) else {
                continue;
            };
            let _ = writeln!(
                out,
                "| {} | {fov}° | {:.5} | {:.5} / {:.5} | {} / {} |",
                rep.scene,
                a.before,
                a.after,
                b.after,
                it(a),
                it(b)
            );
        }
    }
    out
}

/// A plot of the ROI's relative MSE over the iterations (log scale) for the head walk at the
/// first FOV, reuse against restart, one panel a report: an SVG document.
#[must_use]
pub fn plot_svg(reports: &[MotionReport]) -> String {
    let (pw, ph, pad) = (480.0f64, 260.0f64, 48.0f64);
    let height = ph * reports.len().max(1) as f64;
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{pw}\" height=\"{height}\" font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    for (i, rep) in reports.iter().enumerate() {
        let Some(&fov) = rep.config.fovs_deg.first() else {
            continue;
        };
        let series: Vec<(&Series, &str)> =
            [(EyeMove::Reuse, "#1f77b4"), (EyeMove::Restart, "#d62728")]
                .iter()
                .filter_map(|&(p, colour)| find(rep, fov, "head walk", p).map(|s| (s, colour)))
                .collect();
        let values: Vec<f64> = series
            .iter()
            .flat_map(|(s, _)| s.points.iter().map(|p| p.roi_rel_mse))
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        if values.is_empty() {
            continue;
        }
        let lo = values
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
            .log10()
            .floor();
        let hi = values
            .iter()
            .copied()
            .fold(0.0, f64::max)
            .log10()
            .ceil()
            .max(lo + 1.0);
        let n = f64::from(rep.config.iterations());
        let y0 = ph * i as f64;
        let x = |k: f64| pad + (pw - 1.5 * pad) * k / n;
        let y = |v: f64| y0 + pad * 0.5 + (ph - 1.5 * pad) * (hi - v.log10()) / (hi - lo);
        let _ = writeln!(
            svg,
            "<text x=\"{pad}\" y=\"{}\">{}: ROI relMSE over the head walk, {fov}° ROI (blue: reuse, red: restart)</text>",
            y0 + 14.0,
            rep.scene
        );
        let _ = writeln!(
            svg,
            "<rect x=\"{pad}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#888\"/>",
            y0 + pad * 0.5,
            pw - 1.5 * pad,
            ph - 1.5 * pad
        );
        for e in lo as i32..=hi as i32 {
            let _ = writeln!(
                svg,
                "<text x=\"4\" y=\"{:.1}\">1e{e}</text>",
                y(10f64.powi(e)) + 4.0
            );
        }
        let _ = writeln!(
            svg,
            "<text x=\"{:.1}\" y=\"{:.1}\">iterations ({} a second of the walk)</text>",
            pw / 2.0 - 60.0,
            y0 + ph - 8.0,
            rep.config.fps
        );
        for (s, colour) in series {
            let pts: Vec<String> = s
                .points
                .iter()
                .filter(|p| p.roi_rel_mse.is_finite() && p.roi_rel_mse > 0.0)
                .map(|p| format!("{:.1},{:.1}", x(f64::from(p.iteration)), y(p.roi_rel_mse)))
                .collect();
            let _ = writeln!(
                svg,
                "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\" points=\"{}\"/>",
                pts.join(" ")
            );
        }
    }
    svg.push_str("</svg>\n");
    svg
}

/// Writes `text` to `path` whole (a temporary file renamed: never a truncated file).
pub fn write_text(path: &Path, text: &str, what: &str) -> anyhow::Result<()> {
    crate::output::replace_with(path, |tmp| {
        std::fs::write(tmp, text.as_bytes())
            .map_err(|e| anyhow::anyhow!("{what} {}: {e}", path.display()))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sway swings ± its amplitude about its centre at its frequency.
    #[test]
    fn the_sway_swings_about_its_centre() {
        let w = sway(DVec3::new(0.0, 0.0, 1.0), 0.015, 0.5, 4.0, 16);
        assert_eq!(w.eyes.len(), 16);
        assert_eq!(w.eyes[0], DVec3::new(0.0, 0.0, 1.0));
        // A quarter period (0.5 s at 0.5 Hz = 2 iterations) later: the full amplitude.
        assert!((w.eyes[2].x - 0.015).abs() < 1e-12);
        assert!((w.eyes[6].x + 0.015).abs() < 1e-12);
        assert!(w.eyes.iter().all(|e| e.y == 0.0 && e.z == 1.0));
    }

    /// Bad numbers are named before any work.
    #[test]
    fn the_config_names_bad_numbers() {
        let ok = MotionBenchConfig::default();
        ok.validate().unwrap();
        let e = MotionBenchConfig {
            every: 0,
            ..ok.clone()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("--every 0"), "{e}");
        let e = MotionBenchConfig {
            fps: 0.0,
            ..ok.clone()
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("--fps 0"), "{e}");
        let e = MotionBenchConfig {
            step_m: f64::NAN,
            ..ok
        }
        .validate()
        .unwrap_err();
        assert!(e.to_string().contains("--step-cm"), "{e}");
    }
}
