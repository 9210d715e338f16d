//! `raygun replay`, `raygun record` and `raygun synth-replays`: clap arguments and run
//! functions. Arguments are turned into a validated configuration before any work starts.
//!
//! `raygun replay FILE` prints one JSON line per ROI change (and per failed shot, with
//! `"kind":"miss"` or `"untracked"`):
//!
//! ```text
//! {"t":1.916667,"kind":"shoot","centre_canvas_px":[5870.74,3779.658],"centre_image_px":[1667.527,1496.188],"fov_deg":[30.0,30.0],"tile":"c3r3","filter":true}
//! ```
//!
//! `t` is seconds since the session's first event; pixels are rounded to 1e-3, degrees to
//! 1e-4, so the output is deterministic and can be compared with a golden file.

use std::io::{self, Write};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::{ArgGroup, Args};

use crate::display::DisplayModel;
use crate::interaction::{Interaction, InteractionConfig, RoiChange};
use crate::tracking::calibration::Calibration;
use crate::tracking::event::DeviceId;
use crate::tracking::ingest::{Ingest, Pipeline, Protocol};
use crate::tracking::problems::ProblemLog;
use crate::tracking::replay::{
    LineFile, Playback, ReplayHeader, ReplayPayload, ReplayReader, ReplayWriter, play,
};
use crate::tracking::udp::{ListenerConfig, UdpSource, record};

/// `raygun replay`.
#[derive(Args, Debug, Clone)]
pub struct ReplayArgs {
    /// Replay file (JSON Lines).
    pub file: PathBuf,
    /// Display model to shoot at: a file, or a built-in model (hornet, desktop-27in-4k,
    /// projection-4m-4k); default: the one the recording's header names.
    #[arg(long, value_name = "MODEL")]
    pub display: Option<String>,
    /// Interaction mapping (JSON); default: the documented defaults.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Device to follow, e.g. `flystick:0`; default: the header's, else the config's.
    #[arg(long, value_name = "KIND:N")]
    pub device: Option<DeviceId>,
    /// Tracker→room calibration (JSON, as `raygun calibrate` writes it); default: the
    /// mapping's `calibration`, else the one the recording was made with.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Play at recorded speed instead of as fast as possible.
    #[arg(long)]
    pub realtime: bool,
}

impl ReplayArgs {
    /// A replay of `file` with everything else taken from its header.
    #[must_use]
    pub fn of(file: PathBuf) -> Self {
        Self {
            file,
            display: None,
            config: None,
            device: None,
            calibration: None,
            realtime: false,
        }
    }
}

/// `raygun record`.
#[derive(Args, Debug, Clone)]
#[command(group(ArgGroup::new("source").required(true).args(["dtrack", "osc", "vrpn"])))]
pub struct RecordArgs {
    /// Listen for DTrack ASCII on this UDP port (0: any free port, said at start).
    #[arg(long, value_name = "PORT")]
    pub dtrack: Option<u16>,
    /// Listen for OSC on this UDP port (0: any free port, said at start).
    #[arg(long, value_name = "PORT")]
    pub osc: Option<u16>,
    /// Record a VRPN server's device (DEVICE@HOST[:PORT], or DEVICE@tcp://HOST[:PORT]): the raw
    /// messages, replayed through the same decoder; the recording ends at --seconds or when the
    /// server closes.
    #[arg(long, value_name = "DEVICE@HOST[:PORT]")]
    pub vrpn: Option<crate::tracking::vrpn::VrpnAddress>,
    /// Replay file to write.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// The display the session is for (a file or a built-in model), stored in the recording so
    /// that `replay` and `render --guide` use it.
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Tracker→room calibration (JSON), stored in the recording; default: identity (DTrack
    /// millimetres, OSC metres).
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Address to bind; anything but loopback needs `--allow-network`.
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    pub bind: IpAddr,
    /// Allow binding a non-loopback address.
    #[arg(long)]
    pub allow_network: bool,
    /// Accept datagrams only from these sources (repeatable); default: any.
    #[arg(long = "allow-from")]
    pub allow_from: Vec<IpAddr>,
    /// Stop after this many seconds; default: run until killed.
    #[arg(long)]
    pub seconds: Option<f64>,
}

/// `raygun synth-replays`.
#[derive(Args, Debug, Clone)]
pub struct SynthArgs {
    /// Directory to write into.
    #[arg(long, default_value = "tracking-replays")]
    pub out: PathBuf,
}

/// The display model a replay names: a file as given, else one next to the replay's folder
/// (where the shipped replays' models live), else a built-in model of that name.
fn resolve_display(named: &str, replay: &Path) -> anyhow::Result<(DisplayModel, String)> {
    let beside = replay
        .parent()
        .and_then(Path::parent)
        .map(|p| p.join(named))
        .filter(|p| !Path::new(named).exists() && p.exists());
    let spec = beside.map_or_else(|| named.to_owned(), |p| p.display().to_string());
    let (model, origin) = DisplayModel::open(&spec)?;
    Ok((model, origin.to_string()))
}

/// Everything a replay run needs, validated.
pub struct ReplayPlan {
    pub header: ReplayHeader,
    pub surface: DisplayModel,
    /// Which display model is used, for messages ("display-models/hornet.json", "the built-in
    /// hornet model", "the model stored in the recording").
    pub display_origin: String,
    pub interaction: InteractionConfig,
    /// The calibration given on the command line or in the mapping (the header's own applies
    /// otherwise).
    pub calibration: Option<Calibration>,
    /// The decoders the header asks for, with the calibration applied, before any input.
    pub ingest: Ingest,
    pub playback: Playback,
}

impl ReplayPlan {
    /// Reads the header and resolves display, device, calibration and mapping.
    pub fn new(
        args: &ReplayArgs,
    ) -> anyhow::Result<(Self, ReplayReader<io::BufReader<std::fs::File>>)> {
        let reader = ReplayReader::open(&args.file)?;
        let header = reader.header().clone();
        let mut interaction = match &args.config {
            Some(p) => InteractionConfig::load(p)?,
            None => InteractionConfig::default(),
        };
        if let Some(d) = args.device.or(header.device) {
            interaction.device = d;
        }
        let calibration = match args
            .calibration
            .as_ref()
            .or(interaction.calibration.as_ref())
        {
            Some(p) => Some(Calibration::load(p)?),
            None => None,
        };
        if let Some(c) = calibration.as_ref().or(header.calibration.as_ref()) {
            c.validate(&args.file)
                .with_context(|| format!("{}: calibration", args.file.display()))?;
            interaction.use_calibrated_axes(c);
        }
        interaction.validate()?;
        let (surface, display_origin) =
            match (&args.display, &header.display_model, &header.display) {
                (Some(spec), _, _) => {
                    let (m, origin) = DisplayModel::open(spec)?;
                    (m, origin.to_string())
                }
                (None, Some(m), _) => (m.clone(), "the model stored in the recording".to_owned()),
                (None, None, Some(named)) => resolve_display(named, &args.file)?,
                (None, None, None) => bail!(
                    "{}: the recording names no display: give --display MODEL",
                    args.file.display()
                ),
            };
        // Every decoder the header asks for must be usable.
        let ingest = header
            .ingest(calibration.as_ref())
            .with_context(|| args.file.display().to_string())?;
        let playback = if args.realtime {
            Playback::RealTime
        } else {
            Playback::AsFastAsPossible
        };
        Ok((
            Self {
                header,
                surface,
                display_origin,
                interaction,
                calibration,
                ingest,
                playback,
            },
            reader,
        ))
    }

    /// A fresh pipeline configured from the header, the calibration and the mapping.
    #[must_use]
    pub fn pipeline(&self) -> Pipeline {
        Pipeline::new(
            self.ingest.clone(),
            Interaction::new(self.interaction.clone()),
        )
    }
}

/// Writes ROI changes as JSON lines, times relative to the first event seen.
pub struct ChangePrinter<W: Write> {
    out: W,
    t_origin: Option<f64>,
}

impl<W: Write> ChangePrinter<W> {
    #[must_use]
    pub fn new(out: W) -> Self {
        Self {
            out,
            t_origin: None,
        }
    }

    /// Sets the time origin if unset (call with each event's time).
    pub fn saw_event(&mut self, t: f64) {
        self.t_origin.get_or_insert(t);
    }

    pub fn print(&mut self, c: &RoiChange) -> io::Result<()> {
        let origin = *self.t_origin.get_or_insert(c.t);
        serde_json::to_writer(&mut self.out, &c.report(origin))?;
        self.out.write_all(b"\n")
    }

    /// The underlying writer.
    #[must_use]
    pub fn into_inner(self) -> W {
        self.out
    }
}

/// Runs a replay, printing changes to `out`; returns the problem counts (reader and decoders).
pub fn run_replay(args: &ReplayArgs, out: impl Write) -> anyhow::Result<ProblemLog> {
    let mut printer = ChangePrinter::new(out);
    let mut io_result = Ok(());
    let printer_ref = std::cell::RefCell::new(&mut printer);
    let problems = replay_changes(
        args,
        |t| printer_ref.borrow_mut().saw_event(t),
        |c| {
            if io_result.is_ok() {
                io_result = printer_ref.borrow_mut().print(c);
            }
        },
    )?;
    io_result.context("writing ROI changes")?;
    Ok(problems)
}

/// Plays a replay through the live parsers and the interaction state machine: `saw_event` gets
/// the time of each event of the configured device, `on_change` each ROI change. Returns the
/// problem counts (reader and decoders).
pub fn replay_changes(
    args: &ReplayArgs,
    saw_event: impl FnMut(f64),
    on_change: impl FnMut(&RoiChange),
) -> anyhow::Result<ProblemLog> {
    let (plan, reader) = ReplayPlan::new(args)?;
    Ok(play_plan(&plan, reader, saw_event, on_change))
}

/// [`replay_changes`] for a plan made already (its file is read again from the start).
pub fn replay_changes_with(
    plan: &ReplayPlan,
    file: &Path,
    saw_event: impl FnMut(f64),
    on_change: impl FnMut(&RoiChange),
) -> anyhow::Result<ProblemLog> {
    let reader = ReplayReader::open(file)?;
    Ok(play_plan(plan, reader, saw_event, on_change))
}

fn play_plan(
    plan: &ReplayPlan,
    reader: ReplayReader<io::BufReader<std::fs::File>>,
    mut saw_event: impl FnMut(f64),
    mut on_change: impl FnMut(&RoiChange),
) -> ProblemLog {
    let mut pipeline = plan.pipeline();
    let device = plan.interaction.device;
    let reader_problems = play(reader, plan.playback, |item| {
        let changes = match &item.payload {
            ReplayPayload::Datagram(protocol, bytes) => {
                let (events, changes) = pipeline.datagram(*protocol, bytes, item.t, &plan.surface);
                if let Some(e) = events.iter().find(|e| e.device == device) {
                    saw_event(e.t);
                }
                changes
            }
            ReplayPayload::Event(e) => {
                if e.device == device && e.is_valid() {
                    saw_event(e.t);
                }
                pipeline.event(e.clone(), &plan.surface)
            }
        };
        for c in changes {
            on_change(c);
        }
    });
    let mut problems = reader_problems;
    problems.merge(&pipeline.ingest.problems);
    problems
}

/// Validated recorder settings.
pub fn listener_config(args: &RecordArgs) -> anyhow::Result<(ListenerConfig, Protocol)> {
    let (port, protocol) = match (args.dtrack, args.osc) {
        (Some(p), None) => (p, Protocol::Dtrack),
        (None, Some(p)) => (p, Protocol::Osc),
        _ => bail!("give exactly one of --dtrack PORT and --osc PORT"),
    };
    if let Some(s) = args.seconds
        && !(s.is_finite() && s > 0.0)
    {
        bail!("--seconds must be a positive number of seconds, not {s}");
    }
    let config = ListenerConfig {
        bind: SocketAddr::new(args.bind, port),
        allow_non_loopback: args.allow_network,
        allow_from: args.allow_from.clone(),
        ..ListenerConfig::loopback(port)
    };
    Ok((config, protocol))
}

/// Records live traffic into a replay file; returns the number of datagrams written. The
/// recording's header holds the display model and the calibration, so that replaying it needs
/// neither. Says "listening on ADDR:PORT" once bound.
pub fn run_record(args: &RecordArgs, stop: &AtomicBool) -> anyhow::Result<u64> {
    if let Some(s) = args.seconds
        && !(s.is_finite() && s > 0.0)
    {
        bail!("--seconds must be a positive number of seconds, not {s}");
    }
    crate::output::check_writable(&args.out)?;
    let (model, origin) = DisplayModel::open(&args.display)?;
    let calibration = match &args.calibration {
        Some(p) => Some(Calibration::load(p)?),
        None => None,
    };
    if let Some(address) = &args.vrpn {
        return record_vrpn(args, address, model, origin, calibration, stop);
    }
    let (config, protocol) = listener_config(args)?;
    let mut source = UdpSource::bind(config)?;
    let addr = source.local_addr()?;
    let mut header = ReplayHeader::new(format!(
        "recorded by raygun record from {protocol:?} on {addr}, for {origin}"
    ));
    header.display = Some(match origin {
        crate::display::ModelOrigin::Builtin(name) => name.to_owned(),
        crate::display::ModelOrigin::File(p) => p.display().to_string(),
    });
    header.display_model = Some(model);
    header.calibration = calibration;
    let file =
        LineFile::create(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let mut writer = ReplayWriter::new(file, &header)?;
    writer.flush()?;
    eprintln!(
        "raygun record: listening on {addr} for {protocol:?}, writing {}",
        args.out.display()
    );
    let mut problems = ProblemLog::default();
    let n = record(
        &mut source,
        protocol,
        &mut writer,
        stop,
        args.seconds.map(Duration::from_secs_f64),
        &mut problems,
    )
    .with_context(|| {
        format!(
            "recording into {} (every record up to the failure is kept)",
            args.out.display()
        )
    })?;
    Ok(n)
}

/// `record --vrpn`: the raw VRPN reads of one connection, with the display and the calibration
/// in the header.
fn record_vrpn(
    args: &RecordArgs,
    address: &crate::tracking::vrpn::VrpnAddress,
    model: DisplayModel,
    origin: crate::display::ModelOrigin,
    calibration: Option<Calibration>,
    stop: &AtomicBool,
) -> anyhow::Result<u64> {
    use crate::tracking::vrpn::{self, VrpnClientConfig, VrpnConfig, VrpnSource};
    let mut source = VrpnSource::new(VrpnClientConfig {
        reconnect: false,
        allow_non_loopback: args.allow_network,
        ..VrpnClientConfig::new(address.clone())
    })?;
    let mut header = vrpn::recording_header(address, &VrpnConfig::default());
    header.display = Some(match &origin {
        crate::display::ModelOrigin::Builtin(name) => (*name).to_owned(),
        crate::display::ModelOrigin::File(p) => p.display().to_string(),
    });
    header.display_model = Some(model);
    header.calibration = calibration;
    let mut ingest = header.ingest(None)?;
    ingest.problems.quiet = true;
    let file =
        LineFile::create(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let mut writer = ReplayWriter::new(file, &header)?;
    writer.flush()?;
    eprintln!(
        "raygun record: recording VRPN {address} ({}), writing {}",
        source.server(),
        args.out.display()
    );
    let n = vrpn::record(
        &mut source,
        &mut writer,
        &mut ingest,
        stop,
        args.seconds.map(Duration::from_secs_f64),
    )
    .with_context(|| {
        format!(
            "recording into {} (every record up to the failure is kept)",
            args.out.display()
        )
    })?;
    if ingest.problems.total() > 0 {
        let kinds: Vec<String> = ingest
            .problems
            .counts()
            .iter()
            .map(|(kind, n)| format!("{n} × {kind}"))
            .collect();
        eprintln!("raygun record: input problems: {}", kinds.join(", "));
    }
    Ok(n)
}

/// Writes the synthetic sessions.
pub fn run_synth(args: &SynthArgs) -> anyhow::Result<Vec<PathBuf>> {
    crate::tracking::synth::write_all(&args.out)
        .with_context(|| format!("writing into {}", args.out.display()))
}

/// The golden file of a replay: `tracking-replays/golden/<stem>.roi.jsonl`.
#[must_use]
pub fn golden_path(replay: &Path) -> PathBuf {
    let name = replay
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or("replay.jsonl");
    let stem = name.strip_suffix(".jsonl").unwrap_or(name);
    replay
        .parent()
        .unwrap_or(Path::new("."))
        .join("golden")
        .join(format!("{stem}.roi.jsonl"))
}
