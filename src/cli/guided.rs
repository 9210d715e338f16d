//! `raygun render … --guide REPLAY_OR_POSE --iterations N`: a guided progressive render whose
//! ROI comes from a tracking replay (spread evenly over the iterations) or a fixed pose.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use glam::{DVec2, Vec3};

use crate::cli::args::{parse_pair, parse_vec3};
use crate::cli::render::RenderArgs;
use crate::cli::tracking::{ReplayArgs, replay_changes};
use crate::display::DisplayModel;
use crate::filter::{FilterKind, FilterParams};
use crate::frame::{GuideConfig, GuidedRenderer};
use crate::gpu::Backend;
use crate::roi::cone::Cone;
use crate::roi::dgi::{Falloff, Roi};
use crate::scene::Scene;
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
    /// Parses `pose:X,Y,Z:DX,DY,DZ:FOV[,FOV_V]` (room frame, metres, degrees; up is +Y),
    /// `mouse:X,Y:A,B` (centre and semi-axes in image pixels) or a replay file path.
    pub fn parse(
        arg: &str,
        model: &DisplayModel,
        display: &Path,
        size: [u32; 2],
    ) -> anyhow::Result<Self> {
        if let Some(rest) = arg.strip_prefix("pose:") {
            let parts: Vec<&str> = rest.split(':').collect();
            let [o, d, f] = parts[..] else {
                bail!(
                    "--guide pose:X,Y,Z:DX,DY,DZ:FOV[,FOV_V] needs three ':'-separated parts, got '{arg}'"
                );
            };
            let origin = parse_vec3(o).with_context(|| format!("--guide {arg}: origin"))?;
            let dir = parse_vec3(d).with_context(|| format!("--guide {arg}: direction"))?;
            let fov: Vec<f64> = f
                .split(',')
                .map(|v| v.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .with_context(|| format!("--guide {arg}: field of view"))?;
            let (h, v) = match fov[..] {
                [a] => (a, a),
                [a, b] => (a, b),
                _ => bail!("--guide {arg}: the field of view is FOV or FOV_H,FOV_V (degrees)"),
            };
            return Ok(Self::Fixed(Roi::Cone(Cone::from_pose(
                origin,
                dir,
                glam::DVec3::Y,
                h,
                v,
            )?)));
        }
        if let Some(rest) = arg.strip_prefix("mouse:") {
            let (c, a) = rest.split_once(':').with_context(|| {
                format!("--guide mouse:X,Y:A,B needs a centre and semi-axes, got '{arg}'")
            })?;
            let center = parse_pair(c).with_context(|| format!("--guide {arg}: centre"))?;
            let axes = parse_pair(a).with_context(|| format!("--guide {arg}: semi-axes"))?;
            if !(axes.x >= 0.0 && axes.y >= 0.0) {
                bail!("--guide {arg}: semi-axes must be non-negative");
            }
            let scale =
                model.canvas_rect().size() / DVec2::new(f64::from(size[0]), f64::from(size[1]));
            return Ok(Self::Fixed(Roi::CanvasEllipse {
                center: model.image_to_canvas(center, size),
                semi_axes: axes * scale,
            }));
        }
        let args = ReplayArgs {
            file: PathBuf::from(arg),
            display: Some(display.to_path_buf()),
            config: None,
            device: None,
            realtime: false,
        };
        let mut changes = Vec::new();
        let mut first = None;
        let mut last = 0.0f64;
        replay_changes(
            &args,
            |t_event| {
                first.get_or_insert(t_event);
                last = last.max(t_event);
            },
            |c| {
                changes.push((c.t, c.roi.to_roi().ok().flatten()));
            },
        )?;
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

/// Runs `iterations` guided frames with the ROI from `source`, then reads back and filters.
/// `on_iteration` is called after each frame with the number done.
#[allow(clippy::too_many_arguments)]
pub fn render_guided(
    backend: &Backend,
    scene: &Scene,
    settings: TraceSettings,
    model: &DisplayModel,
    config: GuideConfig,
    filter: &FilterParams,
    source: &GuideSource,
    iterations: u32,
    mut on_iteration: impl FnMut(u32),
) -> anyhow::Result<GuidedResult> {
    let mut r = GuidedRenderer::new(backend, scene, settings, model, config)?;
    let t0 = std::time::Instant::now();
    let mut current: Option<Roi> = None;
    for k in 0..iterations {
        let roi = source.roi_at(k, iterations);
        if k == 0 || roi != current {
            r.set_roi(roi)?;
            current = roi;
        }
        r.run_frame(false)?;
        on_iteration(k + 1);
    }
    let acc = r.accumulation()?;
    let seconds = t0.elapsed().as_secs_f64();
    let dgi = r.dgi()?;
    let image = filtered_image(backend, filter, &acc, &dgi)?;
    Ok(GuidedResult {
        size: [settings.width, settings.height],
        iterations,
        image,
        dgi,
        counts: acc.count,
        seconds,
    })
}

/// Writes the DGI and the sample counts (EXR or PNG by extension).
pub fn write_guides(res: &GuidedResult, dgi_out: &Path, counts_out: &Path) -> anyhow::Result<()> {
    let [w, h] = res.size;
    crate::output::write_gray(dgi_out, w, h, &res.dgi, "d")?;
    let counts: Vec<f32> = res.counts.iter().map(|&c| c as f32).collect();
    crate::output::write_gray(counts_out, w, h, &counts, "samples")?;
    Ok(())
}

/// The guide arguments of `render` as a [`GuideConfig`].
pub fn guide_config(args: &RenderArgs) -> anyhow::Result<GuideConfig> {
    Ok(GuideConfig {
        metric: args.metric,
        falloff: Falloff::new(args.falloff_base, args.falloff_scale)?,
        p_min: args.p_min,
        order: args.order,
    })
}

pub fn run(
    args: &RenderArgs,
    scene: &Scene,
    settings: TraceSettings,
    backend: &Backend,
    guide: &str,
    iterations: u32,
) -> anyhow::Result<()> {
    let model = DisplayModel::load(&args.display)?;
    let source = GuideSource::parse(guide, &model, &args.display, args.size)?;
    let filter = args.filter.params()?;
    let config = guide_config(args)?;
    let bar = crate::cli::render::progress(args.quiet, u64::from(iterations), "iterations");
    let res = render_guided(
        backend,
        scene,
        settings,
        &model,
        config,
        &filter,
        &source,
        iterations,
        |k| bar.set_position(u64::from(k)),
    )?;
    bar.finish_and_clear();
    let [w, h] = res.size;
    for out in &args.out {
        crate::output::write_rgb(out, w, h, &res.image, args.exposure)?;
    }
    crate::cli::render::write_wall_tiles(args, &model, &res.image)?;
    let first = &args.out[0];
    let dgi_out = args.dgi_out.clone().unwrap_or_else(|| beside(first, "dgi"));
    let counts_out = args
        .counts_out
        .clone()
        .unwrap_or_else(|| beside(first, "counts"));
    write_guides(&res, &dgi_out, &counts_out)?;
    let samples = res.samples();
    eprintln!(
        "raygun: guided render, {iterations} iterations in {:.2} s on {}: {samples} samples ({:.2} % of full frame), {:.2} ms per megasample; wrote {}, {}",
        res.seconds,
        backend.describe(),
        100.0 * res.sample_share(),
        res.seconds * 1e3 / (samples as f64 / 1e6),
        dgi_out.display(),
        counts_out.display(),
    );
    Ok(())
}
