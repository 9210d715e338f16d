//! `raygun render … --cluster`: the render of `render` (full frame or guided) across the ranks
//! of an MPI job. Every rank validates the command and loads the scene; the start-up check
//! compares what the ranks are about to do; rank 0 follows the guide, shows the progress and
//! writes every output, bit for bit what one process writes.

use anyhow::Context;

use super::guided::GuidedPlan;
use super::{RenderArgs, settings, wall_camera};
use crate::cli::cluster::{block_owners, check, identity, model_field, or_abort, trace_backend};
use crate::cli::progress::Progress;
use crate::cli::scene::load_scene_timed;
use crate::cluster::handshake::scene_hash;
use crate::cluster::owners::{BlockOwners, TileOwners};
use crate::cluster::{Cluster, ClusterRenderer, ClusterSetup};
use crate::display::DisplayModel;
use crate::filter::denoise::DenoiseParams;
use crate::filter::{Filter, FilterParams};
use crate::gpu::Backend;
use crate::scene::Scene;
use crate::session::cluster::{ClusterRun, run_cluster};
use crate::session::render::{GuidedResult, Stopping};
use crate::trace::path::TraceSettings;
use crate::trace::wall::WallCamera;

/// What every rank has checked and loaded before the start-up check.
struct Prepared {
    plan: Option<GuidedPlan>,
    /// Where this rank traces.
    backend: Backend,
    scene: Scene,
    /// Seconds this rank's load of the scene took (one-time work).
    load_seconds: f64,
    settings: TraceSettings,
    wall: Option<WallCamera>,
    /// The display of `--tiles` for a full frame.
    tiles_model: Option<DisplayModel>,
    owners: BlockOwners,
    /// The tile map the block owners were made from (with a display).
    tile_owners: Option<TileOwners>,
    fields: Vec<(&'static str, String)>,
}

pub fn run(args: &RenderArgs) -> anyhow::Result<()> {
    let mut c = crate::cli::cluster::start(&args.cluster)?;
    let prepared = prepare(args, &c);
    let mine = match &prepared {
        Ok(p) => identity(c.ranks(), &p.fields),
        Err(e) => Err(crate::cluster::handshake::StartupFailure(
            crate::cli::error_chain(e),
        )),
    };
    check(&mut c, mine)?;
    // The check passed, so this rank prepared (its error would have failed the check).
    let p = prepared?;
    let done = work(&mut c, args, p);
    or_abort(&c, done);
    Ok(())
}

fn prepare(args: &RenderArgs, c: &Cluster) -> anyhow::Result<Prepared> {
    let config = super::RenderConfig::for_rank(args, c.is_root())?;
    // What a rank holds on its CPU (the picture's inputs and its filter on rank 0).
    super::check_memory(
        config.work(false),
        (args.denoise.denoise, crate::frame::EyeMove::Restart),
        args.size,
        &Backend::Cpu,
    )?;
    let super::RenderConfig {
        plan,
        wall,
        tiles_model,
        ..
    } = config;
    // Each rank traces on its own GPU where it has one and computes the DGI there (as one GPU
    // process does); the schedule and the owners' tiles stay on the CPUs, and rank 0 filters
    // the whole picture where it traced.
    let (backend, note) = args.backend.choose()?;
    if let Some(note) = note {
        crate::cli::say(args.quiet, note);
    }
    let (scene, load_seconds) = load_scene_timed(&args.scene, args.env.as_deref(), args.access)?;
    let settings = settings(args, &scene)?;
    let wc = wall_camera(wall.as_ref(), &settings)?;
    let model = plan
        .as_ref()
        .map(|p| &p.model)
        .or(wall.as_ref().map(|w| &w.model))
        .or(tiles_model.as_ref());
    let (owners, tile_owners, tile_map) = block_owners(&args.cluster, model, args.size, c.ranks())?;
    let mut fields = vec![
        (
            "command",
            if plan.is_some() {
                "render, guided".to_owned()
            } else {
                "render, full frame".to_owned()
            },
        ),
        ("display model", model.map_or("none".into(), model_field)),
        ("tile map", tile_map),
        (
            "scene",
            format!("{} ({:016x})", args.scene, scene_hash(&scene)),
        ),
        ("settings", format!("{settings:?}")),
        (
            "wall camera",
            format!("{:?}", wc.as_ref().map(|w| w.eye_room)),
        ),
        ("DGI mode", format!("{:?}", args.cluster.cluster_dgi)),
        ("trace backend", trace_backend(&backend)),
        ("whole picture on rank 0", format!("{}", assembles(args))),
    ];
    match &plan {
        Some(p) => {
            fields.push(("guide", format!("{:?}", p.source)));
            fields.push((
                "guide settings",
                format!("{:?} {:?} {:?}", p.config, p.filter, p.stopping),
            ));
        }
        None => fields.push(("spp", format!("{:?}", args.spp))),
    }
    Ok(Prepared {
        plan,
        backend,
        scene,
        load_seconds,
        settings,
        wall: wc,
        tiles_model,
        owners,
        tile_owners,
        fields,
    })
}

fn work(c: &mut Cluster, args: &RenderArgs, mut p: Prepared) -> anyhow::Result<()> {
    let (root, ranks) = (c.is_root(), c.ranks());
    let setup = ClusterSetup {
        settings: p.settings,
        guide: p.plan.as_ref().map(|plan| (&plan.model, plan.config)),
        wall: p.wall.clone(),
        owners: p.owners.clone(),
        dgi_mode: args.cluster.cluster_dgi,
    };
    let mut r = ClusterRenderer::new(c, &p.scene, setup)?;
    let device = format!("{ranks} rank(s), {}", trace_backend(&p.backend));
    let t0 = std::time::Instant::now();
    if let Backend::Gpu(ctx) = std::mem::replace(&mut p.backend, Backend::Cpu) {
        r.trace_on_gpu(ctx.into())?;
    }
    let upload_seconds = t0.elapsed().as_secs_f64();
    let stopping = match &p.plan {
        Some(plan) => plan.stopping.clone(),
        None => Stopping {
            iterations: Some(args.spp.unwrap_or(super::DEFAULT_SPP)),
            until: Vec::new(),
        },
    };
    if root && let Some(plan) = &p.plan {
        crate::cli::say(args.quiet, format_args!("display: {}", plan.display_note));
    }
    let mut bar = Progress::new(
        args.quiet || !root,
        if p.plan.is_some() {
            "guided render"
        } else {
            "rendering"
        },
        stopping.iterations.map(u64::from),
        if p.plan.is_some() {
            "iterations"
        } else {
            "spp"
        },
    );
    let run = run_cluster(
        &mut r,
        p.plan.as_ref().map(|plan| &plan.source),
        &stopping,
        args.cluster.cluster_fault,
        assembles(args),
        |s, progress| {
            if let Some(p) = progress {
                bar.note(&format!(
                    "ROI: median SE {:.4}, fewest samples {}",
                    p.median_se, p.min_samples
                ));
            }
            bar.set(u64::from(s.iteration) + 1);
        },
    )?;
    bar.finish();
    if root {
        let one_time = crate::cli::progress::OneTime {
            load_seconds: p.load_seconds,
            build_seconds: r.build_seconds,
            upload_seconds,
        };
        crate::cli::say(args.quiet, format_args!("rank 0: {one_time}"));
    }
    let tiles_written = write_owned_tiles(args, &p, &mut r)?;
    let summary = summary(&run, ranks);
    let Some((acc, dgi)) = run.gathered.as_ref() else {
        if root {
            tiles_only_note(&p, &r, &run, &device, &summary, args.quiet)?;
        }
        return Ok(());
    };
    let [w, h] = args.size;
    match &p.plan {
        Some(plan) => {
            // On rank 0's GPU when it traced on one (one GPU process's image), else the CPU twin.
            let filter_backend = match r.gpu() {
                Some(ctx) => Backend::Gpu(Box::new(ctx.clone())),
                None => Backend::Cpu,
            };
            let mut image = Filter::new(&filter_backend).image(&plan.filter, acc, dgi)?;
            let mut dropped = 0;
            if let Some(d) = interactive(args, &plan.filter) {
                (image, dropped) =
                    denoise_whole(&filter_backend, &r, d, acc, &image, p.wall.as_ref())?;
            }
            if let Some(wc) = &p.wall {
                wc.blank_unshown(&mut image);
            }
            let res = GuidedResult {
                size: args.size,
                iterations: run.iterations,
                image,
                dgi: dgi.clone(),
                counts: acc.count.clone(),
                sums: Vec::new(),
                seconds: run.seconds,
                build_seconds: r.build_seconds,
                upload_seconds,
                stop: run.stop,
                progress: run.progress,
                accumulated: run.accumulated,
                eye_restarts: run.eye_restarts.clone(),
                eye_reuses: Vec::new(),
                eyes_refused: run.eyes_refused,
                denoise_dropped: dropped,
            };
            super::guided::write_outputs(args, plan, &res, tiles_written, &device, &summary)
        }
        None => {
            let mut image = acc.mean_image();
            if let Some(d) = interactive(args, &off()) {
                let dropped;
                (image, dropped) =
                    denoise_whole(&Backend::Cpu, &r, d, acc, &image, p.wall.as_ref())?;
                super::say_dropped(args.quiet, dropped);
            }
            for out in &args.out {
                crate::output::write_rgb(out, w, h, &image, args.exposure)
                    .with_context(|| out.display().to_string())?;
            }
            if !tiles_written && let Some(model) = &p.tiles_model {
                super::write_wall_tiles(args, model, &image)?;
            }
            let samples: u64 = acc.count.iter().map(|&n| u64::from(n)).sum();
            let files: Vec<&std::path::Path> =
                args.out.iter().map(std::path::PathBuf::as_path).collect();
            crate::cli::say(
                args.quiet,
                format_args!(
                    "{}, {w}×{h}, {} spp in {:.2} s on {device}: {:.2} ms per megasample (BVH build {:.2} s); {summary}{}",
                    crate::messages::count(p.scene.triangles.len(), "triangle"),
                    run.iterations,
                    run.seconds,
                    run.seconds * 1e3 / (samples as f64 / 1e6),
                    r.build_seconds,
                    crate::cli::wrote(&files),
                ),
            );
            Ok(())
        }
    }
}

/// Whether rank 0 assembles the whole picture: only for an output that needs it (`--out`, the
/// DGI, the counts); with `--tiles` alone the owners' tiles are the picture.
fn assembles(args: &RenderArgs) -> bool {
    !args.out.is_empty() || args.dgi_out.is_some() || args.counts_out.is_some()
}

/// Rank 0's closing message for a render that only wrote its tiles: what ran, from the
/// samples every rank counts.
fn tiles_only_note(
    p: &Prepared,
    r: &ClusterRenderer<'_>,
    run: &ClusterRun,
    device: &str,
    summary: &str,
    quiet: bool,
) -> anyhow::Result<()> {
    let samples = r.samples();
    if p.plan.is_some() && samples == 0 {
        return Err(super::guided::nothing_sampled(run.iterations));
    }
    crate::cli::say(
        quiet,
        format_args!(
            "{} stopped ({}): {} in {:.2} s on {device}: {}, {:.2} ms per megasample; the whole picture was not assembled (no --out); {summary}",
            if p.plan.is_some() {
                "guided render"
            } else {
                "render"
            },
            run.stop,
            crate::messages::count(run.iterations as usize, "iteration"),
            run.seconds,
            crate::messages::count(samples as usize, "sample"),
            run.seconds * 1e3 / (samples.max(1) as f64 / 1e6),
        ),
    );
    Ok(())
}

/// The interactive denoiser's settings where `--denoise interactive` asks for it (the ranks
/// denoise their tiles, and rank 0 the whole picture, with the filter's variance threshold as
/// one process does).
fn interactive(args: &RenderArgs, filter: &FilterParams) -> Option<DenoiseParams> {
    (args.denoise.denoise == crate::filter::DenoiseKind::Interactive).then(|| DenoiseParams {
        variance_threshold: filter.variance_threshold,
        ..DenoiseParams::default()
    })
}

/// Rank 0's whole picture denoised as one process denoises it on `backend`, with the features
/// of the rank's own copy of the scene on the CPU.
fn denoise_whole(
    backend: &Backend,
    r: &ClusterRenderer<'_>,
    params: DenoiseParams,
    acc: &crate::trace::accum::Accumulation,
    filled: &[glam::Vec3],
    wall: Option<&crate::trace::wall::WallCamera>,
) -> anyhow::Result<(Vec<glam::Vec3>, u64)> {
    let f = crate::trace::features::features_cpu(&r.packed, &r.settings, wall);
    let features = crate::filter::denoise::Features {
        width: r.settings.width,
        height: r.settings.height,
        albedo: f.albedo,
        normal_depth: f.normal_depth,
    };
    Ok(crate::frame::denoise_picture(
        backend,
        crate::filter::Denoiser::Interactive(params),
        acc,
        &features,
        filled,
        wall,
    )?)
}

/// `--tiles DIR`: every rank filters and writes the display tiles it owns
/// ([`ClusterRenderer::tile_pictures`]), the files one process writes; rank 0 says how many
/// each rank wrote. `false` (nothing written) without `--tiles` or a tile map.
fn write_owned_tiles(
    args: &RenderArgs,
    p: &Prepared,
    r: &mut ClusterRenderer<'_>,
) -> anyhow::Result<bool> {
    let (Some(dir), Some(tiles)) = (&args.tiles, &p.tile_owners) else {
        return Ok(false);
    };
    // A guided render that sampled nothing writes nothing: rank 0 says why (every rank has the
    // counts, so every rank decides alike).
    if p.plan.is_some() && r.samples() == 0 {
        return Ok(false);
    }
    // A full frame's `--tiles` display (the wall camera's, or --display).
    let (model, params) = match (&p.plan, &p.tiles_model) {
        (Some(plan), _) => (&plan.model, plan.filter),
        (None, Some(m)) => (m, off()),
        (None, None) => return Ok(false),
    };
    let format = super::tiles_format(args)?;
    let denoise = interactive(args, &params);
    let pictures = r.tile_pictures(model, tiles, &params, denoise.as_ref())?;
    for t in &pictures {
        crate::output::tiles::write_tile(dir, model, t.tile, &t.pixels, format, args.exposure)
            .with_context(|| format!("--tiles {}", dir.display()))?;
    }
    let written = (pictures.len() as u32).to_le_bytes().to_vec();
    if let Some(all) = r.cluster_mut().gather("the tiles written", written)? {
        let per_rank: Vec<u32> = all
            .iter()
            .map(|b| {
                b.get(..4)
                    .map_or(0, |b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            })
            .collect();
        let list: Vec<String> = per_rank
            .iter()
            .enumerate()
            .map(|(rank, n)| format!("rank {rank}: {n}"))
            .collect();
        crate::cli::say(
            args.quiet,
            format_args!(
                "the owners wrote {} to {} ({})",
                crate::messages::count(per_rank.iter().sum::<u32>() as usize, "tile image"),
                dir.display(),
                list.join(", ")
            ),
        );
    }
    Ok(true)
}

/// A full frame's tiles: the mean image.
fn off() -> crate::filter::FilterParams {
    crate::filter::FilterParams {
        kind: crate::filter::FilterKind::Off,
        ..Default::default()
    }
}

/// Rank 0's share of the work and of the traffic, per iteration.
fn summary(run: &ClusterRun, ranks: usize) -> String {
    let n = run.frames.len().max(1) as f64;
    let traced: u64 = run.frames.iter().map(|f| f.pixels_traced).sum();
    let all: u64 = run.frames.iter().map(|f| f.pixels).sum();
    let sent: u64 = run.frames.iter().map(|f| f.traffic.bytes_sent).sum();
    let got: u64 = run.frames.iter().map(|f| f.traffic.bytes_received).sum();
    format!(
        "rank 0 of {ranks} traced {:.1} % of the samples and sent {:.0} / received {:.0} bytes per iteration",
        100.0 * traced as f64 / all.max(1) as f64,
        sent as f64 / n,
        got as f64 / n
    )
}
