//! `raygun view --scene FILE --display MODEL [--dtrack PORT | --osc PORT | --replay FILE]
//! [--camera wall --eye X,Y,Z] [--head KIND:N --eye-offset X,Y,Z --eye-threshold M]`.

use std::path::PathBuf;

use anyhow::Context;

use crate::cluster::{ClusterRenderer, ClusterSetup};
use crate::display::DisplayModel;
use crate::gpu::Backend;
use crate::interaction::CursorSmoother;
use crate::session::live::LiveTracking;
use crate::session::replay::ReplayOptions;
use crate::session::timeline::Timeline;
use crate::session::viewer_setup::{LiveInput, ViewerSetup};
use crate::trace::camera::RenderCamera;
use crate::trace::path::{DEFAULT_MAX_DEPTH, TraceSettings};
use crate::tracking::event::DeviceId;
use crate::tracking::ingest::Protocol;
use crate::tracking::vrpn::VrpnAddress;
#[cfg(feature = "viewer")]
use crate::viewer::app::ViewerApp;
use crate::viewer::core::ViewerCore;
use crate::viewer::state::{RoiSource, ViewerState};

/// The device the viewer's window draws with ([`ViewArgs::window_gpu`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum WindowGpu {
    /// The GPU raygun renders on.
    Shared,
    /// A device of the window's own.
    Own,
}

#[derive(Clone, Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("tracking").args(["dtrack", "osc", "vrpn", "replay"])))]
pub struct ViewArgs {
    /// Scene: a .gltf/.glb file or builtin:NAME.
    #[arg(
        long,
        value_name = "FILE|builtin:NAME",
        default_value = "builtin:cornell-light"
    )]
    pub scene: String,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Display model whose canvas the image covers: a file, or a built-in model (hornet,
    /// desktop-27in-4k, projection-4m-4k).
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Image size in pixels, W,H, or `native`: the display canvas's own pixel size.
    /// The renderer's: the window scales it to fit.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H|native", value_parser = crate::cli::args::parse_size_or_native, default_value = "992,400")]
    pub size: [u32; 2],
    /// Environment light: linear radiance R,G,B or an equirectangular .hdr/.exr image.
    #[arg(long, value_name = "R,G,B|FILE")]
    pub env: Option<String>,
    /// Camera by name, or `wall`: the wall camera — each pixel's primary ray from --eye
    /// through its point on --display (the eye follows a tracked head, or the mouse: drag to
    /// orbit, shift- or middle-drag to pan, the wheel to dolly).
    #[arg(long, value_name = "NAME|wall")]
    pub camera: Option<String>,
    #[command(flatten)]
    pub wall: crate::cli::wall::WallArgs,
    /// The tracked head that moves the wall camera's eye (live input, or a replay's; default:
    /// the replay's header's head).
    #[command(flatten)]
    pub head: crate::cli::head::HeadArgs,
    #[command(flatten)]
    pub look: crate::cli::args::LookArgs,
    /// Maximum path vertices (also a panel slider).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_DEPTH)]
    pub max_depth: u32,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// The device the window draws with where raygun renders on a GPU: `shared`, the GPU raygun
    /// renders on (the picture is written into the window's texture there and never leaves
    /// it), or `own`, a device the window picks for its display (each picture then comes back
    /// through the host: for a GPU that drives no display).
    #[arg(long, value_enum, default_value_t = WindowGpu::Shared)]
    pub window_gpu: WindowGpu,
    /// Live DTrack ASCII on this loopback UDP port.
    #[arg(long, value_name = "PORT")]
    pub dtrack: Option<u16>,
    /// Live OSC on this loopback UDP port.
    #[arg(long, value_name = "PORT")]
    pub osc: Option<u16>,
    /// Live VRPN from a server (`vrpn_Tracker_DTrack`, Vicon, …): `DEVICE@HOST[:PORT]` (VRPN's
    /// classic UDP mode) or `DEVICE@tcp://HOST[:PORT]`; reconnects when the server goes away.
    #[arg(long, value_name = "DEVICE@HOST[:PORT]")]
    pub vrpn: Option<VrpnAddress>,
    /// Allow a VRPN server that is not on this machine.
    #[arg(long, requires = "vrpn")]
    pub allow_network: bool,
    /// A replay to play, pause and scrub.
    #[arg(long, value_name = "FILE")]
    pub replay: Option<PathBuf>,
    /// Tracked device to follow (live input); default: the --config's (flystick:0).
    #[arg(long, value_name = "KIND:N")]
    pub device: Option<DeviceId>,
    /// Interaction mapping JSON (device axes, buttons, stick, the cursor's smoothing, a
    /// calibration file) for live input and replays; docs/tracking.md lists its fields.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Tracker→room calibration for live input (JSON, as `raygun calibrate` writes it);
    /// default: the mapping's, else identity. A replay uses the one it was recorded with.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Lowest sampling probability outside the ROI, 0 to 1 (also a panel slider; 0: the
    /// paper's).
    #[arg(
        long,
        value_name = "P",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub p_min: f32,
    /// The ROI's target standard error (median over its pixels of the mean luminance's): the
    /// panel shows the time to it (also a panel setting).
    #[arg(long, value_name = "SE")]
    pub target_se: Option<f64>,
    /// A mouse ROI from the start: centre in image pixels (the click position's equivalent).
    #[arg(long, value_name = "X,Y", value_parser = crate::cli::args::parse_pair)]
    pub roi_at: Option<glam::DVec2>,
    /// Radius of the mouse ROI, canvas pixels (also a panel slider).
    #[arg(long, value_name = "PX", default_value_t = 600.0)]
    pub roi_radius: f64,
    /// Initial filter settings (also in the panel).
    #[command(flatten)]
    pub filter: crate::cli::filter::FilterArgs,
    /// Denoise the shown picture (also in the panel): interactive (raygun's own edge-avoiding
    /// denoiser, steered by each pixel's albedo, normal and depth), oidn (the same while the ROI
    /// or the eye moves, and Intel Open Image Denoise's picture once both have been still for a
    /// second; install it with `bash tools/oidn.sh install`, or set OIDN_DIR) or off (the
    /// filter's picture). With --cluster: off or interactive (rank 0 denoises its picture, the
    /// owners their tiles).
    #[arg(long, value_enum, default_value_t = crate::filter::DenoiseKind::Interactive)]
    pub denoise: crate::filter::DenoiseKind,
    /// Where the save button writes (image EXR/PNG, DGI, counts, the picture as shown).
    #[arg(long, value_name = "DIR", default_value = "raygun-view")]
    pub save_dir: PathBuf,
    /// Save `screenshot.*` to --save-dir after N iterations and close (smoke tests).
    #[arg(long, value_name = "N")]
    pub screenshot_after: Option<u32>,
    /// With --cluster (under `mpirun -np N`): rank 0 opens the window and follows the mouse or
    /// the tracking; every rank traces a share of each frame (DESIGN.md §12).
    #[command(flatten)]
    pub cluster: crate::cli::cluster::ClusterArgs,
    /// With --cluster: every rank but 0 opens a window showing the display tiles it owns, laid
    /// out as they hang and filtered where they are owned (on a wall: each PC's screens; give
    /// the console, rank 0, no tiles with --tile-owners). With --screenshot-after each saves
    /// the tiles it showed as `rankN-tiles/<tile id>.png` in its --save-dir when rank 0 closes.
    #[arg(long, requires = "cluster")]
    pub show_tiles: bool,
}

/// What `view` has loaded and worked out before the renderer exists.
struct Setup {
    backend: Backend,
    scene: crate::scene::Scene,
    model: DisplayModel,
    base: TraceSettings,
    wall: Option<crate::trace::wall::WallCamera>,
    state: ViewerState,
    timeline: Option<Timeline>,
    live: Option<LiveTracking>,
    /// OIDN, opened for `--denoise oidn`.
    oidn: Option<crate::filter::oidn::Device>,
    /// Seconds the scene's load took (one-time work).
    load_seconds: f64,
}

/// Whether a window can be opened: an X11 or Wayland display is named in the environment.
#[must_use]
pub fn has_display() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

pub fn run(args: &ViewArgs) -> anyhow::Result<()> {
    // Said before loading anything.
    if !cfg!(feature = "viewer") {
        anyhow::bail!(NO_WINDOW);
    }
    let mut args = args.clone();
    args.size = crate::cli::args::resolve_size(args.size, &args.display)?;
    let args = &args;
    if args.cluster.cluster {
        if args.denoise == crate::filter::DenoiseKind::Oidn {
            anyhow::bail!(
                "--denoise oidn denoises one process's picture: across ranks the viewer denoises with --denoise interactive"
            );
        }
        args.head.cluster_on_eye_move()?;
        return run_cluster(args);
    }
    if !has_display() {
        anyhow::bail!(NO_DISPLAY);
    }
    if args.show_tiles {
        anyhow::bail!("--show-tiles needs --cluster: the owners' windows are ranks' windows");
    }
    let s = setup(args, true)?;
    let mut core = ViewerCore::with_wall(&s.backend, &s.scene, &s.model, s.base, s.state, s.wall)?;
    if let Some((build_seconds, upload_seconds)) = core.set_up_seconds() {
        let one_time = crate::cli::progress::OneTime {
            load_seconds: s.load_seconds,
            build_seconds,
            upload_seconds,
        };
        eprintln!("raygun view: {one_time}");
    }
    if let Some(device) = s.oidn {
        core.set_oidn(device);
    }
    open_window(core, s.timeline, s.live, args)
}

/// `view --cluster`: every rank loads what the viewer needs; the start-up check compares them;
/// rank 0 opens the window over a [`ClusterView`] and the other ranks follow its steps until it
/// closes.
fn run_cluster(args: &ViewArgs) -> anyhow::Result<()> {
    use crate::cli::cluster::{block_owners, check, identity, model_field};
    let mut c = crate::cli::cluster::start(&args.cluster)?;
    let (root, rank) = (c.is_root(), c.rank());
    let prepared = (|| {
        if (root || args.show_tiles) && !has_display() {
            anyhow::bail!(NO_DISPLAY);
        }
        let s = setup(args, root)?;
        let (owners, tile_owners, tile_map) =
            block_owners(&args.cluster, Some(&s.model), args.size, c.ranks())?;
        let config = s.state.guide_config()?;
        let fields = vec![
            ("command", "view".to_owned()),
            ("display model", model_field(&s.model)),
            ("tile map", tile_map),
            (
                "scene",
                format!(
                    "{} ({:016x})",
                    args.scene,
                    crate::cluster::handshake::scene_hash(&s.scene)
                ),
            ),
            ("settings", format!("{:?}", s.base)),
            (
                "wall camera",
                format!("{:?}", s.wall.as_ref().map(|w| w.eye_room)),
            ),
            ("guide settings", format!("{config:?}")),
            ("DGI mode", format!("{:?}", args.cluster.cluster_dgi)),
            (
                "trace backend",
                crate::cli::cluster::trace_backend(&s.backend),
            ),
            ("owners show their tiles", format!("{}", args.show_tiles)),
        ];
        Ok((s, owners, tile_owners, config, fields))
    })();
    let mine = match &prepared {
        Ok((.., fields)) => identity(c.ranks(), fields),
        Err(e) => Err(crate::cluster::handshake::StartupFailure(
            crate::cli::error_chain(e),
        )),
    };
    check(&mut c, mine)?;
    let (s, owners, tile_owners, config, _) = prepared?;
    // The ranks trace on their GPUs where --backend says so; rank 0 filters its window's
    // picture where it traces (its GPU: the one-process GPU viewer's filter).
    let (gpu, filter_backend) = match s.backend {
        Backend::Gpu(ctx) => {
            let shared = Backend::Gpu(Box::new((*ctx).clone()));
            (Some(std::sync::Arc::from(ctx)), shared)
        }
        Backend::Cpu => (None, Backend::Cpu),
    };
    let done = (|| -> anyhow::Result<()> {
        let setup = ClusterSetup {
            settings: s.base,
            guide: Some((&s.model, config)),
            wall: s.wall,
            owners,
            dgi_mode: args.cluster.cluster_dgi,
        };
        let mut r = ClusterRenderer::new(&mut c, &s.scene, setup)?;
        let t0 = std::time::Instant::now();
        if let Some(ctx) = gpu {
            r.trace_on_gpu(ctx)?;
        }
        let one_time = crate::cli::progress::OneTime {
            load_seconds: s.load_seconds,
            build_seconds: r.build_seconds,
            upload_seconds: t0.elapsed().as_secs_f64(),
        };
        let view = crate::session::cluster::ClusterView::new(r, &s.model)?;
        let view = match tile_owners {
            Some(t) if args.show_tiles => view.with_tiles(t),
            _ => view,
        }
        .with_fault(args.cluster.cluster_fault);
        if root {
            eprintln!("raygun view: {}", view.describe());
            eprintln!("raygun view: rank 0: {one_time}");
            let core = ViewerCore::over_cluster(
                &filter_backend,
                &s.scene,
                &s.model,
                s.base,
                s.state,
                view,
            )?;
            open_window(core, s.timeline, s.live, args)
        } else if args.show_tiles {
            open_tiles_window(view, args)
        } else {
            let mut view = view;
            view.follow()?;
            Ok(())
        }
    })();
    match done {
        Err(e) if !root => {
            // This rank's link closes (its last sends waited for); then, since rank 0 waits on
            // this rank, the job ends now (mpirun ends every rank) rather than at rank 0's
            // deadline.
            drop(c);
            eprintln!(
                "raygun: error: rank {rank}: {}",
                crate::cli::error_chain(&e)
            );
            std::process::exit(1);
        }
        done => done,
    }
}

/// Everything `view` loads, checks and starts before the renderer exists; `root`: this process
/// shows the window (it alone listens for tracking). The display, the mapping, the replay, the
/// wall camera and the live source are built by the session's [`ViewerSetup`] builder in the
/// order their errors come; the backend, the memory check and the scene between them.
fn setup(args: &ViewArgs, root: bool) -> anyhow::Result<Setup> {
    check_numbers(args)?;
    if root || (args.show_tiles && args.screenshot_after.is_some()) {
        // Only the windows save.
        crate::output::check_folder(&args.save_dir).context("--save-dir")?;
    }
    let filter = args.filter.params()?;
    let head = args.head.head()?;
    let (model, _) = DisplayModel::open(&args.display)?;
    let builder = ViewerSetup::builder(model, args.size).interaction(
        args.config.as_deref(),
        args.device,
        args.calibration.as_deref(),
    )?;
    let backend = args.backend.select()?;
    // (`--cluster --denoise oidn` was refused before: the interactive denoiser across ranks.)
    let denoise = args.denoise;
    crate::cli::render::check_memory(
        crate::memory::Work::Render {
            gpu: backend.is_gpu(),
            filter: filter.kind,
        },
        (denoise, args.head.on_eye_move()),
        args.size,
        &backend,
    )?;
    let oidn = crate::cli::filter::DenoiseArgs { denoise }.device(&backend)?;
    let (scene, load_seconds) =
        crate::cli::scene::load_scene_timed(&args.scene, args.env.as_deref(), args.access)?;
    let [w, h] = args.size;
    let look = args.look.viewpoint();
    let name = args
        .camera
        .as_deref()
        .filter(|c| *c != crate::cli::wall::WALL_CAMERA);
    let camera = RenderCamera::choose_or_look_at(&scene, name, look.as_ref(), w, h)
        .with_context(|| format!("scene {}", args.scene))?;
    if root {
        eprintln!("raygun view: rendering on {}", backend.describe());
    }
    let replay = args.replay.as_ref().map(|file| ReplayOptions {
        display: Some(args.display.clone()),
        config: args.config.clone(),
        device: args.device,
        calibration: args.calibration.clone(),
        head: args.head.overrides(),
        ..ReplayOptions::of(file.clone())
    });
    let builder = builder.replay(replay.as_ref())?;
    // The wall camera: --eye, else the tracked head's first eye in the replay.
    let spec = crate::cli::wall::wall_spec_or_eye(
        args.camera.as_deref(),
        &args.wall,
        Some(builder.model()),
        builder.first_eye(),
    )?;
    let builder = builder
        .wall(spec.as_ref(), &camera)
        .context("--camera wall")?;
    // Only the window's process listens: the other ranks follow its steps.
    let input = if root { live_input(args) } else { None };
    let builder = builder.live(input.clone())?;
    let base = TraceSettings {
        width: w,
        height: h,
        seed: 1,
        max_depth: args.max_depth,
        camera,
    };
    let v = builder.build(scene, base);
    match (&input, &v.live) {
        (Some(LiveInput::Vrpn { address, .. }), Some(_)) => {
            eprintln!("raygun view: following VRPN {address}");
        }
        (Some(LiveInput::Udp { protocol, .. }), Some(l)) => {
            eprintln!(
                "raygun view: listening on 127.0.0.1:{} for {protocol}",
                l.port
            );
        }
        _ => {}
    }
    if let (Some(l), Some(h)) = (&v.live, head) {
        l.follow_head(h);
        eprintln!("raygun view: the wall camera's eye follows {}", h.device);
    }
    let source = if v.timeline.is_some() {
        RoiSource::Replay
    } else if v.live.is_some() {
        RoiSource::Live
    } else {
        RoiSource::Mouse
    };
    let mut state = ViewerState::new(source, args.max_depth);
    state.filter = filter;
    state.denoise = denoise;
    state.mouse_radius_px = args.roi_radius;
    state.p_min = args.p_min;
    state.target_se = args.target_se;
    state.cursor = CursorSmoother::new(v.interaction.cursor.clone());
    state.eye_threshold_m = args
        .head
        .eye_threshold
        .or(head.map(|h| h.eye_threshold_m))
        .unwrap_or_else(|| args.head.threshold_m());
    state.on_eye_move = args.head.on_eye_move();
    if let Some(c) = args.roi_at {
        state.click(&v.model, c, args.size);
    }
    Ok(Setup {
        backend,
        scene: v.scene,
        model: v.model,
        base: v.base,
        wall: v.wall,
        state,
        timeline: v.timeline,
        live: v.live,
        oidn,
        load_seconds,
    })
}

/// An error naming the first of `--roi-radius`, `--p-min` and `--target-se` out of its range.
fn check_numbers(args: &ViewArgs) -> anyhow::Result<()> {
    if !(args.roi_radius.is_finite() && args.roi_radius > 0.0) {
        anyhow::bail!("--roi-radius must be a positive number of canvas pixels");
    }
    if !(0.0..=1.0).contains(&args.p_min) {
        anyhow::bail!(
            "--p-min must be a probability from 0 to 1, not {}",
            crate::messages::number(f64::from(args.p_min))
        );
    }
    if let Some(t) = args.target_se
        && !(t.is_finite() && t > 0.0)
    {
        anyhow::bail!("--target-se must be a positive number, not {t}");
    }
    Ok(())
}

/// The live tracking source `--vrpn`, `--dtrack` or `--osc` names.
fn live_input(args: &ViewArgs) -> Option<LiveInput> {
    match (&args.vrpn, args.dtrack, args.osc) {
        (Some(address), _, _) => Some(LiveInput::Vrpn {
            address: address.clone(),
            allow_network: args.allow_network,
        }),
        (None, Some(port), _) => Some(LiveInput::Udp {
            port,
            protocol: Protocol::Dtrack,
        }),
        (None, None, Some(port)) => Some(LiveInput::Udp {
            port,
            protocol: Protocol::Osc,
        }),
        (None, None, None) => None,
    }
}

/// What `raygun view` says where no window can be opened.
const NO_DISPLAY: &str = "no display to open the viewer's window on (DISPLAY and WAYLAND_DISPLAY are unset): `raygun render … --guide REPLAY|pose:…|mouse:…` renders the same guided image to files, and `raygun demo --headless` runs the demo without a window";

/// What `raygun view` says when it was built without its window.
const NO_WINDOW: &str = "this raygun was built without its window (the `viewer` feature, on by default): rebuild it with default features to use `raygun view`";

/// Shows the guided render in an egui window until it is closed.
#[cfg(feature = "viewer")]
fn open_window(
    core: ViewerCore,
    timeline: Option<Timeline>,
    live: Option<LiveTracking>,
    args: &ViewArgs,
) -> anyhow::Result<()> {
    let mut app = ViewerApp::new(
        core,
        timeline,
        live,
        args.save_dir.clone(),
        args.screenshot_after,
    );
    let failure = std::sync::Arc::clone(&app.failure);
    let mut options = eframe::NativeOptions {
        viewport: eframe::egui::ViewportBuilder::default()
            .with_title("raygun view")
            .with_inner_size([1400.0, 700.0]),
        ..Default::default()
    };
    // The window draws with the renderer's device: its pictures need not leave the GPU.
    let shared = app
        .core
        .gpu()
        .filter(|_| args.window_gpu == WindowGpu::Shared);
    app.shares_gpu = shared.is_some();
    if let Some(ctx) = shared {
        options.wgpu_options.wgpu_setup =
            eframe::egui_wgpu::WgpuSetup::Existing(eframe::egui_wgpu::WgpuSetupExisting {
                instance: ctx.instance.clone(),
                adapter: ctx.adapter.clone(),
                device: ctx.device.clone(),
                queue: ctx.queue.clone(),
            });
    }
    let hint = if shared.is_some() {
        "; `--window-gpu own` lets the window pick a device for its display"
    } else {
        ""
    };
    eframe::run_native(
        "raygun view",
        options,
        Box::new(move |_cc| Ok(Box::new(app))),
    )
    .map_err(|e| {
        anyhow::anyhow!(
            "the viewer's window could not open on display {}: {} (`raygun render … --guide …` and `raygun demo --headless` need no window{hint})",
            std::env::var("DISPLAY")
                .or_else(|_| std::env::var("WAYLAND_DISPLAY"))
                .unwrap_or_default(),
            crate::messages::without_source_paths(&e.to_string())
        )
    })?;
    match failure.lock().ok().and_then(|mut f| f.take()) {
        Some(message) => anyhow::bail!(message),
        None => Ok(()),
    }
}

/// An owner's window of its own tiles (`--show-tiles`) until rank 0's window closes.
#[cfg(feature = "viewer")]
fn open_tiles_window(
    view: crate::session::cluster::ClusterView<'_>,
    args: &ViewArgs,
) -> anyhow::Result<()> {
    let rank = view.rank();
    let app = crate::viewer::tiles::TilesApp::new(
        view,
        args.screenshot_after.map(|_| args.save_dir.clone()),
    );
    let failure = std::sync::Arc::clone(&app.failure);
    let options = eframe::NativeOptions {
        viewport: eframe::egui::ViewportBuilder::default()
            .with_title(format!("raygun view: rank {rank}'s tiles"))
            .with_inner_size([960.0, 540.0]),
        ..Default::default()
    };
    eframe::run_native(
        "raygun view tiles",
        options,
        Box::new(move |_cc| Ok(Box::new(app))),
    )
    .map_err(|e| {
        anyhow::anyhow!(
            "rank {rank}'s tiles window could not open: {}",
            crate::messages::without_source_paths(&e.to_string())
        )
    })?;
    match failure.lock().ok().and_then(|mut f| f.take()) {
        Some(message) => anyhow::bail!(message),
        None => Ok(()),
    }
}

#[cfg(not(feature = "viewer"))]
fn open_tiles_window(
    _: crate::session::cluster::ClusterView<'_>,
    _: &ViewArgs,
) -> anyhow::Result<()> {
    anyhow::bail!(NO_WINDOW)
}

#[cfg(not(feature = "viewer"))]
fn open_window(
    _: ViewerCore,
    _: Option<Timeline>,
    _: Option<LiveTracking>,
    _: &ViewArgs,
) -> anyhow::Result<()> {
    anyhow::bail!(NO_WINDOW)
}
