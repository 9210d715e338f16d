//! `raygun bench motion` arguments (`crate::bench::motion`).

use std::path::PathBuf;

use anyhow::Context;

use crate::bench::motion::{self, MotionBenchConfig, Walk};
use crate::cli::progress::{Progress, print_and_save};
use crate::display::DisplayModel;
use crate::session::guide::GuideSource;
use crate::session::replay::{ReplayOptions, ReplayPlan};

#[derive(Clone, Debug, clap::Args)]
pub struct MotionBenchArgs {
    /// Scenes (files or builtin:NAME), comma-separated.
    #[arg(
        long,
        value_name = "SCENE,…",
        value_delimiter = ',',
        default_value = "builtin:cornell,builtin:city-small"
    )]
    pub scene: Vec<String>,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Display model of the wall camera.
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// The head walk: a replay whose header names a tracked head.
    #[arg(
        long,
        value_name = "FILE",
        default_value = "tracking-replays/head-1-walk.dtrack.jsonl"
    )]
    pub replay: PathBuf,
    /// Image size of the renders (at least 16 a side).
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", value_parser = crate::cli::args::parse_size, default_value = "248,100")]
    pub size: [u32; 2],
    /// Fields of view of the ROI, degrees (square cones).
    #[arg(
        long,
        value_name = "DEG,…",
        value_delimiter = ',',
        default_value = "10,60"
    )]
    pub fov: Vec<f64>,
    /// Iterations a second of the walk.
    #[arg(long, value_name = "N", default_value_t = 4.0)]
    pub fps: f64,
    /// Compare with the reference every this many iterations.
    #[arg(long, value_name = "N", default_value_t = 8)]
    pub every: u32,
    /// Samples per pixel of each reference (one at every eye compared at).
    #[arg(long, value_name = "N", default_value_t = 256)]
    pub reference_spp: u32,
    /// The sway's amplitude, centimetres either side.
    #[arg(long, value_name = "CM", default_value_t = 1.5)]
    pub sway_cm: f64,
    /// The sway's frequency, Hz.
    #[arg(long, value_name = "HZ", default_value_t = 0.75)]
    pub sway_hz: f64,
    /// The step's length, centimetres.
    #[arg(long, value_name = "CM", default_value_t = 2.0)]
    pub step_cm: f64,
    /// Longest path (bounces).
    #[arg(long, value_name = "N", default_value_t = 4)]
    pub max_depth: u32,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// Write the report as JSON here.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write the plot of the ROI's error over the head walk here (SVG).
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Also write the Markdown tables to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// The head walk of `file`: one eye an iteration, `fps` iterations a second of it, and its
/// length in seconds.
fn head_walk(file: &std::path::Path, fps: f64) -> anyhow::Result<(Walk, f64)> {
    let (plan, _) = ReplayPlan::new(&ReplayOptions::of(file.to_owned()))
        .with_context(|| format!("--replay {}", file.display()))?;
    let source = GuideSource::from_replay(&plan, file)
        .with_context(|| format!("--replay {}", file.display()))?;
    let GuideSource::Replay { duration, .. } = &source else {
        anyhow::bail!("--replay {}: no session in it", file.display());
    };
    if source.first_eye().is_none() {
        anyhow::bail!(
            "--replay {}: its header names no tracked head (no eye to walk)",
            file.display()
        );
    }
    let seconds = *duration;
    let n = (seconds * fps).round().max(2.0) as u32;
    let eyes = (0..n)
        .map(|k| source.eye_at(k, n).expect("a head has eyes"))
        .collect();
    Ok((
        Walk {
            name: "head walk",
            eyes,
        },
        seconds,
    ))
}

/// `raygun bench motion` (`bench::motion`).
pub fn run(args: &MotionBenchArgs) -> anyhow::Result<()> {
    for (flag, path) in [
        ("--json", &args.json),
        ("--plot", &args.plot),
        ("--out", &args.out),
    ] {
        if let Some(p) = path {
            crate::output::check_writable(p).with_context(|| flag.to_string())?;
        }
    }
    let (walk, seconds) = head_walk(&args.replay, args.fps)?;
    let cfg = MotionBenchConfig {
        size: args.size,
        fovs_deg: args.fov.clone(),
        fps: args.fps,
        seconds,
        every: args.every,
        reference_spp: args.reference_spp,
        sway_amplitude_m: args.sway_cm / 100.0,
        sway_hz: args.sway_hz,
        step_m: args.step_cm / 100.0,
        max_depth: args.max_depth,
        ..MotionBenchConfig::default()
    };
    cfg.validate()?;
    let display = DisplayModel::open(&args.display).context("--display")?.0;
    let backend = args.backend.select()?;
    let planned = motion::planned_iterations(&cfg) * args.scene.len() as u64;
    let mut bar = Progress::new(false, "bench motion", Some(planned), "iterations");
    let mut done = 0u64;
    let mut reports = Vec::new();
    for name in &args.scene {
        let scene = crate::cli::scene::load_scene(name, None, args.access)?;
        let short = name.strip_prefix("builtin:").unwrap_or(name);
        let report = motion::run(
            &backend,
            &display,
            (short, &scene),
            &cfg,
            &walk,
            |what, n| {
                done += u64::from(n);
                bar.note(&format!("{short}: {what}"));
                bar.set(done.min(planned));
            },
        )?;
        reports.push(report);
    }
    bar.finish();
    print_and_save(&motion::markdown(&reports), args.out.as_deref())?;
    if let Some(path) = &args.json {
        motion::write_text(path, &serde_json::to_string_pretty(&reports)?, "--json")?;
    }
    if let Some(path) = &args.plot {
        motion::write_text(path, &motion::plot_svg(&reports), "--plot")?;
    }
    Ok(())
}
