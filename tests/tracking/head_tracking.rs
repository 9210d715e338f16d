//! Head tracking (DESIGN.md §11): a tracked body moves the wall camera's eye. Recordings
//! carry the head (its poses in the datagrams, its name and eye offset in the header), replays
//! replay it, and `render --guide REPLAY` moves the eye deterministically under the restart
//! rule — the iterations and eyes of its restarts are a golden file.
//!
//! `RAYGUN_BLESS=1 cargo test --test tracking head_tracking::` rewrites the golden file.

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use glam::DVec3;
use raygun::display::DisplayModel;
use raygun::filter::FilterParams;
use raygun::frame::{EyeMove, GuideConfig};
use raygun::gpu::Backend;
use raygun::scene::Scene;
use raygun::session::guide::GuideSource;
use raygun::session::render::{GuidedRender, GuidedResult, Stopping, render_guided};
use raygun::session::replay::{EyeReport, ReplayOptions, ReplayPlan};
use raygun::trace::camera::RenderCamera;
use raygun::trace::path::TraceSettings;
use raygun::trace::wall::{WallCamera, WorldFromRoom};
use raygun::tracking::event::{DeviceId, DeviceKind};
use raygun::tracking::replay::{ReplayPayload, ReplayReader};

use crate::support;
use support::{ROOT, command, ok, raygun, s, stderr, stdout, tmp_dir};

const HEAD_DTRACK: &str = "tracking-replays/head-1-walk.dtrack.jsonl";
const HEAD_OSC: &str = "tracking-replays/head-1-walk.osc.jsonl";
const SIZE: [u32; 2] = [62, 25];
const ITERATIONS: u32 = 40;

fn bless() -> bool {
    std::env::var_os("RAYGUN_BLESS").is_some()
}

fn path(rel: &str) -> PathBuf {
    Path::new(ROOT).join(rel)
}

/// The guided render of a head replay through the wall camera (CPU twin), from the head's
/// first eye with `auto` placement.
fn render(replay: &str) -> (GuidedResult, GuideSource) {
    render_with(replay, EyeMove::Restart)
}

fn render_with(replay: &str, on_eye_move: EyeMove) -> (GuidedResult, GuideSource) {
    let file = path(replay);
    let (plan, _) = ReplayPlan::new(&ReplayOptions::of(file.clone())).unwrap();
    assert!(plan.head.is_some(), "{replay} names its head");
    let source = GuideSource::from_replay(&plan, &file).unwrap();
    let scene = Scene::builtin("cornell").unwrap();
    let camera = RenderCamera::choose(&scene, None, SIZE[0], SIZE[1]).unwrap();
    let settings = TraceSettings {
        width: SIZE[0],
        height: SIZE[1],
        seed: 1,
        max_depth: 2,
        camera,
    };
    let eye = source.first_eye().unwrap();
    let c = &camera;
    let wall = WallCamera::new(
        &plan.surface,
        SIZE,
        eye,
        &WorldFromRoom::Auto,
        (c.position.as_dvec3(), c.forward.as_dvec3(), c.up.as_dvec3()),
    )
    .unwrap();
    let r = render_guided(
        &Backend::Cpu,
        &scene,
        GuidedRender {
            settings,
            model: &plan.surface,
            wall: Some(wall),
            config: GuideConfig {
                p_min: 0.05,
                ..GuideConfig::default()
            },
            filter: FilterParams::default(),
            denoise: None,
            keep_sums: false,
            on_eye_move,
        },
        &source,
        &Stopping {
            iterations: Some(ITERATIONS),
            until: Vec::new(),
        },
        |_, _| {},
    )
    .unwrap();
    (r, source)
}

/// The restarts as golden lines: `{"iteration":k,"eye_room_m":[…]}` (eyes rounded to 0.1 mm).
fn restart_lines(r: &GuidedResult) -> String {
    r.eye_restarts
        .iter()
        .map(|&(k, eye)| {
            let e = EyeReport::new(0.0, eye).eye_room_m;
            format!("{}\n", serde_json::json!({"iteration": k, "eye_room_m": e}))
        })
        .collect()
}

#[test]
fn render_guide_moves_the_eye_deterministically_and_keeps_the_roi() {
    let (a, source) = render(HEAD_DTRACK);
    let golden = path("tracking-replays/golden/head-1-walk.dtrack.render-eyes.jsonl");
    let got = restart_lines(&a);
    if bless() {
        std::fs::write(&golden, &got).unwrap();
    }
    let want = std::fs::read_to_string(&golden)
        .unwrap_or_else(|e| panic!("{}: {e} (RAYGUN_BLESS=1 writes it)", golden.display()));
    assert_eq!(
        got,
        want,
        "the eye restarts differ from {}",
        golden.display()
    );
    // The head walks right, in, left and back: several restarts, none while standing (its
    // 2 mm sway stays below the 1 cm threshold) — the first eye starts the render.
    assert!(a.eye_restarts.len() >= 5, "{}", got);
    assert!(a.eye_restarts.iter().all(|&(k, _)| k > 0), "{got}");
    assert_eq!(a.eyes_refused, 0);
    // The picture holds the iterations since the last restart.
    let last = a.eye_restarts.last().unwrap().0;
    assert_eq!(a.accumulated, ITERATIONS - last);
    assert!(a.counts.iter().all(|&c| c <= a.accumulated));
    // Deterministic: a second run is the same bit for bit.
    let (b, _) = render(HEAD_DTRACK);
    assert_eq!(a.eye_restarts, b.eye_restarts);
    assert_eq!(a.counts, b.counts);
    assert!(a.image == b.image);
    // The OSC form of the session (head `osc:1`) restarts at the same iterations.
    let (o, _) = render(HEAD_OSC);
    let its = |r: &GuidedResult| r.eye_restarts.iter().map(|x| x.0).collect::<Vec<_>>();
    assert_eq!(its(&a), its(&o));
    for (x, y) in a.eye_restarts.iter().zip(&o.eye_restarts) {
        assert!(x.1.distance(y.1) < 1e-3, "{} vs {}", x.1, y.1);
    }
    // The ROI survives the restarts: the last DGI is the one of the replay's last ROI.
    let last_roi = source.roi_at(ITERATIONS - 1, ITERATIONS);
    assert!(last_roi.is_some());
    assert!(a.dgi.contains(&0.0), "the last ROI is in the DGI");
}

/// The same walk with reuse: the eye moves at the same iterations, each move carries most of
/// the picture (the walk's 1–2 cm steps), the iterations go on, and more samples are in the
/// picture at the end than after the last restart.
#[test]
fn render_guide_with_reuse_carries_the_picture_through_the_walk() {
    let (a, _) = render(HEAD_DTRACK);
    let (b, _) = render_with(HEAD_DTRACK, EyeMove::Reuse);
    assert!(b.eye_restarts.is_empty());
    let its = b.eye_reuses.iter().map(|x| x.0).collect::<Vec<_>>();
    assert_eq!(its, a.eye_restarts.iter().map(|x| x.0).collect::<Vec<_>>());
    let mean = b.eye_reuses.iter().map(|x| x.2.share()).sum::<f64>() / its.len() as f64;
    assert!(mean > 0.5, "{:?}", b.eye_reuses);
    assert_eq!(b.accumulated, ITERATIONS);
    let total = |r: &GuidedResult| r.counts.iter().map(|&c| u64::from(c)).sum::<u64>();
    assert!(total(&b) > total(&a), "{} vs {}", total(&b), total(&a));
}

#[test]
fn render_with_a_head_replay_needs_no_eye_and_says_how_often_it_moved() {
    let dir = tmp_dir("head-render");
    let out = dir.join("head.exr");
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--camera",
        "wall",
        "--size",
        "62,25",
        "--max-depth",
        "1",
        "--backend",
        "cpu",
        "--guide",
        s(&path(HEAD_DTRACK)),
        "--iterations",
        "20",
        "--out",
        s(&out),
    ]);
    ok(&o);
    let err = stderr(&o);
    assert!(err.contains("the tracked head moved the eye"), "{err}");
    assert!(err.contains("carried the accumulation of"), "{err}");
    assert!(out.exists());
    // A threshold past every step of the walk: no restart.
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--camera",
        "wall",
        "--size",
        "62,25",
        "--max-depth",
        "1",
        "--backend",
        "cpu",
        "--guide",
        s(&path(HEAD_DTRACK)),
        "--eye-threshold",
        "5",
        "--iterations",
        "20",
        "--out",
        s(&out),
    ]);
    ok(&o);
    assert!(!stderr(&o).contains("moved the eye"), "{}", stderr(&o));
    // Bad head flags name themselves.
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--camera",
        "wall",
        "--guide",
        s(&path(HEAD_DTRACK)),
        "--iterations",
        "2",
        "--eye-threshold",
        "-1",
        "--out",
        s(&out),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--eye-threshold"), "{}", stderr(&o));
}

/// `raygun replay` prints the eyes that restart the accumulation; a replay recorded before
/// heads existed gets one from `--head` (flystick-5's head body 3 never moves: one eye).
#[test]
fn replay_prints_eye_restarts_and_old_replays_take_a_head_from_the_command_line() {
    let o = raygun(&["replay", s(&path(HEAD_DTRACK))]);
    ok(&o);
    let eyes = stdout(&o)
        .lines()
        .filter(|l| l.contains("\"kind\":\"eye\""))
        .count();
    assert!(eyes > 20, "{eyes}");
    let old = path("tracking-replays/flystick-5-plus-extra-devices.dtrack.jsonl");
    let o = raygun(&["replay", s(&old)]);
    ok(&o);
    assert!(!stdout(&o).contains("\"kind\":\"eye\""));
    let o = raygun(&["replay", s(&old), "--head", "body:3"]);
    ok(&o);
    let text = stdout(&o);
    let lines: Vec<&str> = text
        .lines()
        .filter(|l| l.contains("\"kind\":\"eye\""))
        .collect();
    assert_eq!(
        lines,
        ["{\"t\":0.0,\"kind\":\"eye\",\"eye_room_m\":[0.0,0.05,1.0]}"]
    );
    let o = raygun(&["replay", s(&old), "--head", "mouse:0"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--head"), "{}", stderr(&o));
    // An eye offset for a live recording needs the head it sits on.
    let dir = tmp_dir("head-flags");
    let o = raygun(&[
        "record",
        "--dtrack",
        "0",
        "--out",
        s(&dir.join("x.jsonl")),
        "--eye-offset",
        "0,0,0.1",
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--head"), "{}", stderr(&o));
}

/// The synthetic sessions' tracker frame as a calibration file (tests/lab.rs has the same).
const SESSION_CALIBRATION: &str = r#"{
  "raygun_calibration": 1,
  "rotation_rows": [[1, 0, 0], [0, 0, 1], [0, -1, 0]],
  "translation_m": [0.0, -1.45, 0.0]
}"#;

fn listening_port(child: &mut Child) -> (u16, BufReader<std::process::ChildStderr>) {
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut line = String::new();
    while Instant::now() < deadline {
        line.clear();
        if err.read_line(&mut line).unwrap() == 0 {
            break;
        }
        if let Some(rest) = line.split("listening on 127.0.0.1:").nth(1) {
            let port: String = rest.chars().take_while(char::is_ascii_digit).collect();
            return (port.parse().unwrap(), err);
        }
    }
    panic!("no 'listening on' line; last: {line}");
}

/// `raygun record --head`: the live session's head goes into the header, its poses into the
/// datagrams, and the recording replays to the shipped session's eye restarts with no flag.
#[test]
fn a_recording_carries_the_head_and_replays_its_eyes() {
    let dir = tmp_dir("head-record");
    let cal = dir.join("lab.json");
    std::fs::write(&cal, SESSION_CALIBRATION).unwrap();
    let mut grams = Vec::new();
    let mut r = ReplayReader::open(&path(HEAD_DTRACK)).unwrap();
    while let Some(item) = r.next_item() {
        if let ReplayPayload::Datagram(_, b) = item.payload {
            grams.push(b);
        }
    }
    let out = dir.join("rec.jsonl");
    let mut child = command(
        Path::new(ROOT),
        &[
            "record",
            "--dtrack",
            "0",
            "--out",
            s(&out),
            "--display",
            "hornet",
            "--calibration",
            s(&cal),
            "--head",
            "body:3",
            "--eye-offset",
            "0,-0.08,-0.06",
        ],
    )
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    let (port, _err) = listening_port(&mut child);
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    for g in &grams {
        sock.send_to(g, ("127.0.0.1", port)).unwrap();
        std::thread::sleep(Duration::from_micros(300));
    }
    std::thread::sleep(Duration::from_millis(500));
    let st = std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    assert!(child.wait().unwrap().success());
    let header = ReplayReader::open(&out).unwrap().header().clone();
    let head = header.head.expect("the head is in the header");
    assert_eq!(head.device, DeviceId::new(DeviceKind::Body, 3));
    assert_eq!(head.eye_offset_m, [0.0, -0.08, -0.06]);
    let eyes = |o: &std::process::Output| -> Vec<String> {
        stdout(o)
            .lines()
            .filter(|l| l.contains("\"kind\":\"eye\""))
            .map(|l| {
                // Receive times differ from the tracker's: compare the eyes.
                let v: serde_json::Value = serde_json::from_str(l).unwrap();
                v["eye_room_m"].to_string()
            })
            .collect()
    };
    let o = raygun(&["replay", s(&out)]);
    ok(&o);
    let shipped = raygun(&["replay", s(&path(HEAD_DTRACK))]);
    ok(&shipped);
    let (got, want) = (eyes(&o), eyes(&shipped));
    assert!(!want.is_empty());
    assert_eq!(got, want);
}

/// A model for the unit-free checks below.
fn hornet() -> DisplayModel {
    DisplayModel::open("hornet").unwrap().0
}

#[test]
fn the_head_sessions_eyes_stay_in_front_of_the_wall() {
    let model = hornet();
    let file = path(HEAD_DTRACK);
    let (plan, _) = ReplayPlan::new(&ReplayOptions::of(file.clone())).unwrap();
    let source = GuideSource::from_replay(&plan, &file).unwrap();
    let GuideSource::Replay { eyes, .. } = &source else {
        panic!("a replay guide")
    };
    assert!(eyes.len() > 1000);
    let any = (DVec3::ZERO, DVec3::NEG_Z, DVec3::Y);
    for (_, e) in eyes {
        WallCamera::new(&model, [8, 4], *e, &WorldFromRoom::Identity, any).unwrap();
    }
}
