//! `raygun render … --guide REPLAY_OR_POSE (--iterations N | --until …)`: a guided progressive
//! render whose ROI comes from a tracking replay (spread evenly over the iterations) or a fixed
//! pose or mouse ROI.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use glam::{DVec2, Vec3};

use crate::cli::args::{parse_pair, parse_vec3};
use crate::cli::progress::Progress;
use crate::cli::render::RenderArgs;
use crate::cli::tracking::{ReplayArgs, ReplayPlan, replay_changes_with};
use crate::display::DisplayModel;
use crate::filter::{FilterKind, FilterParams};
use crate::frame::{GuideConfig, GuidedRenderer};
use crate::gpu::Backend;
use crate::roi::cone::Cone;
use crate::roi::dgi::{Falloff, Roi};
use crate::scene::Scene;
use crate::stop::{RoiProgress, StopCondition, StopReason, reached};
use crate::trace::accum::Accumulation;
use crate::trace::cpu::TraceSettings;

/// Where the ROI comes from.
#[derive(Clone, Debug)]
pub enum GuideSource {
    /// A fixed ROI for every iteration.
    Fixed(Roi),
    /// A replay's ROI changes, (seconds since the first, ROI) in time order, spread evenly
    /// over the iterations.
    Replay {
        changes: Vec<(f64, Option<Roi>)>,
        duration: f64,
    },
}

impl GuideSource {
    /// Parses `pose:X,Y,Z:DX,DY,DZ:FOV[,FOV_V]` (room frame, metres, degrees; up is +Y) or
    /// `mouse:X,Y:A,B` (centre and semi-axes in image pixels) against `model`; `None` for
    /// anything else (a replay file).
    pub fn parse_fixed(
        arg: &str,
        model: &DisplayModel,
        size: [u32; 2],
    ) -> anyhow::Result<Option<Self>> {
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
            let cone = Cone::from_pose(origin, dir, glam::DVec3::Y, h, v)?;
            if model.intersect(origin, dir).is_none() {
                bail!(
                    "--guide pose: the ray from {origin} along {dir} misses the display ({}): it gives no ROI",
                    model.name()
                );
            }
            return Ok(Some(Self::Fixed(Roi::Cone(cone))));
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
            return Ok(Some(Self::Fixed(Roi::CanvasEllipse {
                center: model.image_to_canvas(center, size),
                semi_axes: axes * scale,
            })));
        }
        Ok(None)
    }

    /// The ROI changes of a replay, timed from its first event of the followed device.
    pub fn from_replay(plan: &ReplayPlan, file: &Path) -> anyhow::Result<Self> {
        let mut changes = Vec::new();
        let mut first = None;
        let mut last = 0.0f64;
        replay_changes_with(
            plan,
            file,
            |t_event| {
                first.get_or_insert(t_event);
                last = last.max(t_event);
            },
            |c| {
                changes.push((c.t, c.roi.to_roi().ok().flatten()));
            },
        )?;
        if !changes.iter().any(|(_, r)| r.is_some()) {
            bail!(
                "{}: no shot of the replay hits the display ({}): it gives no ROI (`raygun replay` lists its shots and misses)",
                file.display(),
                plan.display_origin
            );
        }
        let t0 = first.unwrap_or(0.0);
        let changes: Vec<(f64, Option<Roi>)> =
            changes.into_iter().map(|(t, r)| (t - t0, r)).collect();
        Ok(Self::Replay {
            changes,
            duration: (last - t0).max(0.0),
        })
    }

    /// The ROI for iteration `k` of `n`.
    #[must_use]
    pub fn roi_at(&self, k: u32, n: u32) -> Option<Roi> {
        match self {
            Self::Fixed(r) => Some(*r),
            Self::Replay { changes, duration } => {
                let t = duration * f64::from(k) / f64::from(n.max(1));
                changes
                    .iter()
                    .rev()
                    .find(|(tc, _)| *tc <= t)
                    .and_then(|(_, r)| *r)
            }
        }
    }
}

/// `<stem>.<what>.exr` next to `out`.
fn beside(out: &Path, what: &str) -> PathBuf {
    let stem = out.file_stem().and_then(|s| s.to_str()).unwrap_or("render");
    out.with_file_name(format!("{stem}.{what}.exr"))
}

/// When a guided render stops.
#[derive(Clone, Debug, Default)]
pub struct Stopping {
    /// At most this many iterations (`None`: until a condition is reached).
    pub iterations: Option<u32>,
    pub until: Vec<StopCondition>,
}

/// How often the ROI's progress is measured for a stop condition (a read-back on the GPU).
const PROGRESS_INTERVAL_S: f64 = 0.5;

/// What a guided render produced.
pub struct GuidedResult {
    pub size: [u32; 2],
    pub iterations: u32,
    /// The filtered mean image (linear RGB, row-major).
    pub image: Vec<Vec3>,
    /// The DGI of the last iteration.
    pub dgi: Vec<f32>,
    /// Samples per pixel.
    pub counts: Vec<u32>,
    /// Wall-clock seconds of the iterations (read-back and filter excluded).
    pub seconds: f64,
    pub stop: StopReason,
    /// The ROI's last measured progress (with stop conditions only).
    pub progress: Option<RoiProgress>,
}

impl GuidedResult {
    /// Samples taken in all.
    #[must_use]
    pub fn samples(&self) -> u64 {
        self.counts.iter().map(|&c| u64::from(c)).sum()
    }

    /// Samples as a share of `iterations` full frames.
    #[must_use]
    pub fn sample_share(&self) -> f64 {
        self.samples() as f64
            / (f64::from(self.size[0]) * f64::from(self.size[1]) * f64::from(self.iterations))
    }
}

/// The mean image of `acc`, filtered by `filter` on `backend` (the GPU kernels or the CPU twin).
pub fn filtered_image(
    backend: &Backend,
    filter: &FilterParams,
    acc: &Accumulation,
    dgi: &[f32],
) -> anyhow::Result<Vec<Vec3>> {
    Ok(match (backend, filter.kind) {
        (_, FilterKind::Off) => acc.mean_image(),
        (Backend::Gpu(ctx), _) => crate::filter::gpu::FilterKernels::new(ctx)
            .filter(ctx, filter, acc, dgi)?
            .iter()
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect(),
        (Backend::Cpu, _) => crate::filter::filter_cpu(filter, acc, dgi)?
            .iter()
            .map(|p| p.as_vec3())
            .collect(),
    })
}

/// Runs guided frames with the ROI from `source` until `stopping` says so, then reads back and
/// filters. `on_iteration` is called after each frame with the number done and the ROI's
/// progress when it was measured.
#[allow(clippy::too_many_arguments)]
pub fn render_guided(
    backend: &Backend,
    scene: &Scene,
    settings: TraceSettings,
    model: &DisplayModel,
    config: GuideConfig,
    filter: &FilterParams,
    source: &GuideSource,
    stopping: &Stopping,
    mut on_iteration: impl FnMut(u32, Option<&RoiProgress>),
) -> anyhow::Result<GuidedResult> {
    let mut r = GuidedRenderer::new(backend, scene, settings, model, config)?;
    let t0 = Instant::now();
    let needs_progress = stopping.until.iter().any(StopCondition::needs_progress);
    let spread = stopping.iterations.unwrap_or(1);
    let mut current: Option<Roi> = None;
    let mut last_check = f64::NEG_INFINITY;
    let mut progress = None;
    let mut k = 0;
    let stop = loop {
        if stopping.iterations.is_some_and(|n| k >= n) {
            break StopReason::Iterations(k);
        }
        let roi = source.roi_at(k, spread);
        if k == 0 || roi != current {
            r.set_roi(roi)?;
            current = roi;
        }
        r.run_frame(false)?;
        k += 1;
        let elapsed = t0.elapsed().as_secs_f64();
        let mut measured = false;
        if needs_progress && elapsed - last_check >= PROGRESS_INTERVAL_S {
            last_check = elapsed;
            progress = r.roi_progress()?;
            measured = true;
        }
        on_iteration(k, progress.as_ref().filter(|_| measured));
        if let Some(c) = reached(&stopping.until, progress.as_ref(), elapsed) {
            break StopReason::Reached(c);
        }
    };
    let seconds = t0.elapsed().as_secs_f64();
    let (acc, dgi) = r.finish()?;
    let image = filtered_image(backend, filter, &acc, &dgi)?;
    Ok(GuidedResult {
        size: [settings.width, settings.height],
        iterations: k,
        image,
        dgi,
        counts: acc.count,
        seconds,
        stop,
        progress,
    })
}

/// Writes the DGI and the sample counts (EXR or PNG by extension).
pub fn write_guides(res: &GuidedResult, dgi_out: &Path, counts_out: &Path) -> anyhow::Result<()> {
    let [w, h] = res.size;
    crate::output::write_gray(dgi_out, w, h, &res.dgi, crate::output::DGI_CHANNEL)?;
    let counts: Vec<f32> = res.counts.iter().map(|&c| c as f32).collect();
    crate::output::write_gray(counts_out, w, h, &counts, "samples")?;
    Ok(())
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
    pub dgi_out: PathBuf,
    pub counts_out: PathBuf,
}

impl GuidedPlan {
    /// Resolves the display (a replay guide's header names one; `--display` overrides it), the
    /// guide and the stop rule, and checks that the run means something: a guide that gives no
    /// ROI is an error, not a black image.
    pub fn new(args: &RenderArgs, guide: &str) -> anyhow::Result<Self> {
        let config = guide_config(args)?;
        let filter = args.filter.params()?;
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
                GuideSource::parse_fixed(guide, &model, args.size)?.expect("a pose or mouse guide");
            (model, origin.to_string(), source)
        } else {
            let file = PathBuf::from(guide);
            let replay = ReplayArgs {
                display: args.display.clone(),
                calibration: args.calibration.clone(),
                ..ReplayArgs::of(file.clone())
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
        let first = &args.out[0];
        let dgi_out = args.dgi_out.clone().unwrap_or_else(|| beside(first, "dgi"));
        let counts_out = args
            .counts_out
            .clone()
            .unwrap_or_else(|| beside(first, "counts"));
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
    scene: &Scene,
    settings: TraceSettings,
    backend: &Backend,
) -> anyhow::Result<()> {
    eprintln!("raygun: display: {}", plan.display_note);
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
    let t0 = Instant::now();
    let res = render_guided(
        backend,
        scene,
        settings,
        &plan.model,
        plan.config,
        &plan.filter,
        &plan.source,
        &plan.stopping,
        |k, progress| {
            if let Some(p) = progress {
                let eta = target_se
                    .and_then(|x| p.seconds_to_se(x, t0.elapsed().as_secs_f64()))
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
    let samples = res.samples();
    if samples == 0 {
        bail!(
            "no pixel was sampled in {} iterations: the ROI never reached the image and --p-min is 0",
            res.iterations
        );
    }
    let [w, h] = res.size;
    for out in &args.out {
        crate::output::write_rgb(out, w, h, &res.image, args.exposure)?;
    }
    crate::cli::render::write_wall_tiles(args, &plan.model, &res.image)?;
    write_guides(&res, &plan.dgi_out, &plan.counts_out)?;
    let roi = res.progress.map_or(String::new(), |p| {
        format!(
            "; ROI: {} pixels, median SE {:.4}, fewest samples {}",
            p.pixels, p.median_se, p.min_samples
        )
    });
    eprintln!(
        "raygun: guided render stopped ({}): {} iterations in {:.2} s on {}: {samples} samples ({:.2} % of full frame), {:.2} ms per megasample{roi}; wrote {}, {}",
        res.stop,
        res.iterations,
        res.seconds,
        backend.describe(),
        100.0 * res.sample_share(),
        res.seconds * 1e3 / (samples as f64 / 1e6),
        plan.dgi_out.display(),
        plan.counts_out.display(),
    );
    Ok(())
}
