//! Live listener behaviour: bad input of every kind is counted per kind and never reaches the
//! ROI; binding and source rules; the recorder writes what it received.

use std::net::{IpAddr, Ipv4Addr, SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use raygun::cli::tracking::{RecordArgs, listener_config};
use raygun::interaction::{ChangeCause, HingedWall, RoiChange};
use raygun::session::pipeline::Pipeline;
use raygun::session::udp::{ListenerConfig, Live, UdpError, UdpSource, record, run_live};
use raygun::tracking::event::{DeviceId, DeviceKind};
use raygun::tracking::ingest::Protocol;
use raygun::tracking::osc::encode;
use raygun::tracking::problems::ProblemLog;
use raygun::tracking::replay::{ReplayHeader, ReplayPayload, ReplayReader, ReplayWriter};
use rosc::{OscMessage, OscPacket, OscType};

const ID_ROT: &str = "[1 0 0 0 1 0 0 0 1]";

fn quick(port: u16) -> ListenerConfig {
    ListenerConfig {
        poll: Duration::from_millis(5),
        ..ListenerConfig::loopback(port)
    }
}

/// Runs a listener for `protocol`, sends `datagrams` from loopback, and returns the ROI changes
/// and problem counts.
fn feed(
    protocol: Protocol,
    device: DeviceId,
    datagrams: &[Vec<u8>],
) -> (Vec<RoiChange>, ProblemLog, Live) {
    let mut source = UdpSource::bind(quick(0)).unwrap();
    let addr = source.local_addr().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let live = Arc::new(Live::default());
    let handle = {
        let (stop, live) = (stop.clone(), live.clone());
        std::thread::spawn(move || {
            let mut pipeline = Pipeline::quiet_live(device);
            let wall = HingedWall::hornet();
            let mut changes = Vec::new();
            run_live(
                &mut source,
                protocol,
                &mut pipeline,
                &wall,
                &stop,
                &live,
                |_, c| {
                    changes.extend_from_slice(c);
                },
            )
            .unwrap();
            (changes, pipeline.ingest.problems)
        })
    };
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    for (i, d) in datagrams.iter().enumerate() {
        sender.send_to(d, addr).unwrap();
        let deadline = Instant::now() + Duration::from_secs(5);
        // One at a time: the test is about handling, not about loss.
        while live.datagrams() < i as u64 + 1 {
            assert!(Instant::now() < deadline);
            std::thread::yield_now();
        }
    }
    stop.store(true, Ordering::Relaxed);
    let (changes, problems) = handle.join().unwrap();
    let live = Arc::try_unwrap(live).unwrap();
    (changes, problems, live)
}

fn shot(t_ms: u32, buttons: u32) -> Vec<u8> {
    // Stick at the viewer's eye pointing straight at the wall centre.
    format!("fr {t_ms}\n6df2 1 1 [0 1.0 6 2][0 0 1000]{ID_ROT}[{buttons} 0 0]\n").into_bytes()
}

#[test]
fn bad_dtrack_input_of_every_kind_is_counted_and_never_reaches_the_roi() {
    let flystick = DeviceId::new(DeviceKind::Flystick, 0);
    let mut oversized = b"fr 1\n".to_vec();
    oversized.resize(40_000, b' ');
    let bad: Vec<Vec<u8>> = vec![
        vec![0xde, 0xad, 0xbe, 0xef, 0x00, 0xff],
        format!("6df2 1 1 [0 1.0 6 2][nan 0 1000]{ID_ROT}[1 0 0]").into_bytes(),
        format!("6df2 1 1 [0 1.0 6 2][inf 0 1000]{ID_ROT}[1 0 0]").into_bytes(),
        b"6d 4294967295 [0 1.0]".to_vec(),
        oversized,
        b"6df2 1 1 [0 1.0 6 2][0 0 1000][9 9 9 9 9 9 9 9 9][1 0 0]".to_vec(),
        format!("6df2 1 1 [0 1.0 6 2][0 0 1000]{ID_ROT}[1 7.0 0]").into_bytes(),
    ];
    let mut all = bad.clone();
    // Then a good release and a good press: exactly one shot.
    all.push(shot(1, 0));
    all.push(shot(2, 1));
    let (changes, problems, live) = feed(Protocol::Dtrack, flystick, &all);
    for kind in [
        "dtrack_not_text",
        "dtrack_non_finite",
        "dtrack_out_of_range",
        "dtrack_oversized",
        "dtrack_not_rotation",
    ] {
        assert!(
            problems.count(kind) >= 1,
            "{kind} not counted: {:?}",
            problems.counts()
        );
    }
    assert_eq!(problems.total(), bad.len() as u64);
    assert_eq!(changes.len(), 1);
    assert_eq!(changes[0].cause, ChangeCause::Shoot);
    let centre = changes[0].roi.centre.clone().unwrap();
    assert!(centre.point.length() < 1e-9, "{:?}", centre.point);
    let snap = live.snapshot();
    assert_eq!(snap.roi, Some(changes[0].roi.clone()));
    assert_eq!(snap.version, 1);
    assert_eq!(snap.problems.total(), bad.len() as u64);
}

#[test]
fn bad_osc_input_of_every_kind_is_counted_and_never_reaches_the_roi() {
    let osc0 = DeviceId::new(DeviceKind::Osc, 0);
    let msg = |addr: &str, args: Vec<OscType>| {
        encode::bytes(&OscPacket::Message(OscMessage {
            addr: addr.into(),
            args,
        }))
    };
    let good_pose = encode::bytes(&encode::pose(
        0,
        &raygun::tracking::event::Pose {
            position: glam::DVec3::new(0.0, 0.0, 1.0),
            orientation: glam::DQuat::IDENTITY,
        },
    ));
    let truncated = good_pose[..good_pose.len() - 3].to_vec();
    let bad: Vec<Vec<u8>> = vec![
        b"garbage that is not OSC".to_vec(),
        truncated,
        msg("/raygun/0/buttons", vec![OscType::String("1".into())]),
        msg("/raygun/0/axes", vec![OscType::Float(f32::NAN)]),
        msg("/raygun/0/pose", vec![OscType::Float(f32::INFINITY); 7]),
        msg("/raygun/0/fov", vec![OscType::Float(1.0)]),
        msg("/raygun/9999/lost", vec![]),
    ];
    let mut all = bad.clone();
    all.push(good_pose);
    all.push(encode::bytes(&encode::buttons(0, 0)));
    all.push(encode::bytes(&encode::buttons(0, 1)));
    let (changes, problems, _) = feed(Protocol::Osc, osc0, &all);
    for kind in [
        "osc_decode",
        "osc_type_mismatch",
        "osc_bad_value",
        "osc_arg_count",
        "osc_bad_device",
    ] {
        assert!(
            problems.count(kind) >= 1,
            "{kind} not counted: {:?}",
            problems.counts()
        );
    }
    assert_eq!(problems.total(), bad.len() as u64);
    assert_eq!(changes.len(), 1);
    assert!(changes[0].roi.centre.as_ref().unwrap().point.length() < 1e-9);
}

#[test]
fn binding_a_network_address_needs_the_explicit_flag() {
    let config = ListenerConfig {
        bind: SocketAddr::new(IpAddr::V4(Ipv4Addr::UNSPECIFIED), 0),
        ..ListenerConfig::loopback(0)
    };
    assert!(matches!(
        UdpSource::bind(config.clone()),
        Err(UdpError::NonLoopback { .. })
    ));
    let allowed = ListenerConfig {
        allow_non_loopback: true,
        ..config
    };
    assert!(UdpSource::bind(allowed).is_ok());
}

#[test]
fn receive_buffer_is_at_least_64_kib_and_smaller_requests_are_refused() {
    let s = UdpSource::bind(quick(0)).unwrap();
    assert!(s.recv_buffer_bytes().unwrap() >= 64 * 1024);
    let small = ListenerConfig {
        recv_buffer_bytes: 4096,
        ..quick(0)
    };
    assert!(matches!(
        UdpSource::bind(small),
        Err(UdpError::BufferTooSmall { .. })
    ));
}

#[test]
fn largest_osc_bundle_fits_the_receive_path() {
    // ~60 KiB of messages in one bundle (the UDP maximum is 65 507 bytes).
    let content: Vec<OscPacket> = (0..2000).map(|_| encode::buttons(0, 0)).collect();
    let big = encode::bytes(&encode::bundle(10.0, content));
    assert!(big.len() > 60_000 && big.len() < 65_507, "{}", big.len());
    // End with a press so the bundle's effect is visible.
    let press = encode::bytes(&encode::buttons(0, 1));
    let pose = encode::bytes(&encode::pose(
        0,
        &raygun::tracking::event::Pose {
            position: glam::DVec3::new(0.0, 0.0, 1.0),
            orientation: glam::DQuat::IDENTITY,
        },
    ));
    let (changes, problems, _) = feed(
        Protocol::Osc,
        DeviceId::new(DeviceKind::Osc, 0),
        &[pose, big, press],
    );
    assert_eq!(problems.total(), 0, "{:?}", problems.counts());
    assert_eq!(changes.len(), 1);
}

#[test]
fn sources_off_the_allow_list_are_rejected_and_counted() {
    let mut source = UdpSource::bind(ListenerConfig {
        allow_from: vec![IpAddr::V4(Ipv4Addr::new(10, 9, 8, 7))],
        ..quick(0)
    })
    .unwrap();
    let addr = source.local_addr().unwrap();
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    sender.send_to(&shot(1, 1), addr).unwrap();
    let mut writer = ReplayWriter::new(Vec::new(), &ReplayHeader::new("t")).unwrap();
    let mut problems = ProblemLog::quiet();
    let n = record(
        &mut source,
        Protocol::Dtrack,
        &mut writer,
        &AtomicBool::new(false),
        Some(Duration::from_millis(200)),
        &mut problems,
    )
    .unwrap();
    assert_eq!(n, 0);
    assert_eq!(problems.count("udp_rejected_source"), 1);
}

#[test]
fn recorder_writes_every_datagram_in_the_replay_format() {
    let mut source = UdpSource::bind(quick(0)).unwrap();
    let addr = source.local_addr().unwrap();
    let sent: Vec<Vec<u8>> = vec![shot(1, 0), vec![0xff, 0x00, 0x41], shot(2, 1)];
    let to_send = sent.clone();
    let sender = std::thread::spawn(move || {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        std::thread::sleep(Duration::from_millis(20));
        for d in &to_send {
            s.send_to(d, addr).unwrap();
        }
    });
    let mut writer = ReplayWriter::new(Vec::new(), &ReplayHeader::new("recorded")).unwrap();
    let mut problems = ProblemLog::quiet();
    let n = record(
        &mut source,
        Protocol::Dtrack,
        &mut writer,
        &AtomicBool::new(false),
        // Ample time for the sender thread on a loaded CI machine (it sends after 20 ms).
        Some(Duration::from_secs(2)),
        &mut problems,
    )
    .unwrap();
    sender.join().unwrap();
    assert_eq!(n, 3);
    let bytes = writer.into_inner();
    let mut reader = ReplayReader::new(&bytes[..], Path::new("rec")).unwrap();
    let mut got = Vec::new();
    let mut last_t = 0.0;
    while let Some(item) = reader.next_item() {
        assert!(item.t >= last_t);
        last_t = item.t;
        match item.payload {
            ReplayPayload::Datagram(Protocol::Dtrack, b) => got.push(b),
            other => panic!("{other:?}"),
        }
    }
    assert_eq!(got, sent);
}

#[test]
fn record_arguments_are_validated_before_binding() {
    let args = |dtrack, osc, seconds| RecordArgs {
        dtrack,
        osc,
        vrpn: None,
        out: "x.jsonl".into(),
        display: "hornet".into(),
        calibration: None,
        bind: IpAddr::V4(Ipv4Addr::LOCALHOST),
        allow_network: false,
        allow_from: vec![],
        seconds,
        head: Default::default(),
    };
    assert!(listener_config(&args(Some(5000), None, None)).is_ok());
    let (c, p) = listener_config(&args(None, Some(9000), Some(1.0))).unwrap();
    assert_eq!((c.bind.port(), p), (9000, Protocol::Osc));
    assert!(listener_config(&args(Some(1), Some(2), None)).is_err());
    assert!(listener_config(&args(Some(1), None, Some(-1.0))).is_err());
    assert!(listener_config(&args(Some(1), None, Some(f64::NAN))).is_err());
}
