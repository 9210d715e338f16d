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
mod tests {
    use super::*;
    use crate::tracking::dtrack::TrackerToRoom;
    use crate::tracking::event::DeviceKind;
    use crate::tracking::vrpn::wire::{MAX_MESSAGE_LEN, encode};
    use proptest::prelude::*;

    const POS_QUAT: i32 = 4;
    const CHANGE: i32 = 18;
    const STATES: i32 = 19;
    const ANALOG: i32 = 22;
    const ID_Q: [f64; 4] = [0.0, 0.0, 0.0, 1.0];

    fn flystick() -> DeviceId {
        DeviceId::new(DeviceKind::Flystick, 0)
    }

    fn body() -> DeviceId {
        DeviceId::new(DeviceKind::Body, 0)
    }

    /// A server's byte stream: cookie, the descriptions vrpn_server sends, then messages.
    struct Stream {
        bytes: Vec<u8>,
        seq: u32,
    }

    impl Stream {
        fn new() -> Self {
            let mut s = Self {
                bytes: encode::cookie().to_vec(),
                seq: 0,
            };
            for (id, name) in [(0, "VRPN Control"), (1, "DTrack"), (2, "Other")] {
                encode::sender_description(&mut s.bytes, s.seq, id, name);
                s.seq += 1;
            }
            for (id, name) in [
                (POS_QUAT, "vrpn_Tracker Pos_Quat"),
                (CHANGE, "vrpn_Button Change"),
                (STATES, "vrpn_Button States"),
                (ANALOG, "vrpn_Analog Channel"),
                (15, "vrpn_Base text_message"),
            ] {
                encode::type_description(&mut s.bytes, s.seq, id, name);
                s.seq += 1;
            }
            s
        }

        fn msg(&mut self, t: f64, sender: i32, kind: i32, payload: &[u8]) -> &mut Self {
            encode::message(
                &mut self.bytes,
                VrpnTime::from_seconds(t),
                sender,
                kind,
                self.seq,
                payload,
            );
            self.seq += 1;
            self
        }

        fn pose(&mut self, t: f64, sensor: i32, pos: [f64; 3]) -> &mut Self {
            self.msg(t, 1, POS_QUAT, &encode::pos_quat(sensor, pos, ID_Q))
        }

        fn button(&mut self, t: f64, button: i32, state: i32) -> &mut Self {
            self.msg(t, 1, CHANGE, &encode::button_change(button, state))
        }
    }

    fn decoder(config: VrpnConfig) -> VrpnDecoder {
        VrpnDecoder::new("DTrack", config, TimeSource::Tracker).unwrap()
    }

    fn decode_all(d: &mut VrpnDecoder, bytes: &[u8]) -> (Vec<TrackingEvent>, ProblemLog) {
        let mut out = Vec::new();
        let mut p = ProblemLog::quiet();
        d.decode(Channel::Tcp, bytes, 0.0, &mut out, &mut p);
        (out, p)
    }

    fn kinds(events: &[TrackingEvent], device: DeviceId) -> Vec<&'static str> {
        events
            .iter()
            .filter(|e| e.device == device)
            .map(|e| match e.pose {
                Some(Tracking::Tracked(_)) => "tracked",
                Some(Tracking::Lost) => "lost",
                None => "state",
            })
            .collect()
    }

    #[test]
    fn a_pose_goes_through_the_calibration_and_carries_the_sticks_state() {
        // Tracker Z up (DTrack's factory frame), in metres as VRPN sends them.
        let config = VrpnConfig {
            tracker_to_room: TrackerToRoom {
                translation_m: [1.0, 0.0, 0.0],
                metres_per_unit: 1.0,
                ..TrackerToRoom::z_up()
            },
            ..VrpnConfig::default()
        };
        let mut d = decoder(config);
        let mut s = Stream::new();
        // Not normalised on the wire (as vrpn_Tracker_DTrack sends it).
        s.msg(
            5.0,
            1,
            POS_QUAT,
            &encode::pos_quat(1, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0 + 3e-7]),
        );
        let (events, p) = decode_all(&mut d, &s.bytes);
        assert_eq!(p.total(), 0, "{:?}", p.counts());
        let [e] = &events[..] else {
            panic!("{events:?}")
        };
        assert_eq!((e.t, e.device, e.buttons), (5.0, flystick(), Some(0)));
        assert_eq!(e.axes, Some(vec![0.0, 0.0]));
        let Some(Tracking::Tracked(pose)) = e.pose else {
            panic!()
        };
        // Tracker Z up, metres: 1 m above the origin is room (0, 1, 0) + offset.
        assert!((pose.position - DVec3::new(1.0, 1.0, 0.0)).length() < 1e-12);
        assert!(pose.is_valid());
        assert!((pose.orientation * DVec3::NEG_Z - DVec3::NEG_Y).length() < 1e-12);
    }

    #[test]
    fn a_sensor_missing_from_a_frame_is_lost_in_every_such_frame() {
        let mut d = decoder(VrpnConfig::default());
        let mut s = Stream::new();
        s.pose(1.0, 0, [0.0; 3]).pose(1.0, 1, [0.0; 3]);
        s.pose(2.0, 0, [0.0; 3]);
        s.pose(3.0, 0, [0.0; 3]);
        s.pose(4.0, 0, [0.0; 3]).pose(4.0, 1, [0.0; 3]);
        let (events, p) = decode_all(&mut d, &s.bytes);
        assert_eq!(p.total(), 0);
        // Frame 2 ends when frame 3 starts, frame 3 when frame 4 starts.
        assert_eq!(
            kinds(&events, flystick()),
            ["tracked", "lost", "lost", "tracked"]
        );
        let lost: Vec<f64> = events
            .iter()
            .filter(|e| e.pose == Some(Tracking::Lost))
            .map(|e| e.t)
            .collect();
        assert_eq!(lost, [2.0, 3.0]);
        assert_eq!(kinds(&events, body()), ["tracked"; 4]);
    }

    #[test]
    fn a_button_of_the_same_frame_sees_the_stick_lost_not_its_stale_pose() {
        let mut d = decoder(VrpnConfig::default());
        let mut s = Stream::new();
        s.pose(1.0, 0, [0.0; 3]).pose(1.0, 1, [0.0; 3]);
        // Frame 2: the stick is untracked and its trigger is pressed.
        s.pose(2.0, 0, [0.0; 3]).button(2.0, 0, 1);
        let (events, _) = decode_all(&mut d, &s.bytes);
        assert_eq!(kinds(&events, flystick()), ["tracked", "lost", "state"]);
        assert_eq!(events.last().unwrap().buttons, Some(1));
    }

    #[test]
    fn servers_stamping_each_sensor_need_a_frame_tolerance() {
        let mut s = Stream::new();
        for k in 0..5 {
            let t = f64::from(k) / 60.0;
            s.pose(t, 0, [0.0; 3]).pose(t + 5e-6, 1, [0.0; 3]);
        }
        let (events, _) = decode_all(&mut decoder(VrpnConfig::default()), &s.bytes);
        assert!(
            kinds(&events, body()).contains(&"lost"),
            "without a tolerance each report is its own frame"
        );
        let tolerant = VrpnConfig {
            frame_tolerance_s: 0.025,
            ..VrpnConfig::default()
        };
        let (events, _) = decode_all(&mut decoder(tolerant), &s.bytes);
        assert!(
            events
                .iter()
                .all(|e| matches!(e.pose, Some(Tracking::Tracked(_))))
        );
    }

    #[test]
    fn analogs_map_with_signs_and_take_the_frames_clock() {
        let config = VrpnConfig {
            analogs: vec![AnalogGroup {
                device: flystick(),
                first: 0,
                count: 2,
                signs: vec![1.0, -1.0],
            }],
            ..VrpnConfig::default()
        };
        let mut d = decoder(config);
        let mut s = Stream::new();
        s.pose(100.0, 1, [0.0; 3]);
        // Stamped by another clock, seconds away from the tracker's.
        s.msg(7.0, 1, ANALOG, &encode::analog(&[0.5, 0.25]));
        s.button(100.0, 2, 1);
        let (events, p) = decode_all(&mut d, &s.bytes);
        assert_eq!(p.total(), 0);
        assert_eq!(events[1].t, 100.0);
        assert_eq!(events[1].axes, Some(vec![0.5, -0.25]));
        assert_eq!(events[2].buttons, Some(0b100));
        assert_eq!(events[2].axes, Some(vec![0.5, -0.25]));
        // A mapped channel outside [-1, 1] is refused, the others still count.
        let mut s2 = Stream::new();
        s2.msg(7.0, 1, ANALOG, &encode::analog(&[1.5, 0.0]));
        let (events, p) = decode_all(&mut decoder(VrpnConfig::default()), &s2.bytes);
        assert!(events.is_empty());
        assert_eq!(p.count("vrpn_out_of_range"), 1);
    }

    #[test]
    fn button_states_at_connect_with_time_zero_emit_nothing() {
        let mut d = decoder(VrpnConfig::default());
        let mut s = Stream::new();
        s.msg(0.0, 1, STATES, &encode::button_states(&[]));
        s.msg(0.0, 1, STATES, &encode::button_states(&[1, 0, 1]));
        let (events, p) = decode_all(&mut d, &s.bytes);
        // No time is known yet: an event at t = 0 would start the session in 1970.
        assert_eq!((events.len(), p.total()), (0, 0));
        // The state is kept and goes out with the next report.
        let mut tail = Vec::new();
        encode::message(
            &mut tail,
            VrpnTime::new(9, 0),
            1,
            POS_QUAT,
            99,
            &encode::pos_quat(1, [0.0; 3], ID_Q),
        );
        let (events, _) = decode_all(&mut d, &tail);
        assert_eq!(events[0].buttons, Some(0b101));
    }

    #[test]
    fn byte_by_byte_reads_decode_exactly_as_one_read() {
        let mut s = Stream::new();
        for k in 0..20 {
            let t = 1.0 + f64::from(k) / 60.0;
            s.pose(t, 0, [0.1, 0.2, 0.3]);
            if k % 3 != 0 {
                s.pose(t, 1, [f64::from(k), 0.0, 0.0]);
            }
            if k % 4 == 1 {
                s.button(t, 0, k % 8 / 4);
                s.msg(t + 1e-4, 1, ANALOG, &encode::analog(&[0.1, -0.1]));
            }
        }
        let (whole, _) = decode_all(&mut decoder(VrpnConfig::default()), &s.bytes);
        let mut d = decoder(VrpnConfig::default());
        let mut out = Vec::new();
        let mut p = ProblemLog::quiet();
        for b in &s.bytes {
            d.decode(Channel::Tcp, std::slice::from_ref(b), 0.0, &mut out, &mut p);
        }
        assert_eq!(p.total(), 0);
        assert!(!whole.is_empty());
        assert_eq!(out, whole);
    }

    #[test]
    fn the_end_of_a_connection_loses_everything_and_releases_the_buttons() {
        let mut d = decoder(VrpnConfig::default());
        let mut s = Stream::new();
        s.pose(1.0, 0, [0.0; 3])
            .pose(1.0, 1, [0.0; 3])
            .button(1.0, 0, 1);
        let cut = s.bytes.len();
        s.pose(2.0, 1, [0.0; 3]);
        let (mut events, mut p) = decode_all(&mut d, &s.bytes[..cut + 10]);
        d.decode(Channel::Tcp, &[], 0.1, &mut events, &mut p);
        assert_eq!(p.count("vrpn_truncated"), 1, "{:?}", p.counts());
        let end: Vec<_> = events.iter().skip(3).collect();
        assert_eq!(end.len(), 2, "{end:?}");
        assert!(
            end.iter()
                .all(|e| e.pose == Some(Tracking::Lost) && e.t == 1.0)
        );
        let stick = end.iter().find(|e| e.device == flystick()).unwrap();
        assert_eq!(stick.buttons, Some(0));
        // A new connection starts from its cookie with fresh ids.
        let (events, p) = decode_all(&mut d, &Stream::new().pose(3.0, 1, [0.0; 3]).bytes);
        assert_eq!((events.len(), p.total()), (1, 0));
        assert_eq!(d.stats().connections, 2);
    }

    #[test]
    fn a_wrong_cookie_or_major_version_breaks_the_stream_once() {
        for (cookie, kind) in [
            (
                encode::cookie_with(b"vrpn: ver. 08.00"),
                "vrpn_version_mismatch",
            ),
            (*b"SSH-2.0-OpenSSH_9.6\r\n\0\0\0", "vrpn_bad_cookie"),
        ] {
            let mut d = decoder(VrpnConfig::default());
            let mut s = Stream::new();
            s.bytes[..COOKIE_LEN].copy_from_slice(&cookie);
            s.pose(1.0, 1, [0.0; 3]);
            let (events, p) = decode_all(&mut d, &s.bytes);
            assert!(events.is_empty());
            assert_eq!((p.count(kind), p.total()), (1, 1), "{:?}", p.counts());
            assert!(d.take_reconnect() && !d.take_reconnect());
            // The rest of the connection is ignored, not counted again.
            let (_, p) = decode_all(&mut d, &s.bytes);
            assert_eq!(p.total(), 0);
        }
        // A 07.35 server is fine.
        let mut s = Stream::new();
        s.bytes[..COOKIE_LEN].copy_from_slice(&encode::cookie_with(b"vrpn: ver. 07.35"));
        let (events, p) = decode_all(
            &mut decoder(VrpnConfig::default()),
            &s.pose(1.0, 1, [0.0; 3]).bytes,
        );
        assert_eq!((events.len(), p.total()), (1, 0));
    }

    #[test]
    fn impossible_lengths_break_the_stream_and_keep_memory_bounded() {
        for (len, kind) in [
            (12u32, "vrpn_length_too_small"),
            (MAX_MESSAGE_LEN as u32 + 1, "vrpn_length_too_large"),
            (u32::MAX, "vrpn_length_too_large"),
        ] {
            let mut d = decoder(VrpnConfig::default());
            let mut s = Stream::new();
            s.pose(1.0, 1, [0.0; 3]);
            let at = s.bytes.len();
            s.pose(2.0, 1, [0.0; 3]);
            s.bytes[at..at + 4].copy_from_slice(&len.to_be_bytes());
            let (events, p) = decode_all(&mut d, &s.bytes);
            assert_eq!(events.len(), 1, "the message before is decoded");
            assert_eq!((p.count(kind), p.total()), (1, 1));
            assert!(
                p.logged(kind)
                    .unwrap()
                    .contains("TCP message 9 at stream byte"),
                "{:?}",
                p.logged(kind)
            );
            let (_, p) = decode_all(&mut d, &vec![0xab; 1 << 20]);
            assert_eq!(p.total(), 0);
            assert!(d.conn.pending.is_empty());
        }
        // A message that never completes holds at most one message's bytes.
        let mut d = decoder(VrpnConfig::default());
        let mut s = Stream::new();
        let at = s.bytes.len();
        s.msg(1.0, 1, 15, &vec![b'x'; MAX_MESSAGE_LEN - 24]);
        let (_, p) = decode_all(&mut d, &s.bytes[..s.bytes.len() - 1]);
        assert_eq!(p.total(), 0);
        assert!(
            d.conn.pending.len() < MAX_MESSAGE_LEN
                && d.conn.pending.len() == s.bytes.len() - 1 - at
        );
    }

    #[test]
    fn unknown_and_redefined_ids_and_other_devices() {
        let mut d = decoder(VrpnConfig::default());
        let mut s = Stream::new();
        s.msg(1.0, 7, POS_QUAT, &encode::pos_quat(1, [0.0; 3], ID_Q));
        s.msg(1.0, 1, 99, &encode::pos_quat(1, [0.0; 3], ID_Q));
        // Redefining sender 1 as "Other" is refused: its poses stay the DTrack device's.
        encode::sender_description(&mut s.bytes, 50, 1, "Other");
        encode::sender_description(&mut s.bytes, 51, 1, "DTrack");
        encode::type_description(&mut s.bytes, 52, 99, "vrpn_Tracker Pos_Quat");
        s.msg(1.0, 2, POS_QUAT, &encode::pos_quat(1, [0.0; 3], ID_Q));
        s.msg(1.0, 1, 99, &encode::pos_quat(1, [0.0; 3], ID_Q));
        let (events, p) = decode_all(&mut d, &s.bytes);
        assert_eq!(p.count("vrpn_unknown_sender"), 1);
        assert_eq!(p.count("vrpn_unknown_type"), 1);
        assert_eq!(p.count("vrpn_redefined_id"), 1);
        assert_eq!(p.total(), 3);
        assert_eq!(events.len(), 1);
        assert_eq!(d.stats().other_senders, 1);
    }

    #[test]
    fn silence_loses_the_tracked_sensors_once() {
        let mut d = decoder(VrpnConfig::default());
        let mut s = Stream::new();
        s.pose(1.0, 1, [0.0; 3]);
        let mut out = Vec::new();
        let mut p = ProblemLog::quiet();
        d.decode(Channel::Tcp, &s.bytes, 10.0, &mut out, &mut p);
        d.idle(10.2, &mut out);
        assert_eq!(out.len(), 1);
        d.idle(10.3, &mut out);
        d.idle(11.0, &mut out);
        assert_eq!(out.len(), 2);
        assert_eq!(out[1].pose, Some(Tracking::Lost));
        assert_eq!(out[1].t, 1.0, "in tracker time, at the last known time");
    }

    #[test]
    fn udp_datagrams_use_the_tcp_ids_and_count_missing_sequence_numbers() {
        let mut d = decoder(VrpnConfig::default());
        let (_, p) = decode_all(&mut d, &Stream::new().bytes);
        assert_eq!(p.total(), 0);
        let mut out = Vec::new();
        let mut p = ProblemLog::quiet();
        for (seq, t) in [(0u32, 1.0), (1, 1.1), (5, 1.2)] {
            let mut dg = Vec::new();
            encode::message(
                &mut dg,
                VrpnTime::from_seconds(t),
                1,
                POS_QUAT,
                seq,
                &encode::pos_quat(1, [0.0; 3], ID_Q),
            );
            d.decode(Channel::Udp, &dg, 0.0, &mut out, &mut p);
        }
        assert_eq!((out.len(), p.total(), d.stats().udp_missing), (3, 0, 3));
        // A datagram cut inside its message is counted and dropped.
        let mut dg = Vec::new();
        encode::message(
            &mut dg,
            VrpnTime::new(2, 0),
            1,
            POS_QUAT,
            6,
            &encode::pos_quat(1, [0.0; 3], ID_Q),
        );
        d.decode(Channel::Udp, &dg[..50], 0.0, &mut out, &mut p);
        d.decode(Channel::Udp, &dg[..10], 0.0, &mut out, &mut p);
        assert_eq!((out.len(), p.count("vrpn_truncated")), (3, 2));
    }

    #[test]
    fn late_reports_are_dropped_but_a_clock_set_back_is_followed() {
        let mut s = Stream::new();
        s.pose(100.0, 1, [0.0; 3]).pose(99.99, 1, [1.0, 0.0, 0.0]);
        s.pose(50.0, 1, [2.0, 0.0, 0.0])
            .pose(50.1, 1, [3.0, 0.0, 0.0]);
        let mut d = decoder(VrpnConfig::default());
        let (events, _) = decode_all(&mut d, &s.bytes);
        let t: Vec<f64> = events.iter().map(|e| e.t).collect();
        assert_eq!(t, [100.0, 50.0, 50.1]);
        assert_eq!(d.stats().stale, 1);
    }

    #[test]
    fn a_flood_is_reported_once() {
        let mut d = decoder(VrpnConfig::default());
        let mut s = Stream::new();
        let one = {
            let mut m = Vec::new();
            encode::message(&mut m, VrpnTime::new(1, 0), 1, 15, 0, &[]);
            m
        };
        for _ in 0..FLOOD_MESSAGES_PER_S + 10 {
            s.bytes.extend_from_slice(&one);
        }
        let (_, p) = decode_all(&mut d, &s.bytes);
        assert_eq!((p.count("vrpn_flood"), p.total()), (1, 1));
    }

    proptest! {
        #[test]
        fn arbitrary_bytes_never_panic_and_events_stay_valid(
            chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..200), 0..8),
            prefix in any::<bool>(),
        ) {
            let mut d = decoder(VrpnConfig::default());
            let mut out = Vec::new();
            let mut p = ProblemLog::quiet();
            if prefix {
                d.decode(Channel::Tcp, &Stream::new().bytes, 0.0, &mut out, &mut p);
            }
            for (i, c) in chunks.iter().enumerate() {
                let ch = if i % 3 == 2 { Channel::Udp } else { Channel::Tcp };
                d.decode(ch, c, i as f64, &mut out, &mut p);
            }
            prop_assert!(out.iter().all(TrackingEvent::is_valid));
            prop_assert!(d.conn.pending.len() <= MAX_MESSAGE_LEN + 200 * 8);
        }

        #[test]
        fn mutated_streams_never_panic(at in 0usize..2000, byte in any::<u8>(), cut in 0usize..2000) {
            let mut s = Stream::new();
            s.pose(1.0, 0, [0.0; 3]).pose(1.0, 1, [0.0; 3]).button(1.0, 0, 1);
            s.msg(1.0, 1, ANALOG, &encode::analog(&[0.5, 0.5]));
            s.msg(0.0, 1, STATES, &encode::button_states(&[1, 0]));
            let mut b = s.bytes.clone();
            let n = b.len();
            b[at % n] = byte;
            b.truncate(cut % (n + 1));
            let mut d = decoder(VrpnConfig::default());
            let (events, _) = decode_all(&mut d, &b);
            prop_assert!(events.iter().all(TrackingEvent::is_valid));
        }
    }
}
