//! `raygun render … --guide REPLAY_OR_POSE (--iterations N | --until …)`: a guided progressive
//! render whose ROI comes from a tracking replay (spread evenly over the iterations) or a fixed
//! pose or mouse ROI.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use glam::DVec2;

use crate::cli::args::{parse_pair, parse_vec3};
use crate::cli::progress::Progress;
use crate::cli::render::RenderArgs;
use crate::display::DisplayModel;
use crate::filter::FilterParams;
use crate::frame::GuideConfig;
use crate::frame::stop::StopCondition;
use crate::roi::cone::Cone;
use crate::roi::dgi::{Falloff, Roi};
use crate::session::guide::GuideSource;
use crate::session::render::{GuidedRender, Stopping, render_guided};
use crate::session::replay::{ReplayOptions, ReplayPlan};

/// Parses `pose:X,Y,Z:DX,DY,DZ:FOV[,FOV_V]` (room frame, metres, degrees; up is +Y) or
/// `mouse:X,Y:A,B` (centre and semi-axes in image pixels) against `model`; `None` for
/// anything else (a replay file).
pub fn parse_fixed_guide(
    arg: &str,
    model: &DisplayModel,
    size: [u32; 2],
) -> anyhow::Result<Option<GuideSource>> {
    if let Some(rest) = arg.strip_prefix("pose:") {
        let parts: Vec<&str> = rest.split(':').collect();
        let [o, d, f] = parts[..] else {
            bail!(
                "--guide pose:X,Y,Z:DX,DY,DZ:FOV[,FOV_V] needs three ':'-separated parts, got {}",
                crate::messages::quote(arg)
            );
        };
        let origin = parse_vec3(o).context("--guide pose: the origin")?;
        let dir = parse_vec3(d).context("--guide pose: the direction")?;
        let fov: Vec<f64> = f
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .context("--guide pose: the field of view (degrees)")?;
        let (h, v) = match fov[..] {
            [a] => (a, a),
            [a, b] => (a, b),
            _ => bail!("--guide pose: the field of view is FOV or FOV_H,FOV_V (degrees)"),
        };
        let cone = Cone::from_pose(origin, dir, glam::DVec3::Y, h, v).map_err(|e| match e {
            crate::roi::cone::ConeError::UpParallel => anyhow::anyhow!(
                "--guide pose: the direction {dir} points straight up or down: the ROI's \
                 horizontal axis is level (square to the room's +Y), so the ray gun must not \
                 point vertically"
            ),
            e => anyhow::Error::new(e).context("--guide pose"),
        })?;
        crate::cli::dgi::check_pose_hits(model, origin, dir, "--guide pose")?;
        return Ok(Some(GuideSource::Fixed(Roi::Cone(cone))));
    }
    if let Some(rest) = arg.strip_prefix("mouse:") {
        let (c, a) = rest.split_once(':').with_context(|| {
            format!(
                "--guide mouse:X,Y:A,B needs a centre and semi-axes, got {}",
                crate::messages::quote(arg)
            )
        })?;
        let center = parse_pair(c).context("--guide mouse: the centre")?;
        let axes = parse_pair(a).context("--guide mouse: the semi-axes")?;
        if !(axes.x > 0.0 && axes.y > 0.0) {
            bail!(
                "--guide mouse: the semi-axes must be positive (image pixels), got {},{}",
                crate::messages::number(axes.x),
                crate::messages::number(axes.y)
            );
        }
        // The ellipse must reach the image: the nearest image point to its centre, in
        // the ellipse's unit-circle coordinates, lies within 1.
        let s = DVec2::new(f64::from(size[0]), f64::from(size[1]));
        let nearest = center.clamp(DVec2::ZERO, s);
        if ((nearest - center) / axes).length() > 1.0 {
            bail!(
                "--guide mouse: the ellipse at {},{} with semi-axes {},{} lies outside the {}×{} image: it gives no ROI",
                crate::messages::number(center.x),
                crate::messages::number(center.y),
                crate::messages::number(axes.x),
                crate::messages::number(axes.y),
                size[0],
                size[1]
            );
        }
        let scale = model.canvas_rect().size() / s;
        return Ok(Some(GuideSource::Fixed(Roi::CanvasEllipse {
            center: model.image_to_canvas(center, size),
            semi_axes: axes * scale,
        })));
    }
    Ok(None)
}

/// `<stem>.<what>.exr` next to `out`.
fn beside(out: &Path, what: &str) -> PathBuf {
    let stem = out.file_stem().and_then(|s| s.to_str()).unwrap_or("render");
    out.with_file_name(format!("{stem}.{what}.exr"))
}

/// The guide arguments of `render` as a [`GuideConfig`].
pub fn guide_config(args: &RenderArgs) -> anyhow::Result<GuideConfig> {
    if !(0.0..=1.0).contains(&args.p_min) {
        bail!(
            "--p-min must be a probability from 0 to 1, not {}",
            crate::messages::number(f64::from(args.p_min))
        );
    }
    Ok(GuideConfig {
        metric: args.metric,
        falloff: Falloff::new(args.falloff_base, args.falloff_scale)?,
        p_min: args.p_min,
        order: args.order,
    })
}

/// A guided render's validated inputs: everything but the scene.
pub struct GuidedPlan {
    pub model: DisplayModel,
    /// Which model and why, for the closing message.
    pub display_note: String,
    pub source: GuideSource,
    pub config: GuideConfig,
    pub filter: FilterParams,
    pub stopping: Stopping,
    /// Where the DGI and the counts go: `--dgi-out`/`--counts-out`, else beside the first
    /// `--out` (none without one).
    pub dgi_out: Option<PathBuf>,
    pub counts_out: Option<PathBuf>,
}

impl GuidedPlan {
    /// Resolves the display (a replay guide's header names one; `--display` overrides it), the
    /// guide and the stop rule, and checks that the run means something: a guide that gives no
    /// ROI is an error, not a black image.
    pub fn new(args: &RenderArgs, guide: &str) -> anyhow::Result<Self> {
        let config = guide_config(args)?;
        let filter = args.filter.params()?;
        args.head.check()?;
        if args.iterations == Some(0) {
            bail!("--iterations must be at least 1");
        }
        let fixed = guide.starts_with("pose:") || guide.starts_with("mouse:");
        let (model, display_note, source) = if fixed {
            let spec = args
                .display
                .as_deref()
                .unwrap_or(crate::display::DEFAULT_MODEL);
            let (model, origin) = DisplayModel::open(spec)?;
            let source =
                parse_fixed_guide(guide, &model, args.size)?.expect("a pose or mouse guide");
            (model, origin.to_string(), source)
        } else {
            let file = PathBuf::from(guide);
            let replay = ReplayOptions {
                display: args.display.clone(),
                calibration: args.calibration.clone(),
                head: args.head.overrides(),
                ..ReplayOptions::of(file.clone())
            };
            let (plan, _) =
                ReplayPlan::new(&replay).with_context(|| format!("--guide {}", file.display()))?;
            let note = if args.display.is_some() {
                plan.display_origin.clone()
            } else {
                format!("{}, as the replay's header says", plan.display_origin)
            };
            if args.iterations.is_none() {
                bail!(
                    "--guide {}: a replay guide needs --iterations N (the replay is spread over them); --until can stop it sooner",
                    file.display()
                );
            }
            let source = GuideSource::from_replay(&plan, &file)?;
            (plan.surface, note, source)
        };
        if args.iterations.is_none() && args.until.is_empty() {
            bail!("a guided render needs --iterations N or --until CONDITION");
        }
        if args.tiles.is_some() {
            crate::cli::render::warn_if_resampled(args.size, &model, &display_note);
        }
        let first = args.out.first();
        let dgi_out = args
            .dgi_out
            .clone()
            .or_else(|| first.map(|f| beside(f, "dgi")));
        let counts_out = args
            .counts_out
            .clone()
            .or_else(|| first.map(|f| beside(f, "counts")));
        Ok(Self {
            model,
            display_note,
            source,
            config,
            filter,
            stopping: Stopping {
                iterations: args.iterations,
                until: args.until.clone(),
            },
            dgi_out,
            counts_out,
        })
    }
}

pub fn run(
    args: &RenderArgs,
    plan: &GuidedPlan,
    job: super::Job<'_>,
    denoise: Option<crate::filter::Denoiser<'_>>,
) -> anyhow::Result<()> {
    let super::Job {
        scene,
        load_seconds,
        settings,
        wall,
        backend,
    } = job;
    crate::cli::say(args.quiet, format_args!("display: {}", plan.display_note));
    let mut bar = Progress::new(
        args.quiet,
        "guided render",
        plan.stopping.iterations.map(u64::from),
        "iterations",
    );
    let target_se = plan.stopping.until.iter().find_map(|c| match c {
        StopCondition::RoiSe(x) => Some(*x),
        _ => None,
    });
    let res = render_guided(
        backend,
        scene,
        GuidedRender {
            settings,
            model: &plan.model,
            wall,
            config: plan.config,
            filter: plan.filter,
            denoise,
            keep_sums: false,
            on_eye_move: args.head.on_eye_move(),
        },
        &plan.source,
        &plan.stopping,
        |k, progress| {
            // The time sampled so far at the pace after the first frame: the BVH build and
            // the upload before it are not time spent on the ROI.
            if let Some(p) = progress {
                let eta = target_se
                    .zip(bar.sampling_seconds(u64::from(k)))
                    .and_then(|(x, sampled)| p.seconds_to_se(x, sampled))
                    .map_or(String::new(), |s| format!(", about {s:.0} s to the target"));
                bar.note(&format!(
                    "ROI: median SE {:.4}, fewest samples {}{eta}",
                    p.median_se, p.min_samples
                ));
            }
            bar.set(u64::from(k));
        },
    )?;
    bar.finish();
    crate::cli::say(
        args.quiet,
        crate::cli::progress::OneTime {
            load_seconds,
            build_seconds: res.build_seconds,
            upload_seconds: res.upload_seconds,
        },
    );
    write_outputs(args, plan, &res, false, &backend.describe(), "")
}

/// Why a guided render that took no sample writes nothing.
pub fn nothing_sampled(iterations: u32) -> anyhow::Error {
    anyhow::anyhow!(
        "no pixel was sampled in {}: the ROI never reached the image and --p-min is 0",
        crate::messages::count(iterations as usize, "iteration")
    )
}

/// `; wrote DGI, COUNTS` for the guide images a render writes (nothing without them).
fn wrote_files(args: &RenderArgs, plan: &GuidedPlan) -> String {
    let files: Vec<&std::path::Path> = args
        .out
        .iter()
        .chain([&plan.dgi_out, &plan.counts_out].into_iter().flatten())
        .map(std::path::PathBuf::as_path)
        .collect();
    crate::cli::wrote(&files)
}

/// Writes a guided render's image, tiles (unless their owners wrote them: `tiles_written`),
/// DGI and counts, and says what was done (`device` ran it; `extra` closes the message).
pub fn write_outputs(
    args: &RenderArgs,
    plan: &GuidedPlan,
    res: &crate::session::render::GuidedResult,
    tiles_written: bool,
    device: &str,
    extra: &str,
) -> anyhow::Result<()> {
    let samples = res.samples();
    if samples == 0 {
        return Err(nothing_sampled(res.iterations));
    }
    let [w, h] = res.size;
    for out in &args.out {
        crate::output::write_rgb(out, w, h, &res.image, args.exposure)?;
    }
    if !tiles_written {
        crate::cli::render::write_wall_tiles(args, &plan.model, &res.image)?;
    }
    res.write_guides(plan.dgi_out.as_deref(), plan.counts_out.as_deref())?;
    super::say_dropped(args.quiet, res.denoise_dropped);
    say_eye_moves(args.quiet, res);
    let roi = res.progress.map_or(String::new(), |p| {
        format!(
            "; ROI: {} pixels, median SE {:.4}, fewest samples {}",
            p.pixels, p.median_se, p.min_samples
        )
    });
    crate::cli::say(
        args.quiet,
        format_args!(
            "guided render stopped ({}): {} in {:.2} s on {}: {} ({:.2} % of full frame), {:.2} ms per megasample{roi}{}",
            res.stop,
            crate::messages::count(res.iterations as usize, "iteration"),
            res.seconds,
            device,
            crate::messages::count(samples as usize, "sample"),
            100.0 * res.sample_share(),
            res.seconds * 1e3 / (samples as f64 / 1e6),
            wrote_files(args, plan),
        ),
    );
    if !extra.is_empty() {
        crate::cli::say(args.quiet, extra);
    }
    Ok(())
}

/// Says how often a tracked head moved the eye and what each move did to the accumulation
/// (nothing when it never moved and no eye was refused).
fn say_eye_moves(quiet: bool, res: &crate::session::render::GuidedResult) {
    let refused = if res.eyes_refused > 0 {
        format!(
            "; {} on or behind a tile's plane {} refused",
            crate::messages::count(res.eyes_refused as usize, "eye"),
            if res.eyes_refused == 1 { "was" } else { "were" }
        )
    } else {
        String::new()
    };
    let what = if !res.eye_reuses.is_empty() {
        let share = res
            .eye_reuses
            .iter()
            .map(|(_, _, s)| s.share())
            .sum::<f64>()
            / res.eye_reuses.len() as f64;
        format!(
            "{} (each move carried the accumulation of {:.0} % of the shown pixels on average, the ROI kept)",
            crate::messages::count(res.eye_reuses.len(), "time"),
            100.0 * share
        )
    } else if !res.eye_restarts.is_empty() || res.eyes_refused > 0 {
        format!(
            "{} (the accumulation restarted each time, the ROI kept; the picture holds the last {})",
            crate::messages::count(res.eye_restarts.len(), "time"),
            crate::messages::count(res.accumulated as usize, "iteration"),
        )
    } else {
        return;
    };
    crate::cli::say(
        quiet,
        format_args!("the tracked head moved the eye {what}{refused}"),
    );
}
