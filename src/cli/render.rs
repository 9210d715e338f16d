//! `raygun render`: a progressive path-traced image of a glTF scene, written as EXR (linear,
//! 32-bit float RGB) and/or PNG (sRGB, 8-bit) by the files' extensions.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};

use crate::cli::args::parse_size;
use crate::display::DisplayModel;
use crate::gpu::{Backend, BackendChoice};
use crate::output::{Format, write_rgb};
use crate::scene::{Environment, Scene};
use crate::trace::camera::RenderCamera;
use crate::trace::cpu::{DEFAULT_MAX_DEPTH, TraceSettings};
use crate::trace::render::Renderer;

#[derive(Clone, Debug, clap::Args)]
pub struct RenderArgs {
    /// Scene: a .gltf/.glb file, or builtin:cornell, builtin:cornell-light, builtin:city,
    /// builtin:city-small.
    #[arg(long, value_name = "FILE|builtin:NAME")]
    pub scene: String,
    /// Camera by name (default: the scene's first camera, else one framing the scene).
    #[arg(long, value_name = "NAME")]
    pub camera: Option<String>,
    /// Image size.
    #[arg(long, value_name = "W,H", value_parser = parse_size, default_value = "1280,720")]
    pub size: [u32; 2],
    /// Samples per pixel.
    #[arg(long, value_name = "N", default_value_t = 64)]
    pub spp: u32,
    /// Environment light: linear radiance R,G,B or an equirectangular .hdr/.exr image
    /// (default: white, radiance 1).
    #[arg(long, value_name = "R,G,B|FILE")]
    pub env: Option<String>,
    /// Maximum path vertices.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_DEPTH)]
    pub max_depth: u32,
    /// Seed of the per-pixel random sequences.
    #[arg(long, default_value_t = 1)]
    pub seed: u32,
    /// Output files (repeatable): .exr (linear RGB, f32) or .png (sRGB, 8-bit).
    #[arg(long, value_name = "FILE", required = true)]
    pub out: Vec<PathBuf>,
    /// PNG exposure in stops (the EXR keeps the linear values).
    #[arg(
        long,
        value_name = "EV",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub exposure: f32,
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Guided rendering (DESIGN.md §6): the ROI from a tracking replay (spread evenly over the
    /// iterations), a ray-gun pose `pose:X,Y,Z:DX,DY,DZ:FOV[,FOV_V]` (room frame, degrees) or
    /// a mouse ROI `mouse:X,Y:A,B` (image pixels). Writes the image, the DGI and the per-pixel
    /// sample counts.
    #[arg(
        long,
        value_name = "REPLAY|pose:…|mouse:…",
        requires = "iterations",
        allow_hyphen_values = true
    )]
    pub guide: Option<String>,
    /// Guided iterations (each traces one path per scheduled pixel); replaces --spp.
    #[arg(long, value_name = "N", requires = "guide")]
    pub iterations: Option<u32>,
    /// Display model whose canvas the image covers (guided rendering).
    #[arg(
        long,
        value_name = "FILE",
        default_value = "display-models/hornet.json"
    )]
    pub display: PathBuf,
    /// Lowest sampling probability (paper preset 0).
    #[arg(long, value_name = "P", default_value_t = 0.0)]
    pub p_min: f32,
    /// Distance measure of the DGI.
    #[arg(long, value_enum, default_value_t = crate::roi::dgi::Metric::Exact)]
    pub metric: crate::roi::dgi::Metric,
    /// Falloff L = BASE + SCALE × ROI radius: the base, metres along the wall.
    #[arg(long, value_name = "METRES", default_value_t = crate::roi::dgi::Falloff::DEFAULT_BASE_M)]
    pub falloff_base: f64,
    /// Falloff L = BASE + SCALE × ROI radius: the scale.
    #[arg(long, value_name = "K", default_value_t = crate::roi::dgi::Falloff::DEFAULT_SCALE)]
    pub falloff_scale: f64,
    /// Order of the scheduled pixel list.
    #[arg(long, value_enum, default_value_t = crate::schedule::Order::Coherent)]
    pub order: crate::schedule::Order,
    #[command(flatten)]
    pub filter: crate::cli::filter::FilterArgs,
    /// Where to write the DGI (EXR or PNG; default `<out stem>.dgi.exr`).
    #[arg(long, value_name = "FILE")]
    pub dgi_out: Option<PathBuf>,
    /// Where to write the per-pixel sample counts (EXR; default `<out stem>.counts.exr`).
    #[arg(long, value_name = "FILE")]
    pub counts_out: Option<PathBuf>,
    /// Wall output: one image per tile of --display, `DIR/<tile id>.<exr|png>`, cut from the
    /// image (which covers the canvas) with the pixels behind bezels left out. Render at the
    /// canvas size for an exact cut; other sizes are resampled by nearest neighbour.
    #[arg(long, value_name = "DIR")]
    pub tiles: Option<PathBuf>,
    /// Format of the tile images (default: the first --out file's).
    #[arg(long, value_name = "exr|png", requires = "tiles", value_parser = parse_format)]
    pub tiles_format: Option<Format>,
}

fn parse_format(s: &str) -> Result<Format, String> {
    match s.to_ascii_lowercase().as_str() {
        "exr" => Ok(Format::Exr),
        "png" => Ok(Format::Png),
        _ => Err(format!("'{s}': the tile format is exr or png")),
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
    let format = match args.tiles_format {
        Some(f) => f,
        None => Format::from_path(&args.out[0])?,
    };
    let canvas = crate::output::tiles::canvas_pixel_size(model);
    if canvas != args.size {
        eprintln!(
            "raygun: --tiles: the {}×{} image is resampled (nearest neighbour) to the {}×{} canvas of {}",
            args.size[0],
            args.size[1],
            canvas[0],
            canvas[1],
            args.display.display()
        );
    }
    let paths =
        crate::output::tiles::write_tiles(dir, model, image, args.size, format, args.exposure)
            .with_context(|| format!("--tiles {}", dir.display()))?;
    eprintln!(
        "raygun: wrote {} tile images to {}",
        paths.len(),
        dir.display()
    );
    Ok(())
}

/// A progress bar over `len` units (hidden when `quiet`).
#[must_use]
pub fn progress(quiet: bool, len: u64, unit: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    ProgressBar::new(len).with_style(
        ProgressStyle::with_template(&format!(
            "{{msg}} [{{bar:40}}] {{pos}}/{{len}} {unit}, {{elapsed}} (eta {{eta}})"
        ))
        .expect("static template")
        .progress_chars("=> "),
    )
}

/// Loads the scene named by `--scene`, with `--env` applied and its unsupported features
/// reported on standard error.
pub fn load_scene(scene: &str, env: Option<&str>) -> anyhow::Result<Scene> {
    let mut s = Scene::open(scene)?;
    if let Some(env) = env {
        s.environment = Environment::parse(env)?;
    }
    for u in &s.unsupported {
        eprintln!("raygun: {scene}: not supported, ignored: {u}");
    }
    Ok(s)
}

/// Loads each of `scenes` with [`load_scene`], named by its argument without `builtin:`.
pub fn load_scenes(scenes: &[String], env: Option<&str>) -> anyhow::Result<Vec<(String, Scene)>> {
    scenes
        .iter()
        .map(|s| {
            Ok((
                s.trim_start_matches("builtin:").to_string(),
                load_scene(s, env)?,
            ))
        })
        .collect()
}

pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    if args.spp == 0 {
        anyhow::bail!("--spp must be at least 1");
    }
    if args.max_depth == 0 {
        anyhow::bail!("--max-depth must be at least 1");
    }
    for out in &args.out {
        crate::output::Format::from_path(out)?;
    }
    // Load the model before the render so a bad --display fails at once.
    let wall = match &args.tiles {
        Some(_) => Some(DisplayModel::load(&args.display)?),
        None => None,
    };
    let scene = load_scene(&args.scene, args.env.as_deref())?;
    let [w, h] = args.size;
    let camera = RenderCamera::choose(&scene, args.camera.as_deref(), w, h)
        .with_context(|| format!("scene {}", args.scene))?;
    let backend = Backend::select(args.backend)?;
    let settings = TraceSettings {
        width: w,
        height: h,
        seed: args.seed,
        max_depth: args.max_depth,
        camera,
    };
    if let (Some(guide), Some(iterations)) = (&args.guide, args.iterations) {
        if iterations == 0 {
            anyhow::bail!("--iterations must be at least 1");
        }
        return crate::cli::guided::run(args, &scene, settings, &backend, guide, iterations);
    }
    let mut renderer = Renderer::new(&backend, &scene, settings)?;
    let bar = progress(args.quiet, u64::from(args.spp), "spp");
    bar.set_message("rendering");
    // Batches of about a quarter second keep the bar moving without starving the GPU.
    let t0 = Instant::now();
    let mut done = 0;
    let mut batch = 1;
    while done < args.spp {
        let n = batch.min(args.spp - done);
        let tb = Instant::now();
        renderer.iterate(n)?;
        done += n;
        bar.set_position(u64::from(done));
        if tb.elapsed().as_secs_f64() < 0.25 {
            batch *= 2;
        }
    }
    let seconds = t0.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let acc = renderer.accumulation()?;
    let image = acc.mean_image();
    for out in &args.out {
        write_rgb(out, w, h, &image, args.exposure)?;
    }
    if let Some(model) = &wall {
        write_wall_tiles(args, model, &image)?;
    }
    let megasamples = f64::from(w) * f64::from(h) * f64::from(args.spp) / 1e6;
    eprintln!(
        "raygun: {} triangles, {w}×{h}, {} spp in {:.2} s on {}: {:.2} ms per megasample (BVH build {:.2} s)",
        scene.triangles.len(),
        args.spp,
        seconds,
        backend.describe(),
        seconds * 1e3 / megasamples,
        renderer.build_seconds,
    );
    Ok(())
}
