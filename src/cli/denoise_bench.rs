//! `raygun bench denoise` arguments (`crate::bench::denoise`).

use std::path::PathBuf;

use anyhow::Context;

use crate::cli::progress::{Progress, print_and_save};
use crate::display::DisplayModel;

#[derive(Clone, Debug, clap::Args)]
pub struct DenoiseBenchArgs {
    /// Scene (a file or builtin:NAME).
    #[arg(long, value_name = "SCENE", default_value = "builtin:cornell")]
    pub scene: String,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Display model (the paper's setup: HORNET).
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Image size of the renders (at least 16 a side, at most 3840×2160 pixels).
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", value_parser = crate::cli::args::parse_size, default_value = "320,180")]
    pub size: [u32; 2],
    /// Fields of view of the ROI, degrees (square cones).
    #[arg(
        long,
        value_name = "DEG,…",
        value_delimiter = ',',
        default_value = "10,60"
    )]
    pub fov: Vec<f64>,
    /// Iteration counts after which every method makes a picture, ascending (1 to 256).
    #[arg(
        long,
        value_name = "N,…",
        value_delimiter = ',',
        default_value = "1,4,16,64"
    )]
    pub iterations: Vec<u32>,
    /// Samples per pixel of the full-frame reference.
    #[arg(long, value_name = "N", default_value_t = 1024)]
    pub reference_spp: u32,
    /// Sizes of the synthetic time-per-picture measurements beside --size (WxH,…), or `none`.
    #[arg(long, value_name = "WxH,…|none", default_value = "1920x1080,3840x2160", value_parser = parse_timing_sizes)]
    pub timing_sizes: TimingSizes,
    /// Timed runs per size (median reported), after one warm-up.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub timing_runs: u32,
    /// Write side-by-side crops (ROI edge and periphery; reference, off, filter, interactive,
    /// OIDN) of the first FOV's pictures here (PNG).
    #[arg(long, value_name = "FILE.png")]
    pub crops: Option<PathBuf>,
    /// The iteration count of the crops (one of --iterations); default 4 where listed, else
    /// the first.
    #[arg(long, value_name = "N")]
    pub crops_iterations: Option<u32>,
    /// Environment (R,G,B or an .hdr/.exr file); default white.
    #[arg(long, value_name = "R,G,B|FILE")]
    pub env: Option<String>,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// Write the report as JSON here.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Also write the Markdown tables to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// `--timing-sizes`: sizes, possibly none.
#[derive(Clone, Debug, PartialEq)]
pub struct TimingSizes(pub Vec<[u32; 2]>);

/// A `--timing-sizes` item that is no size.
#[derive(Debug, thiserror::Error)]
#[error("'{0}': expected WxH with positive integers (e.g. 1920x1080), or none")]
pub struct TimingSizesError(String);

/// `WxH,…` or `none`.
fn parse_timing_sizes(text: &str) -> Result<TimingSizes, TimingSizesError> {
    if text.trim() == "none" {
        return Ok(TimingSizes(Vec::new()));
    }
    text.split(',')
        .map(|item| {
            let item = item.trim();
            item.split_once('x')
                .and_then(|(w, h)| Some([w.parse::<u32>().ok()?, h.parse::<u32>().ok()?]))
                .filter(|[w, h]| *w > 0 && *h > 0)
                .ok_or_else(|| TimingSizesError(item.to_owned()))
        })
        .collect::<Result<_, _>>()
        .map(TimingSizes)
}

/// `raygun bench denoise` (`bench::denoise`).
pub fn run(args: &DenoiseBenchArgs) -> anyhow::Result<()> {
    let cfg = crate::bench::denoise::DenoiseBenchConfig {
        scene: args.scene.clone(),
        size: args.size,
        fovs_deg: args.fov.clone(),
        iterations: args.iterations.clone(),
        reference_spp: args.reference_spp,
        timing_sizes: args.timing_sizes.0.clone(),
        timing_runs: args.timing_runs,
        crops_iterations: args.crops_iterations.unwrap_or_else(|| {
            if args.iterations.contains(&4) {
                4
            } else {
                args.iterations.first().copied().unwrap_or(1)
            }
        }),
        ..Default::default()
    };
    cfg.validate()?;
    let display = DisplayModel::open(&args.display).context("--display")?.0;
    let backend = args.backend.select()?;
    let scene = crate::cli::scene::load_scene(&args.scene, args.env.as_deref(), args.access)?;
    let oidn = crate::bench::denoise::open_oidn(&backend);
    if let Err(e) = &oidn {
        eprintln!("bench denoise: OIDN is not measured: {e}");
    }
    let mut planned = crate::bench::denoise::planned_frames(&cfg);
    let mut bar = Progress::new(false, "bench denoise", Some(planned), "frames");
    let mut done = 0u64;
    let report = crate::bench::denoise::run(
        &backend,
        &display,
        &scene,
        &cfg,
        oidn,
        args.crops.as_deref(),
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
    print_and_save(
        &crate::bench::denoise::markdown(&report),
        args.out.as_deref(),
    )?;
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report)?;
        crate::output::replace_with(path, |tmp| {
            std::fs::write(tmp, text.as_bytes())
                .map_err(|e| anyhow::anyhow!("--json {}: {e}", path.display()))
        })?;
    }
    Ok(())
}
