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
//!
//! The files: the room transform ([`TrackerToRoom`], `transform.rs`), this file's record
//! parser over the lexer of bracketed blocks (`lexer.rs`), the decoder that turns frames into
//! events (`decoder.rs`) and the writer of `6df2` blocks the synthesiser uses (`writer.rs`).

mod decoder;
mod lexer;
#[cfg(test)]
mod tests;
mod transform;
mod writer;

use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

use super::event::{DeviceId, DeviceKind, MAX_AXES, Pose, Tracking, TrackingEvent};
pub use decoder::{DtrackDecoder, TimeSource};
use lexer::Cursor;
use transform::orthonormality_error;
pub use transform::{ROTATION_TOLERANCE, TrackerToRoom, TransformError};
pub use writer::format_flystick_block;

/// Largest datagram accepted; DTrack frames of a full lab (tens of bodies) stay under 8 KiB,
/// and anything near the UDP limit is not DTrack.
pub const MAX_DATAGRAM: usize = 32 * 1024;
/// Most devices one record may list; bounds the work a forged count can cause.
pub const MAX_DEVICES: u32 = 256;
/// Most buttons a FlyStick record may carry: one 32-bit word of button bits.
pub const MAX_BUTTONS: u32 = 32;

/// Seconds per day: `ts` wraps here.
pub const SECONDS_PER_DAY: f64 = 86_400.0;

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
