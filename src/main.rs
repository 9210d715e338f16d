//! The `raygun` command. Arguments are parsed into each command's typed configuration before any
//! work starts; errors are printed once, with their cause chain.

use clap::{Parser, Subcommand};

use raygun::cli;

/// raygun — guided high-quality rendering on display walls.
#[derive(Parser)]
#[command(version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The whole pipeline on embedded defaults: the Cornell box on the HORNET wall, guided by a
    /// bundled FlyStick session, in the viewer (headless without a display: writes images and
    /// a report).
    Demo(cli::demo::DemoArgs),
    /// Path-trace a glTF scene progressively and write EXR (linear) and/or PNG (sRGB).
    ///
    /// The one-time work before the first frame — the scene's load, the BVH's build, the
    /// upload (on a GPU: the kernels, the scene and the first buffers) — is reported on a line
    /// of its own, `one-time work (not in the sampling time): scene load S s, BVH build S s,
    /// upload S s`; the closing line's time and its ms per megasample, and the progress line's
    /// time left, count from the first frame and leave it out.
    Render(cli::render::RenderArgs),
    /// An interactive window showing the guided render as it converges (mouse, replay or live
    /// DTrack, OSC or VRPN steering).
    View(cli::view::ViewArgs),
    /// Write the distance-guide image for a ray-gun pose or a mouse ROI.
    Dgi(cli::dgi::DgiArgs),
    /// Where a ray meets the display, as one JSON object.
    Pick(cli::display::PickArgs),
    /// Display-model tools.
    #[command(subcommand)]
    Display(DisplayCommand),
    /// Replay a tracking session: one JSON line per ROI change.
    Replay(cli::tracking::ReplayArgs),
    /// Record live DTrack, OSC or VRPN traffic into a replay file (Ctrl-C, SIGTERM or SIGHUP
    /// stops and saves).
    Record(cli::tracking::RecordArgs),
    /// Solve the tracker→room calibration from presses at known wall points; writes the file
    /// `view`, `record`, `replay` and `render --guide` take.
    Calibrate(cli::calibrate::CalibrateArgs),
    /// Regenerate the synthetic FlyStick and mouse sessions in `tracking-replays/`.
    SynthReplays(cli::tracking::SynthArgs),
    /// Closest points on ellipses: `a,b,x,y` lines on stdin → `distance,cx,cy` on stdout.
    ///
    /// The ellipse is (x/a)² + (y/b)² = 1, centred at the origin. `distance` is the distance to
    /// the ellipse *curve*, for a point inside as for one outside (not 0 inside: that is the
    /// filled ellipse's distance), and (cx, cy) the closest point on the curve. Where two
    /// points are equally close (inside, on the major axis between the centres of curvature of
    /// the two vertices) the one on the positive side of the minor axis is printed. A bad line
    /// prints `nan,nan,nan` and an error naming the line and field; the exit status is 1 then.
    #[command(verbatim_doc_comment)]
    EllipseDistance,
    /// Scenes: write the generated paper scenes (.glb), summarise a scene file.
    #[command(subcommand)]
    Scene(cli::scene::SceneCommand),
    /// Benchmarks: speed and error, with the hardware they ran on.
    #[command(subcommand)]
    Bench(cli::bench::BenchCommand),
}

#[derive(Subcommand)]
enum DisplayCommand {
    /// Print the model's explicit form (generators expanded), as the loader sees it.
    Expand(cli::display::ExpandArgs),
    /// Write the output map: which tile each desktop shows where (docs/screens.md).
    Outputs(cli::display::OutputsArgs),
}

fn main() {
    // .cargo/config.toml builds for AVX2 and FMA (and the bit instructions that come with
    // them) on x86-64; say so instead of dying on an illegal instruction.
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        let missing: Vec<&str> = [
            ("avx2", has!("avx2")),
            ("fma", has!("fma")),
            ("bmi1", has!("bmi1")),
            ("bmi2", has!("bmi2")),
            ("lzcnt", has!("lzcnt")),
            ("popcnt", has!("popcnt")),
        ]
        .into_iter()
        .filter_map(|(name, present)| (!present).then_some(name))
        .collect();
        if !missing.is_empty() {
            eprintln!(
                "raygun: this build needs a CPU with AVX2, FMA, BMI1, BMI2, LZCNT and POPCNT \
                 (see .cargo/config.toml); this one lacks {}: rebuild without that file's \
                 target-feature flags for this CPU",
                missing.join(", ")
            );
            std::process::exit(1);
        }
    }
    let cli = Cli::parse();
    // Which walks the CPU twin takes is read once, deep in the traversal: refuse a bad
    // choice here, before any work.
    if let Err(e) = raygun::trace::bvh::CpuPackets::from_env() {
        eprintln!("raygun: error: {e}");
        std::process::exit(1);
    }
    let runtime_dir = quiet_xdg_runtime_dir();
    let result = match &cli.command {
        Command::Demo(args) => cli::demo::run(args),
        Command::Render(args) => cli::render::run(args),
        Command::View(args) => cli::view::run(args),
        Command::Dgi(args) => cli::dgi::run(args),
        Command::Pick(args) => cli::display::pick(args).and_then(|v| cli::print_out(&v)),
        Command::Display(DisplayCommand::Expand(args)) => {
            cli::display::expand(args).and_then(|text| cli::print_out(&text))
        }
        Command::Display(DisplayCommand::Outputs(args)) => {
            cli::display::outputs(args).and_then(|text| cli::print_out(&text))
        }
        Command::Replay(args) => replay(args),
        Command::Record(args) => record(args),
        Command::Calibrate(args) => {
            with_stop_signals(|stop| cli::calibrate::run(args, stop)).map(|_| ())
        }
        Command::SynthReplays(args) => cli::tracking::run_synth(args)
            .and_then(|files| files.iter().try_for_each(|f| cli::print_out(&f.display()))),
        Command::EllipseDistance => ellipse_distance(),
        Command::Scene(cmd) => cli::scene::run(cmd).and_then(|text| cli::print_out(&text)),
        Command::Bench(cmd) => cli::bench::run(cmd),
    };
    if let Err(e) = result {
        if cli::is_broken_pipe(&e) {
            drop(runtime_dir);
            return;
        }
        eprintln!("raygun: error: {}", cli::error_chain(&e));
        drop(runtime_dir);
        std::process::exit(1);
    }
}

/// Mesa's Vulkan and GL drivers print "XDG_RUNTIME_DIR is invalid or not set" while raygun
/// looks for a GPU, which is not the user's error and not raygun's business: where the variable
/// is unset or names no folder, point it at a private temporary one (a desktop session always
/// sets it; a service or an ssh session often does not). The folder is removed when the
/// returned guard is dropped (before, every run left an empty one in the temporary folder).
fn quiet_xdg_runtime_dir() -> Option<RuntimeDir> {
    let ok = std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| std::path::Path::new(&d).is_dir());
    if ok {
        return None;
    }
    let dir = std::env::temp_dir().join(format!("raygun-runtime-{}", std::process::id()));
    if std::fs::create_dir_all(&dir).is_ok() {
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700));
        }
        // SAFETY: called in `main` before anything else runs (the command line is parsed, no
        // thread exists) that could read the environment concurrently.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
        return Some(RuntimeDir(dir));
    }
    None
}

/// The private runtime folder `quiet_xdg_runtime_dir` made; removed with what the drivers put
/// in it when dropped.
struct RuntimeDir(std::path::PathBuf);

impl Drop for RuntimeDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs `work` with a flag that Ctrl-C (SIGINT), SIGTERM (systemd, `timeout`) and SIGHUP (a
/// closed terminal) set, so that a recording or a calibration ends cleanly however it is
/// stopped.
fn with_stop_signals<T>(
    work: impl FnOnce(&std::sync::atomic::AtomicBool) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))?;
    work(&stop)
}

/// Streams stdin to stdout; exits 1 after the whole stream if any line was bad.
fn ellipse_distance() -> anyhow::Result<()> {
    let stats = cli::ellipse_distance::run(
        std::io::stdin().lock(),
        std::io::BufWriter::new(std::io::stdout().lock()),
        std::io::stderr().lock(),
    )?;
    if stats.errors > 0 {
        anyhow::bail!(
            "{} of {} {} rejected",
            stats.errors,
            raygun::messages::count(stats.queries, "query line"),
            if stats.errors == 1 { "was" } else { "were" }
        );
    }
    Ok(())
}

fn replay(args: &cli::tracking::ReplayArgs) -> anyhow::Result<()> {
    let summary =
        cli::tracking::run_replay(args, std::io::BufWriter::new(std::io::stdout().lock()))?;
    eprintln!("raygun replay: {}", summary.line());
    let problems = &summary.problems;
    if problems.total() > 0 {
        let kinds: Vec<String> = problems
            .counts()
            .iter()
            .map(|(kind, n)| format!("{n} × {kind}"))
            .collect();
        eprintln!("raygun replay: input problems: {}", kinds.join(", "));
    }
    Ok(())
}

/// Records until stopped (Ctrl-C, SIGTERM, SIGHUP) or `--seconds`; the stop flag lets the
/// writer flush everything, and the command exits 0 with a complete file.
fn record(args: &cli::tracking::RecordArgs) -> anyhow::Result<()> {
    let n = with_stop_signals(|stop| cli::tracking::run_record(args, stop))?;
    eprintln!(
        "raygun record: {} written to {}",
        raygun::messages::count(usize::try_from(n).unwrap_or(usize::MAX), "record"),
        args.out.display()
    );
    Ok(())
}
