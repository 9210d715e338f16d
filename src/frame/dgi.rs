//! The DGI of an ROI (DESIGN.md §5) as a renderer installs it: the job for the DGI kernel, and
//! the CPU twin's values, whole or in the bands a rank of a job computes.

use super::{FrameError, GuideConfig};
use crate::roi::dgi::{DgiParams, Guide, Roi, Surface, compute_cpu, roi_radius_m};

/// The DGI job of `roi` for a `size` image on `surface` (pitch `pitch_m` metres per canvas
/// pixel): the guide and the parameters with the falloff `config` gives that ROI's radius.
pub fn prepare_dgi(
    surface: &Surface,
    pitch_m: f64,
    config: &GuideConfig,
    roi: &Roi,
    [width, height]: [u32; 2],
) -> Result<(Guide, DgiParams), FrameError> {
    let guide = Guide::new(surface, roi, config.metric)?;
    let length = config
        .falloff
        .length_px(roi_radius_m(surface, roi), pitch_m);
    Ok((
        guide,
        DgiParams {
            width,
            height,
            falloff_px: Some(length),
        },
    ))
}

/// The DGI of `roi` (`None`: 0 everywhere) computed by the CPU twin: what a CPU renderer's
/// [`Render::set_roi`](super::Render::set_roi) installs, value for value.
pub fn dgi_cpu(
    surface: &Surface,
    pitch_m: f64,
    config: &GuideConfig,
    roi: Option<&Roi>,
    size: [u32; 2],
) -> Result<Vec<f32>, FrameError> {
    Ok(match roi {
        Some(r) => {
            let (guide, params) = prepare_dgi(surface, pitch_m, config, r, size)?;
            compute_cpu(surface, &guide, &params)
        }
        None => vec![0.0; size[0] as usize * size[1] as usize],
    })
}

/// [`dgi_cpu`] of the bands of [`crate::roi::dgi::BLOCK`] rows `k`, `k + n`, … alone (0
/// elsewhere), each bit for bit the whole image's: the share of rank `k` of `n` when the ranks
/// split the DGI.
pub fn dgi_cpu_bands(
    surface: &Surface,
    pitch_m: f64,
    config: &GuideConfig,
    roi: Option<&Roi>,
    size: [u32; 2],
    (k, n): (usize, usize),
) -> Result<Vec<f32>, FrameError> {
    Ok(match roi {
        Some(r) => {
            let (guide, params) = prepare_dgi(surface, pitch_m, config, r, size)?;
            crate::roi::dgi::compute_cpu_bands(surface, &guide, &params, k, n)
        }
        None => vec![0.0; size[0] as usize * size[1] as usize],
    })
}
