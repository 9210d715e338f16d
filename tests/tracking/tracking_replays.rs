//! The shipped replays: up to date with their generator, and every one gives its golden ROI
//! sequence both offline and through the live UDP path.
//!
//! `RAYGUN_BLESS=1 cargo test --test tracking tracking_replays::` rewrites the replays and golden files.

use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use raygun::cli::tracking::{ReplayArgs, run_replay};
use raygun::interaction::synth;
use raygun::session::replay::{ChangePrinter, ReplayPlan, golden_path};
use raygun::session::udp::{ListenerConfig, Live, UdpSource, run_live};
use raygun::tracking::head::EyeRule;
use raygun::tracking::replay::ReplayPayload;

fn replay_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tracking-replays")
}

fn bless() -> bool {
    std::env::var_os("RAYGUN_BLESS").is_some()
}

fn replay_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(replay_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "jsonl"))
        .collect();
    v.sort();
    v
}

fn args(file: &Path) -> ReplayArgs {
    ReplayArgs {
        file: file.to_owned(),
        display: None,
        config: None,
        device: None,
        calibration: None,
        realtime: false,
        head: Default::default(),
    }
}

#[test]
fn shipped_replays_are_what_the_generator_makes() {
    let dir = replay_dir();
    let all = synth::all_replays().unwrap();
    assert!(all.len() >= 13, "six FlySticks in two forms and a mouse");
    for (name, bytes) in all {
        let path = dir.join(&name);
        if bless() {
            std::fs::write(&path, &bytes).unwrap();
        }
        let on_disk = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(
            on_disk == bytes,
            "{name} differs from the generator's output; run with RAYGUN_BLESS=1"
        );
    }
}

#[test]
fn every_replay_matches_its_golden_roi_sequence() {
    let files = replay_files();
    assert!(files.len() >= 13);
    for file in files {
        let mut out = Vec::new();
        let problems = run_replay(&args(&file), &mut out).unwrap().problems;
        assert_eq!(
            problems.total(),
            0,
            "{}: {:?}",
            file.display(),
            problems.counts()
        );
        let golden = golden_path(&file);
        if bless() {
            std::fs::create_dir_all(golden.parent().unwrap()).unwrap();
            std::fs::write(&golden, &out).unwrap();
        }
        let expect = std::fs::read_to_string(&golden)
            .unwrap_or_else(|e| panic!("{}: {e}", golden.display()));
        let got = String::from_utf8(out).unwrap();
        assert!(
            got == expect,
            "{}: ROI changes differ from {}",
            file.display(),
            golden.display()
        );
        // Every session shoots, and the FlySticks sweep the FOV over the 10°–60° range.
        assert!(got.contains("\"kind\":\"shoot\""), "{}", file.display());
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with("flystick") {
            let fovs: Vec<f64> = got
                .lines()
                .map(|l| {
                    serde_json::from_str::<serde_json::Value>(l).unwrap()["fov_deg"][0]
                        .as_f64()
                        .unwrap()
                })
                .collect();
            let lo = fovs.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = fovs.iter().copied().fold(0.0, f64::max);
            assert!(lo < 11.5 && hi > 58.5, "{name}: FOV range {lo}..{hi}");
        }
    }
}

#[test]
fn sessions_report_their_misses_and_untracked_shots() {
    let golden = |stem: &str| {
        std::fs::read_to_string(
            replay_dir()
                .join("golden")
                .join(format!("{stem}.roi.jsonl")),
        )
        .unwrap()
    };
    assert!(golden("flystick-4-misses.dtrack").contains("\"kind\":\"miss\""));
    assert!(golden("flystick-3-dropouts.dtrack").contains("\"kind\":\"untracked\""));
    assert!(golden("flystick-5-plus-extra-devices.dtrack").contains("\"kind\":\"toggle_filter\""));
}

/// Sends every datagram of `file` to a live listener over loopback and returns what it printed.
fn run_over_udp(file: &Path) -> String {
    let (plan, mut reader) = ReplayPlan::new(&args(file).options()).unwrap();
    let mut datagrams = Vec::new();
    let mut protocol = None;
    while let Some(item) = reader.next_item() {
        if let ReplayPayload::Datagram(p, bytes) = item.payload {
            protocol = Some(p);
            datagrams.push(bytes);
        }
    }
    let protocol = protocol.unwrap();
    let mut source = UdpSource::bind(ListenerConfig {
        poll: Duration::from_millis(5),
        ..ListenerConfig::loopback(0)
    })
    .unwrap();
    let addr = source.local_addr().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let live = Arc::new(Live::default());
    let device = plan.interaction.device;
    let listener = {
        let (stop, live) = (stop.clone(), live.clone());
        std::thread::spawn(move || {
            let mut pipeline = plan.pipeline();
            let mut printer = ChangePrinter::new(Vec::new());
            let head = plan.head;
            let mut rule = head.map(|h| EyeRule::new(h.eye_threshold_m));
            run_live(
                &mut source,
                protocol,
                &mut pipeline,
                &plan.surface,
                &stop,
                &live,
                |events, changes| {
                    if let Some(e) = events.iter().find(|e| e.device == device) {
                        printer.saw_event(e.t);
                    }
                    // A tracked head's eyes that restart the accumulation, as `raygun replay`
                    // prints them.
                    for e in events {
                        if let (Some(h), Some(r)) = (head, &mut rule)
                            && let Some(eye) = h.eye_of(e)
                            && r.offer(eye)
                        {
                            printer.print_eye(e.t, eye).unwrap();
                        }
                    }
                    for c in changes {
                        printer.print(c).unwrap();
                    }
                },
            )
            .unwrap();
            (printer.into_inner(), pipeline.ingest.problems)
        })
    };
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    let wait_for = |n: u64| {
        let deadline = Instant::now() + Duration::from_secs(10);
        while live.datagrams() < n {
            assert!(
                Instant::now() < deadline,
                "listener stalled at {} of {n}",
                live.datagrams()
            );
            std::thread::yield_now();
        }
    };
    for (i, d) in datagrams.iter().enumerate() {
        sender.send_to(d, addr).unwrap();
        // Flow control: never more than 64 datagrams in flight, so loopback never drops one.
        if i % 64 == 63 {
            wait_for(i as u64 + 1);
        }
    }
    wait_for(datagrams.len() as u64);
    stop.store(true, Ordering::Relaxed);
    let (out, problems) = listener.join().unwrap();
    assert_eq!(problems.total(), 0, "{:?}", problems.counts());
    String::from_utf8(out).unwrap()
}

#[test]
fn every_raw_replay_gives_its_golden_sequence_through_the_live_udp_listener() {
    let raw: Vec<PathBuf> = replay_files()
        .into_iter()
        .filter(|p| {
            let n = p.to_string_lossy();
            n.ends_with(".dtrack.jsonl") || n.ends_with(".osc.jsonl")
        })
        .collect();
    assert_eq!(raw.len(), 14);
    for file in raw {
        let got = run_over_udp(&file);
        let expect = std::fs::read_to_string(golden_path(&file)).unwrap();
        assert!(
            got == expect,
            "{}: live ROI changes differ from the golden file",
            file.display()
        );
    }
}

#[test]
fn bad_replay_lines_are_counted_once_per_kind_and_never_change_the_roi() {
    // A shipped replay with garbage mixed in must print exactly its golden sequence.
    let file = replay_dir().join("flystick-1-centre-sweeps.dtrack.jsonl");
    let text = std::fs::read_to_string(&file).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();

    // Appended after the last record (t = 19.98 s): every kind of bad line once.
    let garbage = [
        "this is not json",
        r#"{"t":1e999,"dtrack":"fr 1"}"#,
        // Back in time, with a trigger press that must not fire.
        r#"{"t":0.0,"dtrack":"fr 1\nts 36000.0\n6df2 1 1 [0 1.0 6 2][0 0 0][1 0 0 0 1 0 0 0 1][1 0 0]"}"#,
        r#"{"t":100.0,"osc_hex":"zz"}"#,
        // Good lines whose datagrams are bad: counted by the decoder.
        r#"{"t":100.0,"dtrack":"6df2 1 1 [0 1.0 6 2][nan 0 0][1 0 0 0 1 0 0 0 1][1 0 0]"}"#,
        r#"{"t":100.0,"dtrack":"6d 99999999 [0 1.0]"}"#,
    ];
    lines.extend(garbage.iter().map(|g| (*g).to_owned()));
    let dir = std::env::temp_dir().join(format!("raygun-bad-replay-{}", std::process::id()));
    let bad = dir.join("tracking-replays").join("bad.jsonl");
    std::fs::create_dir_all(bad.parent().unwrap()).unwrap();
    std::fs::write(&bad, lines.join("\n") + "\n").unwrap();
    let mut a = args(&bad);
    a.display = Some(concat!(env!("CARGO_MANIFEST_DIR"), "/display-models/hornet.json").to_owned());
    let mut out = Vec::new();
    let problems = run_replay(&a, &mut out).unwrap().problems;
    std::fs::remove_dir_all(&dir).unwrap();
    let expect = std::fs::read_to_string(golden_path(&file)).unwrap();
    assert!(
        String::from_utf8(out).unwrap() == expect,
        "garbage changed the ROI sequence"
    );
    for kind in [
        "replay_not_json",
        "replay_back_in_time",
        "replay_bad_payload",
        "dtrack_non_finite",
        "dtrack_out_of_range",
    ] {
        assert!(problems.count(kind) >= 1, "{kind}: {:?}", problems.counts());
    }
    assert_eq!(problems.count("replay_not_json"), 2);
    assert_eq!(problems.total(), 6, "{:?}", problems.counts());
    assert!(
        problems
            .logged("replay_back_in_time")
            .unwrap()
            .contains("bad.jsonl:")
    );
}

#[test]
fn replay_needs_a_display_and_says_which_file_lacks_one() {
    let dir = std::env::temp_dir().join(format!("raygun-no-display-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("s.jsonl");
    std::fs::write(
        &file,
        "{\"raygun_replay\":1}\n{\"t\":0.0,\"dtrack\":\"fr 1\"}\n",
    )
    .unwrap();
    let err = run_replay(&args(&file), Vec::new()).unwrap_err();
    std::fs::remove_dir_all(&dir).unwrap();
    let msg = format!("{err:#}");
    assert!(
        msg.contains("s.jsonl") && msg.contains("--display"),
        "{msg}"
    );
}

/// What a replay reads is bounded: a device is refused unread, the header and every line are
/// at most `MAX_LINE` bytes (an over-long record is skipped and counted, without being held),
/// and a header whose `display` names no display model says so, naming the replay and the
/// field.
#[test]
fn replay_reads_are_bounded_and_a_bad_header_display_is_named() {
    use raygun::tracking::replay::MAX_LINE;
    let dir = std::env::temp_dir().join(format!("raygun-bounded-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let e = format!(
        "{:#}",
        run_replay(&args(Path::new("/dev/zero")), Vec::new()).unwrap_err()
    );
    assert!(
        e.contains("/dev/zero: is a character device, not a file"),
        "{e}"
    );
    // A header line longer than the limit is refused after MAX_LINE + 1 bytes.
    let long = dir.join("long-header.jsonl");
    let header = format!(
        "{{\"raygun_replay\":1,\"description\":\"{}\"}}\n",
        "x".repeat(MAX_LINE)
    );
    std::fs::write(&long, header).unwrap();
    let e = format!("{:#}", run_replay(&args(&long), Vec::new()).unwrap_err());
    assert!(
        e.contains("long-header.jsonl: line 1 is not a replay header")
            && e.contains(&format!("longer than {MAX_LINE} bytes")),
        "{e}"
    );
    // An over-long record between good ones is skipped and counted; the rest plays.
    let file = replay_dir().join("flystick-1-centre-sweeps.dtrack.jsonl");
    let text = std::fs::read_to_string(&file).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    lines.insert(
        2,
        format!("{{\"t\":0.0,\"dtrack\":\"{}\"}}", "y".repeat(3 * MAX_LINE)),
    );
    let padded = dir.join("tracking-replays").join("long-record.jsonl");
    std::fs::create_dir_all(padded.parent().unwrap()).unwrap();
    std::fs::write(&padded, lines.join("\n") + "\n").unwrap();
    let mut out = Vec::new();
    let problems = run_replay(&args(&padded), &mut out).unwrap().problems;
    assert_eq!(
        problems.count("replay_line_too_long"),
        1,
        "{:?}",
        problems.counts()
    );
    let expect = std::fs::read_to_string(golden_path(&file)).unwrap();
    assert!(String::from_utf8(out).unwrap() == expect);
    // The header's display names a file that is no display model.
    let notes = dir.join("notes.txt");
    std::fs::write(&notes, "not JSON").unwrap();
    let named = dir.join("named.jsonl");
    let header = serde_json::json!({ "raygun_replay": 1, "display": notes.display().to_string() });
    std::fs::write(
        &named,
        format!("{header}\n{{\"t\":0.0,\"dtrack\":\"fr 1\"}}\n"),
    )
    .unwrap();
    let e = format!("{:#}", run_replay(&args(&named), Vec::new()).unwrap_err());
    assert!(
        e.contains(&format!(
            "named.jsonl: the header's field `display` names {:?}, which is not a display model",
            notes.display().to_string()
        )),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn replay_applies_a_mapping_file() {
    // With no buttons mapped, the session can only change the FOV.
    let dir = std::env::temp_dir().join(format!("raygun-mapping-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("mapping.json");
    std::fs::write(&config, r#"{"buttons":{},"stick":{"signs":[-1,-1]}}"#).unwrap();
    let file = replay_dir().join("flystick-1-centre-sweeps.osc.jsonl");
    let mut a = args(&file);
    a.config = Some(config);
    let mut out = Vec::new();
    run_replay(&a, &mut out).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(!text.is_empty());
    assert!(text.lines().all(|l| l.contains("\"kind\":\"fov\"")));
    // The first sweep pushes the stick down (towards 10°); with flipped signs the FOV grows.
    let first: serde_json::Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    assert!(first["fov_deg"][0].as_f64().unwrap() > 30.0, "{first}");
}
