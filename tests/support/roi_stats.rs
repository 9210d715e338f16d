//! The ROI's statistics measured on the GPU against the CPU twin's: the totals (pixels,
//! samples, fewest samples, noisy pixels) exactly, the medians within
//! `output::gpu::SE_TOLERANCE` relative (`RoiStats::matches`).

use raygun::output::gpu::SE_TOLERANCE;
use raygun::output::stats::RoiStats;

pub fn same(label: &str, cpu: &RoiStats, gpu: &RoiStats) {
    if let Err(e) = cpu.matches(gpu, SE_TOLERANCE) {
        panic!("{label}: {e}\nCPU {cpu:?}\nGPU {gpu:?}");
    }
}
