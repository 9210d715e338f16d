//! `raygun calibrate`: the tracker→room calibration in one step. Hold the tracked device at
//! three or more known points of the wall (tile corners or centres, or room points) in turn and
//! press its trigger at each; raygun solves the rotation and translation that map the tracker's
//! positions onto those points (least squares, Horn's closed form), says how well they fit, and
//! writes the calibration file that `view`, `record`, `replay` and `render --guide` take.
//!
//! Positions rather than pointing rays: three rays from one place at three known points is the
//! perspective-three-point problem, with up to four solutions; three held positions determine
//! the transform uniquely and their residual says at once whether a point was missed.
//!
//! The presses come from live DTrack or OSC input (`--dtrack PORT`, `--osc PORT`) or from a
//! recording of such a session (`--replay FILE`, as `raygun record` writes it).

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use clap::{ArgGroup, Args};
use glam::{DVec2, DVec3};

use crate::display::DisplayModel;
use crate::session::calibrate::{PressCollector, raw_ingest};
use crate::session::udp::{ListenerConfig, Received, UdpSource};
use crate::tracking::calibration::{Calibration, DTRACK_METRES_PER_UNIT, Units, solve};
use crate::tracking::event::{DeviceId, DeviceKind, TrackingEvent};
use crate::tracking::ingest::Protocol;
use crate::tracking::replay::{ReplayPayload, ReplayReader};

/// `raygun calibrate`.
#[derive(Args, Debug, Clone)]
#[command(group(ArgGroup::new("input").required(true).args(["dtrack", "osc", "replay"])))]
pub struct CalibrateArgs {
    /// The wall the targets are on: a file, or a built-in model.
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// A point to hold the device at, in order (repeatable, at least 3 not on one line):
    /// `TILE:CORNER` with CORNER one of top-left, top-right, bottom-left, bottom-right, centre
    /// (of the tile's lit area, e.g. c0r0:top-left), or room coordinates `X,Y,Z` in metres.
    #[arg(
        long = "target",
        value_name = "TILE:CORNER|X,Y,Z",
        required = true,
        allow_hyphen_values = true
    )]
    pub targets: Vec<String>,
    /// Live DTrack ASCII on this loopback UDP port.
    #[arg(long, value_name = "PORT")]
    pub dtrack: Option<u16>,
    /// Live OSC on this loopback UDP port.
    #[arg(long, value_name = "PORT")]
    pub osc: Option<u16>,
    /// A recording of the presses (`raygun record`).
    #[arg(long, value_name = "FILE")]
    pub replay: Option<PathBuf>,
    /// The device held at the targets.
    #[arg(long, value_name = "KIND:N", default_value = "flystick:0")]
    pub device: DeviceId,
    /// The button whose presses mark a target (0: the FlyStick's trigger).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub button: u32,
    /// What the tracker's numbers mean (default: the protocol's own, DTrack mm, OSC m).
    #[arg(long, value_name = "mm|cm|m")]
    pub units: Option<Units>,
    /// Give up live input after this many seconds.
    #[arg(long, value_name = "S", default_value_t = 300.0)]
    pub seconds: f64,
    /// The calibration file to write.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

/// A target: what to call it and where it is in the room.
#[derive(Clone, Debug, PartialEq)]
pub struct Target {
    pub name: String,
    pub room: DVec3,
}

/// Parses a target against the display model.
pub fn parse_target(spec: &str, model: &DisplayModel) -> anyhow::Result<Target> {
    if let Ok(p) = crate::cli::args::parse_vec3(spec) {
        return Ok(Target {
            name: format!("room point {spec}"),
            room: p,
        });
    }
    let (tile, corner) = spec.split_once(':').with_context(|| {
        format!(
            "--target {}: give TILE:CORNER (e.g. c0r0:top-left) or X,Y,Z",
            crate::messages::quote(spec)
        )
    })?;
    let i = model.tile_index(tile).with_context(|| {
        format!(
            "--target {}: {} has no tile {}",
            crate::messages::quote(spec),
            model.name(),
            crate::messages::quote(tile)
        )
    })?;
    let t = &model.tiles()[i];
    let [w, h] = t.resolution().map(f64::from);
    let px = match corner {
        "top-left" => DVec2::new(0.0, 0.0),
        "top-right" => DVec2::new(w, 0.0),
        "bottom-left" => DVec2::new(0.0, h),
        "bottom-right" => DVec2::new(w, h),
        "centre" | "center" => DVec2::new(w / 2.0, h / 2.0),
        _ => bail!(
            "--target {}: the corner is top-left, top-right, bottom-left, bottom-right or centre",
            crate::messages::quote(spec)
        ),
    };
    Ok(Target {
        name: format!("{corner} of tile {tile}"),
        room: t.tile_px_to_point(px),
    })
}

pub fn run(args: &CalibrateArgs, stop: &AtomicBool) -> anyhow::Result<Calibration> {
    crate::output::check_writable(&args.out)?;
    if args.button >= 32 {
        bail!("--button must be below 32");
    }
    if !(args.seconds.is_finite() && args.seconds > 0.0) {
        bail!("--seconds must be a positive number");
    }
    let (model, origin) = DisplayModel::open(&args.display)?;
    let targets: Vec<Target> = args
        .targets
        .iter()
        .map(|t| parse_target(t, &model))
        .collect::<anyhow::Result<_>>()?;
    if targets.len() < 3 {
        bail!(
            "{} targets: at least 3, not on one line, are needed",
            targets.len()
        );
    }
    let native = match (args.dtrack, args.osc, &args.replay) {
        (Some(_), _, _) => DTRACK_METRES_PER_UNIT,
        (_, Some(_), _) => 1.0,
        (_, _, Some(f)) => replay_native_unit(f)?,
        _ => unreachable!("clap requires one input"),
    };
    let metres_per_unit = args.units.map_or(native, Units::metres_per_unit);
    eprintln!(
        "raygun calibrate: {} on {origin}",
        crate::messages::count(targets.len(), "target")
    );
    let mut collector = PressCollector::new(args.device, args.button);
    collect_presses(args, stop, &targets, &mut collector)?;
    if collector.untracked_presses > 0 {
        eprintln!(
            "raygun calibrate: {} while {} was not tracked {} ignored",
            crate::messages::count(collector.untracked_presses as usize, "press"),
            args.device,
            if collector.untracked_presses == 1 {
                "was"
            } else {
                "were"
            }
        );
    }
    if collector.positions.len() < targets.len() {
        bail!(
            "{}: {} of button {} by {} found, {} given",
            args.replay
                .as_deref()
                .map_or_else(String::new, |p| p.display().to_string()),
            crate::messages::count(collector.positions.len(), "press"),
            args.button,
            args.device,
            crate::messages::count(targets.len(), "target")
        );
    }
    let room: Vec<DVec3> = targets.iter().map(|t| t.room).collect();
    let (transform, report) = solve(&collector.positions, &room, metres_per_unit)?;
    let worst = collector
        .positions
        .iter()
        .zip(&targets)
        .map(|(p, t)| (transform.map_point(*p).distance(t.room), &t.name))
        .fold(
            (0.0, None),
            |best, (d, n)| {
                if d > best.0 { (d, Some(n)) } else { best }
            },
        );
    eprintln!(
        "raygun calibrate: solved from {} points: residual RMS {:.2} mm, largest {:.2} mm (at the {})",
        report.points,
        report.rms_mm,
        report.max_mm,
        worst.1.map_or("?", |s| s.as_str())
    );
    if (report.scale - 1.0).abs() > 0.02 {
        eprintln!(
            "raygun calibrate: warning: the points fit best scaled by {:.4}: are the tracker's units right? (give --units mm|cm|m)",
            report.scale
        );
    }
    let calibration = Calibration {
        rotation_rows: transform.rotation_rows,
        translation_m: transform.translation_m,
        units: args.units,
        solved: Some(report),
        ..Calibration::default()
    };
    calibration.validate(&args.out)?;
    crate::output::write_bytes(&args.out, calibration.to_json_pretty().as_bytes())?;
    eprintln!("raygun calibrate: wrote {}", args.out.display());
    Ok(calibration)
}

/// The presses of `collector`'s button, one for each of `targets` in turn: from the recording,
/// or from the live source within `--seconds` (naming each target as it is due).
fn collect_presses(
    args: &CalibrateArgs,
    stop: &AtomicBool,
    targets: &[Target],
    collector: &mut PressCollector,
) -> anyhow::Result<()> {
    // A person holds the device for a live source; a recording's presses are already there.
    let live = args.replay.is_none();
    let prompt = |n: usize| {
        if live && let Some(t) = targets.get(n) {
            eprintln!(
                "raygun calibrate: target {}/{}: hold {} at the {} (room {:.3}, {:.3}, {:.3} m) and press button {}",
                n + 1,
                targets.len(),
                args.device,
                t.name,
                t.room.x,
                t.room.y,
                t.room.z,
                args.button
            );
        }
    };
    prompt(0);
    let mut ingest = raw_ingest();
    let feed = |events: &[TrackingEvent], collector: &mut PressCollector| {
        for e in events {
            if collector.event(e) {
                let n = collector.positions.len();
                let name = targets.get(n - 1).map_or("", |t| t.name.as_str());
                if live {
                    eprintln!("raygun calibrate: target {n} ({name}) recorded");
                } else {
                    eprintln!("raygun calibrate: target {n} ({name}): press {n} of the recording");
                }
                prompt(n);
            }
        }
    };
    if let Some(file) = &args.replay {
        let mut reader = ReplayReader::open(file)?;
        while let Some(item) = reader.next_item() {
            if collector.positions.len() >= targets.len() {
                break;
            }
            match &item.payload {
                ReplayPayload::Datagram(protocol, bytes) => {
                    let events = ingest.datagram(*protocol, bytes, item.t).to_vec();
                    feed(&events, collector);
                }
                ReplayPayload::Event(e) => {
                    if let Some(e) = ingest.event(e.clone()) {
                        feed(&[e], collector);
                    }
                }
            }
        }
    } else {
        let (port, protocol) = match (args.dtrack, args.osc) {
            (Some(p), _) => (p, Protocol::Dtrack),
            (_, Some(p)) => (p, Protocol::Osc),
            _ => unreachable!("clap requires one input"),
        };
        let mut source = UdpSource::bind(ListenerConfig::loopback(port))?;
        let addr: SocketAddr = source.local_addr()?;
        eprintln!("raygun calibrate: listening on {addr} for {protocol}");
        let start = Instant::now();
        let limit = Duration::from_secs_f64(args.seconds);
        while collector.positions.len() < targets.len() {
            if stop.load(Ordering::Relaxed) {
                bail!(
                    "stopped after {} of {} targets",
                    collector.positions.len(),
                    targets.len()
                );
            }
            if start.elapsed() > limit {
                bail!(
                    "no more presses within --seconds {}: {} of {} targets recorded",
                    args.seconds,
                    collector.positions.len(),
                    targets.len()
                );
            }
            if let Received::Datagram(bytes, _) = source.recv()? {
                let t = start.elapsed().as_secs_f64();
                let events = ingest.datagram(protocol, bytes, t).to_vec();
                feed(&events, collector);
            }
        }
    }
    Ok(())
}

/// The unit a recording's positions are in: DTrack's millimetres if it holds DTrack
/// datagrams, else metres.
fn replay_native_unit(file: &Path) -> anyhow::Result<f64> {
    let mut reader = ReplayReader::open(file)?;
    while let Some(item) = reader.next_item() {
        match item.payload {
            ReplayPayload::Datagram(Protocol::Dtrack, _) => return Ok(DTRACK_METRES_PER_UNIT),
            ReplayPayload::Datagram(_, _) => return Ok(1.0),
            ReplayPayload::Event(e) if e.device.kind == DeviceKind::Mouse => continue,
            ReplayPayload::Event(_) => return Ok(1.0),
        }
    }
    Ok(1.0)
}
