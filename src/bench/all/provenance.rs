//! Where a report's figures come from: the command, the commit (and whether the tree was
//! dirty), the date, the CPU and the adapter, and whether the adapter is a datacenter GPU.

use serde::Serialize;

use crate::gpu::Backend;

/// Who ran it where, and how to run it again.
#[derive(Clone, Debug, Serialize)]
pub struct Header {
    /// The command line, shell-quoted.
    pub command: String,
    /// The backend in words (adapter and API, or the CPU twins and their threads).
    pub device: String,
    /// The GPU adapter, when the backend is a GPU.
    pub adapter: Option<String>,
    /// Processor model and the threads the CPU work ran on.
    pub cpu: String,
    pub commit: String,
    /// Whether the working tree differed from the commit (`git status --porcelain`).
    pub dirty: bool,
    /// "release" or "debug" (debug builds are several times slower on the CPU).
    pub profile: String,
    /// UTC, YYYY-MM-DD.
    pub date: String,
    pub scene: String,
    pub display: String,
}

/// `args` as one shell command line (single quotes where a word needs them).
#[must_use]
pub fn shell_join(args: impl IntoIterator<Item = String>) -> String {
    args.into_iter()
        .map(|a| {
            let plain = !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_./,:=@+".contains(c));
            if plain {
                a
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

fn git_dirty() -> bool {
    std::process::Command::new("git")
        .args(["status", "--porcelain", "--untracked-files=no"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .is_some_and(|o| !o.stdout.is_empty())
}

impl Header {
    /// The header of a run on `backend` now, from this process's command line.
    #[must_use]
    pub fn now(backend: &Backend, scene: &str, display: &str) -> Self {
        Self {
            command: shell_join(std::env::args()),
            device: crate::bench::device(backend),
            adapter: backend.adapter(),
            cpu: crate::bench::cpu_description(),
            commit: commit(),
            dirty: git_dirty(),
            profile: if cfg!(debug_assertions) {
                "debug"
            } else {
                "release"
            }
            .into(),
            date: utc_date(),
            scene: scene.to_string(),
            display: display.to_string(),
        }
    }
}

/// The commit of the working directory (`git rev-parse HEAD`), or "unknown".
#[must_use]
pub fn commit() -> String {
    std::process::Command::new("git")
        .args(["rev-parse", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".into())
}

/// Today's UTC date as YYYY-MM-DD (civil-from-days, proleptic Gregorian).
#[must_use]
pub fn utc_date() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let z = (secs / 86_400) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

/// Adapter names of datacenter GPUs (the targets' class of device).
const DATACENTER_GPUS: [&str; 12] = [
    "H100", "H200", "H800", "GH200", "A100", "A800", "B100", "B200", "GB200", "L40", "MI300",
    "MI250",
];

/// The adapter's name when the backend is a datacenter GPU.
#[must_use]
pub fn datacenter_gpu(backend: &Backend) -> Option<String> {
    match backend {
        Backend::Gpu(ctx)
            if ctx.info.device_type != wgpu::DeviceType::Cpu
                && DATACENTER_GPUS.iter().any(|g| ctx.info.name.contains(g)) =>
        {
            Some(ctx.info.name.clone())
        }
        _ => None,
    }
}
