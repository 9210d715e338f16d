//! Running the `raygun` binary from tests, and a fresh folder per test for its files.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository root (where the shipped models and replays are).
pub const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// `raygun ARGS` in the repository root, with a valid XDG_RUNTIME_DIR.
pub fn raygun(args: &[&str]) -> Output {
    raygun_in(Path::new(ROOT), args)
}

/// `raygun ARGS` in `dir`.
pub fn raygun_in(dir: &Path, args: &[&str]) -> Output {
    command(dir, args).output().expect("the raygun binary runs")
}

/// The command, for tests that need to change it further (environment, stdin, spawn).
pub fn command(dir: &Path, args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_raygun"));
    c.args(args)
        .current_dir(dir)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir());
    c
}

/// A new, empty folder for one test (`name` must be unique among the tests of a binary),
/// removed when the test passes; a failing test's folder stays for a look at its files.
pub fn tmp_dir(name: &str) -> TmpDir {
    let d = std::env::temp_dir().join(format!("raygun-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TmpDir(d)
}

/// A test's folder (see [`tmp_dir`]); it is a `Path` wherever one is wanted.
pub struct TmpDir(PathBuf);

impl std::ops::Deref for TmpDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TmpDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for TmpDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for TmpDir {
    fn drop(&mut self) {
        // Wall tiles at a display's native size are hundreds of megabytes: a passing test's
        // files must not pile up in the temporary folder from run to run.
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A path for a file named `name` in this test binary's folder (created; names must be unique
/// among the tests of a binary). The folder is removed when the binary exits with no test
/// having failed; a failure leaves it for a look at its files.
pub fn tmp_file(name: &str) -> PathBuf {
    static CLEAN_AT_EXIT: std::sync::Once = std::sync::Once::new();
    CLEAN_AT_EXIT.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            A_TEST_FAILED.store(true, std::sync::atomic::Ordering::SeqCst);
            previous(info);
        }));
        // SAFETY: registers a plain function, which only removes a folder, to run at exit.
        unsafe { libc::atexit(remove_tmp_files) };
    });
    let d = tmp_files_dir();
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// [`tmp_file`]'s folder.
fn tmp_files_dir() -> PathBuf {
    std::env::temp_dir().join(format!("raygun-test-{}", std::process::id()))
}

/// Set by the panic hook [`tmp_file`] installs: some test of this binary failed.
static A_TEST_FAILED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

extern "C" fn remove_tmp_files() {
    if !A_TEST_FAILED.load(std::sync::atomic::Ordering::SeqCst) {
        let _ = std::fs::remove_dir_all(tmp_files_dir());
    }
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Asserts success, showing standard error otherwise.
pub fn ok(o: &Output) {
    assert!(o.status.success(), "{}", stderr(o));
}

/// Asserts a clean failure (exit 1, an `error:` line, no panic or abort) whose message
/// contains every one of `needles`; returns standard error.
pub fn fails_with(o: &Output, needles: &[&str]) -> String {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "exit status {:?}: {e}", o.status);
    assert!(e.contains("error:"), "{e}");
    assert!(
        !e.contains("panicked") && !e.contains("RUST_BACKTRACE"),
        "{e}"
    );
    for n in needles {
        assert!(e.contains(n), "missing {n:?} in: {e}");
    }
    e
}

/// The path as a `&str` (test paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
