//! `render … --cluster` under `mpirun` (the `cluster` feature; CI runs
//! `cargo test --features cluster --test cluster`): N ranks write exactly the files one
//! process writes, byte for byte, for 1, 2 and 3 ranks; a rank that stops answering or ends
//! ends the job within seconds with an error naming it; ranks that disagree are stopped
//! before any work. Without the feature, `--cluster` says how to get it.

#[path = "support/cli.rs"]
mod support;

#[cfg(not(feature = "cluster"))]
use support::*;

#[cfg(not(feature = "cluster"))]
#[test]
fn without_the_feature_cluster_says_how_to_get_it() {
    let o = raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--size",
        "8,8",
        "--out",
        "x.exr",
        "--cluster",
    ]);
    fails_with(
        &o,
        &[
            "--cluster",
            "cargo build --release --features cluster",
            "openmpi-bin",
            "mpirun",
        ],
    );
}

/// `bench guided --cluster --cluster-threads N`: the ranks as threads of one process (no MPI,
/// with or without the feature), here on GPU ranks (lavapipe): every scheduled sample traced by
/// one rank, what one sent the other received.
#[test]
fn the_cluster_benchmark_runs_its_ranks_as_threads_without_mpi() {
    let out = support::tmp_file("bench-threads.json");
    let o = support::raygun(&[
        "bench",
        "guided",
        "--cluster",
        "--cluster-threads",
        "2",
        "--backend",
        "gpu",
        "--scene",
        "builtin:cornell",
        "--size",
        "96,40",
        "--fov",
        "10,60",
        "--iterations",
        "2",
        "--model-size",
        "96,40",
        "--model-ranks",
        "2",
        "--json",
        "--out",
        support::s(&out),
    ]);
    support::ok(&o);
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    let device = r["device"].as_str().unwrap();
    assert!(
        device.contains("2 rank(s) as threads of one process") && device.contains("llvmpipe"),
        "{device}"
    );
    let scaling = r["scaling"].as_array().unwrap();
    assert_eq!(scaling.len(), 2);
    for row in scaling {
        let per_rank = row["per_rank"].as_array().unwrap();
        assert_eq!(per_rank.len(), 2);
        let traced: f64 = per_rank
            .iter()
            .map(|p| p["samples_traced_per_iteration"].as_f64().unwrap())
            .sum();
        assert_eq!(traced, row["samples_per_iteration"].as_f64().unwrap());
        // The tracer's call is timed inside the trace step.
        assert!(per_rank.iter().all(|p| {
            let (trace, call) = (
                p["ms_trace"].as_f64().unwrap(),
                p["ms_trace_call"].as_f64().unwrap(),
            );
            trace > 0.0 && call > 0.0 && call <= trace
        }));
        assert_eq!(
            per_rank[0]["bytes_sent_per_iteration"],
            per_rank[1]["bytes_received_per_iteration"]
        );
    }
    // No threads, no ranks.
    let o = support::raygun(&["bench", "guided", "--cluster", "--cluster-threads", "0"]);
    support::fails_with(&o, &["--cluster-threads must be at least 1"]);
}

#[cfg(feature = "cluster")]
mod mpi {
    use std::path::{Path, PathBuf};
    use std::process::{Command, Output};
    use std::time::{Duration, Instant};

    use super::support::*;

    /// `mpirun -np N` with what a CI container needs: root allowed, more ranks than cores,
    /// shared memory between the ranks on one machine.
    fn mpirun(apps: &[(usize, &Path, Vec<String>)]) -> Output {
        mpirun_in(&[], apps)
    }

    /// [`mpirun`] started by `prefix` (a program and its arguments, e.g. `xvfb-run …`).
    fn mpirun_in(prefix: &[&str], apps: &[(usize, &Path, Vec<String>)]) -> Output {
        let mut c = match prefix.split_first() {
            Some((program, args)) => {
                let mut c = Command::new(program);
                c.args(args).arg("mpirun");
                c
            }
            None => Command::new("mpirun"),
        };
        c.args([
            "--allow-run-as-root",
            "--oversubscribe",
            "--mca",
            "btl",
            "self,vader",
        ])
        .current_dir(ROOT)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        // Each rank on one core's worth of threads: the ranks share the machine.
        .env("RAYON_NUM_THREADS", "1");
        for (i, (np, exe, args)) in apps.iter().enumerate() {
            if i > 0 {
                c.arg(":");
            }
            c.args(["-np", &np.to_string()]).arg(exe).args(args);
        }
        c.output()
            .expect("mpirun runs (apt-get install openmpi-bin)")
    }

    fn exe() -> PathBuf {
        PathBuf::from(env!("CARGO_BIN_EXE_raygun"))
    }

    fn strings(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| (*s).to_owned()).collect()
    }

    /// A guided render on a replay (the ROI changes), p_min 0.05, at a tiny size.
    fn guided(dir: &Path) -> Vec<String> {
        let out = dir.join("img.exr");
        strings(&[
            "render",
            "--scene",
            "builtin:cornell",
            "--size",
            "90,36",
            "--max-depth",
            "4",
            "--guide",
            "tracking-replays/flystick-1-centre-sweeps.dtrack.jsonl",
            "--iterations",
            "6",
            "--p-min",
            "0.05",
            "--backend",
            "cpu",
            "--out",
            s(&out),
        ])
    }

    /// A full frame through the wall camera.
    fn full_wall(dir: &Path) -> Vec<String> {
        strings(&[
            "render",
            "--scene",
            "builtin:cornell",
            "--size",
            "70,28",
            "--spp",
            "3",
            "--max-depth",
            "3",
            "--camera",
            "wall",
            "--display",
            "hornet",
            "--eye",
            "0,0,1.5",
            "--backend",
            "cpu",
            "--out",
            s(&dir.join("img.exr")),
        ])
    }

    fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
        let mut out = Vec::new();
        let mut stack = vec![dir.to_owned()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    stack.push(p);
                } else {
                    let name = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
                    out.push((name, std::fs::read(&p).unwrap()));
                }
            }
        }
        out.sort();
        out
    }

    /// One process, which must succeed.
    fn run_ok(args: &[String]) {
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        ok(&raygun(&refs));
    }

    fn with(mut args: Vec<String>, more: &[&str]) -> Vec<String> {
        args.extend(strings(more));
        args
    }

    fn same_files_as_one_process(name: &str, make: fn(&Path) -> Vec<String>, extra: &[&str]) {
        let one = tmp_dir(&format!("{name}-one"));
        run_ok(&make(&one));
        let want = files(&one);
        assert!(!want.is_empty(), "{want:?}");
        for np in 1..=3 {
            let dir = tmp_dir(&format!("{name}-{np}"));
            let o = mpirun(&[(
                np,
                &exe(),
                with(
                    make(&dir),
                    &with(strings(&["--cluster"]), extra)
                        .iter()
                        .map(String::as_str)
                        .collect::<Vec<_>>(),
                ),
            )]);
            ok(&o);
            let got = files(&dir);
            assert_eq!(
                got.iter().map(|f| &f.0).collect::<Vec<_>>(),
                want.iter().map(|f| &f.0).collect::<Vec<_>>(),
                "{np} ranks: the same files"
            );
            for ((n, a), (_, b)) in got.iter().zip(&want) {
                assert!(a == b, "{np} ranks: {n} differs from the one-process file");
            }
        }
    }

    #[test]
    fn guided_renders_on_1_2_and_3_ranks_write_the_one_process_files_byte_for_byte() {
        same_files_as_one_process("guided", guided, &[]);
    }

    #[test]
    fn broadcast_dgi_renders_match_too() {
        same_files_as_one_process("broadcast", guided, &["--cluster-dgi", "broadcast"]);
    }

    #[test]
    fn split_dgi_renders_match_too() {
        same_files_as_one_process("split", guided, &["--cluster-dgi", "split"]);
    }

    #[test]
    fn full_wall_frames_match_too() {
        same_files_as_one_process("wall", full_wall, &[]);
    }

    /// `--denoise interactive`: rank 0 denoises the whole picture and every owner its tiles
    /// (with the margin the denoiser reaches), the one process's files byte for byte.
    #[test]
    fn denoised_renders_and_their_tiles_match_too() {
        fn guided_denoised(dir: &Path) -> Vec<String> {
            let tiles = dir.join("tiles");
            with(
                guided(dir),
                &["--denoise", "interactive", "--tiles", s(&tiles)],
            )
        }
        fn wall_denoised(dir: &Path) -> Vec<String> {
            with(full_wall(dir), &["--denoise", "interactive"])
        }
        same_files_as_one_process("denoised", guided_denoised, &[]);
        same_files_as_one_process("denoised-wall", wall_denoised, &[]);
    }

    /// `view --cluster`: rank 0 opens the one window (Xvfb here) and follows the mouse ROI,
    /// every rank traces — GPU ranks (lavapipe) through the wall camera — and the whole job ends
    /// when the window closes (`--screenshot-after`), every ROI pixel of the saved picture
    /// sampled in every frame. (That the picture is the one-process viewer's bit for bit is
    /// tests/viewer/viewer.rs's, over in-process ranks.)
    #[test]
    fn the_viewer_across_ranks_opens_one_window_and_every_rank_ends_with_it() {
        let dir = tmp_dir("view");
        let n = 6;
        let (o, _) = view_job(
            &dir,
            n,
            &[
                "--backend",
                "gpu",
                "--camera",
                "wall",
                "--eye",
                "0,0,1.2",
                "--p-min",
                "0.1",
            ],
        );
        ok(&o);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("3 rank(s), rank 0 tracing on llvmpipe"),
            "{err}"
        );
        assert_eq!(err.matches("rendering on").count(), 1, "one window: {err}");
        assert!(dir.join("screenshot.window.png").exists(), "{err}");
        let counts: Vec<f32> =
            exr::prelude::read_first_flat_layer_from_file(dir.join("screenshot.counts.exr"))
                .unwrap()
                .layer_data
                .channel_data
                .list[0]
                .sample_data
                .values_as_f32()
                .collect();
        let dgi = image::open(dir.join("screenshot.dgi.png"))
            .unwrap()
            .to_luma8();
        let roi: Vec<f32> = dgi
            .pixels()
            .zip(&counts)
            .filter(|(d, _)| d.0[0] == 0)
            .map(|(_, &c)| c)
            .collect();
        assert!(!roi.is_empty());
        assert!(roi.iter().all(|&c| c >= n as f32), "{roi:?}");
        assert!(counts.iter().any(|&c| c < n as f32), "the periphery less");
    }

    /// `view --cluster --show-tiles`: every rank but 0 opens a window of the tiles it owns
    /// (whole columns: rank 1 columns 3–4, the Cornell box, rank 2 columns 5–6, the white
    /// environment beside it) and, asked for a screenshot, saves the tiles it showed last at
    /// their own resolution. (That they are the
    /// one-process picture's cut bit for bit is tests/viewer/viewer.rs's.)
    #[test]
    fn with_show_tiles_every_owner_shows_its_own_tiles() {
        let dir = tmp_dir("view-tiles");
        let o = mpirun_in(
            &["xvfb-run", "-a", "-s", "-screen 0 1600x900x24"],
            &[(
                3,
                &exe(),
                strings(&[
                    "view",
                    "--cluster",
                    "--show-tiles",
                    "--display",
                    SMALL_HORNET,
                    "--size",
                    "native",
                    "--backend",
                    "cpu",
                    "--roi-at",
                    "170,45",
                    "--roi-radius",
                    "60",
                    "--p-min",
                    "0.1",
                    "--screenshot-after",
                    "4",
                    "--save-dir",
                    s(&dir),
                ]),
            )],
        );
        ok(&o);
        let err = String::from_utf8_lossy(&o.stderr);
        for (rank, columns) in [(1, [3, 4]), (2, [5, 6])] {
            let got: Vec<String> = files(&dir.join(format!("rank{rank}-tiles")))
                .into_iter()
                .map(|f| f.0)
                .collect();
            let want: Vec<String> = columns
                .iter()
                .flat_map(|c| (0..5).map(move |r| format!("c{c}r{r}.png")))
                .collect();
            assert_eq!(got, want, "rank {rank}: {err}");
            let mut colours = Vec::new();
            for name in &want {
                let tile = image::open(dir.join(format!("rank{rank}-tiles/{name}")))
                    .unwrap()
                    .to_rgb8();
                assert_eq!(tile.dimensions(), (48, 27), "the tile's own resolution");
                colours.extend(tile.pixels().map(|p| p.0));
            }
            colours.sort_unstable();
            colours.dedup();
            if rank == 1 {
                assert!(colours.len() > 20, "rank 1 shows the box: {colours:?}");
            } else {
                // Beside the box: the white environment alone.
                assert_eq!(colours, [[255; 3]], "rank 2");
            }
        }
        assert!(!dir.join("rank0-tiles").exists(), "rank 0 is the console");
    }

    /// `view --cluster` on 3 ranks under Xvfb at 64×26, the mouse ROI fixed, closing after `n`
    /// iterations, with `more` flags (the backend among them).
    fn view_job(dir: &Path, n: u32, more: &[&str]) -> (Output, Duration) {
        let t0 = Instant::now();
        let o = mpirun_in(
            &["xvfb-run", "-a", "-s", "-screen 0 1280x700x24"],
            &[(
                3,
                &exe(),
                with(
                    strings(&[
                        "view",
                        "--cluster",
                        "--size",
                        "64,26",
                        "--roi-at",
                        "32,13",
                        "--roi-radius",
                        "200",
                        "--screenshot-after",
                        &n.to_string(),
                        "--save-dir",
                        s(dir),
                    ]),
                    more,
                ),
            )],
        );
        (o, t0.elapsed())
    }

    /// The viewer's faults are loud too: a rank that stops answering is named on rank 0 within
    /// seconds, and one that ends ends the job, the window with it.
    #[test]
    fn a_viewer_rank_that_hangs_or_ends_ends_the_job_within_seconds() {
        for (name, fault, said) in [
            (
                "view-hang",
                "2:3:hang",
                "raygun: error: rank 0: cluster: rank 2 did not answer",
            ),
            (
                "view-exit",
                "1:3:exit",
                "rank 1: --cluster-fault: ending at iteration 3",
            ),
        ] {
            let dir = tmp_dir(name);
            let (o, took) = view_job(
                &dir,
                10_000,
                &[
                    "--backend",
                    "cpu",
                    "--cluster-timeout",
                    "2",
                    "--cluster-fault",
                    fault,
                ],
            );
            let e = stderr(&o);
            assert!(!o.status.success(), "{e}");
            assert!(e.contains(said), "{e}");
            assert!(took < Duration::from_secs(40), "took {took:?}: {e}");
        }
    }

    /// `args` with `--backend cpu` made `--backend gpu` (lavapipe here).
    fn on_gpu(args: Vec<String>) -> Vec<String> {
        let b = args.iter().position(|a| a == "--backend").unwrap();
        let mut args = args;
        args[b + 1] = "gpu".to_owned();
        args
    }

    /// Ranks that trace on their GPUs (the kernel's compact mode: samples back to the rank,
    /// then to their owners) write one GPU process's full frame byte for byte: the same kernel
    /// computes each sample, and its owner adds it as the GPU would.
    #[test]
    fn gpu_ranks_write_the_one_process_gpu_frame_byte_for_byte() {
        same_files_as_one_process("wall-gpu", |d| on_gpu(full_wall(d)), &[]);
    }

    /// A guided render on GPU ranks is one GPU process's files byte for byte on 1, 2 and 3
    /// ranks: its counts, its DGI (the ranks compute it on their GPUs as that process does) and
    /// its image (rank 0 filters it on its GPU).
    #[test]
    fn gpu_ranks_guided_renders_are_the_same_on_1_2_and_3_ranks() {
        let one = tmp_dir("guided-gpu-one");
        run_ok(&on_gpu(guided(&one)));
        let mut first: Option<Vec<(String, Vec<u8>)>> = None;
        for np in 1..=3 {
            let dir = tmp_dir(&format!("guided-gpu-{np}"));
            let o = mpirun(&[(np, &exe(), with(on_gpu(guided(&dir)), &["--cluster"]))]);
            ok(&o);
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(err.contains("rank(s), GPU "), "{err}");
            let got = files(&dir);
            let file = |f: &[(String, Vec<u8>)], name: &str| {
                f.iter().find(|(n, _)| n == name).unwrap().1.clone()
            };
            for name in ["img.counts.exr", "img.dgi.exr", "img.exr"] {
                assert!(
                    file(&got, name) == file(&files(&one), name),
                    "{np} ranks: {name}"
                );
            }
            match &first {
                None => first = Some(got),
                Some(want) => assert!(&got == want, "{np} ranks: other files than 1 rank's"),
            }
        }
    }

    /// A guided render through the wall camera whose eye follows the replay's tracked head:
    /// rank 0 applies the restart rule and sends the eyes it restarted at, so every rank
    /// restarts in the same frames as one process does.
    fn head_wall(dir: &Path) -> Vec<String> {
        strings(&[
            "render",
            "--scene",
            "builtin:cornell",
            "--camera",
            "wall",
            "--size",
            "62,25",
            "--max-depth",
            "2",
            "--guide",
            "tracking-replays/head-1-walk.dtrack.jsonl",
            // Ranks restart at a move: the one process does too, to be compared byte for byte.
            "--on-eye-move",
            "restart",
            "--iterations",
            "20",
            "--p-min",
            "0.2",
            "--backend",
            "cpu",
            "--quiet",
            "--out",
            s(&dir.join("img.exr")),
        ])
    }

    #[test]
    fn a_tracked_heads_restarts_match_too() {
        same_files_as_one_process("head", head_wall, &[]);
    }

    /// HORNET with 48×27-pixel panels: its 7 × 5 tiles, kilobytes to write rather than the
    /// native wall's 73.8 megapixels.
    const SMALL_HORNET: &str = "tests/data/displays/hornet-small.json";

    /// The guided render with its wall tiles, which every owner filters and writes itself.
    fn guided_tiles(dir: &Path) -> Vec<String> {
        with(
            guided(dir),
            &["--display", SMALL_HORNET, "--tiles", s(&dir.join("tiles"))],
        )
    }

    fn guided_tiles_exact(dir: &Path) -> Vec<String> {
        with(guided_tiles(dir), &["--filter", "exact", "--k-max", "10"])
    }

    fn full_wall_tiles(dir: &Path) -> Vec<String> {
        let mut args = with(full_wall(dir), &["--tiles", s(&dir.join("tiles"))]);
        let d = args.iter().position(|a| a == "--display").unwrap();
        args[d + 1] = SMALL_HORNET.to_owned();
        args
    }

    #[test]
    fn owners_write_their_own_tiles_the_one_process_tiles_byte_for_byte() {
        same_files_as_one_process("tiles", guided_tiles, &[]);
        same_files_as_one_process("tiles-exact", guided_tiles_exact, &[]);
        same_files_as_one_process("tiles-wall", full_wall_tiles, &[]);
        // Whole columns dealt over 3 ranks: 3, 2 and 2 of HORNET's 7, 5 tiles each.
        let dir = tmp_dir("tiles-who");
        let o = mpirun(&[(3, &exe(), with(guided_tiles(&dir), &["--cluster"]))]);
        ok(&o);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("the owners wrote 35 tile images")
                && err.contains("(rank 0: 15, rank 1: 10, rank 2: 10)"),
            "{err}"
        );
    }

    /// `args` without its `--out FILE`.
    fn without_out(args: Vec<String>) -> Vec<String> {
        let i = args.iter().position(|a| a == "--out").unwrap();
        args.into_iter()
            .enumerate()
            .filter(|(k, _)| *k != i && *k != i + 1)
            .map(|(_, a)| a)
            .collect()
    }

    /// With --tiles and no --out nothing needs the whole picture: rank 0 never assembles it,
    /// and the owners' tiles are still the one-process tiles (which one process writes without
    /// --out too, as EXR).
    #[test]
    fn tiles_alone_are_written_without_assembling_the_picture() {
        let one = tmp_dir("tiles-alone-one");
        run_ok(&guided_tiles(&one));
        let want: Vec<(String, Vec<u8>)> = files(&one.join("tiles"))
            .into_iter()
            .map(|(n, b)| (format!("tiles/{n}"), b))
            .collect();
        assert_eq!(want.len(), 35);
        let alone = tmp_dir("tiles-alone-process");
        run_ok(&without_out(guided_tiles(&alone)));
        assert!(files(&alone) == want);
        let dir = tmp_dir("tiles-alone-3");
        let o = mpirun(&[(
            3,
            &exe(),
            with(without_out(guided_tiles(&dir)), &["--cluster"]),
        )]);
        ok(&o);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("the whole picture was not assembled"), "{err}");
        assert!(err.contains("the owners wrote 35 tile images"), "{err}");
        // Only the tiles: no image, DGI or counts beside them.
        assert!(
            files(&dir) == files(&alone),
            "3 ranks: other files than one process's"
        );
        // Neither --out nor --tiles: nothing would be written.
        let o = raygun(&["render", "--scene", "builtin:cornell", "--spp", "1"]);
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("--out"), "{err}");
    }

    #[test]
    fn a_tile_owners_file_changes_who_accumulates_not_the_image() {
        let one = tmp_dir("owners-one");
        run_ok(&guided(&one));
        // Rows to ranks, against the default columns.
        let text: String = (0..7)
            .flat_map(|c| (0..5).map(move |r| format!("c{c}r{r} {}\n", r % 3)))
            .collect();
        let owners = tmp_file("rows.owners");
        std::fs::write(&owners, format!("# rows\n{text}")).unwrap();
        let dir = tmp_dir("owners-3");
        let o = mpirun(&[(
            3,
            &exe(),
            with(guided(&dir), &["--cluster", "--tile-owners", s(&owners)]),
        )]);
        ok(&o);
        assert!(files(&dir) == files(&one), "a tile map changed the files");
    }

    fn timed(apps: &[(usize, &Path, Vec<String>)]) -> (Output, Duration) {
        let t0 = Instant::now();
        let o = mpirun(apps);
        (o, t0.elapsed())
    }

    #[test]
    fn a_rank_that_stops_answering_is_named_on_rank_0_within_seconds() {
        let dir = tmp_dir("hang");
        let (o, took) = timed(&[(
            3,
            &exe(),
            with(
                guided(&dir),
                &[
                    "--cluster",
                    "--cluster-timeout",
                    "2",
                    "--cluster-fault",
                    "2:3:hang",
                ],
            ),
        )]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{e}");
        assert!(
            e.contains("raygun: error: rank 0: cluster: rank 2 did not answer"),
            "{e}"
        );
        assert!(took < Duration::from_secs(30), "took {took:?}: {e}");
    }

    #[test]
    fn a_rank_that_ends_ends_the_job_within_seconds() {
        let dir = tmp_dir("exit");
        let (o, took) = timed(&[(
            3,
            &exe(),
            with(
                guided(&dir),
                &[
                    "--cluster",
                    "--cluster-timeout",
                    "2",
                    "--cluster-fault",
                    "1:2:exit",
                ],
            ),
        )]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{e}");
        assert!(e.contains("rank 1"), "{e}");
        assert!(took < Duration::from_secs(30), "took {took:?}: {e}");
        assert!(
            !dir.join("img.exr").exists(),
            "no output after a failed job"
        );
    }

    #[test]
    fn ranks_that_disagree_are_stopped_before_any_work_naming_the_rank() {
        let dir = tmp_dir("mismatch");
        // A pose guide (it hits both displays below).
        let base: Vec<String> = guided(&dir)
            .into_iter()
            .map(|a| {
                if a.ends_with(".jsonl") {
                    "pose:0,0,1:0,0,-1:30".to_owned()
                } else {
                    a
                }
            })
            .collect();
        let base = with(base, &["--cluster"]);
        // Another display model on rank 1.
        let o = mpirun(&[
            (1, &exe(), base.clone()),
            (
                1,
                &exe(),
                with(base.clone(), &["--display", "desktop-27in-4k"]),
            ),
        ]);
        let e = fails_with(&o, &["rank 1's display model differs from rank 0's"]);
        assert!(e.contains("desktop-27in-4k"), "{e}");
        // Another tile map on rank 2.
        let all: String = (0..7)
            .flat_map(|c| (0..5).map(move |r| format!("c{c}r{r} {}\n", c % 3)))
            .collect();
        let other = tmp_file("other.owners");
        std::fs::write(&other, all.replace("c6r4 0", "c6r4 1")).unwrap();
        let mine = tmp_file("mine.owners");
        std::fs::write(&mine, &all).unwrap();
        let o = mpirun(&[
            (2, &exe(), with(base.clone(), &["--tile-owners", s(&mine)])),
            (1, &exe(), with(base.clone(), &["--tile-owners", s(&other)])),
        ]);
        fails_with(
            &o,
            &["rank 2's tile map differs from rank 0's: c6r4=1 on rank 2, c6r4=0 on rank 0"],
        );
        // Rank 1 on the CPU twins, rank 0 on its GPU: each would be right, together they
        // would equal no one process.
        let o = mpirun(&[(1, &exe(), on_gpu(base.clone())), (1, &exe(), base.clone())]);
        let e = fails_with(&o, &["rank 1's trace backend differs from rank 0's"]);
        assert!(e.contains("the CPU twins") && e.contains("GPU "), "{e}");
        // Another binary on rank 1 (the same program with a byte appended).
        let copy = tmp_file("raygun-copy");
        let mut bytes = std::fs::read(exe()).unwrap();
        bytes.push(0);
        std::fs::write(&copy, bytes).unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&copy, std::fs::Permissions::from_mode(0o755)).unwrap();
        }
        let o = mpirun(&[(1, &exe(), base.clone()), (1, &copy, base.clone())]);
        fails_with(&o, &["rank 1's binary differs from rank 0's"]);
        // A rank that cannot start says why through rank 0.
        let o = mpirun(&[
            (1, &exe(), base.clone()),
            (
                1,
                &exe(),
                with(base, &["--tile-owners", "/nonexistent/owners"]),
            ),
        ]);
        fails_with(&o, &["rank 1 could not start", "/nonexistent/owners"]);
        assert!(!dir.join("img.exr").exists());
    }

    #[test]
    fn a_bad_tile_owners_file_is_rejected_naming_file_and_line() {
        let bad = tmp_file("bad.owners");
        std::fs::write(&bad, "# owners\nc0r0 0\nc0r1 five\n").unwrap();
        let dir = tmp_dir("bad-owners");
        let o = mpirun(&[(
            2,
            &exe(),
            with(guided(&dir), &["--cluster", "--tile-owners", s(&bad)]),
        )]);
        fails_with(&o, &["bad.owners:3: rank \"five\""]);
    }

    #[test]
    fn the_cluster_benchmark_reports_every_rank_and_counts_bytes_consistently() {
        let out = tmp_file("bench.json");
        let o = mpirun(&[(
            2,
            &exe(),
            strings(&[
                "bench",
                "guided",
                "--cluster",
                "--scene",
                "builtin:cornell",
                "--size",
                "96,40",
                "--fov",
                "10,60",
                "--iterations",
                "2",
                "--model-size",
                "96,40",
                "--model-ranks",
                "3",
                "--json",
                "--out",
                s(&out),
            ]),
        )]);
        ok(&o);
        let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
        let scaling = r["scaling"].as_array().unwrap();
        assert_eq!(scaling.len(), 2);
        for row in scaling {
            let per_rank = row["per_rank"].as_array().unwrap();
            assert_eq!(per_rank.len(), 2);
            // Every scheduled sample was traced by exactly one rank.
            let traced: f64 = per_rank
                .iter()
                .map(|p| p["samples_traced_per_iteration"].as_f64().unwrap())
                .sum();
            assert_eq!(traced, row["samples_per_iteration"].as_f64().unwrap());
            // What one rank sent the other received.
            assert_eq!(
                per_rank[0]["bytes_sent_per_iteration"],
                per_rank[1]["bytes_received_per_iteration"]
            );
            // The same for the owners' pictures; only rank 0 assembles the whole one.
            assert_eq!(
                per_rank[0]["tile_pictures_bytes_sent"],
                per_rank[1]["tile_pictures_bytes_received"]
            );
            assert!(
                per_rank[0]["tile_pictures_bytes_received"]
                    .as_u64()
                    .unwrap()
                    > 0
            );
            assert!(per_rank[0]["ms_gather_and_filter"].as_f64().unwrap() > 0.0);
            assert_eq!(per_rank[1]["ms_gather_and_filter"], 0.0);
            // A picture this small is the console's whole: every pixel rank 1 owns, 20 bytes.
            assert_eq!(per_rank[0]["console_every"], 1);
            assert!(per_rank[0]["ms_console_picture"].as_f64().unwrap() > 0.0);
            assert!(per_rank[0]["console_bytes_received"].as_u64().unwrap() > 0);
            assert_eq!(per_rank[1]["console_bytes_received"], 0);
        }
        let exchange = r["exchange"].as_array().unwrap();
        assert_eq!(exchange.len(), 2 * 2 * 3, "maps × FOVs × rank counts");
        for e in exchange {
            let one = e["ranks"] == 1;
            assert_eq!(e["bytes_sent_max"] == 0, one, "{e}");
            assert_eq!(e["margin_received_max"] == 0, one, "{e}");
            assert_eq!(e["gather_received"] == 0, one, "{e}");
            assert_eq!(e["console_every"], 1, "{e}");
            assert_eq!(e["console_received"], e["gather_received"], "{e}");
        }
    }

    #[test]
    fn a_stop_on_the_rois_progress_is_measured_from_the_owners() {
        // A fixed ROI until every pixel in it has two samples (measured every half second),
        // on 3 ranks; the ROI summary in the closing message.
        let dir = tmp_dir("until");
        let mut args: Vec<String> = guided(&dir)
            .into_iter()
            .map(|a| match a.as_str() {
                "6" => "1000000".to_owned(),
                _ if a.ends_with(".jsonl") => "pose:0,0,1:0,0,-1:30".to_owned(),
                _ => a,
            })
            .collect();
        args.extend(strings(&["--until", "roi-spp:2", "--cluster"]));
        let o = mpirun(&[(3, &exe(), args)]);
        ok(&o);
        let e = stderr(&o);
        assert!(e.contains("roi-spp:2 reached"), "{e}");
        assert!(e.contains("fewest samples"), "{e}");
    }
}
