//! `raygun bench …` arguments.

use std::path::PathBuf;

use anyhow::Context;

use crate::cli::progress::{Progress, bench_progress, print_and_save};

use crate::bench::dgi::{self, DgiBenchConfig};
use crate::cluster::Cluster;
use crate::display::DisplayModel;
use crate::gpu::{Backend, BackendChoice};
use crate::roi::dgi::{Falloff, Surface};

#[derive(Clone, Debug, clap::Subcommand)]
pub enum BenchCommand {
    /// The GPU adapter the benchmarks run on: name, API, driver, subgroup sizes, limits and
    /// features (every adapter found, the chosen one first), and this machine's CPU.
    Adapter(AdapterArgs),
    /// DGI time per metric and backend, and the cheaper metrics' error against the exact one.
    Dgi(DgiBenchArgs),
    /// Filter time (exact and fast) and error against a reference inside and outside the ROI.
    Filter(crate::cli::filter::FilterBenchArgs),
    /// The denoisers measured against a high-spp reference of a guided render: off, the
    /// paper's filter, raygun's interactive denoiser and Intel Open Image Denoise, by relative
    /// MSE and FLIP inside and outside the ROI at equal iterations and equal time, and their
    /// time per picture up to 4K.
    Denoise(crate::cli::denoise_bench::DenoiseBenchArgs),
    /// A moving eye on the wall (a tracked head's walk, a sway, a 2 cm step) with the
    /// accumulation reused and restarted at each move: the ROI's and the periphery's error
    /// against a reference at each eye, the share carried and the cost of a move.
    Motion(crate::cli::motion_bench::MotionBenchArgs),
    /// Scheduling (mask, compaction, indirect arguments) per FOV, GPU and CPU twin.
    Schedule(ScheduleBenchArgs),
    /// Full-frame path tracing: ms per frame, ms per megasample and rays per second.
    Trace(TraceBenchArgs),
    /// The paper's benchmark: guided vs full-frame per FOV (share sampled, ms per iteration,
    /// speed-up, equal-time RMSE in the ROI) and the Figure 5 plot.
    Guided(GuidedBenchArgs),
    /// A guided iteration at the display canvas's own resolution (HORNET: 13519×5457, 73.8 MP)
    /// per FOV: ms per iteration (DGI, schedule, trace), share sampled, memory by stage.
    Native(NativeBenchArgs),
    /// Every benchmark plus convergence curves (RMSE vs time, guided vs full frame, filtered
    /// and not), DGI metrics and the closest-point solver (time vs error), per-stage times, and
    /// the paper's table and the targets beside ours, into DIR: report.md, report.json,
    /// fig5.png, dgi_metrics.png, convergence.png.
    All(AllBenchArgs),
    /// The accumulation's read-back from the GPU (16 bytes a pixel) through a fresh mappable
    /// buffer and through a kept one, side by side: ms and GB/s.
    Readback(ReadbackArgs),
    /// One shown picture of a guided render by the host path (read back, filter, convert on
    /// the CPU), the GPU-resident one (filter and convert on the GPU, read back 8 bits) and
    /// into a texture on the GPU (nothing read back), side by side: ms per picture, stage
    /// times, bytes moved and the window's upload of the bytes.
    Picture(PictureArgs),
}

#[derive(Clone, Debug, clap::Args)]
pub struct PictureArgs {
    /// Scene (a file or builtin:NAME).
    #[arg(long, value_name = "SCENE", default_value = "builtin:cornell")]
    pub scene: String,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Display model (the paper's setup: HORNET).
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Image size in pixels, W,H.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", default_value = "3840,2160", value_parser = crate::cli::args::parse_size)]
    pub size: [u32; 2],
    /// The ROI's field of view, degrees (a square cone).
    #[arg(long, value_name = "DEG", default_value_t = 10.0)]
    pub fov: f64,
    /// Rounds (each runs a frame, then shows its picture both ways).
    #[arg(long, default_value_t = 9)]
    pub rounds: u32,
    /// Exposure of the shown picture, stops.
    #[arg(
        long,
        value_name = "STOPS",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub exposure: f32,
    #[command(flatten)]
    pub filter: crate::cli::filter::FilterArgs,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    pub json: bool,
    /// Also write the output to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// `raygun bench picture` (a GPU is required: the CPU twin has one path).
fn run_picture(args: &PictureArgs) -> anyhow::Result<()> {
    let display = DisplayModel::open(&args.display).context("--display")?.0;
    let filter = args.filter.params()?;
    if !args.exposure.is_finite() {
        anyhow::bail!(
            "--exposure must be a finite number of stops, not {}",
            args.exposure
        );
    }
    let ctx = crate::gpu::GpuContext::new()?;
    let backend = Backend::Gpu(Box::new(ctx));
    let mut scenes =
        crate::cli::scene::load_scenes(std::slice::from_ref(&args.scene), None, args.access)?;
    let (name, scene) = scenes.remove(0);
    let cfg = crate::bench::picture::PictureConfig {
        size: args.size,
        fov_deg: args.fov,
        rounds: args.rounds,
        filter,
        exposure: args.exposure,
        seed: 1,
    };
    let report = crate::bench::picture::run(&backend, &display, &name, &scene, &cfg)?;
    let text = if args.json {
        serde_json::to_string_pretty(&report)?
    } else {
        crate::bench::picture::markdown(&report)
    };
    print_and_save(&text, args.out.as_deref())
}

#[derive(Clone, Debug, clap::Args)]
pub struct ReadbackArgs {
    /// Image size in pixels, W,H. Its accumulation is read back.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", default_value = "3840,2160", value_parser = crate::cli::args::parse_size)]
    pub size: [u32; 2],
    /// Rounds (each reads back both ways).
    #[arg(long, default_value_t = 9)]
    pub rounds: u32,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    pub json: bool,
    /// Also write the output to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// `raygun bench readback` (a GPU is required: there is nothing to read back on the CPU).
fn run_readback(args: &ReadbackArgs) -> anyhow::Result<()> {
    let ctx = crate::gpu::GpuContext::new()?;
    let report = crate::bench::readback::run(&ctx, args.size, args.rounds)?;
    let text = if args.json {
        serde_json::to_string_pretty(&report)?
    } else {
        crate::bench::readback::markdown(&report)
    };
    print_and_save(&text, args.out.as_deref())
}

#[derive(Clone, Debug, clap::Args)]
pub struct AdapterArgs {
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Also write the output to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// `raygun bench adapter`.
fn run_adapter(args: &AdapterArgs) -> anyhow::Result<()> {
    let chosen = crate::gpu::GpuContext::new().map(|ctx| ctx.report());
    let all = crate::gpu::list_adapters();
    let report = serde_json::json!({
        "chosen": chosen.as_ref().ok(),
        "error": chosen.as_ref().err().map(ToString::to_string),
        "adapters": all,
        "cpu": crate::bench::cpu_description(),
    });
    let text = if args.json {
        serde_json::to_string_pretty(&report)?
    } else {
        let mut t = String::new();
        match &chosen {
            Ok(c) => {
                t += &format!(
                    "adapter: {} ({}, {}), driver {} {}\nsubgroup size {}–{}\n",
                    c["name"].as_str().unwrap_or("?"),
                    c["backend"].as_str().unwrap_or("?"),
                    c["device_type"].as_str().unwrap_or("?"),
                    c["driver"].as_str().unwrap_or("?"),
                    c["driver_info"].as_str().unwrap_or("?"),
                    c["subgroup_min_size"],
                    c["subgroup_max_size"]
                );
                for (k, v) in c["limits"].as_object().into_iter().flatten() {
                    t += &format!("limit {k} = {v}\n");
                }
                for (k, v) in c["features"].as_object().into_iter().flatten() {
                    t += &format!("feature {k}: {v}\n");
                }
            }
            Err(e) => t += &format!("no adapter: {e}\n"),
        }
        for a in &all {
            t += &format!("found: {a}\n");
        }
        t += &format!("cpu: {}", report["cpu"].as_str().unwrap_or("?"));
        t
    };
    print_and_save(&text, args.out.as_deref())
}

#[derive(Clone, Debug, clap::Args)]
pub struct AllBenchArgs {
    /// Small settings that finish in minutes on the CPU backend (160×90, 10° and 60°).
    #[arg(long)]
    pub quick: bool,
    /// Output directory (created).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Image size in pixels, W,H. Default: the mode's (quick 160×90, full 3840×2160).
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", value_parser = crate::cli::args::parse_size)]
    pub size: Option<[u32; 2]>,
    /// Scene (file or builtin:NAME).
    #[arg(long, value_name = "SCENE", default_value = "builtin:cornell")]
    pub scene: String,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Display model (the paper's setup: HORNET).
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// Guided iterations of the guided benchmark and of each convergence curve, overriding
    /// the mode's (quick 128, full 100): fewer for a report that must fit a short run.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub iterations: Option<u32>,
    /// Samples per pixel of the converged references the errors are measured against,
    /// overriding the mode's (1024).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub reference_spp: Option<u32>,
}

fn run_all_bench(args: &AllBenchArgs) -> anyhow::Result<()> {
    let backend = args.backend.select()?;
    let display = DisplayModel::open(&args.display)?.0;
    let scene = crate::cli::scene::load_scene(&args.scene, None, args.access)?;
    let name = args.scene.trim_start_matches("builtin:");
    let mut cfg = crate::bench::all::AllConfig::new(args.quick, args.size);
    cfg.iterations = args.iterations.unwrap_or(cfg.iterations);
    cfg.reference_spp = args.reference_spp.unwrap_or(cfg.reference_spp);
    let steps = crate::bench::all::progress_steps(&cfg, name, matches!(backend, Backend::Gpu(_)));
    let (bar, progress) = bench_progress(false, steps);
    let report = crate::bench::all::run(
        &backend,
        &display,
        display.name(),
        name,
        &scene,
        &cfg,
        progress,
    )?;
    bar.finish_and_clear();
    crate::bench::all::write(&report, &args.out)?;
    eprintln!(
        "raygun bench all: wrote report.md, report.json, fig5.png, dgi_metrics.png, convergence.png to {}",
        args.out.display()
    );
    Ok(())
}

#[derive(Clone, Debug, clap::Args)]
pub struct GuidedBenchArgs {
    /// Scenes (files or builtin:NAME).
    #[arg(
        long,
        value_name = "SCENE,…",
        value_delimiter = ',',
        default_value = "builtin:cornell,builtin:city"
    )]
    pub scene: Vec<String>,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Display model (the paper's setup: HORNET).
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Image size in pixels, W,H, or `native`: the display canvas's own pixel size.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H|native", value_parser = crate::cli::args::parse_size_or_native, default_value = "3840,2160")]
    pub size: [u32; 2],
    /// Fields of view, degrees.
    #[arg(
        long,
        value_name = "DEG,…",
        value_delimiter = ',',
        default_value = "10,20,30,40,50,60"
    )]
    pub fov: Vec<f64>,
    /// Guided iterations per FOV.
    #[arg(long, value_name = "N", default_value_t = 100)]
    pub iterations: u32,
    /// Samples per pixel of the converged reference; default 16 × --iterations, from 64 to
    /// 1024 (the renders it judges have at most --iterations samples a pixel).
    #[arg(long, value_name = "N")]
    pub reference_spp: Option<u32>,
    /// Lowest sampling probability (paper preset 0).
    #[arg(long, value_name = "P", default_value_t = 0.0)]
    pub p_min: f32,
    /// List orders to measure (coherent, scattered).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "coherent")]
    pub order: Vec<crate::schedule::Order>,
    /// Environment (R,G,B or an .hdr/.exr file); default white.
    #[arg(long, value_name = "R,G,B|FILE")]
    pub env: Option<String>,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    pub json: bool,
    /// Also write the output to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Write the Figure 5 plot (PNG) here.
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// `wall`: every render of the benchmark through the wall camera from --eye (its pixels
    /// off the tiles never traced); default: the scene's pinhole stretched over the canvas.
    #[arg(long, value_name = "wall")]
    pub camera: Option<String>,
    #[command(flatten)]
    pub wall: crate::cli::wall::WallArgs,
    /// With --cluster (under `mpirun -np N`): the guided iterations across the ranks (strong
    /// scaling: ms per iteration, trace and exchange per rank, bytes per iteration, the DGI
    /// computed against broadcast), the exact exchange of larger images for 1 to
    /// --model-ranks ranks, and the link model. Takes the first --scene.
    #[command(flatten)]
    pub cluster: crate::cli::cluster::ClusterArgs,
    /// With --cluster: the ranks as N threads of this one process, exchanging through memory
    /// (the tests' in-process seam) instead of MPI — no `cluster` feature or mpirun needed, so
    /// a GPU machine without MPI measures a GPU rank's rate for the model this way. The
    /// exchange's times are then memory copies, not a link's.
    #[arg(long, value_name = "N", requires = "cluster")]
    pub cluster_threads: Option<usize>,
    /// Image sizes of the exchange count and the model (repeatable; default 3840,2160 and
    /// HORNET's native 13519,5457).
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", value_parser = crate::cli::args::parse_size, requires = "cluster")]
    pub model_size: Vec<[u32; 2]>,
    /// Most ranks of the exchange count.
    #[arg(long, value_name = "N", default_value_t = 35, requires = "cluster")]
    pub model_ranks: usize,
    /// The model's link speed per rank, Gbit/s (full duplex).
    #[arg(
        long,
        value_name = "GBPS",
        default_value_t = 100.0,
        requires = "cluster"
    )]
    pub link_gbps: f64,
}

/// `bench guided --cluster`: the cluster benchmark (`bench::cluster`).
fn run_cluster_bench(args: &GuidedBenchArgs) -> anyhow::Result<()> {
    if !(args.link_gbps.is_finite() && args.link_gbps > 0.0) {
        anyhow::bail!("--link-gbps must be a positive number of Gbit/s");
    }
    if args.model_ranks == 0 {
        anyhow::bail!("--model-ranks must be at least 1");
    }
    if args.camera.is_some() {
        anyhow::bail!("bench guided --cluster measures the pinhole (no --camera)");
    }
    let text = match args.cluster_threads {
        Some(0) => anyhow::bail!("--cluster-threads must be at least 1"),
        Some(n) => {
            args.cluster.validate()?;
            let timeout = std::time::Duration::from_secs_f64(args.cluster.cluster_timeout);
            let mut done = std::thread::scope(|s| {
                let ranks: Vec<_> = crate::cluster::exchange::InProcess::job(n)
                    .into_iter()
                    .map(|end| {
                        s.spawn(move || {
                            let rank = crate::cluster::exchange::Exchange::rank(&end);
                            let mut c = Cluster::new(Box::new(end), timeout);
                            cluster_bench(&mut c, args)
                                .with_context(|| format!("rank {rank} (a thread)"))
                        })
                    })
                    .collect();
                ranks
                    .into_iter()
                    .map(|h| h.join().expect("a rank's thread returns"))
                    .collect::<anyhow::Result<Vec<_>>>()
            })?;
            done.swap_remove(0)
        }
        None => {
            let mut c = crate::cli::cluster::start(&args.cluster)?;
            let text = cluster_bench(&mut c, args);
            crate::cli::cluster::or_abort(&c, text)
        }
    };
    match text {
        Some(text) => print_and_save(&text, args.out.as_deref()),
        None => Ok(()),
    }
}

/// The cluster benchmark on this rank of the job `c`: the report's text on rank 0.
fn cluster_bench(c: &mut Cluster, args: &GuidedBenchArgs) -> anyhow::Result<Option<String>> {
    use crate::cli::cluster::{check, identity};
    let scene_name = args.scene[0].clone();
    let prepared = (|| -> anyhow::Result<_> {
        let display = DisplayModel::open(&args.display).context("--display")?.0;
        let size = crate::cli::args::resolve_size(args.size, &args.display)?;
        let scene = crate::cli::scene::load_scene(&scene_name, args.env.as_deref(), args.access)?;
        let backend = args.backend.select()?;
        Ok((display, size, scene, backend))
    })();
    let mine = match &prepared {
        Ok((d, size, s, b)) => identity(
            c.ranks(),
            &[
                ("command", "bench guided --cluster".to_owned()),
                ("display model", crate::cli::cluster::model_field(d)),
                (
                    "scene",
                    format!(
                        "{scene_name} ({:016x})",
                        crate::cluster::handshake::scene_hash(s)
                    ),
                ),
                (
                    "settings",
                    format!("{size:?} {:?} {}", args.fov, args.iterations),
                ),
                ("trace backend", crate::cli::cluster::trace_backend(b)),
            ],
        ),
        Err(e) => Err(crate::cluster::handshake::StartupFailure(
            crate::cli::error_chain(e),
        )),
    };
    check(c, mine)?;
    let (display, size, scene, backend) = prepared?;
    let device = format!(
        "{} rank(s){}, each on {}",
        c.ranks(),
        if args.cluster_threads.is_some() {
            " as threads of one process (the in-memory exchange)"
        } else {
            ""
        },
        match &backend {
            Backend::Gpu(ctx) => ctx.describe(),
            Backend::Cpu => format!("the CPU twins, {}", crate::bench::cpu_description()),
        }
    );
    let gpu = match backend {
        Backend::Gpu(ctx) => Some(std::sync::Arc::from(ctx)),
        Backend::Cpu => None,
    };
    let model_sizes = if args.model_size.is_empty() {
        vec![[3840, 2160], [13519, 5457]]
    } else {
        args.model_size.clone()
    };
    let cfg = crate::bench::cluster::ClusterBenchConfig {
        scene: scene_name,
        size,
        fovs_deg: args.fov.clone(),
        iterations: args.iterations,
        max_depth: crate::trace::path::DEFAULT_MAX_DEPTH,
        model_sizes,
        model_ranks: args.model_ranks,
        link_gbps: args.link_gbps,
    };
    // GPU ranks draw the whole schedule on their GPUs: no masks in the model's link.
    let gpu_ranks = gpu.is_some();
    let Some(scaling) = crate::bench::cluster::scaling(c, &scene, &display, &cfg, gpu)? else {
        return Ok(None);
    };
    let exchange = crate::bench::cluster::exchange(
        &display,
        &cfg.model_sizes,
        &cfg.fovs_deg,
        cfg.model_ranks,
        gpu_ranks,
        |what| eprintln!("raygun: {what}"),
    )?;
    let report = crate::bench::cluster::ClusterBenchReport {
        device,
        config: cfg,
        scaling,
        exchange,
    };
    Ok(Some(if args.json {
        serde_json::to_string_pretty(&report)?
    } else {
        crate::bench::cluster::markdown(&report)
    }))
}

#[derive(Clone, Debug, clap::Args)]
pub struct NativeBenchArgs {
    /// Scenes (files or builtin:NAME).
    #[arg(
        long,
        value_name = "SCENE,…",
        value_delimiter = ',',
        default_value = "builtin:cornell"
    )]
    pub scene: Vec<String>,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Display model, rendered at its canvas's own pixel size.
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Fields of view, degrees.
    #[arg(
        long,
        value_name = "DEG,…",
        value_delimiter = ',',
        default_value = "10,60"
    )]
    pub fov: Vec<f64>,
    /// Timed iterations per FOV (after the frame that computes the DGI).
    #[arg(long, value_name = "N", default_value_t = 5)]
    pub iterations: u32,
    /// Lowest sampling probability (paper preset 0).
    #[arg(long, value_name = "P", default_value_t = 0.0)]
    pub p_min: f32,
    /// Environment (R,G,B or an .hdr/.exr file); default white.
    #[arg(long, value_name = "R,G,B|FILE")]
    pub env: Option<String>,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    pub json: bool,
    /// Also write the output to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// `wall`: through the wall camera from --eye (pixels off the tiles never traced); default:
    /// the scene's pinhole stretched over the canvas.
    #[arg(long, value_name = "wall")]
    pub camera: Option<String>,
    #[command(flatten)]
    pub wall: crate::cli::wall::WallArgs,
}

fn run_native_bench(args: &NativeBenchArgs) -> anyhow::Result<()> {
    let display = DisplayModel::open(&args.display).context("--display")?.0;
    if let Some(c) = args.camera.as_deref()
        && c != crate::cli::wall::WALL_CAMERA
    {
        anyhow::bail!("--camera {c}: bench native measures the pinhole (default) or wall");
    }
    let wall = crate::cli::wall::wall_spec(args.camera.as_deref(), &args.wall, Some(&display))?;
    if !(0.0..=1.0).contains(&args.p_min) {
        anyhow::bail!(
            "--p-min must be a probability from 0 to 1, not {}",
            args.p_min
        );
    }
    let backend = args.backend.select()?;
    let scenes = crate::cli::scene::load_scenes(&args.scene, args.env.as_deref(), args.access)?;
    let cfg = crate::bench::native::NativeBenchConfig {
        fovs_deg: args.fov.clone(),
        iterations: args.iterations.max(1),
        p_min: args.p_min,
        ..Default::default()
    };
    let (bar, progress) = bench_progress(args.json, (scenes.len() * cfg.fovs_deg.len()) as u64);
    let report =
        crate::bench::native::run(&backend, &display, &scenes, &cfg, wall.as_ref(), progress)?;
    bar.finish_and_clear();
    let device = crate::bench::device(&backend);
    let text = if args.json {
        serde_json::to_string_pretty(&serde_json::json!({
            "device": device,
            "config": cfg,
            "report": report,
        }))?
    } else {
        crate::bench::native::markdown(&report, &device)
    };
    print_and_save(&text, args.out.as_deref())?;
    Ok(())
}

fn run_guided_bench(args: &GuidedBenchArgs) -> anyhow::Result<()> {
    if args.cluster.cluster {
        return run_cluster_bench(args);
    }
    let display = DisplayModel::open(&args.display).context("--display")?.0;
    if let Some(c) = args.camera.as_deref()
        && c != crate::cli::wall::WALL_CAMERA
    {
        anyhow::bail!("--camera {c}: bench guided measures the pinhole (default) or wall");
    }
    let wall = crate::cli::wall::wall_spec(args.camera.as_deref(), &args.wall, Some(&display))?;
    let backend = args.backend.select()?;
    let scenes = crate::cli::scene::load_scenes(&args.scene, args.env.as_deref(), args.access)?;
    let cfg = crate::bench::guided::GuidedBenchConfig {
        size: crate::cli::args::resolve_size(args.size, &args.display)?,
        fovs_deg: args.fov.clone(),
        iterations: args.iterations,
        reference_spp: args
            .reference_spp
            .unwrap_or_else(|| crate::bench::guided::default_reference_spp(args.iterations))
            .max(1),
        p_min: args.p_min,
        orders: args.order.clone(),
        ..Default::default()
    };
    // Frames, as `render` counts samples: the reference alone is minutes at the paper's size.
    let mut planned = crate::bench::guided::planned_frames(&cfg, scenes.len());
    let mut bar = Progress::new(args.json, "bench guided", Some(planned), "frames");
    let mut done = 0u64;
    let report = crate::bench::guided::run(
        &backend,
        &display,
        &scenes,
        &cfg,
        wall.as_ref(),
        |what, frames| {
            done += u64::from(frames);
            if done > planned {
                planned = done;
                bar.lengthen(planned);
            }
            bar.note(what);
            bar.set(done);
        },
    )?;
    bar.finish();
    let text = if args.json {
        serde_json::to_string_pretty(&report)?
    } else {
        crate::bench::guided::markdown(&report)
    };
    print_and_save(&text, args.out.as_deref())?;
    if let Some(plot) = &args.plot {
        crate::output::replace_with(plot, |tmp| {
            crate::bench::guided::plot(&report, tmp).map_err(anyhow::Error::from)
        })?;
    }
    Ok(())
}

#[derive(Clone, Debug, clap::Args)]
pub struct TraceBenchArgs {
    /// Scenes to measure (files or builtin:NAME).
    #[arg(
        long,
        value_name = "SCENE,…",
        value_delimiter = ',',
        default_value = "builtin:cornell,builtin:city"
    )]
    pub scene: Vec<String>,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Image size in pixels, W,H.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", value_parser = crate::cli::args::parse_size, default_value = "3840,2160")]
    pub size: [u32; 2],
    /// Timed frames of one sample per pixel (median reported).
    #[arg(long, value_name = "N", default_value_t = 20)]
    pub spp: u32,
    /// Maximum path vertices.
    #[arg(long, value_name = "N", default_value_t = crate::trace::path::DEFAULT_MAX_DEPTH)]
    pub max_depth: u32,
    /// Environment (R,G,B or an .hdr/.exr file); default white.
    #[arg(long, value_name = "R,G,B|FILE")]
    pub env: Option<String>,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// Print JSON instead of a Markdown table.
    #[arg(long)]
    pub json: bool,
    /// Also write the output to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// `wall`: measure the wall camera beside the pinhole, frames interleaved (needs --eye
    /// and --display); default: the pinhole alone.
    #[arg(long, value_name = "pinhole|wall")]
    pub camera: Option<String>,
    /// The wall camera's display model (a file or a built-in name).
    #[arg(long, value_name = "MODEL")]
    pub display: Option<String>,
    #[command(flatten)]
    pub wall: crate::cli::wall::WallArgs,
    /// Time these variants of the GPU trace kernel side by side, their frames interleaved:
    /// where the traversal stack lives (`private`, as written; `function`, zeroed at every
    /// ray; `workgroup` memory), then optionally `+unchecked` (without wgpu's run-time
    /// checks), `+wgN` (N = 32, 64, 128 or 256 threads a workgroup; 64 otherwise) and
    /// `+regenG` (paths regenerated in launches of at most G workgroups) or `+split[N]` (full
    /// frames in the wavefront split, N paths a chunk), and `+vote[P]` (triangle tests
    /// postponed by subgroup vote at P %, 20 otherwise), e.g.
    /// `function,private+unchecked+wg32,private+regen1056,private+split,private+vote`. Same pictures, different code;
    /// variants the adapter cannot run are named and left out. Default: the one
    /// `RAYGUN_TRACE_KERNEL` names, else `private`.
    #[cfg(feature = "kernel-lab")]
    #[arg(long, value_name = "VARIANT,…", value_delimiter = ',')]
    pub trace_kernel: Vec<crate::gpu::variant::TraceVariant>,
}

fn run_trace_bench(args: &TraceBenchArgs) -> anyhow::Result<()> {
    let camera = args.camera.as_deref().filter(|c| *c != "pinhole");
    if let Some(c) = camera
        && c != crate::cli::wall::WALL_CAMERA
    {
        anyhow::bail!("--camera {c}: bench trace measures pinhole or wall");
    }
    let model = match (&args.display, camera) {
        (Some(d), Some(_)) => Some(DisplayModel::open(d).context("--display")?.0),
        _ => None,
    };
    let wall = crate::cli::wall::wall_spec(camera, &args.wall, model.as_ref())?;
    let backend = args.backend.select()?;
    let scenes = crate::cli::scene::load_scenes(&args.scene, args.env.as_deref(), args.access)?;
    let cfg = crate::bench::trace::TraceBenchConfig {
        size: args.size,
        frames: args.spp.max(1),
        max_depth: args.max_depth.max(1),
        ..Default::default()
    };
    let (bar, progress) = bench_progress(args.json, scenes.len() as u64);
    #[cfg(not(feature = "kernel-lab"))]
    let rows = crate::bench::trace::run(&backend, &scenes, &cfg, wall.as_ref(), progress)?;
    #[cfg(feature = "kernel-lab")]
    let (rows, refused) = {
        let (kernels, refused) = lab_kernels(&args.trace_kernel, &backend)?;
        let rows = crate::bench::trace::run_kernels(
            &backend,
            &scenes,
            &cfg,
            wall.as_ref(),
            &kernels,
            progress,
        )?;
        (rows, refused)
    };
    bar.finish_and_clear();
    let device = crate::bench::device(&backend);
    let text = if args.json {
        #[cfg_attr(not(feature = "kernel-lab"), allow(unused_mut))]
        let mut json = serde_json::json!({
            "device": device,
            "config": cfg,
            "rows": rows,
        });
        #[cfg(feature = "kernel-lab")]
        {
            json["kernels_not_run"] = serde_json::json!(refused);
        }
        serde_json::to_string_pretty(&json)?
    } else {
        #[cfg_attr(not(feature = "kernel-lab"), allow(unused_mut))]
        let mut md = crate::bench::trace::markdown(&rows, &device);
        #[cfg(feature = "kernel-lab")]
        for r in &refused {
            md += &format!("\nNot run on this adapter: {r}.\n");
        }
        md
    };
    print_and_save(&text, args.out.as_deref())?;
    Ok(())
}

/// The kernel lab's `--trace-kernel` variants this adapter can run, and why each other one
/// cannot (a workgroup stack over its workgroup memory), printed: left out and named, so that
/// one list serves every adapter. An error where it can run none of them.
#[cfg(feature = "kernel-lab")]
fn lab_kernels(
    asked: &[crate::gpu::variant::TraceVariant],
    backend: &Backend,
) -> anyhow::Result<(Vec<crate::gpu::variant::TraceVariant>, Vec<String>)> {
    let mut kernels = Vec::new();
    let mut refused = Vec::new();
    for &v in asked {
        match backend {
            Backend::Gpu(ctx) => match v.check(&ctx.limits, ctx.device.features()) {
                Ok(()) => kernels.push(v),
                Err(e) => refused.push(e.to_string()),
            },
            // `bench::trace::run_kernels` refuses variants on the CPU, naming the flag.
            Backend::Cpu => kernels.push(v),
        }
    }
    for r in &refused {
        eprintln!("raygun bench trace: not run: {r}");
    }
    if !asked.is_empty() && kernels.is_empty() {
        anyhow::bail!("--trace-kernel: this adapter can run none of the variants asked for");
    }
    Ok((kernels, refused))
}

#[derive(Clone, Debug, clap::Args)]
pub struct DgiBenchArgs {
    /// Display model (the paper's setup: HORNET).
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Image size in pixels, W,H.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", value_parser = crate::cli::args::parse_size, default_value = "3840,2160")]
    pub size: [u32; 2],
    /// Fields of view to measure, degrees (square cones).
    #[arg(
        long,
        value_name = "DEG,…",
        value_delimiter = ',',
        default_value = "10,30,60"
    )]
    pub fov: Vec<f64>,
    /// GPU repetitions per measurement (median reported).
    #[arg(long, default_value_t = 50)]
    pub reps: u32,
    /// CPU repetitions per measurement.
    #[arg(long, default_value_t = 3)]
    pub cpu_reps: u32,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// Print JSON instead of a Markdown table.
    #[arg(long)]
    pub json: bool,
    /// Also write the output to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// Checks every file and folder a benchmark will write, and the settings that would make its
/// figures meaningless, before any work.
fn check_before(cmd: &BenchCommand) -> anyhow::Result<()> {
    let file_out = match cmd {
        BenchCommand::Adapter(a) => a.out.as_deref(),
        BenchCommand::Dgi(a) => a.out.as_deref(),
        BenchCommand::Filter(a) => a.out.as_deref(),
        BenchCommand::Denoise(a) => {
            if let Some(p) = &a.crops
                && crate::output::check_image_path(p).context("--crops")?
                    != crate::output::Format::Png
            {
                anyhow::bail!("--crops {}: the crops are a PNG", p.display());
            }
            if let Some(p) = &a.crops {
                crate::output::check_writable(p).context("--crops")?;
            }
            if let Some(p) = &a.json {
                crate::output::check_writable(p).context("--json")?;
            }
            a.out.as_deref()
        }
        BenchCommand::Motion(a) => a.out.as_deref(),
        BenchCommand::Schedule(a) => a.out.as_deref(),
        BenchCommand::Trace(a) => a.out.as_deref(),
        BenchCommand::Guided(a) => a.out.as_deref(),
        BenchCommand::Native(a) => a.out.as_deref(),
        BenchCommand::Readback(a) => a.out.as_deref(),
        BenchCommand::Picture(a) => a.out.as_deref(),
        BenchCommand::All(a) => {
            crate::output::check_folder(&a.out).context("--out")?;
            None
        }
    };
    if let Some(p) = file_out {
        crate::output::check_writable(p).context("--out")?;
    }
    if let BenchCommand::Guided(a) = cmd {
        if let Some(p) = &a.plot
            && crate::output::check_image_path(p).context("--plot")? != crate::output::Format::Png
        {
            anyhow::bail!("--plot {}: the plot is a PNG", p.display());
        }
        if a.iterations == 0 {
            anyhow::bail!("--iterations must be at least 1 (every figure is per iteration)");
        }
        if a.reference_spp == Some(0) {
            anyhow::bail!("--reference-spp must be at least 1");
        }
        if !(0.0..=1.0).contains(&a.p_min) {
            anyhow::bail!("--p-min must be a probability from 0 to 1, not {}", a.p_min);
        }
    }
    Ok(())
}

pub fn run(cmd: &BenchCommand) -> anyhow::Result<()> {
    check_before(cmd)?;
    match cmd {
        BenchCommand::Adapter(args) => run_adapter(args),
        BenchCommand::Filter(args) => crate::cli::filter::run_bench(args),
        BenchCommand::Denoise(args) => crate::cli::denoise_bench::run(args),
        BenchCommand::Motion(args) => crate::cli::motion_bench::run(args),
        BenchCommand::Schedule(args) => run_schedule(args),
        BenchCommand::Trace(args) => run_trace_bench(args),
        BenchCommand::Guided(args) => run_guided_bench(args),
        BenchCommand::Native(args) => run_native_bench(args),
        BenchCommand::All(args) => run_all_bench(args),
        BenchCommand::Readback(args) => run_readback(args),
        BenchCommand::Picture(args) => run_picture(args),
        BenchCommand::Dgi(args) => {
            let model = DisplayModel::open(&args.display)?.0;
            let surface = Surface::from_model(&model);
            let backend = args.backend.select()?;
            let config = DgiBenchConfig {
                size: args.size,
                fovs_deg: args.fov.clone(),
                gpu_reps: args.reps.max(1),
                cpu_reps: args.cpu_reps.max(1),
                falloff: Falloff::default(),
                ..DgiBenchConfig::default()
            };
            let (bar, progress) = bench_progress(args.json, 3 * config.fovs_deg.len() as u64);
            let report = dgi::run(&surface, model.name(), &backend, &config, progress)?;
            bar.finish_and_clear();
            let text = if args.json {
                serde_json::to_string_pretty(&report)?
            } else {
                report.to_markdown()
            };
            print_and_save(&text, args.out.as_deref())
        }
    }
}

/// `raygun bench schedule` arguments.
#[derive(Clone, Debug, clap::Args)]
pub struct ScheduleBenchArgs {
    /// Display model (the paper's setup: HORNET).
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Image size in pixels, W,H.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", value_parser = crate::cli::args::parse_size, default_value = "3840,2160")]
    pub size: [u32; 2],
    /// Fields of view, degrees (square cones).
    #[arg(
        long,
        value_name = "DEG,…",
        value_delimiter = ',',
        default_value = "10,20,30,40,50,60"
    )]
    pub fov: Vec<f64>,
    /// Lowest sampling probability (paper preset 0).
    #[arg(long, default_value_t = 0.0)]
    pub p_min: f32,
    /// List orders to time.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "coherent,scattered"
    )]
    pub order: Vec<crate::schedule::Order>,
    /// GPU iterations per measurement (median reported).
    #[arg(long, default_value_t = 50)]
    pub reps: u32,
    /// CPU iterations per measurement.
    #[arg(long, default_value_t = 5)]
    pub cpu_reps: u32,
    /// `cpu` measures the twin only; `gpu` (the default: this benchmark is about the kernel)
    /// measures both, on any adapter; `auto` skips software adapters, as elsewhere.
    #[arg(long, value_enum, default_value_t = BackendChoice::Gpu)]
    pub backend: BackendChoice,
    /// Print JSON instead of a Markdown table.
    #[arg(long)]
    pub json: bool,
    /// Also write the output to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// `raygun bench schedule`.
fn run_schedule(args: &ScheduleBenchArgs) -> anyhow::Result<()> {
    let model = DisplayModel::open(&args.display)?.0;
    let surface = Surface::from_model(&model);
    let backend = Backend::select(args.backend)?;
    let config = crate::bench::schedule::ScheduleBenchConfig {
        size: args.size,
        fovs_deg: args.fov.clone(),
        p_min: crate::schedule::validate_p_min(args.p_min)?,
        orders: args.order.clone(),
        gpu_reps: args.reps.max(1),
        cpu_reps: args.cpu_reps.max(1),
        ..crate::bench::schedule::ScheduleBenchConfig::default()
    };
    let gpu = u64::from(matches!(backend, Backend::Gpu(_)));
    let steps = config.fovs_deg.len() as u64 * (1 + config.orders.len() as u64 * (1 + gpu));
    let (bar, progress) = bench_progress(args.json, steps);
    let report = crate::bench::schedule::run(&surface, model.name(), &backend, &config, progress)?;
    bar.finish_and_clear();
    let text = if args.json {
        serde_json::to_string_pretty(&report)?
    } else {
        report.to_markdown()
    };
    print_and_save(&text, args.out.as_deref())
}
