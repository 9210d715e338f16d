//! A.R.T. DTrack ASCII protocol: one UDP datagram → one [`DtrackFrame`] → normalised events.
//!
//! Format (DTrack2/DTrack3 "Technical Appendix", as implemented by A.R.T.'s `DTrackParser`):
//! one datagram holds one frame, one line per record, the record type first.
//!
//! ```text
//! fr 21753                                    frame counter
//! ts 39596.024831                             seconds since 00:00 UTC (wraps at midnight)
//! ts2 1700000000 24831                        seconds since 1970 UTC, microseconds (newer DTrack)
//! 6dcal 4                                     number of calibrated bodies
//! 6d 1 [0 1.000][326.8 -187.2 109.9][b0 b1 b2 b3 b4 b5 b6 b7 b8]
//! 6df2 1 1 [0 1.000 6 2][x y z][b0 .. b8][buttons axis0 axis1]
//! ```
//!
//! * Positions are millimetres in the tracker's room frame; the 3×3 rotation `b0..b8` is
//!   written column by column (b0 b1 b2 is the first column). Old DTrack versions append the
//!   three Euler angles to the `6d` position block (6 values); they repeat the matrix and are
//!   ignored.
//! * `6d` lists only the bodies that are tracked in this frame, so a body's id is *not* its
//!   index in the line; `6df2` lists every calibrated FlyStick, untracked ones with quality −1
//!   and an all-zero rotation. An untracked FlyStick keeps its buttons and stick, but yields
//!   no pose: a zero matrix is never turned into a quaternion.
//! * `6df2` block 1 is `[id quality buttons_count controllers_count]`; the last block holds
//!   ⌈buttons_count/32⌉ integers of button bits (bit i = button i) and then the controllers
//!   (analog axes in [−1, 1]). FlyStick2: 6 buttons, 2 axes; FlyStick2+: 8 buttons, 3 axes.
//! * Unknown record types are ignored (newer DTracks add records); a malformed known record
//!   fails the whole frame with an error naming the line and field, because a half-parsed
//!   frame could pair one body's position with another's buttons.
//! * Lines end in LF, CR LF or CR; senders may append NUL bytes (C strings).

use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

use super::event::{DeviceId, DeviceKind, MAX_AXES, Pose, Tracking, TrackingEvent};

/// Largest datagram accepted; DTrack frames of a full lab (tens of bodies) stay under 8 KiB,
/// and anything near the UDP limit is not DTrack.
pub const MAX_DATAGRAM: usize = 32 * 1024;
/// Most devices one record may list; bounds the work a forged count can cause.
pub const MAX_DEVICES: u32 = 256;
/// Most buttons a FlyStick record may carry: one 32-bit word of button bits.
pub const MAX_BUTTONS: u32 = 32;
/// Tolerance of ‖RᵀR − I‖ (max norm) for a rotation matrix: DTrack prints 6 decimals, so an
/// honest matrix is off by ~1e-6; 1e-3 rejects garbage without rejecting rounding.
pub const ROTATION_TOLERANCE: f64 = 1e-3;
/// Seconds per day: `ts` wraps here.
pub const SECONDS_PER_DAY: f64 = 86_400.0;

/// The tracker→room transform (DESIGN.md §2: configuration, never guessed). A tracker point
/// `p` (tracker units) maps to `rotation · (p · metres_per_unit) + translation_m`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerToRoom {
    /// Rotation tracker → room, written row by row (as one reads a matrix).
    pub rotation_rows: [[f64; 3]; 3],
    /// Room-frame offset of the tracker origin, metres.
    pub translation_m: [f64; 3],
    /// Metres per tracker unit: DTrack sends millimetres.
    pub metres_per_unit: f64,
}

impl Default for TrackerToRoom {
    /// Identity rotation and offset, millimetres: right for a DTrack room calibrated with
    /// "Y up, Z towards the viewer", as DESIGN.md §2's room frame is.
    fn default() -> Self {
        Self {
            rotation_rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation_m: [0.0; 3],
            metres_per_unit: 1e-3,
        }
    }
}

/// Why a tracker→room transform cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransformError {
    #[error(
        "tracker_to_room.rotation_rows is not a rotation (‖RᵀR − I‖ = {error:.3e}, det = {det:.6})"
    )]
    NotRotation { error: f64, det: f64 },
    #[error("tracker_to_room.{field} holds a non-finite or non-positive value")]
    BadValue { field: &'static str },
}

impl TrackerToRoom {
    /// DTrack's factory room calibration has Z up; this maps it onto Y up (x stays, tracker
    /// Z → room Y, tracker Y → room −Z).
    #[must_use]
    pub fn z_up() -> Self {
        Self {
            rotation_rows: [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]],
            ..Self::default()
        }
    }

    /// The rotation as a matrix.
    #[must_use]
    pub fn rotation(&self) -> DMat3 {
        DMat3::from_cols_array_2d(&self.rotation_rows).transpose()
    }

    /// Checks that the rotation is a proper rotation and the numbers are usable.
    pub fn validate(&self) -> Result<(), TransformError> {
        if !(self.metres_per_unit.is_finite() && self.metres_per_unit > 0.0) {
            return Err(TransformError::BadValue {
                field: "metres_per_unit",
            });
        }
        if !self.translation_m.iter().all(|v| v.is_finite()) {
            return Err(TransformError::BadValue {
                field: "translation_m",
            });
        }
        let r = self.rotation();
        let error = orthonormality_error(&r);
        let det = r.determinant();
        if !(error < ROTATION_TOLERANCE && det > 0.0) {
            return Err(TransformError::NotRotation { error, det });
        }
        Ok(())
    }
}

/// Parser configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DtrackConfig {
    pub tracker_to_room: TrackerToRoom,
    /// Multiplies FlyStick controller i (i < 3) by this sign: sticks are mounted and
    /// configured differently between labs, and "push up = bigger FOV" is a user expectation.
    pub joystick_signs: [f64; 3],
}

impl Default for DtrackConfig {
    fn default() -> Self {
        Self {
            tracker_to_room: TrackerToRoom::default(),
            joystick_signs: [1.0; 3],
        }
    }
}

/// The timestamp a frame carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Timestamp {
    /// `ts`: seconds since 00:00 UTC, wraps every day.
    SinceMidnight(f64),
    /// `ts2`: seconds and microseconds since 1970-01-01 UTC.
    Unix { sec: u64, usec: u32 },
}

/// One standard body of a `6d` record.
#[derive(Clone, Debug, PartialEq)]
pub struct BodySample {
    pub id: u32,
    pub quality: f64,
    /// `None` when untracked.
    pub pose: Option<Pose>,
}

/// One FlyStick of a `6df2` record.
#[derive(Clone, Debug, PartialEq)]
pub struct FlystickSample {
    pub id: u32,
    pub quality: f64,
    /// `None` when untracked (quality −1, zero rotation); buttons and axes are still valid.
    pub pose: Option<Pose>,
    pub button_count: u32,
    /// Bit i = button i pressed; bit 0 is the trigger.
    pub buttons: u32,
    /// Controllers with the configured signs applied.
    pub axes: Vec<f64>,
}

/// Everything one datagram said.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct DtrackFrame {
    pub frame_counter: Option<u32>,
    pub timestamp: Option<Timestamp>,
    pub calibrated_bodies: Option<u32>,
    pub calibrated_flysticks: Option<u32>,
    pub bodies: Vec<BodySample>,
    pub flysticks: Vec<FlystickSample>,
}

/// A datagram that cannot be used, with the line (1-based, counting non-empty lines) at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("DTrack datagram, line {line}: {kind}")]
pub struct DtrackError {
    /// 0 for faults of the whole datagram (size, encoding).
    pub line: usize,
    pub kind: DtrackErrorKind,
}

/// What is wrong; each variant is one "kind" for counting and once-per-kind logging.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DtrackErrorKind {
    #[error("datagram of {len} bytes exceeds the {max}-byte limit")]
    Oversized { len: usize, max: usize },
    #[error("not ASCII text (byte 0x{byte:02x} at offset {offset})")]
    NotText { byte: u8, offset: usize },
    #[error("`{record}` field `{field}`: expected {expected}, found {found:?}")]
    BadToken {
        record: &'static str,
        field: &'static str,
        expected: &'static str,
        found: String,
    },
    #[error("`{record}` field `{field}`: the line ends early")]
    Missing {
        record: &'static str,
        field: &'static str,
    },
    #[error("`{record}` field `{field}`: {value} is not finite")]
    NonFinite {
        record: &'static str,
        field: &'static str,
        value: f64,
    },
    #[error("`{record}` field `{field}`: {value} is out of range {min}..={max}")]
    OutOfRange {
        record: &'static str,
        field: &'static str,
        value: f64,
        min: f64,
        max: f64,
    },
    #[error("`{record}` field `{field}`: {found} values, expected {expected}")]
    BlockLength {
        record: &'static str,
        field: &'static str,
        found: usize,
        expected: &'static str,
    },
    #[error("`{record}`: device id {id} appears twice")]
    DuplicateId { record: &'static str, id: u32 },
    #[error("`{record}` id {id}: rotation matrix is not a rotation (‖RᵀR − I‖ = {error:.2e})")]
    NotRotation {
        record: &'static str,
        id: u32,
        error: f64,
    },
    #[error("`{record}`: unexpected trailing text {found:?}")]
    Trailing { record: &'static str, found: String },
}

impl DtrackErrorKind {
    /// A short stable name per kind, for counters and once-per-kind logs.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Oversized { .. } => "dtrack_oversized",
            Self::NotText { .. } => "dtrack_not_text",
            Self::BadToken { .. } => "dtrack_bad_token",
            Self::Missing { .. } => "dtrack_missing_field",
            Self::NonFinite { .. } => "dtrack_non_finite",
            Self::OutOfRange { .. } => "dtrack_out_of_range",
            Self::BlockLength { .. } => "dtrack_block_length",
            Self::DuplicateId { .. } => "dtrack_duplicate_id",
            Self::NotRotation { .. } => "dtrack_not_rotation",
            Self::Trailing { .. } => "dtrack_trailing_text",
        }
    }
}

/// Parses one datagram. Pure: the midnight wrap of `ts` needs history and is handled by
/// [`DtrackDecoder`].
pub fn parse_datagram(data: &[u8], config: &DtrackConfig) -> Result<DtrackFrame, DtrackError> {
    let whole = |kind| DtrackError { line: 0, kind };
    if data.len() > MAX_DATAGRAM {
        return Err(whole(DtrackErrorKind::Oversized {
            len: data.len(),
            max: MAX_DATAGRAM,
        }));
    }
    // C senders may include the string terminator (and some pad with several).
    let end = data.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    let data = &data[..end];
    if let Some(offset) = data.iter().position(|&b| {
        !(b.is_ascii_graphic() || b == b' ' || b == b'\t' || b == b'\r' || b == b'\n')
    }) {
        return Err(whole(DtrackErrorKind::NotText {
            byte: data[offset],
            offset,
        }));
    }
    // Checked above: ASCII only.
    let text = std::str::from_utf8(data).map_err(|e| {
        whole(DtrackErrorKind::NotText {
            byte: data[e.valid_up_to()],
            offset: e.valid_up_to(),
        })
    })?;

    let mut frame = DtrackFrame::default();
    let lines = text
        .split(['\n', '\r'])
        .map(str::trim)
        .filter(|l| !l.is_empty());
    for (index, line) in lines.enumerate() {
        parse_line(line, config, &mut frame).map_err(|kind| DtrackError {
            line: index + 1,
            kind,
        })?;
    }
    Ok(frame)
}

fn parse_line(
    line: &str,
    config: &DtrackConfig,
    frame: &mut DtrackFrame,
) -> Result<(), DtrackErrorKind> {
    let (head, rest) = line.split_once([' ', '\t']).unwrap_or((line, ""));
    match head {
        "fr" => {
            let mut c = Cursor::new("fr", rest);
            frame.frame_counter = Some(c.uint("frame counter", u32::MAX)?);
            c.finish()
        }
        "ts" => {
            let mut c = Cursor::new("ts", rest);
            // 86400 itself appears for a leap second.
            let t = c.float_in("seconds since midnight", 0.0, SECONDS_PER_DAY + 1.0)?;
            frame.timestamp = Some(Timestamp::SinceMidnight(t));
            c.finish()
        }
        "ts2" => {
            let mut c = Cursor::new("ts2", rest);
            let sec = u64::from(c.uint("seconds", u32::MAX)?);
            let usec = c.uint("microseconds", 999_999)?;
            // Newer DTracks append further numbers (e.g. a latency); they are ignored, but they
            // must still be numbers.
            while c.peek().is_some() {
                c.float("ts2 extension")?;
            }
            frame.timestamp = Some(Timestamp::Unix { sec, usec });
            Ok(())
        }
        "6dcal" => {
            let mut c = Cursor::new("6dcal", rest);
            frame.calibrated_bodies = Some(c.uint("calibrated bodies", MAX_DEVICES)?);
            c.finish()
        }
        "6d" => parse_6d(rest, config, frame),
        "6df2" => parse_6df2(rest, config, frame),
        _ => Ok(()),
    }
}

fn parse_6d(
    rest: &str,
    config: &DtrackConfig,
    frame: &mut DtrackFrame,
) -> Result<(), DtrackErrorKind> {
    const R: &str = "6d";
    let mut c = Cursor::new(R, rest);
    let n = c.uint("body count", MAX_DEVICES)?;
    let mut bodies = Vec::with_capacity(n as usize);
    for _ in 0..n {
        c.open("[id quality]")?;
        let id = c.uint("body id", u32::MAX)?;
        let quality = c.float("quality")?;
        c.close("[id quality]")?;
        if bodies.iter().any(|b: &BodySample| b.id == id) {
            return Err(DtrackErrorKind::DuplicateId { record: R, id });
        }
        let position = c.position_block()?;
        let rot = c.rotation_block()?;
        let pose = make_pose(R, id, quality, position, &rot, config)?;
        bodies.push(BodySample { id, quality, pose });
    }
    c.finish()?;
    frame.bodies = bodies;
    Ok(())
}

fn parse_6df2(
    rest: &str,
    config: &DtrackConfig,
    frame: &mut DtrackFrame,
) -> Result<(), DtrackErrorKind> {
    const R: &str = "6df2";
    let mut c = Cursor::new(R, rest);
    let calibrated = c.uint("calibrated flysticks", MAX_DEVICES)?;
    let n = c.uint("flystick count", MAX_DEVICES)?;
    let mut sticks = Vec::with_capacity(n as usize);
    for _ in 0..n {
        c.open("[id quality buttons controllers]")?;
        let id = c.uint("flystick id", u32::MAX)?;
        let quality = c.float("quality")?;
        let button_count = c.uint("button count", MAX_BUTTONS)?;
        let axis_count = c.uint("controller count", MAX_AXES as u32)?;
        c.close("[id quality buttons controllers]")?;
        if sticks.iter().any(|s: &FlystickSample| s.id == id) {
            return Err(DtrackErrorKind::DuplicateId { record: R, id });
        }
        let position = c.position_block()?;
        let rot = c.rotation_block()?;
        c.open("[buttons controllers]")?;
        // ⌈count/32⌉ words; with MAX_BUTTONS = 32 that is at most one.
        let buttons = if button_count > 0 {
            let word = c.uint("button bits", u32::MAX)?;
            let mask = if button_count == 32 {
                u32::MAX
            } else {
                (1u32 << button_count) - 1
            };
            word & mask
        } else {
            0
        };
        let mut axes = Vec::with_capacity(axis_count as usize);
        for i in 0..axis_count as usize {
            let v = c.float_in("controller", -1.0, 1.0)?;
            let sign = config.joystick_signs.get(i).copied().unwrap_or(1.0);
            axes.push(v * sign);
        }
        c.close("[buttons controllers]")?;
        let pose = make_pose(R, id, quality, position, &rot, config)?;
        sticks.push(FlystickSample {
            id,
            quality,
            pose,
            button_count,
            buttons,
            axes,
        });
    }
    c.finish()?;
    frame.calibrated_flysticks = Some(calibrated);
    frame.flysticks = sticks;
    Ok(())
}

fn orthonormality_error(r: &DMat3) -> f64 {
    let e = r.transpose() * *r - DMat3::IDENTITY;
    e.to_cols_array()
        .iter()
        .fold(0.0_f64, |m, v| m.max(v.abs()))
}

/// Turns one record's numbers into a room pose, or `None` for an untracked device. The zero
/// matrix of an untracked device is checked *before* any quaternion is made.
fn make_pose(
    record: &'static str,
    id: u32,
    quality: f64,
    position: DVec3,
    rot_cols: &[f64; 9],
    config: &DtrackConfig,
) -> Result<Option<Pose>, DtrackErrorKind> {
    if quality < 0.0 || rot_cols.iter().all(|v| *v == 0.0) {
        return Ok(None);
    }
    let r = DMat3::from_cols_array(rot_cols);
    let error = orthonormality_error(&r);
    if !(error < ROTATION_TOLERANCE && r.determinant() > 0.0) {
        return Err(DtrackErrorKind::NotRotation { record, id, error });
    }
    Ok(Some(config.tracker_to_room.map_pose(position, r)))
}

/// A tokenizer over one record: tokens are `[`, `]` and runs of other non-space characters.
struct Cursor<'a> {
    record: &'static str,
    rest: &'a str,
}

impl<'a> Cursor<'a> {
    fn new(record: &'static str, rest: &'a str) -> Self {
        Self { record, rest }
    }

    fn peek(&mut self) -> Option<&'a str> {
        self.rest = self.rest.trim_start();
        let s = self.rest;
        let first = s.chars().next()?;
        if first == '[' || first == ']' {
            return Some(&s[..1]);
        }
        let end = s
            .find(|ch: char| ch.is_ascii_whitespace() || ch == '[' || ch == ']')
            .unwrap_or(s.len());
        Some(&s[..end])
    }

    fn next(&mut self, field: &'static str) -> Result<&'a str, DtrackErrorKind> {
        let tok = self.peek().ok_or(DtrackErrorKind::Missing {
            record: self.record,
            field,
        })?;
        self.rest = &self.rest[tok.len()..];
        Ok(tok)
    }

    fn bad(&self, field: &'static str, expected: &'static str, found: &str) -> DtrackErrorKind {
        DtrackErrorKind::BadToken {
            record: self.record,
            field,
            expected,
            // Bounded: the token goes into logs.
            found: found.chars().take(24).collect(),
        }
    }

    fn uint(&mut self, field: &'static str, max: u32) -> Result<u32, DtrackErrorKind> {
        let tok = self.next(field)?;
        let v: u64 = tok
            .parse()
            .map_err(|_| self.bad(field, "an unsigned integer", tok))?;
        if v > u64::from(max) {
            return Err(DtrackErrorKind::OutOfRange {
                record: self.record,
                field,
                value: v as f64,
                min: 0.0,
                max: f64::from(max),
            });
        }
        Ok(v as u32)
    }

    fn float(&mut self, field: &'static str) -> Result<f64, DtrackErrorKind> {
        let tok = self.next(field)?;
        // Rust also parses "inf"/"nan"; DTrack never writes them, so they are rejected below.
        let v: f64 = tok.parse().map_err(|_| self.bad(field, "a number", tok))?;
        if !v.is_finite() {
            return Err(DtrackErrorKind::NonFinite {
                record: self.record,
                field,
                value: v,
            });
        }
        Ok(v)
    }

    fn float_in(
        &mut self,
        field: &'static str,
        min: f64,
        max: f64,
    ) -> Result<f64, DtrackErrorKind> {
        let v = self.float(field)?;
        if !(min..=max).contains(&v) {
            return Err(DtrackErrorKind::OutOfRange {
                record: self.record,
                field,
                value: v,
                min,
                max,
            });
        }
        Ok(v)
    }

    fn open(&mut self, field: &'static str) -> Result<(), DtrackErrorKind> {
        let tok = self.next(field)?;
        if tok == "[" {
            Ok(())
        } else {
            Err(self.bad(field, "'['", tok))
        }
    }

    fn close(&mut self, field: &'static str) -> Result<(), DtrackErrorKind> {
        let tok = self.next(field)?;
        if tok == "]" {
            Ok(())
        } else {
            Err(self.bad(field, "']'", tok))
        }
    }

    /// Reads numbers up to the closing bracket into `out`, returning how many there were.
    fn block(&mut self, field: &'static str, out: &mut [f64]) -> Result<usize, DtrackErrorKind> {
        self.open(field)?;
        let mut n = 0;
        loop {
            if self.peek() == Some("]") {
                self.next(field)?;
                return Ok(n);
            }
            let v = self.float(field)?;
            if n == out.len() {
                return Err(DtrackErrorKind::BlockLength {
                    record: self.record,
                    field,
                    found: n + 1,
                    expected: "no more",
                });
            }
            out[n] = v;
            n += 1;
        }
    }

    fn position_block(&mut self) -> Result<DVec3, DtrackErrorKind> {
        let mut v = [0.0; 6];
        let n = self.block("[position]", &mut v)?;
        if n != 3 && n != 6 {
            return Err(DtrackErrorKind::BlockLength {
                record: self.record,
                field: "[position]",
                found: n,
                expected: "3 (or 6 with Euler angles)",
            });
        }
        Ok(DVec3::new(v[0], v[1], v[2]))
    }

    fn rotation_block(&mut self) -> Result<[f64; 9], DtrackErrorKind> {
        let mut v = [0.0; 9];
        let n = self.block("[rotation]", &mut v)?;
        if n != 9 {
            return Err(DtrackErrorKind::BlockLength {
                record: self.record,
                field: "[rotation]",
                found: n,
                expected: "9",
            });
        }
        Ok(v)
    }

    fn finish(&mut self) -> Result<(), DtrackErrorKind> {
        match self.peek() {
            None => Ok(()),
            Some(tok) => Err(DtrackErrorKind::Trailing {
                record: self.record,
                found: tok.chars().take(24).collect(),
            }),
        }
    }
}

/// Where event times come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeSource {
    /// The frame's `ts`/`ts2` when it has one (the tracker's measurement time, free of network
    /// jitter), else the receive time.
    #[default]
    Tracker,
    /// Always the receive time.
    Receive,
}

/// A stateful decoder: parses datagrams and turns them into events with continuous times
/// (the `ts` midnight wrap is undone).
#[derive(Clone, Debug)]
pub struct DtrackDecoder {
    config: DtrackConfig,
    time_source: TimeSource,
    last_ts: Option<f64>,
    day_offset: f64,
}

impl DtrackDecoder {
    #[must_use]
    pub fn new(config: DtrackConfig, time_source: TimeSource) -> Self {
        Self {
            config,
            time_source,
            last_ts: None,
            day_offset: 0.0,
        }
    }

    #[must_use]
    pub fn config(&self) -> &DtrackConfig {
        &self.config
    }

    /// Replaces the configuration (a calibration given after construction).
    pub fn set_config(&mut self, config: DtrackConfig) {
        self.config = config;
    }

    /// The continuous time of a `ts` value: a jump back by more than half a day is a wrap
    /// past midnight (DTrack frames are milliseconds apart, never hours).
    fn unwrap_ts(&mut self, ts: f64) -> f64 {
        let t = ts + self.day_offset;
        let t = match self.last_ts {
            Some(last) if t < last - SECONDS_PER_DAY / 2.0 => {
                self.day_offset += SECONDS_PER_DAY;
                ts + self.day_offset
            }
            _ => t,
        };
        self.last_ts = Some(t);
        t
    }

    /// Parses one datagram received at `receive_t` and appends its events to `out`.
    pub fn decode_into(
        &mut self,
        data: &[u8],
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
    ) -> Result<DtrackFrame, DtrackError> {
        let frame = parse_datagram(data, &self.config)?;
        let t = match (self.time_source, frame.timestamp) {
            (TimeSource::Tracker, Some(Timestamp::SinceMidnight(ts))) => self.unwrap_ts(ts),
            (TimeSource::Tracker, Some(Timestamp::Unix { sec, usec })) => {
                sec as f64 + f64::from(usec) * 1e-6
            }
            _ => receive_t,
        };
        let tracking = |pose: Option<Pose>| Some(pose.map_or(Tracking::Lost, Tracking::Tracked));
        for b in &frame.bodies {
            out.push(TrackingEvent {
                pose: tracking(b.pose),
                ..TrackingEvent::empty(t, DeviceId::new(DeviceKind::Body, b.id))
            });
        }
        for s in &frame.flysticks {
            out.push(TrackingEvent {
                pose: tracking(s.pose),
                buttons: Some(s.buttons),
                axes: Some(s.axes.clone()),
                ..TrackingEvent::empty(t, DeviceId::new(DeviceKind::Flystick, s.id))
            });
        }
        Ok(frame)
    }
}

/// Formats one FlyStick as a `6df2` line body (used by the synthetic session generator and
/// tests; the inverse of the parser up to printing precision).
#[must_use]
pub fn format_flystick_block(
    id: u32,
    pose_mm: Option<(DVec3, DMat3)>,
    button_count: u32,
    buttons: u32,
    axes: &[f64],
) -> String {
    use std::fmt::Write;
    let mut s = String::with_capacity(200);
    let quality = if pose_mm.is_some() { 1.0 } else { -1.0 };
    let _ = write!(s, "[{id} {quality:.3} {button_count} {}]", axes.len());
    match pose_mm {
        Some((p, r)) => {
            let _ = write!(s, "[{:.3} {:.3} {:.3}][", p.x, p.y, p.z);
            for (i, v) in r.to_cols_array().iter().enumerate() {
                let sep = if i == 0 { "" } else { " " };
                let _ = write!(s, "{sep}{v:.6}");
            }
            s.push(']');
        }
        None => {
            s.push_str("[0.000 0.000 0.000][0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000]");
        }
    }
    let _ = write!(s, "[{buttons}");
    for a in axes {
        let _ = write!(s, " {a:.6}");
    }
    s.push(']');
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;
    use proptest::prelude::*;

    const ID_ROT: &str =
        "[1.000000 0.000000 0.000000 0.000000 1.000000 0.000000 0.000000 0.000000 1.000000]";

    fn cfg() -> DtrackConfig {
        DtrackConfig::default()
    }

    fn parse(s: &str) -> Result<DtrackFrame, DtrackError> {
        parse_datagram(s.as_bytes(), &cfg())
    }

    fn flystick_line(q: &str, pos: &str, rot: &str, tail: &str) -> String {
        format!("6df2 1 1 [0 {q} 6 2][{pos}]{rot}{tail}")
    }

    #[test]
    fn full_frame_with_every_record() {
        let text = format!(
            "fr 21753\nts 39596.024831\n6dcal 2\n6d 1 [0 1.000][326.848 -187.216 109.921]{ID_ROT}\n{}\n",
            flystick_line("1.000", "100.0 1500.0 1000.0", ID_ROT, "[5 0.5 -0.25]")
        );
        let f = parse(&text).unwrap();
        assert_eq!(f.frame_counter, Some(21753));
        assert_eq!(f.timestamp, Some(Timestamp::SinceMidnight(39596.024831)));
        assert_eq!(f.calibrated_bodies, Some(2));
        assert_eq!(f.bodies.len(), 1);
        let p = f.bodies[0].pose.unwrap();
        // mm → m.
        assert!((p.position - DVec3::new(0.326848, -0.187216, 0.109921)).length() < 1e-12);
        let s = &f.flysticks[0];
        assert_eq!((s.button_count, s.buttons), (6, 5));
        assert_eq!(s.axes, vec![0.5, -0.25]);
        assert!((s.pose.unwrap().position - DVec3::new(0.1, 1.5, 1.0)).length() < 1e-12);
    }

    #[test]
    fn rotation_matrix_is_read_column_by_column() {
        // 90° about +Z: the first column is the image of x, i.e. (0, 1, 0).
        let rot = "[0 1 0 -1 0 0 0 0 1]";
        let f = parse(&format!("6d 1 [0 1.0][0 0 0]{rot}")).unwrap();
        let q = f.bodies[0].pose.unwrap().orientation;
        assert!((q * DVec3::X - DVec3::Y).length() < 1e-12);
        assert!((q * DVec3::Y + DVec3::X).length() < 1e-12);
    }

    #[test]
    fn line_endings_lf_crlf_and_cr_parse_alike() {
        let lf = format!("fr 1\n6d 1 [3 1.0][1 2 3]{ID_ROT}\n");
        let crlf = lf.replace('\n', "\r\n");
        let cr = lf.replace('\n', "\r");
        let a = parse(&lf).unwrap();
        assert_eq!(parse(&crlf).unwrap(), a);
        assert_eq!(parse(&cr).unwrap(), a);
    }

    #[test]
    fn trailing_nul_bytes_are_ignored() {
        let mut bytes = b"fr 7\n".to_vec();
        bytes.extend_from_slice(&[0, 0, 0]);
        let f = parse_datagram(&bytes, &cfg()).unwrap();
        assert_eq!(f.frame_counter, Some(7));
    }

    #[test]
    fn nul_byte_inside_the_text_fails_the_frame() {
        let e = parse_datagram(b"fr 7\0\nts 1.0", &cfg()).unwrap_err();
        assert_eq!(e.kind.name(), "dtrack_not_text");
    }

    #[test]
    fn six_value_position_block_drops_euler_angles() {
        let f = parse(&format!(
            "6d 1 [0 1.0][10 20 30 -160.86 -38.04 -118.44]{ID_ROT}"
        ))
        .unwrap();
        assert!(
            (f.bodies[0].pose.unwrap().position - DVec3::new(0.01, 0.02, 0.03)).length() < 1e-15
        );
    }

    #[test]
    fn four_value_position_block_is_an_error_naming_the_field() {
        let e = parse(&format!("fr 1\n6d 1 [0 1.0][10 20 30 40]{ID_ROT}")).unwrap_err();
        assert_eq!(e.line, 2);
        assert!(matches!(
            e.kind,
            DtrackErrorKind::BlockLength {
                field: "[position]",
                found: 4,
                ..
            }
        ));
        assert!(e.to_string().contains("line 2"));
    }

    #[test]
    fn body_id_is_taken_from_the_block_not_the_index() {
        let f = parse(&format!(
            "6d 2 [4 1.0][0 0 0]{ID_ROT} [9 0.5][1 1 1]{ID_ROT}"
        ))
        .unwrap();
        let ids: Vec<u32> = f.bodies.iter().map(|b| b.id).collect();
        assert_eq!(ids, vec![4, 9]);
    }

    #[test]
    fn duplicate_ids_fail_the_frame() {
        let e = parse(&format!(
            "6d 2 [4 1.0][0 0 0]{ID_ROT} [4 0.5][1 1 1]{ID_ROT}"
        ))
        .unwrap_err();
        assert!(matches!(e.kind, DtrackErrorKind::DuplicateId { id: 4, .. }));
    }

    #[test]
    fn untracked_flystick_keeps_buttons_but_has_no_pose() {
        let zero =
            "[0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000]";
        let f = parse(&flystick_line("-1.000", "0 0 0", zero, "[1 0.0 0.8]")).unwrap();
        let s = &f.flysticks[0];
        assert_eq!(s.pose, None);
        assert_eq!(s.buttons, 1);
        assert_eq!(s.axes, vec![0.0, 0.8]);
        let mut out = Vec::new();
        let mut d = DtrackDecoder::new(cfg(), TimeSource::Receive);
        d.decode_into(
            flystick_line("-1.000", "0 0 0", zero, "[1 0.0 0.8]").as_bytes(),
            3.0,
            &mut out,
        )
        .unwrap();
        assert_eq!(out[0].pose, Some(Tracking::Lost));
        assert_eq!(out[0].buttons, Some(1));
    }

    #[test]
    fn zero_rotation_with_positive_quality_is_still_untracked() {
        let zero = "[0 0 0 0 0 0 0 0 0]";
        let f = parse(&format!("6d 1 [0 1.0][1 2 3]{zero}")).unwrap();
        assert_eq!(f.bodies[0].pose, None);
    }

    #[test]
    fn flystick2_plus_has_eight_buttons_and_three_axes() {
        let f = parse(&format!(
            "6df2 1 1 [0 1.0 8 3][0 0 0]{ID_ROT}[255 0.1 0.2 -0.3]"
        ))
        .unwrap();
        let s = &f.flysticks[0];
        assert_eq!((s.button_count, s.buttons), (8, 255));
        assert_eq!(s.axes, vec![0.1, 0.2, -0.3]);
    }

    #[test]
    fn button_bits_beyond_the_count_are_masked() {
        let f = parse(&format!("6df2 1 1 [0 1.0 6 2][0 0 0]{ID_ROT}[255 0 0]")).unwrap();
        assert_eq!(f.flysticks[0].buttons, 0b11_1111);
    }

    #[test]
    fn joystick_signs_apply_per_axis() {
        let config = DtrackConfig {
            joystick_signs: [-1.0, 1.0, -1.0],
            ..cfg()
        };
        let f = parse_datagram(
            format!("6df2 1 1 [0 1.0 8 3][0 0 0]{ID_ROT}[0 0.5 0.5 0.5]").as_bytes(),
            &config,
        )
        .unwrap();
        assert_eq!(f.flysticks[0].axes, vec![-0.5, 0.5, -0.5]);
    }

    #[test]
    fn tracker_to_room_transform_applies_rotation_translation_and_units() {
        let config = DtrackConfig {
            tracker_to_room: TrackerToRoom {
                translation_m: [1.0, 0.0, 0.0],
                ..TrackerToRoom::z_up()
            },
            ..cfg()
        };
        config.tracker_to_room.validate().unwrap();
        // Tracker Z up: the point 1 m above the tracker origin is room (0, 1, 0) + offset.
        let f = parse_datagram(
            format!("6d 1 [0 1.0][0 0 1000]{ID_ROT}").as_bytes(),
            &config,
        )
        .unwrap();
        let p = f.bodies[0].pose.unwrap();
        assert!((p.position - DVec3::new(1.0, 1.0, 0.0)).length() < 1e-12);
        // A body aligned with the tracker frame points (−Z) at tracker −Z = room −Y.
        assert!((p.orientation * DVec3::NEG_Z - DVec3::NEG_Y).length() < 1e-12);
    }

    #[test]
    fn mirror_transform_is_rejected() {
        let t = TrackerToRoom {
            rotation_rows: [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            ..TrackerToRoom::default()
        };
        assert!(matches!(
            t.validate(),
            Err(TransformError::NotRotation { .. })
        ));
    }

    #[test]
    fn non_rotation_matrix_fails_the_frame() {
        let e = parse("fr 1\n6d 1 [0 1.0][0 0 0][2 0 0 0 1 0 0 0 1]").unwrap_err();
        assert!(matches!(e.kind, DtrackErrorKind::NotRotation { id: 0, .. }));
    }

    #[test]
    fn unknown_lines_are_ignored() {
        let f = parse("fr 3\n3d 2 [1 1.0][1 2 3] [2 1.0][4 5 6]\n6dmt2 whatever\nfr2 9").unwrap();
        assert_eq!(f.frame_counter, Some(3));
    }

    #[test]
    fn nan_and_infinity_are_rejected() {
        for bad in ["nan", "inf", "-inf", "infinity", "NaN"] {
            let e = parse(&format!("6d 1 [0 1.0][{bad} 0 0]{ID_ROT}")).unwrap_err();
            assert_eq!(e.kind.name(), "dtrack_non_finite", "{bad}");
        }
    }

    #[test]
    fn huge_counts_are_rejected_before_any_allocation() {
        let e = parse("6d 4000000000 [0 1.0]").unwrap_err();
        assert_eq!(e.kind.name(), "dtrack_out_of_range");
        let e = parse("6d 99999999999999999999999").unwrap_err();
        assert_eq!(e.kind.name(), "dtrack_bad_token");
        let e = parse(&format!("6df2 1 1 [0 1.0 33 2][0 0 0]{ID_ROT}[0 0 0]")).unwrap_err();
        assert!(matches!(
            e.kind,
            DtrackErrorKind::OutOfRange {
                field: "button count",
                ..
            }
        ));
    }

    #[test]
    fn count_larger_than_the_blocks_present_fails() {
        let e = parse(&format!("6d 2 [0 1.0][0 0 0]{ID_ROT}")).unwrap_err();
        assert!(matches!(e.kind, DtrackErrorKind::Missing { .. }));
    }

    #[test]
    fn trailing_text_on_a_known_record_fails() {
        let e = parse("fr 1 2").unwrap_err();
        assert_eq!(e.kind.name(), "dtrack_trailing_text");
    }

    #[test]
    fn stick_deflection_outside_unit_range_fails() {
        let e = parse(&format!("6df2 1 1 [0 1.0 6 2][0 0 0]{ID_ROT}[0 1.5 0]")).unwrap_err();
        assert!(matches!(
            e.kind,
            DtrackErrorKind::OutOfRange {
                field: "controller",
                ..
            }
        ));
    }

    #[test]
    fn oversized_datagram_is_rejected() {
        let big = vec![b' '; MAX_DATAGRAM + 1];
        let e = parse_datagram(&big, &cfg()).unwrap_err();
        assert_eq!((e.line, e.kind.name()), (0, "dtrack_oversized"));
    }

    #[test]
    fn ts2_gives_unix_seconds_and_microseconds_and_tolerates_extensions() {
        let f = parse("ts2 1700000000 250000").unwrap();
        assert_eq!(
            f.timestamp,
            Some(Timestamp::Unix {
                sec: 1_700_000_000,
                usec: 250_000
            })
        );
        let f = parse("ts2 1700000000 250000 1200").unwrap();
        assert!(f.timestamp.is_some());
        assert!(parse("ts2 1700000000 1000000").is_err());
        let mut d = DtrackDecoder::new(cfg(), TimeSource::Tracker);
        let mut out = Vec::new();
        d.decode_into(
            format!("ts2 1700000000 250000\n6d 1 [0 1.0][0 0 0]{ID_ROT}").as_bytes(),
            0.0,
            &mut out,
        )
        .unwrap();
        assert!((out[0].t - 1_700_000_000.25).abs() < 1e-6);
    }

    #[test]
    fn ts_midnight_wrap_keeps_time_increasing() {
        let mut d = DtrackDecoder::new(cfg(), TimeSource::Tracker);
        let mut times = Vec::new();
        for ts in [86399.98, 86399.99, 0.0, 0.01, 0.02] {
            let mut out = Vec::new();
            d.decode_into(
                format!("ts {ts}\n6d 1 [0 1.0][0 0 0]{ID_ROT}").as_bytes(),
                0.0,
                &mut out,
            )
            .unwrap();
            times.push(out[0].t);
        }
        for w in times.windows(2) {
            assert!(w[1] > w[0] && w[1] - w[0] < 0.011, "{times:?}");
        }
        assert!((times[4] - (SECONDS_PER_DAY + 0.02)).abs() < 1e-9);
    }

    #[test]
    fn ts_out_of_day_range_fails() {
        assert!(parse("ts 90000.0").is_err());
        assert!(parse("ts -1.0").is_err());
    }

    #[test]
    fn receive_time_is_used_without_timestamp_or_when_configured() {
        let text = format!("ts 100.0\n6d 1 [0 1.0][0 0 0]{ID_ROT}");
        let mut out = Vec::new();
        DtrackDecoder::new(cfg(), TimeSource::Receive)
            .decode_into(text.as_bytes(), 7.5, &mut out)
            .unwrap();
        assert_eq!(out[0].t, 7.5);
    }

    #[test]
    fn formatted_flystick_parses_back() {
        let r = DMat3::from_quat(DQuat::from_euler(glam::EulerRot::YXZ, 0.3, -0.2, 0.1));
        let line = format!(
            "6df2 1 1 {}",
            format_flystick_block(
                0,
                Some((DVec3::new(10.0, 1500.0, 900.0), r)),
                6,
                3,
                &[0.25, -1.0]
            )
        );
        let f = parse(&line).unwrap();
        let s = &f.flysticks[0];
        let q = s.pose.unwrap().orientation;
        assert!(q.angle_between(DQuat::from_mat3(&r)) < 1e-5);
        assert_eq!(s.axes, vec![0.25, -1.0]);
        let lost = format!(
            "6df2 1 1 {}",
            format_flystick_block(0, None, 8, 1, &[0.0, 0.0, 0.0])
        );
        assert_eq!(parse(&lost).unwrap().flysticks[0].pose, None);
    }

    proptest! {
        #[test]
        fn arbitrary_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..512)) {
            let _ = parse_datagram(&data, &cfg());
        }

        #[test]
        fn mutated_valid_frames_never_panic_and_poses_stay_valid(
            cut in 0usize..400, byte in any::<u8>(), at in 0usize..400,
        ) {
            let mut text = format!("fr 1\nts 5.0\n{}", flystick_line("1.0", "1 2 3", ID_ROT, "[3 0.5 0.5]")).into_bytes();
            if at < text.len() { text[at] = byte; }
            text.truncate(cut.min(text.len()));
            if let Ok(f) = parse_datagram(&text, &cfg()) {
                for s in &f.flysticks {
                    prop_assert!(s.pose.is_none_or(|p| p.is_valid()));
                    prop_assert!(s.axes.iter().all(|a| a.is_finite()));
                }
            }
        }
    }
}
