//! Images that explain a render: the ROI outline, the sample-count heat map, the noise map and
//! the noise contrast between ROI and periphery.

/// The ROI outline, painted by the display kernel's twin (`output::srgb8`).
pub use crate::output::srgb8::{OUTLINE, roi_outline};
/// The statistics the window shows, defined with the ROI's statistics (the output stage's, so
/// that the GPU measures the same): re-exported where the viewer has always had them.
pub use crate::output::stats::{
    NoiseContrast, NoiseRegions, median_finite, noise_image, roi_samples,
};

/// Samples per pixel as RGBA: black (0) through red and yellow to white (the most).
#[must_use]
pub fn heat_map(counts: &[u32]) -> Vec<u8> {
    let max = counts.iter().copied().max().unwrap_or(0).max(1) as f32;
    counts
        .iter()
        .flat_map(|&c| {
            let t = c as f32 / max * 3.0;
            let ch = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
            [ch(t), ch(t - 1.0), ch(t - 2.0), 255]
        })
        .collect()
}

/// Undefined noise (fewer than two samples) in the noise overlay: dark blue.
pub const NOISE_UNDEFINED: [u8; 4] = [0, 0, 110, 255];

/// The ratio of standard errors the guide predicts between the ROI (sampled every iteration)
/// and the periphery (sampled with probability p_min): SE ∝ 1/√n and n_roi / n_periphery =
/// 1 / p_min, so √p_min for pixels whose samples spread alike.
#[must_use]
pub fn predicted_noise_ratio(p_min: f32) -> f32 {
    p_min.sqrt()
}

/// The noise overlay: SE as grey scaled by its 99th percentile, undefined pixels
/// [`NOISE_UNDEFINED`].
#[must_use]
pub fn noise_map(noise: &[f32]) -> Vec<u8> {
    let mut finite: Vec<f32> = noise.iter().copied().filter(|v| v.is_finite()).collect();
    let rank = (finite.len().saturating_sub(1) * 99) / 100;
    let top = if finite.is_empty() {
        None
    } else {
        Some(*finite.select_nth_unstable_by(rank, f32::total_cmp).1)
    }
    .filter(|v| *v > 0.0)
    .unwrap_or(1.0);
    noise
        .iter()
        .flat_map(|&v| {
            if v.is_finite() {
                let g = crate::output::unit_to_u8((v / top).clamp(0.0, 1.0));
                [g, g, g, 255]
            } else {
                NOISE_UNDEFINED
            }
        })
        .collect()
}
