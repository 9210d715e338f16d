//! The `raygun` binary end to end: arguments, outputs and error messages.

use crate::support;
use support::{raygun, tmp_file};

use std::path::PathBuf;
use std::process::Command;

fn read_exr_gray(path: &PathBuf) -> (usize, usize, Vec<f32>) {
    let img = exr::prelude::read_first_flat_layer_from_file(path).unwrap();
    let size = img.layer_data.size;
    let values = img.layer_data.channel_data.list[0]
        .sample_data
        .values_as_f32()
        .collect();
    (size.0, size.1, values)
}

#[test]
fn dgi_writes_exr_on_both_backends_and_they_agree() {
    let mut results = Vec::new();
    for backend in ["cpu", "gpu"] {
        let out = tmp_file(&format!("dgi-{backend}.exr"));
        let o = raygun(&[
            "dgi",
            "--display",
            "display-models/hornet.json",
            "--origin",
            "0,0,1",
            "--dir",
            "0,0,-1",
            "--fov",
            "30,20",
            "--size",
            "192,108",
            "--backend",
            backend,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let (w, h, v) = read_exr_gray(&out);
        assert_eq!((w, h), (192, 108));
        assert!(v.iter().all(|d| (0.0..=1.0).contains(d)));
        // The centre pixel is in the ROI; a corner is far outside it.
        assert_eq!(v[54 * 192 + 96], 0.0);
        assert_eq!(v[0], 1.0);
        results.push(v);
    }
    let worst = results[0]
        .iter()
        .zip(&results[1])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(worst < 1e-4, "GPU vs CPU: {worst}");
}

#[test]
fn dgi_mouse_variant_and_png() {
    let out = tmp_file("mouse.png");
    let o = raygun(&[
        "dgi",
        "--display",
        "display-models/desktop-27in-4k.json",
        "--center-px",
        "192,108",
        "--axes-px",
        "40,20",
        "--size",
        "384,216",
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let png = image::open(&out).unwrap().to_luma8();
    assert_eq!(png.dimensions(), (384, 216));
    assert_eq!(png.get_pixel(192, 108)[0], 0);
    // d grows away from the ellipse (the default falloff, ~0.48 m here, spans most of a
    // 0.6 m monitor, so the corner is not saturated).
    let row: Vec<u8> = (0..192).rev().map(|x| png.get_pixel(x, 108)[0]).collect();
    assert!(row.windows(2).all(|w| w[0] <= w[1]), "{row:?}");
    assert!(png.get_pixel(0, 0)[0] > 100);
}

#[test]
fn dgi_raw_distances_are_canvas_pixels() {
    let out = tmp_file("raw.exr");
    // Mouse ellipse with semi-axes 100 × 100 image px on a 3840×2160 image of the 4K monitor:
    // image px = canvas px, so the raw distance at 300 px right of the centre is 200.
    let o = raygun(&[
        "dgi",
        "--display",
        "display-models/desktop-27in-4k.json",
        "--center-px",
        "1920.5,1080.5",
        "--axes-px",
        "100,100",
        "--raw",
        "--backend",
        "cpu",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (w, _, v) = read_exr_gray(&out);
    assert!(
        (v[1080 * w + 2220] - 200.0).abs() < 1e-3,
        "{}",
        v[1080 * w + 2220]
    );
}

#[test]
fn errors_name_what_is_wrong_and_exit_non_zero() {
    let o = raygun(&[
        "dgi",
        "--display",
        "no/such/model.json",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,-1",
        "--fov",
        "30,30",
        "--out",
        "x.png",
        "--backend",
        "cpu",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no/such/model.json"), "{err}");

    let o = raygun(&[
        "dgi",
        "--display",
        "display-models/hornet.json",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,-1",
        "--fov",
        "200,30",
        "--out",
        "x.png",
        "--backend",
        "cpu",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("180"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );

    let o = raygun(&[
        "dgi",
        "--display",
        "display-models/hornet.json",
        "--origin",
        "0,0",
        "--dir",
        "0,0,-1",
        "--fov",
        "30,30",
        "--out",
        "x.png",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("X,Y,Z"));

    let o = raygun(&[
        "dgi",
        "--display",
        "display-models/hornet.json",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,-1",
        "--fov",
        "30,30",
        "--raw",
        "--out",
        "x.png",
        "--backend",
        "cpu",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains(".exr"));

    // A cone whose ray misses the wall gives no ROI: an error, as for `render --guide pose:`,
    // not an all-white DGI.
    let out = std::env::temp_dir().join(format!("raygun-miss-{}.png", std::process::id()));
    let o = raygun(&[
        "dgi",
        "--display",
        "hornet",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,1",
        "--fov",
        "30,30",
        "--out",
        out.to_str().unwrap(),
        "--backend",
        "cpu",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--origin/--dir: the ray from")
            && err.contains("misses the display (HORNET): it gives no ROI"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn pick_prints_the_hit_as_json() {
    let o = raygun(&[
        "pick",
        "--display",
        "display-models/hornet.json",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,-1",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["hit"], true);
    assert!((v["t"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    let o = raygun(&[
        "pick",
        "--display",
        "display-models/hornet.json",
        "--origin",
        "0,0,1",
        "--dir",
        "0,0,1",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v, serde_json::json!({"hit": false}));
}

#[test]
fn display_expand_round_trips_through_the_loader() {
    let o = raygun(&["display", "expand", "display-models/hornet.json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8(o.stdout).unwrap();
    let expanded = raygun::display::DisplayModel::from_json(&text, "expanded").unwrap();
    let original = raygun::display::DisplayModel::load(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("display-models/hornet.json"),
    )
    .unwrap();
    assert_eq!(expanded.tiles().len(), 35);
    assert_eq!(expanded.to_json_pretty(), original.to_json_pretty());
}

#[test]
fn record_stops_on_ctrl_c_and_keeps_every_datagram() {
    let out = tmp_file("recorded.jsonl");
    let port = 40000 + (std::process::id() % 20000) as u16;
    let child = Command::new(env!("CARGO_BIN_EXE_raygun"))
        .args([
            "record",
            "--dtrack",
            &port.to_string(),
            "--out",
            out.to_str().unwrap(),
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    // Send until the recorder has bound (it starts in well under a second).
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    let mut sent = 0;
    while std::time::Instant::now() < deadline && sent < 40 {
        sock.send_to(format!("fr {sent}\n").as_bytes(), ("127.0.0.1", port))
            .unwrap();
        sent += 1;
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(
        lines[0].contains("raygun_replay"),
        "header first: {}",
        lines[0]
    );
    // The last datagram sent before Ctrl-C is in the file (nothing lost in a buffer).
    assert!(lines.len() > 10, "{} lines", lines.len());
    assert!(text.contains(&format!("fr {}", sent - 1)), "{text}");
}

/// `bench trace --trace-kernel` times the trace kernel's variants side by side and labels every
/// row; `RAYGUN_TRACE_KERNEL` compiles another variant for any command, and a guided render
/// made with it (another stack, regeneration, the vote) writes the default kernel's files byte
/// for byte; bad names are refused by name. A kernel-lab test: lavapipe compiles each variant
/// in tens of seconds.
#[cfg(feature = "kernel-lab")]
#[test]
fn trace_kernel_variants_are_timed_side_by_side_and_render_the_same_files() {
    let o = raygun(&[
        "bench",
        "trace",
        "--backend",
        "gpu",
        "--scene",
        "builtin:cornell",
        "--size",
        "32,18",
        "--spp",
        "1",
        "--json",
        "--trace-kernel",
        "function,workgroup+unchecked+wg32",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    let json: serde_json::Value = serde_json::from_str(&out[out.find('{').unwrap()..]).unwrap();
    let kernels: Vec<&str> = json["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["kernel"].as_str().unwrap())
        .collect();
    assert_eq!(kernels, ["function", "workgroup+unchecked+wg32"]);

    let o = raygun(&[
        "bench",
        "trace",
        "--backend",
        "cpu",
        "--scene",
        "builtin:cornell",
        "--size",
        "8,8",
        "--spp",
        "1",
        "--trace-kernel",
        "private",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--backend gpu"));
    let o = raygun(&["bench", "trace", "--trace-kernel", "shared"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("function, private or workgroup"));

    let dir = support::tmp_dir("trace-kernel-env");
    let render = |name: &str, variant: Option<&str>| {
        let out = dir.join(name);
        let mut c = support::command(
            std::path::Path::new(support::ROOT),
            &[
                "render",
                "--scene",
                "builtin:cornell-light",
                "--backend",
                "gpu",
                "--size",
                "48,27",
                "--iterations",
                "3",
                "--guide",
                "pose:0,0,1:0,0,-1:20",
                "--display",
                "hornet",
            ],
        );
        c.arg("--out").arg(&out);
        if let Some(v) = variant {
            c.env("RAYGUN_TRACE_KERNEL", v);
        }
        (c.output().unwrap(), out)
    };
    let (a, a_file) = render("function.exr", None);
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    let (b, b_file) = render("private.exr", Some("private+unchecked+wg128"));
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    assert!(
        String::from_utf8_lossy(&b.stderr).contains("trace kernel private+unchecked+wg128")
            || String::from_utf8_lossy(&b.stdout).contains("trace kernel private+unchecked+wg128"),
        "the run names its kernel"
    );
    assert!(std::fs::read(&a_file).unwrap() == std::fs::read(&b_file).unwrap());
    // Regenerated in one workgroup: the full frames and every guided iteration's list (the
    // scheduler's arguments capped to one group of 32) traced by 32 threads.
    let (c, c_file) = render("regen.exr", Some("function+wg32+regen1"));
    assert!(c.status.success(), "{}", String::from_utf8_lossy(&c.stderr));
    assert!(std::fs::read(&a_file).unwrap() == std::fs::read(&c_file).unwrap());
    // Triangle tests postponed by subgroup vote whenever any lane is not testing triangles
    // (lavapipe has subgroups of 8).
    let (d, d_file) = render("vote.exr", Some("private+vote100"));
    assert!(d.status.success(), "{}", String::from_utf8_lossy(&d.stderr));
    assert!(std::fs::read(&a_file).unwrap() == std::fs::read(&d_file).unwrap());
    let (bad, _) = render("bad.exr", Some("stack"));
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("RAYGUN_TRACE_KERNEL=\"stack\""), "{err}");
}

/// A build without the kernel lab has one trace kernel and no way to ask for another:
/// `bench trace` has no `--trace-kernel` and its help names no variant, and a
/// `RAYGUN_TRACE_KERNEL` is refused — with `--backend auto` too, not taken for a missing GPU —
/// naming the variable and the feature that has it, before any work; its benchmark rows name
/// the kernel as the kernel lab names the default.
#[cfg(not(feature = "kernel-lab"))]
#[test]
fn a_build_without_the_kernel_lab_has_one_trace_kernel() {
    let help = raygun(&["bench", "trace", "--help"]);
    assert!(help.status.success());
    let help = String::from_utf8_lossy(&help.stdout).to_lowercase();
    assert!(help.contains("--scene"), "{help}");
    assert!(
        !help.contains("--trace-kernel") && !help.contains("variant"),
        "{help}"
    );
    let o = raygun(&["bench", "trace", "--trace-kernel", "private"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--trace-kernel"));

    let dir = support::tmp_dir("no-kernel-lab");
    for backend in ["gpu", "auto"] {
        let out = dir.join(format!("{backend}.exr"));
        let o = support::command(
            std::path::Path::new(support::ROOT),
            &[
                "render",
                "--scene",
                "builtin:cornell",
                "--size",
                "8,8",
                "--spp",
                "1",
                "--backend",
                backend,
            ],
        )
        .arg("--out")
        .arg(&out)
        .env("RAYGUN_TRACE_KERNEL", "private+vote")
        .output()
        .unwrap();
        assert!(!o.status.success(), "{backend}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("RAYGUN_TRACE_KERNEL=\"private+vote\"") && err.contains("kernel-lab"),
            "{backend}: {err}"
        );
        assert!(!err.contains("using the CPU backend"), "{backend}: {err}");
        assert!(!out.exists(), "{backend}");
    }

    let o = raygun(&[
        "bench",
        "trace",
        "--backend",
        "gpu",
        "--scene",
        "builtin:cornell",
        "--size",
        "16,9",
        "--spp",
        "1",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    let json: serde_json::Value = serde_json::from_str(&out[out.find('{').unwrap()..]).unwrap();
    assert_eq!(json["rows"][0]["kernel"], "private");
    assert!(json.get("kernels_not_run").is_none(), "{json}");
}

/// `RAYGUN_CPU_PACKETS` chooses how the CPU twin walks its rays — one at a time, or packets in
/// AVX2 or (where the processor has it) AVX-512 lanes — and every choice renders the same file
/// byte for byte; the benchmark's report names the walks it ran; a value that is
/// not a choice, or one this processor cannot run, is refused naming the variable.
#[test]
fn cpu_packet_widths_render_the_same_files() {
    let dir = support::tmp_dir("cpu-packets");
    let run = |args: &[&str], packets: Option<&str>| {
        let mut c = support::command(std::path::Path::new(support::ROOT), args);
        if let Some(v) = packets {
            c.env("RAYGUN_CPU_PACKETS", v);
        }
        c.output().unwrap()
    };
    let render = |name: &str, packets: Option<&str>| {
        let out = dir.join(name);
        let out_arg = out.to_str().unwrap().to_owned();
        let o = run(
            &[
                "render",
                "--scene",
                "builtin:city-small",
                "--guide",
                "pose:0,0,1:0,0,-1:60",
                "--backend",
                "cpu",
                "--size",
                "96,54",
                "--iterations",
                "3",
                "--out",
                &out_arg,
            ],
            packets,
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(&out).unwrap()
    };
    // The packets in AVX2 where the build targets AVX2 and FMA (x86-64's, .cargo/config.toml),
    // as `CpuPackets::widest` decides; elsewhere one ray at a time, both widths refused.
    let avx2 = cfg!(all(target_feature = "avx2", target_feature = "fma"));
    #[cfg(target_arch = "x86_64")]
    let avx512 = std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512dq");
    #[cfg(not(target_arch = "x86_64"))]
    let avx512 = false;
    let one = render("one.exr", Some("0"));
    if avx2 {
        assert!(render("avx2.exr", Some("avx2")) == one, "AVX2 packets");
    }
    assert!(render("widest.exr", None) == one, "the widest packets");
    let bench = |packets: &str| {
        let o = run(
            &[
                "bench",
                "trace",
                "--backend",
                "cpu",
                "--scene",
                "builtin:cornell",
                "--size",
                "16,9",
                "--spp",
                "1",
                "--json",
            ],
            Some(packets),
        );
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).into_owned(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let (ok, out, err) = bench("avx2");
    if avx2 {
        assert!(ok, "{err}");
        assert!(out.contains("rays in packets of 16 (AVX2)"), "{out}");
    } else {
        assert!(!ok && err.contains("RAYGUN_CPU_PACKETS=\"avx2\""), "{err}");
    }
    let (ok, out, err) = bench("avx512");
    if avx512 {
        assert!(ok, "{err}");
        assert!(out.contains("rays in packets of 16 (AVX-512)"), "{out}");
    } else {
        assert!(
            !ok && err.contains("RAYGUN_CPU_PACKETS=\"avx512\""),
            "{err}"
        );
    }
    for bad in ["8", "yes", ""] {
        let (ok, _, err) = bench(bad);
        assert!(!ok, "RAYGUN_CPU_PACKETS={bad:?} accepted");
        assert!(
            err.contains(&format!("RAYGUN_CPU_PACKETS={bad:?}")),
            "{err}"
        );
    }
}

/// `--size` reads the same in every command that takes an image size (a command's own default
/// and its own remark follow the shared sentence).
#[test]
fn size_reads_the_same_everywhere() {
    let commands: [&[&str]; 13] = [
        &["render"],
        &["demo"],
        &["view"],
        &["dgi"],
        &["pick"],
        &["bench", "dgi"],
        &["bench", "filter"],
        &["bench", "schedule"],
        &["bench", "trace"],
        &["bench", "guided"],
        &["bench", "all"],
        &["bench", "readback"],
        &["bench", "picture"],
    ];
    for command in commands {
        let o = raygun(&[command, &["--help"]].concat());
        assert!(o.status.success(), "{command:?}");
        let help = String::from_utf8_lossy(&o.stdout);
        // The flag's line and the lines of its text, up to the next flag.
        let mut lines = help
            .lines()
            .skip_while(|l| !l.trim_start().starts_with("--size"));
        let first = lines
            .next()
            .unwrap_or_else(|| panic!("{command:?} has no --size: {help}"));
        let size = std::iter::once(first)
            .chain(lines.take_while(|l| !l.trim_start().starts_with('-')))
            .flat_map(str::split_whitespace)
            .collect::<Vec<_>>()
            .join(" ");
        assert!(
            size.contains("Image size in pixels, W,H"),
            "{command:?}: {size}"
        );
        let native = size.contains("<W,H|native>");
        assert_eq!(
            native,
            size.contains("or `native`: the display canvas's own pixel size"),
            "{command:?}: {size}"
        );
    }
}

/// The seconds a `one-time work` line gives for each of the load, the build and the upload,
/// read from a command's standard error.
fn one_time_seconds(stderr: &str) -> [f64; 3] {
    let line = stderr
        .lines()
        .find(|l| l.contains("one-time work (not in the sampling time): "))
        .unwrap_or_else(|| panic!("no one-time line in:\n{stderr}"));
    let seconds = |label: &str| -> f64 {
        let from = line
            .find(label)
            .unwrap_or_else(|| panic!("{label}: {line}"))
            + label.len();
        let value = line[from..].trim_start().split(' ').next().unwrap();
        value
            .parse()
            .unwrap_or_else(|_| panic!("{label} {value}: {line}"))
    };
    [
        seconds("scene load"),
        seconds("BVH build"),
        seconds("upload"),
    ]
}

/// A render says how long its one-time work took — the scene's load, the BVH's build, the
/// upload — on a line of its own, apart from the sampling time (its `ms per megasample`
/// figure), full frame and guided alike; `scene info` gives the load and the build, in its
/// text and in its JSON.
#[test]
fn renders_report_their_one_time_work_apart_from_the_sampling_time() {
    let dir = support::tmp_dir("one-time-work");
    let out = dir.join("out.png");
    let guided: [&str; 4] = ["--guide", "pose:0,0,1:0,0,-1:20", "--iterations", "2"];
    for extra in [&["--spp", "2"][..], &guided[..]] {
        let mut args = vec![
            "render",
            "--scene",
            "builtin:cornell",
            "--backend",
            "cpu",
            "--size",
            "32,18",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = raygun(&args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        for s in one_time_seconds(&err) {
            assert!(s.is_finite() && s >= 0.0, "{err}");
        }
        // The sampling figure stays on its own line, as before.
        assert!(err.contains(" ms per megasample"), "{err}");
    }
    // `--quiet` says nothing of it.
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--backend",
        "cpu",
        "--size",
        "8,8",
        "--spp",
        "1",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    assert!(!String::from_utf8_lossy(&o.stderr).contains("one-time"));

    let o = raygun(&["scene", "info", "builtin:cornell", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in ["load_seconds", "build_seconds"] {
        let s = v["timing"][key].as_f64().unwrap_or(f64::NAN);
        assert!(s.is_finite() && s >= 0.0, "{key}: {v}");
    }
    let text = String::from_utf8(raygun(&["scene", "info", "builtin:cornell"]).stdout).unwrap();
    assert!(
        text.contains("one-time work: scene load ") && text.contains(" s, BVH build "),
        "{text}"
    );
}
