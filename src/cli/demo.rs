//! `raygun demo`: the whole pipeline on embedded defaults — the Cornell box (with its ceiling
//! light) on the HORNET wall, guided by a bundled synthetic FlyStick session. Opens the viewer
//! (playing the session) where there is a display; otherwise (or with `--headless`) renders and
//! writes the image, the DGI, the sample counts and a short report.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::cli::progress::{OneTime, Progress};
use crate::cli::view::{ViewArgs, has_display};
use crate::display::DisplayModel;
use crate::filter::{DenoiseKind, FilterParams};
use crate::frame::GuideConfig;
use crate::gpu::Backend;
use crate::output::OutputSet;
use crate::session::guide::GuideSource;
use crate::session::render::{GuidedRender, GuidedResult, Stopping, render_guided};
use crate::session::replay::{ReplayOptions, ReplayPlan};
use crate::trace::camera::RenderCamera;
use crate::trace::path::{DEFAULT_MAX_DEPTH, TraceSettings};

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
    /// Image size in pixels, W,H, or `native`: the display canvas's own pixel size (HORNET's
    /// 13519×5457). The image covers HORNET's canvas (aspect about 2.48:1).
    #[arg(allow_hyphen_values = true, long, value_name = "W,H|native", value_parser = crate::cli::args::parse_size_or_native, default_value = "992,400")]
    pub size: [u32; 2],
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// Also write the 35 wall tiles (1920×1080 PNGs) to `<out>/tiles/`.
    #[arg(long)]
    pub tiles: bool,
    /// Print only warnings and errors: no progress bar, no summary.
    #[arg(long)]
    pub quiet: bool,
    /// `wall`: render through the wall camera from --eye (in the viewer too, where the mouse
    /// moves the eye).
    #[arg(long, value_name = "wall")]
    pub camera: Option<String>,
    #[command(flatten)]
    pub wall: crate::cli::wall::WallArgs,
    /// Denoise the picture: interactive (raygun's own edge-avoiding denoiser, steered by each
    /// pixel's albedo, normal and depth), oidn (headless: Intel Open Image Denoise 2 with the
    /// same albedo and normal; in the viewer: once the ROI and the eye are still; install it
    /// with `bash tools/oidn.sh install`, or set OIDN_DIR) or off (the filter's picture).
    #[arg(long, value_enum, default_value_t = DenoiseKind::Interactive)]
    pub denoise: DenoiseKind,
}

/// Writes the embedded display model and replay under `<out>/inputs/`, counted in `set`;
/// returns their paths.
pub fn write_inputs(out: &Path, set: &mut OutputSet) -> anyhow::Result<(PathBuf, PathBuf)> {
    let dir = out.join("inputs");
    set.folder(&dir)?;
    let display = dir.join(DISPLAY_FILE);
    let replay = dir.join(REPLAY_FILE);
    set.write_bytes(&display, DISPLAY_JSON.as_bytes())?;
    set.write_bytes(&replay, REPLAY_JSONL.as_bytes())?;
    Ok((display, replay))
}

/// What a headless demo wrote.
pub struct DemoOutput {
    pub result: GuidedResult,
    /// The one-time work before the first iteration (not in `result.seconds`).
    pub one_time: OneTime,
    pub files: Vec<PathBuf>,
    pub report: PathBuf,
}

pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    let mut args = args.clone();
    if args.size == crate::cli::args::NATIVE_SIZE {
        let embedded = DisplayModel::from_json(DISPLAY_JSON, DISPLAY_FILE)?;
        args.size = crate::output::tiles::canvas_pixel_size(&embedded);
    }
    let args = &args;
    // Without the `viewer` feature there is no window to open: the demo renders headless.
    let windowed = cfg!(feature = "viewer") && has_display();
    if !args.headless && windowed {
        check_camera(args)?;
        let embedded = DisplayModel::from_json(DISPLAY_JSON, DISPLAY_FILE)?;
        crate::cli::wall::wall_spec(args.camera.as_deref(), &args.wall, Some(&embedded))?;
        let mut set = OutputSet::new();
        let (display, replay) = write_inputs(&args.out, &mut set)?;
        // The viewer reads them while it runs; they stay.
        set.finish();
        return crate::cli::view::run(&view_args(args, &display, &replay));
    }
    if !args.headless {
        if cfg!(feature = "viewer") {
            crate::cli::say(
                args.quiet,
                "demo: no display (DISPLAY / WAYLAND_DISPLAY unset): rendering headless",
            );
        } else {
            crate::cli::say(
                args.quiet,
                "demo: built without its window (the `viewer` feature): rendering headless",
            );
        }
    }
    let out = run_headless(args)?;
    crate::cli::say(args.quiet, out.one_time);
    crate::cli::say(
        args.quiet,
        format_args!(
            "demo: {} in {:.2} s, {:.1} % of full-frame samples; wrote {} and {}",
            crate::messages::count(out.result.iterations as usize, "iteration"),
            out.result.seconds,
            100.0 * out.result.sample_share(),
            crate::messages::count(out.files.len(), "file"),
            out.report.display()
        ),
    );
    Ok(())
}

/// The headless demo: renders, writes `image.png`, `image.exr`, `dgi.png`, `counts.exr`
/// (and the tiles with `--tiles`) and `report.md` into `--out`.
pub fn run_headless(args: &DemoArgs) -> anyhow::Result<DemoOutput> {
    if args.iterations == 0 {
        anyhow::bail!("--iterations must be at least 1");
    }
    check_camera(args)?;
    let embedded = DisplayModel::from_json(DISPLAY_JSON, DISPLAY_FILE)?;
    let wall_spec =
        crate::cli::wall::wall_spec(args.camera.as_deref(), &args.wall, Some(&embedded))?;
    // Everything the demo writes, taken back if it fails before the report (a full disk).
    let mut set = OutputSet::new();
    set.folder(&args.out)?;
    let (backend, note) = args.backend.choose()?;
    if let Some(note) = note {
        crate::cli::say(args.quiet, note);
    }
    let filter = FilterParams::default();
    let (oidn_device, denoise_note) = check_and_open(args, &backend, &filter)?;
    let denoise_args = crate::cli::filter::DenoiseArgs {
        denoise: args.denoise,
    };
    let denoiser = denoise_args.denoiser(
        oidn_device.as_ref(),
        &filter,
        crate::filter::oidn::Quality::High,
    );
    let (display_path, replay_path) = write_inputs(&args.out, &mut set)?;
    let model = DisplayModel::load(&display_path)?;
    if args.tiles {
        crate::cli::render::warn_if_resampled(args.size, &model, "HORNET");
    }
    let (scene, settings, load_seconds) = scene_and_settings(args.size)?;
    let [w, h] = args.size;
    let (plan, _) = ReplayPlan::new(&ReplayOptions {
        display: Some(display_path.display().to_string()),
        ..ReplayOptions::of(replay_path.clone())
    })?;
    let source = GuideSource::from_replay(&plan, &replay_path)?;
    let config = GuideConfig::default();
    let mut bar = Progress::new(
        args.quiet,
        "demo",
        Some(u64::from(args.iterations)),
        "iterations",
    );
    let wall = wall_spec
        .map(|w| w.camera(args.size, &settings.camera))
        .transpose()
        .context("--camera wall")?;
    let crop_wall = wall.clone();
    let result = render_guided(
        &backend,
        &scene,
        GuidedRender {
            settings,
            model: &model,
            wall,
            config,
            filter,
            denoise: denoiser,
            keep_sums: true,
            on_eye_move: crate::frame::EyeMove::Reuse,
        },
        &source,
        &Stopping {
            iterations: Some(args.iterations),
            until: Vec::new(),
        },
        |k, _| bar.set(u64::from(k)),
    )?;
    bar.finish();
    let mut files = vec![
        FileNote::new(
            display_path,
            "the display model (HORNET), written from the copy built into raygun",
        ),
        FileNote::new(
            replay_path,
            "the FlyStick session that guides the render (synthetic), built in likewise",
        ),
    ];
    write_images(args, &result, denoiser.is_some(), &mut set, &mut files)?;
    let (dgi, counts) = (args.out.join("dgi.png"), args.out.join("counts.exr"));
    set.add(&dgi);
    set.add(&counts);
    result.write_guides(Some(&dgi), Some(&counts))?;
    files.push(FileNote::new(
        dgi,
        "the distance-guide image of the session's last ROI (black: in the ROI, white: d = 1)",
    ));
    files.push(FileNote::new(
        counts,
        "samples per pixel over the whole session (one float channel `samples`)",
    ));
    if u64::from(w) * u64::from(h) <= CROPS_MAX_PIXELS {
        let crops = args.out.join("denoisers.png");
        set.add(&crops);
        let view = CropView {
            scene: &scene,
            settings,
            wall: crop_wall.as_ref(),
            filter: &filter,
        };
        write_denoiser_crops(&crops, &backend, &view, &result, oidn_device.as_ref())?;
        files.push(FileNote::new(
            crops,
            "the denoisers side by side at the ROI's edge (top) and in the periphery (bottom): the raw mean (unsampled pixels black), the paper's filter, raygun's interactive denoiser and Intel Open Image Denoise (grey where it is not installed)",
        ));
    }
    if args.tiles {
        files.push(write_tiles(args, &model, &result, &mut set)?);
    }
    let report = args.out.join("report.md");
    let one_time = OneTime {
        load_seconds,
        build_seconds: result.build_seconds,
        upload_seconds: result.upload_seconds,
    };
    let how = HowRendered {
        one_time,
        config: &config,
        filter: &filter,
        denoise: denoise_note
            .as_deref()
            .map(|n| n.trim_start_matches("denoise: ")),
    };
    let text = report_text(&backend, &model, &how, &result, &args.out, &files);
    set.write_bytes(&report, text.as_bytes())?;
    set.finish();
    Ok(DemoOutput {
        result,
        one_time,
        files: files.into_iter().map(|f| f.path).collect(),
        report,
    })
}

/// Writes `--tiles`' PNGs, one per wall tile, into `--out`'s `tiles` folder, counted in `set`.
fn write_tiles(
    args: &DemoArgs,
    model: &DisplayModel,
    result: &GuidedResult,
    set: &mut OutputSet,
) -> anyhow::Result<FileNote> {
    let [w, h] = args.size;
    let dir = args.out.join("tiles");
    set.folder(&dir)?;
    for t in 0..model.tiles().len() {
        let format = crate::output::Format::Png;
        set.add(&crate::output::tiles::tile_path(&dir, model, t, format));
    }
    let n = crate::output::tiles::write_tiles(
        &dir,
        model,
        &result.image,
        args.size,
        crate::output::Format::Png,
        0.0,
    )?
    .len();
    Ok(FileNote::new(
        dir,
        &format!(
            "{n} PNGs, one per wall tile (`<tile id>.png`, 1920×1080), cut from the image and resampled (nearest neighbour) from {w}×{h}"
        ),
    ))
}

/// Writes `image.png` and `image.exr` into `--out`, each counted in `set` and listed in `files`.
fn write_images(
    args: &DemoArgs,
    result: &GuidedResult,
    denoised: bool,
    set: &mut OutputSet,
    files: &mut Vec<FileNote>,
) -> anyhow::Result<()> {
    let [w, h] = result.size;
    for name in ["image.png", "image.exr"] {
        let p = args.out.join(name);
        crate::output::write_rgb(&p, w, h, &result.image, 0.0)?;
        set.add(&p);
        files.push(FileNote::new(
            p,
            match (name.ends_with("png"), denoised) {
                (true, false) => "the filtered image, sRGB 8-bit",
                (false, false) => "the filtered image, linear RGB, 32-bit float",
                (true, true) => "the filtered and denoised image, sRGB 8-bit",
                (false, true) => "the filtered and denoised image, linear RGB, 32-bit float",
            },
        ));
    }
    Ok(())
}

/// The largest picture the demo makes its denoisers' crops for (1920×1080): they denoise the
/// whole accumulation three more ways, about 230 bytes a pixel more than the render holds.
pub const CROPS_MAX_PIXELS: u64 = 1920 * 1080;

/// What the demo's picture shows: the scene, its settings, the wall camera and the filter.
struct CropView<'a> {
    scene: &'a crate::scene::Scene,
    settings: TraceSettings,
    wall: Option<&'a crate::trace::wall::WallCamera>,
    filter: &'a FilterParams,
}

/// `path`: the demo's accumulation as each denoiser shows it, crops side by side
/// (`bench denoise`'s crops, without a reference): the raw mean, the paper's filter, raygun's
/// interactive denoiser and OIDN (on its CPU device unless `oidn` was opened for the render;
/// grey where the library is not installed).
fn write_denoiser_crops(
    path: &Path,
    backend: &Backend,
    view: &CropView<'_>,
    result: &GuidedResult,
    oidn: Option<&crate::filter::oidn::Device>,
) -> anyhow::Result<()> {
    use crate::filter::{Denoiser, denoise::DenoiseParams, oidn};
    let [w, h] = result.size;
    let acc = crate::trace::accum::Accumulation {
        width: w,
        height: h,
        sum: result.sums.clone(),
        count: result.counts.clone(),
    };
    let f = crate::trace::features::features_cpu(
        &crate::trace::pack::PackedScene::new(view.scene),
        &view.settings,
        view.wall,
    );
    let features = crate::filter::denoise::Features {
        width: w,
        height: h,
        albedo: f.albedo,
        normal_depth: f.normal_depth,
    };
    let mut raw = acc.mean_image();
    let mut filtered = crate::filter::Filter::new(backend).image(view.filter, &acc, &result.dgi)?;
    if let Some(wc) = view.wall {
        wc.blank_unshown(&mut raw);
        wc.blank_unshown(&mut filtered);
    }
    let denoise = |d: Denoiser<'_>| -> anyhow::Result<Vec<glam::Vec3>> {
        let (image, _) =
            crate::frame::denoise_picture(backend, d, &acc, &features, &filtered, view.wall)?;
        Ok(image)
    };
    let interactive = denoise(Denoiser::Interactive(DenoiseParams {
        variance_threshold: view.filter.variance_threshold,
        ..DenoiseParams::default()
    }))?;
    // The render's device, else OIDN's CPU device where the library is installed.
    let opened = match oidn {
        Some(_) => None,
        None => oidn::Oidn::load()
            .and_then(|o| o.device(oidn::DeviceChoice::Cpu))
            .ok(),
    };
    let oidn_image = match oidn.or(opened.as_ref()) {
        Some(device) => Some(denoise(Denoiser::Oidn(device, oidn::Quality::High))?),
        None => None,
    };
    let oidn_label = if oidn_image.is_some() {
        "OIDN"
    } else {
        "OIDN (not installed)"
    };
    let columns = vec![
        ("raw mean".to_owned(), Some(raw)),
        ("paper's filter".to_owned(), Some(filtered.clone())),
        ("interactive".to_owned(), Some(interactive)),
        (oidn_label.to_owned(), oidn_image),
    ];
    crate::bench::denoise::write_crop_columns(path, result.size, &columns, &result.dgi)?;
    Ok(())
}

/// The demo's scene, what it is traced with at `size`, and the seconds its load took.
fn scene_and_settings(size: [u32; 2]) -> anyhow::Result<(crate::scene::Scene, TraceSettings, f64)> {
    let (scene, load_seconds) = crate::cli::scene::load_scene_timed(
        SCENE,
        Some(ENV),
        crate::cli::scene::SceneAccess::default(),
    )?;
    let [w, h] = size;
    let camera = RenderCamera::choose(&scene, None, w, h).context("demo scene camera")?;
    let settings = TraceSettings {
        width: w,
        height: h,
        seed: 1,
        max_depth: DEFAULT_MAX_DEPTH,
        camera,
    };
    Ok((scene, settings, load_seconds))
}

/// Checks the render's memory (with its denoiser's) and opens OIDN for `--denoise oidn`;
/// returns the device and what the demo says about its denoiser.
fn check_and_open(
    args: &DemoArgs,
    backend: &Backend,
    filter: &FilterParams,
) -> anyhow::Result<(Option<crate::filter::oidn::Device>, Option<String>)> {
    crate::cli::render::check_memory(
        crate::memory::Work::Render {
            gpu: backend.is_gpu(),
            filter: filter.kind,
        },
        (args.denoise, crate::frame::EyeMove::Reuse),
        args.size,
        backend,
    )?;
    let denoise_args = crate::cli::filter::DenoiseArgs {
        denoise: args.denoise,
    };
    let device = denoise_args.device(backend)?;
    let note = denoise_args.describe(device.as_ref(), backend);
    if let Some(note) = &note {
        crate::cli::say(args.quiet, note);
    }
    Ok((device, note))
}

/// The demo's scene camera, or `--camera wall`.
fn check_camera(args: &DemoArgs) -> anyhow::Result<()> {
    if let Some(c) = args.camera.as_deref()
        && c != crate::cli::wall::WALL_CAMERA
    {
        anyhow::bail!("--camera {c}: the demo's only other camera is `wall`");
    }
    Ok(())
}

/// A file the demo wrote and what it is.
struct FileNote {
    path: PathBuf,
    what: String,
}

impl FileNote {
    fn new(path: PathBuf, what: &str) -> Self {
        Self {
            path,
            what: what.to_owned(),
        }
    }
}

/// A value-enum setting by its command-line name.
fn name_of<T: clap::ValueEnum>(v: &T) -> String {
    v.to_possible_value()
        .map_or_else(|| "?".into(), |p| p.get_name().to_owned())
}

/// How the demo's picture was made: the guide's settings, the filter and the denoiser (what
/// the command said about it; `None`: off) and the one-time work before its first iteration.
struct HowRendered<'a> {
    config: &'a GuideConfig,
    filter: &'a FilterParams,
    denoise: Option<&'a str>,
    /// The one-time work before the first iteration.
    one_time: OneTime,
}

fn report_text(
    backend: &Backend,
    model: &DisplayModel,
    how: &HowRendered<'_>,
    r: &GuidedResult,
    out: &Path,
    files: &[FileNote],
) -> String {
    let [w, h] = r.size;
    let (config, filter) = (how.config, how.filter);
    let samples = r.samples();
    let mut s = String::new();
    // Writing to a String cannot fail.
    let _ = writeln!(s, "# raygun demo\n");
    let _ = writeln!(s, "| setting | value |\n|---|---|");
    let _ = writeln!(
        s,
        "| scene | `{SCENE}` (the Cornell box with its ceiling light), environment radiance {ENV} |"
    );
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
        "| guide | the replay `inputs/{REPLAY_FILE}`, spread evenly over the iterations |"
    );
    let _ = writeln!(s, "| image | {w}×{h}, covering the display's canvas |");
    let _ = writeln!(s, "| iterations | {} |", r.iterations);
    let _ = writeln!(s, "| backend | {} |", backend.describe());
    let _ = writeln!(s, "| distance measure | {} |", name_of(&config.metric));
    let _ = writeln!(
        s,
        "| falloff | L = {} m + {} × ROI radius |",
        config.falloff.base_m, config.falloff.scale
    );
    let _ = writeln!(s, "| lowest sampling probability | {} |", config.p_min);
    let _ = writeln!(s, "| pixel order | {} |", name_of(&config.order));
    let _ = writeln!(
        s,
        "| filter | {}, blend by {}, largest radius {} px, c = {} samples |",
        name_of(&filter.kind),
        name_of(&filter.blend),
        filter.k_max,
        filter.c
    );
    let _ = writeln!(s, "| denoiser | {} |", how.denoise.unwrap_or("off"));
    let _ = writeln!(s, "\n## Results\n");
    let _ = writeln!(s, "| measure | value |\n|---|---|");
    let _ = writeln!(s, "| render time (iterations) | {:.3} s |", r.seconds);
    let t = &how.one_time;
    let _ = writeln!(s, "| scene load (one-time) | {:.3} s |", t.load_seconds);
    let _ = writeln!(s, "| BVH build (one-time) | {:.3} s |", t.build_seconds);
    let _ = writeln!(s, "| upload (one-time) | {:.3} s |", t.upload_seconds);
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
        let name = f.path.strip_prefix(out).unwrap_or(&f.path);
        let _ = writeln!(s, "- `{}`: {}", name.display(), f.what);
    }
    let _ = writeln!(s, "- `report.md`: this report");
    s
}

/// The demo's viewer: its scene and size, the embedded display and replay written to disk.
#[must_use]
pub fn view_args(args: &DemoArgs, display: &Path, replay: &Path) -> ViewArgs {
    ViewArgs {
        scene: SCENE.to_owned(),
        access: crate::cli::scene::SceneAccess::default(),
        display: display.display().to_string(),
        size: args.size,
        env: Some(ENV.to_owned()),
        camera: args.camera.clone(),
        wall: args.wall.clone(),
        head: crate::cli::head::HeadArgs::default(),
        look: crate::cli::args::LookArgs::default(),
        max_depth: DEFAULT_MAX_DEPTH,
        backend: args.backend,
        window_gpu: crate::cli::view::WindowGpu::Shared,
        dtrack: None,
        osc: None,
        vrpn: None,
        allow_network: false,
        replay: Some(replay.to_path_buf()),
        device: None,
        config: None,
        calibration: None,
        p_min: 0.0,
        target_se: None,
        roi_at: None,
        roi_radius: 600.0,
        filter: crate::cli::filter::FilterArgs {
            filter: crate::filter::FilterKind::Fast,
            blend: crate::filter::Blend::Count,
            k_max: crate::filter::FilterParams::DEFAULT_K_MAX,
            c: crate::filter::FilterParams::DEFAULT_C,
            variance_threshold: crate::filter::FilterParams::DEFAULT_VARIANCE_THRESHOLD,
        },
        denoise: args.denoise,
        save_dir: args.out.clone(),
        screenshot_after: None,
        show_tiles: false,
        cluster: crate::cli::cluster::ClusterArgs::default(),
    }
}
