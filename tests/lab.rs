//! Ready for a real lab: the calibration of live tracking and of recordings, outputs that are
//! never lost or misplaced, sizes that cannot fit, and errors a person can act on. Each test
//! drives the `raygun` binary the way a lab engineer would.

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use raygun::display::DisplayModel;
use raygun::tracking::calibration::Calibration;
use raygun::tracking::replay::{ReplayPayload, ReplayReader};

#[path = "support/cli.rs"]
mod support;
use support::{ROOT, command, fails_with, ok, raygun, raygun_in, s, stderr, stdout, tmp_dir};

const CENTRE_SWEEPS: &str = "tracking-replays/flystick-1-centre-sweeps.dtrack.jsonl";

/// The synthetic sessions' tracker frame (`synth::session_tracker_to_room`) as a calibration
/// file: DTrack's factory Z-up frame, 1.45 m below the room origin, millimetres.
const SESSION_CALIBRATION: &str = r#"{
  "raygun_calibration": 1,
  "rotation_rows": [[1, 0, 0], [0, 0, 1], [0, -1, 0]],
  "translation_m": [0.0, -1.45, 0.0]
}"#;

/// A copy of a shipped DTrack replay whose header has lost its tracker→room transform: what a
/// recording made without calibration looks like.
fn uncalibrated_copy(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(Path::new(ROOT).join(CENTRE_SWEEPS)).unwrap();
    let (head, rest) = text.split_once('\n').unwrap();
    let mut header: serde_json::Value = serde_json::from_str(head).unwrap();
    header.as_object_mut().unwrap().remove("dtrack");
    let out = dir.join("uncalibrated.dtrack.jsonl");
    std::fs::write(&out, format!("{header}\n{rest}")).unwrap();
    out
}

fn golden(replay: &str) -> String {
    let p = raygun::session::replay::golden_path(&Path::new(ROOT).join(replay));
    std::fs::read_to_string(p).unwrap()
}

#[test]
fn a_calibration_file_makes_an_uncalibrated_recording_replay_exactly() {
    let dir = tmp_dir("calibrated-replay");
    let replay = uncalibrated_copy(&dir);
    let cal = dir.join("lab.json");
    std::fs::write(&cal, SESSION_CALIBRATION).unwrap();
    // Without it every shot leaves the wrong place (or misses).
    let o = raygun(&["replay", s(&replay), "--display", "hornet"]);
    ok(&o);
    assert_ne!(stdout(&o), golden(CENTRE_SWEEPS));
    // With it: the ROI changes of the calibrated original, exactly.
    let o = raygun(&[
        "replay",
        s(&replay),
        "--calibration",
        s(&cal),
        "--display",
        "hornet",
    ]);
    ok(&o);
    assert_eq!(stdout(&o), golden(CENTRE_SWEEPS));
    // The same calibration named by the interaction mapping, relative to the mapping's folder.
    std::fs::write(dir.join("mapping.json"), r#"{"calibration": "lab.json"}"#).unwrap();
    let o = raygun_in(
        Path::new("/"),
        &[
            "replay",
            s(&replay),
            "--config",
            s(&dir.join("mapping.json")),
            "--display",
            "hornet",
        ],
    );
    ok(&o);
    assert_eq!(stdout(&o), golden(CENTRE_SWEEPS));
    // And `render --guide` takes it too: the DGI of its last ROI is the original's.
    let dgi_of = |replay: &Path, extra: &[&str], name: &str| {
        let out = dir.join(format!("{name}.exr"));
        let mut args = vec![
            "render",
            "--scene",
            "builtin:cornell",
            "--size",
            "40,16",
            "--backend",
            "cpu",
            "--guide",
            s(replay),
            "--iterations",
            "3",
            "--out",
            s(&out),
        ];
        args.extend_from_slice(extra);
        ok(&raygun(&args));
        std::fs::read(dir.join(format!("{name}.dgi.exr"))).unwrap()
    };
    let original = dgi_of(&Path::new(ROOT).join(CENTRE_SWEEPS), &[], "original");
    let calibrated = dgi_of(&replay, &["--calibration", s(&cal)], "calibrated");
    assert_eq!(original, calibrated);
}

/// Waits for `raygun …` to say "listening on 127.0.0.1:PORT" on standard error; returns the
/// port and a reader for the rest of its standard error.
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

/// The DTrack datagrams of the uncalibrated centre-sweeps copy.
fn datagrams(replay: &Path) -> Vec<Vec<u8>> {
    let mut r = ReplayReader::open(replay).unwrap();
    let mut v = Vec::new();
    while let Some(item) = r.next_item() {
        if let ReplayPayload::Datagram(_, b) = item.payload {
            v.push(b);
        }
    }
    v
}

fn signal(child: &Child, sig: &str) {
    let st = std::process::Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
}

fn records(path: &Path) -> (raygun::tracking::replay::ReplayHeader, usize, u64) {
    let mut r = ReplayReader::open(path).unwrap();
    let header = r.header().clone();
    let mut n = 0;
    while r.next_item().is_some() {
        n += 1;
    }
    (header, n, r.problems.total())
}

#[test]
fn record_stores_display_and_calibration_and_sigterm_and_sighup_end_it_cleanly() {
    let dir = tmp_dir("record-signals");
    let cal = dir.join("lab.json");
    std::fs::write(&cal, SESSION_CALIBRATION).unwrap();
    let grams = datagrams(&uncalibrated_copy(&dir));
    for sig in ["-TERM", "-HUP"] {
        let out = dir.join(format!("rec{sig}.jsonl"));
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
            ],
        )
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
        let (port, _err) = listening_port(&mut child);
        let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
        for g in &grams[..300] {
            sock.send_to(g, ("127.0.0.1", port)).unwrap();
            std::thread::sleep(Duration::from_micros(300));
        }
        // Give the recorder a moment to take the last datagrams off the socket.
        std::thread::sleep(Duration::from_millis(500));
        signal(&child, sig);
        let status = child.wait().unwrap();
        assert!(status.success(), "{sig}: {status:?}");
        let (header, n, problems) = records(&out);
        assert_eq!((n, problems), (300, 0), "{sig}");
        assert_eq!(header.display.as_deref(), Some("hornet"));
        assert_eq!(
            header.display_model.as_ref().map(|m| m.tiles().len()),
            Some(35)
        );
        let stored = header.calibration.expect("the calibration is stored");
        assert_eq!(
            stored,
            Calibration::from_json(SESSION_CALIBRATION, &cal).unwrap()
        );
        // The recording replays by itself: no --display, no --calibration.
        let o = raygun(&["replay", s(&out)]);
        ok(&o);
        assert!(stdout(&o).contains("\"kind\":\"shoot\""), "{}", stdout(&o));
    }
}

#[test]
fn a_killed_recorder_keeps_all_but_the_last_moments() {
    let dir = tmp_dir("record-kill");
    let grams = datagrams(&uncalibrated_copy(&dir));
    let out = dir.join("killed.jsonl");
    let mut child = command(
        Path::new(ROOT),
        &["record", "--dtrack", "0", "--out", s(&out)],
    )
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    let (port, _err) = listening_port(&mut child);
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    // A steady 200 Hz stream for 2 s, then kill -9 in the middle of it.
    let start = Instant::now();
    let mut sent: Vec<Duration> = Vec::new();
    for g in grams.iter().cycle().take(400) {
        sock.send_to(g, ("127.0.0.1", port)).unwrap();
        sent.push(start.elapsed());
        std::thread::sleep(Duration::from_millis(5));
    }
    let killed_at = start.elapsed();
    signal(&child, "-KILL");
    let _ = child.wait();
    let (_, n, problems) = records(&out);
    // Lost: at most what was sent in the last second before the kill (the recorder writes at
    // least every 0.25 s; the rest is slack for a loaded machine), and at most one partial line.
    let recent = sent
        .iter()
        .filter(|t| killed_at.saturating_sub(**t) < Duration::from_secs(1))
        .count();
    assert!(
        n + recent >= sent.len(),
        "{n} of {} kept, {recent} recent",
        sent.len()
    );
    assert!(problems <= 1, "{problems}");
}

#[test]
fn record_says_where_it_listens_and_names_the_flag_for_the_network() {
    let dir = tmp_dir("record-bind");
    let o = raygun(&[
        "record",
        "--dtrack",
        "0",
        "--bind",
        "0.0.0.0",
        "--out",
        s(&dir.join("x.jsonl")),
    ]);
    fails_with(&o, &["0.0.0.0", "--allow-network"]);
    // A VRPN server on another machine names the same flag (refused before any connection).
    let o = raygun(&[
        "record",
        "--vrpn",
        "Tracker0@192.0.2.1",
        "--out",
        s(&dir.join("v.jsonl")),
    ]);
    fails_with(&o, &["192.0.2.1", "--allow-network"]);
    // A recording folder that does not exist fails before anything binds.
    let o = raygun(&["record", "--dtrack", "0", "--out", "/nonexistent/x.jsonl"]);
    fails_with(&o, &["/nonexistent"]);
}

/// A DTrack session in a rotated and shifted tracker frame: the FlyStick held still at each of
/// `points` (room metres) for 0.2 s, with the trigger pressed in the middle of each hold.
fn held_points_session(
    points: &[glam::DVec3],
    to_room: &raygun::tracking::dtrack::TrackerToRoom,
) -> Vec<u8> {
    use raygun::tracking::dtrack::format_flystick_block;
    use raygun::tracking::ingest::Protocol;
    use raygun::tracking::replay::{ReplayHeader, ReplayWriter};
    let mut w = ReplayWriter::new(Vec::new(), &ReplayHeader::new("held points")).unwrap();
    let r = to_room.rotation().transpose();
    let mut t = 0.0;
    let mut frame = 0;
    for (k, p) in points.iter().enumerate() {
        // ±0.2 mm of hand tremor, deterministic.
        let wobble = glam::DVec3::new(0.2, -0.1, 0.15) * if k % 2 == 0 { 1.0 } else { -1.0 };
        let tracker = r * (*p - glam::DVec3::from_array(to_room.translation_m))
            / to_room.metres_per_unit
            + wobble;
        for step in 0..12 {
            let buttons = u32::from((4..8).contains(&step));
            let text = format!(
                "fr {frame}\nts {:.6}\n6df2 1 1 {}\n",
                10.0 + t,
                format_flystick_block(0, Some((tracker, r)), 6, buttons, &[0.0, 0.0])
            );
            w.datagram(t, Protocol::Dtrack, text.as_bytes()).unwrap();
            t += 1.0 / 60.0;
            frame += 1;
        }
    }
    w.into_inner()
}

#[test]
fn calibrate_solves_the_tracker_frame_from_presses_at_wall_points_and_states_the_residual() {
    use raygun::tracking::dtrack::TrackerToRoom;
    let dir = tmp_dir("calibrate");
    let model = DisplayModel::open("hornet").unwrap().0;
    let targets = [
        "c0r0:top-left",
        "c6r0:top-right",
        "c3r4:bottom-left",
        "c3r2:centre",
    ];
    let points: Vec<glam::DVec3> = targets
        .iter()
        .map(|t| {
            raygun::cli::calibrate::parse_target(t, &model)
                .unwrap()
                .room
        })
        .collect();
    let r = glam::DMat3::from_rotation_y(25f64.to_radians()) * TrackerToRoom::z_up().rotation();
    let truth = TrackerToRoom {
        rotation_rows: r.transpose().to_cols_array_2d(),
        translation_m: [0.3, -1.2, 2.1],
        metres_per_unit: 1e-3,
    };
    let session = dir.join("presses.jsonl");
    std::fs::write(&session, held_points_session(&points, &truth)).unwrap();
    let cal = dir.join("lab.json");
    let mut args = vec!["calibrate", "--replay", s(&session), "--out", s(&cal)];
    for t in &targets {
        args.extend(["--target", t]);
    }
    let o = raygun(&args);
    ok(&o);
    let e = stderr(&o);
    assert!(e.contains("residual RMS"), "{e}");
    // A recording's presses are already there: no prompts to hold the device anywhere.
    assert!(
        !e.contains("hold ")
            && e.contains("target 1 (top-left of tile c0r0): press 1 of the recording"),
        "{e}"
    );
    let c = Calibration::load(&cal).unwrap();
    let got = c.tracker_to_room(1e-3);
    let diff = (got.rotation() - truth.rotation())
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(diff < 1e-3, "rotation off by {diff}");
    let dt =
        glam::DVec3::from_array(got.translation_m) - glam::DVec3::from_array(truth.translation_m);
    assert!(dt.length() < 1e-3, "translation off by {dt}");
    let report = c.solved.expect("the residual is stored");
    assert!(report.rms_mm < 1.0 && report.points == 4, "{report:?}");
    // Live, over UDP: the same presses, the same answer.
    let live = dir.join("live.json");
    let mut args = vec![
        "calibrate",
        "--dtrack",
        "0",
        "--out",
        s(&live),
        "--seconds",
        "60",
    ];
    for t in &targets {
        args.extend(["--target", t]);
    }
    let mut child = command(Path::new(ROOT), &args)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (port, mut err) = listening_port(&mut child);
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    for g in datagrams(&session) {
        sock.send_to(&g, ("127.0.0.1", port)).unwrap();
        std::thread::sleep(Duration::from_millis(2));
    }
    let status = child.wait().unwrap();
    let mut rest = String::new();
    let _ = std::io::Read::read_to_string(&mut err, &mut rest);
    assert!(status.success(), "{rest}");
    assert_eq!(
        Calibration::load(&live).unwrap().rotation_rows,
        c.rotation_rows
    );
}

#[test]
fn calibrate_refuses_points_on_a_line_and_too_few_targets() {
    let dir = tmp_dir("calibrate-bad");
    let model = DisplayModel::open("hornet").unwrap().0;
    let line = ["c0r2:centre", "c1r2:centre", "c2r2:centre"];
    let points: Vec<glam::DVec3> = line
        .iter()
        .map(|t| {
            raygun::cli::calibrate::parse_target(t, &model)
                .unwrap()
                .room
        })
        .collect();
    // On a curved wall three tile centres of one row are not collinear; use room points on a
    // line instead.
    let _ = points;
    let session = dir.join("presses.jsonl");
    let on_line = [
        glam::DVec3::new(-1.0, 0.0, 0.0),
        glam::DVec3::new(0.0, 0.0, 0.0),
        glam::DVec3::new(1.0, 0.0, 0.0),
    ];
    std::fs::write(
        &session,
        held_points_session(
            &on_line,
            &raygun::tracking::dtrack::TrackerToRoom::default(),
        ),
    )
    .unwrap();
    let out = dir.join("x.json");
    let o = raygun(&[
        "calibrate",
        "--replay",
        s(&session),
        "--out",
        s(&out),
        "--target",
        "-1,0,0",
        "--target",
        "0,0,0",
        "--target",
        "1,0,0",
    ]);
    fails_with(&o, &["one line"]);
    assert!(!out.exists());
    let o = raygun(&[
        "calibrate",
        "--replay",
        s(&session),
        "--out",
        s(&out),
        "--target",
        "c0r0:top-left",
        "--target",
        "c0r0:centre",
    ]);
    fails_with(&o, &["at least 3"]);
    let o = raygun(&[
        "calibrate",
        "--replay",
        s(&session),
        "--out",
        s(&out),
        "--target",
        "c9r9:centre",
        "--target",
        "0,0,0",
        "--target",
        "1,0,0",
    ]);
    fails_with(&o, &["c9r9"]);
}

#[test]
fn huge_sizes_are_refused_with_the_bytes_and_never_abort() {
    let dir = tmp_dir("huge");
    let out = dir.join("r.png");
    for args in [
        vec![
            "render",
            "--scene",
            "builtin:cornell",
            "--size",
            "100000,100000",
            "--out",
            s(&out),
        ],
        vec![
            "render",
            "--scene",
            "builtin:cornell",
            "--size",
            "60000,60000",
            "--guide",
            "mouse:10,10:5,5",
            "--iterations",
            "1",
            "--out",
            s(&out),
            "--backend",
            "cpu",
        ],
        vec![
            "dgi",
            "--size",
            "100000,100000",
            "--origin",
            "0,0,1",
            "--dir",
            "0,0,-1",
            "--fov",
            "30,30",
            "--out",
            s(&dir.join("d.exr")),
        ],
        vec![
            "dgi",
            "--size",
            "60000,60000",
            "--origin",
            "0,0,1",
            "--dir",
            "0,0,-1",
            "--fov",
            "30,30",
            "--out",
            s(&dir.join("d.exr")),
            "--backend",
            "cpu",
        ],
    ] {
        let o = raygun(&args);
        let e = fails_with(&o, &["--size"]);
        assert!(e.contains("pixels") || e.contains("GB"), "{e}");
    }
    // The viewer checks before it opens a window.
    let o = command(
        Path::new(ROOT),
        &["view", "--size", "60000,60000", "--backend", "cpu"],
    )
    .env("DISPLAY", ":99")
    .output()
    .unwrap();
    fails_with(&o, &["--size 60000,60000", "GB"]);
    assert!(!out.exists());
}

fn model_json(id: &str) -> String {
    format!(
        r#"{{"name":"one","tiles":[{{"id":{},"column":0,"row":0,"resolution":[100,50],
        "top_left":[0,0.5,0],"top_right":[1,0.5,0],"bottom_left":[0,0,0],
        "bezel":{{"left":0,"right":0,"top":0,"bottom":0}},"canvas":[0,0]}}]}}"#,
        serde_json::to_string(id).unwrap()
    )
}

#[test]
fn tile_ids_that_are_not_plain_file_names_are_refused_and_nothing_leaves_the_folder() {
    for bad in [
        "../../EVIL",
        "a/b",
        "a\\b",
        "..",
        ".hidden",
        "/etc/passwd",
        "tab\there",
        "CON",
        "nul.txt",
        "a:b",
        "trailing.",
        " lead",
        &"x".repeat(65),
    ] {
        let e = DisplayModel::from_json(&model_json(bad), "bad.json").unwrap_err();
        let text = e.to_string();
        assert!(text.starts_with("bad.json: tile "), "{bad:?}: {text}");
        assert!(text.contains("field `id`"), "{bad:?}: {text}");
    }
    DisplayModel::from_json(&model_json("c0r0"), "good.json").unwrap();
    DisplayModel::from_json(&model_json("left-wall_2.top"), "good.json").unwrap();
    // Through the command: an error naming file, tile and field, and no file anywhere.
    let dir = tmp_dir("evil-tiles");
    let model = dir.join("evil.json");
    std::fs::write(&model, model_json("../../EVIL")).unwrap();
    let tiles = dir.join("a/b/tiles");
    std::fs::create_dir_all(dir.join("a/b")).unwrap();
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--size",
        "8,4",
        "--spp",
        "1",
        "--out",
        s(&dir.join("o.png")),
        "--tiles",
        s(&tiles),
        "--display",
        s(&model),
    ]);
    fails_with(&o, &["evil.json", "EVIL", "id"]);
    assert!(!dir.join("a/EVIL.png").exists() && !dir.join("EVIL.png").exists());
}

#[test]
fn tiles_that_overlap_in_the_room_are_refused() {
    let folded = r#"{"name":"folded","generator":{"columns":7,"rows":1,"resolution":[1920,1080],
        "active_size":[1.0181,0.5727],"bezel":{"left":0.003,"right":0.003,"top":0.003,"bottom":0.003},
        "yaw_step_deg":90.0,"center":[0,0,0],"normal":[0,0,1],"up":[0,1,0]}}"#;
    let e = DisplayModel::from_json(folded, "folded.json").unwrap_err();
    assert!(e.to_string().contains("generator.yaw_step_deg"), "{e}");
    assert!(e.to_string().contains("overlaps"), "{e}");
    // 45° with 7 columns curves but never folds back onto itself: accepted.
    DisplayModel::from_json(&folded.replace("90.0", "45.0"), "curved.json").unwrap();
    let tile = |id: &str, x: f64| {
        format!(
            r#"{{"id":"{id}","column":{},"row":0,"resolution":[100,50],"top_left":[0,0.5,0],
            "top_right":[1,0.5,0],"bottom_left":[0,0,0],
            "bezel":{{"left":0,"right":0,"top":0,"bottom":0}},"canvas":[{x},0]}}"#,
            x as u32 / 100
        )
    };
    let twins = format!(
        r#"{{"name":"twins","tiles":[{},{}]}}"#,
        tile("a", 0.0),
        tile("b", 200.0)
    );
    let e = DisplayModel::from_json(&twins, "twins.json").unwrap_err();
    assert!(
        e.to_string().contains("tile \"b\"") && e.to_string().contains("\"a\""),
        "{e}"
    );
    // Every shipped model is untouched by the check.
    for m in ["hornet", "desktop-27in-4k", "projection-4m-4k"] {
        DisplayModel::open(m).unwrap();
    }
}

#[test]
fn outputs_are_checked_before_any_work() {
    let dir = tmp_dir("outputs-first");
    // A render that would take hours fails at once on its output folder.
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:city",
        "--size",
        "1920,1080",
        "--spp",
        "100000",
        "--out",
        "/nonexistent/r.png",
        "--backend",
        "cpu",
    ]);
    fails_with(&o, &["/nonexistent"]);
    // A bad --dgi-out extension fails before the image is written.
    let out = dir.join("g.png");
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--size",
        "16,8",
        "--guide",
        "mouse:8,4:3,3",
        "--iterations",
        "2",
        "--out",
        s(&out),
        "--dgi-out",
        s(&dir.join("d.tif")),
    ]);
    fails_with(&o, &["d.tif", "extension"]);
    assert!(!out.exists());
    for args in [
        vec![
            "dgi",
            "--origin",
            "0,0,1",
            "--dir",
            "0,0,-1",
            "--fov",
            "30,30",
            "--out",
            "/nonexistent/d.exr",
        ],
        vec!["scene", "cornell", "--out", "/nonexistent/c.glb"],
        vec![
            "bench",
            "dgi",
            "--size",
            "8,4",
            "--out",
            "/nonexistent/b.md",
        ],
        vec!["demo", "--headless", "--out", "/proc/version/demo"],
    ] {
        fails_with(&raygun(&args), &[]);
    }
    // `scene --out x.png` would write a GLB named .png.
    fails_with(
        &raygun(&["scene", "cornell", "--out", s(&dir.join("x.png"))]),
        &[".glb"],
    );
    assert!(!dir.join("x.png").exists());
}

/// `raygun ARGS` with the file-size limit at `kb` kilobytes and SIGXFSZ ignored, so a write
/// beyond it fails as a full disk does (EFBIG).
fn with_file_limit(kb: u32, args: &[&str]) -> std::process::Command {
    let mut c = std::process::Command::new("bash");
    c.arg("-c")
        .arg(format!("ulimit -f {kb}; trap '' XFSZ; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_raygun"))
        .args(args)
        .current_dir(ROOT)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir());
    c
}

#[test]
fn a_full_disk_leaves_no_truncated_image_and_a_recording_of_whole_lines() {
    let dir = tmp_dir("full-disk");
    let out = dir.join("big.exr");
    let o = with_file_limit(
        4,
        &[
            "render",
            "--scene",
            "builtin:cornell",
            "--size",
            "256,256",
            "--spp",
            "1",
            "--out",
            s(&out),
            "--backend",
            "cpu",
        ],
    )
    .output()
    .unwrap();
    fails_with(&o, &["big.exr"]);
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
    // The recorder: the write that fails is cut back to the last whole record.
    let rec = dir.join("rec.jsonl");
    // 64 kB: the header (with the display model) fits, some 300 records more do not.
    let mut child = with_file_limit(64, &["record", "--dtrack", "0", "--out", s(&rec)])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (port, mut err) = listening_port(&mut child);
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let grams = datagrams(&uncalibrated_copy(&dir));
    for g in grams.iter().cycle().take(1200) {
        let _ = sock.send_to(g, ("127.0.0.1", port));
        std::thread::sleep(Duration::from_millis(2));
    }
    let status = child.wait().unwrap();
    let mut rest = String::new();
    let _ = std::io::Read::read_to_string(&mut err, &mut rest);
    assert_eq!(status.code(), Some(1), "{rest}");
    assert!(
        rest.contains("every record up to the failure is kept"),
        "{rest}"
    );
    let text = std::fs::read_to_string(&rec).unwrap();
    assert!(text.ends_with('\n'));
    let (_, n, problems) = records(&rec);
    assert!(n > 10, "{n}");
    assert_eq!(problems, 0);
}

/// The demo writes several files; a full disk halfway leaves none of them, nor the folders it
/// made. With files limited to 64 kB the display model (under 1 kB) is written and the replay
/// (265 kB) is not; at 300 kB the inputs fit and the 32-bit image (1.9 MB) fails after the
/// render.
#[test]
fn a_full_disk_leaves_nothing_of_the_demo() {
    let dir = tmp_dir("full-disk-demo");
    for kb in [64, 300] {
        let out = dir.join(format!("demo-{kb}"));
        let o = with_file_limit(
            kb,
            &[
                "demo",
                "--headless",
                "--size",
                "640,258",
                "--iterations",
                "2",
                "--backend",
                "cpu",
                "--quiet",
                "--out",
                s(&out),
            ],
        )
        .output()
        .unwrap();
        fails_with(&o, &[]);
        assert!(!out.exists(), "{kb} kB: {:?} is left", out);
    }
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}

/// `--quiet` prints nothing but warnings and errors; summaries name every file written and
/// count in words that agree with their numbers; messages speak the user's syntax.
#[test]
fn quiet_is_quiet_and_messages_say_what_happened() {
    let dir = tmp_dir("say");
    let out = dir.join("q.png");
    let render = |extra: &[&str], out: &Path| {
        let mut args = vec![
            "render",
            "--scene",
            "builtin:cornell",
            "--size",
            "16,9",
            "--spp",
            "1",
            "--out",
            s(out),
        ];
        args.extend_from_slice(extra);
        raygun(&args)
    };
    // Whatever the adapter (`auto` says why it takes the CPU where it does), nothing at all.
    let o = render(&["--quiet"], &out);
    ok(&o);
    assert_eq!(stderr(&o), "", "--quiet");
    let o = render(&["--backend", "cpu"], &out);
    ok(&o);
    let e = stderr(&o);
    assert!(e.contains(&format!("; wrote {}", out.display())), "{e}");
    // A guided render lists its image with its DGI and counts.
    let guided = dir.join("g.exr");
    let dgi = dir.join("g.dgi.exr");
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--size",
        "16,9",
        "--guide",
        "mouse:8,4:3,3",
        "--iterations",
        "1",
        "--backend",
        "cpu",
        "--dgi-out",
        s(&dgi),
        "--out",
        s(&guided),
    ]);
    ok(&o);
    let e = stderr(&o);
    assert!(
        e.contains(&format!("; wrote {}, {}", guided.display(), dgi.display()))
            && e.contains("(1 iteration done): 1 iteration in"),
        "{e}"
    );
    // A scene of one triangle says so in the singular.
    let tri = dir.join("one.gltf");
    let pos: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let gltf = serde_json::json!({
        "asset": { "version": "2.0" },
        "buffers": [{ "byteLength": 36, "uri": format!("data:application/octet-stream;base64,{}", base64_of(&pos)) }],
        "bufferViews": [{ "buffer": 0, "byteLength": 36 }],
        "accessors": [{ "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                        "min": [0, 0, 0], "max": [1, 1, 0] }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 } }] }],
        "nodes": [{ "mesh": 0 }],
        "scenes": [{ "nodes": [0] }]
    });
    std::fs::write(&tri, gltf.to_string()).unwrap();
    let o = raygun(&["scene", "info", s(&tri)]);
    ok(&o);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        text.contains("1 triangle (0 emissive), 1 material, 0 textures"),
        "{text}"
    );
    // A replay in which nobody pressed anything says what it read.
    let quiet = dir.join("no-press.jsonl");
    let frame = |t: f64, n: u32| {
        serde_json::json!({ "t": t, "dtrack": format!(
            "fr {n}\nts {t}\n6df2 1 1 [0 1.0 6 2][0 0 1000][1 0 0 0 1 0 0 0 1][0 0 0]"
        ) })
    };
    let header =
        serde_json::json!({ "raygun_replay": 1, "display": "hornet", "device": "flystick:0" });
    let lines: Vec<String> = std::iter::once(header.to_string())
        .chain((0..3).map(|k| frame(f64::from(k) * 0.5, k + 1).to_string()))
        .collect();
    std::fs::write(&quiet, lines.join("\n") + "\n").unwrap();
    let o = raygun(&["replay", s(&quiet)]);
    ok(&o);
    assert!(o.stdout.is_empty());
    let e = stderr(&o);
    assert!(
        e.contains("3 frames of flystick:0 over 1.0 s: no trigger was pressed"),
        "{e}"
    );
    // Display models: a negative bezel (zero is allowed), NaN, and a pitch too small for
    // six decimals.
    let model = |bezel: &str, res: &str| {
        format!(
            r#"{{"name":"m","generator":{{"columns":1,"rows":1,"resolution":{res},"active_size":[1.0,0.5625],"bezel":{{"left":{bezel},"right":0,"top":0,"bottom":0}},"yaw_step_deg":0}}}}"#
        )
    };
    for (name, text, needles) in [
        (
            "neg.json",
            model("-5", "[1920, 1080]"),
            vec!["-5 m is negative: it must be 0 or more"],
        ),
        (
            "nan.json",
            model("NaN", "[1920, 1080]"),
            vec!["NaN and Infinity are not JSON numbers"],
        ),
        (
            "fine.json",
            model("0", "[4000000000, 1080]"),
            vec!["pixel pitch differs between the axes: 2.5e-7 mm across"],
        ),
    ] {
        let f = dir.join(name);
        std::fs::write(&f, text).unwrap();
        let o = raygun(&["display", "expand", s(&f)]);
        let e = fails_with(&o, &needles);
        assert!(
            !e.contains("(or zero)") && !e.contains(": 0.000000 mm"),
            "{e}"
        );
    }
    // A negative size is a bad size, not an unknown flag.
    let o = raygun(&[
        "dgi",
        "--size",
        "-5,10",
        "--center-px",
        "1,1",
        "--axes-px",
        "1,1",
        "--out",
        "/tmp/x.png",
    ]);
    let e = stderr(&o);
    assert!(
        !o.status.success() && e.contains("--size") && e.contains("-5,10"),
        "{e}"
    );
    assert!(!e.contains("unexpected argument"), "{e}");
    // A vertical pose: the syntax has no up vector to blame.
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--guide",
        "pose:0,0,1:0,1,0:30",
        "--iterations",
        "1",
        "--out",
        s(&dir.join("p.png")),
    ]);
    let e = fails_with(&o, &["--guide pose", "points straight up or down"]);
    assert!(!e.contains("up vector"), "{e}");
    // One rule for outputs: the file or folder named is made, the folders above it are not.
    let o = render(&["--tiles", s(&dir.join("no/such/tiles"))], &out);
    fails_with(&o, &["does not exist"]);
    assert!(!dir.join("no").exists());
    let o = render(&["--quiet", "--tiles", s(&dir.join("tiles"))], &out);
    ok(&o);
    assert!(dir.join("tiles").is_dir());
    // Help shows words, not rustdoc links.
    let o = raygun(&["render", "--help"]);
    let help = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(!help.contains("[`"), "{help}");
    // A closed pipe (`raygun … | head` after head has gone) ends a printing command quietly.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = command(Path::new(ROOT), &["display", "expand", "hornet"])
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stderr(&o), "");
}

/// Standard base64 of `bytes` (the tests' data URIs).
fn base64_of(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = c
            .iter()
            .enumerate()
            .fold(0u32, |n, (i, &b)| n | u32::from(b) << (16 - 8 * i));
        for k in 0..4 {
            if k <= c.len() {
                out.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[test]
fn render_guide_takes_the_replays_display_and_says_so() {
    let dir = tmp_dir("guide-display");
    let mouse = "tracking-replays/mouse-1-desktop.events.jsonl";
    let run = |extra: &[&str], name: &str| {
        let out = dir.join(format!("{name}.exr"));
        let mut args = vec![
            "render",
            "--scene",
            "builtin:cornell",
            "--size",
            "48,27",
            "--backend",
            "cpu",
            "--guide",
            mouse,
            "--iterations",
            "3",
            "--out",
            s(&out),
        ];
        args.extend_from_slice(extra);
        let o = raygun(&args);
        ok(&o);
        (
            stderr(&o),
            std::fs::read(dir.join(format!("{name}.dgi.exr"))).unwrap(),
        )
    };
    let (said, from_header) = run(&[], "header");
    assert!(
        said.contains("desktop-27in-4k") && said.contains("header"),
        "{said}"
    );
    let (_, explicit) = run(&["--display", "desktop-27in-4k"], "explicit");
    assert_eq!(from_header, explicit);
    let (said, other) = run(&["--display", "hornet"], "hornet");
    assert!(said.contains("hornet"), "{said}");
    assert_ne!(from_header, other);
}

#[test]
fn commands_work_from_any_folder() {
    let elsewhere = tmp_dir("elsewhere");
    // A copy away from the repository: its header's "display-models/hornet.json" is not there.
    let replay = elsewhere.join("sweeps.jsonl");
    std::fs::copy(Path::new(ROOT).join(CENTRE_SWEEPS), &replay).unwrap();
    let o = raygun_in(
        &elsewhere,
        &[
            "render",
            "--scene",
            "builtin:cornell-light",
            "--size",
            "32,13",
            "--backend",
            "cpu",
            "--guide",
            s(&replay),
            "--iterations",
            "2",
            "--out",
            "x.png",
        ],
    );
    ok(&o);
    assert!(stderr(&o).contains("built-in hornet"), "{}", stderr(&o));
    assert!(elsewhere.join("x.png").exists() && elsewhere.join("x.dgi.exr").exists());
    ok(&raygun_in(
        &elsewhere,
        &[
            "dgi",
            "--origin",
            "0,0,1",
            "--dir",
            "0,0,-1",
            "--fov",
            "30,30",
            "--size",
            "32,18",
            "--out",
            "d.png",
            "--backend",
            "cpu",
        ],
    ));
    ok(&raygun_in(
        &elsewhere,
        &[
            "bench",
            "dgi",
            "--size",
            "32,18",
            "--fov",
            "10",
            "--reps",
            "1",
            "--cpu-reps",
            "1",
            "--backend",
            "cpu",
        ],
    ));
    ok(&raygun_in(&elsewhere, &["replay", s(&replay)]));
}

#[test]
fn a_run_that_would_mean_nothing_is_an_error() {
    let dir = tmp_dir("meaningless");
    let out = dir.join("m.png");
    let render = |extra: &[&str]| {
        let mut args = vec![
            "render",
            "--scene",
            "builtin:cornell",
            "--size",
            "16,8",
            "--out",
            s(&out),
        ];
        args.extend_from_slice(extra);
        raygun(&args)
    };
    fails_with(
        &render(&["--guide", "mouse:-50,-50:3,3", "--iterations", "2"]),
        &["outside"],
    );
    fails_with(
        &render(&["--guide", "mouse:8,4:0,0", "--iterations", "2"]),
        &["positive"],
    );
    fails_with(
        &render(&["--guide", "pose:0,0,1:0,0,1:30", "--iterations", "2"]),
        &["misses"],
    );
    fails_with(&render(&["--exposure", "NaN"]), &["--exposure"]);
    fails_with(
        &render(&["--guide", "mouse:8,4:3,3", "--iterations", "0"]),
        &["--iterations"],
    );
    fails_with(
        &render(&[
            "--guide",
            "mouse:8,4:3,3",
            "--iterations",
            "2",
            "--p-min",
            "-1",
        ]),
        &["--p-min", "-1"],
    );
    // A replay none of whose shots hits the wall: the stick points away from it.
    let replay = dir.join("away.jsonl");
    let mut text = String::from("{\"raygun_replay\":1,\"display\":\"hornet\"}\n");
    for k in 0..10 {
        let block = raygun::tracking::dtrack::format_flystick_block(
            0,
            Some((
                glam::DVec3::new(0.0, 0.0, 1000.0),
                glam::DMat3::from_rotation_y(std::f64::consts::PI),
            )),
            6,
            u32::from((3..6).contains(&k)),
            &[0.0, 0.0],
        );
        let line = serde_json::json!({"t": f64::from(k) / 60.0, "dtrack": format!("fr {k}\nts {}\n6df2 1 1 {block}\n", 10.0 + f64::from(k) / 60.0)});
        text.push_str(&format!("{line}\n"));
    }
    std::fs::write(&replay, text).unwrap();
    fails_with(
        &render(&["--guide", s(&replay), "--iterations", "2"]),
        &["no shot"],
    );
    // Settings that would be silently ignored are refused by the parser (exit 2).
    for args in [
        vec![
            "--spp",
            "4",
            "--guide",
            "mouse:8,4:3,3",
            "--iterations",
            "2",
        ],
        vec!["--p-min", "0.5"],
        vec!["--until", "time:1"],
        vec!["--k-max", "8"],
    ] {
        let o = render(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    }
    let o = raygun(&["bench", "guided", "--size", "8,4", "--iterations", "0"]);
    fails_with(&o, &["--iterations"]);
    assert!(!out.exists());
}

#[test]
fn stop_conditions_end_a_guided_render_and_say_why() {
    let dir = tmp_dir("until");
    let out = dir.join("u.exr");
    let base = [
        "render",
        "--scene",
        "builtin:cornell-light",
        "--size",
        "48,27",
        "--backend",
        "cpu",
        "--guide",
        "mouse:24,13:6,6",
        "--out",
        s(&out),
    ];
    let run = |extra: &[&str]| {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        raygun(&args)
    };
    let o = run(&["--until", "roi-spp:6"]);
    ok(&o);
    assert!(stderr(&o).contains("roi-spp:6 reached"), "{}", stderr(&o));
    let gray = |p: PathBuf| -> Vec<f32> {
        let img = exr::prelude::read_first_flat_layer_from_file(p).unwrap();
        img.layer_data.channel_data.list[0]
            .sample_data
            .values_as_f32()
            .collect()
    };
    let dgi = gray(dir.join("u.dgi.exr"));
    let counts = gray(dir.join("u.counts.exr"));
    let roi: Vec<f32> = dgi
        .iter()
        .zip(&counts)
        .filter(|(d, _)| **d == 0.0)
        .map(|(_, c)| *c)
        .collect();
    assert!(!roi.is_empty());
    assert!(roi.iter().all(|c| *c >= 6.0), "{roi:?}");
    let o = run(&["--until", "roi-se:0.05", "--iterations", "100000"]);
    ok(&o);
    let e = stderr(&o);
    assert!(e.contains("roi-se:0.05 reached"), "{e}");
    let se: f64 = e
        .rsplit("median SE ")
        .next()
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(se <= 0.05, "{e}");
    let o = run(&["--until", "time:1", "--until", "roi-spp:1000000"]);
    ok(&o);
    assert!(stderr(&o).contains("time:1 reached"), "{}", stderr(&o));
    // --iterations stays: it ends the render when no condition is reached first.
    let o = run(&["--until", "roi-spp:1000000", "--iterations", "3"]);
    ok(&o);
    assert!(stderr(&o).contains("3 iterations done"), "{}", stderr(&o));
    // A replay is spread over the iterations: it needs them.
    let mut args = base.to_vec();
    args[8] = CENTRE_SWEEPS;
    args.extend(["--until", "time:1"]);
    fails_with(&raygun(&args), &["--iterations"]);
    let o = run(&["--until", "roi-sse:1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("roi-sse"), "{}", stderr(&o));
}

#[test]
fn messages_speak_to_users() {
    // Mesa's XDG_RUNTIME_DIR complaint is not the user's business.
    let xdg = tmp_dir("xdg");
    // raygun without XDG_RUNTIME_DIR: its output, and the private runtime folder it would make.
    let without_runtime = |args: &[&str]| {
        let child = command(Path::new(ROOT), args)
            .env_remove("XDG_RUNTIME_DIR")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let runtime = std::env::temp_dir().join(format!("raygun-runtime-{}", child.id()));
        (child.wait_with_output().unwrap(), runtime)
    };
    let out = xdg.join("d.png");
    let (o, runtime) = without_runtime(&[
        "dgi",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,-1",
        "--fov",
        "30,30",
        "--size",
        "16,9",
        "--out",
        s(&out),
    ]);
    ok(&o);
    assert!(!stderr(&o).contains("XDG_RUNTIME_DIR"), "{}", stderr(&o));
    // The private runtime folder raygun made for the drivers is gone when it ends, after an
    // error too.
    assert!(!runtime.exists(), "{} was left behind", runtime.display());
    let out = xdg.join("e.png");
    let (failed, runtime) = without_runtime(&[
        "dgi",
        "--display",
        "/nonexistent/m.json",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,-1",
        "--fov",
        "30,30",
        "--out",
        s(&out),
    ]);
    assert_eq!(failed.status.code(), Some(1));
    assert!(!runtime.exists(), "{} was left behind", runtime.display());
    // A cause is said once.
    let o = raygun(&[
        "dgi",
        "--display",
        "/nonexistent/m.json",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,-1",
        "--fov",
        "30,30",
        "--out",
        "/tmp/x.png",
    ]);
    let e = fails_with(&o, &["/nonexistent/m.json"]);
    assert_eq!(e.to_lowercase().matches("no such file").count(), 1, "{e}");
    // The viewer without a display points to what works.
    let o = command(Path::new(ROOT), &["view"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    if cfg!(feature = "viewer") {
        fails_with(&o, &["raygun render", "demo --headless"]);
    }
    // A display that is named but cannot be reached: the message names it, not winit's source.
    let no_x = tmp_dir("no-x");
    let o = command(
        Path::new(ROOT),
        &[
            "view",
            "--size",
            "16,8",
            "--backend",
            "cpu",
            "--save-dir",
            s(&no_x),
        ],
    )
    .env("DISPLAY", ":99")
    .env_remove("WAYLAND_DISPLAY")
    .output()
    .unwrap();
    if cfg!(feature = "viewer") {
        let e = fails_with(&o, &[":99", "raygun render"]);
        assert!(!e.contains(".rs:"), "{e}");
    }
    // An unwritable save folder fails before the window opens.
    let o = command(
        Path::new(ROOT),
        &[
            "view",
            "--save-dir",
            "/proc/version/shots",
            "--screenshot-after",
            "1",
        ],
    )
    .env("DISPLAY", ":99")
    .output()
    .unwrap();
    if cfg!(feature = "viewer") {
        fails_with(&o, &["--save-dir", "/proc/version"]);
    }
    // Huge values are quoted short.
    let dir = tmp_dir("messages");
    let big = dir.join("big.json");
    std::fs::write(&big, model_json(&"y".repeat(10_000_000))).unwrap();
    let o = raygun(&[
        "pick",
        "--display",
        s(&big),
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,-1",
    ]);
    let e = fails_with(&o, &["big.json"]);
    assert!(e.len() < 1000, "{} bytes", e.len());
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--guide",
        "mouse:8,4:3,3",
        "--iterations",
        "1",
        "--falloff-base",
        "-1e308",
        "--out",
        "/tmp/x.png",
    ]);
    let e = fails_with(&o, &["-1e308"]);
    assert!(e.len() < 300, "{e}");
    let o = raygun(&[
        "dgi",
        "--fov",
        "1e-9,1e-9",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,-1",
        "--out",
        "/tmp/x.png",
    ]);
    let e = fails_with(&o, &["narrower"]);
    assert!(!e.contains("half-space"), "{e}");
    // A negative value for a flag is read as the value, and the range error explains it.
    let o = raygun(&["view", "--p-min", "-1"]);
    assert_ne!(o.status.code(), Some(0));
    assert!(
        !stderr(&o).contains("unexpected argument"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn help_speaks_to_users() {
    let commands: &[&[&str]] = &[
        &[],
        &["render"],
        &["view"],
        &["dgi"],
        &["demo"],
        &["pick"],
        &["replay"],
        &["record"],
        &["calibrate"],
        &["ellipse-distance"],
        &["scene", "info"],
        &["bench", "dgi"],
        &["bench", "guided"],
        &["bench", "trace"],
        &["bench", "filter"],
        &["bench", "denoise"],
        &["bench", "schedule"],
        &["bench", "all"],
        &["display", "expand"],
        &["display", "outputs"],
        &["synth-replays"],
    ];
    for c in commands {
        let mut args = c.to_vec();
        args.push("--help");
        let o = raygun(&args);
        ok(&o);
        let text = stdout(&o);
        for banned in [
            "f32::",
            "MIN_POSITIVE",
            "issue ",
            "DESIGN.md",
            "src/",
            "`Gpu`",
            "f64, rayon",
        ] {
            assert!(
                !text.contains(banned),
                "raygun {c:?} --help says {banned:?}:\n{text}"
            );
        }
    }
}

#[test]
fn the_demo_report_lists_and_explains_every_file_in_words() {
    let dir = tmp_dir("demo-report");
    let out = dir.join("demo");
    let o = raygun(&[
        "demo",
        "--headless",
        "--out",
        s(&out),
        "--size",
        "62,25",
        "--iterations",
        "2",
        "--backend",
        "cpu",
        "--quiet",
    ]);
    ok(&o);
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    for debug_text in ["{ ", "Falloff", "base_m", "Exact", "Fast", "Coherent"] {
        assert!(!report.contains(debug_text), "{debug_text:?} in:\n{report}");
    }
    for file in [
        "inputs/hornet.json",
        "inputs/flystick-1-centre-sweeps.dtrack.jsonl",
        "image.png",
        "image.exr",
        "dgi.png",
        "counts.exr",
        "denoisers.png",
        "report.md",
    ] {
        let line = report
            .lines()
            .find(|l| l.contains(&format!("`{file}`")))
            .unwrap_or_else(|| panic!("{file} not listed:\n{report}"));
        assert!(line.len() > file.len() + 10, "{file} not explained: {line}");
    }
    assert!(report.contains("last ROI"), "{report}");
}

#[test]
fn one_name_for_the_dgi_channel_and_honest_benchmark_tables() {
    let dir = tmp_dir("consistency");
    let channel = |p: &Path| {
        let img = exr::prelude::read_first_flat_layer_from_file(p).unwrap();
        img.layer_data.channel_data.list[0].name.to_string()
    };
    let d = dir.join("d.exr");
    ok(&raygun(&[
        "dgi",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,-1",
        "--fov",
        "30,30",
        "--size",
        "16,9",
        "--out",
        s(&d),
    ]));
    let r = dir.join("r.exr");
    ok(&raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--size",
        "16,9",
        "--guide",
        "mouse:8,4:3,3",
        "--iterations",
        "1",
        "--out",
        s(&r),
        "--backend",
        "cpu",
    ]));
    assert_eq!(channel(&d), "d");
    assert_eq!(channel(&dir.join("r.dgi.exr")), "d");
    let o = raygun(&[
        "bench",
        "dgi",
        "--size",
        "16,9",
        "--fov",
        "10",
        "--reps",
        "1",
        "--cpu-reps",
        "1",
        "--backend",
        "cpu",
    ]);
    ok(&o);
    let md = stdout(&o);
    let header = md.lines().find(|l| l.starts_with("| FOV")).unwrap();
    let rule = md.lines().find(|l| l.starts_with("|---")).unwrap();
    assert_eq!(
        header.matches('|').count(),
        rule.matches('|').count(),
        "{header}"
    );
    assert!(!md.contains("0.0e0"), "{md}");
}

#[test]
fn progress_is_reported_off_a_terminal() {
    let dir = tmp_dir("progress");
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--size",
        "16,9",
        "--spp",
        "2",
        "--out",
        s(&dir.join("p.png")),
        "--backend",
        "cpu",
    ]);
    ok(&o);
    assert!(stderr(&o).contains("raygun: rendering "), "{}", stderr(&o));
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--size",
        "16,9",
        "--spp",
        "2",
        "--out",
        s(&dir.join("p.png")),
        "--backend",
        "cpu",
        "--quiet",
    ]);
    ok(&o);
    assert!(!stderr(&o).contains("raygun: rendering "), "{}", stderr(&o));
}

/// The repository's text files under `dirs` (recursively, build output left out) and the
/// named `files` that exist: source, shaders, scripts and documentation.
fn text_files(dirs: &[&str], files: &[&str]) -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                if path
                    .file_name()
                    .is_some_and(|n| n != "target" && n != ".git")
                {
                    walk(&path, out);
                }
            } else if path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| ["rs", "wgsl", "sh", "py", "md", "toml"].contains(&e))
            {
                out.push(path);
            }
        }
    }
    let root = Path::new(ROOT);
    let mut out = Vec::new();
    for d in dirs {
        walk(&root.join(d), &mut out);
    }
    out.extend(files.iter().map(|f| root.join(f)).filter(|p| p.is_file()));
    out.sort();
    out
}

/// Each line of `files` (non-UTF-8 files skipped) as (`path:line`, line).
fn numbered_lines(files: &[PathBuf]) -> Vec<(String, String)> {
    let root = Path::new(ROOT);
    let mut out = Vec::new();
    for f in files {
        let Ok(text) = std::fs::read_to_string(f) else {
            continue;
        };
        let name = f.strip_prefix(root).unwrap_or(f).display().to_string();
        for (i, line) in text.lines().enumerate() {
            out.push((format!("{name}:{}", i + 1), line.to_string()));
        }
    }
    out
}

/// Code that relies on a measured figure cites the section of the benchmark report that holds
/// it, in one form on one line: `BENCHMARKS.md, *Methods*` — the file's name, a comma and one
/// of its headings in asterisks. A citation that names no section, or a heading the report
/// does not have, fails with its file and line; the report stays a report (at most 700 lines).
#[test]
fn benchmark_citations_name_a_section_of_the_report() {
    let report_name = concat!("BENCHMARKS", ".md");
    let report = std::fs::read_to_string(Path::new(ROOT).join(report_name)).unwrap();
    let headings: Vec<&str> = report
        .lines()
        .filter(|l| l.starts_with('#'))
        .map(|l| l.trim_start_matches('#').trim())
        .collect();
    let files = text_files(
        &["src", "shaders", "tests", "tools", "benches", "examples"],
        &["Cargo.toml"],
    );
    let mut citations = 0;
    let mut bad = Vec::new();
    let lines = report.lines().count();
    if lines > 700 {
        bad.push(format!(
            "{report_name} has {lines} lines: a report of where raygun stands, not a log"
        ));
    }
    for (at, line) in numbered_lines(&files) {
        for (i, _) in line.match_indices(report_name) {
            citations += 1;
            let rest = &line[i + report_name.len()..];
            let heading = rest
                .strip_prefix(", *")
                .and_then(|r| r.split_once('*'))
                .map(|(h, _)| h);
            match heading {
                Some(h) if headings.contains(&h) => {}
                Some(h) => bad.push(format!("{at}: *{h}* is no heading of {report_name}")),
                None => bad.push(format!(
                    "{at}: cites {report_name} without a section (`{report_name}, *Heading*` on \
                     one line)"
                )),
            }
        }
    }
    assert!(
        citations > 0,
        "no citations found: is the scan looking in the right place?"
    );
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// Why a line speaks of how raygun was developed rather than of raygun, if it does: a tracker
/// issue's number (the word issue, or a hash sign in prose, before digits), the word "session"
/// for a stretch of development work (a demonstrative or an ordinal from the third before it,
/// or a number after it — product words such as a tracking session, a recorded or replayed
/// session, the `session` layer or the first and second sessions of a server pass), borrowed
/// machines, dated diary headings (Markdown only) and a note left for the next reader.
fn development_words(line: &str, markdown: bool) -> Option<&'static str> {
    let l = line.to_lowercase();
    let b = l.as_bytes();
    let alnum = |i: usize| b[i].is_ascii_alphanumeric();
    let digit_at = |mut i: usize, hash: bool| {
        while i < b.len() && b[i] == b' ' {
            i += 1;
        }
        if hash && i < b.len() && b[i] == b'#' {
            i += 1;
        }
        i < b.len() && b[i].is_ascii_digit()
    };
    for (i, _) in l.match_indices("issue") {
        let after = i + "issue".len();
        let after = if b.get(after) == Some(&b's') {
            after + 1
        } else {
            after
        };
        if (i == 0 || !alnum(i - 1)) && digit_at(after, true) {
            return Some("a tracker issue's number");
        }
    }
    for (i, _) in l.match_indices('#') {
        let starts_word = i == 0 || matches!(b[i - 1], b' ' | b'\t' | b'(' | b'[');
        let digits = b[i + 1..].iter().take_while(|c| c.is_ascii_digit()).count();
        let ends_word = b
            .get(i + 1 + digits)
            .is_none_or(|&c| !(c.is_ascii_alphanumeric() || c == b'_'));
        if starts_word && digits > 0 && ends_word {
            return Some("a tracker issue's number (#N)");
        }
    }
    const BEFORE: &[&str] = &[
        "this", "that", "earlier", "later", "previous", "prior", "next",
    ];
    const ORDINALS: &[&str] = &[
        "third",
        "fourth",
        "fifth",
        "sixth",
        "seventh",
        "eighth",
        "ninth",
        "tenth",
        "eleventh",
        "twelfth",
        "thirteenth",
        "fourteenth",
        "fifteenth",
        "sixteenth",
        "seventeenth",
        "eighteenth",
        "nineteenth",
        "twentieth",
        "thirtieth",
    ];
    for (i, _) in l.match_indices("session") {
        if i > 0 && alnum(i - 1) {
            continue;
        }
        let before = l[..i].trim_end();
        let word_start = before
            .rfind(|c: char| !(c.is_ascii_alphabetic() || c == '-'))
            .map_or(0, |k| k + 1);
        let word = if before.len() < i {
            &before[word_start..]
        } else {
            ""
        };
        let last = word.rsplit('-').next().unwrap_or("");
        let compound = word.contains('-') && (last == "first" || last == "second");
        if BEFORE.contains(&word) || ORDINALS.contains(&last) || compound {
            return Some("a development session");
        }
        let after = i + "session".len();
        let after = if b.get(after) == Some(&b's') {
            after + 1
        } else {
            after
        };
        if digit_at(after, false) {
            return Some("a development session's number");
        }
    }
    let borrowed = concat!("le", "nt");
    for (i, _) in l.match_indices(borrowed) {
        let end = i + borrowed.len();
        if (i == 0 || !b[i - 1].is_ascii_alphabetic())
            && b.get(end).is_none_or(|c| !c.is_ascii_alphabetic())
        {
            return Some("a borrowed machine");
        }
    }
    if l.contains(concat!("this", " week")) {
        return Some("a diary's week");
    }
    if l.contains(concat!("lead-read", "-first")) {
        return Some("a note left for the next reader");
    }
    let heading = line.len() - line.trim_start().len() <= 3 && line.trim_start().starts_with('#');
    let dated = b.windows(10).any(|w| {
        w.iter().enumerate().all(|(k, c)| match k {
            4 | 7 => *c == b'-',
            _ => c.is_ascii_digit(),
        })
    });
    if markdown && heading && dated {
        return Some("a dated diary heading");
    }
    None
}

/// raygun's code, scripts and documentation say what raygun does and how fast it is, not how it
/// was developed: no tracker issue numbers, no development sessions, no borrowed machines, no
/// dated diary headings, no notes to the next reader. Product vocabulary passes; the checker
/// is checked on both.
#[test]
fn no_word_of_how_raygun_was_developed() {
    for (line, md) in [
        (
            concat!("Head tracking (issue", " 19, part 2): the eye follows"),
            false,
        ),
        (concat!("see issue #", "19"), false),
        (concat!("the fix for #", "19 landed"), false),
        (concat!("issues", " 17 and 19"), false),
        (concat!("measured in this ", "session on the EPYC"), false),
        (
            concat!("the eleventh ", "session's resident picture"),
            false,
        ),
        (concat!("the twenty-first ", "session found"), false),
        (concat!("(session", " 4) four rows per vector"), false),
        ("### 2026-12-04 — NVIDIA H200", true),
        (concat!("see LEAD-READ", "-FIRST.md"), false),
        (concat!("no GPU was ", "le", "nt"), false),
    ] {
        assert!(development_words(line, md).is_some(), "not caught: {line}");
    }
    for (line, md) in [
        (
            "A tracking session with a FlyStick: the session layer replays it",
            false,
        ),
        (
            "a recorded session, a replay session, the synthetic sessions",
            false,
        ),
        ("Closing lets the server's second session end.", false),
        (
            "session::live::LiveTracking and held_points_session()",
            false,
        ),
        (
            "#[derive(Clone)] and r#\"raw\"# and {:#x} and $# and \"#1\"",
            false,
        ),
        ("## Distance-guide image", true),
        ("| H200, 2026-12-04 | met |", true),
        ("excellent, silent, equivalent tissues", false),
    ] {
        assert_eq!(development_words(line, md), None, "{line}");
    }
    let files = text_files(
        &[
            "src", "shaders", "tests", "tools", "benches", "examples", "docs", "fuzz",
        ],
        &["README.md", concat!("BENCHMARKS", ".md"), "Cargo.toml"],
    );
    let mut found = Vec::new();
    for (at, line) in numbered_lines(&files) {
        if let Some(why) = development_words(&line, at.contains(".md:")) {
            found.push(format!("{at}: {why}: {}", line.trim()));
        }
    }
    assert!(found.is_empty(), "{}", found.join("\n"));
}
