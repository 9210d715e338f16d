//! `raygun replay`, `raygun record` and `raygun synth-replays`: clap arguments and run
//! functions. Arguments are turned into a validated configuration before any work starts.
//!
//! `raygun replay FILE` prints the ROI changes as JSON lines (see [`crate::session::replay`]).

use std::io::Write;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::{ArgGroup, Args};

use crate::display::DisplayModel;
use crate::session::replay::{ChangePrinter, ReplayOptions, ReplayPlan, replay_changes_with};
use crate::session::udp::{ListenerConfig, UdpSource, record};
use crate::tracking::calibration::Calibration;
use crate::tracking::event::DeviceId;
use crate::tracking::head::EyeRule;
use crate::tracking::ingest::Protocol;
use crate::tracking::problems::ProblemLog;
use crate::tracking::replay::{LineFile, ReplayHeader, ReplayWriter};

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
    /// A tracked head (default: the recording's): its eyes that restart the accumulation are
    /// printed as `"kind":"eye"` lines.
    #[command(flatten)]
    pub head: crate::cli::head::HeadArgs,
}

impl ReplayArgs {
    /// What the arguments ask the session layer to replay.
    #[must_use]
    pub fn options(&self) -> ReplayOptions {
        ReplayOptions {
            file: self.file.clone(),
            display: self.display.clone(),
            config: self.config.clone(),
            device: self.device,
            calibration: self.calibration.clone(),
            realtime: self.realtime,
            head: self.head.overrides(),
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
    /// Record a VRPN server's device (`DEVICE@HOST[:PORT]`, or `DEVICE@tcp://HOST[:PORT]`): the raw
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
    /// The tracked head, named in the recording's header so that replays move the wall
    /// camera's eye (its poses are in the recorded datagrams with every other device's).
    #[command(flatten)]
    pub head: crate::cli::head::HeadArgs,
}

/// `raygun synth-replays`.
#[derive(Args, Debug, Clone)]
pub struct SynthArgs {
    /// Directory to write into.
    #[arg(long, default_value = "tracking-replays")]
    pub out: PathBuf,
}

/// Runs a replay, printing changes to `out` (and, with a tracked head, the eyes that restart
/// the accumulation); returns the problem counts (reader and decoders).
pub fn run_replay(args: &ReplayArgs, out: impl Write) -> anyhow::Result<ReplaySummary> {
    args.head.check()?;
    let options = args.options();
    let (plan, _) = ReplayPlan::new(&options)?;
    let mut rule = plan.head.map(|h| EyeRule::new(h.eye_threshold_m));
    let mut printer = ChangePrinter::new(out);
    let io_result = std::cell::RefCell::new(Ok(()));
    let printer_ref = std::cell::RefCell::new(&mut printer);
    let summary = std::cell::RefCell::new(ReplaySummary {
        device: plan.interaction.device.to_string(),
        ..ReplaySummary::default()
    });
    let problems = replay_changes_with(
        &plan,
        &options.file,
        |t| {
            let mut s = summary.borrow_mut();
            s.frames += 1;
            s.first_t.get_or_insert(t);
            s.last_t = t;
            printer_ref.borrow_mut().saw_event(t);
        },
        |c| {
            summary.borrow_mut().changes += 1;
            let mut r = io_result.borrow_mut();
            if r.is_ok() {
                *r = printer_ref.borrow_mut().print(c);
            }
        },
        |t, eye| {
            let mut r = io_result.borrow_mut();
            if let Some(rule) = &mut rule
                && rule.offer(eye)
                && r.is_ok()
            {
                summary.borrow_mut().eyes += 1;
                *r = printer_ref.borrow_mut().print_eye(t, eye);
            }
        },
    )?;
    io_result.into_inner().context("writing ROI changes")?;
    let mut summary = summary.into_inner();
    summary.problems = problems;
    Ok(summary)
}

/// What `raygun replay` read and printed.
#[derive(Debug, Default)]
pub struct ReplaySummary {
    /// The followed device, as named on the command line.
    pub device: String,
    /// Frames (datagrams or events) that held the followed device.
    pub frames: u64,
    /// The time of the first and last of them, seconds.
    pub first_t: Option<f64>,
    pub last_t: f64,
    /// ROI changes printed (shots, misses, FOV changes).
    pub changes: u64,
    /// Eye lines printed (restarts of a tracked head).
    pub eyes: u64,
    /// Bad input, counted by kind.
    pub problems: ProblemLog,
}

impl ReplaySummary {
    /// One line for standard error: how much was read, and what it gave — said plainly when a
    /// session never pressed the trigger (stdout then holds nothing).
    #[must_use]
    pub fn line(&self) -> String {
        let span = self.first_t.map_or(0.0, |t0| self.last_t - t0);
        let read = format!(
            "{} of {} over {span:.1} s",
            crate::messages::count(self.frames as usize, "frame"),
            self.device
        );
        let eyes = if self.eyes > 0 {
            format!(
                ", {}",
                crate::messages::count(self.eyes as usize, "eye restart")
            )
        } else {
            String::new()
        };
        if self.changes == 0 {
            format!(
                "{read}: no trigger was pressed and the stick did not move: no ROI change{eyes}"
            )
        } else {
            format!(
                "{read}: {}{eyes}",
                crate::messages::count(self.changes as usize, "ROI change")
            )
        }
    }
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
    let head = args.head.head()?;
    let (model, origin) = DisplayModel::open(&args.display)?;
    let calibration = match &args.calibration {
        Some(p) => Some(Calibration::load(p)?),
        None => None,
    };
    if let Some(address) = &args.vrpn {
        return record_vrpn(args, address, model, origin, calibration, head, stop);
    }
    let (config, protocol) = listener_config(args)?;
    let mut source = UdpSource::bind(config)?;
    let addr = source.local_addr()?;
    let mut header = ReplayHeader::new(format!(
        "recorded by raygun record from {protocol} on {addr}, for {origin}"
    ));
    header.display = Some(match origin {
        crate::display::ModelOrigin::Builtin(name) => name.to_owned(),
        crate::display::ModelOrigin::File(p) => p.display().to_string(),
    });
    header.display_model = Some(model);
    header.calibration = calibration;
    header.head = head;
    let file =
        LineFile::create(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let mut writer = ReplayWriter::new(file, &header)?;
    writer.flush()?;
    eprintln!(
        "raygun record: listening on {addr} for {protocol}, writing {}",
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
    head: Option<crate::tracking::head::HeadConfig>,
    stop: &AtomicBool,
) -> anyhow::Result<u64> {
    use crate::session::vrpn::{VrpnClientConfig, VrpnSource};
    use crate::tracking::vrpn::VrpnConfig;
    let mut source = VrpnSource::new(VrpnClientConfig {
        reconnect: false,
        allow_non_loopback: args.allow_network,
        ..VrpnClientConfig::new(address.clone())
    })?;
    let mut header = ReplayHeader::vrpn_recording(address, &VrpnConfig::default());
    header.display = Some(match &origin {
        crate::display::ModelOrigin::Builtin(name) => (*name).to_owned(),
        crate::display::ModelOrigin::File(p) => p.display().to_string(),
    });
    header.display_model = Some(model);
    header.calibration = calibration;
    header.head = head;
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
    let n = crate::session::vrpn::record(
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
    crate::interaction::synth::write_all(&args.out)
        .with_context(|| format!("writing into {}", args.out.display()))
}
