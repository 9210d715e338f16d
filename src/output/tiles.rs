//! Wall output: one image per display tile, cut from a rendered image that covers the canvas.
//!
//! The rendered image covers the canvas bounding rectangle, each axis scaled on its own
//! ([`DisplayModel::image_to_canvas`]). Tile pixel `(x, y)` shows the image pixel whose square
//! holds the tile pixel's centre on the canvas: **nearest-neighbour** resampling. When the image
//! is rendered at the canvas's own resolution ([`canvas_pixel_size`]) that is a plain cut: each
//! tile pixel is the one canvas pixel it covers. Image pixels behind bezels (and in gaps between
//! tiles) belong to no tile and are not shown.

use std::path::{Path, PathBuf};

use glam::{DVec2, Vec3};

use super::{Format, OutputError};
use crate::display::DisplayModel;

pub use crate::display::cut::{canvas_pixel_size, tile_axes};

/// For tile `tile`, the row-major index into an `image_size` image of the pixel each tile
/// pixel shows ([`tile_axes`]), row by row.
#[must_use]
pub fn tile_source_indices(model: &DisplayModel, tile: usize, image_size: [u32; 2]) -> Vec<usize> {
    let (xs, ys) = tile_axes(model, tile, image_size);
    let w = image_size[0] as usize;
    let mut out = Vec::with_capacity(xs.len() * ys.len());
    for &y in &ys {
        out.extend(xs.iter().map(|&x| y * w + x));
    }
    out
}

/// Cuts tile `tile`'s pixels from an `image_size` image covering the canvas.
#[must_use]
pub fn cut_tile<T: Copy>(
    model: &DisplayModel,
    tile: usize,
    image: &[T],
    image_size: [u32; 2],
) -> Vec<T> {
    tile_source_indices(model, tile, image_size)
        .into_iter()
        .map(|i| image[i])
        .collect()
}

/// The image as the wall shows it: pixels whose centre lies on no tile's active area (behind a
/// bezel, or in a gap) replaced by `blank`. At the canvas size that blanks the 11–12 columns and
/// rows between HORNET's tiles; at a smaller size each bezel blanks a line of pixels wherever it
/// covers their centres, so the viewer shows where the wall's seams are.
#[must_use]
pub fn wall_view<T: Copy>(
    model: &DisplayModel,
    image: &[T],
    image_size: [u32; 2],
    blank: T,
) -> Vec<T> {
    let [w, h] = image_size;
    let mut out = vec![blank; image.len()];
    let canvas = model.canvas_rect();
    let scale = canvas.size() / DVec2::new(f64::from(w), f64::from(h));
    // At the canvas size a tile's cut follows its first pixel by translation (see
    // [`tile_axes`]), so its last pixels may sit up to `resolution × |scale − 1|` outside the
    // active area: the mask allows that drift, so every pixel a tile shows is kept.
    let exact = image_size == canvas_pixel_size(model);
    let drift = |res: u32, s: f64| {
        if exact {
            f64::from(res) * (s - 1.0).abs()
        } else {
            0.0
        }
    };
    // Image pixels whose centre min + (i + 0.5)·scale lies in [lo, hi], per axis.
    let range = |lo: f64, hi: f64, origin: f64, s: f64, n: u32| {
        let first = ((lo - origin) / s - 0.5).ceil().clamp(0.0, f64::from(n)) as usize;
        let end = (((hi - origin) / s - 0.5).floor() + 1.0).clamp(0.0, f64::from(n)) as usize;
        first..end.max(first)
    };
    for t in model.tiles() {
        let a = t.active_rect();
        let [rw, rh] = t.resolution();
        let (dx, dy) = (drift(rw, scale.x), drift(rh, scale.y));
        let xs = range(a.min.x - dx, a.max.x + dx, canvas.min.x, scale.x, w);
        for y in range(a.min.y - dy, a.max.y + dy, canvas.min.y, scale.y, h) {
            let row = y * w as usize;
            out[row + xs.start..row + xs.end].copy_from_slice(&image[row + xs.start..row + xs.end]);
        }
    }
    out
}

/// Writes one image per tile into `dir` (created if missing), named `<tile id>.<ext>` by
/// `format`; returns the paths in the model's tile order. PNG uses `exposure` (stops).
pub fn write_tiles(
    dir: &Path,
    model: &DisplayModel,
    image: &[Vec3],
    image_size: [u32; 2],
    format: Format,
    exposure: f32,
) -> Result<Vec<PathBuf>, TilesError> {
    let n = image_size[0] as usize * image_size[1] as usize;
    if image.len() != n {
        return Err(TilesError::Size {
            len: image.len(),
            width: image_size[0],
            height: image_size[1],
        });
    }
    // One tile cut at a time: the whole picture is not copied again.
    (0..model.tiles().len())
        .map(|i| {
            let pixels = cut_tile(model, i, image, image_size);
            write_tile(dir, model, i, &pixels, format, exposure)
        })
        .collect()
}

/// Writes tile `tile`'s picture (`pixels`, its resolution row by row) into `dir` (created if
/// missing) as [`write_tiles`] names it; returns the path. What a wall's PC writes for the
/// tiles it owns (DESIGN.md §12).
pub fn write_tile(
    dir: &Path,
    model: &DisplayModel,
    tile: usize,
    pixels: &[Vec3],
    format: Format,
    exposure: f32,
) -> Result<PathBuf, TilesError> {
    let t = &model.tiles()[tile];
    let [w, h] = t.resolution();
    if pixels.len() != w as usize * h as usize {
        return Err(TilesError::Size {
            len: pixels.len(),
            width: w,
            height: h,
        });
    }
    // The folder named, never the folders above it (`output::check_folder`).
    super::file::create_folder(dir).map_err(|source| TilesError::Dir {
        dir: dir.to_owned(),
        source,
    })?;
    let path = tile_path(dir, model, tile, format);
    super::write_rgb(&path, w, h, pixels, exposure)?;
    Ok(path)
}

/// Where [`write_tile`] writes tile `tile`: `dir/<tile id>.<exr|png>`.
#[must_use]
pub fn tile_path(dir: &Path, model: &DisplayModel, tile: usize, format: Format) -> PathBuf {
    let ext = match format {
        Format::Exr => "exr",
        Format::Png => "png",
    };
    dir.join(format!("{}.{ext}", model.tiles()[tile].id()))
}

/// Why the tile images could not be written.
#[derive(Debug, thiserror::Error)]
pub enum TilesError {
    #[error("{len} pixels do not fill a {width}×{height} image")]
    Size { len: usize, width: u32, height: u32 },
    #[error("{dir}: cannot create the tile directory: {source}")]
    Dir {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Output(#[from] OutputError),
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hornet() -> DisplayModel {
        DisplayModel::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/display-models/hornet.json"
        ))
        .unwrap()
    }

    /// At the canvas resolution every HORNET tile is a 1920×1080 block of the canvas image
    /// (a pure translation), the block whose pixels the tile's active area covers, and no
    /// canvas pixel goes to two tiles.
    #[test]
    fn hornet_tiles_are_exact_cuts_of_a_canvas_sized_image() {
        let m = hornet();
        let size = canvas_pixel_size(&m);
        let [w, h] = size;
        assert_eq!(m.tiles().len(), 35);
        let mut used = vec![false; w as usize * h as usize];
        for (i, t) in m.tiles().iter().enumerate() {
            assert_eq!(t.resolution(), [1920, 1080]);
            let idx = tile_source_indices(&m, i, size);
            assert_eq!(idx.len(), 1920 * 1080);
            let (x0, y0) = (idx[0] % w as usize, idx[0] / w as usize);
            for y in 0..1080usize {
                for x in 0..1920usize {
                    let k = idx[y * 1920 + x];
                    assert_eq!(
                        k,
                        (y0 + y) * w as usize + x0 + x,
                        "tile {} px {x},{y}",
                        t.id()
                    );
                    assert!(!used[k], "canvas pixel {k} shown by two tiles");
                    used[k] = true;
                }
            }
            // The image pixel's square covers the tile's first pixel centre.
            let c = m.image_to_canvas(DVec2::new(x0 as f64, y0 as f64), size);
            let centre = t.tile_px_to_canvas(DVec2::splat(0.5));
            let scale = m.canvas_rect().size() / DVec2::new(f64::from(w), f64::from(h));
            let d = centre - c;
            assert!(d.x >= 0.0 && d.y >= 0.0 && d.x < scale.x && d.y < scale.y);
            // The last pixel has drifted by at most 0.05 px from its nearest image pixel.
            let last = idx[1920 * 1080 - 1];
            let img_centre = m.image_to_canvas(
                DVec2::new(
                    (last % w as usize) as f64 + 0.5,
                    (last / w as usize) as f64 + 0.5,
                ),
                size,
            );
            let off = (t.tile_px_to_canvas(DVec2::new(1919.5, 1079.5)) - img_centre).abs();
            assert!(off.max_element() < 0.55, "tile {}: {off}", t.id());
        }
    }

    #[test]
    fn cut_values_are_the_canvas_values_and_wall_view_blanks_bezels() {
        let m = hornet();
        let size = canvas_pixel_size(&m);
        let [w, _] = size;
        // A cheap pattern: the value of pixel (x, y) is x + 100 000·y, as u32.
        let pattern = |k: usize| (k % w as usize + 100_000 * (k / w as usize)) as u32;
        let i = m.tile_index("c3r2").unwrap();
        let idx = tile_source_indices(&m, i, size);
        let image: Vec<u32> = (0..(size[0] * size[1]) as usize).map(pattern).collect();
        let cut = cut_tile(&m, i, &image, size);
        assert!(cut.iter().zip(&idx).all(|(&v, &k)| v == pattern(k)));
        drop(image);
        // The wall view keeps every pixel a tile shows; along a row through the middle of row 2
        // it blanks one run of 11–12 pixels per seam and the outer bezels' 5–6 (HORNET's 3 mm
        // bezels are 5.66 canvas px), each off by at most one pixel for the 0.2 px the rounded
        // canvas size drifts.
        let ones = vec![1u8; (size[0] * size[1]) as usize];
        let wall = wall_view(&m, &ones, size, 0);
        for t in 0..m.tiles().len() {
            assert!(
                tile_source_indices(&m, t, size)
                    .iter()
                    .all(|&k| wall[k] == 1)
            );
        }
        let y = m.tiles()[i].active_rect().center().y as usize;
        let row = &wall[y * w as usize..(y + 1) * w as usize];
        let mut runs = Vec::new();
        for (x, &v) in row.iter().enumerate() {
            match (v, runs.last_mut()) {
                (0, Some((end, len))) if *end == x => {
                    *end += 1;
                    *len += 1;
                }
                (0, _) => runs.push((x + 1, 1)),
                _ => {}
            }
        }
        let lens: Vec<usize> = runs.iter().map(|r| r.1).collect();
        assert_eq!(lens.len(), 8, "{lens:?}");
        assert!(
            (5..=7).contains(&lens[0]) && (5..=7).contains(&lens[7]),
            "{lens:?}"
        );
        assert!(lens[1..7].iter().all(|l| (10..=13).contains(l)), "{lens:?}");
    }

    /// At the viewer's 992×400 a seam (11.3 canvas px) blanks at most one column of pixels
    /// (13.6 canvas px each), and only where it covers the column's centre.
    #[test]
    fn wall_view_at_a_small_size_blanks_thin_seams() {
        let m = hornet();
        let size = [992, 400];
        let ones = vec![1u8; 992 * 400];
        let wall = wall_view(&m, &ones, size, 0);
        let y = 200 * 992;
        let row = &wall[y..y + 992];
        let blank: Vec<usize> = (0..992).filter(|&x| row[x] == 0).collect();
        assert!(!blank.is_empty() && blank.len() <= 8, "{blank:?}");
        // Blank columns sit where the seams are: canvas x of the column centre within half a
        // pixel of a gap between two tiles' active areas.
        let sx = m.canvas_rect().size().x / 992.0;
        for &x in &blank {
            let cx = m.canvas_rect().min.x + (x as f64 + 0.5) * sx;
            assert!(
                m.tiles().iter().all(|t| {
                    let a = t.active_rect();
                    cx < a.min.x || cx > a.max.x
                }),
                "column {x} (canvas x {cx}) lies on a tile"
            );
        }
    }

    #[test]
    fn a_smaller_render_is_upsampled_by_nearest_neighbour() {
        let m = hornet();
        // 7×5 pixels: one image pixel per tile, roughly.
        let size = [7, 5];
        let image: Vec<u32> = (0..35).collect();
        for (i, t) in m.tiles().iter().enumerate() {
            let cut = cut_tile(&m, i, &image, size);
            let want = t.row() * 7 + t.column();
            assert!(cut.iter().all(|&v| v == want), "tile {}", t.id());
        }
    }
}
