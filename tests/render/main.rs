//! Rendering on both backends: the path tracer, guided frames, the wall camera, the filter,
//! the schedule's statistics, bands, the moving eye's restart, the ROI's statistics, the shown
//! picture, and the peer renderer's references.

mod bands;
mod denoise;
mod eye_restart;
mod eye_reuse;
mod filter_fast;
mod filter_properties;
mod guided;
mod peers;
mod roi_stats;
mod schedule_statistics;
mod shown_picture;
mod trace;
mod wall_camera;

// The helpers of tests/support/ that the files above use, each compiled once here.
#[path = "../support/render.rs"]
mod render;
#[path = "../support/roi_stats.rs"]
mod roi_stats_support;
#[path = "../support/scenes.rs"]
mod scenes;
#[path = "../support/cli.rs"]
mod support;
#[path = "../support/walls.rs"]
mod walls;
