//! Saving what the viewer shows: the picture's image, its DGI, counts and noise, and the
//! window's picture as a PNG.

use std::path::{Path, PathBuf};

use super::ViewerError;
use super::core::Picture;

/// Writes the picture's image (`<stem>.exr` linear, `<stem>.png` as shown with the exposure),
/// the DGI (`<stem>.dgi.png`), the counts (`<stem>.counts.exr`), the noise
/// (`<stem>.noise.exr`: channel `se`, the standard error of the mean luminance, NaN below two
/// samples) and the window's picture with its overlay (`<stem>.view.png`) into `dir`; returns
/// the paths.
pub fn save_picture(
    dir: &Path,
    stem: &str,
    p: &Picture,
    exposure: f32,
) -> Result<Vec<PathBuf>, ViewerError> {
    // The folder named, never the folders above it (`output::check_folder`).
    crate::output::create_folder(dir).map_err(|error| ViewerError::CreateDir {
        dir: dir.to_owned(),
        error,
    })?;
    let [w, h] = p.size;
    let mut files = Vec::new();
    for ext in ["exr", "png"] {
        let path = dir.join(format!("{stem}.{ext}"));
        crate::output::write_rgb(&path, w, h, &p.image, exposure)?;
        files.push(path);
    }
    let dgi = dir.join(format!("{stem}.dgi.png"));
    crate::output::write_gray(&dgi, w, h, &p.dgi, "d")?;
    let counts = dir.join(format!("{stem}.counts.exr"));
    let c: Vec<f32> = p.counts.iter().map(|&c| c as f32).collect();
    crate::output::write_gray(&counts, w, h, &c, "samples")?;
    let noise = dir.join(format!("{stem}.noise.exr"));
    crate::output::write_gray(&noise, w, h, &p.noise, "se")?;
    let view = dir.join(format!("{stem}.view.png"));
    save_view_png(&view, p)?;
    files.extend([dgi, counts, noise, view]);
    Ok(files)
}

/// Writes the picture as shown (RGBA8 PNG).
pub fn save_view_png(path: &Path, p: &Picture) -> Result<(), ViewerError> {
    save_rgba_png(path, p.size, &p.rgba)
}

/// Writes `size` RGBA8 bytes as a PNG (through a temporary name).
pub fn save_rgba_png(path: &Path, [w, h]: [u32; 2], rgba: &[u8]) -> Result<(), ViewerError> {
    let img = image::RgbaImage::from_raw(w, h, rgba.to_vec()).ok_or(ViewerError::PictureSize)?;
    crate::output::replace_with(path, |tmp| {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|error| ViewerError::Png {
                path: path.to_owned(),
                error,
            })
    })
}
