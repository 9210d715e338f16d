//! The VRPN wire format, as VRPN 07.38 writes it (`vrpn_Connection.C`, `vrpn_Tracker.C`,
//! `vrpn_Button.C`, `vrpn_Analog.C`) and as the real server bytes in `tests/data/vrpn/` show
//! it: the cookie, the message header and framing, and the payloads a tracking client needs.
//! Everything here is pure (no state, no I/O); [`super::decoder`] keeps the per-connection
//! state (id tables, partial reads) on top of it.

use std::fmt;

/// Length of the cookie both sides send first.
pub const COOKIE_LEN: usize = 24;
/// What this client writes in its cookie (VRPN's `vrpn_MAGIC`).
pub const MAGIC: &[u8] = b"vrpn: ver. 07.38";
/// What a peer's cookie must start with: VRPN compares up to the last `.` of its template, so
/// only the major version must match (a 07.35 client talks to a 07.38 server).
pub const MAGIC_MAJOR: &[u8] = b"vrpn: ver. 07.";
/// Length of a message header.
pub const HEADER_LEN: usize = 24;
/// Payloads are NUL padded to a multiple of this (`vrpn_ALIGN`).
pub const ALIGN: usize = 8;
/// Longest message accepted (header + payload). VRPN's own TCP buffer is
/// `vrpn_CONNECTION_TCP_BUFLEN` = 64 000 bytes, so no real server sends a longer one; a longer
/// stated length is garbage, and accepting it would let one header make the reassembly buffer
/// grow.
pub const MAX_MESSAGE_LEN: usize = 64_000;
/// Sender and type ids are indices below this (`vrpn_CONNECTION_MAX_SENDERS` and `_TYPES`).
pub const MAX_IDS: usize = 2000;
/// Longest sender or type name, NUL included (VRPN's `cName` is `char[100]`).
pub const MAX_NAME_LEN: usize = 100;
/// Most buttons one Button States message may list (`vrpn_BUTTON_MAX_BUTTONS`).
pub const MAX_BUTTONS: usize = 256;
/// Most channels one Analog Channel message may carry (`vrpn_CHANNEL_MAX`).
pub const MAX_CHANNELS: usize = 128;
/// VRPN's well-known port (`vrpn_DEFAULT_LISTEN_PORT_NO`), TCP and UDP.
pub const DEFAULT_PORT: u16 = 3883;
/// How far a Pos_Quat quaternion's norm may be from 1. vrpn_Tracker_DTrack does not normalise
/// (its quaternions are up to ~3.5e-7 off, from DTrack's 6-decimal matrix); 1e-3 rejects
/// garbage without rejecting rounding, as DTrack's rotation check does.
pub const QUATERNION_TOLERANCE: f64 = 1e-3;

/// System message types (negative type ids; the same on every connection).
pub mod system {
    /// `sender` field = the id described; payload u32 n + name + NUL.
    pub const SENDER_DESCRIPTION: i32 = -1;
    /// `sender` field = the id described; payload u32 n + name + NUL.
    pub const TYPE_DESCRIPTION: i32 = -2;
    /// `sender` field = the UDP port to send to; payload the host + NUL.
    pub const UDP_DESCRIPTION: i32 = -3;
    /// Asks the peer to log; ignored by this client.
    pub const LOG_DESCRIPTION: i32 = -4;
    /// The peer is dropping the connection; the stream's end follows.
    pub const DISCONNECT: i32 = -5;
}

/// A message time stamp (a `struct timeval`: seconds and microseconds since 1970).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct VrpnTime {
    pub sec: u32,
    pub usec: u32,
}

impl VrpnTime {
    #[must_use]
    pub const fn new(sec: u32, usec: u32) -> Self {
        Self { sec, usec }
    }

    /// Seconds as f64 (microsecond resolution survives: 2^53 µs is 285 years).
    #[must_use]
    pub fn seconds(self) -> f64 {
        f64::from(self.sec) + f64::from(self.usec) * 1e-6
    }

    /// VRPN's "no time": vrpn_Button sends its connect-time States message with time 0.
    #[must_use]
    pub fn is_zero(self) -> bool {
        self.sec == 0 && self.usec == 0
    }

    /// The time stamp nearest `seconds` (≥ 0; saturating), for test servers and benchmarks.
    #[must_use]
    pub fn from_seconds(seconds: f64) -> Self {
        let s = seconds.max(0.0);
        let mut sec = s.floor();
        let mut usec = ((s - sec) * 1e6).round();
        if usec >= 1e6 {
            sec += 1.0;
            usec = 0.0;
        }
        Self {
            sec: sec.min(f64::from(u32::MAX)) as u32,
            usec: usec as u32,
        }
    }
}

impl fmt::Display for VrpnTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:06}", self.sec, self.usec)
    }
}

/// A message header (big-endian on the wire).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    /// 24 + payload length, padding not included.
    pub len: u32,
    pub time: VrpnTime,
    /// The sender's id on the peer's side (for descriptions: the id described).
    pub sender: i32,
    /// The type's id on the peer's side; negative for system messages.
    pub kind: i32,
    pub seq: u32,
}

impl Header {
    /// Reads a header from the first 24 bytes of `b`; `None` when `b` is shorter.
    #[must_use]
    pub fn read(b: &[u8]) -> Option<Self> {
        let b: &[u8; HEADER_LEN] = b.get(..HEADER_LEN)?.try_into().ok()?;
        let u = |i: usize| u32::from_be_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        Some(Self {
            len: u(0),
            time: VrpnTime::new(u(4), u(8)),
            sender: u(12) as i32,
            kind: u(16) as i32,
            seq: u(20),
        })
    }

    /// Checks the stated length against the header size and [`MAX_MESSAGE_LEN`].
    pub fn check_len(&self) -> Result<(), VrpnError> {
        let len = self.len as usize;
        if len < HEADER_LEN {
            Err(VrpnError::LengthTooSmall { len: self.len })
        } else if len > MAX_MESSAGE_LEN {
            Err(VrpnError::LengthTooLarge { len: self.len })
        } else {
            Ok(())
        }
    }

    /// Payload bytes, padding not included (call after [`Self::check_len`]).
    #[must_use]
    pub fn payload_len(&self) -> usize {
        (self.len as usize).saturating_sub(HEADER_LEN)
    }

    /// Bytes the message occupies on the wire: header + payload + padding.
    #[must_use]
    pub fn wire_len(&self) -> usize {
        HEADER_LEN + padded(self.payload_len())
    }
}

/// `n` rounded up to a multiple of [`ALIGN`].
#[must_use]
pub const fn padded(n: usize) -> usize {
    n.div_ceil(ALIGN) * ALIGN
}

/// What a cookie said.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Cookie {
    /// `MM.mm`, e.g. `07.38`.
    pub version: String,
}

/// Checks a peer's cookie: it must start with [`MAGIC_MAJOR`] (the major version must match).
pub fn check_cookie(bytes: &[u8; COOKIE_LEN]) -> Result<Cookie, VrpnError> {
    let text_end = bytes.iter().position(|&b| b == 0).unwrap_or(COOKIE_LEN);
    let text = &bytes[..text_end];
    // Bounded and printable: the text goes into logs.
    let shown = || {
        String::from_utf8_lossy(text)
            .chars()
            .take(COOKIE_LEN)
            .collect()
    };
    const PREFIX: &[u8] = b"vrpn: ver. ";
    if !text.starts_with(PREFIX) {
        return Err(VrpnError::BadCookie { found: shown() });
    }
    let version: String = String::from_utf8_lossy(&text[PREFIX.len()..])
        .chars()
        .take_while(|c| !c.is_whitespace())
        .collect();
    if !text.starts_with(MAGIC_MAJOR) {
        return Err(VrpnError::Version { found: version });
    }
    Ok(Cookie { version })
}

/// The message types this client decodes, matched by name (ids differ per side and
/// connection; names do not).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TypeKind {
    PosQuat,
    Velocity,
    Acceleration,
    ButtonChange,
    ButtonStates,
    AnalogChannel,
    /// A described type this client does not decode (To_Room, text messages, …).
    Other,
}

impl TypeKind {
    const NAMES: [(TypeKind, &'static str); 6] = [
        (TypeKind::PosQuat, "vrpn_Tracker Pos_Quat"),
        (TypeKind::Velocity, "vrpn_Tracker Velocity"),
        (TypeKind::Acceleration, "vrpn_Tracker Acceleration"),
        (TypeKind::ButtonChange, "vrpn_Button Change"),
        (TypeKind::ButtonStates, "vrpn_Button States"),
        (TypeKind::AnalogChannel, "vrpn_Analog Channel"),
    ];

    /// The kind of a type name as VRPN describes it.
    #[must_use]
    pub fn from_name(name: &str) -> Self {
        Self::NAMES
            .iter()
            .find(|(_, n)| *n == name)
            .map_or(TypeKind::Other, |(k, _)| *k)
    }

    /// The VRPN type name (`"?"` for [`TypeKind::Other`]).
    #[must_use]
    pub fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(k, _)| *k == self)
            .map_or("?", |(_, n)| n)
    }
}

/// `vrpn_Tracker Pos_Quat`: position (tracker units; metres for vrpn_Tracker_DTrack) and
/// orientation as received (x, y, z, w; not normalised).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PosQuat {
    pub sensor: u32,
    pub pos: [f64; 3],
    pub quat_xyzw: [f64; 4],
}

/// `vrpn_Tracker Velocity` / `Acceleration`: a vector, a quaternion and its interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackerRate {
    pub sensor: u32,
    pub vector: [f64; 3],
    pub quat_xyzw: [f64; 4],
    pub dt: f64,
}

/// A decoded payload.
#[derive(Clone, Debug, PartialEq)]
pub enum Body {
    SenderDescription {
        id: i32,
        name: String,
    },
    TypeDescription {
        id: i32,
        name: String,
    },
    /// The peer's UDP port and host (a server sends its own; nothing to do for a client).
    UdpDescription {
        port: i32,
        host: String,
    },
    LogDescription,
    Disconnect,
    PosQuat(PosQuat),
    Velocity(TrackerRate),
    Acceleration(TrackerRate),
    ButtonChange {
        button: u32,
        pressed: bool,
    },
    /// One state per button, from button 0.
    ButtonStates(Vec<bool>),
    /// One value per channel, from channel 0.
    Analog(Vec<f64>),
    /// A described type this client does not decode.
    Other,
}

/// What is wrong with VRPN input; each variant is one kind for counting and once-per-kind
/// logging ([`VrpnError::name`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VrpnError {
    #[error("cookie {found:?} is not a VRPN cookie (expected \"vrpn: ver. 07.xx  <log mode>\")")]
    BadCookie { found: String },
    #[error(
        "peer speaks VRPN {found:?}; this client speaks 07.38 and needs the same major version (07)"
    )]
    Version { found: String },
    #[error("message length {len} is below the 24-byte header")]
    LengthTooSmall { len: u32 },
    #[error("message length {len} exceeds the {MAX_MESSAGE_LEN}-byte maximum")]
    LengthTooLarge { len: u32 },
    #[error("{what} ends after {have} of its {need} bytes")]
    Truncated {
        what: &'static str,
        have: usize,
        need: usize,
    },
    #[error("{type_name} payload of {len} bytes, expected {expected}")]
    PayloadLength {
        type_name: &'static str,
        len: usize,
        expected: usize,
    },
    #[error("{type_name} {field} = {value} is not finite")]
    NonFinite {
        type_name: &'static str,
        field: &'static str,
        value: f64,
    },
    #[error("{type_name} {field} = {value} is out of range {range}")]
    OutOfRange {
        type_name: &'static str,
        field: &'static str,
        value: f64,
        range: &'static str,
    },
    #[error(
        "Pos_Quat of sensor {sensor}: quaternion norm {norm} is not 1 (±{QUATERNION_TOLERANCE})"
    )]
    BadQuaternion { sensor: u32, norm: f64 },
    #[error("{what} description of id {id}: {reason}")]
    BadDescription {
        what: &'static str,
        id: i32,
        reason: &'static str,
    },
    #[error("{what} id {id} is outside 0..{MAX_IDS}")]
    IdOutOfRange { what: &'static str, id: i32 },
    #[error("{what} id {id} was described as {old:?} and now as {new:?}; the first name is kept")]
    Redefined {
        what: &'static str,
        id: i32,
        old: String,
        new: String,
    },
    #[error("sender id {id} was never described")]
    UnknownSender { id: i32 },
    #[error("type id {id} was never described")]
    UnknownType { id: i32 },
    #[error("system message type {id} is not one VRPN 07.38 defines (-1 to -5)")]
    UnknownSystemType { id: i32 },
    #[error("time stamp {sec} s {usec} µs has 1 000 000 or more microseconds")]
    BadTime { sec: u32, usec: u32 },
}

impl VrpnError {
    /// A short stable name per kind, for counters and once-per-kind logs.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::BadCookie { .. } => "vrpn_bad_cookie",
            Self::Version { .. } => "vrpn_version_mismatch",
            Self::LengthTooSmall { .. } => "vrpn_length_too_small",
            Self::LengthTooLarge { .. } => "vrpn_length_too_large",
            Self::Truncated { .. } => "vrpn_truncated",
            Self::PayloadLength { .. } => "vrpn_bad_payload_length",
            Self::NonFinite { .. } => "vrpn_non_finite",
            Self::OutOfRange { .. } => "vrpn_out_of_range",
            Self::BadQuaternion { .. } => "vrpn_bad_quaternion",
            Self::BadDescription { .. } => "vrpn_bad_description",
            Self::IdOutOfRange { .. } => "vrpn_id_out_of_range",
            Self::Redefined { .. } => "vrpn_redefined_id",
            Self::UnknownSender { .. } => "vrpn_unknown_sender",
            Self::UnknownType { .. } => "vrpn_unknown_type",
            Self::UnknownSystemType { .. } => "vrpn_unknown_system_type",
            Self::BadTime { .. } => "vrpn_bad_time",
        }
    }
}

/// Big-endian reads from a payload whose length was checked first.
struct Payload<'a> {
    b: &'a [u8],
    at: usize,
}

impl Payload<'_> {
    fn i32(&mut self) -> i32 {
        let v = i32::from_be_bytes(self.b[self.at..self.at + 4].try_into().unwrap_or([0; 4]));
        self.at += 4;
        v
    }

    fn f64(&mut self) -> f64 {
        let v = f64::from_be_bytes(self.b[self.at..self.at + 8].try_into().unwrap_or([0; 8]));
        self.at += 8;
        v
    }
}

fn exact(type_name: &'static str, payload: &[u8], expected: usize) -> Result<(), VrpnError> {
    if payload.len() == expected {
        Ok(())
    } else {
        Err(VrpnError::PayloadLength {
            type_name,
            len: payload.len(),
            expected,
        })
    }
}

fn finite(type_name: &'static str, field: &'static str, v: f64) -> Result<f64, VrpnError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(VrpnError::NonFinite {
            type_name,
            field,
            value: v,
        })
    }
}

fn sensor_of(type_name: &'static str, v: i32) -> Result<u32, VrpnError> {
    u32::try_from(v).map_err(|_| VrpnError::OutOfRange {
        type_name,
        field: "sensor",
        value: f64::from(v),
        range: "0..",
    })
}

/// `u32 n` + name + NUL, n counting the NUL (`vrpn_Endpoint::pack_sender_description`).
fn description(what: &'static str, id: i32, payload: &[u8]) -> Result<String, VrpnError> {
    let bad = |reason| VrpnError::BadDescription { what, id, reason };
    if !(0..MAX_IDS as i64).contains(&i64::from(id)) {
        return Err(VrpnError::IdOutOfRange { what, id });
    }
    let n = payload
        .get(..4)
        .map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as usize)
        .ok_or(bad("payload shorter than its 4-byte name length"))?;
    if n == 0 || n > MAX_NAME_LEN {
        return Err(bad("name length is 0 or longer than VRPN's 100-byte names"));
    }
    if payload.len() != 4 + n {
        return Err(bad("name length does not match the payload length"));
    }
    let name = &payload[4..4 + n - 1];
    if payload[4 + n - 1] != 0 || name.contains(&0) {
        return Err(bad("name is not one NUL-terminated string"));
    }
    let name = std::str::from_utf8(name).map_err(|_| bad("name is not UTF-8"))?;
    Ok(name.to_owned())
}

/// A NUL-terminated host name (UDP description payload).
fn c_string(payload: &[u8]) -> String {
    let end = payload
        .iter()
        .position(|&b| b == 0)
        .unwrap_or(payload.len());
    String::from_utf8_lossy(&payload[..end])
        .chars()
        .take(64)
        .collect()
}

fn state(type_name: &'static str, v: i32) -> Result<bool, VrpnError> {
    match v {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err(VrpnError::OutOfRange {
            type_name,
            field: "button state",
            value: f64::from(v),
            range: "0 or 1",
        }),
    }
}

/// Decodes a system message (negative `header.kind`).
pub fn decode_system(header: &Header, payload: &[u8]) -> Result<Body, VrpnError> {
    match header.kind {
        system::SENDER_DESCRIPTION => Ok(Body::SenderDescription {
            id: header.sender,
            name: description("sender", header.sender, payload)?,
        }),
        system::TYPE_DESCRIPTION => Ok(Body::TypeDescription {
            id: header.sender,
            name: description("type", header.sender, payload)?,
        }),
        system::UDP_DESCRIPTION => Ok(Body::UdpDescription {
            port: header.sender,
            host: c_string(payload),
        }),
        system::LOG_DESCRIPTION => Ok(Body::LogDescription),
        system::DISCONNECT => Ok(Body::Disconnect),
        id => Err(VrpnError::UnknownSystemType { id }),
    }
}

/// Decodes the payload of a device message whose type is `kind`. Every number is checked:
/// lengths exactly as VRPN packs them, counts within VRPN's limits, floats finite,
/// quaternions of unit length (±[`QUATERNION_TOLERANCE`]).
pub fn decode_payload(kind: TypeKind, payload: &[u8]) -> Result<Body, VrpnError> {
    let mut p = Payload { b: payload, at: 0 };
    match kind {
        TypeKind::PosQuat => {
            const T: &str = "Pos_Quat";
            exact(T, payload, 64)?;
            let sensor = sensor_of(T, p.i32())?;
            let _pad = p.i32();
            let mut pos = [0.0; 3];
            for v in &mut pos {
                *v = finite(T, "position", p.f64())?;
            }
            let mut quat_xyzw = [0.0; 4];
            for v in &mut quat_xyzw {
                *v = finite(T, "quaternion", p.f64())?;
            }
            let norm = quat_xyzw.iter().map(|v| v * v).sum::<f64>().sqrt();
            if (norm - 1.0).abs() > QUATERNION_TOLERANCE {
                return Err(VrpnError::BadQuaternion { sensor, norm });
            }
            Ok(Body::PosQuat(PosQuat {
                sensor,
                pos,
                quat_xyzw,
            }))
        }
        TypeKind::Velocity | TypeKind::Acceleration => {
            let t = if kind == TypeKind::Velocity {
                "Velocity"
            } else {
                "Acceleration"
            };
            exact(t, payload, 72)?;
            let sensor = sensor_of(t, p.i32())?;
            let _pad = p.i32();
            let mut vector = [0.0; 3];
            for v in &mut vector {
                *v = finite(t, "vector", p.f64())?;
            }
            let mut quat_xyzw = [0.0; 4];
            for v in &mut quat_xyzw {
                *v = finite(t, "quaternion", p.f64())?;
            }
            let dt = finite(t, "dt", p.f64())?;
            let rate = TrackerRate {
                sensor,
                vector,
                quat_xyzw,
                dt,
            };
            Ok(if kind == TypeKind::Velocity {
                Body::Velocity(rate)
            } else {
                Body::Acceleration(rate)
            })
        }
        TypeKind::ButtonChange => {
            const T: &str = "Button Change";
            exact(T, payload, 8)?;
            let button = p.i32();
            let button = u32::try_from(button)
                .ok()
                .filter(|b| (*b as usize) < MAX_BUTTONS)
                .ok_or(VrpnError::OutOfRange {
                    type_name: T,
                    field: "button",
                    value: f64::from(button),
                    range: "0..256",
                })?;
            let pressed = state(T, p.i32())?;
            Ok(Body::ButtonChange { button, pressed })
        }
        TypeKind::ButtonStates => {
            const T: &str = "Button States";
            if payload.len() < 4 {
                return Err(VrpnError::PayloadLength {
                    type_name: T,
                    len: payload.len(),
                    expected: 4,
                });
            }
            let n = p.i32();
            if !(0..=MAX_BUTTONS as i32).contains(&n) {
                return Err(VrpnError::OutOfRange {
                    type_name: T,
                    field: "button count",
                    value: f64::from(n),
                    range: "0..=256",
                });
            }
            let n = n as usize;
            exact(T, payload, 4 + 4 * n)?;
            let states = (0..n)
                .map(|_| state(T, p.i32()))
                .collect::<Result<_, _>>()?;
            Ok(Body::ButtonStates(states))
        }
        TypeKind::AnalogChannel => {
            const T: &str = "Analog Channel";
            if payload.len() < 8 {
                return Err(VrpnError::PayloadLength {
                    type_name: T,
                    len: payload.len(),
                    expected: 8,
                });
            }
            // The channel count is a float64 on the wire (vrpn_Analog::encode_to).
            let n = p.f64();
            if !(n.fract() == 0.0 && (0.0..=MAX_CHANNELS as f64).contains(&n)) {
                return Err(VrpnError::OutOfRange {
                    type_name: T,
                    field: "channel count",
                    value: n,
                    range: "a whole number in 0..=128",
                });
            }
            let n = n as usize;
            exact(T, payload, 8 + 8 * n)?;
            let values = (0..n)
                .map(|_| finite(T, "channel value", p.f64()))
                .collect::<Result<_, _>>()?;
            Ok(Body::Analog(values))
        }
        TypeKind::Other => Ok(Body::Other),
    }
}

/// Writing VRPN: the cookie, message framing and the payloads of the types this client reads.
/// Used by the client for its own cookie and UDP description, and by test servers and the
/// benchmark to produce server bytes.
pub mod encode {
    use super::{ALIGN, COOKIE_LEN, HEADER_LEN, MAGIC, VrpnTime, padded, system};

    /// `vrpn: ver. 07.38` + two spaces + log mode `0` (log nothing), NUL padded to 24 bytes.
    #[must_use]
    pub fn cookie() -> [u8; COOKIE_LEN] {
        cookie_with(MAGIC)
    }

    /// A cookie with another version text (tests of version checks).
    #[must_use]
    pub fn cookie_with(magic: &[u8]) -> [u8; COOKIE_LEN] {
        let mut c = [0u8; COOKIE_LEN];
        let text = [magic, b"  0"].concat();
        let n = text.len().min(COOKIE_LEN);
        c[..n].copy_from_slice(&text[..n]);
        c
    }

    /// Appends one message (header, payload, NUL padding) to `out`.
    pub fn message(
        out: &mut Vec<u8>,
        time: VrpnTime,
        sender: i32,
        kind: i32,
        seq: u32,
        payload: &[u8],
    ) {
        let len = (HEADER_LEN + payload.len()) as u32;
        for v in [len, time.sec, time.usec, sender as u32, kind as u32, seq] {
            out.extend_from_slice(&v.to_be_bytes());
        }
        out.extend_from_slice(payload);
        out.resize(out.len() + padded(payload.len()) - payload.len(), 0);
        debug_assert_eq!(out.len() % ALIGN, 0);
    }

    /// Sender or type description payload: u32 n + name + NUL.
    #[must_use]
    pub fn description(name: &str) -> Vec<u8> {
        let mut p = ((name.len() + 1) as u32).to_be_bytes().to_vec();
        p.extend_from_slice(name.as_bytes());
        p.push(0);
        p
    }

    /// Appends a sender description (`id` named `name`).
    pub fn sender_description(out: &mut Vec<u8>, seq: u32, id: i32, name: &str) {
        message(
            out,
            VrpnTime::default(),
            id,
            system::SENDER_DESCRIPTION,
            seq,
            &description(name),
        );
    }

    /// Appends a type description (`id` named `name`).
    pub fn type_description(out: &mut Vec<u8>, seq: u32, id: i32, name: &str) {
        message(
            out,
            VrpnTime::default(),
            id,
            system::TYPE_DESCRIPTION,
            seq,
            &description(name),
        );
    }

    /// UDP description payload: the host + NUL (the port goes in the sender field).
    #[must_use]
    pub fn udp_description(host: &str) -> Vec<u8> {
        let mut p = host.as_bytes().to_vec();
        p.push(0);
        p
    }

    /// Pos_Quat payload (64 bytes): sensor, sensor again as padding, position, quaternion
    /// x y z w.
    #[must_use]
    pub fn pos_quat(sensor: i32, pos: [f64; 3], quat_xyzw: [f64; 4]) -> Vec<u8> {
        let mut p = Vec::with_capacity(64);
        p.extend_from_slice(&sensor.to_be_bytes());
        p.extend_from_slice(&sensor.to_be_bytes());
        for v in pos.iter().chain(&quat_xyzw) {
            p.extend_from_slice(&v.to_be_bytes());
        }
        p
    }

    /// Button Change payload: button, state (1 pressed, 0 released).
    #[must_use]
    pub fn button_change(button: i32, state: i32) -> Vec<u8> {
        [button.to_be_bytes(), state.to_be_bytes()].concat()
    }

    /// Button States payload: count, then one state per button.
    #[must_use]
    pub fn button_states(states: &[i32]) -> Vec<u8> {
        let mut p = (states.len() as i32).to_be_bytes().to_vec();
        for s in states {
            p.extend_from_slice(&s.to_be_bytes());
        }
        p
    }

    /// Analog Channel payload: the count as a float64, then the values.
    #[must_use]
    pub fn analog(values: &[f64]) -> Vec<u8> {
        let mut p = (values.len() as f64).to_be_bytes().to_vec();
        for v in values {
            p.extend_from_slice(&v.to_be_bytes());
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cookie_is_magic_two_spaces_log_mode_and_nul_padding() {
        let c = encode::cookie();
        assert_eq!(&c[..19], b"vrpn: ver. 07.38  0");
        assert!(c[19..].iter().all(|&b| b == 0));
        assert_eq!(check_cookie(&c).unwrap().version, "07.38");
    }

    #[test]
    fn only_the_major_version_must_match() {
        let older = encode::cookie_with(b"vrpn: ver. 07.35");
        assert_eq!(check_cookie(&older).unwrap().version, "07.35");
        let e = check_cookie(&encode::cookie_with(b"vrpn: ver. 08.01")).unwrap_err();
        assert_eq!(e.name(), "vrpn_version_mismatch");
        assert!(e.to_string().contains("08.01"), "{e}");
        let e = check_cookie(b"GET / HTTP/1.1\r\nHost: x\r").unwrap_err();
        assert_eq!(e.name(), "vrpn_bad_cookie");
    }

    #[test]
    fn header_round_trips_and_lengths_are_checked() {
        let mut out = Vec::new();
        encode::message(&mut out, VrpnTime::new(7, 8), 1, 4, 9, &[1, 2, 3]);
        assert_eq!(out.len(), 32);
        let h = Header::read(&out).unwrap();
        assert_eq!(
            h,
            Header {
                len: 27,
                time: VrpnTime::new(7, 8),
                sender: 1,
                kind: 4,
                seq: 9
            }
        );
        assert_eq!((h.payload_len(), h.wire_len()), (3, 32));
        assert!(Header::read(&out[..23]).is_none());
        let small = Header { len: 23, ..h };
        assert_eq!(
            small.check_len().unwrap_err().name(),
            "vrpn_length_too_small"
        );
        let big = Header {
            len: MAX_MESSAGE_LEN as u32 + 1,
            ..h
        };
        assert_eq!(big.check_len().unwrap_err().name(), "vrpn_length_too_large");
    }

    #[test]
    fn pos_quat_payload_is_sensor_pad_position_quaternion_xyzw() {
        let p = encode::pos_quat(1, [0.5, 1.0, -2.0], [0.0, 0.0, 0.6, 0.8]);
        assert_eq!(p.len(), 64);
        let Body::PosQuat(q) = decode_payload(TypeKind::PosQuat, &p).unwrap() else {
            panic!()
        };
        assert_eq!(
            (q.sensor, q.pos, q.quat_xyzw),
            (1, [0.5, 1.0, -2.0], [0.0, 0.0, 0.6, 0.8])
        );
    }

    #[test]
    fn nan_infinite_and_non_unit_poses_are_rejected() {
        for (pos, quat, kind) in [
            (
                [f64::NAN, 0.0, 0.0],
                [0.0, 0.0, 0.0, 1.0],
                "vrpn_non_finite",
            ),
            ([0.0; 3], [0.0, f64::INFINITY, 0.0, 1.0], "vrpn_non_finite"),
            ([0.0; 3], [0.0; 4], "vrpn_bad_quaternion"),
            ([0.0; 3], [0.0, 0.0, 0.0, 1.01], "vrpn_bad_quaternion"),
        ] {
            let e = decode_payload(TypeKind::PosQuat, &encode::pos_quat(0, pos, quat)).unwrap_err();
            assert_eq!(e.name(), kind, "{pos:?} {quat:?}");
        }
        let e = decode_payload(
            TypeKind::PosQuat,
            &encode::pos_quat(-1, [0.0; 3], [0.0, 0.0, 0.0, 1.0]),
        )
        .unwrap_err();
        assert_eq!(e.name(), "vrpn_out_of_range");
    }

    #[test]
    fn analog_count_is_a_float_and_must_match_the_payload() {
        let Body::Analog(v) =
            decode_payload(TypeKind::AnalogChannel, &encode::analog(&[0.25, -1.0])).unwrap()
        else {
            panic!()
        };
        assert_eq!(v, vec![0.25, -1.0]);
        let mut p = encode::analog(&[0.25, -1.0]);
        p[..8].copy_from_slice(&1.5f64.to_be_bytes());
        assert_eq!(
            decode_payload(TypeKind::AnalogChannel, &p)
                .unwrap_err()
                .name(),
            "vrpn_out_of_range"
        );
        p[..8].copy_from_slice(&3.0f64.to_be_bytes());
        assert_eq!(
            decode_payload(TypeKind::AnalogChannel, &p)
                .unwrap_err()
                .name(),
            "vrpn_bad_payload_length"
        );
        p[..8].copy_from_slice(&1e300f64.to_be_bytes());
        assert_eq!(
            decode_payload(TypeKind::AnalogChannel, &p)
                .unwrap_err()
                .name(),
            "vrpn_out_of_range"
        );
    }

    #[test]
    fn button_payloads_are_checked() {
        assert_eq!(
            decode_payload(TypeKind::ButtonChange, &encode::button_change(3, 1)).unwrap(),
            Body::ButtonChange {
                button: 3,
                pressed: true
            }
        );
        for bad in [
            encode::button_change(3, 2),
            encode::button_change(256, 1),
            encode::button_change(-1, 0),
        ] {
            assert_eq!(
                decode_payload(TypeKind::ButtonChange, &bad)
                    .unwrap_err()
                    .name(),
                "vrpn_out_of_range"
            );
        }
        assert_eq!(
            decode_payload(TypeKind::ButtonStates, &encode::button_states(&[0, 1])).unwrap(),
            Body::ButtonStates(vec![false, true])
        );
        let mut p = encode::button_states(&[0, 1]);
        p[..4].copy_from_slice(&100_000i32.to_be_bytes());
        assert_eq!(
            decode_payload(TypeKind::ButtonStates, &p)
                .unwrap_err()
                .name(),
            "vrpn_out_of_range"
        );
    }

    #[test]
    fn descriptions_need_one_nul_terminated_name_of_the_stated_length() {
        let h = Header {
            len: 0,
            time: VrpnTime::default(),
            sender: 1,
            kind: system::SENDER_DESCRIPTION,
            seq: 0,
        };
        assert_eq!(
            decode_system(&h, &encode::description("DTrack")).unwrap(),
            Body::SenderDescription {
                id: 1,
                name: "DTrack".into()
            }
        );
        let mut p = encode::description("DTrack");
        p[3] += 1;
        assert_eq!(
            decode_system(&h, &p).unwrap_err().name(),
            "vrpn_bad_description"
        );
        let mut p = encode::description("DTrack");
        *p.last_mut().unwrap() = b'x';
        assert_eq!(
            decode_system(&h, &p).unwrap_err().name(),
            "vrpn_bad_description"
        );
        let far = Header { sender: 5000, ..h };
        assert_eq!(
            decode_system(&far, &encode::description("x"))
                .unwrap_err()
                .name(),
            "vrpn_id_out_of_range"
        );
        let odd = Header { kind: -9, ..h };
        assert_eq!(
            decode_system(&odd, &[]).unwrap_err().name(),
            "vrpn_unknown_system_type"
        );
    }

    #[test]
    fn time_from_seconds_rounds_to_microseconds() {
        assert_eq!(VrpnTime::from_seconds(1.5), VrpnTime::new(1, 500_000));
        assert_eq!(VrpnTime::from_seconds(1.999_999_9), VrpnTime::new(2, 0));
        assert_eq!(VrpnTime::new(3, 250_000).seconds(), 3.25);
        assert_eq!(VrpnTime::new(3, 7).to_string(), "3.000007");
    }
}
