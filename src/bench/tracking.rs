//! Ingest benchmarks (DESIGN.md §10; not timed tests): DTrack parse rate per core, OSC
//! decode rate, VRPN decode rate, a 10 kHz DTrack datagram stream through the live UDP
//! listener with latest-state semantics, and a 10 kHz VRPN Pos_Quat stream over loopback TCP
//! into the live VRPN client.
//! Run with `cargo bench --bench tracking_ingest`; results: BENCHMARKS.md, *Tracking ingest*.

use std::fmt::Write as _;
use std::io::{Read, Write};
use std::net::{TcpListener, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use crate::interaction::{HingedWall, Interaction, InteractionConfig};
use crate::session::pipeline::Pipeline;
use crate::session::udp::{ListenerConfig, Live, UdpSource, run_live};
use crate::session::vrpn::{self as vrpn_live, VrpnClientConfig, VrpnSource};
use crate::tracking::dtrack::{DtrackConfig, DtrackDecoder, TimeSource, parse_datagram};
use crate::tracking::event::{DeviceId, DeviceKind, Pose};
use crate::tracking::ingest::{Ingest, Protocol};
use crate::tracking::osc::{OscConfig, OscDecoder, encode};
use crate::tracking::problems::ProblemLog;
use crate::tracking::vrpn::wire::{VrpnTime, encode as vrpn_encode};
use crate::tracking::vrpn::{Channel, VrpnConfig, VrpnDecoder};

/// A typical lab frame: 5 lines (frame, time, calibration, two bodies, one FlyStick).
#[must_use]
pub fn typical_frame(i: u32, buttons: u32) -> String {
    let rot =
        "[0.948575 0.316552 0.000151 0.127231 -0.381696 0.915489 0.289857 -0.868391 -0.402343]";
    format!(
        "fr {i}\nts {:.6}\n6dcal 3\n6d 2 [1 1.000][326.848 -187.216 1109.921]{rot} [4 0.870][-12.5 80.25 1600.0]{rot}\n\
         6df2 1 1 [0 1.000 6 2][247.317 -744.649 1098.267]{rot}[{buttons} 0.125000 -0.500000]\n",
        36_000.0 + f64::from(i) / 60.0
    )
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown CPU".into())
}

/// Runs every benchmark and returns a Markdown report.
#[must_use]
pub fn run() -> String {
    let mut r = String::new();
    let _ = writeln!(
        r,
        "Machine: {} ({} logical CPUs available)\n",
        cpu_model(),
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );

    // 1. DTrack parse rate, one core.
    let frames: Vec<String> = (0..1000).map(|i| typical_frame(i, i % 2)).collect();
    let config = DtrackConfig::default();
    let mut n = 0u64;
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(2) {
        for f in &frames {
            n += u64::from(parse_datagram(f.as_bytes(), &config).is_ok());
        }
    }
    let secs = start.elapsed().as_secs_f64();
    let _ = writeln!(
        r,
        "| DTrack parse (5-line frame, 2 bodies + 1 FlyStick), one core | {:.0} frames/s = {:.2} M lines/s |",
        n as f64 / secs,
        n as f64 * 5.0 / secs / 1e6
    );
    // Decoder including event construction.
    let mut d = DtrackDecoder::new(config.clone(), TimeSource::Tracker);
    let mut out = Vec::new();
    let mut n = 0u64;
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(1) {
        for f in &frames {
            out.clear();
            n += u64::from(d.decode_into(f.as_bytes(), 0.0, &mut out).is_ok());
        }
    }
    let secs = start.elapsed().as_secs_f64();
    let _ = writeln!(
        r,
        "| DTrack decode to normalised events, one core | {:.0} frames/s |",
        n as f64 / secs
    );

    // Whole pipeline (decode + interaction with ray casts on presses), as the listener runs it.
    let mut ingest = Ingest::new(config.clone(), OscConfig::default(), TimeSource::Tracker);
    ingest.problems.quiet = true;
    let mut pipeline = Pipeline::new(ingest, Interaction::new(InteractionConfig::default()));
    let wall = HingedWall::hornet();
    let mut n = 0u64;
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(1) {
        for f in &frames {
            let _ = pipeline.datagram(Protocol::Dtrack, f.as_bytes(), 0.0, &wall);
            n += 1;
        }
    }
    let secs = start.elapsed().as_secs_f64();
    let _ = writeln!(
        r,
        "| DTrack frame through the whole pipeline (decode + interaction), one core | {:.0} frames/s = {:.1} µs per frame |",
        n as f64 / secs,
        secs / n as f64 * 1e6
    );

    // 2. OSC decode rate.
    let pose = Pose {
        position: glam::DVec3::new(0.25, -0.35, 0.75),
        orientation: glam::DQuat::from_rotation_y(0.3),
    };
    let bundle = encode::bytes(&encode::bundle(
        3_976_000_000.5,
        vec![
            encode::pose(0, &pose),
            encode::buttons(0, 1),
            encode::axes(0, &[0.1, -0.2]),
        ],
    ));
    let mut osc = OscDecoder::new(OscConfig::default());
    let mut n = 0u64;
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(1) {
        for _ in 0..1000 {
            out.clear();
            n += u64::from(osc.decode_into(&bundle, 0.0, &mut out).is_ok());
        }
    }
    let secs = start.elapsed().as_secs_f64();
    let _ = writeln!(
        r,
        "| OSC decode (bundle: pose, buttons, axes; {} bytes), one core | {:.0} bundles/s |",
        bundle.len(),
        n as f64 / secs
    );

    // 3. VRPN decode rate.
    let _ = writeln!(r, "{}", vrpn_decode_rate());

    // 4. 10 kHz streams through the live listeners.
    let _ = writeln!(r, "\n{}", stream_10khz(Duration::from_secs(3)));
    let _ = writeln!(r, "\n{}", vrpn_stream_10khz(Duration::from_secs(3)));
    r
}

/// VRPN ids of the benchmark server: sender 1 is the device, then its types.
const VRPN_DEVICE: &str = "DTrack";
const VRPN_POS_QUAT: i32 = 4;
const VRPN_CHANGE: i32 = 18;
const VRPN_ANALOG: i32 = 22;

/// A vrpn_server's first bytes: cookie and descriptions.
fn vrpn_preamble() -> Vec<u8> {
    let mut b = vrpn_encode::cookie().to_vec();
    vrpn_encode::sender_description(&mut b, 0, 0, "VRPN Control");
    vrpn_encode::sender_description(&mut b, 1, 1, VRPN_DEVICE);
    vrpn_encode::type_description(&mut b, 2, VRPN_POS_QUAT, "vrpn_Tracker Pos_Quat");
    vrpn_encode::type_description(&mut b, 3, VRPN_CHANGE, "vrpn_Button Change");
    vrpn_encode::type_description(&mut b, 4, VRPN_ANALOG, "vrpn_Analog Channel");
    b
}

/// Message `i` of the benchmark stream: a FlyStick (sensor 1) pose 1 m in front of HORNET's
/// centre pointing at it (identity calibration); every 500th a trigger change (a shot every
/// 0.1 s at 10 kHz, slower than the 30 ms debounce), every 10th an analog report with the
/// stick pushed (FOV changes).
fn vrpn_message(out: &mut Vec<u8>, i: u32, seq: u32) {
    let t = VrpnTime::from_seconds(1_700_000_000.0 + f64::from(i) * 1e-4);
    let yaw = 0.2 * (f64::from(i) * 1e-3).sin();
    let q = glam::DQuat::from_rotation_y(yaw);
    if i % 500 == 499 {
        let state = i32::from((i / 500).is_multiple_of(2));
        vrpn_encode::message(
            out,
            t,
            1,
            VRPN_CHANGE,
            seq,
            &vrpn_encode::button_change(0, state),
        );
    } else if i % 10 == 9 {
        let y = if (i / 5000).is_multiple_of(2) {
            -0.5
        } else {
            0.5
        };
        vrpn_encode::message(out, t, 1, VRPN_ANALOG, seq, &vrpn_encode::analog(&[0.0, y]));
    } else {
        let p = vrpn_encode::pos_quat(1, [0.1, 0.0, 1.0], [q.x, q.y, q.z, q.w]);
        vrpn_encode::message(out, t, 1, VRPN_POS_QUAT, seq, &p);
    }
}

/// VRPN decode rate: a vrpn_server stream (Pos_Quat, 10 % analogs, 0.2 % button changes) cut
/// into 4 KiB reads, through the decoder alone and through the whole pipeline.
#[must_use]
pub fn vrpn_decode_rate() -> String {
    let mut stream = vrpn_preamble();
    let preamble = stream.len();
    let n = 20_000u32;
    for i in 0..n {
        vrpn_message(&mut stream, i, 5 + i);
    }
    let body = &stream[preamble..];
    let mut r = String::new();
    let mut out = Vec::new();
    let mut problems = ProblemLog::quiet();
    let (mut messages, mut bytes) = (0u64, 0u64);
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(2) {
        let mut d = VrpnDecoder::new(VRPN_DEVICE, VrpnConfig::default(), TimeSource::Tracker)
            .expect("default mapping");
        d.decode(
            Channel::Tcp,
            &stream[..preamble],
            0.0,
            &mut out,
            &mut problems,
        );
        for (k, chunk) in body.chunks(4096).enumerate() {
            out.clear();
            // Receive times as a 10 kHz stream would have them (the flood check uses them).
            d.decode(
                Channel::Tcp,
                chunk,
                k as f64 * 0.0046,
                &mut out,
                &mut problems,
            );
        }
        messages += d.stats().messages;
        bytes += d.stats().tcp_bytes;
    }
    let secs = start.elapsed().as_secs_f64();
    let _ = writeln!(
        r,
        "| VRPN decode to normalised events (88-byte Pos_Quat, 10 % analogs, 0.2 % buttons; 4 KiB reads), one core | {:.2} M messages/s = {:.0} MB/s, {} problems |",
        messages as f64 / secs / 1e6,
        bytes as f64 / secs / 1e6,
        problems.total()
    );
    let mut n_msgs = 0u64;
    let wall = HingedWall::hornet();
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(1) {
        let mut ingest = Ingest::vrpn_only(VRPN_DEVICE, VrpnConfig::default(), TimeSource::Tracker)
            .expect("default mapping");
        ingest.problems.quiet = true;
        let mut p = Pipeline::new(ingest, Interaction::new(InteractionConfig::default()));
        let _ = p.datagram(Protocol::VrpnTcp, &stream[..preamble], 0.0, &wall);
        for (k, chunk) in body.chunks(4096).enumerate() {
            let _ = p.datagram(Protocol::VrpnTcp, chunk, k as f64 * 0.0046, &wall);
        }
        n_msgs += u64::from(n);
    }
    let secs = start.elapsed().as_secs_f64();
    let _ = write!(
        r,
        "| VRPN message through the whole pipeline (decode + interaction with its ray casts), one core | {:.2} M messages/s = {:.2} µs per message |",
        n_msgs as f64 / secs / 1e6,
        secs / n_msgs as f64 * 1e6
    );
    r
}

/// A fake vrpn_server sends Pos_Quat (with buttons and analogs mixed in) at 10 kHz over
/// loopback TCP, one write per message, to the live VRPN client ([`vrpn_live::run_live`]); reports
/// loss, drain time, backlog and memory.
#[must_use]
pub fn vrpn_stream_10khz(duration: Duration) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind loopback");
    let addr = listener.local_addr().expect("local address");
    let handled = Arc::new(AtomicU64::new(0));
    let stop = Arc::new(AtomicBool::new(false));
    let live = Arc::new(Live::default());
    let rss_before = super::proc_status_kib("VmRSS:");
    let server = {
        let handled = handled.clone();
        std::thread::spawn(
            move || -> std::io::Result<(u64, u64, f64, std::net::TcpStream)> {
                let (mut tcp, _) = listener.accept()?;
                tcp.set_nodelay(true)?;
                let pre = vrpn_preamble();
                tcp.write_all(&pre[..24])?;
                let mut cookie = [0u8; 24];
                tcp.read_exact(&mut cookie)?;
                tcp.write_all(&pre[24..])?;
                let period = Duration::from_micros(100);
                let start = Instant::now();
                let (mut sent, mut max_backlog) = (0u64, 0u64);
                let mut msg = Vec::with_capacity(96);
                while start.elapsed() < duration {
                    let due = period * sent as u32;
                    while start.elapsed() < due {
                        std::hint::spin_loop();
                    }
                    msg.clear();
                    vrpn_message(&mut msg, sent as u32, 5 + sent as u32);
                    tcp.write_all(&msg)?;
                    sent += 1;
                    if sent.is_multiple_of(100) {
                        max_backlog =
                            max_backlog.max(sent.saturating_sub(handled.load(Ordering::Acquire)));
                    }
                }
                // The connection stays open (returned) until the client has drained it.
                Ok((sent, max_backlog, start.elapsed().as_secs_f64(), tcp))
            },
        )
    };
    let client = {
        let (stop, live, handled) = (stop.clone(), live.clone(), handled.clone());
        std::thread::spawn(move || -> (u64, u64) {
            let address = format!("{VRPN_DEVICE}@tcp://{addr}")
                .parse()
                .expect("address");
            let mut source = VrpnSource::new(VrpnClientConfig {
                poll: Duration::from_millis(5),
                ..VrpnClientConfig::new(address)
            })
            .expect("loopback client");
            let mut ingest =
                Ingest::vrpn_only(VRPN_DEVICE, VrpnConfig::default(), TimeSource::Tracker)
                    .expect("default mapping");
            ingest.problems.quiet = true;
            let mut pipeline =
                Pipeline::new(ingest, Interaction::new(InteractionConfig::default()));
            let wall = HingedWall::hornet();
            let _ = vrpn_live::run_live(
                &mut source,
                &mut pipeline,
                &wall,
                &stop,
                &live,
                |events, _| {
                    // Each message of this stream gives exactly one FlyStick event.
                    handled.fetch_add(events.len() as u64, Ordering::Release);
                },
            );
            let stats = pipeline
                .ingest
                .vrpn()
                .map(|v| v.stats().clone())
                .unwrap_or_default();
            (
                stats.pos_quat + stats.button_changes + stats.analog,
                pipeline.ingest.problems.total(),
            )
        })
    };
    let (sent, max_backlog, send_secs, connection) = match server.join() {
        Ok(Ok((s, b, secs, tcp))) => (s, b, secs, Some(tcp)),
        _ => (0, 0, 0.0, None),
    };
    let sent_at = Instant::now();
    let drain_deadline = sent_at + Duration::from_secs(2);
    while handled.load(Ordering::Acquire) < sent && Instant::now() < drain_deadline {
        std::hint::spin_loop();
    }
    let drain = sent_at.elapsed();
    stop.store(true, Ordering::Relaxed);
    let (decoded, problems) = client.join().unwrap_or((0, u64::MAX));
    drop(connection);
    let rss_after = super::proc_status_kib("VmRSS:");
    let snap = live.snapshot();
    format!(
        "| 10 kHz VRPN Pos_Quat stream over loopback TCP into the live client, {send_secs:.1} s | sent {sent}, decoded {decoded} ({:.2} % lost), \
         {problems} problems, {} ROI changes |\n\
         | time from the last send to the last message handled (ROI lag at the end) | {:.3} ms |\n\
         | largest backlog seen (sent − handled, sampled every 100) | {max_backlog} messages |\n\
         | process RSS before → after the stream | {} → {} KiB |",
        100.0 * (sent - decoded.min(sent)) as f64 / sent.max(1) as f64,
        snap.version,
        drain.as_secs_f64() * 1e3,
        rss_before.map_or("?".into(), |v| v.to_string()),
        rss_after.map_or("?".into(), |v| v.to_string()),
    )
}

/// Sends DTrack frames at 10 kHz over loopback to a live listener and reports loss, drain
/// time, backlog and memory.
#[must_use]
pub fn stream_10khz(duration: Duration) -> String {
    let mut source = UdpSource::bind(ListenerConfig {
        poll: Duration::from_millis(5),
        ..ListenerConfig::loopback(0)
    })
    .expect("bind loopback");
    let addr = source.local_addr().expect("local address");
    let stop = Arc::new(AtomicBool::new(false));
    let live = Arc::new(Live::default());
    let rss_before = super::proc_status_kib("VmRSS:");
    let listener = {
        let (stop, live) = (stop.clone(), live.clone());
        std::thread::spawn(move || {
            let mut pipeline = Pipeline::quiet_live(DeviceId::new(DeviceKind::Flystick, 0));
            let wall = HingedWall::hornet();
            let _ = run_live(
                &mut source,
                Protocol::Dtrack,
                &mut pipeline,
                &wall,
                &stop,
                &live,
                |_, _| {},
            );
            pipeline.ingest.problems.total()
        })
    };
    let sender = UdpSocket::bind("127.0.0.1:0").expect("bind sender");
    let frames: Vec<Vec<u8>> = (0..1000)
        .map(|i| typical_frame(i, u32::from(i % 100 < 50)).into_bytes())
        .collect();
    let period = Duration::from_micros(100);
    let start = Instant::now();
    let mut sent = 0u64;
    let mut max_backlog = 0u64;
    while start.elapsed() < duration {
        let due = period * sent as u32;
        while start.elapsed() < due {
            std::hint::spin_loop();
        }
        let _ = sender.send_to(&frames[sent as usize % frames.len()], addr);
        sent += 1;
        if sent.is_multiple_of(100) {
            max_backlog = max_backlog.max(sent.saturating_sub(live.datagrams()));
        }
    }
    let send_secs = start.elapsed().as_secs_f64();
    let sent_at = Instant::now();
    let drain_deadline = sent_at + Duration::from_secs(2);
    while live.datagrams() < sent && Instant::now() < drain_deadline {
        std::hint::spin_loop();
    }
    let drain = sent_at.elapsed();
    let received = live.datagrams();
    stop.store(true, Ordering::Relaxed);
    let problems = listener.join().unwrap_or(u64::MAX);
    let rss_after = super::proc_status_kib("VmRSS:");
    let snap = live.snapshot();
    format!(
        "| 10 kHz DTrack stream over loopback, {send_secs:.1} s | sent {sent}, handled {received} ({:.2} % lost), \
         {problems} problems, {} ROI changes |\n\
         | time from last send to last datagram handled (ROI lag at the end) | {:.3} ms |\n\
         | largest backlog seen (sent − handled, sampled every 100) | {max_backlog} datagrams |\n\
         | process RSS before → after the stream | {} → {} KiB |",
        100.0 * (sent - received.min(sent)) as f64 / sent as f64,
        snap.version,
        drain.as_secs_f64() * 1e3,
        rss_before.map_or("?".into(), |v| v.to_string()),
        rss_after.map_or("?".into(), |v| v.to_string()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_benchmark_frame_parses_with_two_bodies_and_a_stick() {
        let f = parse_datagram(typical_frame(3, 1).as_bytes(), &DtrackConfig::default()).unwrap();
        assert_eq!((f.bodies.len(), f.flysticks.len()), (2, 1));
        assert_eq!(f.flysticks[0].buttons, 1);
    }

    #[test]
    fn the_vrpn_benchmark_stream_decodes_without_problems_and_shoots() {
        let mut stream = vrpn_preamble();
        for i in 0..1000 {
            vrpn_message(&mut stream, i, 5 + i);
        }
        let mut ingest =
            Ingest::vrpn_only(VRPN_DEVICE, VrpnConfig::default(), TimeSource::Tracker).unwrap();
        ingest.problems.quiet = true;
        let mut p = Pipeline::new(ingest, Interaction::new(InteractionConfig::default()));
        let wall = HingedWall::hornet();
        let (events, changes) = p.datagram(Protocol::VrpnTcp, &stream, 0.0, &wall);
        assert_eq!(events.len(), 1000);
        assert!(
            changes
                .iter()
                .any(|c| c.cause == crate::interaction::ChangeCause::Fov)
        );
        assert!(
            changes
                .iter()
                .any(|c| c.cause == crate::interaction::ChangeCause::Shoot)
        );
        assert_eq!(p.ingest.problems.total(), 0);
    }
}
