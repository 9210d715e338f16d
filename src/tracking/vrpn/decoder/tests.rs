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
        d.conn.pending.len() < MAX_MESSAGE_LEN && d.conn.pending.len() == s.bytes.len() - 1 - at
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
