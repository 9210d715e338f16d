//! `raygun demo`: the whole pipeline on embedded defaults — the Cornell box (with its ceiling
//! light) on the HORNET wall, guided by a bundled synthetic FlyStick session. Opens the viewer
//! (playing the session) where there is a display; otherwise (or with `--headless`) renders and
//! writes the image, the DGI, the sample counts and a short report.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::cli::args::parse_size;
use crate::cli::guided::{GuideSource, GuidedResult, render_guided, write_guides};
use crate::display::DisplayModel;
use crate::filter::FilterParams;
use crate::frame::GuideConfig;
use crate::gpu::{Backend, BackendChoice};
use crate::trace::camera::RenderCamera;
use crate::trace::cpu::{DEFAULT_MAX_DEPTH, TraceSettings};

/// The demo's scene.
pub const SCENE: &str = "builtin:cornell-light";
/// The demo's environment: a dim blue-grey sky (linear radiance), so the box's own light
/// dominates and the wall around the box is not blown out.
pub const ENV: &str = "0.2,0.22,0.25";
/// The demo's display model (HORNET), embedded so the demo runs from any directory.
pub const DISPLAY_JSON: &str = include_str!("../../display-models/hornet.json");
/// The demo's tracking session: 20 s of synthetic FlyStick sweeps about the wall centre.
pub const REPLAY_JSONL: &str =
    include_str!("../../tracking-replays/flystick-1-centre-sweeps.dtrack.jsonl");
/// File names of the embedded inputs, as written under `<out>/inputs/`.
pub const DISPLAY_FILE: &str = "hornet.json";
pub const REPLAY_FILE: &str = "flystick-1-centre-sweeps.dtrack.jsonl";

#[derive(Clone, Debug, clap::Args)]
pub struct DemoArgs {
    /// Output directory (headless: image, DGI, counts, report; the inputs go to `inputs/`).
    #[arg(long, value_name = "DIR", default_value = "raygun-demo")]
    pub out: PathBuf,
    /// Render without a window even where there is a display.
    #[arg(long)]
    pub headless: bool,
    /// Guided iterations (the replay is spread evenly over them).
    #[arg(long, value_name = "N", default_value_t = 64)]
    pub iterations: u32,
    /// Image size; the image covers HORNET's canvas (aspect about 2.48:1).
    #[arg(long, value_name = "W,H", value_parser = parse_size, default_value = "992,400")]
    pub size: [u32; 2],
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Also write the 35 wall tiles (1920×1080 PNGs) to `<out>/tiles/`.
    #[arg(long)]
    pub tiles: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Whether a window can be opened: an X11 or Wayland display is named in the environment.
#[must_use]
pub fn has_display() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// Writes the embedded display model and replay under `<out>/inputs/`; returns their paths.
pub fn write_inputs(out: &Path) -> anyhow::Result<(PathBuf, PathBuf)> {
    let dir = out.join("inputs");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let display = dir.join(DISPLAY_FILE);
    let replay = dir.join(REPLAY_FILE);
    std::fs::write(&display, DISPLAY_JSON)
        .with_context(|| format!("writing {}", display.display()))?;
    std::fs::write(&replay, REPLAY_JSONL)
        .with_context(|| format!("writing {}", replay.display()))?;
    Ok((display, replay))
}

/// What a headless demo wrote.
pub struct DemoOutput {
    pub result: GuidedResult,
    pub files: Vec<PathBuf>,
    pub report: PathBuf,
}

pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    // Without the `viewer` feature there is no window to open: the demo renders headless.
    let windowed = cfg!(feature = "viewer") && has_display();
    if !args.headless && windowed {
        let (display, replay) = write_inputs(&args.out)?;
        return crate::cli::view::run(&crate::cli::view::ViewArgs::demo(args, &display, &replay));
    }
    if !args.headless {
        if cfg!(feature = "viewer") {
            eprintln!(
                "raygun demo: no display (DISPLAY / WAYLAND_DISPLAY unset): rendering headless"
            );
        } else {
            eprintln!(
                "raygun demo: built without its window (the `viewer` feature): rendering headless"
            );
        }
    }
    let out = run_headless(args)?;
    eprintln!(
        "raygun demo: {} iterations in {:.2} s, {:.1} % of full-frame samples; wrote {} files and {}",
        out.result.iterations,
        out.result.seconds,
        100.0 * out.result.sample_share(),
        out.files.len(),
        out.report.display()
    );
    Ok(())
}

/// The headless demo: renders, writes `image.png`, `image.exr`, `dgi.png`, `counts.exr`
/// (and the tiles with `--tiles`) and `report.md` into `--out`.
pub fn run_headless(args: &DemoArgs) -> anyhow::Result<DemoOutput> {
    if args.iterations == 0 {
        anyhow::bail!("--iterations must be at least 1");
    }
    let (display_path, replay_path) = write_inputs(&args.out)?;
    let model = DisplayModel::load(&display_path)?;
    let scene = crate::cli::render::load_scene(SCENE, Some(ENV))?;
    let [w, h] = args.size;
    let camera = RenderCamera::choose(&scene, None, w, h).context("demo scene camera")?;
    let backend = Backend::select(args.backend)?;
    let settings = TraceSettings {
        width: w,
        height: h,
        seed: 1,
        max_depth: DEFAULT_MAX_DEPTH,
        camera,
    };
    let source = GuideSource::parse(
        replay_path.to_str().context("non-UTF-8 output path")?,
        &model,
        &display_path,
        args.size,
    )?;
    let config = GuideConfig::default();
    let filter = FilterParams::default();
    let bar = crate::cli::render::progress(args.quiet, u64::from(args.iterations), "iterations");
    bar.set_message("demo");
    let result = render_guided(
        &backend,
        &scene,
        settings,
        &model,
        config,
        &filter,
        &source,
        args.iterations,
        |k| bar.set_position(u64::from(k)),
    )?;
    bar.finish_and_clear();
    let mut files = Vec::new();
    for name in ["image.png", "image.exr"] {
        let p = args.out.join(name);
        crate::output::write_rgb(&p, w, h, &result.image, 0.0)?;
        files.push(p);
    }
    let (dgi, counts) = (args.out.join("dgi.png"), args.out.join("counts.exr"));
    write_guides(&result, &dgi, &counts)?;
    files.extend([dgi, counts]);
    if args.tiles {
        let dir = args.out.join("tiles");
        files.extend(crate::output::tiles::write_tiles(
            &dir,
            &model,
            &result.image,
            args.size,
            crate::output::Format::Png,
            0.0,
        )?);
    }
    let report = args.out.join("report.md");
    let text = report_text(args, &backend, &model, &config, &filter, &result, &files);
    std::fs::write(&report, text).with_context(|| format!("writing {}", report.display()))?;
    Ok(DemoOutput {
        result,
        files,
        report,
    })
}

fn report_text(
    args: &DemoArgs,
    backend: &Backend,
    model: &DisplayModel,
    config: &GuideConfig,
    filter: &FilterParams,
    r: &GuidedResult,
    files: &[PathBuf],
) -> String {
    let [w, h] = r.size;
    let samples = r.samples();
    let mut s = String::new();
    // Writing to a String cannot fail.
    let _ = writeln!(s, "# raygun demo\n");
    let _ = writeln!(s, "| setting | value |\n|---|---|");
    let _ = writeln!(s, "| scene | `{SCENE}`, environment {ENV} |");
    let _ = writeln!(
        s,
        "| display | {} ({} tiles, canvas {:.0}×{:.0} px) |",
        model.name(),
        model.tiles().len(),
        model.canvas_rect().size().x,
        model.canvas_rect().size().y
    );
    let _ = writeln!(
        s,
        "| guide | replay `{REPLAY_FILE}` spread over the iterations |"
    );
    let _ = writeln!(s, "| image | {w}×{h} |");
    let _ = writeln!(s, "| iterations | {} |", r.iterations);
    let _ = writeln!(s, "| backend | {} |", backend.describe());
    let _ = writeln!(
        s,
        "| guide config | metric {:?}, falloff {:?}, p_min {}, order {:?} |",
        config.metric, config.falloff, config.p_min, config.order
    );
    let _ = writeln!(
        s,
        "| filter | {:?}, blend {:?}, k_max {}, c {} |",
        filter.kind, filter.blend, filter.k_max, filter.c
    );
    let _ = writeln!(s, "\n## Results\n");
    let _ = writeln!(s, "| measure | value |\n|---|---|");
    let _ = writeln!(s, "| render time (iterations) | {:.3} s |", r.seconds);
    let _ = writeln!(
        s,
        "| per iteration | {:.2} ms |",
        r.seconds * 1e3 / f64::from(r.iterations)
    );
    let _ = writeln!(s, "| samples | {samples} |");
    let _ = writeln!(
        s,
        "| share of full-frame samples | {:.2} % |",
        100.0 * r.sample_share()
    );
    let sampled = r.counts.iter().filter(|&&c| c > 0).count();
    let _ = writeln!(
        s,
        "| pixels sampled at least once | {:.2} % |",
        100.0 * sampled as f64 / r.counts.len() as f64
    );
    let _ = writeln!(
        s,
        "| most samples in a pixel | {} |",
        r.counts.iter().max().copied().unwrap_or(0)
    );
    let _ = writeln!(s, "\n## Files\n");
    for f in files {
        let name = f.strip_prefix(&args.out).unwrap_or(f);
        let _ = writeln!(s, "- `{}`", name.display());
    }
    s
}
