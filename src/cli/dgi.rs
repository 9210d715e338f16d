//! `raygun dgi`: the distance-guide image for a pose (ray gun) or a click (mouse).

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::ValueEnum;
use glam::{DVec2, DVec3};

use crate::cli::args::{parse_pair, parse_vec3};
use crate::display::DisplayModel;
use crate::gpu::Backend;
use crate::roi::cone::Cone;
use crate::roi::dgi::{DgiParams, Falloff, Guide, Metric, Roi, Surface, compute_cpu, roi_radius_m};
use crate::roi::gpu::DgiKernel;

#[derive(Clone, Debug, clap::Args)]
pub struct DgiArgs {
    /// Display model: a file, or a built-in model (hornet, desktop-27in-4k, projection-4m-4k).
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Ray-gun apex in the room frame, metres.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true,
          requires_all = ["dir", "fov"], conflicts_with_all = ["center_px", "axes_px"])]
    pub origin: Option<DVec3>,
    /// Pointing direction in the room frame.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub dir: Option<DVec3>,
    /// Up hint: the ROI's vertical axis is this vector made perpendicular to the direction.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true,
          default_value = "0,1,0")]
    pub up: DVec3,
    /// Full horizontal and vertical field of view, degrees.
    #[arg(long, value_name = "H,V", value_parser = parse_pair)]
    pub fov: Option<DVec2>,
    /// Mouse ROI: centre in image pixels.
    #[arg(long = "center-px", value_name = "X,Y", value_parser = parse_pair,
          requires = "axes_px", allow_hyphen_values = true)]
    pub center_px: Option<DVec2>,
    /// Mouse ROI: semi-axes in image pixels.
    #[arg(long = "axes-px", value_name = "A,B", value_parser = parse_pair)]
    pub axes_px: Option<DVec2>,
    /// Distance measure.
    #[arg(long, value_enum, default_value_t = Metric::Exact)]
    pub metric: Metric,
    /// Image size in pixels, W,H, or `native`: the display canvas's own pixel size.
    /// The image covers the canvas.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H|native", value_parser = crate::cli::args::parse_size_or_native, default_value = "3840,2160")]
    pub size: [u32; 2],
    /// Falloff L = BASE + SCALE × ROI radius: the base, metres along the wall.
    #[arg(long, value_name = "METRES", default_value_t = Falloff::DEFAULT_BASE_M)]
    pub falloff_base: f64,
    /// Falloff L = BASE + SCALE × ROI radius: the scale.
    #[arg(long, value_name = "K", default_value_t = Falloff::DEFAULT_SCALE)]
    pub falloff_scale: f64,
    /// Write the raw canvas distance (canvas pixels) instead of d (EXR only).
    #[arg(long)]
    pub raw: bool,
    /// Output file: .exr (32-bit float, one channel) or .png (8-bit view of d).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
}

/// A ray-gun pose gives an ROI only where its ray meets the display (a press that misses leaves
/// the ROI as it was, DESIGN.md §4): the error `what` (the flags that gave the pose) says so.
pub fn check_pose_hits(
    model: &DisplayModel,
    origin: DVec3,
    dir: DVec3,
    what: &str,
) -> anyhow::Result<()> {
    if model.intersect(origin, dir).is_none() {
        bail!(
            "{what}: the ray from {origin} along {dir} misses the display ({}): it gives no ROI",
            model.name()
        );
    }
    Ok(())
}

/// Builds the ROI the arguments describe.
pub fn roi_from_args(args: &DgiArgs, model: &DisplayModel) -> anyhow::Result<Roi> {
    match (args.origin, args.center_px) {
        (Some(origin), None) => {
            let (Some(dir), Some(fov)) = (args.dir, args.fov) else {
                bail!("--origin needs --dir and --fov");
            };
            let cone = Cone::from_pose(origin, dir, args.up, fov.x, fov.y)?;
            check_pose_hits(model, origin, dir, "--origin/--dir")?;
            Ok(Roi::Cone(cone))
        }
        (None, Some(center)) => {
            let axes = args.axes_px.context("--center-px needs --axes-px")?;
            if !(axes.x >= 0.0 && axes.y >= 0.0) {
                bail!(
                    "--axes-px must be two non-negative numbers, got {},{}",
                    axes.x,
                    axes.y
                );
            }
            let canvas = model.canvas_rect();
            let scale =
                canvas.size() / DVec2::new(f64::from(args.size[0]), f64::from(args.size[1]));
            Ok(Roi::CanvasEllipse {
                center: model.image_to_canvas(center, args.size),
                semi_axes: axes * scale,
            })
        }
        _ => bail!(
            "give either a ray-gun pose (--origin, --dir, --fov) or a mouse ROI (--center-px, --axes-px)"
        ),
    }
}

pub fn run(args: &DgiArgs) -> anyhow::Result<()> {
    let mut args = args.clone();
    args.size = crate::cli::args::resolve_size(args.size, &args.display)?;
    let args = &args;
    // The output first: a bad path or extension fails before any work.
    crate::output::check_image_path(&args.out)?;
    if args.raw
        && !args
            .out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
    {
        bail!("--raw distances need an .exr output");
    }
    let model = DisplayModel::open(&args.display)?.0;
    let roi = roi_from_args(args, &model)?;
    let backend = args.backend.select()?;
    crate::cli::render::check_memory(
        crate::memory::Work::Dgi {
            gpu: backend.is_gpu(),
        },
        (
            crate::filter::DenoiseKind::Off,
            crate::frame::EyeMove::Restart,
        ),
        args.size,
        &backend,
    )?;
    let surface = Surface::from_model(&model);
    let falloff = Falloff::new(args.falloff_base, args.falloff_scale)?;
    let length_px = falloff.length_px(roi_radius_m(&surface, &roi), model.pitch_m());
    let params = DgiParams {
        width: args.size[0],
        height: args.size[1],
        falloff_px: (!args.raw).then_some(length_px),
    };
    let guide = Guide::new(&surface, &roi, args.metric)?;
    let values = match &backend {
        Backend::Gpu(ctx) => DgiKernel::new(ctx).compute(ctx, &surface, &guide, &params)?,
        Backend::Cpu => compute_cpu(&surface, &guide, &params),
    };
    crate::output::write_gray(
        &args.out,
        params.width,
        params.height,
        &values,
        if args.raw {
            "distance"
        } else {
            crate::output::DGI_CHANNEL
        },
    )?;
    eprintln!(
        "raygun dgi: {}×{} {} on {} → {}",
        params.width,
        params.height,
        args.metric
            .to_possible_value()
            .map_or_else(String::new, |v| v.get_name().to_owned()),
        backend.describe(),
        args.out.display()
    );
    Ok(())
}
