//! The environment light from the `--env` argument: `R,G,B` (a constant radiance), or an
//! equirectangular image in linear RGB, `.hdr` (Radiance RGBE) or `.exr` (the first RGB(A)
//! layer, largest resolution level).

use std::path::Path;

use glam::Vec3;

use super::{Environment, EnvironmentMap};

/// Environment images larger than this (decoded f32 RGB bytes) are refused: 16k × 8k texels.
const MAX_ENVIRONMENT_BYTES: u64 = 16384 * 8192 * 12;

/// An `--env` argument that cannot be used; every message names the argument or the file.
#[derive(Debug, thiserror::Error)]
pub enum EnvironmentError {
    #[error("--env '{arg}': {reason}")]
    Argument { arg: String, reason: String },
    #[error("{file}: cannot read the environment image: {reason}")]
    Read { file: String, reason: String },
    #[error(
        "{file}: pixel ({x}, {y}) has radiance ({r}, {g}, {b}); environment texels must be finite and ≥ 0"
    )]
    Texel {
        file: String,
        x: u32,
        y: u32,
        r: f32,
        g: f32,
        b: f32,
    },
}

impl Environment {
    /// Parses `--env`: `R,G,B` → [`Environment::Constant`], a `.hdr` / `.exr` path →
    /// [`Environment::Map`].
    pub fn parse(arg: &str) -> Result<Self, EnvironmentError> {
        let bad = |reason: String| EnvironmentError::Argument {
            arg: arg.into(),
            reason,
        };
        let parts: Vec<&str> = arg.split(',').map(str::trim).collect();
        let numbers: Option<Vec<f32>> = parts.iter().map(|p| p.parse().ok()).collect();
        if let Some(v) = numbers {
            let [r, g, b] = v[..] else {
                return Err(bad(format!(
                    "a constant environment needs three numbers R,G,B, got {}",
                    v.len()
                )));
            };
            let c = Vec3::new(r, g, b);
            if !(c.is_finite() && c.min_element() >= 0.0) {
                return Err(bad("radiance must be finite and ≥ 0".into()));
            }
            return Ok(Self::Constant(c));
        }
        let ext = Path::new(arg)
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("hdr" | "exr") => EnvironmentMap::load(arg).map(Self::Map),
            _ => Err(bad(
                "expected R,G,B (linear radiance) or an equirectangular .hdr or .exr file".into(),
            )),
        }
    }
}

impl EnvironmentMap {
    /// Loads a `.hdr` or `.exr` equirectangular image (by extension) in linear RGB.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, EnvironmentError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let read = |reason: String| EnvironmentError::Read {
            file: file.clone(),
            reason,
        };
        // A device or a pipe named `sky.hdr` is never decoded (the decoders would read it
        // for ever); a regular file's size bounds the read, the texel limit the decode.
        crate::input::open_regular(path).map_err(|e| read(e.to_string()))?;
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let (width, height, texels) = match ext.as_deref() {
            Some("hdr") => {
                let mut reader = image::ImageReader::open(path).map_err(|e| read(e.to_string()))?;
                reader.set_format(image::ImageFormat::Hdr);
                let mut limits = image::Limits::default();
                limits.max_alloc = Some(MAX_ENVIRONMENT_BYTES);
                reader.limits(limits);
                let img = reader
                    .decode()
                    .map_err(|e| read(e.to_string()))?
                    .to_rgb32f();
                let texels = img.pixels().map(|p| Vec3::from_array(p.0)).collect();
                (img.width(), img.height(), texels)
            }
            Some("exr") => read_exr(path).map_err(|e| read(e.to_string()))?,
            _ => return Err(read("unsupported format (use .hdr or .exr)".into())),
        };
        if width == 0 || height == 0 {
            return Err(read("the image is empty".into()));
        }
        let map = Self {
            name: file,
            width,
            height,
            texels,
        };
        map.validate()?;
        Ok(map)
    }

    /// Every texel finite and ≥ 0 (the tracer would otherwise average NaN or negative light
    /// into the image); the error names the first bad pixel.
    pub fn validate(&self) -> Result<(), EnvironmentError> {
        if let Some(i) = self
            .texels
            .iter()
            .position(|t| !(t.is_finite() && t.min_element() >= 0.0))
        {
            let t = self.texels[i];
            return Err(EnvironmentError::Texel {
                file: self.name.clone(),
                x: (i % self.width as usize) as u32,
                y: (i / self.width as usize) as u32,
                r: t.x,
                g: t.y,
                b: t.z,
            });
        }
        Ok(())
    }
}

/// Why an OpenEXR file gives no environment image.
#[derive(Debug, thiserror::Error)]
enum ExrError {
    #[error("{0}")]
    Decode(#[from] exr::error::Error),
    #[error("{width}×{height} texels is more than the {MAX_ENVIRONMENT_BYTES} bytes allowed")]
    TooLarge { width: usize, height: usize },
}

/// The first RGB(A) layer of an OpenEXR file (alpha ignored).
fn read_exr(path: &Path) -> Result<(u32, u32, Vec<Vec3>), ExrError> {
    use exr::prelude::*;
    struct Pixels {
        width: usize,
        texels: Vec<Vec3>,
    }
    let image = read_first_rgba_layer_from_file(
        path,
        |size: exr::math::Vec2<usize>, _: &RgbaChannels| {
            let n = size.width().saturating_mul(size.height());
            // Refused before allocating: the header's size is the file's claim, not its bytes.
            if n as u64 * 12 > MAX_ENVIRONMENT_BYTES {
                return Pixels {
                    width: 0,
                    texels: Vec::new(),
                };
            }
            Pixels {
                width: size.width(),
                texels: vec![Vec3::ZERO; n],
            }
        },
        |px: &mut Pixels, pos: exr::math::Vec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
            if px.width > 0 {
                px.texels[pos.y() * px.width + pos.x()] = Vec3::new(r, g, b);
            }
        },
    )?;
    let size = image.layer_data.size;
    let pixels = image.layer_data.channel_data.pixels;
    if pixels.texels.len() != size.width() * size.height() {
        return Err(ExrError::TooLarge {
            width: size.width(),
            height: size.height(),
        });
    }
    Ok((size.width() as u32, size.height() as u32, pixels.texels))
}
