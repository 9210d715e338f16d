//! Ingest benchmarks (issue 3; not timed tests): DTrack parse rate per core, OSC decode rate,
//! and a 10 kHz datagram stream through the live listener with latest-state semantics.
//! Run with `cargo bench --bench tracking_ingest`; results are quoted in `BENCHMARKS.md`.

use std::fmt::Write as _;
use std::net::UdpSocket;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::dtrack::{DtrackConfig, DtrackDecoder, TimeSource, parse_datagram};
use super::event::{DeviceId, DeviceKind, Pose};
use super::ingest::{Ingest, Pipeline, Protocol};
use super::osc::{OscConfig, OscDecoder, encode};
use super::udp::{ListenerConfig, Live, UdpSource, run_live};
use crate::interaction::{HingedWall, Interaction, InteractionConfig};

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

fn rss_kib() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
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

    // 3. 10 kHz stream through the live listener.
    let _ = writeln!(r, "\n{}", stream_10khz(Duration::from_secs(3)));
    r
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
    let rss_before = rss_kib();
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
    let rss_after = rss_kib();
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
}
