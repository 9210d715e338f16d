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

/// The PNG's size for `size` and `columns` columns: two rows of crops, a label row on top.
#[must_use]
pub fn crops_png_size(size: [u32; 2], columns: u32) -> [u32; 2] {
    let (side, scale) = crop_geometry(size);
    let cell = side * scale;
    [
        columns * cell + (columns + 1) * CROP_GAP,
        CROP_LABEL + 2 * cell + 3 * CROP_GAP,
    ]
}

/// One column of the crops: its label and the picture (`None`: shown grey, "not loaded").
pub type CropColumn = (String, Option<Vec<Vec3>>);

/// The crops of `columns` (each a `size` picture; labelled) at the ROI's edge and in the
/// periphery, found from `dgi`, written as a PNG to `path`: what `bench denoise` and the demo
/// show side by side. Returns the geometry: `(side, scale, png size, edge, periphery)`.
pub fn write_crop_columns(
    path: &Path,
    size: [u32; 2],
    columns: &[CropColumn],
    dgi: &[f32],
) -> Result<CropsGeometry, DenoiseBenchError> {
    use plotters::prelude::*;
    let err = |reason: String| DenoiseBenchError::Crops {
        path: path.display().to_string(),
        reason,
    };
    let [w, _] = size;
    let (side, scale) = crop_geometry(size);
    let cell = side * scale;
    let [pw, ph] = crops_png_size(size, columns.len() as u32);
    let (edge, periphery) = crop_corners(dgi, size, side);
    let bytes: Vec<Option<Vec<u8>>> = columns
        .iter()
        .map(|(_, i)| {
            i.as_ref()
                .map(|i| crate::output::srgb8::display_rgb(i, 0.0))
        })
        .collect();
    let mut png = vec![255u8; (pw * ph * 3) as usize];
    for (c, bytes) in bytes.iter().enumerate() {
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
    Ok(CropsGeometry {
        side,
        scale,
        size: [pw, ph],
        roi_edge_at: edge,
        periphery_at: periphery,
    })
}

/// Where [`write_crop_columns`] took its crops and how it drew them.
#[derive(Clone, Copy, Debug)]
pub struct CropsGeometry {
    /// A crop's side in picture pixels, and PNG pixels a picture pixel.
    pub side: u32,
    pub scale: u32,
    /// The PNG's width and height.
    pub size: [u32; 2],
    /// Top-left corners of the ROI-edge and periphery crops (picture pixels).
    pub roi_edge_at: [u32; 2],
    pub periphery_at: [u32; 2],
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
    let mut columns: Vec<CropColumn> = vec![("reference".into(), Some(reference.to_vec()))];
    for (k, method) in METHODS.into_iter().enumerate() {
        let label = match &images[k] {
            Some(_) => method.to_owned(),
            None => format!("{method} (not loaded)"),
        };
        columns.push((label, images[k].clone()));
    }
    let g = write_crop_columns(path, size, &columns, dgi)?;
    Ok(CropsInfo {
        path: path.display().to_string(),
        width: g.size[0],
        height: g.size[1],
        side: g.side,
        scale: g.scale,
        fov_deg: fov,
        iterations,
        roi_edge_at: g.roi_edge_at,
        periphery_at: g.periphery_at,
        columns: columns.into_iter().map(|(l, _)| l).collect(),
    })
}
