//! `bench denoise`'s crops: the ROI's edge and the periphery, each method side by side, as a PNG
//! ([`super`]).

use std::path::Path;

use glam::Vec3;

use super::{CROP_GAP, CROP_LABEL, CROP_SHOWN, CROP_SIDE, CropsInfo, DenoiseBenchError, METHODS};

/// The crops' side (picture pixels) and scale (PNG pixels a picture pixel) for `size`.
#[must_use]
pub fn crop_geometry([w, h]: [u32; 2]) -> (u32, u32) {
    let side = CROP_SIDE.min(w / 3).min(h / 2).max(1);
    (side, CROP_SHOWN.div_ceil(side).max(1))
}

/// The PNG's size for `size`: five columns and two rows of crops, a label row on top.
#[must_use]
pub fn crops_png_size(size: [u32; 2]) -> [u32; 2] {
    let (side, scale) = crop_geometry(size);
    let cell = side * scale;
    [
        5 * cell + 6 * CROP_GAP,
        CROP_LABEL + 2 * cell + 3 * CROP_GAP,
    ]
}

/// Top-left corners of the ROI-edge crop (centred on the ROI outline's leftmost pixel nearest
/// the middle row; the picture's centre without an outline) and the periphery crop (of the
/// picture's four corners and the middles of its left and right sides, the window farthest
/// from the ROI by mean DGI).
pub(super) fn crop_corners(dgi: &[f32], [w, h]: [u32; 2], side: u32) -> ([u32; 2], [u32; 2]) {
    let clamp = |c: [i64; 2]| {
        [
            (c[0] - i64::from(side / 2)).clamp(0, i64::from(w - side)) as u32,
            (c[1] - i64::from(side / 2)).clamp(0, i64::from(h - side)) as u32,
        ]
    };
    let outline = crate::output::srgb8::roi_outline(dgi, [w, h]);
    let edge = outline
        .iter()
        .map(|&p| (p as u32 % w, p as u32 / w))
        .min_by_key(|&(x, y)| (x, y.abs_diff(h / 2)))
        .map_or([i64::from(w / 2), i64::from(h / 2)], |(x, y)| {
            [i64::from(x), i64::from(y)]
        });
    let window_dgi = |[x0, y0]: [u32; 2]| {
        let mut s = 0f64;
        for y in y0..y0 + side {
            for x in x0..x0 + side {
                s += f64::from(dgi[(y * w + x) as usize]);
            }
        }
        s
    };
    let (r, b) = (w - side, h - side);
    let periphery = [[0, 0], [r, 0], [0, b], [r, b], [0, b / 2], [r, b / 2]]
        .into_iter()
        .max_by(|a, c| window_dgi(*a).total_cmp(&window_dgi(*c)))
        .expect("six candidates");
    (clamp(edge), periphery)
}

/// Writes the crops PNG: columns reference, off, filter, interactive, oidn (grey where OIDN
/// was not loaded), rows the ROI's edge and the periphery, each crop scaled up by whole pixels.
pub(super) fn write_crops(
    path: &Path,
    size: [u32; 2],
    reference: &[Vec3],
    images: &[Option<Vec<Vec3>>],
    dgi: &[f32],
    (fov, iterations): (f64, u32),
) -> Result<CropsInfo, DenoiseBenchError> {
    use plotters::prelude::*;
    let err = |reason: String| DenoiseBenchError::Crops {
        path: path.display().to_string(),
        reason,
    };
    let [w, _] = size;
    let (side, scale) = crop_geometry(size);
    let cell = side * scale;
    let [pw, ph] = crops_png_size(size);
    let (edge, periphery) = crop_corners(dgi, size, side);
    let mut columns: Vec<(String, Option<Vec<u8>>)> = vec![(
        "reference".into(),
        Some(crate::output::srgb8::display_rgb(reference, 0.0)),
    )];
    for (k, method) in METHODS.into_iter().enumerate() {
        let label = match &images[k] {
            Some(_) => method.to_owned(),
            None => format!("{method} (not loaded)"),
        };
        let bytes = images[k]
            .as_ref()
            .map(|i| crate::output::srgb8::display_rgb(i, 0.0));
        columns.push((label, bytes));
    }
    let mut png = vec![255u8; (pw * ph * 3) as usize];
    for (c, (_, bytes)) in columns.iter().enumerate() {
        let x0 = CROP_GAP + c as u32 * (cell + CROP_GAP);
        for (row, [cx, cy]) in [edge, periphery].into_iter().enumerate() {
            let y0 = CROP_LABEL + CROP_GAP + row as u32 * (cell + CROP_GAP);
            for y in 0..cell {
                for x in 0..cell {
                    let o = (((y0 + y) * pw + x0 + x) * 3) as usize;
                    let rgb = match bytes {
                        Some(b) => {
                            let s = (((cy + y / scale) * w + cx + x / scale) * 3) as usize;
                            [b[s], b[s + 1], b[s + 2]]
                        }
                        None => [128; 3],
                    };
                    png[o..o + 3].copy_from_slice(&rgb);
                }
            }
        }
    }
    crate::bench::font::register().map_err(|e| err(e.to_string()))?;
    {
        let root = BitMapBackend::with_buffer(&mut png, (pw, ph)).into_drawing_area();
        let font_px = (CROP_LABEL as f64 * 0.65)
            .min(f64::from(cell) / 7.0)
            .max(8.0);
        for (c, (label, _)) in columns.iter().enumerate() {
            let x0 = CROP_GAP + c as u32 * (cell + CROP_GAP);
            root.draw(&Text::new(
                label.clone(),
                (x0 as i32, 4),
                (crate::bench::font::FAMILY, font_px)
                    .into_font()
                    .color(&BLACK),
            ))
            .map_err(|e| err(e.to_string()))?;
        }
        root.present().map_err(|e| err(e.to_string()))?;
    }
    let img = image::RgbImage::from_raw(pw, ph, png).expect("sized above");
    crate::output::replace_with(path, |tmp| {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|e| err(e.to_string()))
    })?;
    Ok(CropsInfo {
        path: path.display().to_string(),
        width: pw,
        height: ph,
        side,
        scale,
        fov_deg: fov,
        iterations,
        roi_edge_at: edge,
        periphery_at: periphery,
        columns: columns.into_iter().map(|(l, _)| l).collect(),
    })
}
