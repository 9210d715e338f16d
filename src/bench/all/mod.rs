//! `raygun bench all`: every benchmark in one run — DGI, full-frame tracing, the
//! paper's guided benchmark and the filter — plus convergence curves: RMSE against a converged
//! reference inside and outside the ROI versus accumulated frame time, guided vs full frame,
//! unfiltered vs the fast filter; the DGI metrics' time against their error and the
//! closest-point solver on the hard-case set; per-stage times per iteration; and the paper's
//! table (DESIGN.md §9) and raygun's targets beside ours. Writes `report.md`, `report.json`
//! (the same figures), `fig5.png`, `dgi_metrics.png` and `convergence.png`.

pub mod convergence;
pub mod markdown;
pub mod plots;
pub mod provenance;
pub mod stages;
pub mod tables;

use std::path::Path;

use serde::Serialize;

use crate::bench::dgi::{self, DgiBenchConfig, DgiBenchReport};
use crate::bench::filter::{self, FilterBenchConfig, FilterBenchReport};
use crate::bench::guided::{self, GuidedBenchConfig, GuidedBenchReport};
use crate::bench::paper::{Shot, Subject};
use crate::bench::solver::{self, SolverReport};
use crate::bench::trace::{self, TraceBenchConfig, TraceBenchRow};
use crate::display::DisplayModel;
use crate::filter::{FilterKind, FilterParams};
use crate::gpu::Backend;
use crate::roi::dgi::{Falloff, Surface};
use crate::scene::Scene;
use convergence::{Convergence, convergence};
use markdown::markdown;
use plots::{plot_convergence, plot_dgi_metrics};
use provenance::{Header, datacenter_gpu};
use stages::StageRow;
use tables::{PaperRow, TargetRow, paper_rows, target_rows};

/// Every setting of the run.
#[derive(Clone, Debug, Serialize)]
pub struct AllConfig {
    pub quick: bool,
    pub size: [u32; 2],
    pub fovs_deg: Vec<f64>,
    /// Guided iterations of the guided benchmark and of each guided convergence curve.
    pub iterations: u32,
    /// Samples per pixel of the converged references.
    pub reference_spp: u32,
    /// A curve point every this many iterations.
    pub sample_every: u32,
    pub trace_frames: u32,
    pub dgi_gpu_reps: u32,
    pub dgi_cpu_reps: u32,
    pub filter_reps: u32,
    /// Timed passes of the closest-point solvers over the hard-case set.
    pub solver_reps: u32,
    /// Iterations of the per-stage measurement (per FOV).
    pub stage_iterations: u32,
    /// Also time a full frame of `builtin:city` (the paper's second scene) when the report's
    /// scene is not it.
    pub city: bool,
    /// Fast filter settings of the filtered curves and the filter benchmark's error table.
    pub filter: FilterParams,
    pub seed: u32,
}

impl AllConfig {
    /// Settings by `--quick`; `size` overrides the image size (k_max scales with the width).
    #[must_use]
    pub fn new(quick: bool, size: Option<[u32; 2]>) -> Self {
        let size = size.unwrap_or(if quick { [160, 90] } else { [3840, 2160] });
        let k_max = (FilterParams::DEFAULT_K_MAX * size[0] as f32 / 3840.0)
            .clamp(1.0, FilterParams::MAX_K_MAX);
        let filter = FilterParams {
            kind: FilterKind::Fast,
            k_max,
            ..FilterParams::default()
        };
        if quick {
            Self {
                quick,
                size,
                fovs_deg: vec![10.0, 60.0],
                iterations: 128,
                reference_spp: 1024,
                sample_every: 8,
                trace_frames: 5,
                dgi_gpu_reps: 5,
                dgi_cpu_reps: 1,
                filter_reps: 3,
                solver_reps: 3,
                stage_iterations: 16,
                city: true,
                filter,
                seed: 1,
            }
        } else {
            Self {
                quick,
                size,
                fovs_deg: vec![10.0, 20.0, 30.0, 40.0, 50.0, 60.0],
                iterations: 100,
                reference_spp: 1024,
                sample_every: 5,
                trace_frames: 20,
                dgi_gpu_reps: 50,
                dgi_cpu_reps: 3,
                filter_reps: 20,
                solver_reps: 20,
                stage_iterations: 100,
                city: true,
                filter,
                seed: 1,
            }
        }
    }
}

/// Everything `bench all` measured.
#[derive(Clone, Debug, Serialize)]
pub struct AllReport {
    pub header: Header,
    pub config: AllConfig,
    pub dgi: DgiBenchReport,
    pub trace: Vec<TraceBenchRow>,
    pub guided: GuidedBenchReport,
    pub filter: FilterBenchReport,
    pub convergence: Vec<Convergence>,
    pub solver: SolverReport,
    pub stages: Vec<StageRow>,
    /// DESIGN.md §9's table, row for row, with ours beside it.
    pub paper: Vec<PaperRow>,
    pub targets: Vec<TargetRow>,
}

#[derive(Debug, thiserror::Error)]
pub enum AllBenchError {
    #[error("DGI benchmark: {0}")]
    Dgi(#[from] dgi::BenchError),
    #[error("trace benchmark: {0}")]
    Trace(#[from] trace::TraceBenchError),
    #[error("guided benchmark: {0}")]
    Guided(#[from] guided::GuidedBenchError),
    #[error("filter benchmark: {0}")]
    Filter(#[from] filter::FilterBenchError),
    #[error("closest-point solver benchmark: {0}")]
    Solver(#[from] solver::SolverBenchError),
    #[error("scene '{scene}': {reason}")]
    Scene { scene: String, reason: String },
    #[error("convergence curves: {0}")]
    Frame(#[from] crate::frame::FrameError),
    #[error("convergence curves: {0}")]
    Gpu(#[from] crate::gpu::GpuError),
    #[error("convergence curves: {0}")]
    FilterInput(#[from] crate::filter::FilterInputError),
    #[error("per-stage filter: {0}")]
    FilterStage(#[from] crate::filter::FilterGpuError),
    #[error("convergence curves: {0}")]
    Cone(#[from] crate::roi::cone::ConeError),
    #[error("convergence curves: scene '{scene}': {source}")]
    Camera {
        scene: String,
        #[source]
        source: crate::trace::camera::CameraError,
    },
    #[error("writing {path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("writing {path}: {reason}")]
    Output { path: String, reason: String },
}

/// The FOVs of the filter, convergence and per-stage sections: the first and last of the list.
fn end_fovs(cfg: &AllConfig) -> Vec<f64> {
    match (cfg.fovs_deg.first(), cfg.fovs_deg.last()) {
        (Some(&a), Some(&b)) if a != b => vec![a, b],
        (Some(&a), _) => vec![a],
        _ => Vec::new(),
    }
}

/// Whether `name` is the paper's city scene (the full-frame table's second row).
fn is_city(name: &str) -> bool {
    name.contains("city")
}

/// How many times [`run`] calls its `progress` (for a progress bar's length).
#[must_use]
pub fn progress_steps(cfg: &AllConfig, name: &str, gpu: bool) -> u64 {
    let fovs = cfg.fovs_deg.len() as u64;
    let ends = end_fovs(cfg).len() as u64;
    let scenes = 1 + u64::from(cfg.city && !is_city(name));
    (1 + 3 * fovs) // DGI
        + (1 + scenes) // trace
        + (1 + 2 + fovs) // guided
        + (1 + 4 * ends) // filter (one k_max: exact and fast)
        + (1 + 2 * ends) // convergence
        + (2 + u64::from(gpu)) // solver
        + ends * (1 + u64::from(gpu)) // stages (the host way, and on a GPU the GPU way)
}

/// Runs every benchmark on `scene` (named `name`): DGI, full-frame tracing (plus `builtin:city`
/// when `cfg.city`), the guided benchmark, the filter, the convergence curves and per-stage times
/// at the first and last of `cfg.fovs_deg`, and the closest-point solver; then lays the paper's
/// table and raygun's targets beside them.
pub fn run(
    backend: &Backend,
    display: &DisplayModel,
    display_name: &str,
    name: &str,
    scene: &Scene,
    cfg: &AllConfig,
    mut progress: impl FnMut(&str),
) -> Result<AllReport, AllBenchError> {
    let header = Header::now(backend, name, display_name);
    let surface = Surface::from_model(display);
    progress("DGI");
    let dgi = dgi::run(
        &surface,
        display.name(),
        backend,
        &DgiBenchConfig {
            size: cfg.size,
            fovs_deg: cfg.fovs_deg.clone(),
            gpu_reps: cfg.dgi_gpu_reps.max(1),
            cpu_reps: cfg.dgi_cpu_reps.max(1),
            falloff: Falloff::default(),
            ..DgiBenchConfig::default()
        },
        &mut progress,
    )?;
    progress("trace");
    let scenes = vec![(name.to_string(), scene.clone())];
    let mut trace_scenes = scenes.clone();
    if cfg.city && !is_city(name) {
        let city = Scene::open("builtin:city").map_err(|e| AllBenchError::Scene {
            scene: "builtin:city".into(),
            reason: e.to_string(),
        })?;
        trace_scenes.push(("city".to_string(), city));
    }
    let trace = trace::run(
        backend,
        &trace_scenes,
        &TraceBenchConfig {
            size: cfg.size,
            frames: cfg.trace_frames.max(1),
            seed: cfg.seed,
            ..TraceBenchConfig::default()
        },
        None,
        &mut progress,
    )?;
    drop(trace_scenes);
    progress("guided");
    let guided = guided::run(
        backend,
        display,
        &scenes,
        &GuidedBenchConfig {
            size: cfg.size,
            fovs_deg: cfg.fovs_deg.clone(),
            iterations: cfg.iterations.max(1),
            full_frames: cfg.trace_frames.max(1),
            reference_spp: cfg.reference_spp.max(1),
            seed: cfg.seed,
            ..GuidedBenchConfig::default()
        },
        None,
        // Bench all counts steps: a step's start, not its frames.
        |what, frames| {
            if frames == 0 {
                progress(what);
            }
        },
    )?;
    progress("filter");
    let subject = Subject {
        backend,
        display,
        name,
        scene,
    };
    let fovs = end_fovs(cfg);
    let fcfg = FilterBenchConfig {
        size: cfg.size,
        fovs_deg: fovs.clone(),
        k_maxes: vec![cfg.filter.k_max],
        reps: cfg.filter_reps.max(1),
        rounds: cfg.iterations.max(1),
        error_params: cfg.filter,
        seed: cfg.seed,
        ..FilterBenchConfig::default()
    };
    let filter = filter::run_with_inputs(
        &surface,
        display_name,
        backend,
        &fcfg,
        &mut progress,
        |fov, _| {
            let shot = Shot {
                size: cfg.size,
                fov,
                iterations: cfg.iterations.max(1),
                seed: cfg.seed,
            };
            guided::filter_input(&subject, shot, cfg.reference_spp.max(1))
                .map_err(|e| filter::FilterBenchError::Render(e.to_string()))
        },
    )?;
    let convergence = convergence(backend, display, name, scene, &fovs, cfg, &mut progress)?;
    let solver = solver::run(backend, cfg.solver_reps, &mut progress)?;
    let mut stage_rows = Vec::new();
    // On a GPU the three ways the picture reaches the window: the host way first (the rows
    // the targets read), then the picture kept on the GPU and read back, then written into a
    // texture there.
    let paths: &[stages::PicturePath] = if backend.is_gpu() {
        &[
            stages::PicturePath::Host,
            stages::PicturePath::Gpu,
            stages::PicturePath::Texture,
        ]
    } else {
        &[stages::PicturePath::Host]
    };
    for &fov in &fovs {
        for &path in paths {
            progress(&format!("per-stage times: {fov}°, picture {path:?}"));
            let shot = Shot {
                size: cfg.size,
                fov,
                iterations: cfg.stage_iterations,
                seed: cfg.seed.wrapping_add(21),
            };
            stage_rows.push(stages::measure(&subject, shot, &cfg.filter, 0.0, path)?);
        }
    }
    let mut report = AllReport {
        header,
        config: cfg.clone(),
        dgi,
        trace,
        guided,
        filter,
        convergence,
        solver,
        stages: stage_rows,
        paper: Vec::new(),
        targets: Vec::new(),
    };
    report.paper = paper_rows(&report);
    report.targets = target_rows(&report, datacenter_gpu(backend));
    Ok(report)
}

impl From<crate::output::FileError> for AllBenchError {
    fn from(e: crate::output::FileError) -> Self {
        Self::Output {
            path: String::new(),
            reason: e.to_string(),
        }
    }
}

/// Writes `report.md`, `report.json`, `fig5.png`, `dgi_metrics.png` and `convergence.png` into
/// `dir` (created).
pub fn write(r: &AllReport, dir: &Path) -> Result<(), AllBenchError> {
    let io = |p: &Path| {
        let path = p.display().to_string();
        move |source| AllBenchError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let file = |e: crate::output::FileError| AllBenchError::Output {
        path: dir.display().to_string(),
        reason: e.to_string(),
    };
    let md = dir.join("report.md");
    crate::output::write_bytes(&md, markdown(r).as_bytes()).map_err(file)?;
    let json = dir.join("report.json");
    let text = serde_json::to_string_pretty(r).map_err(|e| AllBenchError::Output {
        path: json.display().to_string(),
        reason: e.to_string(),
    })?;
    crate::output::write_bytes(&json, text.as_bytes()).map_err(file)?;
    let plot = |name: &str, draw: &dyn Fn(&Path) -> Result<(), AllBenchError>| {
        let path = dir.join(name);
        crate::output::replace_with(&path, |tmp| draw(tmp))
    };
    plot("fig5.png", &|p| Ok(guided::plot(&r.guided, p)?))?;
    plot("dgi_metrics.png", &|p| plot_dgi_metrics(&r.dgi, p))?;
    plot("convergence.png", &|p| plot_convergence(r, p))
}
