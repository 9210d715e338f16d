//! `tools/pgo-build.sh`: the profile-guided build's training set must keep running as the
//! command line and the scenes change (a failed training run would stop the build after its
//! first release build, eight minutes in). `--train BIN` runs exactly that set with the test
//! build; the two builds themselves are measured, not tested (BENCHMARKS.md, *Builds*).

use std::process::{Command, Output};

fn script(args: &[&str]) -> Output {
    script_in(env!("CARGO_MANIFEST_DIR"), args)
}

/// The script run from `dir`.
fn script_in(dir: &str, args: &[&str]) -> Output {
    Command::new("bash")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tools/pgo-build.sh"))
        .args(args)
        .current_dir(dir)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn every_training_run_finishes_with_the_test_build() {
    let o = script(&["--train", env!("CARGO_BIN_EXE_raygun")]);
    let log = stderr(&o);
    assert!(o.status.success(), "{log}");
    assert!(log.contains("every training run finished"), "{log}");
    let runs: Vec<&str> = log.lines().filter(|l| l.starts_with("  raygun ")).collect();
    // Nine runs: eight scenes and cameras through `bench trace`, and `bench guided`.
    assert_eq!(runs.len(), 9, "{log}");
    for what in [
        "builtin:city-small",
        "envmap.glb",
        "glass.glb",
        "lights.glb",
        "--camera wall",
        "bench guided",
    ] {
        assert!(
            runs.iter().any(|r| r.contains(what)),
            "no run with {what}: {log}"
        );
    }
}

#[test]
fn a_failing_training_run_stops_the_script_and_names_the_run() {
    // `false` is executable and fails every run: the first one must stop the script.
    let o = script(&["--train", "/bin/false"]);
    let log = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{log}");
    assert!(
        log.contains("the training run failed: raygun bench trace")
            && log.contains("builtin:cornell-light"),
        "{log}"
    );
    assert_eq!(log.matches("  raygun ").count(), 1, "{log}");
}

#[test]
fn a_relative_binary_is_the_callers() {
    // Run from /bin, `./false` is /bin/false (found, and failing its first run), not a file
    // in the repository the script works from.
    let o = script_in("/bin", &["--train", "./false"]);
    let log = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{log}");
    assert!(log.contains("the training run failed"), "{log}");
}

#[test]
fn bad_arguments_are_refused_in_one_line() {
    for (args, says) in [
        (
            &["--train"][..],
            "--train needs one executable raygun binary",
        ),
        (
            &["--train", "/nonexistent/raygun"][..],
            "--train needs one executable",
        ),
        (&["--bogus"][..], "unknown option --bogus"),
        (
            &["tools"][..],
            "OUT is the binary's path, one file, not a folder",
        ),
        (&["a", "b"][..], "OUT is the binary's path"),
    ] {
        let o = script(args);
        let log = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {log}");
        assert!(log.contains(says), "{args:?}: {log}");
        assert_eq!(log.lines().count(), 1, "{args:?}: {log}");
    }
}
