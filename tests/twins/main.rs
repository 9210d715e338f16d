//! Every GPU kernel against its CPU twin, one file per stage (lavapipe in CI: small images).
//!
//! Each stage's file states its tolerance by name, with the reason it is what it is:
//! * `roi` — the DGI: f32 on the GPU against the f64 twin, bounded per metric by the f32
//!   solver's error ([`raygun::roi::ellipse::F32_DISTANCE_BOUND`] and the kernel's own bounds);
//! * `schedule` — exact: the same pixels, the same count, each block's run in the twin's order
//!   (the selection is one integer hash and one f32 comparison on both sides);
//! * `trace` — statistical: the same image in distribution with different seeds (a Welch test
//!   per block), and the same samples to rounding with the same seed;
//! * `filter` — f32 kernels against the f64 twins, relative to the image's scale;
//! * `output` — exact: the display kernel's 8-bit sRGB bytes are the CPU table's, its ROI
//!   outline the twin's pixels; the ROI's statistics: totals exact, medians within
//!   `output::gpu::SE_TOLERANCE`.

#[path = "../support/gltf_scenes.rs"]
mod gltf_scenes;
#[path = "../support/render.rs"]
mod render;
#[path = "../support/roi_stats.rs"]
mod roi_stats;
#[path = "../support/scenes.rs"]
mod scenes;

mod filter;
mod output;
mod roi;
mod schedule;
mod trace;
