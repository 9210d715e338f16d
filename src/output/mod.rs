//! Output: images on disk (EXR for the numbers, PNG for people), chosen by file extension, each
//! written through a temporary name and renamed into place ([`file`](mod@file)).

use std::path::{Path, PathBuf};

pub mod file;
pub mod gpu;
pub mod srgb8;
pub mod stats;
pub mod tiles;

pub use file::{
    FileError, OutputSet, check_folder, check_writable, create_folder, replace_with, write_bytes,
};

/// Why an image could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: unsupported image extension (use .exr or .png)")]
    Extension { path: PathBuf },
    #[error("{path}: {len} values do not fill a {width}×{height}×{channels} image")]
    Size {
        path: PathBuf,
        len: usize,
        width: u32,
        height: u32,
        channels: usize,
    },
    #[error("{path}: writing EXR failed: {source}")]
    Exr {
        path: PathBuf,
        #[source]
        source: exr::error::Error,
    },
    #[error("{path}: writing PNG failed: {source}")]
    Png {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
    #[error(transparent)]
    File(#[from] FileError),
}

/// The channel name of a DGI written as EXR (by `render --guide`, `dgi`, `view`'s saves): the
/// value d of DESIGN.md §5.
pub const DGI_CHANNEL: &str = "d";

/// The image formats raygun writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// OpenEXR, 32-bit float, linear.
    Exr,
    /// PNG, 8-bit.
    Png,
}

impl Format {
    pub fn from_path(path: &Path) -> Result<Self, OutputError> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("exr") => Ok(Self::Exr),
            Some("png") => Ok(Self::Png),
            _ => Err(OutputError::Extension {
                path: path.to_owned(),
            }),
        }
    }
}

/// Checks an image output before any work: a known extension and a folder that takes the file.
pub fn check_image_path(path: &Path) -> Result<Format, OutputError> {
    let format = Format::from_path(path)?;
    check_writable(path)?;
    Ok(format)
}

/// The EXR encoding of every file raygun writes: exr's fast lossless one (RLE, 64×64 tiles)
/// with its tiles in increasing order. exr compresses tiles on several threads; in its default
/// unspecified order they are written as they finish, so the same image gave different bytes
/// from run to run. Sorted, the same pixels always give the same file (what the cluster's
/// byte-for-byte tests compare).
const REPRODUCIBLE_EXR: exr::prelude::Encoding = exr::prelude::Encoding {
    line_order: exr::prelude::LineOrder::Increasing,
    ..exr::prelude::Encoding::FAST_LOSSLESS
};

/// Writes a one-channel float image (row-major): EXR keeps the values as 32-bit floats in a
/// channel named `channel`; PNG shows them as 8-bit grey, mapping [0, 1] to [0, 255] (values
/// outside are clamped, NaN is black).
pub fn write_gray(
    path: &Path,
    width: u32,
    height: u32,
    values: &[f32],
    channel: &str,
) -> Result<(), OutputError> {
    check_len(path, width, height, 1, values.len())?;
    match Format::from_path(path)? {
        Format::Exr => {
            use exr::prelude::*;
            let ch = AnyChannel::new(channel, FlatSamples::F32(values.to_vec()));
            let layer = Layer::new(
                (width as usize, height as usize),
                LayerAttributes::named(channel),
                REPRODUCIBLE_EXR,
                AnyChannels::sort(SmallVec::from_vec(vec![ch])),
            );
            replace_with(path, |tmp| {
                Image::from_layer(layer)
                    .write()
                    .to_file(tmp)
                    .map_err(|source| OutputError::Exr {
                        path: path.to_owned(),
                        source,
                    })
            })
        }
        Format::Png => {
            let bytes: Vec<u8> = values.iter().map(|&v| unit_to_u8(v)).collect();
            let img =
                image::GrayImage::from_raw(width, height, bytes).expect("length checked above");
            replace_with(path, |tmp| {
                img.save_with_format(tmp, image::ImageFormat::Png)
                    .map_err(|source| OutputError::Png {
                        path: path.to_owned(),
                        source,
                    })
            })
        }
    }
}

/// Writes a linear RGB image (row-major): EXR keeps 32-bit float R, G, B channels; PNG shows
/// it as 8-bit sRGB after scaling by 2^`exposure` and clamping to [0, 1] (NaN is black).
pub fn write_rgb(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[glam::Vec3],
    exposure: f32,
) -> Result<(), OutputError> {
    check_len(path, width, height, 1, pixels.len())?;
    match Format::from_path(path)? {
        Format::Exr => {
            use exr::prelude::*;
            let channel = |name: &str, k: usize| {
                AnyChannel::new(
                    name,
                    FlatSamples::F32(pixels.iter().map(|p| p[k]).collect()),
                )
            };
            let layer = Layer::new(
                (width as usize, height as usize),
                LayerAttributes::named("rgb"),
                REPRODUCIBLE_EXR,
                AnyChannels::sort(SmallVec::from_vec(vec![
                    channel("R", 0),
                    channel("G", 1),
                    channel("B", 2),
                ])),
            );
            replace_with(path, |tmp| {
                Image::from_layer(layer)
                    .write()
                    .to_file(tmp)
                    .map_err(|source| OutputError::Exr {
                        path: path.to_owned(),
                        source,
                    })
            })
        }
        Format::Png => {
            let bytes = srgb8::display_rgb(pixels, exposure);
            let img =
                image::RgbImage::from_raw(width, height, bytes).expect("length checked above");
            replace_with(path, |tmp| {
                img.save_with_format(tmp, image::ImageFormat::Png)
                    .map_err(|source| OutputError::Png {
                        path: path.to_owned(),
                        source,
                    })
            })
        }
    }
}

/// The sRGB transfer function (linear [0, 1] → encoded [0, 1]); values outside are clamped.
#[must_use]
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

fn check_len(
    path: &Path,
    width: u32,
    height: u32,
    channels: usize,
    len: usize,
) -> Result<(), OutputError> {
    if len != width as usize * height as usize * channels {
        return Err(OutputError::Size {
            path: path.to_owned(),
            len,
            width,
            height,
            channels,
        });
    }
    Ok(())
}

/// [0, 1] → [0, 255], rounding to nearest; NaN → 0.
#[must_use]
pub fn unit_to_u8(v: f32) -> u8 {
    if v.is_nan() {
        return 0;
    }
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_exr_and_png() {
        let dir = std::env::temp_dir().join(format!("raygun-output-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let values: Vec<f32> = (0..12).map(|i| i as f32 / 11.0).collect();
        let exr_path = dir.join("g.exr");
        write_gray(&exr_path, 4, 3, &values, "Y").unwrap();
        let img = exr::prelude::read_first_flat_layer_from_file(&exr_path).unwrap();
        let samples = &img.layer_data.channel_data.list[0].sample_data;
        let back: Vec<f32> = samples.values_as_f32().collect();
        assert_eq!(back, values);
        let png_path = dir.join("g.png");
        write_gray(&png_path, 4, 3, &values, "Y").unwrap();
        let png = image::open(&png_path).unwrap().to_luma8();
        assert_eq!(png.get_pixel(3, 2)[0], 255);
        assert_eq!(png.get_pixel(0, 0)[0], 0);
        assert!(matches!(
            write_gray(&dir.join("g.tif"), 4, 3, &values, "Y"),
            Err(OutputError::Extension { .. })
        ));
        assert!(matches!(
            write_gray(&png_path, 5, 3, &values, "Y"),
            Err(OutputError::Size { .. })
        ));
        std::fs::remove_dir_all(&dir).ok();
    }
}
