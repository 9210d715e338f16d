//! The viewer smoke test's settings (tests/viewer/viewer_xvfb.rs), shared with the ViewerCore test that
//! shows its noise claim fails for a uniform sampler (tests/viewer/viewer.rs).

/// Image size: small, for lavapipe in CI (the test renders with `--backend gpu`).
pub const SIZE: [u32; 2] = [124, 50];
/// The mouse ROI: centre (image pixels) and radius (canvas pixels; with the default falloff the
/// DGI reaches 1, the periphery, inside the Cornell box).
pub const ROI_AT: [f64; 2] = [62.0, 25.0];
pub const ROI_RADIUS: f64 = 600.0;
/// The periphery is sampled with probability 1/16: 16× fewer samples than the ROI.
pub const P_MIN: f32 = 1.0 / 16.0;
/// Iterations before the screenshot: the periphery then has 4 samples on average, enough for a
/// standard error in most of its pixels (it needs two).
pub const ITERATIONS: u32 = 64;
