//! OSC over UDP (decoded with `rosc`): raygun's own address space and the VMC protocol's
//! controller messages.
//!
//! # raygun's address space
//!
//! `<n>` is a decimal device number (device `osc:<n>`); numbers are OSC `f` (float32) or `d`
//! (float64), integers `i`. Poses are in the room frame of DESIGN.md §2 (metres, right-handed,
//! +Y up).
//!
//! | address               | arguments                    | meaning                                 |
//! |-----------------------|------------------------------|-----------------------------------------|
//! | `/raygun/<n>/pose`    | `x y z qx qy qz qw`          | tracked pose (quaternion normalised)    |
//! | `/raygun/<n>/lost`    | none                         | the device is not tracked               |
//! | `/raygun/<n>/buttons` | `i` bitmask                  | bit i = button i pressed, bit 0 trigger |
//! | `/raygun/<n>/axes`    | 1–8 numbers in [−1, 1]       | analog axes (x, y of the stick, …)      |
//! | `/raygun/<n>/fov`     | `h v` degrees in (0, 180)    | set the field of view directly          |
//! | `/raygun/<n>/canvas`  | `x y` canvas pixels          | pointer on the canvas (mouse-like)      |
//!
//! # VMC (Virtual Motion Capture protocol)
//!
//! * `/VMC/Ext/Con/Pos s f f f f f f f`: controller `serial`, position and quaternion in
//!   Unity's *left-handed* frame (+X right, +Y up, +Z forward). Mirroring z converts it:
//!   (x, y, z) → (x, y, −z) and (qx, qy, qz, qw) → (−qx, −qy, qz, qw); Unity's forward (+Z)
//!   becomes −Z, the default pointing axis of DESIGN.md §2.
//! * `/VMC/Ext/Con i s i i i f f f`: `active` (1 press, 0 release, 2 axis moved), input
//!   `name`, `is_left`, `is_touch`, `is_axis`, axis x y z. Touches are ignored. Names map to
//!   button bits: `*Trigger*` → 0, `*Grip*` → 1, `*Menu*`/`*Start*` → 2, `*Stick*` or
//!   `*Pad*` clicks → 3, `*A*`/`*X*`-buttons (`ClickButton1`, …) → 4/5; the axes of a
//!   `Thumbstick`/`Trackpad` input become the device's axes.
//! * VMC devices are hands: `vmc:0` is the right hand, `vmc:1` the left. Button messages name
//!   the hand; pose messages name a serial, which [`OscConfig::vmc_serials`] maps to a hand;
//!   an unmapped serial is given the right hand, then the left, in order of appearance, and
//!   further serials are ignored.
//!
//! A bundle is flattened (nested bundles too); its time tag, unless "immediately", is the
//! event time when the time source is the tracker. Any malformed message fails the whole
//! datagram, like a bad DTrack line fails its frame.

use std::collections::BTreeMap;

use glam::{DQuat, DVec2, DVec3};
use rosc::{OscBundle, OscMessage, OscPacket, OscType};
use serde::{Deserialize, Serialize};

use super::dtrack::{TimeSource, TrackerToRoom};
use super::event::{DeviceId, DeviceKind, MAX_AXES, Pose, Tracking, TrackingEvent};

/// The largest UDP payload over IPv4; receive buffers are at least this big (bundles of many
/// messages are large).
pub const MAX_DATAGRAM: usize = 65_507;
/// Deepest bundle nesting accepted.
pub const MAX_BUNDLE_DEPTH: usize = 8;
/// Highest device number of the raygun address space.
pub const MAX_DEVICE: u32 = 255;

/// OSC decoder configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OscConfig {
    /// VMC serial → hand ("right" or "left").
    pub vmc_serials: BTreeMap<String, VmcHand>,
    pub time_source: TimeSource,
    /// The sender's frame → room (a calibration, [`super::calibration`]); the identity in metres
    /// (the default) leaves the poses as sent.
    #[serde(skip_serializing_if = "TrackerToRoom::is_identity_metres")]
    pub tracker_to_room: TrackerToRoom,
}

impl Default for OscConfig {
    fn default() -> Self {
        Self {
            vmc_serials: BTreeMap::new(),
            time_source: TimeSource::default(),
            tracker_to_room: TrackerToRoom::identity_metres(),
        }
    }
}

/// A VMC hand.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VmcHand {
    Right,
    Left,
}

impl VmcHand {
    fn device(self) -> DeviceId {
        DeviceId::new(DeviceKind::Vmc, self as u32)
    }
}

/// A datagram that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OscError {
    #[error("OSC datagram of {len} bytes exceeds the {max}-byte limit")]
    Oversized { len: usize, max: usize },
    #[error("OSC datagram does not decode: {0}")]
    Decode(String),
    #[error("OSC datagram has {0} bytes after its packet")]
    TrailingBytes(usize),
    #[error("OSC bundles nested deeper than {MAX_BUNDLE_DEPTH}")]
    TooDeep,
    #[error("OSC {address}: argument {index} should be {expected}, is {found}")]
    TypeMismatch {
        address: String,
        index: usize,
        expected: &'static str,
        found: &'static str,
    },
    #[error("OSC {address}: {found} arguments, expected {expected}")]
    ArgCount {
        address: String,
        found: usize,
        expected: &'static str,
    },
    #[error("OSC {address}: argument {index} = {value} is not finite or out of range")]
    BadValue {
        address: String,
        index: usize,
        value: f64,
    },
    #[error("OSC {address}: device number is not an integer in 0..={MAX_DEVICE}")]
    BadDevice { address: String },
}

impl OscError {
    /// A short stable name per kind, for counters and once-per-kind logs.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Oversized { .. } => "osc_oversized",
            Self::Decode(_) => "osc_decode",
            Self::TrailingBytes(_) => "osc_trailing_bytes",
            Self::TooDeep => "osc_too_deep",
            Self::TypeMismatch { .. } => "osc_type_mismatch",
            Self::ArgCount { .. } => "osc_arg_count",
            Self::BadValue { .. } => "osc_bad_value",
            Self::BadDevice { .. } => "osc_bad_device",
        }
    }
}

fn type_name(a: &OscType) -> &'static str {
    match a {
        OscType::Int(_) => "int32",
        OscType::Float(_) => "float32",
        OscType::String(_) => "string",
        OscType::Blob(_) => "blob",
        OscType::Time(_) => "timetag",
        OscType::Long(_) => "int64",
        OscType::Double(_) => "float64",
        OscType::Char(_) => "char",
        OscType::Color(_) => "color",
        OscType::Midi(_) => "midi",
        OscType::Bool(_) => "bool",
        OscType::Array(_) => "array",
        OscType::Nil => "nil",
        OscType::Inf => "infinitum",
    }
}

/// Argument access with typed errors naming the address and index.
struct Args<'a> {
    msg: &'a OscMessage,
}

impl Args<'_> {
    fn count(&self, expected: &'static str, ok: bool) -> Result<(), OscError> {
        if ok {
            Ok(())
        } else {
            Err(OscError::ArgCount {
                address: self.msg.addr.clone(),
                found: self.msg.args.len(),
                expected,
            })
        }
    }

    fn mismatch(&self, index: usize, expected: &'static str) -> OscError {
        OscError::TypeMismatch {
            address: self.msg.addr.clone(),
            index,
            expected,
            found: self.msg.args.get(index).map_or("nothing", type_name),
        }
    }

    fn num(&self, index: usize) -> Result<f64, OscError> {
        let v = match self.msg.args.get(index) {
            Some(OscType::Float(v)) => f64::from(*v),
            Some(OscType::Double(v)) => *v,
            _ => return Err(self.mismatch(index, "float32 or float64")),
        };
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.bad(index, v))
        }
    }

    fn num_in(&self, index: usize, lo: f64, hi: f64) -> Result<f64, OscError> {
        let v = self.num(index)?;
        if (lo..=hi).contains(&v) {
            Ok(v)
        } else {
            Err(self.bad(index, v))
        }
    }

    fn int(&self, index: usize) -> Result<i32, OscError> {
        match self.msg.args.get(index) {
            Some(OscType::Int(v)) => Ok(*v),
            _ => Err(self.mismatch(index, "int32")),
        }
    }

    fn string(&self, index: usize) -> Result<&str, OscError> {
        match self.msg.args.get(index) {
            Some(OscType::String(s)) => Ok(s),
            _ => Err(self.mismatch(index, "string")),
        }
    }

    fn bad(&self, index: usize, value: f64) -> OscError {
        OscError::BadValue {
            address: self.msg.addr.clone(),
            index,
            value,
        }
    }
}

/// Per-hand VMC state: VMC sends one message per input, the event carries all buttons.
#[derive(Clone, Debug, Default)]
struct VmcHandState {
    buttons: u32,
}

/// A stateful OSC decoder.
#[derive(Clone, Debug)]
pub struct OscDecoder {
    config: OscConfig,
    hands: [VmcHandState; 2],
    /// Serials assigned a hand in order of appearance (at most two).
    auto_serials: Vec<(String, VmcHand)>,
}

impl OscDecoder {
    #[must_use]
    pub fn new(config: OscConfig) -> Self {
        Self {
            config,
            hands: Default::default(),
            auto_serials: Vec::new(),
        }
    }

    #[must_use]
    pub fn config(&self) -> &OscConfig {
        &self.config
    }

    /// Replaces the configuration (a calibration given after construction).
    pub fn set_config(&mut self, config: OscConfig) {
        self.config = config;
    }

    /// Decodes one datagram received at `receive_t`, appending its events to `out`. On error
    /// nothing is appended and no VMC state changes.
    pub fn decode_into(
        &mut self,
        data: &[u8],
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
    ) -> Result<(), OscError> {
        if data.len() > MAX_DATAGRAM {
            return Err(OscError::Oversized {
                len: data.len(),
                max: MAX_DATAGRAM,
            });
        }
        let (rest, packet) =
            rosc::decoder::decode_udp(data).map_err(|e| OscError::Decode(e.to_string()))?;
        if !rest.is_empty() {
            return Err(OscError::TrailingBytes(rest.len()));
        }
        let mut messages = Vec::new();
        flatten(
            &packet,
            receive_t,
            self.config.time_source,
            0,
            &mut messages,
        )?;
        // Decode into scratch state first so that a bad message leaves no partial effect.
        let mut scratch = self.clone();
        let start = out.len();
        for (t, msg) in &messages {
            if let Err(e) = scratch.message(msg, *t, out) {
                out.truncate(start);
                return Err(e);
            }
        }
        *self = scratch;
        let to_room = &self.config.tracker_to_room;
        if !to_room.is_identity_metres() {
            for e in &mut out[start..] {
                if let Some(Tracking::Tracked(p)) = &mut e.pose {
                    *p = to_room.map_pose(p.position, glam::DMat3::from_quat(p.orientation));
                }
            }
        }
        Ok(())
    }

    fn message(
        &mut self,
        msg: &OscMessage,
        t: f64,
        out: &mut Vec<TrackingEvent>,
    ) -> Result<(), OscError> {
        let args = Args { msg };
        if let Some(rest) = msg.addr.strip_prefix("/raygun/") {
            let Some((num, leaf)) = rest.split_once('/') else {
                return Ok(());
            };
            let id = num
                .parse::<u32>()
                .ok()
                .filter(|n| *n <= MAX_DEVICE)
                .ok_or_else(|| OscError::BadDevice {
                    address: msg.addr.clone(),
                })?;
            let mut e = TrackingEvent::empty(t, DeviceId::new(DeviceKind::Osc, id));
            let n = msg.args.len();
            match leaf {
                "pose" => {
                    args.count("7 (x y z qx qy qz qw)", n == 7)?;
                    let v: Vec<f64> = (0..7).map(|i| args.num(i)).collect::<Result<_, _>>()?;
                    e.pose = Some(Tracking::Tracked(pose_from(&args, &v)?));
                }
                "lost" => {
                    args.count("0", n == 0)?;
                    e.pose = Some(Tracking::Lost);
                }
                "buttons" => {
                    args.count("1 (bitmask)", n == 1)?;
                    let b = args.int(0)?;
                    // The bitmask is the int's bit pattern.
                    e.buttons = Some(b as u32);
                }
                "axes" => {
                    args.count("1 to 8", (1..=MAX_AXES).contains(&n))?;
                    e.axes = Some(
                        (0..n)
                            .map(|i| args.num_in(i, -1.0, 1.0))
                            .collect::<Result<_, _>>()?,
                    );
                }
                "fov" => {
                    args.count("2 (horizontal, vertical degrees)", n == 2)?;
                    let h = args.num(0)?;
                    let v = args.num(1)?;
                    for (i, x) in [h, v].into_iter().enumerate() {
                        if !(x > 0.0 && x < 180.0) {
                            return Err(args.bad(i, x));
                        }
                    }
                    e.fov_deg = Some([h, v]);
                }
                "canvas" => {
                    args.count("2 (x y canvas pixels)", n == 2)?;
                    e.canvas = Some(DVec2::new(args.num(0)?, args.num(1)?));
                }
                _ => return Ok(()),
            }
            out.push(e);
            return Ok(());
        }
        match msg.addr.as_str() {
            "/VMC/Ext/Con/Pos" => {
                args.count("8 (serial x y z qx qy qz qw)", msg.args.len() == 8)?;
                let serial = args.string(0)?;
                let v: Vec<f64> = (1..8).map(|i| args.num(i)).collect::<Result<_, _>>()?;
                // Unity (left-handed) → room (right-handed): mirror z.
                let unity = [v[0], v[1], -v[2], -v[3], -v[4], v[5], v[6]];
                let pose = pose_from(&args, &unity)?;
                if let Some(hand) = self.hand_of(serial) {
                    let mut e = TrackingEvent::empty(t, hand.device());
                    e.pose = Some(Tracking::Tracked(pose));
                    out.push(e);
                }
                Ok(())
            }
            "/VMC/Ext/Con" => {
                args.count(
                    "8 (active name is_left is_touch is_axis x y z)",
                    msg.args.len() == 8,
                )?;
                let active = args.int(0)?;
                let name = args.string(1)?;
                let is_left = args.int(2)?;
                let is_touch = args.int(3)?;
                let is_axis = args.int(4)?;
                let axes = [
                    args.num_in(5, -1.0, 1.0)?,
                    args.num_in(6, -1.0, 1.0)?,
                    args.num_in(7, -1.0, 1.0)?,
                ];
                if is_touch != 0 {
                    return Ok(());
                }
                let hand = if is_left != 0 {
                    VmcHand::Left
                } else {
                    VmcHand::Right
                };
                let state = &mut self.hands[hand as usize];
                let mut e = TrackingEvent::empty(t, hand.device());
                if is_axis != 0 {
                    e.axes = Some(axes[..2].to_vec());
                }
                if is_axis == 0 || active != 2 {
                    if let Some(bit) = vmc_button_bit(name) {
                        match active {
                            1 => state.buttons |= 1 << bit,
                            0 => state.buttons &= !(1 << bit),
                            _ => {}
                        }
                    }
                    e.buttons = Some(state.buttons);
                }
                out.push(e);
                Ok(())
            }
            _ => Ok(()),
        }
    }

    fn hand_of(&mut self, serial: &str) -> Option<VmcHand> {
        if let Some(h) = self.config.vmc_serials.get(serial) {
            return Some(*h);
        }
        if let Some((_, h)) = self.auto_serials.iter().find(|(s, _)| s == serial) {
            return Some(*h);
        }
        let taken: Vec<VmcHand> = self
            .config
            .vmc_serials
            .values()
            .chain(self.auto_serials.iter().map(|(_, h)| h))
            .copied()
            .collect();
        let free = [VmcHand::Right, VmcHand::Left]
            .into_iter()
            .find(|h| !taken.contains(h))?;
        self.auto_serials.push((serial.to_owned(), free));
        Some(free)
    }
}

fn vmc_button_bit(name: &str) -> Option<u32> {
    let n = name.to_ascii_lowercase();
    if n.contains("trigger") {
        Some(0)
    } else if n.contains("grip") {
        Some(1)
    } else if n.contains("menu") || n.contains("start") {
        Some(2)
    } else if n.contains("stick") || n.contains("pad") {
        Some(3)
    } else if n.ends_with("button1") || n.ends_with("buttona") || n.ends_with("buttonx") {
        Some(4)
    } else if n.ends_with("button2") || n.ends_with("buttonb") || n.ends_with("buttony") {
        Some(5)
    } else {
        None
    }
}

fn pose_from(args: &Args<'_>, v: &[f64]) -> Result<Pose, OscError> {
    let q = DQuat::from_xyzw(v[3], v[4], v[5], v[6]);
    let len = q.length();
    // A quaternion far from unit length is not a rotation someone meant to send.
    if !(0.5..=2.0).contains(&len) {
        return Err(args.bad(3, len));
    }
    Ok(Pose {
        position: DVec3::new(v[0], v[1], v[2]),
        orientation: q / len,
    })
}

/// OSC time tag → seconds since the NTP epoch; "immediately" (0, 1) has no time.
fn timetag_seconds(b: &OscBundle) -> Option<f64> {
    let tt = b.timetag;
    if tt.seconds == 0 && tt.fractional <= 1 {
        return None;
    }
    Some(f64::from(tt.seconds) + f64::from(tt.fractional) / 4_294_967_296.0)
}

fn flatten<'a>(
    p: &'a OscPacket,
    t: f64,
    source: TimeSource,
    depth: usize,
    out: &mut Vec<(f64, &'a OscMessage)>,
) -> Result<(), OscError> {
    match p {
        OscPacket::Message(m) => out.push((t, m)),
        OscPacket::Bundle(b) => {
            if depth >= MAX_BUNDLE_DEPTH {
                return Err(OscError::TooDeep);
            }
            let t = match (source, timetag_seconds(b)) {
                (TimeSource::Tracker, Some(s)) => s,
                _ => t,
            };
            for c in &b.content {
                flatten(c, t, source, depth + 1, out)?;
            }
        }
    }
    Ok(())
}

/// Encoding helpers for the synthetic generator and tests: raygun-space messages.
pub mod encode {
    use super::*;
    use rosc::OscTime;

    fn msg(addr: String, args: Vec<OscType>) -> OscPacket {
        OscPacket::Message(OscMessage { addr, args })
    }

    /// `/raygun/<n>/pose`.
    #[must_use]
    pub fn pose(n: u32, p: &Pose) -> OscPacket {
        let q = p.orientation;
        let v = [p.position.x, p.position.y, p.position.z, q.x, q.y, q.z, q.w];
        msg(
            format!("/raygun/{n}/pose"),
            v.iter().map(|x| OscType::Float(*x as f32)).collect(),
        )
    }

    /// `/raygun/<n>/lost`.
    #[must_use]
    pub fn lost(n: u32) -> OscPacket {
        msg(format!("/raygun/{n}/lost"), vec![])
    }

    /// `/raygun/<n>/buttons`.
    #[must_use]
    pub fn buttons(n: u32, bits: u32) -> OscPacket {
        msg(
            format!("/raygun/{n}/buttons"),
            vec![OscType::Int(bits as i32)],
        )
    }

    /// `/raygun/<n>/axes`.
    #[must_use]
    pub fn axes(n: u32, axes: &[f64]) -> OscPacket {
        msg(
            format!("/raygun/{n}/axes"),
            axes.iter().map(|x| OscType::Float(*x as f32)).collect(),
        )
    }

    /// `/raygun/<n>/canvas`.
    #[must_use]
    pub fn canvas(n: u32, c: DVec2) -> OscPacket {
        msg(
            format!("/raygun/{n}/canvas"),
            vec![OscType::Double(c.x), OscType::Double(c.y)],
        )
    }

    /// A bundle with a time tag of `seconds` since the NTP epoch (must be ≥ 1 so that it is
    /// not "immediately").
    #[must_use]
    pub fn bundle(seconds: f64, content: Vec<OscPacket>) -> OscPacket {
        let whole = seconds.floor();
        let frac = ((seconds - whole) * 4_294_967_296.0)
            .round()
            .min(4_294_967_295.0);
        OscPacket::Bundle(OscBundle {
            timetag: OscTime {
                seconds: whole as u32,
                fractional: frac as u32,
            },
            content,
        })
    }

    /// Bytes of a packet.
    #[must_use]
    pub fn bytes(p: &OscPacket) -> Vec<u8> {
        // Encoding an in-memory packet of finite size cannot fail.
        rosc::encoder::encode(p).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::encode::*;
    use super::*;
    use proptest::prelude::*;

    fn decode(p: &OscPacket) -> Result<Vec<TrackingEvent>, OscError> {
        let mut out = Vec::new();
        OscDecoder::new(OscConfig::default()).decode_into(&bytes(p), 2.0, &mut out)?;
        Ok(out)
    }

    fn raw(addr: &str, args: Vec<OscType>) -> OscPacket {
        OscPacket::Message(OscMessage {
            addr: addr.into(),
            args,
        })
    }

    #[test]
    fn pose_message_gives_a_normalised_tracked_pose() {
        let p = Pose {
            position: DVec3::new(0.5, 1.5, 1.0),
            orientation: DQuat::from_rotation_y(0.4),
        };
        let out = decode(&pose(3, &p)).unwrap();
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].device, DeviceId::new(DeviceKind::Osc, 3));
        assert_eq!(out[0].t, 2.0);
        let Some(Tracking::Tracked(q)) = out[0].pose else {
            panic!("no pose")
        };
        assert!((q.position - p.position).length() < 1e-6);
        assert!(q.orientation.angle_between(p.orientation) < 1e-6);
        assert!(q.is_valid());
    }

    #[test]
    fn bundle_is_flattened_and_its_timetag_is_the_time() {
        let b = bundle(1000.5, vec![buttons(0, 1), axes(0, &[0.5, -0.5]), lost(0)]);
        let out = decode(&b).unwrap();
        assert_eq!(out.len(), 3);
        assert!(out.iter().all(|e| (e.t - 1000.5).abs() < 1e-9));
        assert_eq!(out[0].buttons, Some(1));
        assert_eq!(out[1].axes, Some(vec![0.5, -0.5]));
        assert_eq!(out[2].pose, Some(Tracking::Lost));
    }

    #[test]
    fn nested_bundles_within_the_limit_decode_and_deeper_ones_fail() {
        let mut p = buttons(0, 2);
        for _ in 0..MAX_BUNDLE_DEPTH {
            p = bundle(5.0, vec![p]);
        }
        assert_eq!(decode(&p).unwrap()[0].buttons, Some(2));
        let p = bundle(5.0, vec![p]);
        assert_eq!(decode(&p).unwrap_err(), OscError::TooDeep);
    }

    #[test]
    fn type_mismatch_names_address_and_index() {
        let e = decode(&raw("/raygun/0/buttons", vec![OscType::Float(1.0)])).unwrap_err();
        assert_eq!(
            e,
            OscError::TypeMismatch {
                address: "/raygun/0/buttons".into(),
                index: 0,
                expected: "int32",
                found: "float32"
            }
        );
        let e = decode(&raw(
            "/raygun/0/axes",
            vec![OscType::Float(0.0), OscType::String("x".into())],
        ))
        .unwrap_err();
        assert_eq!(e.name(), "osc_type_mismatch");
    }

    #[test]
    fn wrong_argument_count_is_an_error() {
        let e = decode(&raw("/raygun/0/pose", vec![OscType::Float(0.0); 6])).unwrap_err();
        assert_eq!(e.name(), "osc_arg_count");
        let e = decode(&raw("/raygun/0/axes", vec![OscType::Float(0.0); 9])).unwrap_err();
        assert_eq!(e.name(), "osc_arg_count");
    }

    #[test]
    fn non_finite_and_out_of_range_values_are_errors() {
        let mut args = vec![OscType::Float(0.0); 7];
        args[6] = OscType::Float(1.0);
        args[1] = OscType::Float(f32::NAN);
        assert_eq!(
            decode(&raw("/raygun/0/pose", args)).unwrap_err().name(),
            "osc_bad_value"
        );
        let zero_q = vec![OscType::Float(0.0); 7];
        assert_eq!(
            decode(&raw("/raygun/0/pose", zero_q)).unwrap_err().name(),
            "osc_bad_value"
        );
        let e = decode(&raw("/raygun/0/axes", vec![OscType::Double(1.5)])).unwrap_err();
        assert_eq!(e.name(), "osc_bad_value");
        let e = decode(&raw(
            "/raygun/0/fov",
            vec![OscType::Float(200.0), OscType::Float(10.0)],
        ))
        .unwrap_err();
        assert_eq!(e.name(), "osc_bad_value");
    }

    #[test]
    fn bad_device_number_is_an_error_and_unknown_addresses_are_ignored() {
        assert_eq!(
            decode(&lost(MAX_DEVICE + 1)).unwrap_err().name(),
            "osc_bad_device"
        );
        assert_eq!(
            decode(&raw("/raygun/x/lost", vec![])).unwrap_err().name(),
            "osc_bad_device"
        );
        assert!(
            decode(&raw("/something/else", vec![OscType::Nil]))
                .unwrap()
                .is_empty()
        );
        assert!(
            decode(&raw("/raygun/0/unknown", vec![]))
                .unwrap()
                .is_empty()
        );
    }

    #[test]
    fn truncated_packets_are_errors_not_panics() {
        let b = bytes(&bundle(
            10.0,
            vec![pose(
                0,
                &Pose {
                    position: DVec3::ONE,
                    orientation: DQuat::IDENTITY,
                },
            )],
        ));
        for cut in 0..b.len() {
            let mut out = Vec::new();
            let r = OscDecoder::new(OscConfig::default()).decode_into(&b[..cut], 0.0, &mut out);
            assert!(out.is_empty(), "cut at {cut} produced events");
            // 16 bytes ("#bundle\0" + time tag) is a complete, empty bundle.
            assert_eq!(r.is_ok(), cut == 16, "cut at {cut}: {r:?}");
        }
    }

    #[test]
    fn one_bad_message_in_a_bundle_fails_the_datagram_without_side_effects() {
        let b = bundle(
            10.0,
            vec![buttons(0, 1), raw("/raygun/0/axes", vec![OscType::Int(1)])],
        );
        let mut out = Vec::new();
        let mut d = OscDecoder::new(OscConfig::default());
        assert!(d.decode_into(&bytes(&b), 0.0, &mut out).is_err());
        assert!(out.is_empty());
    }

    fn vmc_con(active: i32, name: &str, left: i32, axis: i32, x: f32, y: f32) -> OscPacket {
        raw(
            "/VMC/Ext/Con",
            vec![
                OscType::Int(active),
                OscType::String(name.into()),
                OscType::Int(left),
                OscType::Int(0),
                OscType::Int(axis),
                OscType::Float(x),
                OscType::Float(y),
                OscType::Float(0.0),
            ],
        )
    }

    fn vmc_pos(serial: &str, p: [f32; 3], q: [f32; 4]) -> OscPacket {
        let mut args = vec![OscType::String(serial.into())];
        args.extend(p.iter().chain(q.iter()).map(|v| OscType::Float(*v)));
        raw("/VMC/Ext/Con/Pos", args)
    }

    #[test]
    fn vmc_pose_is_converted_from_unity_left_handed_frame() {
        // Unity: controller at z = +1 (forward), rotated +90° about Unity's Y. In Unity a
        // positive Y rotation turns forward (+Z) towards +X.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let out = decode(&vmc_pos("LHR-1", [0.2, 1.4, 1.0], [0.0, h, 0.0, h])).unwrap();
        let Some(Tracking::Tracked(p)) = out[0].pose else {
            panic!()
        };
        assert_eq!(out[0].device, DeviceId::new(DeviceKind::Vmc, 0));
        assert!((p.position - DVec3::new(0.2, 1.4, -1.0)).length() < 1e-6);
        // Unity forward +Z maps to our −Z; after the rotation Unity's forward is +X, which is
        // +X in our frame too, so our pointing axis −Z must map to +X.
        assert!((p.orientation * DVec3::NEG_Z - DVec3::X).length() < 1e-6);
        // Up stays up.
        assert!((p.orientation * DVec3::Y - DVec3::Y).length() < 1e-6);
    }

    #[test]
    fn vmc_buttons_accumulate_per_hand_and_axes_pass_through() {
        let mut d = OscDecoder::new(OscConfig::default());
        let mut out = Vec::new();
        for p in [
            vmc_con(1, "ClickTrigger", 0, 0, 0.0, 0.0),
            vmc_con(1, "ClickGrip", 0, 0, 0.0, 0.0),
            vmc_con(0, "ClickTrigger", 0, 0, 0.0, 0.0),
            vmc_con(2, "Thumbstick", 1, 1, 0.5, -0.25),
        ] {
            d.decode_into(&bytes(&p), 0.0, &mut out).unwrap();
        }
        let b: Vec<Option<u32>> = out.iter().map(|e| e.buttons).collect();
        assert_eq!(b, vec![Some(1), Some(3), Some(2), None]);
        assert_eq!(out[3].device, DeviceId::new(DeviceKind::Vmc, 1));
        assert_eq!(out[3].axes, Some(vec![0.5, -0.25]));
    }

    #[test]
    fn vmc_serials_get_hands_by_config_then_by_appearance() {
        let mut config = OscConfig::default();
        config.vmc_serials.insert("L".into(), VmcHand::Left);
        let mut d = OscDecoder::new(config);
        let mut out = Vec::new();
        let q = [0.0, 0.0, 0.0, 1.0];
        for s in ["A", "L", "B", "A"] {
            d.decode_into(&bytes(&vmc_pos(s, [0.0; 3], q)), 0.0, &mut out)
                .unwrap();
        }
        let ids: Vec<u32> = out.iter().map(|e| e.device.id).collect();
        // A → right (free), L → left (configured), B → no hand left: ignored, A again → right.
        assert_eq!(ids, vec![0, 1, 0]);
    }

    proptest! {
        #[test]
        fn arbitrary_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..256)) {
            let mut out = Vec::new();
            let _ = OscDecoder::new(OscConfig::default()).decode_into(&data, 0.0, &mut out);
            prop_assert!(out.iter().all(|e| e.is_valid()));
        }

        #[test]
        fn corrupted_bundles_never_panic(at in 0usize..200, byte in any::<u8>()) {
            let mut b = bytes(&bundle(3.0, vec![buttons(1, 3), axes(1, &[0.1, 0.2]), vmc_con(1, "Trigger", 0, 0, 0.0, 0.0)]));
            if at < b.len() { b[at] = byte; }
            let mut out = Vec::new();
            let _ = OscDecoder::new(OscConfig::default()).decode_into(&b, 0.0, &mut out);
            prop_assert!(out.iter().all(|e| e.is_valid()));
        }
    }
}
