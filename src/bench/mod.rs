//! Benchmarks (`raygun bench …`): speed and error, measured in the repository, reported with
//! the hardware they ran on. Never timed tests.

pub mod all;
pub mod cluster;
pub mod denoise;
pub mod dgi;
pub mod filter;
pub mod font;
pub mod guided;
pub mod motion;
pub mod native;
pub mod paper;
pub mod picture;
pub mod readback;
pub mod schedule;
pub mod solver;
pub mod solver_study;
pub mod trace;
pub mod tracking;

/// A `/proc/self/status` figure in KiB ("VmRSS:", the resident set; "VmHWM:", its peak), where
/// the system has one (Linux).
#[must_use]
pub fn proc_status_kib(key: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(key))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// The median (mean of the two middle values for an even count; NaN when empty).
#[must_use]
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// A benchmark's device line: the backend's ([`crate::gpu::Backend::describe`]), and for the
/// CPU twins how they walk their rays ([`crate::trace::bvh::CpuPackets`]).
#[must_use]
pub fn device(backend: &crate::gpu::Backend) -> String {
    match backend {
        crate::gpu::Backend::Gpu(_) => backend.describe(),
        crate::gpu::Backend::Cpu => format!(
            "{}, {}",
            backend.describe(),
            crate::trace::bvh::CpuPackets::current().describe()
        ),
    }
}

/// The CPU side of a benchmark's hardware line: "N threads (ARCH, how the CPU twin walks its
/// rays)".
#[must_use]
pub fn cpu_threads() -> String {
    format!(
        "{} threads ({}, {})",
        rayon::current_num_threads(),
        std::env::consts::ARCH,
        crate::trace::bvh::CpuPackets::current().describe()
    )
}

/// The CPU model (Linux: `model name` of /proc/cpuinfo) and [`cpu_threads`].
#[must_use]
pub fn cpu_description() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, m)| m.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown CPU".to_owned());
    format!("{model}, {}", cpu_threads())
}
