//! Replays played against a display: the plan (header, display, device, calibration,
//! mapping, decoders, all resolved before any input), its ROI changes, and their JSON lines.
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
use std::path::{Path, PathBuf};

use super::pipeline::Pipeline;
use crate::display::{DisplayModel, DisplayModelError};
use crate::interaction::config::ConfigError;
use crate::interaction::{Interaction, InteractionConfig, RoiChange};
use crate::tracking::calibration::{Calibration, CalibrationError};
use crate::tracking::event::DeviceId;
use crate::tracking::head::{EyeRule, HeadConfig, HeadError, HeadOverride};
use crate::tracking::ingest::Ingest;
use crate::tracking::problems::ProblemLog;
use crate::tracking::replay::{
    HeaderConfigError, Playback, ReplayError, ReplayHeader, ReplayPayload, ReplayReader, play,
};

/// What to replay and against what; `None` fields come from the recording's header.
#[derive(Clone, Debug)]
pub struct ReplayOptions {
    pub file: PathBuf,
    /// A display model file or a built-in model's name.
    pub display: Option<String>,
    /// An interaction mapping (JSON).
    pub config: Option<PathBuf>,
    pub device: Option<DeviceId>,
    /// A tracker→room calibration (JSON).
    pub calibration: Option<PathBuf>,
    /// At recorded speed instead of as fast as possible.
    pub realtime: bool,
    /// Changes to the header's tracked head (`--head`, `--eye-offset`, `--eye-threshold`).
    pub head: HeadOverride,
}

impl ReplayOptions {
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
            head: HeadOverride::default(),
        }
    }
}

/// Why a replay could not be planned.
#[derive(Debug, thiserror::Error)]
pub enum ReplayPlanError {
    #[error(transparent)]
    Replay(#[from] ReplayError),
    #[error(transparent)]
    Mapping(#[from] ConfigError),
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    #[error("{}: calibration", file.display())]
    BadCalibration {
        file: PathBuf,
        #[source]
        source: CalibrationError,
    },
    #[error(transparent)]
    Display(#[from] DisplayModelError),
    #[error("{}: the header's field `display` names {}, which is not a display model", file.display(), crate::messages::quote(named))]
    HeaderDisplay {
        file: PathBuf,
        named: String,
        #[source]
        source: Box<DisplayModelError>,
    },
    #[error("{}: the recording names no display: give --display MODEL", .0.display())]
    NoDisplay(PathBuf),
    #[error("{}", file.display())]
    Header {
        file: PathBuf,
        #[source]
        source: HeaderConfigError,
    },
    #[error("{}: the head", file.display())]
    Head {
        file: PathBuf,
        #[source]
        source: HeadError,
    },
}

/// The display model a replay names: a file as given, else one next to the replay's folder
/// (where the shipped replays' models live), else a built-in model of that name.
fn resolve_display(
    named: &str,
    replay: &Path,
) -> Result<(DisplayModel, String), DisplayModelError> {
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
    /// The tracked head: the options' or the header's (`None`: the eye stays put).
    pub head: Option<HeadConfig>,
}

impl ReplayPlan {
    /// Reads the header and resolves display, device, calibration and mapping.
    pub fn new(
        args: &ReplayOptions,
    ) -> Result<(Self, ReplayReader<io::BufReader<std::fs::File>>), ReplayPlanError> {
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
                .map_err(|source| ReplayPlanError::BadCalibration {
                    file: args.file.clone(),
                    source,
                })?;
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
                (None, None, Some(named)) => {
                    resolve_display(named, &args.file).map_err(|source| {
                        ReplayPlanError::HeaderDisplay {
                            file: args.file.clone(),
                            named: named.clone(),
                            source: Box::new(source),
                        }
                    })?
                }
                (None, None, None) => return Err(ReplayPlanError::NoDisplay(args.file.clone())),
            };
        // Every decoder the header asks for must be usable.
        let ingest =
            header
                .ingest(calibration.as_ref())
                .map_err(|source| ReplayPlanError::Header {
                    file: args.file.clone(),
                    source,
                })?;
        let head = args.head.apply(header.head);
        if let Some(h) = &head {
            h.validate().map_err(|source| ReplayPlanError::Head {
                file: args.file.clone(),
                source,
            })?;
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
                display_origin,
                interaction,
                calibration,
                ingest,
                playback,
                head,
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

    /// Prints an eye that restarts the accumulation: `{"t":…,"kind":"eye","eye_room_m":[x,y,z]}`
    /// (millimetre-rounded metres).
    pub fn print_eye(&mut self, t: f64, eye: glam::DVec3) -> io::Result<()> {
        let origin = *self.t_origin.get_or_insert(t);
        serde_json::to_writer(&mut self.out, &EyeReport::new(t - origin, eye))?;
        self.out.write_all(b"\n")
    }

    /// The underlying writer.
    #[must_use]
    pub fn into_inner(self) -> W {
        self.out
    }
}

/// The printed form of an eye restart (`raygun replay`, golden files), rounded like
/// [`RoiChange::report`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct EyeReport {
    pub t: f64,
    pub kind: &'static str,
    pub eye_room_m: [f64; 3],
}

impl EyeReport {
    #[must_use]
    pub fn new(t: f64, eye: glam::DVec3) -> Self {
        let r = |v: f64, d: usize| {
            let x: f64 = format!("{v:.d$}").parse().unwrap_or(v);
            if x == 0.0 { 0.0 } else { x }
        };
        Self {
            t: r(t, 6),
            kind: "eye",
            eye_room_m: eye.to_array().map(|v| r(v, 4)),
        }
    }
}

/// Plays a replay through the live parsers and the interaction state machine: `saw_event` gets
/// the time of each event of the configured device, `on_change` each ROI change and `on_eye`
/// (with a head, [`ReplayPlan::head`]) the time and room-frame eye of each tracked head pose,
/// before the changes of the same record. Returns the problem counts (reader and decoders).
pub fn replay_changes(
    args: &ReplayOptions,
    saw_event: impl FnMut(f64),
    on_change: impl FnMut(&RoiChange),
    on_eye: impl FnMut(f64, glam::DVec3),
) -> Result<ProblemLog, ReplayPlanError> {
    let (plan, reader) = ReplayPlan::new(args)?;
    Ok(play_plan(&plan, reader, saw_event, on_change, on_eye))
}

/// [`replay_changes`] for a plan made already (its file is read again from the start).
pub fn replay_changes_with(
    plan: &ReplayPlan,
    file: &Path,
    saw_event: impl FnMut(f64),
    on_change: impl FnMut(&RoiChange),
    on_eye: impl FnMut(f64, glam::DVec3),
) -> Result<ProblemLog, ReplayError> {
    let reader = ReplayReader::open(file)?;
    Ok(play_plan(plan, reader, saw_event, on_change, on_eye))
}

fn play_plan(
    plan: &ReplayPlan,
    reader: ReplayReader<io::BufReader<std::fs::File>>,
    mut saw_event: impl FnMut(f64),
    mut on_change: impl FnMut(&RoiChange),
    mut on_eye: impl FnMut(f64, glam::DVec3),
) -> ProblemLog {
    let mut pipeline = plan.pipeline();
    let device = plan.interaction.device;
    let head = plan.head;
    let mut eyes = |e: &crate::tracking::event::TrackingEvent| {
        if let Some(eye) = head.and_then(|h| h.eye_of(e)) {
            on_eye(e.t, eye);
        }
    };
    let reader_problems = play(reader, plan.playback, |item| {
        let changes = match &item.payload {
            ReplayPayload::Datagram(protocol, bytes) => {
                let (events, changes) = pipeline.datagram(*protocol, bytes, item.t, &plan.surface);
                if let Some(e) = events.iter().find(|e| e.device == device) {
                    saw_event(e.t);
                }
                events.iter().for_each(&mut eyes);
                changes
            }
            ReplayPayload::Event(e) => {
                if e.device == device && e.is_valid() {
                    saw_event(e.t);
                }
                eyes(e);
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

/// The eyes of a head stream that restart the accumulation under `threshold_m`
/// ([`EyeRule`]): (time, eye) in order.
#[must_use]
pub fn eye_restarts(eyes: &[(f64, glam::DVec3)], threshold_m: f64) -> Vec<(f64, glam::DVec3)> {
    let mut rule = EyeRule::new(threshold_m);
    eyes.iter()
        .copied()
        .filter(|&(_, e)| rule.offer(e))
        .collect()
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
