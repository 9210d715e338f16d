//! The VRPN decoder: raw reads (TCP stream pieces, UDP datagrams) of one connection in,
//! normalised events out. Live clients and replays both feed it the raw bytes, so a replay
//! decodes exactly what the live run did.
//!
//! Per connection it keeps the cookie, a partial message that a read cut off, and the peer's
//! id → name tables; ids are matched to the device and the message types by name. A read of
//! zero bytes on the TCP channel is the end of the connection: every device is lost and its
//! buttons are released, and the next bytes must start with a new cookie.
//!
//! Events mirror the DTrack parser's, so the interaction stage needs nothing VRPN-specific:
//! every report of a device carries its whole state (pose, button mask, axes), and a sensor
//! that a tracker frame lacks is reported `Lost` in every such frame, as DTrack reports an
//! untracked FlyStick with quality −1 (see [`VrpnConfig::frame_tolerance_s`]).

use std::fmt;

use glam::{DMat3, DQuat, DVec3};

use super::config::{AnalogGroup, ButtonGroup, VrpnConfig, VrpnConfigError};
use super::wire::{
    Body, COOKIE_LEN, HEADER_LEN, Header, PosQuat, TypeKind, VrpnError, VrpnTime, check_cookie,
    decode_payload, decode_system, system,
};
use crate::tracking::dtrack::TimeSource;
use crate::tracking::event::{DeviceId, Pose, Tracking, TrackingEvent};
use crate::tracking::problems::ProblemLog;

/// More messages than this within one second of receive time is reported as a flood: 10× a
/// 1 kHz tracker with 10 sensors, 100× what vrpn_Tracker_DTrack sends for 15 targets at 60 Hz.
/// Decoding goes on (memory stays bounded whatever the rate; TCP flow control slows the
/// server), but the operator learns why the machine is busy.
pub const FLOOD_MESSAGES_PER_S: u64 = 100_000;

/// A Pos_Quat stamped at most this much before the open frame is a late UDP datagram and is
/// dropped; one stamped further back means the server's clock was set back (an NTP step), and
/// starts a new frame, so that a clock change never freezes a device.
pub const MAX_REORDER_S: f64 = 1.0;

/// Which socket a read came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    Tcp,
    Udp,
}

impl fmt::Display for Channel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Channel::Tcp => "TCP",
            Channel::Udp => "UDP",
        })
    }
}

/// One decoded message, as received (kept only when asked for, see
/// [`VrpnDecoder::keep_messages`]): what a test compares with a capture's listing, and what a
/// tool prints.
#[derive(Clone, Debug, PartialEq)]
pub struct VrpnMessage {
    pub channel: Channel,
    pub header: Header,
    /// The sender's name; `None` for system messages.
    pub sender: Option<String>,
    /// The type's name (`system:SENDER_DESCRIPTION` … for system messages).
    pub type_name: String,
    pub body: Body,
}

/// Counters of what was decoded (not problems: these are normal traffic).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct VrpnStats {
    /// Connections whose cookie was accepted.
    pub connections: u64,
    pub tcp_bytes: u64,
    pub udp_datagrams: u64,
    /// Messages framed, on both channels, system messages included.
    pub messages: u64,
    /// Messages of the device, by type.
    pub pos_quat: u64,
    pub button_changes: u64,
    pub button_states: u64,
    pub analog: u64,
    /// Messages of other senders (VRPN sends every device's messages to every client).
    pub other_senders: u64,
    /// Reports of sensors, buttons or channels the mapping does not use.
    pub unmapped: u64,
    /// Pos_Quat reports older than the current frame (UDP reordering); dropped.
    pub stale: u64,
    /// UDP messages missing by sequence number.
    pub udp_missing: u64,
    /// Bytes ignored after the stream broke (until the connection ends).
    pub ignored_bytes: u64,
}

#[derive(Clone, Debug)]
struct SenderEntry {
    name: String,
    ours: bool,
}

#[derive(Clone, Debug)]
struct TypeEntry {
    name: String,
    kind: TypeKind,
}

/// The state of one connection; replaced when it ends.
#[derive(Clone, Debug, Default)]
struct Connection {
    cookie: [u8; COOKIE_LEN],
    cookie_have: usize,
    cookie_ok: bool,
    /// Bytes of a message that the last TCP read cut off.
    pending: Vec<u8>,
    /// A fatal framing error happened: the rest of the stream is ignored.
    broken: bool,
    senders: Vec<Option<SenderEntry>>,
    types: Vec<Option<TypeEntry>>,
    tcp_offset: u64,
    tcp_index: u64,
    udp_index: u64,
    udp_next_seq: Option<u32>,
}

#[derive(Clone, Debug)]
struct SensorState {
    sensor: u32,
    device: usize,
    /// Reported at least once on this connection.
    known: bool,
    tracked: bool,
    last: VrpnTime,
    seen_in_frame: bool,
}

#[derive(Clone, Debug)]
struct DeviceState {
    id: DeviceId,
    has_sensor: bool,
    buttons: Option<u32>,
    axes: Option<Vec<f64>>,
}

#[derive(Clone, Copy, Debug)]
struct Frame {
    stamp: VrpnTime,
    t: f64,
    closed: bool,
}

#[derive(Clone, Copy, Debug, Default)]
struct FloodWindow {
    start: f64,
    count: u64,
    reported: bool,
}

/// A stateful decoder for one VRPN device (one sender name) over successive connections.
#[derive(Clone, Debug)]
pub struct VrpnDecoder {
    device: String,
    config: VrpnConfig,
    time_source: TimeSource,
    rotation: DMat3,
    rotation_q: DQuat,
    translation: DVec3,
    metres_per_unit: f64,
    conn: Connection,
    sensors: Vec<SensorState>,
    devices: Vec<DeviceState>,
    buttons: Vec<(ButtonGroup, usize)>,
    analogs: Vec<(AnalogGroup, usize)>,
    frame: Option<Frame>,
    /// The latest tracker or button time of the device (seconds): the clock of analog reports
    /// and of messages without a time.
    clock: Option<f64>,
    last_receive: Option<f64>,
    flood: FloodWindow,
    keep: bool,
    messages: Vec<VrpnMessage>,
    stats: VrpnStats,
    wants_reconnect: bool,
}

fn system_name(kind: i32) -> &'static str {
    match kind {
        system::SENDER_DESCRIPTION => "system:SENDER_DESCRIPTION",
        system::TYPE_DESCRIPTION => "system:TYPE_DESCRIPTION",
        system::UDP_DESCRIPTION => "system:UDP_DESCRIPTION",
        system::LOG_DESCRIPTION => "system:LOG_DESCRIPTION",
        system::DISCONNECT => "system:DISCONNECT",
        _ => "system:?",
    }
}

impl VrpnDecoder {
    /// A decoder for the messages of `device` (the DEVICE of DEVICE@HOST), mapped by a
    /// configuration that is validated here.
    pub fn new(
        device: impl Into<String>,
        config: VrpnConfig,
        time_source: TimeSource,
    ) -> Result<Self, VrpnConfigError> {
        config.validate()?;
        let mut devices: Vec<DeviceState> = Vec::new();
        let index_of = |id: DeviceId, devices: &mut Vec<DeviceState>| {
            devices.iter().position(|d| d.id == id).unwrap_or_else(|| {
                devices.push(DeviceState {
                    id,
                    has_sensor: false,
                    buttons: None,
                    axes: None,
                });
                devices.len() - 1
            })
        };
        let sensors = config
            .sensors
            .iter()
            .map(|(&sensor, &id)| {
                let device = index_of(id, &mut devices);
                devices[device].has_sensor = true;
                SensorState {
                    sensor,
                    device,
                    known: false,
                    tracked: false,
                    last: VrpnTime::default(),
                    seen_in_frame: false,
                }
            })
            .collect();
        let buttons = config
            .buttons
            .iter()
            .map(|g| {
                let d = index_of(g.device, &mut devices);
                devices[d].buttons = Some(0);
                (g.clone(), d)
            })
            .collect();
        let analogs = config
            .analogs
            .iter()
            .map(|g| {
                let d = index_of(g.device, &mut devices);
                devices[d].axes = Some(vec![0.0; g.count as usize]);
                (g.clone(), d)
            })
            .collect();
        let t = &config.tracker_to_room;
        let rotation = t.rotation();
        Ok(Self {
            device: device.into(),
            rotation,
            rotation_q: DQuat::from_mat3(&rotation).normalize(),
            translation: DVec3::from_array(t.translation_m),
            metres_per_unit: t.metres_per_unit,
            config,
            time_source,
            conn: Connection::default(),
            sensors,
            devices,
            buttons,
            analogs,
            frame: None,
            clock: None,
            last_receive: None,
            flood: FloodWindow::default(),
            keep: false,
            messages: Vec::new(),
            stats: VrpnStats::default(),
            wants_reconnect: false,
        })
    }

    /// The device name whose messages are decoded.
    #[must_use]
    pub fn device(&self) -> &str {
        &self.device
    }

    #[must_use]
    pub fn config(&self) -> &VrpnConfig {
        &self.config
    }

    #[must_use]
    pub fn stats(&self) -> &VrpnStats {
        &self.stats
    }

    /// Keep every decoded message of the next [`Self::decode`] call for [`Self::messages`]
    /// (off by default: it costs an allocation per message).
    pub fn keep_messages(&mut self, on: bool) {
        self.keep = on;
        self.messages.clear();
    }

    /// The messages the last [`Self::decode`] call decoded, when [`Self::keep_messages`] is on.
    #[must_use]
    pub fn messages(&self) -> &[VrpnMessage] {
        &self.messages
    }

    /// The peer's sender names by id, as described on the current connection.
    #[must_use]
    pub fn sender_names(&self) -> Vec<(i32, &str)> {
        table(&self.conn.senders, |e| &e.name)
    }

    /// The peer's type names by id, as described on the current connection.
    #[must_use]
    pub fn type_names(&self) -> Vec<(i32, &str)> {
        table(&self.conn.types, |e| &e.name)
    }

    /// Whether the current stream broke (bad cookie, impossible length) since the last call:
    /// a live client should then drop the connection and connect again.
    pub fn take_reconnect(&mut self) -> bool {
        std::mem::take(&mut self.wants_reconnect)
    }

    /// Decodes one read received at `receive_t` (seconds) and appends its events to `out`;
    /// problems are counted in `problems` per message, so one bad message costs only itself.
    /// `data` empty on [`Channel::Tcp`] means the connection ended.
    pub fn decode(
        &mut self,
        channel: Channel,
        data: &[u8],
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
        problems: &mut ProblemLog,
    ) {
        self.idle(receive_t, out);
        self.last_receive = Some(receive_t);
        self.messages.clear();
        match channel {
            Channel::Tcp if data.is_empty() => self.end_of_stream(receive_t, out, problems),
            Channel::Tcp => self.tcp(data, receive_t, out, problems),
            Channel::Udp => self.udp(data, receive_t, out, problems),
        }
    }

    /// Nothing arrived up to `receive_t`: after [`VrpnConfig::silence_s`] without any input,
    /// every tracked sensor is reported lost (its last pose is stale). Live loops call this
    /// when a poll times out; [`Self::decode`] calls it first, so a replay, which has no idle
    /// polls, loses the sensors when the input resumes, before the next button press.
    pub fn idle(&mut self, receive_t: f64, out: &mut Vec<TrackingEvent>) {
        let s = self.config.silence_s;
        let silent = self.last_receive.is_some_and(|r| receive_t - r >= s);
        if s > 0.0 && silent && self.sensors.iter().any(|x| x.tracked) {
            let Some(t) = self.time_now(receive_t) else {
                return;
            };
            for i in 0..self.sensors.len() {
                if self.sensors[i].tracked {
                    self.sensors[i].tracked = false;
                    let dev = self.sensors[i].device;
                    out.push(self.state_event(t, dev, Some(Tracking::Lost)));
                }
            }
        }
    }

    /// The time of an event that has no time stamp of its own.
    fn time_now(&self, receive_t: f64) -> Option<f64> {
        match self.time_source {
            TimeSource::Receive => Some(receive_t),
            TimeSource::Tracker => self.clock,
        }
    }

    /// The time of an event stamped `stamp`; `None` when it has none and no clock is known.
    fn time_of(&self, stamp: VrpnTime, receive_t: f64) -> Option<f64> {
        match self.time_source {
            TimeSource::Receive => Some(receive_t),
            TimeSource::Tracker if stamp.is_zero() => self.clock,
            TimeSource::Tracker => Some(stamp.seconds()),
        }
    }

    fn advance_clock(&mut self, stamp: VrpnTime) {
        if !stamp.is_zero() {
            let s = stamp.seconds();
            self.clock = Some(match self.clock {
                Some(c) if c - s <= MAX_REORDER_S => c.max(s),
                _ => s,
            });
        }
    }

    fn state_event(&self, t: f64, device: usize, pose: Option<Tracking>) -> TrackingEvent {
        let d = &self.devices[device];
        TrackingEvent {
            pose,
            buttons: d.buttons,
            axes: d.axes.clone(),
            ..TrackingEvent::empty(t, d.id)
        }
    }

    fn break_stream(&mut self, problems: &mut ProblemLog, kind: &'static str, detail: String) {
        problems.report(
            kind,
            format_args!("{detail}; the rest of this connection is ignored"),
        );
        self.conn.broken = true;
        self.conn.pending.clear();
        self.wants_reconnect = true;
    }

    fn tcp(
        &mut self,
        mut data: &[u8],
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
        problems: &mut ProblemLog,
    ) {
        self.stats.tcp_bytes += data.len() as u64;
        if self.conn.broken {
            self.stats.ignored_bytes += data.len() as u64;
            return;
        }
        if !self.conn.cookie_ok {
            let c = &mut self.conn;
            let take = (COOKIE_LEN - c.cookie_have).min(data.len());
            c.cookie[c.cookie_have..c.cookie_have + take].copy_from_slice(&data[..take]);
            c.cookie_have += take;
            c.tcp_offset += take as u64;
            data = &data[take..];
            if c.cookie_have < COOKIE_LEN {
                return;
            }
            match check_cookie(&c.cookie) {
                Ok(_) => {
                    c.cookie_ok = true;
                    self.stats.connections += 1;
                }
                Err(e) => {
                    self.stats.ignored_bytes += data.len() as u64;
                    self.break_stream(problems, e.name(), format!("TCP stream: {e}"));
                    return;
                }
            }
        }
        let mut pending = std::mem::take(&mut self.conn.pending);
        pending.extend_from_slice(data);
        let mut at = 0;
        while let Some(h) = Header::read(&pending[at..]) {
            if let Err(e) = h.check_len() {
                let detail = format!(
                    "TCP message {} at stream byte {}: {e}",
                    self.conn.tcp_index, self.conn.tcp_offset
                );
                self.stats.ignored_bytes += (pending.len() - at) as u64;
                self.break_stream(problems, e.name(), detail);
                return;
            }
            let wire = h.wire_len();
            if pending.len() - at < wire {
                break;
            }
            let payload = &pending[at + HEADER_LEN..at + HEADER_LEN + h.payload_len()];
            self.message(Channel::Tcp, &h, payload, receive_t, out, problems);
            self.conn.tcp_index += 1;
            self.conn.tcp_offset += wire as u64;
            at += wire;
        }
        pending.drain(..at);
        // Bounded: a header stating more than MAX_MESSAGE_LEN broke the stream above, so what
        // stays is less than one message.
        self.conn.pending = pending;
    }

    fn udp(
        &mut self,
        data: &[u8],
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
        problems: &mut ProblemLog,
    ) {
        self.stats.udp_datagrams += 1;
        if self.conn.broken {
            self.stats.ignored_bytes += data.len() as u64;
            return;
        }
        let mut at = 0;
        while at < data.len() {
            let rest = &data[at..];
            let index = self.conn.udp_index;
            let Some(h) = Header::read(rest) else {
                let e = VrpnError::Truncated {
                    what: "a UDP message header",
                    have: rest.len(),
                    need: HEADER_LEN,
                };
                problems.report(e.name(), format_args!("UDP message {index}: {e}"));
                return;
            };
            if let Err(e) = h.check_len() {
                problems.report(
                    e.name(),
                    format_args!("UDP message {index}: {e}; the rest of the datagram is dropped"),
                );
                return;
            }
            // The last message of a datagram may lack its padding; its payload may not.
            if rest.len() < h.len as usize {
                let e = VrpnError::Truncated {
                    what: "a UDP message",
                    have: rest.len(),
                    need: h.len as usize,
                };
                problems.report(e.name(), format_args!("UDP message {index}: {e}"));
                return;
            }
            if let Some(next) = self.conn.udp_next_seq
                && h.seq > next
            {
                self.stats.udp_missing += u64::from(h.seq - next);
            }
            self.conn.udp_next_seq = Some(h.seq.wrapping_add(1));
            let payload = &rest[HEADER_LEN..h.len as usize];
            self.message(Channel::Udp, &h, payload, receive_t, out, problems);
            self.conn.udp_index += 1;
            at += h.wire_len().min(rest.len());
        }
    }

    fn flood_check(&mut self, receive_t: f64, problems: &mut ProblemLog) {
        let w = &mut self.flood;
        if !(receive_t - w.start < 1.0 && receive_t >= w.start) {
            *w = FloodWindow {
                start: receive_t,
                ..FloodWindow::default()
            };
        }
        w.count += 1;
        if w.count > FLOOD_MESSAGES_PER_S && !w.reported {
            w.reported = true;
            problems.report(
                "vrpn_flood",
                format_args!(
                    "more than {FLOOD_MESSAGES_PER_S} messages within one second (receive time {receive_t:.3} s)"
                ),
            );
        }
    }

    fn keep_message(
        &mut self,
        channel: Channel,
        header: &Header,
        sender: Option<String>,
        type_name: String,
        body: Body,
    ) {
        if self.keep {
            self.messages.push(VrpnMessage {
                channel,
                header: *header,
                sender,
                type_name,
                body,
            });
        }
    }

    fn message(
        &mut self,
        channel: Channel,
        h: &Header,
        payload: &[u8],
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
        problems: &mut ProblemLog,
    ) {
        self.stats.messages += 1;
        self.flood_check(receive_t, problems);
        let index = match channel {
            Channel::Tcp => self.conn.tcp_index,
            Channel::Udp => self.conn.udp_index,
        };
        let at = || format!("{channel} message {index} (seq {})", h.seq);
        if h.kind < 0 {
            match decode_system(h, payload) {
                Err(e) => problems.report(e.name(), format_args!("{}: {e}", at())),
                Ok(body) => {
                    match &body {
                        Body::SenderDescription { id, name } => {
                            let ours = *name == self.device;
                            let entry = SenderEntry {
                                name: name.clone(),
                                ours,
                            };
                            if let Err(e) =
                                describe(&mut self.conn.senders, "sender", *id, entry, |e| &e.name)
                            {
                                problems.report(e.name(), format_args!("{}: {e}", at()));
                            }
                        }
                        Body::TypeDescription { id, name } => {
                            let entry = TypeEntry {
                                name: name.clone(),
                                kind: TypeKind::from_name(name),
                            };
                            if let Err(e) =
                                describe(&mut self.conn.types, "type", *id, entry, |e| &e.name)
                            {
                                problems.report(e.name(), format_args!("{}: {e}", at()));
                            }
                        }
                        _ => {}
                    }
                    self.keep_message(channel, h, None, system_name(h.kind).into(), body);
                }
            }
            return;
        }
        let Some(sender) = entry(&self.conn.senders, h.sender) else {
            let e = VrpnError::UnknownSender { id: h.sender };
            problems.report(e.name(), format_args!("{}: {e}", at()));
            return;
        };
        let ours = sender.ours;
        let sender_name = self.keep.then(|| sender.name.clone());
        let Some(ty) = entry(&self.conn.types, h.kind) else {
            let e = VrpnError::UnknownType { id: h.kind };
            problems.report(e.name(), format_args!("{}: {e}", at()));
            return;
        };
        let kind = ty.kind;
        let type_name = if self.keep {
            ty.name.clone()
        } else {
            String::new()
        };
        if !ours {
            self.stats.other_senders += 1;
            return;
        }
        if h.time.usec >= 1_000_000 {
            let e = VrpnError::BadTime {
                sec: h.time.sec,
                usec: h.time.usec,
            };
            problems.report(e.name(), format_args!("{}: {e}", at()));
            return;
        }
        let body = match decode_payload(kind, payload) {
            Ok(b) => b,
            Err(e) => {
                problems.report(e.name(), format_args!("{}: {e}", at()));
                return;
            }
        };
        match &body {
            Body::PosQuat(p) => self.pose(h.time, p, receive_t, out),
            Body::ButtonChange { button, pressed } => {
                self.button_change(h.time, *button, *pressed, receive_t, out);
            }
            Body::ButtonStates(states) => self.button_states(h.time, states, receive_t, out),
            Body::Analog(values) => {
                if let Err(e) = self.analog(h.time, values, receive_t, out) {
                    problems.report(e.name(), format_args!("{}: {e}", at()));
                    return;
                }
            }
            _ => {}
        }
        self.keep_message(channel, h, sender_name, type_name, body);
    }

    /// The room pose of a report: the quaternion as received is normalised here, once, when
    /// it becomes a room-frame pose (VRPN does not normalise; the raw value stays in the
    /// message).
    fn room_pose(&self, p: &PosQuat) -> Pose {
        let [x, y, z, w] = p.quat_xyzw;
        let q = DQuat::from_xyzw(x, y, z, w).normalize();
        Pose {
            position: self.rotation * (DVec3::from_array(p.pos) * self.metres_per_unit)
                + self.translation,
            orientation: (self.rotation_q * q).normalize(),
        }
    }

    /// Ends the open frame: every known sensor it lacks is lost.
    fn close_frame(&mut self, out: &mut Vec<TrackingEvent>) {
        let Some(f) = self.frame.as_mut() else {
            return;
        };
        if f.closed {
            return;
        }
        f.closed = true;
        let (frame_s, t) = (f.stamp.seconds(), f.t);
        let tolerance = self.config.frame_tolerance_s;
        for i in 0..self.sensors.len() {
            let s = &self.sensors[i];
            if s.known && !s.seen_in_frame && frame_s - s.last.seconds() > tolerance {
                let dev = s.device;
                self.sensors[i].tracked = false;
                out.push(self.state_event(t, dev, Some(Tracking::Lost)));
            }
        }
    }

    /// A button report stamped at or after the open frame's time ends that frame:
    /// vrpn_Tracker_DTrack sends a frame's buttons after all of its poses.
    fn close_frame_before(&mut self, stamp: VrpnTime, out: &mut Vec<TrackingEvent>) {
        if !stamp.is_zero() && self.frame.is_some_and(|f| stamp >= f.stamp) {
            self.close_frame(out);
        }
    }

    fn pose(&mut self, stamp: VrpnTime, p: &PosQuat, receive_t: f64, out: &mut Vec<TrackingEvent>) {
        self.stats.pos_quat += 1;
        let t = self.time_of(stamp, receive_t);
        if !stamp.is_zero() {
            match self.frame {
                Some(f)
                    if stamp < f.stamp && f.stamp.seconds() - stamp.seconds() <= MAX_REORDER_S =>
                {
                    self.stats.stale += 1;
                    return;
                }
                Some(f) if stamp == f.stamp => {}
                _ => {
                    self.close_frame(out);
                    for s in &mut self.sensors {
                        s.seen_in_frame = false;
                    }
                    self.frame = Some(Frame {
                        stamp,
                        t: t.unwrap_or(receive_t),
                        closed: false,
                    });
                }
            }
            self.advance_clock(stamp);
        }
        let Ok(i) = self.sensors.binary_search_by_key(&p.sensor, |s| s.sensor) else {
            self.stats.unmapped += 1;
            return;
        };
        let pose = self.room_pose(p);
        let s = &mut self.sensors[i];
        s.known = true;
        s.tracked = true;
        s.seen_in_frame = true;
        if !stamp.is_zero() {
            s.last = stamp;
        }
        let dev = s.device;
        if let Some(t) = t {
            out.push(self.state_event(t, dev, Some(Tracking::Tracked(pose))));
        }
    }

    fn button_change(
        &mut self,
        stamp: VrpnTime,
        button: u32,
        pressed: bool,
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
    ) {
        self.stats.button_changes += 1;
        self.close_frame_before(stamp, out);
        self.advance_clock(stamp);
        let Some(&(ref g, dev)) = self
            .buttons
            .iter()
            .find(|(g, _)| (g.first..g.first + g.count).contains(&button))
        else {
            self.stats.unmapped += 1;
            return;
        };
        let bit = 1u32 << (button - g.first);
        let mask = self.devices[dev].buttons.get_or_insert(0);
        if pressed {
            *mask |= bit;
        } else {
            *mask &= !bit;
        }
        if let Some(t) = self.time_of(stamp, receive_t) {
            out.push(self.state_event(t, dev, None));
        }
    }

    fn button_states(
        &mut self,
        stamp: VrpnTime,
        states: &[bool],
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
    ) {
        self.stats.button_states += 1;
        self.close_frame_before(stamp, out);
        self.advance_clock(stamp);
        let t = self.time_of(stamp, receive_t);
        for k in 0..self.buttons.len() {
            let (g, dev) = (&self.buttons[k].0, self.buttons[k].1);
            let old = self.devices[dev].buttons.unwrap_or(0);
            let mut mask = old;
            for i in 0..g.count {
                if let Some(&on) = states.get((g.first + i) as usize) {
                    mask = if on { mask | 1 << i } else { mask & !(1 << i) };
                }
            }
            self.devices[dev].buttons = Some(mask);
            // The connect-time message (time 0, before any data) changes nothing to report.
            if let (true, Some(t)) = (mask != old, t) {
                out.push(self.state_event(t, dev, None));
            }
        }
    }

    /// Analog reports of vrpn_Tracker_DTrack carry the server's clock, not DTrack's `ts`; on
    /// two machines those differ by any amount, so in tracker time an analog report takes the
    /// time of the device's latest tracker or button report (the frame it belongs to) and
    /// keeps its own stamp only before there is one.
    fn analog(
        &mut self,
        stamp: VrpnTime,
        values: &[f64],
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
    ) -> Result<(), VrpnError> {
        self.stats.analog += 1;
        for (g, _) in &self.analogs {
            for ch in g.first..g.first + g.count {
                if let Some(&v) = values.get(ch as usize)
                    && !(-1.0..=1.0).contains(&v)
                {
                    return Err(VrpnError::OutOfRange {
                        type_name: "Analog Channel",
                        field: "mapped stick axis",
                        value: v,
                        range: "-1..=1",
                    });
                }
            }
        }
        let t = match self.time_source {
            TimeSource::Receive => Some(receive_t),
            TimeSource::Tracker => self.clock.or((!stamp.is_zero()).then(|| stamp.seconds())),
        };
        let mut mapped = false;
        for k in 0..self.analogs.len() {
            let (g, dev) = (&self.analogs[k].0, self.analogs[k].1);
            // One axis per mapped channel (made so in `new`; the config allows one analog
            // group per device).
            let axes = self.devices[dev]
                .axes
                .get_or_insert_with(|| vec![0.0; g.count as usize]);
            let mut changed = false;
            for (i, axis) in axes.iter_mut().enumerate() {
                if let Some(&v) = values.get(g.first as usize + i) {
                    *axis = v * g.sign(i);
                    changed = true;
                }
            }
            if changed {
                mapped = true;
                if let Some(t) = t {
                    out.push(self.state_event(t, dev, None));
                }
            }
        }
        if !mapped {
            self.stats.unmapped += 1;
        }
        Ok(())
    }

    /// The connection ended (a zero-byte read): every device is lost, its buttons released
    /// and its stick centred (nobody knows their state now), and the next connection starts
    /// from its cookie with fresh id tables.
    fn end_of_stream(
        &mut self,
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
        problems: &mut ProblemLog,
    ) {
        let c = &self.conn;
        if !c.broken {
            if (1..COOKIE_LEN).contains(&c.cookie_have) {
                let e = VrpnError::Truncated {
                    what: "the cookie",
                    have: c.cookie_have,
                    need: COOKIE_LEN,
                };
                problems.report(e.name(), format_args!("TCP stream ended: {e}"));
            } else if !c.pending.is_empty() {
                let need = Header::read(&c.pending).map_or(HEADER_LEN, |h| h.wire_len());
                let e = VrpnError::Truncated {
                    what: "the last TCP message",
                    have: c.pending.len(),
                    need,
                };
                problems.report(
                    e.name(),
                    format_args!("TCP stream ended at byte {}: {e}", c.tcp_offset),
                );
            }
        }
        let t = self.time_now(receive_t);
        for dev in 0..self.devices.len() {
            let known = self.sensors.iter().any(|s| s.device == dev && s.known);
            let d = &mut self.devices[dev];
            let held = d.buttons.is_some_and(|b| b != 0)
                || d.axes.as_ref().is_some_and(|a| a.iter().any(|v| *v != 0.0));
            if let Some(b) = &mut d.buttons {
                *b = 0;
            }
            if let Some(a) = &mut d.axes {
                a.iter_mut().for_each(|v| *v = 0.0);
            }
            if let (true, Some(t)) = (known || held, t) {
                let pose = (known && d.has_sensor).then_some(Tracking::Lost);
                out.push(self.state_event(t, dev, pose));
            }
        }
        for s in &mut self.sensors {
            s.known = false;
            s.tracked = false;
            s.seen_in_frame = false;
        }
        self.frame = None;
        self.conn = Connection::default();
        self.wants_reconnect = false;
    }
}

/// Adds a description to an id table; a second description of an id with another name is
/// refused (a valid stream never does this, and switching mid-stream could route one device's
/// data to another).
fn describe<E>(
    table: &mut Vec<Option<E>>,
    what: &'static str,
    id: i32,
    entry: E,
    name: impl Fn(&E) -> &String,
) -> Result<(), VrpnError> {
    // decode_system checked 0 <= id < MAX_IDS.
    let i = usize::try_from(id).map_err(|_| VrpnError::IdOutOfRange { what, id })?;
    if i >= table.len() {
        table.resize_with(i + 1, || None);
    }
    match &table[i] {
        Some(old) if name(old) != name(&entry) => Err(VrpnError::Redefined {
            what,
            id,
            old: name(old).chars().take(100).collect(),
            new: name(&entry).chars().take(100).collect(),
        }),
        Some(_) => Ok(()),
        None => {
            table[i] = Some(entry);
            Ok(())
        }
    }
}

fn entry<E>(v: &[Option<E>], id: i32) -> Option<&E> {
    usize::try_from(id).ok().and_then(|i| v.get(i)?.as_ref())
}

fn table<E>(v: &[Option<E>], name: impl Fn(&E) -> &String) -> Vec<(i32, &str)> {
    v.iter()
        .enumerate()
        .filter_map(|(i, e)| Some((i as i32, name(e.as_ref()?).as_str())))
        .collect()
}

#[cfg(test)]
mod tests;
