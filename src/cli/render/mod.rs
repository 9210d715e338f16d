//! `raygun render`: a progressive path-traced image of a glTF scene, written as EXR (linear,
//! 32-bit float RGB) and/or PNG (sRGB, 8-bit) by the files' extensions.
//!
//! Everything the command will write is checked before any work (extensions, folders that
//! exist and take files), and so is the memory the size needs; every file is written through a
//! temporary name and renamed into place.

pub mod cluster;
pub mod guided;

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::ArgGroup;

use crate::cli::progress::{OneTime, Progress};
use crate::cli::scene::load_scene_timed;
use crate::cli::wall::WALL_CAMERA;
use crate::display::DisplayModel;
use crate::frame::Renderer;
use crate::frame::stop::StopCondition;
use crate::gpu::Backend;
use crate::memory::{Budget, Work};
use crate::output::{Format, check_image_path, write_rgb};
use crate::scene::Scene;
use crate::trace::camera::RenderCamera;
use crate::trace::path::{DEFAULT_MAX_DEPTH, TraceSettings};
use crate::trace::wall::{WallCamera, WallSpec};

/// Samples per pixel of a full-frame render when `--spp` is not given.
pub const DEFAULT_SPP: u32 = 64;

#[derive(Clone, Debug, clap::Args)]
#[command(group(
    ArgGroup::new("guided_only")
        .multiple(true)
        .args([
            "iterations", "until", "p_min", "metric", "falloff_base", "falloff_scale", "order",
            "filter", "blend", "k_max", "c", "variance_threshold", "dgi_out", "counts_out",
            "calibration", "head", "eye_offset", "eye_threshold",
        ])
        .requires("guide")
))]
pub struct RenderArgs {
    /// Scene: a .gltf/.glb file, or builtin:cornell, builtin:cornell-light, builtin:city,
    /// builtin:city-small.
    #[arg(long, value_name = "FILE|builtin:NAME")]
    pub scene: String,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Camera by name (default: the scene's first camera, else one framing the scene), or
    /// `wall`: the wall camera — each pixel's primary ray from --eye through its point on
    /// --display; pixels no tile shows (bezels) are never traced and stay black.
    #[arg(long, value_name = "NAME|wall")]
    pub camera: Option<String>,
    #[command(flatten)]
    pub wall: crate::cli::wall::WallArgs,
    /// A replay guide's tracked head moves the wall camera's eye (default: the replay's header's
    /// head); `--eye` may then be left out (the head's first eye).
    #[command(flatten)]
    pub head: crate::cli::head::HeadArgs,
    #[command(flatten)]
    pub look: crate::cli::args::LookArgs,
    /// Image size in pixels, W,H, or `native`: the display canvas's own pixel size.
    /// At `native` (13519×5457 for HORNET) --tiles writes every tile at its own resolution
    /// without resampling.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H|native", value_parser = crate::cli::args::parse_size_or_native, default_value = "1280,720")]
    pub size: [u32; 2],
    /// Samples per pixel of a full-frame render (default 64; guided renders take
    /// --iterations instead).
    #[arg(long, value_name = "N", conflicts_with = "guide")]
    pub spp: Option<u32>,
    /// Environment light: linear radiance R,G,B or an equirectangular .hdr/.exr image
    /// (default: white, radiance 1).
    #[arg(long, value_name = "R,G,B|FILE")]
    pub env: Option<String>,
    /// Maximum path vertices: 1 is direct light only (Mitsuba's max_depth 2).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_DEPTH)]
    pub max_depth: u32,
    /// Seed of the per-pixel random sequences.
    #[arg(long, default_value_t = 1)]
    pub seed: u32,
    /// Output files (repeatable): .exr (linear RGB, f32) or .png (sRGB, 8-bit). Needed unless
    /// --tiles writes the wall's tiles instead (with --cluster the whole picture is then never
    /// assembled on one rank).
    #[arg(long, value_name = "FILE", required_unless_present = "tiles")]
    pub out: Vec<PathBuf>,
    /// PNG exposure in stops (the EXR keeps the linear values).
    #[arg(
        long,
        value_name = "EV",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub exposure: f32,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// Print only warnings and errors: no progress report, no summary.
    #[arg(long)]
    pub quiet: bool,
    /// Guided rendering: the ROI from a tracking replay (spread evenly over the iterations),
    /// a ray-gun pose `pose:X,Y,Z:DX,DY,DZ:FOV[,FOV_V]` (room frame, metres, degrees) or a
    /// mouse ROI `mouse:X,Y:A,B` (centre and semi-axes in image pixels). Writes the image, the
    /// distance-guide image and the per-pixel sample counts.
    #[arg(long, value_name = "REPLAY|pose:…|mouse:…", allow_hyphen_values = true)]
    pub guide: Option<String>,
    /// Guided iterations (each traces one path per scheduled pixel). Needed with a replay
    /// guide; optional with a pose or mouse guide when --until is given.
    #[arg(long, value_name = "N")]
    pub iterations: Option<u32>,
    /// Stop a guided render early (repeatable; the first reached wins): roi-se:X (median
    /// standard error of the ROI pixels' mean luminance at or below X), roi-spp:N (every ROI
    /// pixel has N samples) or time:SECONDS.
    #[arg(long, value_name = "roi-se:X|roi-spp:N|time:S")]
    pub until: Vec<StopCondition>,
    /// Display model whose canvas the image covers: a file, or a built-in model (hornet,
    /// desktop-27in-4k, projection-4m-4k). Default: the replay's, else hornet.
    #[arg(long, value_name = "MODEL")]
    pub display: Option<String>,
    /// Tracker→room calibration for a replay guide (default: the one it was recorded with).
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Lowest sampling probability, 0 to 1 (the paper's: 0).
    #[arg(
        long,
        value_name = "P",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub p_min: f32,
    /// Distance measure of the DGI.
    #[arg(long, value_enum, default_value_t = crate::roi::dgi::Metric::Exact)]
    pub metric: crate::roi::dgi::Metric,
    /// Falloff L = BASE + SCALE × ROI radius: the base, metres along the wall.
    #[arg(long, value_name = "METRES", default_value_t = crate::roi::dgi::Falloff::DEFAULT_BASE_M, allow_hyphen_values = true)]
    pub falloff_base: f64,
    /// Falloff L = BASE + SCALE × ROI radius: the scale.
    #[arg(long, value_name = "K", default_value_t = crate::roi::dgi::Falloff::DEFAULT_SCALE, allow_hyphen_values = true)]
    pub falloff_scale: f64,
    /// Order of the scheduled pixel list.
    #[arg(long, value_enum, default_value_t = crate::schedule::Order::Coherent)]
    pub order: crate::schedule::Order,
    #[command(flatten)]
    pub filter: crate::cli::filter::FilterArgs,
    #[command(flatten)]
    pub denoise: crate::cli::filter::DenoiseArgs,
    /// Where to write the DGI (EXR or PNG; default `<out stem>.dgi.exr` beside the first
    /// --out, none without one).
    #[arg(long, value_name = "FILE")]
    pub dgi_out: Option<PathBuf>,
    /// Where to write the per-pixel sample counts (EXR or PNG; default
    /// `<out stem>.counts.exr` beside the first --out, none without one).
    #[arg(long, value_name = "FILE")]
    pub counts_out: Option<PathBuf>,
    /// Wall output: one image per tile of --display, `DIR/<tile id>.<exr|png>`, cut from the
    /// image (which covers the canvas) with the pixels behind bezels left out. Render at the
    /// canvas size for an exact cut; other sizes are resampled by nearest neighbour.
    #[arg(long, value_name = "DIR")]
    pub tiles: Option<PathBuf>,
    /// Format of the tile images (default: the first --out file's, else EXR).
    #[arg(long, value_name = "exr|png", requires = "tiles", value_parser = parse_format)]
    pub tiles_format: Option<Format>,
    #[command(flatten)]
    pub cluster: crate::cli::cluster::ClusterArgs,
}

/// A `--tiles-format` that is neither exr nor png.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("'{0}': the tile format is exr or png")]
pub struct TileFormatError(String);

fn parse_format(s: &str) -> Result<Format, TileFormatError> {
    match s.to_ascii_lowercase().as_str() {
        "exr" => Ok(Format::Exr),
        "png" => Ok(Format::Png),
        _ => Err(TileFormatError(s.to_owned())),
    }
}

/// `--tiles DIR`: writes one image per display tile, cut from `image` (at `args.size`).
pub fn write_wall_tiles(
    args: &RenderArgs,
    model: &DisplayModel,
    image: &[glam::Vec3],
) -> anyhow::Result<()> {
    let Some(dir) = &args.tiles else {
        return Ok(());
    };
    let format = tiles_format(args)?;
    let paths =
        crate::output::tiles::write_tiles(dir, model, image, args.size, format, args.exposure)
            .with_context(|| format!("--tiles {}", dir.display()))?;
    crate::cli::say(
        args.quiet,
        format_args!("wrote {} tile images to {}", paths.len(), dir.display()),
    );
    Ok(())
}

/// The format of `--tiles`' images: `--tiles-format`, or the first `--out` file's, or EXR
/// (the linear values) without one.
pub fn tiles_format(args: &RenderArgs) -> anyhow::Result<Format> {
    Ok(match (args.tiles_format, args.out.first()) {
        (Some(f), _) => f,
        (None, Some(out)) => Format::from_path(out)?,
        (None, None) => Format::Exr,
    })
}

/// Says when `--tiles` will resample the image (it is not at the canvas size).
pub fn warn_if_resampled(size: [u32; 2], model: &DisplayModel, origin: &str) {
    let canvas = crate::output::tiles::canvas_pixel_size(model);
    if canvas != size {
        eprintln!(
            "raygun: --tiles: the {}×{} image is resampled (nearest neighbour) to the {}×{} canvas of {origin}; render at --size {},{} for an exact cut",
            size[0], size[1], canvas[0], canvas[1], canvas[0], canvas[1]
        );
    }
}

/// Checks the memory a render of `size` needs against this machine and the backend, printing
/// the note for a large run.
pub fn check_memory(
    work: Work,
    (denoise, on_eye_move): (crate::filter::DenoiseKind, crate::frame::EyeMove),
    size: [u32; 2],
    backend: &Backend,
) -> anyhow::Result<()> {
    let mut budget = Budget::of(work, size).with_denoise(denoise, backend.is_gpu());
    if on_eye_move == crate::frame::EyeMove::Reuse {
        budget = budget.with_reuse(backend.max_binding());
    }
    // A kernel-lab build's trace kernel may hold buffers of its own (the wavefront split's).
    #[cfg(feature = "kernel-lab")]
    let budget = match backend {
        Backend::Gpu(ctx) => budget.with_trace_kernel(work, ctx.trace_variant(), ctx.max_binding()),
        Backend::Cpu => budget,
    };
    if let Some(note) =
        budget.check(crate::memory::available_host_bytes(), backend.max_binding())?
    {
        eprintln!("raygun: {note}");
    }
    Ok(())
}

/// The numbers that need no file or scene.
fn check_args(args: &RenderArgs) -> anyhow::Result<()> {
    if args.spp == Some(0) {
        anyhow::bail!("--spp must be at least 1");
    }
    if args.max_depth == 0 {
        anyhow::bail!("--max-depth must be at least 1");
    }
    if !args.exposure.is_finite() {
        anyhow::bail!(
            "--exposure must be a finite number of stops, not {}",
            crate::messages::number(f64::from(args.exposure))
        );
    }
    if args.cluster.cluster && args.denoise.denoise == crate::filter::DenoiseKind::Oidn {
        anyhow::bail!(
            "--denoise oidn denoises one process's picture: with --cluster the ranks denoise \
             their tiles with --denoise interactive; leave out one of the two"
        );
    }
    if args.cluster.cluster {
        args.head.cluster_on_eye_move()?;
    }
    Ok(())
}

/// Says how many pixels the denoiser dropped for a NaN or infinite sum (nothing when none).
pub fn say_dropped(quiet: bool, dropped: u64) {
    if dropped > 0 {
        crate::cli::say(
            quiet,
            format_args!(
                "denoise: {} with a NaN or infinite sum dropped (filled from their neighbours)",
                crate::messages::count(dropped as usize, "pixel")
            ),
        );
    }
}

/// Every output the render will write, checked before any work.
fn check_outputs(args: &RenderArgs) -> anyhow::Result<()> {
    for out in &args.out {
        check_image_path(out)?;
    }
    if let Some(p) = &args.dgi_out {
        check_image_path(p).context("--dgi-out")?;
    }
    if let Some(p) = &args.counts_out {
        check_image_path(p).context("--counts-out")?;
    }
    if let Some(dir) = &args.tiles {
        crate::output::check_folder(dir).context("--tiles")?;
    }
    Ok(())
}

/// `render`'s validated configuration: every check that needs neither the GPU nor the scene —
/// the numbers, every output, the filter, the guide with its display and calibration, the wall
/// camera's flags and the denoiser's kind — done once, before any work, in the order the
/// errors are reported.
pub struct RenderConfig {
    /// The arguments with `--size native` replaced by the display canvas's pixel size.
    pub args: RenderArgs,
    pub filter: crate::filter::FilterParams,
    /// A guided render's inputs (`--guide`); `None` for a full frame.
    pub plan: Option<guided::GuidedPlan>,
    /// `--camera wall` checked against the display.
    pub wall: Option<WallSpec>,
    /// The display a full frame's `--tiles` are cut for (a guided render's is its plan's).
    pub tiles_model: Option<DisplayModel>,
}

impl RenderConfig {
    /// Checks `args` and resolves the display, the guide and the wall spec; a full frame's
    /// `--tiles` display warns here when the image will be resampled.
    pub fn new(args: &RenderArgs) -> anyhow::Result<Self> {
        Self::for_rank(args, true)
    }

    /// [`Self::new`] on a rank of `--cluster`: rank 0 (`root`) writes the image and checks
    /// every output, and says when tiles will be resampled; every other rank checks only the
    /// `--tiles` folder it writes its own tiles into (on its own machine's disk, or a shared
    /// one).
    pub fn for_rank(args: &RenderArgs, root: bool) -> anyhow::Result<Self> {
        let args = with_native_size(args)?;
        check_args(&args)?;
        if root {
            check_outputs(&args)?;
        } else if let Some(dir) = &args.tiles {
            crate::output::check_folder(dir).context("--tiles")?;
        }
        let filter = args.filter.params()?;
        let plan = match &args.guide {
            Some(guide) => Some(guided::GuidedPlan::new(&args, guide)?),
            None => None,
        };
        let wall = resolve_wall(&args, plan.as_ref())?;
        // A full frame: --display matters only for the tiles and the wall camera.
        let tiles_model = match (&args.tiles, &plan, &wall) {
            (None, _, _) | (Some(_), Some(_), _) => None,
            (Some(_), None, Some(w)) => Some(w.model.clone()),
            (Some(_), None, None) => {
                let spec = args
                    .display
                    .as_deref()
                    .unwrap_or(crate::display::DEFAULT_MODEL);
                let (model, origin) = DisplayModel::open(spec)?;
                if root {
                    warn_if_resampled(args.size, &model, &origin.to_string());
                }
                Some(model)
            }
        };
        Ok(Self {
            args,
            filter,
            plan,
            wall,
            tiles_model,
        })
    }

    /// What the memory check counts for this render on a GPU (`gpu`) or the CPU.
    pub fn work(&self, gpu: bool) -> Work {
        if self.plan.is_some() {
            Work::Render {
                gpu,
                filter: self.filter.kind,
            }
        } else {
            Work::FullFrame { gpu }
        }
    }
}

/// `args` with `--size native` replaced by the pixel size of the canvas of `--display` (or the
/// default model).
fn with_native_size(args: &RenderArgs) -> anyhow::Result<RenderArgs> {
    let mut args = args.clone();
    let display = args
        .display
        .as_deref()
        .unwrap_or(crate::display::DEFAULT_MODEL);
    args.size = crate::cli::args::resolve_size(args.size, display)?;
    Ok(args)
}

/// `raygun render`: the configuration, then the backend and the memory it needs, then the
/// scene, then the work.
pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    if args.cluster.cluster {
        return cluster::run(&with_native_size(args)?);
    }
    let config = RenderConfig::new(args)?;
    let args = &config.args;
    let (backend, note) = args.backend.choose()?;
    if let Some(note) = note {
        crate::cli::say(args.quiet, note);
    }
    // A moving eye is a wall camera's.
    let moves = if args.camera.as_deref() == Some("wall") {
        args.head.on_eye_move()
    } else {
        crate::frame::EyeMove::Restart
    };
    check_memory(
        config.work(backend.is_gpu()),
        (args.denoise.denoise, moves),
        args.size,
        &backend,
    )?;
    let oidn_device = args.denoise.device(&backend)?;
    if let Some(note) = args.denoise.describe(oidn_device.as_ref(), &backend) {
        crate::cli::say(args.quiet, note);
    }
    let denoiser = args.denoise.denoiser(
        oidn_device.as_ref(),
        &config.filter,
        crate::filter::oidn::Quality::High,
    );
    let (scene, load_seconds) = load_scene_timed(&args.scene, args.env.as_deref(), args.access)?;
    let settings = settings(args, &scene)?;
    let wall = wall_camera(config.wall.as_ref(), &settings)?;
    let job = Job {
        scene: &scene,
        load_seconds,
        settings,
        wall,
        backend: &backend,
    };
    match &config.plan {
        Some(plan) => guided::run(args, plan, job, denoiser),
        None => full_frame(&config, job, denoiser),
    }
}

/// What a render traces, once the scene is loaded (`load_seconds`: one-time work, reported
/// apart from the sampling time).
pub struct Job<'a> {
    pub scene: &'a Scene,
    pub load_seconds: f64,
    pub settings: TraceSettings,
    pub wall: Option<WallCamera>,
    pub backend: &'a Backend,
}

/// A full-frame render of `--spp` samples per pixel, denoised when asked, and its files.
fn full_frame(
    config: &RenderConfig,
    job: Job<'_>,
    denoiser: Option<crate::filter::Denoiser<'_>>,
) -> anyhow::Result<()> {
    let Job {
        scene,
        load_seconds,
        settings,
        wall,
        backend,
    } = job;
    let args = &config.args;
    let [w, h] = args.size;
    let spp = args.spp.unwrap_or(DEFAULT_SPP);
    let mut renderer = match wall {
        Some(wc) => Renderer::full_wall(backend, scene, settings, wc)?,
        None => Renderer::full(backend, scene, settings)?,
    };
    let mut bar = Progress::new(args.quiet, "rendering", Some(u64::from(spp)), "spp");
    // Batches of about a quarter second keep the bar moving without starving the GPU. The
    // sampling time starts here, at the first frame: the load, the build and the upload are
    // one-time work, reported apart.
    let t0 = Instant::now();
    let mut done = 0;
    let mut batch = 1;
    while done < spp {
        let n = batch.min(spp - done);
        let tb = Instant::now();
        renderer.iterate(n)?;
        done += n;
        bar.set(u64::from(done));
        if tb.elapsed().as_secs_f64() < 0.25 {
            batch *= 2;
        }
    }
    let seconds = t0.elapsed().as_secs_f64();
    bar.finish();
    let acc = renderer.accumulation()?;
    let mut image = acc.mean_image();
    if let Some(d) = denoiser {
        let features = renderer.features()?;
        let wall = crate::frame::Render::wall(&renderer);
        let dropped;
        (image, dropped) = crate::frame::denoise_picture(backend, d, &acc, features, &image, wall)?;
        say_dropped(args.quiet, dropped);
    }
    drop(acc);
    for out in &args.out {
        write_rgb(out, w, h, &image, args.exposure)?;
    }
    if let Some(model) = &config.tiles_model {
        write_wall_tiles(args, model, &image)?;
    }
    let megasamples = f64::from(w) * f64::from(h) * f64::from(spp) / 1e6;
    let files: Vec<&std::path::Path> = args.out.iter().map(PathBuf::as_path).collect();
    crate::cli::say(
        args.quiet,
        OneTime {
            load_seconds,
            build_seconds: renderer.build_seconds,
            upload_seconds: renderer.upload_seconds,
        },
    );
    crate::cli::say(
        args.quiet,
        format_args!(
            "{}, {w}×{h}, {spp} spp in {:.2} s on {}: {:.2} ms per megasample (BVH build {:.2} s){}",
            crate::messages::count(scene.triangles.len(), "triangle"),
            seconds,
            backend.describe(),
            seconds * 1e3 / megasamples,
            renderer.build_seconds,
            crate::cli::wrote(&files),
        ),
    );
    Ok(())
}

/// The wall camera's flags checked against the display (`--camera wall`), before any work: the
/// guided plan's display (`--display`'s or the replay's), else `--display`'s; a replay's tracked
/// head gives the eye where `--eye` is left out.
fn resolve_wall(
    args: &RenderArgs,
    plan: Option<&guided::GuidedPlan>,
) -> anyhow::Result<Option<WallSpec>> {
    let wants = args.camera.as_deref() == Some(WALL_CAMERA);
    let model = match (&args.display, plan) {
        // A guided render's display: --display's, else the replay's.
        (_, Some(p)) if wants => Some(p.model.clone()),
        (Some(d), None) if wants => Some(DisplayModel::open(d).context("--display")?.0),
        _ => None,
    };
    let head_eye = plan.and_then(|p| p.source.first_eye());
    crate::cli::wall::wall_spec_or_eye(args.camera.as_deref(), &args.wall, model.as_ref(), head_eye)
}

/// The wall camera of `spec` for the settings' image, `auto` placing their camera at the eye.
fn wall_camera(
    spec: Option<&WallSpec>,
    settings: &TraceSettings,
) -> anyhow::Result<Option<WallCamera>> {
    spec.map(|s| {
        s.camera([settings.width, settings.height], &settings.camera)
            .context("--camera wall")
    })
    .transpose()
}

/// The tracer's settings from the arguments and the scene's camera (with `--camera wall`, the
/// camera `--world-from-room auto` puts at the eye: the scene's first).
fn settings(args: &RenderArgs, scene: &Scene) -> anyhow::Result<TraceSettings> {
    let [w, h] = args.size;
    let look = args.look.viewpoint();
    let name = args.camera.as_deref().filter(|c| *c != WALL_CAMERA);
    let camera = RenderCamera::choose_or_look_at(scene, name, look.as_ref(), w, h)
        .with_context(|| format!("scene {}", args.scene))?;
    Ok(TraceSettings {
        width: w,
        height: h,
        seed: args.seed,
        max_depth: args.max_depth,
        camera,
    })
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        render: super::RenderArgs,
    }

    fn args(extra: &[&str]) -> super::RenderArgs {
        let mut argv = vec!["render", "--scene", "builtin:cornell", "--out", "x.png"];
        argv.extend_from_slice(extra);
        Cli::try_parse_from(argv).unwrap().render
    }

    #[test]
    fn oidn_is_refused_with_the_cluster_and_the_interactive_denoiser_taken() {
        let e = super::check_args(&args(&["--cluster", "--denoise", "oidn"])).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("--denoise oidn denoises one process's picture"),
            "{e}"
        );
        super::check_args(&args(&["--denoise", "oidn"])).unwrap();
        super::check_args(&args(&["--cluster", "--denoise", "off"])).unwrap();
        super::check_args(&args(&["--cluster", "--denoise", "interactive"])).unwrap();
    }

    #[test]
    fn reuse_on_an_eye_move_is_the_default_and_refused_across_ranks() {
        assert_eq!(args(&[]).head.on_eye_move(), crate::frame::EyeMove::Reuse);
        let restart = args(&["--on-eye-move", "restart"]);
        assert_eq!(restart.head.on_eye_move(), crate::frame::EyeMove::Restart);
        let e = super::check_args(&args(&["--cluster", "--on-eye-move", "reuse"])).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("--on-eye-move reuse: a render across ranks"),
            "{e}"
        );
        super::check_args(&args(&["--cluster"])).unwrap();
        super::check_args(&args(&["--cluster", "--on-eye-move", "restart"])).unwrap();
        let argv = [
            "render",
            "--scene",
            "builtin:cornell",
            "--on-eye-move",
            "sometimes",
        ];
        let e = Cli::try_parse_from(argv).err().unwrap();
        assert!(e.to_string().contains("expected reuse or restart"), "{e}");
    }

    #[test]
    fn the_configuration_checks_the_numbers_first_and_knows_its_work() {
        // A bad number is named before a missing guide file is looked for.
        let e = super::RenderConfig::new(&args(&["--spp", "0"]))
            .err()
            .unwrap();
        assert_eq!(e.to_string(), "--spp must be at least 1");
        let e = super::RenderConfig::new(&args(&[
            "--max-depth",
            "0",
            "--guide",
            "no/such/replay.jsonl",
        ]))
        .err()
        .unwrap();
        assert_eq!(e.to_string(), "--max-depth must be at least 1");
        let full = super::RenderConfig::new(&args(&[])).unwrap();
        assert!(full.plan.is_none() && full.wall.is_none() && full.tiles_model.is_none());
        assert!(matches!(
            full.work(false),
            crate::memory::Work::FullFrame { gpu: false }
        ));
        let guided = super::RenderConfig::new(&args(&[
            "--size",
            "64,26",
            "--guide",
            "mouse:32,13:8,4",
            "--iterations",
            "2",
        ]))
        .unwrap();
        assert!(guided.plan.is_some());
        assert!(matches!(
            guided.work(true),
            crate::memory::Work::Render { gpu: true, .. }
        ));
        let native = super::RenderConfig::new(&args(&["--size", "native"])).unwrap();
        assert_ne!(native.args.size, crate::cli::args::NATIVE_SIZE);
    }
}
