//! VRPN end to end. The real `vrpn_server` captures in `tests/data/vrpn/` are served by fake
//! servers written here (a thread on 127.0.0.1:0 that writes its cookie first, as vrpn_server
//! does) to the live client: over TCP in one write and in tiny chunks, and in VRPN's classic
//! UDP set-up (lob, call-back, cookies, the client's UDP description, then TCP and UDP). Each
//! must decode exactly what the capture's JSON listing says. The captures' replays, the live
//! sessions and a recording give the golden ROI changes on HORNET; bad servers of every kind
//! are counted once per kind.
//!
//! `RAYGUN_BLESS=1 cargo test --test tracking tracking_vrpn::` rewrites the replays and golden files.

use crate::walls;

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use glam::DQuat;
use raygun::display::DisplayModel;
use raygun::interaction::{Interaction, InteractionConfig};
use raygun::session::pipeline::Pipeline;
use raygun::session::replay::{ChangePrinter, ReplayOptions, ReplayPlan, golden_path};
use raygun::session::udp::Live;
use raygun::session::vrpn::{VrpnClientConfig, VrpnClientError, VrpnPoll, VrpnSource};
use raygun::tracking::dtrack::{DtrackConfig, DtrackDecoder, TimeSource, TrackerToRoom};
use raygun::tracking::event::{DeviceId, DeviceKind, Tracking, TrackingEvent};
use raygun::tracking::ingest::{Ingest, Protocol};
use raygun::tracking::problems::ProblemLog;
use raygun::tracking::replay::{ReplayHeader, ReplayPayload, ReplayReader, ReplayWriter};
use raygun::tracking::vrpn::wire::{self, Body, Header, VrpnTime, encode};
use raygun::tracking::vrpn::{self, Channel, VrpnAddress, VrpnConfig, VrpnHeader, VrpnMessage};
use serde_json::Value;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/vrpn")
        .join(name)
}

fn read(name: &str) -> Vec<u8> {
    std::fs::read(data(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn listing(name: &str) -> Value {
    serde_json::from_slice(&read(name)).unwrap()
}

fn bless() -> bool {
    std::env::var_os("RAYGUN_BLESS").is_some()
}

fn flystick() -> DeviceId {
    DeviceId::new(DeviceKind::Flystick, 0)
}

fn body() -> DeviceId {
    DeviceId::new(DeviceKind::Body, 0)
}

/// The calibration of the golden files (see `tests/data/vrpn/PROVENANCE.md`): the capture's
/// tracker frame is Y up, so no rotation; its origin at room (0, −1.2, 1.25) puts the
/// FlyStick about 1 m in front of HORNET's centre.
fn golden_config() -> VrpnConfig {
    VrpnConfig {
        tracker_to_room: TrackerToRoom {
            rotation_rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation_m: [0.0, -1.2, 1.25],
            metres_per_unit: 1.0,
        },
        ..VrpnConfig::default()
    }
}

/// The datagrams of a `.udp.bin`: each a u32 big-endian length, then the bytes.
fn datagrams(bytes: &[u8]) -> Vec<Vec<u8>> {
    let mut v = Vec::new();
    let mut at = 0;
    while at < bytes.len() {
        let n = u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        v.push(bytes[at + 4..at + 4 + n].to_vec());
        at += 4 + n;
    }
    v
}

/// The messages of a server's TCP stream after its cookie, whole (padding included).
fn split_messages(stream: &[u8]) -> Vec<(Header, &[u8])> {
    let mut v = Vec::new();
    let mut at = wire::COOKIE_LEN;
    while at < stream.len() {
        let h = Header::read(&stream[at..]).unwrap();
        v.push((h, &stream[at..at + h.wire_len()]));
        at += h.wire_len();
    }
    v
}

/// A capture cut into the reads a client gets: TCP messages grouped per time stamp (those
/// without a time join the read before them; the cookie starts the first), UDP datagrams one
/// by one, merged in time order with each frame's datagram before the frame's TCP button
/// messages (vrpn_Tracker_DTrack sends a frame's poses before its buttons). `t` is the time
/// since the first message, never decreasing.
fn reads_of(tcp: &[u8], udp: &[Vec<u8>]) -> Vec<(Protocol, f64, Vec<u8>)> {
    let mut units: Vec<(VrpnTime, u8, Vec<u8>)> = Vec::new();
    let mut current: Option<(VrpnTime, Vec<u8>)> = Some((VrpnTime::default(), tcp[..24].to_vec()));
    for (h, bytes) in split_messages(tcp) {
        match &mut current {
            Some((stamp, buf)) if h.time.is_zero() || *stamp == h.time || stamp.is_zero() => {
                if stamp.is_zero() {
                    *stamp = h.time;
                }
                buf.extend_from_slice(bytes);
            }
            _ => {
                if let Some((s, b)) = current.take() {
                    units.push((s, 1, b));
                }
                current = Some((h.time, bytes.to_vec()));
            }
        }
    }
    units.extend(current.map(|(s, b)| (s, 1, b)));
    for d in udp {
        units.push((Header::read(d).unwrap().time, 0, d.clone()));
    }
    // Stable: TCP reads keep their order among themselves.
    units.sort_by_key(|(stamp, rank, _)| (*stamp, *rank));
    let t0 = units
        .iter()
        .map(|u| u.0)
        .find(|s| !s.is_zero())
        .unwrap()
        .seconds();
    let mut last = 0.0_f64;
    units
        .into_iter()
        .map(|(stamp, rank, bytes)| {
            if !stamp.is_zero() {
                last = last.max(stamp.seconds() - t0);
            }
            let p = if rank == 0 {
                Protocol::VrpnUdp
            } else {
                Protocol::VrpnTcp
            };
            // Microseconds, so the file prints short and reads back bit-exact.
            (p, (last * 1e6).round() / 1e6, bytes)
        })
        .collect()
}

/// A capture as a raygun replay file.
fn capture_replay(tcp: &[u8], udp: &[Vec<u8>], source: &str, description: &str) -> Vec<u8> {
    let mut header = ReplayHeader::vrpn_recording(&source.parse().unwrap(), &golden_config());
    header.description = description.into();
    header.display = Some("display-models/hornet.json".into());
    header.device = Some(flystick());
    let mut w = ReplayWriter::new(Vec::new(), &header).unwrap();
    for (p, t, bytes) in reads_of(tcp, udp) {
        w.datagram(t, p, &bytes).unwrap();
    }
    w.into_inner()
}

struct Capture {
    name: &'static str,
    tcp: Vec<u8>,
    udp: Vec<Vec<u8>>,
    listing: Value,
}

fn tcp_capture() -> Capture {
    Capture {
        name: "dtrack_flystick_a",
        tcp: read("dtrack_flystick_a.bin"),
        udp: Vec::new(),
        listing: listing("dtrack_flystick_a.json"),
    }
}

fn udp_capture() -> Capture {
    Capture {
        name: "dtrack_flystick_a_udp",
        tcp: read("dtrack_flystick_a_udp.tcp.bin"),
        udp: datagrams(&read("dtrack_flystick_a_udp.udp.bin")),
        listing: listing("dtrack_flystick_a_udp.json"),
    }
}

impl Capture {
    fn replay_path(&self) -> PathBuf {
        data(&format!("{}.vrpn.jsonl", self.name))
    }

    fn replay(&self) -> Vec<u8> {
        let (source, how) = if self.udp.is_empty() {
            ("DTrack@tcp://127.0.0.1:3883", "TCP")
        } else {
            ("DTrack@127.0.0.1:3883", "VRPN's classic UDP mode")
        };
        capture_replay(
            &self.tcp,
            &self.udp,
            source,
            &format!(
                "tests/data/vrpn/{}: real vrpn_server (vrpn_Tracker_DTrack) bytes received over {how}; one read per frame, receive times from the message times",
                self.name
            ),
        )
    }
}

// ---------------------------------------------------------------------------------------
// Fake servers

/// Serves `sessions[i]` to the i-th client as vrpn_server does: writes the session's first 24
/// bytes (its cookie) right after accepting, reads the client's cookie, then writes the rest
/// in writes of `chunk` bytes (0: one write), half-closes and waits for the client to close.
/// An empty session sends nothing at all. Returns the clients' cookies.
fn serve(sessions: Vec<Vec<u8>>, chunk: usize) -> (SocketAddr, JoinHandle<Vec<[u8; 24]>>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let thread = std::thread::spawn(move || {
        let mut cookies = Vec::new();
        for s in sessions {
            let (mut tcp, _) = listener.accept().unwrap();
            tcp.set_nodelay(true).unwrap();
            tcp.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            let head = s.len().min(24);
            tcp.write_all(&s[..head]).unwrap();
            let mut c = [0u8; 24];
            if tcp.read_exact(&mut c).is_ok() {
                cookies.push(c);
            }
            let mut sink = [0u8; 4096];
            if s.is_empty() {
                // A server that says nothing: hold the connection until the client gives up.
                while matches!(tcp.read(&mut sink), Ok(n) if n > 0) {}
                continue;
            }
            let rest = &s[head..];
            let pieces: Vec<&[u8]> = if chunk == 0 {
                vec![rest]
            } else {
                rest.chunks(chunk).collect()
            };
            for p in pieces {
                // The client may close first (it stops reading a broken stream).
                if tcp.write_all(p).is_err() {
                    break;
                }
            }
            let _ = tcp.shutdown(Shutdown::Write);
            // Unread client bytes must not turn the close into a reset that discards ours.
            while matches!(tcp.read(&mut sink), Ok(n) if n > 0) {}
        }
        cookies
    });
    (addr, thread)
}

/// What the client has received so far, for lock-step serving.
#[derive(Default)]
struct Progress {
    tcp_bytes: AtomicU64,
    udp_datagrams: AtomicU64,
}

/// What the classic server saw of the client.
#[derive(Debug)]
struct ClassicClient {
    lob: String,
    cookie: [u8; 24],
    udp_port: i32,
    udp_host: String,
}

/// VRPN's classic set-up, server side: waits for the client's lob `"<ip> <port>\0"` on its
/// UDP port, connects back, writes its cookie, reads the client's cookie and its UDP
/// description (−3: sender = the client's UDP port, payload its IP), then plays `reads` in
/// order, TCP reads over TCP and datagrams to the client's UDP port. It moves in lock-step
/// with the client (each read is sent once the previous one has arrived), so which socket the
/// client reads first never changes what it decodes.
fn serve_classic(
    reads: Vec<(Protocol, f64, Vec<u8>)>,
    progress: Arc<Progress>,
) -> (SocketAddr, JoinHandle<ClassicClient>) {
    let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
    let addr = udp.local_addr().unwrap();
    let thread = std::thread::spawn(move || {
        udp.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let mut buf = [0u8; 1500];
        let (n, _) = udp.recv_from(&mut buf).unwrap();
        assert_eq!(buf[n - 1], 0, "the lob ends in NUL");
        let lob = String::from_utf8(buf[..n - 1].to_vec()).unwrap();
        let (ip, port) = lob.split_once(' ').unwrap();
        let mut tcp = TcpStream::connect((ip, port.parse::<u16>().unwrap())).unwrap();
        tcp.set_nodelay(true).unwrap();
        tcp.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let first = &reads[0].2;
        tcp.write_all(&first[..24]).unwrap();
        let mut cookie = [0u8; 24];
        tcp.read_exact(&mut cookie).unwrap();
        let mut head = [0u8; 24];
        tcp.read_exact(&mut head).unwrap();
        let h = Header::read(&head).unwrap();
        assert_eq!(h.kind, wire::system::UDP_DESCRIPTION);
        let mut payload = vec![0u8; wire::padded(h.payload_len())];
        tcp.read_exact(&mut payload).unwrap();
        let Body::UdpDescription {
            port: udp_port,
            host: udp_host,
        } = wire::decode_system(&h, &payload[..h.payload_len()]).unwrap()
        else {
            panic!()
        };
        let to = SocketAddr::new(udp_host.parse().unwrap(), u16::try_from(udp_port).unwrap());
        let (mut tcp_sent, mut udp_sent) = (24u64, 0u64);
        let wait = |tcp_sent: u64, udp_sent: u64| {
            let deadline = Instant::now() + Duration::from_secs(20);
            while progress.tcp_bytes.load(Ordering::Acquire) < tcp_sent
                || progress.udp_datagrams.load(Ordering::Acquire) < udp_sent
            {
                assert!(Instant::now() < deadline, "client stalled");
                std::thread::yield_now();
            }
        };
        wait(tcp_sent, udp_sent);
        for (i, (p, _, bytes)) in reads.iter().enumerate() {
            let bytes = if i == 0 { &bytes[24..] } else { &bytes[..] };
            match p {
                Protocol::VrpnUdp => {
                    udp.send_to(bytes, to).unwrap();
                    udp_sent += 1;
                }
                _ => {
                    tcp.write_all(bytes).unwrap();
                    tcp_sent += bytes.len() as u64;
                }
            }
            wait(tcp_sent, udp_sent);
        }
        tcp.shutdown(Shutdown::Write).unwrap();
        let mut sink = [0u8; 4096];
        while matches!(tcp.read(&mut sink), Ok(n) if n > 0) {}
        ClassicClient {
            lob,
            cookie,
            udp_port,
            udp_host,
        }
    });
    (addr, thread)
}

// ---------------------------------------------------------------------------------------
// The client side

#[derive(Default)]
struct Collected {
    messages: Vec<VrpnMessage>,
    events: Vec<TrackingEvent>,
    problems: ProblemLog,
    reads: Vec<(Protocol, usize)>,
}

fn client_config(address: &str) -> VrpnClientConfig {
    VrpnClientConfig {
        reconnect: false,
        poll: Duration::from_millis(5),
        ..VrpnClientConfig::new(address.parse().unwrap())
    }
}

/// Polls a client until its session ends, decoding every read, keeping every message.
fn collect(client: VrpnClientConfig, config: VrpnConfig, progress: Option<&Progress>) -> Collected {
    let device = client.address.device.clone();
    let mut source = VrpnSource::new(client).unwrap();
    let mut ingest = Ingest::vrpn_only(&device, config, TimeSource::Tracker).unwrap();
    ingest.problems.quiet = true;
    ingest.vrpn_mut().unwrap().keep_messages(true);
    let mut c = Collected::default();
    let start = Instant::now();
    loop {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the session did not end"
        );
        let polled = source.poll(&mut ingest.problems).unwrap();
        let t = start.elapsed().as_secs_f64();
        match polled.datagram() {
            Some((p, bytes)) => {
                c.reads.push((p, bytes.len()));
                c.events.extend_from_slice(ingest.datagram(p, bytes, t));
                c.messages
                    .extend(ingest.vrpn().unwrap().messages().iter().cloned());
                if let Some(pr) = progress {
                    match p {
                        Protocol::VrpnUdp => pr.udp_datagrams.fetch_add(1, Ordering::Release),
                        _ => pr
                            .tcp_bytes
                            .fetch_add(bytes.len() as u64, Ordering::Release),
                    };
                }
            }
            None if polled == VrpnPoll::Ended => break,
            None => c.events.extend_from_slice(ingest.idle(t)),
        }
        if ingest.take_vrpn_reconnect() {
            source.drop_connection();
        }
    }
    c.problems = ingest.problems.clone();
    c
}

fn serve_and_collect(stream: Vec<u8>, chunk: usize) -> (Collected, [u8; 24]) {
    let (addr, server) = serve(vec![stream], chunk);
    let c = collect(
        client_config(&format!("DTrack@tcp://{addr}")),
        VrpnConfig::default(),
        None,
    );
    let cookies = server.join().unwrap();
    (c, cookies[0])
}

fn classic_collect(capture: &Capture, config: VrpnConfig) -> (Collected, ClassicClient) {
    let progress = Arc::new(Progress::default());
    let (addr, server) = serve_classic(reads_of(&capture.tcp, &capture.udp), progress.clone());
    let c = collect(
        client_config(&format!("DTrack@{addr}")),
        config,
        Some(&progress),
    );
    (c, server.join().unwrap())
}

// ---------------------------------------------------------------------------------------
// Checks against the listings

fn time_of(v: &Value) -> VrpnTime {
    VrpnTime::new(
        v["sec"].as_u64().unwrap() as u32,
        v["usec"].as_u64().unwrap() as u32,
    )
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn on(messages: &[VrpnMessage], channel: Channel) -> Vec<&VrpnMessage> {
    messages.iter().filter(|m| m.channel == channel).collect()
}

fn counts(messages: &[&VrpnMessage]) -> BTreeMap<String, u64> {
    let mut m = BTreeMap::new();
    for x in messages {
        *m.entry(x.type_name.clone()).or_insert(0) += 1;
    }
    m
}

fn listed_counts(v: &Value) -> BTreeMap<String, u64> {
    v.as_object()
        .unwrap()
        .iter()
        .map(|(k, n)| (k.clone(), n.as_u64().unwrap()))
        .collect()
}

/// Everything the listing states, against what the client decoded. Positions and quaternions
/// are compared bit for bit (the listing holds the exact float64 values from the wire).
fn check_listing(c: &Collected, l: &Value) {
    assert_eq!(c.problems.total(), 0, "{:?}", c.problems.counts());
    let tcp = on(&c.messages, Channel::Tcp);
    let udp = on(&c.messages, Channel::Udp);
    let udp_mode = l.get("udp").is_some();

    // Layout: sequence numbers run 0, 1, 2, … on each channel.
    assert_eq!(tcp.len() as u64, l["layout"]["messages"].as_u64().unwrap());
    assert!(
        tcp.iter()
            .enumerate()
            .all(|(i, m)| m.header.seq == i as u32)
    );
    assert!(
        udp.iter()
            .enumerate()
            .all(|(i, m)| m.header.seq == i as u32)
    );
    if udp_mode {
        assert_eq!(udp.len() as u64, l["udp"]["messages"].as_u64().unwrap());
        assert_eq!(counts(&udp), listed_counts(&l["udp"]["message_counts"]));
    } else {
        assert!(udp.is_empty());
    }
    assert_eq!(counts(&tcp), listed_counts(&l["message_counts"]));

    // Senders and types, id → name, exactly as described.
    let mut senders = BTreeMap::new();
    let mut types = BTreeMap::new();
    for m in &tcp {
        match &m.body {
            Body::SenderDescription { id, name } => senders.insert(id.to_string(), name.clone()),
            Body::TypeDescription { id, name } => types.insert(id.to_string(), name.clone()),
            _ => None,
        };
    }
    let names = |v: &Value| -> BTreeMap<String, String> {
        v.as_object()
            .unwrap()
            .iter()
            .map(|(k, n)| (k.clone(), n.as_str().unwrap().to_owned()))
            .collect()
    };
    assert_eq!(senders, names(&l["senders"]));
    assert_eq!(types, names(&l["types"]));

    // Poses per sensor: count, first, last, samples, gaps.
    let all: Vec<&VrpnMessage> = c.messages.iter().collect();
    let poses = |sensor: u32| -> Vec<(VrpnTime, [f64; 3], [f64; 4])> {
        all.iter()
            .filter_map(|m| match &m.body {
                Body::PosQuat(p) if p.sensor == sensor => {
                    assert_eq!(m.sender.as_deref(), Some("DTrack"));
                    Some((m.header.time, p.pos, p.quat_xyzw))
                }
                _ => None,
            })
            .collect()
    };
    let frames: Vec<VrpnTime> = poses(0).iter().map(|p| p.0).collect();
    for sensor in [0u32, 1] {
        let got = poses(sensor);
        let s = &l["tracker"]["sensors"][sensor.to_string()];
        assert_eq!(
            got.len() as u64,
            s["count"].as_u64().unwrap(),
            "sensor {sensor}"
        );
        let mut listed: Vec<&Value> = vec![&s["first"], &s["last"]];
        listed.extend(s["samples"].as_array().unwrap());
        for r in listed {
            let (t, pos, quat) = got[r["report"].as_u64().unwrap() as usize];
            assert_eq!(
                t,
                time_of(&r["time"]),
                "sensor {sensor} report {}",
                r["report"]
            );
            assert_eq!(
                pos.to_vec(),
                floats(&r["pos"]),
                "sensor {sensor} report {}",
                r["report"]
            );
            assert_eq!(quat.to_vec(), floats(&r["quat_xyzw"]));
        }
        // Untracked spells: frames (sensor 0 reports) between two reports of this sensor.
        let mut gaps = Vec::new();
        for w in got.windows(2) {
            let missing = frames
                .iter()
                .filter(|f| **f > w[0].0 && **f < w[1].0)
                .count();
            if missing > 0 {
                gaps.push((w[0].0, w[1].0, missing as u64));
            }
        }
        let listed_gaps: Vec<(VrpnTime, VrpnTime, u64)> = s["gaps"]
            .as_array()
            .unwrap()
            .iter()
            .map(|g| {
                (
                    time_of(&g["after_time"]),
                    time_of(&g["resume_time"]),
                    g["missing_frames"].as_u64().unwrap(),
                )
            })
            .collect();
        assert_eq!(gaps, listed_gaps, "sensor {sensor}");
    }

    // Every button change (with its index in the TCP stream), and the States message.
    let changes: Vec<(u64, u32, bool, VrpnTime)> = tcp
        .iter()
        .enumerate()
        .filter_map(|(i, m)| match m.body {
            Body::ButtonChange { button, pressed } => {
                Some((i as u64, button, pressed, m.header.time))
            }
            _ => None,
        })
        .collect();
    let listed: Vec<(u64, u32, bool, VrpnTime)> = l["buttons"]["changes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| {
            (
                b["message_index"].as_u64().unwrap(),
                b["button"].as_u64().unwrap() as u32,
                b["state"].as_u64().unwrap() == 1,
                time_of(&b["time"]),
            )
        })
        .collect();
    assert_eq!(changes, listed);
    let states: Vec<(u64, Vec<bool>, VrpnTime)> = tcp
        .iter()
        .enumerate()
        .filter_map(|(i, m)| match &m.body {
            Body::ButtonStates(s) => Some((i as u64, s.clone(), m.header.time)),
            _ => None,
        })
        .collect();
    let listed: Vec<(u64, Vec<bool>, VrpnTime)> = l["buttons"]["states_messages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            let v: Vec<bool> = s["states"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_u64() == Some(1))
                .collect();
            assert_eq!(v.len() as u64, s["num_buttons"].as_u64().unwrap());
            (s["message_index"].as_u64().unwrap(), v, time_of(&s["time"]))
        })
        .collect();
    assert_eq!(states, listed);

    // Every analog value, in order, and the first and last times.
    let analog: Vec<(VrpnTime, Vec<f64>)> = all
        .iter()
        .filter_map(|m| match &m.body {
            Body::Analog(v) => Some((m.header.time, v.clone())),
            _ => None,
        })
        .collect();
    let a = &l["analog"];
    assert_eq!(analog.len() as u64, a["count"].as_u64().unwrap());
    let values: Vec<Vec<f64>> = a["all_values"]
        .as_array()
        .unwrap()
        .iter()
        .map(floats)
        .collect();
    assert_eq!(
        analog.iter().map(|x| x.1.clone()).collect::<Vec<_>>(),
        values
    );
    assert_eq!(analog[0].0, time_of(&a["first"]["time"]));
    assert_eq!(analog.last().unwrap().0, time_of(&a["last"]["time"]));
}

/// What the capture must give as events with the default mapping (identity in metres): the
/// FlyStick's and the body's poses as received, normalised; the FlyStick lost in each of the
/// 30 untracked frames (no stale pose); the trigger's presses in its button mask.
fn check_events(c: &Collected, l: &Value) {
    let of = |d: DeviceId| c.events.iter().filter(move |e| e.device == d);
    assert!(c.events.iter().all(TrackingEvent::is_valid));
    let tracked = |d| {
        of(d)
            .filter(|e| matches!(e.pose, Some(Tracking::Tracked(_))))
            .count()
    };
    assert_eq!((tracked(body()), tracked(flystick())), (600, 570));
    let s1 = &l["tracker"]["sensors"]["1"];
    let gap = &s1["gaps"][0];
    let (after, resume) = (
        time_of(&gap["after_time"]).seconds(),
        time_of(&gap["resume_time"]).seconds(),
    );
    let lost: Vec<f64> = of(flystick())
        .filter(|e| e.pose == Some(Tracking::Lost))
        .map(|e| e.t)
        .collect();
    // One per untracked frame, and one when the connection ends (at the last report's time).
    assert_eq!(lost.len(), 31, "{lost:?}");
    assert_eq!(
        lost.iter().filter(|t| **t > after && **t < resume).count(),
        30,
        "{lost:?}"
    );
    assert_eq!(lost[30], time_of(&s1["last"]["time"]).seconds());
    // Between the last report before the gap and the first after it, no tracked pose.
    assert!(
        !of(flystick())
            .any(|e| e.t > after && e.t < resume && matches!(e.pose, Some(Tracking::Tracked(_))))
    );
    // The first pose: the raw values, the quaternion normalised only now.
    let first = of(flystick()).next().unwrap();
    let Some(Tracking::Tracked(p)) = first.pose else {
        panic!()
    };
    assert_eq!(p.position.to_array().to_vec(), floats(&s1["first"]["pos"]));
    let q = floats(&s1["first"]["quat_xyzw"]);
    let raw = DQuat::from_xyzw(q[0], q[1], q[2], q[3]);
    assert!((raw.length() - 1.0).abs() > 0.0 && (raw.length() - 1.0).abs() < 1e-6);
    assert!(p.orientation.abs_diff_eq(raw.normalize(), 1e-15));
    assert_eq!(first.t, time_of(&s1["first"]["time"]).seconds());
    // The trigger: two presses, two releases, at the listed times.
    let mut edges = Vec::new();
    let mut last = 0;
    for e in of(flystick()) {
        let b = e.buttons.unwrap();
        if b != last {
            edges.push((e.t, b));
            last = b;
        }
    }
    let listed: Vec<(f64, u32)> = l["buttons"]["changes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| {
            (
                time_of(&b["time"]).seconds(),
                b["state"].as_u64().unwrap() as u32,
            )
        })
        .collect();
    assert_eq!(edges, listed);
    // The stick's last deflection is the last analog message's.
    let axes = of(flystick())
        .filter_map(|e| e.axes.clone())
        .find(|a| a[0] < -0.7)
        .unwrap();
    assert_eq!(axes, vec![-0.7099999785423279, 0.7099999785423279]);
}

#[test]
fn the_captures_are_the_ones_their_listings_describe() {
    // No sha256 crate in the tree: check the size here and the hash with sha256sum where
    // there is one (CI images have coreutils).
    for (bin, json) in [
        ("dtrack_flystick_a.bin", "dtrack_flystick_a.json"),
        (
            "dtrack_flystick_a_udp.tcp.bin",
            "dtrack_flystick_a_udp.json",
        ),
    ] {
        let l = listing(json);
        assert_eq!(read(bin).len() as u64, l["size_bytes"].as_u64().unwrap());
        if let Ok(out) = std::process::Command::new("sha256sum")
            .arg(data(bin))
            .output()
        {
            let text = String::from_utf8_lossy(&out.stdout);
            assert!(
                text.starts_with(l["sha256"].as_str().unwrap()),
                "{bin}: {text}"
            );
        }
    }
}

#[test]
fn the_tcp_capture_decodes_exactly_what_its_listing_says() {
    let cap = tcp_capture();
    let (c, cookie) = serve_and_collect(cap.tcp.clone(), 0);
    assert_eq!(&cookie[..19], b"vrpn: ver. 07.38  0", "the client's cookie");
    assert!(cookie[19..].iter().all(|&b| b == 0));
    check_listing(&c, &cap.listing);
    check_events(&c, &cap.listing);
    assert_eq!(
        c.reads.last(),
        Some(&(Protocol::VrpnTcp, 0)),
        "the end is an empty read"
    );
}

#[test]
fn the_tcp_capture_in_tiny_chunks_decodes_the_same() {
    let cap = tcp_capture();
    let (whole, _) = serve_and_collect(cap.tcp.clone(), 0);
    for chunk in [7, 1] {
        let (c, _) = serve_and_collect(cap.tcp.clone(), chunk);
        check_listing(&c, &cap.listing);
        assert_eq!(c.messages, whole.messages, "chunk {chunk}");
        assert_eq!(c.events, whole.events, "chunk {chunk}");
        // Partial reads did happen: some read ended inside a message.
        let ends: Vec<u64> = std::iter::once(24)
            .chain(split_messages(&cap.tcp).iter().scan(24u64, |at, (h, _)| {
                *at += h.wire_len() as u64;
                Some(*at)
            }))
            .collect();
        let mut at = 0u64;
        let split = c.reads.iter().any(|(_, n)| {
            at += *n as u64;
            *n > 0 && !ends.contains(&at)
        });
        assert!(
            split,
            "chunk {chunk}: {} reads, none partial",
            c.reads.len()
        );
    }
}

#[test]
fn the_udp_capture_decodes_exactly_what_its_listing_says_in_classic_mode() {
    let cap = udp_capture();
    let (c, client) = classic_collect(&cap, VrpnConfig::default());
    // The handshake as vrpn_Connection does it.
    let (ip, port) = client.lob.split_once(' ').unwrap();
    assert_eq!(ip, "127.0.0.1");
    assert!(port.parse::<u16>().unwrap() > 0);
    assert_eq!(&client.cookie[..19], b"vrpn: ver. 07.38  0");
    assert_eq!(client.udp_host, "127.0.0.1");
    assert!(client.udp_port > 0 && client.udp_port != i32::from(port.parse::<u16>().unwrap()));
    check_listing(&c, &cap.listing);
    check_events(&c, &cap.listing);
    let udp_reads = c.reads.iter().filter(|r| r.0 == Protocol::VrpnUdp).count();
    assert_eq!(udp_reads, 600);
}

// ---------------------------------------------------------------------------------------
// Golden ROI changes

/// Plays a replay through its header's decoders and the interaction state machine, as
/// `raygun replay` does, and prints the ROI changes in the golden files' form.
fn replay_roi_changes(file: &Path) -> (String, ProblemLog) {
    let args = ReplayOptions {
        display: Some(PathBuf::from(walls::HORNET).display().to_string()),
        ..ReplayOptions::of(file.to_owned())
    };
    let (plan, mut reader) = ReplayPlan::new(&args).unwrap();
    reader.problems.quiet = true;
    let mut ingest = plan.header.ingest(None).unwrap();
    ingest.problems.quiet = true;
    let mut pipeline = Pipeline::new(ingest, Interaction::new(plan.interaction.clone()));
    let device = plan.interaction.device;
    let mut printer = ChangePrinter::new(Vec::new());
    while let Some(item) = reader.next_item() {
        let ReplayPayload::Datagram(p, bytes) = item.payload else {
            panic!("a VRPN replay holds raw reads only")
        };
        let (events, changes) = pipeline.datagram(p, &bytes, item.t, &plan.surface);
        if let Some(e) = events.iter().find(|e| e.device == device) {
            printer.saw_event(e.t);
        }
        for c in changes {
            printer.print(c).unwrap();
        }
    }
    let mut problems = reader.problems;
    problems.merge(&pipeline.ingest.problems);
    (String::from_utf8(printer.into_inner()).unwrap(), problems)
}

fn golden(cap: &Capture) -> String {
    let path = golden_path(&cap.replay_path());
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_capture_replays_are_what_the_captures_make() {
    for cap in [tcp_capture(), udp_capture()] {
        let bytes = cap.replay();
        let path = cap.replay_path();
        if bless() {
            std::fs::write(&path, &bytes).unwrap();
        }
        let on_disk = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(
            on_disk == bytes,
            "{} differs from the capture's; run with RAYGUN_BLESS=1",
            path.display()
        );
        let reader = ReplayReader::new(&on_disk[..], &path).unwrap();
        let h: &ReplayHeader = reader.header();
        assert_eq!(h.vrpn.as_ref().map(|v| &v.config), Some(&golden_config()));
    }
}

#[test]
fn the_capture_replays_give_their_golden_roi_changes_on_hornet() {
    for cap in [tcp_capture(), udp_capture()] {
        let file = cap.replay_path();
        let (got, problems) = replay_roi_changes(&file);
        assert_eq!(
            problems.total(),
            0,
            "{}: {:?}",
            file.display(),
            problems.counts()
        );
        let path = golden_path(&file);
        if bless() {
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(&path, &got).unwrap();
        }
        assert!(
            got == golden(&cap),
            "{}: ROI changes differ from {}",
            file.display(),
            path.display()
        );
        // The two trigger presses hit the wall; the stick sweeps change the FOV.
        let kinds: Vec<String> = got
            .lines()
            .map(|l| {
                serde_json::from_str::<Value>(l).unwrap()["kind"]
                    .as_str()
                    .unwrap()
                    .to_owned()
            })
            .collect();
        assert_eq!(kinds.iter().filter(|k| *k == "shoot").count(), 2, "{got}");
        assert!(kinds.iter().filter(|k| *k == "fov").count() > 10);
        assert!(
            kinds.iter().all(|k| k == "shoot" || k == "fov"),
            "{kinds:?}"
        );
    }
}

#[test]
fn a_live_tcp_session_gives_the_golden_roi_changes() {
    let cap = tcp_capture();
    let (addr, server) = serve(vec![cap.tcp.clone()], 1000);
    let mut source = VrpnSource::new(client_config(&format!("DTrack@tcp://{addr}"))).unwrap();
    let mut ingest = Ingest::vrpn_only("DTrack", golden_config(), TimeSource::Tracker).unwrap();
    ingest.problems.quiet = true;
    let surface = DisplayModel::load(PathBuf::from(walls::HORNET)).unwrap();
    let mut pipeline = Pipeline::new(ingest, Interaction::new(InteractionConfig::default()));
    let stop = AtomicBool::new(false);
    let live = Live::default();
    let mut printer = ChangePrinter::new(Vec::new());
    raygun::session::vrpn::run_live(
        &mut source,
        &mut pipeline,
        &surface,
        &stop,
        &live,
        |events, changes| {
            if let Some(e) = events.iter().find(|e| e.device == flystick()) {
                printer.saw_event(e.t);
            }
            for c in changes {
                printer.print(c).unwrap();
            }
        },
    )
    .unwrap();
    server.join().unwrap();
    assert_eq!(
        pipeline.ingest.problems.total(),
        0,
        "{:?}",
        pipeline.ingest.problems.counts()
    );
    let got = String::from_utf8(printer.into_inner()).unwrap();
    assert!(
        got == golden(&cap),
        "live TCP ROI changes differ from the golden file"
    );
    let snap = live.snapshot();
    assert!(snap.roi.is_some() && snap.version == got.lines().count() as u64);
}

#[test]
fn a_live_classic_udp_session_gives_the_golden_roi_changes() {
    let cap = udp_capture();
    let progress = Arc::new(Progress::default());
    let (addr, server) = serve_classic(reads_of(&cap.tcp, &cap.udp), progress.clone());
    let mut source = VrpnSource::new(client_config(&format!("DTrack@{addr}"))).unwrap();
    let ingest = Ingest::vrpn_only("DTrack", golden_config(), TimeSource::Tracker).unwrap();
    let surface = DisplayModel::load(PathBuf::from(walls::HORNET)).unwrap();
    let mut pipeline = Pipeline::new(ingest, Interaction::new(InteractionConfig::default()));
    let mut printer = ChangePrinter::new(Vec::new());
    let start = Instant::now();
    loop {
        let polled = source.poll(&mut pipeline.ingest.problems).unwrap();
        let Some((p, bytes)) = polled.datagram() else {
            if polled == VrpnPoll::Ended {
                break;
            }
            continue;
        };
        let n = bytes.len() as u64;
        let (events, changes) =
            pipeline.datagram(p, bytes, start.elapsed().as_secs_f64(), &surface);
        if let Some(e) = events.iter().find(|e| e.device == flystick()) {
            printer.saw_event(e.t);
        }
        for c in changes {
            printer.print(c).unwrap();
        }
        match p {
            Protocol::VrpnUdp => progress.udp_datagrams.fetch_add(1, Ordering::Release),
            _ => progress.tcp_bytes.fetch_add(n, Ordering::Release),
        };
    }
    server.join().unwrap();
    assert_eq!(
        pipeline.ingest.problems.total(),
        0,
        "{:?}",
        pipeline.ingest.problems.counts()
    );
    let got = String::from_utf8(printer.into_inner()).unwrap();
    assert!(
        got == golden(&cap),
        "live UDP-mode ROI changes differ from the golden file"
    );
}

#[test]
fn a_recording_replays_to_the_golden_roi_changes() {
    let cap = tcp_capture();
    let (addr, server) = serve(vec![cap.tcp.clone()], 4096);
    let address: VrpnAddress = format!("DTrack@tcp://{addr}").parse().unwrap();
    let mut source = VrpnSource::new(client_config(&address.to_string())).unwrap();
    let mut header = ReplayHeader::vrpn_recording(&address, &golden_config());
    header.device = Some(flystick());
    let mut writer = ReplayWriter::new(Vec::new(), &header).unwrap();
    let mut ingest = header.ingest(None).unwrap();
    ingest.problems.quiet = true;
    let stop = AtomicBool::new(false);
    let n = raygun::session::vrpn::record(
        &mut source,
        &mut writer,
        &mut ingest,
        &stop,
        Some(Duration::from_secs(30)),
    )
    .unwrap();
    server.join().unwrap();
    assert_eq!(ingest.problems.total(), 0, "{:?}", ingest.problems.counts());
    assert!(n > 1, "{n} reads");
    let text = writer.into_inner();
    let last = text
        .split(|&b| b == b'\n')
        .rev()
        .find(|l| !l.is_empty())
        .unwrap();
    assert!(
        String::from_utf8_lossy(last).contains("\"vrpn_tcp_hex\":\"\""),
        "the recording ends with the connection's end"
    );
    let dir = std::env::temp_dir().join(format!("raygun-vrpn-record-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("recorded.vrpn.jsonl");
    std::fs::write(&file, &text).unwrap();
    let (got, problems) = replay_roi_changes(&file);
    // The library entry point for replays decodes the same file too.
    let (events, p2) =
        raygun::tracking::replay::replay_events(ReplayReader::open(&file).unwrap()).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!((problems.total(), p2.total()), (0, 0));
    assert!(
        got == golden(&cap),
        "the recording's ROI changes differ from the golden file"
    );
    assert_eq!(
        events.iter().filter(|e| e.device == flystick()).count(),
        570 + 30 + 4 + 52 + 1
    );
}

// ---------------------------------------------------------------------------------------
// VRPN and DTrack of the same session

/// The DTrack datagrams the capture's server was fed.
fn dtrack_datagrams() -> Vec<String> {
    let text = String::from_utf8(read("dtrack_flystick_a.dtrack.txt")).unwrap();
    let mut v: Vec<String> = Vec::new();
    for line in text.lines() {
        if line.starts_with("---- ") {
            v.push(String::new());
        } else if let Some(d) = v.last_mut()
            && !line.starts_with('#')
        {
            d.push_str(line);
            d.push_str("\r\n");
        }
    }
    v
}

#[test]
fn vrpn_and_dtrack_of_the_same_session_give_the_same_poses_buttons_and_sticks() {
    let (c, _) = serve_and_collect(tcp_capture().tcp, 0);
    let mut dtrack = DtrackDecoder::new(DtrackConfig::default(), TimeSource::Tracker);
    let frames = dtrack_datagrams();
    assert_eq!(frames.len(), 600);
    let vrpn_of = |d: DeviceId| -> Vec<&TrackingEvent> {
        c.events.iter().filter(|e| e.device == d).collect()
    };
    let bodies = vrpn_of(body());
    let sticks = vrpn_of(flystick());
    assert_eq!(
        bodies.len(),
        601,
        "600 frames and the end of the connection"
    );
    // VRPN's time is DTrack's ts on the server's date, microseconds truncated.
    let same_time = |vrpn_t: f64, ts: f64| (vrpn_t.rem_euclid(86_400.0) - ts).abs() <= 1.5e-6;
    let (mut worst_pos, mut worst_angle) = (0.0_f64, 0.0_f64);
    let mut stick_frames = 0;
    for (k, text) in frames.iter().enumerate() {
        let mut out = Vec::new();
        dtrack.decode_into(text.as_bytes(), 0.0, &mut out).unwrap();
        let b = out.iter().find(|e| e.device == body()).unwrap();
        assert!(
            same_time(bodies[k].t, b.t),
            "frame {k}: {} vs {}",
            bodies[k].t,
            b.t
        );
        let s = out.iter().find(|e| e.device == flystick()).unwrap();
        // The FlyStick's VRPN events of this frame: its pose (or Lost), then any button and
        // analog reports, which VRPN sends after the frame's poses.
        let frame: Vec<&&TrackingEvent> = sticks.iter().filter(|e| same_time(e.t, s.t)).collect();
        let v = frame
            .iter()
            .find(|e| e.pose.is_some())
            .unwrap_or_else(|| panic!("frame {k}: no VRPN FlyStick pose or Lost"));
        let after = frame.last().unwrap();
        stick_frames += 1;
        for (v, d) in [(bodies[k], b), (**v, s)] {
            match (v.pose, d.pose) {
                (Some(Tracking::Tracked(a)), Some(Tracking::Tracked(b))) => {
                    // VRPN parsed DTrack's millimetres as float32 first.
                    worst_pos = worst_pos.max((a.position - b.position).length());
                    worst_angle = worst_angle.max(a.orientation.angle_between(b.orientation));
                }
                (Some(Tracking::Lost), Some(Tracking::Lost)) => {}
                other => panic!("frame {k}: {other:?}"),
            }
        }
        // DTrack's 6 buttons and VRPN's button mask; the sticks to float32 precision.
        assert_eq!(after.buttons, s.buttons, "frame {k}");
        let (va, da) = (after.axes.as_ref().unwrap(), s.axes.as_ref().unwrap());
        assert!(
            va.iter().zip(da).all(|(a, b)| (a - b).abs() < 1e-7),
            "frame {k}: {va:?} {da:?}"
        );
    }
    assert_eq!(stick_frames, 600);
    assert!(worst_pos < 1e-6, "{worst_pos} m");
    // DTrack prints the matrix to 6 decimals; both sides make a quaternion of it.
    assert!(worst_angle < 1e-5, "{worst_angle} rad");
}

// ---------------------------------------------------------------------------------------
// Bad servers

/// A server stream built from messages: cookie, vrpn_server's descriptions (sender 1 =
/// DTrack; Pos_Quat = 4, Change = 18, Analog = 22), then what the case adds.
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
        for (id, name) in [(0, "VRPN Control"), (1, "DTrack")] {
            encode::sender_description(&mut s.bytes, s.seq, id, name);
            s.seq += 1;
        }
        for (id, name) in [
            (4, "vrpn_Tracker Pos_Quat"),
            (18, "vrpn_Button Change"),
            (22, "vrpn_Analog Channel"),
            (15, "vrpn_Base text_message"),
        ] {
            encode::type_description(&mut s.bytes, s.seq, id, name);
            s.seq += 1;
        }
        s
    }

    fn msg(mut self, t: f64, sender: i32, kind: i32, payload: &[u8]) -> Self {
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

    fn pose(self, t: f64, pos: [f64; 3], quat: [f64; 4]) -> Self {
        self.msg(t, 1, 4, &encode::pos_quat(1, pos, quat))
    }

    fn good(self, t: f64) -> Self {
        self.pose(t, [0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0])
    }

    fn raw(mut self, bytes: &[u8]) -> Self {
        self.bytes.extend_from_slice(bytes);
        self
    }
}

/// A bad server: its name, its stream, the problem counts it must give, and how many good
/// poses still decode.
type BadCase = (&'static str, Vec<u8>, Vec<(&'static str, u64)>, usize);

fn with_len(len: u32) -> Vec<u8> {
    let mut m = Vec::new();
    encode::message(
        &mut m,
        VrpnTime::new(5, 0),
        1,
        4,
        99,
        &encode::pos_quat(1, [0.0; 3], [0.0, 0.0, 0.0, 1.0]),
    );
    m[..4].copy_from_slice(&len.to_be_bytes());
    m
}

#[test]
fn bad_servers_of_every_kind_are_counted_once_per_kind_and_never_crash() {
    let q = [0.0, 0.0, 0.0, 1.0];
    let nan = [f64::NAN, 0.0, 0.0];
    let mut flood = Stream::new();
    let mut text = Vec::new();
    for i in 0..(vrpn::decoder::FLOOD_MESSAGES_PER_S + 1000) as u32 {
        encode::message(&mut text, VrpnTime::new(5, 0), 1, 15, i, &[]);
    }
    flood = flood.raw(&text).good(6.0);
    let mut wrong = Stream::new();
    wrong.bytes[..24].copy_from_slice(b"SSH-2.0-OpenSSH_9.6\r\n\0\0\0");
    let mut major = Stream::new();
    major.bytes[..24].copy_from_slice(&encode::cookie_with(b"vrpn: ver. 08.01"));
    let mut minor = Stream::new();
    minor.bytes[..24].copy_from_slice(&encode::cookie_with(b"vrpn: ver. 07.35"));
    let truncated = {
        let s = Stream::new().good(1.0).good(2.0);
        let n = s.bytes.len() - 30;
        Stream {
            bytes: s.bytes[..n].to_vec(),
            seq: 0,
        }
    };
    // (case, stream, expected problem counts, good poses that still decode)
    let cases: Vec<BadCase> = vec![
        (
            "wrong cookie",
            wrong.good(1.0).bytes,
            vec![("vrpn_bad_cookie", 1)],
            0,
        ),
        (
            "wrong major version",
            major.good(1.0).bytes,
            vec![("vrpn_version_mismatch", 1)],
            0,
        ),
        (
            "older minor version is fine",
            minor.good(1.0).bytes,
            vec![],
            1,
        ),
        (
            "length below 24",
            Stream::new().good(1.0).raw(&with_len(12)).good(2.0).bytes,
            vec![("vrpn_length_too_small", 1)],
            1,
        ),
        (
            "length beyond the maximum",
            Stream::new()
                .good(1.0)
                .raw(&with_len(1 << 30))
                .good(2.0)
                .bytes,
            vec![("vrpn_length_too_large", 1)],
            1,
        ),
        (
            "truncated message",
            truncated.bytes,
            vec![("vrpn_truncated", 1)],
            1,
        ),
        (
            "unknown sender id",
            Stream::new()
                .msg(1.0, 9, 4, &encode::pos_quat(1, [0.0; 3], q))
                .good(2.0)
                .bytes,
            vec![("vrpn_unknown_sender", 1)],
            1,
        ),
        (
            "unknown type id",
            Stream::new()
                .msg(1.0, 1, 77, &encode::pos_quat(1, [0.0; 3], q))
                .good(2.0)
                .bytes,
            vec![("vrpn_unknown_type", 1)],
            1,
        ),
        (
            "description redefining an id",
            {
                let mut s = Stream::new();
                encode::sender_description(&mut s.bytes, 50, 1, "Vicon");
                s.good(1.0).bytes
            },
            vec![("vrpn_redefined_id", 1)],
            1,
        ),
        (
            "NaN and infinite poses",
            Stream::new()
                .pose(1.0, nan, q)
                .pose(1.5, [0.0; 3], [0.0, f64::INFINITY, 0.0, 1.0])
                .good(2.0)
                .bytes,
            vec![("vrpn_non_finite", 2)],
            1,
        ),
        (
            "zero quaternion",
            Stream::new().pose(1.0, [0.0; 3], [0.0; 4]).good(2.0).bytes,
            vec![("vrpn_bad_quaternion", 1)],
            1,
        ),
        (
            "bad payload length",
            Stream::new().msg(1.0, 1, 4, &[0; 40]).good(2.0).bytes,
            vec![("vrpn_bad_payload_length", 1)],
            1,
        ),
        ("a flood", flood.bytes, vec![("vrpn_flood", 1)], 1),
        ("sends nothing", Vec::new(), vec![("vrpn_no_cookie", 1)], 0),
    ];
    for (name, stream, expected, good) in cases {
        let (addr, server) = serve(vec![stream], 0);
        let c = collect(
            VrpnClientConfig {
                handshake_timeout: Duration::from_millis(300),
                ..client_config(&format!("DTrack@tcp://{addr}"))
            },
            VrpnConfig::default(),
            None,
        );
        server.join().unwrap();
        let expected: BTreeMap<&str, u64> = expected.into_iter().collect();
        let got: BTreeMap<&str, u64> = c.problems.counts().iter().map(|(k, v)| (*k, *v)).collect();
        assert_eq!(got, expected, "{name}");
        for kind in expected.keys() {
            assert!(
                c.problems.logged(kind).is_some(),
                "{name}: {kind} logged once"
            );
        }
        let tracked = c
            .events
            .iter()
            .filter(|e| matches!(e.pose, Some(Tracking::Tracked(_))))
            .count();
        assert_eq!(tracked, good, "{name}");
        assert!(c.events.iter().all(TrackingEvent::is_valid), "{name}");
    }
}

#[test]
fn a_refused_connection_is_retried_with_growing_back_off() {
    // A port nobody listens on.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mut source = VrpnSource::new(VrpnClientConfig {
        reconnect: true,
        ..client_config(&format!("DTrack@tcp://127.0.0.1:{port}"))
    })
    .unwrap();
    let mut problems = ProblemLog::quiet();
    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(1000) {
        assert_eq!(source.poll(&mut problems).unwrap(), VrpnPoll::Idle);
    }
    // Attempts at 0, 0.1, 0.3, 0.7 s (back-off 0.1 s doubling): not one per poll.
    let n = problems.count("vrpn_connect_failed");
    assert!((3..=5).contains(&n), "{n} attempts");
    assert_eq!(problems.total(), n);
    assert!(
        problems
            .logged("vrpn_connect_failed")
            .unwrap()
            .contains(&port.to_string())
    );
}

#[test]
fn the_client_reconnects_when_the_server_goes_away_and_loses_the_devices_meanwhile() {
    let session = |t0: f64| Stream::new().good(t0).good(t0 + 0.1).bytes;
    let (addr, server) = serve(vec![session(1.0), session(2.0)], 0);
    let mut source = VrpnSource::new(VrpnClientConfig {
        reconnect: true,
        backoff_min: Duration::from_millis(20),
        ..client_config(&format!("DTrack@tcp://{addr}"))
    })
    .unwrap();
    let mut ingest =
        Ingest::vrpn_only("DTrack", VrpnConfig::default(), TimeSource::Tracker).unwrap();
    ingest.problems.quiet = true;
    let mut events = Vec::new();
    let start = Instant::now();
    while ingest.vrpn().unwrap().stats().connections < 2 || events.len() < 5 {
        assert!(start.elapsed() < Duration::from_secs(10), "{events:?}");
        if let Some((p, bytes)) = source.poll(&mut ingest.problems).unwrap().datagram() {
            events.extend_from_slice(ingest.datagram(p, bytes, 0.0));
        }
    }
    let connections = source.connections();
    // Closing lets the server's second session end.
    drop(source);
    server.join().unwrap();
    let kinds: Vec<(f64, &str)> = events
        .iter()
        .map(|e| {
            (
                e.t,
                if e.pose == Some(Tracking::Lost) {
                    "lost"
                } else {
                    "tracked"
                },
            )
        })
        .collect();
    assert_eq!(
        kinds,
        [
            (1.0, "tracked"),
            (1.1, "tracked"),
            (1.1, "lost"),
            (2.0, "tracked"),
            (2.1, "tracked")
        ]
    );
    assert_eq!(connections, 2);
    assert_eq!(
        ingest.problems.count("vrpn_connection_lost"),
        1,
        "{:?}",
        ingest.problems.counts()
    );
}

#[test]
fn a_server_off_this_machine_needs_the_explicit_opt_in() {
    let far = client_config("DTrack@tcp://192.0.2.1:3883");
    assert!(matches!(
        VrpnSource::new(far.clone()),
        Err(VrpnClientError::NonLoopback { .. })
    ));
    let e = VrpnSource::new(far.clone()).err().unwrap().to_string();
    assert!(e.contains("192.0.2.1") && e.contains("loopback"), "{e}");
    assert!(
        VrpnSource::new(VrpnClientConfig {
            allow_non_loopback: true,
            ..far
        })
        .is_ok()
    );
}

#[test]
fn a_replay_header_without_vrpn_counts_vrpn_reads_as_not_configured() {
    let mut ingest = Ingest::new(
        DtrackConfig::default(),
        Default::default(),
        TimeSource::Tracker,
    );
    ingest.problems.quiet = true;
    let _ = ingest.datagram(Protocol::VrpnTcp, &encode::cookie(), 0.0);
    assert_eq!(ingest.problems.count("vrpn_not_configured"), 1);
    let header = ReplayHeader {
        vrpn: Some(VrpnHeader {
            source: "DTrack@tcp://127.0.0.1".parse().unwrap(),
            config: VrpnConfig {
                silence_s: -1.0,
                ..VrpnConfig::default()
            },
        }),
        ..ReplayHeader::new("bad")
    };
    let e = header.ingest(None).err().unwrap().to_string();
    assert!(e.contains("`vrpn`") && e.contains("silence_s"), "{e}");
}

/// `raygun record --vrpn` and `raygun replay`, end to end: the recording of a live session
/// (the capture served over TCP) carries the display and the calibration in its header and
/// replays by itself to the golden ROI changes.
#[test]
fn the_record_and_replay_commands_reproduce_the_golden_roi_changes() {
    let cap = tcp_capture();
    let (addr, server) = serve(vec![cap.tcp.clone()], 4096);
    let dir = std::env::temp_dir().join(format!("raygun-vrpn-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // The golden calibration as a calibration file (VRPN sends metres: no units needed).
    let cal = dir.join("lab.json");
    std::fs::write(
        &cal,
        r#"{"raygun_calibration": 1, "translation_m": [0.0, -1.2, 1.25]}"#,
    )
    .unwrap();
    let out = dir.join("session.jsonl");
    let raygun = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_raygun"))
            .args(args)
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap()
    };
    let o = raygun(&[
        "record",
        "--vrpn",
        &format!("DTrack@tcp://{addr}"),
        "--out",
        out.to_str().unwrap(),
        "--calibration",
        cal.to_str().unwrap(),
        "--seconds",
        "60",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    server.join().unwrap();
    let o = raygun(&["replay", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got = String::from_utf8(o.stdout).unwrap();
    assert_eq!(got.lines().count(), golden(&cap).lines().count(), "{got}");
    assert!(
        got == golden(&cap),
        "recorded ROI changes differ from the golden file"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `raygun view --vrpn`'s live source: the viewer's state gets the ROI of the capture's first
/// shot, with the calibration applied.
#[test]
fn the_viewers_vrpn_source_delivers_the_shots() {
    use raygun::session::live::LiveTracking;
    use raygun::tracking::calibration::Calibration;
    use raygun::viewer::state::{RoiSource, ViewerState};
    let cap = tcp_capture();
    let (addr, _server) = serve(vec![cap.tcp.clone()], 4096);
    let cal = Calibration::from_json(
        r#"{"raygun_calibration": 1, "translation_m": [0.0, -1.2, 1.25]}"#,
        Path::new("lab.json"),
    )
    .unwrap();
    let model = DisplayModel::load(PathBuf::from(walls::HORNET)).unwrap();
    let mut live = LiveTracking::start_vrpn(
        format!("DTrack@tcp://{addr}").parse().unwrap(),
        false,
        InteractionConfig::default(),
        model.clone(),
        Some(&cal),
    )
    .unwrap();
    let mut state = ViewerState::new(RoiSource::Live, 4);
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while state
        .tracked
        .as_ref()
        .and_then(|r| r.centre.as_ref())
        .is_none()
    {
        assert!(std::time::Instant::now() < deadline, "no ROI arrived");
        std::thread::sleep(Duration::from_millis(20));
        state.apply_live(live.update());
    }
    // The capture plays at once: the state ends at the golden file's last shot (its later FOV
    // changes keep the centre).
    let g = golden(&cap);
    let last: Value = g
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .rfind(|v| v["kind"] == "shoot")
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    state.apply_live(live.update());
    let want = last["centre_canvas_px"].as_array().unwrap();
    let got = state.tracked.unwrap().centre.unwrap().canvas_px;
    assert!(
        (got.x - want[0].as_f64().unwrap()).abs() < 0.01
            && (got.y - want[1].as_f64().unwrap()).abs() < 0.01,
        "{got} vs {want:?}"
    );
}

/// The eyes a replay's tracked head gives (`render --guide` and `replay` read the same).
fn head_eyes(file: PathBuf, head: DeviceId, offset: [f64; 3]) -> Vec<(f64, glam::DVec3)> {
    let mut options = ReplayOptions::of(file.clone());
    options.head = raygun::tracking::head::HeadOverride {
        device: Some(head),
        eye_offset_m: Some(offset),
        eye_threshold_m: None,
    };
    let (plan, _) = ReplayPlan::new(&options).unwrap();
    match raygun::session::guide::GuideSource::from_replay(&plan, &file).unwrap() {
        raygun::session::guide::GuideSource::Replay { eyes, .. } => eyes,
        other => panic!("a replay gives a replay source, not {other:?}"),
    }
}

/// The eye the listing's sensor-0 report `which` ("first" or "last") puts through the golden
/// calibration (identity rotation, origin at room (0, −1.2, 1.25)) with `offset`.
fn listed_eye(listing: &Value, which: &str, offset: [f64; 3]) -> glam::DVec3 {
    let r = &listing["tracker"]["sensors"]["0"][which];
    let v = |key: &str| -> Vec<f64> {
        r[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (p, q) = (v("pos"), v("quat_xyzw"));
    let q = DQuat::from_xyzw(q[0], q[1], q[2], q[3]);
    glam::DVec3::new(p[0], p[1] - 1.2, p[2] + 1.25) + q * glam::DVec3::from_array(offset)
}

/// A VRPN tracker sensor is the wall camera's head (DESIGN.md §11): `--head` names the device
/// the VRPN mapping gives it, through the same calibration as the ray gun — with the default
/// mapping (sensor 0 is body:0) and with a mapping that puts the sensor on another body. A
/// head the mapping gives no sensor is refused by name.
#[test]
fn a_vrpn_sensor_is_the_tracked_head_under_any_mapping() {
    let cap = tcp_capture();
    let offset = [0.03, 0.08, -0.1];
    let eyes = head_eyes(cap.replay_path(), body(), offset);
    let sensor0 = &cap.listing["tracker"]["sensors"]["0"];
    assert_eq!(eyes.len() as u64, sensor0["count"].as_u64().unwrap());
    // 1 µm: the decoder renormalises the wire's quaternion.
    let close = |a: glam::DVec3, b: glam::DVec3| (a - b).length() < 1e-6;
    assert!(close(eyes[0].1, listed_eye(&cap.listing, "first", offset)));
    assert!(close(
        eyes.last().unwrap().1,
        listed_eye(&cap.listing, "last", offset)
    ));
    assert!(eyes.windows(2).all(|w| w[0].0 <= w[1].0), "in time order");

    // The same bytes with sensor 0 mapped to body:4 (a lab's own numbering).
    let mut config = golden_config();
    config.sensors = BTreeMap::from([(0, DeviceId::new(DeviceKind::Body, 4)), (1, flystick())]);
    let mut header =
        ReplayHeader::vrpn_recording(&"DTrack@tcp://127.0.0.1:3883".parse().unwrap(), &config);
    header.description = "the TCP capture, sensor 0 mapped to body:4".into();
    header.display = Some("display-models/hornet.json".into());
    header.device = Some(flystick());
    let mut w = ReplayWriter::new(Vec::new(), &header).unwrap();
    for (p, t, bytes) in reads_of(&cap.tcp, &cap.udp) {
        w.datagram(t, p, &bytes).unwrap();
    }
    let dir = std::env::temp_dir().join(format!("raygun-vrpn-head-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("body4.vrpn.jsonl");
    std::fs::write(&file, w.into_inner()).unwrap();
    let mapped = head_eyes(file.clone(), DeviceId::new(DeviceKind::Body, 4), offset);
    assert_eq!(mapped, eyes, "the sensor's eyes under its new name");
    std::fs::remove_dir_all(&dir).unwrap();
}
