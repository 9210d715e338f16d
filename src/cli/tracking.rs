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
use crate::tracking::event::DeviceId;
use crate::tracking::ingest::{Ingest, Pipeline, Protocol};
use crate::tracking::problems::ProblemLog;
use crate::tracking::replay::{
    Playback, ReplayHeader, ReplayPayload, ReplayReader, ReplayWriter, play,
};
use crate::tracking::udp::{ListenerConfig, UdpSource, record};

/// `raygun replay`.
#[derive(Args, Debug, Clone)]
pub struct ReplayArgs {
    /// Replay file (JSON Lines).
    pub file: PathBuf,
    /// Display model to shoot at (`display-models/*.json`); default: the replay header's
    /// `display`, looked up relative to the working directory, then to the replay's folder's
    /// parent (where the shipped replays' models live).
    #[arg(long)]
    pub display: Option<PathBuf>,
    /// Interaction mapping (JSON); default: the documented defaults.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Device to follow, e.g. `flystick:0`; default: the header's, else the config's.
    #[arg(long)]
    pub device: Option<DeviceId>,
    /// Play at recorded speed instead of as fast as possible.
    #[arg(long)]
    pub realtime: bool,
}

/// `raygun record`.
#[derive(Args, Debug, Clone)]
#[command(group(ArgGroup::new("source").required(true).args(["dtrack", "osc"])))]
pub struct RecordArgs {
    /// Listen for DTrack ASCII on this UDP port.
    #[arg(long)]
    pub dtrack: Option<u16>,
    /// Listen for OSC on this UDP port.
    #[arg(long)]
    pub osc: Option<u16>,
    /// Replay file to write.
    #[arg(long)]
    pub out: PathBuf,
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

/// The display model file a replay names: as given, else next to the replay's folder.
fn resolve_display(named: &str, replay: &Path) -> PathBuf {
    let direct = PathBuf::from(named);
    if direct.exists() {
        return direct;
    }
    let beside = replay
        .parent()
        .and_then(Path::parent)
        .map(|p| p.join(named));
    beside.filter(|p| p.exists()).unwrap_or(direct)
}

/// Everything a replay run needs, validated.
pub struct ReplayPlan {
    pub header: ReplayHeader,
    pub surface: DisplayModel,
    pub interaction: InteractionConfig,
    pub playback: Playback,
}

impl ReplayPlan {
    /// Reads the header and resolves display, device and mapping.
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
        interaction.validate()?;
        let display = match (&args.display, &header.display) {
            (Some(p), _) => p.clone(),
            (None, Some(named)) => resolve_display(named, &args.file),
            (None, None) => bail!(
                "{}: no --display given and the header names none",
                args.file.display()
            ),
        };
        let surface = DisplayModel::load(&display)?;
        if let Some(d) = &header.dtrack {
            d.tracker_to_room
                .validate()
                .with_context(|| format!("{}: header `dtrack`", args.file.display()))?;
        }
        let playback = if args.realtime {
            Playback::RealTime
        } else {
            Playback::AsFastAsPossible
        };
        Ok((
            Self {
                header,
                surface,
                interaction,
                playback,
            },
            reader,
        ))
    }

    /// A fresh pipeline configured from the header and the mapping.
    #[must_use]
    pub fn pipeline(&self) -> Pipeline {
        let ingest = Ingest::new(
            self.header.dtrack.clone().unwrap_or_default(),
            self.header.osc.clone().unwrap_or_default(),
            self.header.time_source,
        );
        Pipeline::new(ingest, Interaction::new(self.interaction.clone()))
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
    mut saw_event: impl FnMut(f64),
    mut on_change: impl FnMut(&RoiChange),
) -> anyhow::Result<ProblemLog> {
    let (plan, reader) = ReplayPlan::new(args)?;
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
    Ok(problems)
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

/// Records live traffic into a replay file; returns the number of datagrams written.
pub fn run_record(args: &RecordArgs, stop: &AtomicBool) -> anyhow::Result<u64> {
    let (config, protocol) = listener_config(args)?;
    let mut source = UdpSource::bind(config)?;
    let file = std::fs::File::create(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let mut header = ReplayHeader::new(format!(
        "recorded by raygun record from {:?} on {}",
        protocol,
        source.local_addr()?
    ));
    header.display = None;
    let mut writer = ReplayWriter::new(io::BufWriter::new(file), &header)?;
    let mut problems = ProblemLog::default();
    let n = record(
        &mut source,
        protocol,
        &mut writer,
        stop,
        args.seconds.map(Duration::from_secs_f64),
        &mut problems,
    )
    .with_context(|| format!("recording into {}", args.out.display()))?;
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
