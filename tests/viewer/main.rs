//! The viewer: its logic without a screen, and the real window under Xvfb.

mod denoise;
mod viewer;
mod viewer_xvfb;

// The helpers of tests/support/ that the files above use, each compiled once here.
#[path = "../support/walls.rs"]
mod walls;
#[path = "../support/xvfb_settings.rs"]
mod xvfb;
