//! The resources a glTF file refers to: buffers, images, textures and their samplers.
//!
//! Resolved here rather than with `gltf::import`, which is all-or-nothing: one undecodable
//! image would fail the whole scene, where raygun falls back to the material's factor and says
//! so. A missing file, though, is an error naming its URI. The scene walk (nodes, cameras,
//! lights) is in `load.rs`, its meshes in `load/mesh.rs` and materials in `load/material.rs`.

use std::collections::HashMap;
use std::io::Cursor;
use std::path::Path;

use super::report::{Report, SceneError, UriError, label};
use super::{Sampler, Texture, Wrap};

/// Images larger than this (bytes of decoded RGBA8) are refused by the decoder: a 16k × 8k
/// texture is 512 MiB, more than any texture the tracer can bind.
const MAX_IMAGE_BYTES: u64 = 512 << 20;

/// The largest EXT_meshopt_compression fallback buffer (decoded data) a file may declare: its
/// bytes cost memory, not file size, so a hostile file could ask for terabytes.
const MAX_DECODED_BYTES: usize = 1 << 30;

/// The GLB header's declared length must cover the header itself: `gltf::binary::Glb` subtracts
/// 12 from it unchecked (an overflow panic, found by fuzzing).
pub(super) fn check_glb_header(bytes: &[u8], file: &str) -> Result<(), SceneError> {
    let Some(rest) = bytes.strip_prefix(b"glTF") else {
        return Ok(());
    };
    let declared = rest
        .get(4..8)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    match declared {
        Some(n) if n >= 12 => Ok(()),
        _ => Err(SceneError::Parse {
            file: file.into(),
            reason: "the GLB header is truncated or declares less than its own 12 bytes".into(),
        }),
    }
}

pub(super) fn load_buffers(
    doc: &gltf::Document,
    blob: Option<&[u8]>,
    file: &str,
    base: Option<&Path>,
    access: UriAccess,
) -> Result<Vec<Vec<u8>>, SceneError> {
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let element = label("buffer", buffer.name(), buffer.index());
        let fallback = buffer
            .extension_value("EXT_meshopt_compression")
            .and_then(|e| e.get("fallback"))
            .and_then(serde_json::Value::as_bool)
            == Some(true);
        if fallback && matches!(buffer.source(), gltf::buffer::Source::Bin) {
            // A placeholder for decoded views (EXT_meshopt_compression): filled below.
            if buffer.length() > MAX_DECODED_BYTES {
                return Err(SceneError::Element {
                    file: file.into(),
                    element,
                    problem: format!(
                        "declares {} bytes of decoded data (at most {MAX_DECODED_BYTES})",
                        buffer.length()
                    ),
                });
            }
            out.push(vec![0; buffer.length()]);
            continue;
        }
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => {
                blob.map(<[u8]>::to_vec)
                    .ok_or_else(|| SceneError::Element {
                        file: file.into(),
                        element: element.clone(),
                        problem: "refers to the GLB binary chunk, but the file has none".into(),
                    })?
            }
            gltf::buffer::Source::Uri(uri) => {
                read_uri(uri, base, access, Want::Exactly(buffer.length() as u64)).map_err(
                    |reason| SceneError::Resource {
                        file: file.into(),
                        element: element.clone(),
                        uri: short_uri(uri),
                        reason,
                    },
                )?
            }
        };
        if data.len() < buffer.length() {
            return Err(SceneError::Element {
                file: file.into(),
                element,
                problem: format!(
                    "has {} bytes, but its byteLength is {}",
                    data.len(),
                    buffer.length()
                ),
            });
        }
        out.push(data);
    }
    decode_meshopt_views(doc, &mut out, file)?;
    Ok(out)
}

/// EXT_meshopt_compression: every buffer view with the extension is decoded from its
/// compressed bytes into the bytes the view itself names (usually in a fallback buffer), with
/// meshoptimizer's decoders (safe for untrusted input: bad data decodes to garbage or an
/// error, never out of bounds) and filters.
fn decode_meshopt_views(
    doc: &gltf::Document,
    buffers: &mut [Vec<u8>],
    file: &str,
) -> Result<(), SceneError> {
    for view in doc.views() {
        let Some(ext) = view.extension_value("EXT_meshopt_compression") else {
            continue;
        };
        let element = label("buffer view", view.name(), view.index());
        let error = |problem: String| SceneError::Element {
            file: file.into(),
            element: element.clone(),
            problem: format!("EXT_meshopt_compression: {problem}"),
        };
        let num = |key: &str| ext.get(key).and_then(serde_json::Value::as_u64);
        let str_of = |key: &str| ext.get(key).and_then(serde_json::Value::as_str);
        let (Some(source), Some(length), Some(stride), Some(count)) = (
            num("buffer"),
            num("byteLength"),
            num("byteStride"),
            num("count"),
        ) else {
            return Err(error(
                "buffer, byteLength, byteStride and count are required".into(),
            ));
        };
        let (source, offset, length, stride, count) = (
            source as usize,
            num("byteOffset").unwrap_or(0) as usize,
            length as usize,
            stride as usize,
            count as usize,
        );
        let mode = str_of("mode").unwrap_or("");
        let filter = str_of("filter").unwrap_or("NONE");
        let valid_stride = match mode {
            "ATTRIBUTES" => stride % 4 == 0 && (4..=256).contains(&stride),
            "TRIANGLES" | "INDICES" => stride == 2 || stride == 4,
            _ => return Err(error(format!("unknown mode '{mode}'"))),
        };
        if !valid_stride {
            return Err(error(format!(
                "byteStride {stride} is not valid for {mode}"
            )));
        }
        let out_len = count
            .checked_mul(stride)
            .filter(|&n| n <= view.length() && n <= MAX_DECODED_BYTES)
            .ok_or_else(|| {
                error(format!(
                    "{count} × {stride} bytes do not fit the view's {} bytes",
                    view.length()
                ))
            })?;
        let compressed = buffers
            .get(source)
            .and_then(|b| b.get(offset..offset.checked_add(length)?))
            .ok_or_else(|| {
                error(format!(
                    "bytes {offset}+{length} of buffer {source} do not exist"
                ))
            })?
            .to_vec();
        let mut decoded = vec![0u8; out_len];
        // SAFETY: `decoded` holds exactly count × stride bytes, the size each decoder writes;
        // the decoders read only `compressed` (its pointer and length) and check its format.
        let rc = unsafe {
            let (dst, src) = (decoded.as_mut_ptr().cast(), compressed.as_ptr());
            match mode {
                "ATTRIBUTES" => meshopt::ffi::meshopt_decodeVertexBuffer(
                    dst,
                    count,
                    stride,
                    src,
                    compressed.len(),
                ),
                "TRIANGLES" => meshopt::ffi::meshopt_decodeIndexBuffer(
                    dst,
                    count,
                    stride,
                    src,
                    compressed.len(),
                ),
                _ => meshopt::ffi::meshopt_decodeIndexSequence(
                    dst,
                    count,
                    stride,
                    src,
                    compressed.len(),
                ),
            }
        };
        if rc != 0 {
            return Err(error(format!(
                "the compressed data does not decode (code {rc})"
            )));
        }
        let filter_ok = match filter {
            "NONE" => true,
            "OCTAHEDRAL" => mode == "ATTRIBUTES" && (stride == 4 || stride == 8),
            "QUATERNION" => mode == "ATTRIBUTES" && stride == 8,
            "EXPONENTIAL" => mode == "ATTRIBUTES",
            _ => false,
        };
        if !filter_ok {
            return Err(error(format!(
                "filter '{filter}' does not apply to {mode} of stride {stride}"
            )));
        }
        // SAFETY: each filter rewrites count elements of `stride` bytes in place, the buffer's
        // exact size; the strides are the ones the filters accept (checked above).
        unsafe {
            let p = decoded.as_mut_ptr().cast();
            match filter {
                "OCTAHEDRAL" => meshopt::ffi::meshopt_decodeFilterOct(p, count, stride),
                "QUATERNION" => meshopt::ffi::meshopt_decodeFilterQuat(p, count, stride),
                "EXPONENTIAL" => meshopt::ffi::meshopt_decodeFilterExp(p, count, stride),
                _ => {}
            }
        }
        let target = buffers
            .get_mut(view.buffer().index())
            .and_then(|b| b.get_mut(view.offset()..view.offset().checked_add(out_len)?))
            .ok_or_else(|| error("the view lies outside its buffer".into()))?;
        target.copy_from_slice(&decoded);
    }
    Ok(())
}

/// A URI for messages: data URIs are cut to their media type.
pub(super) fn short_uri(uri: &str) -> String {
    match uri.strip_prefix("data:") {
        Some(rest) => format!("data:{}…", rest.split([',', ';']).next().unwrap_or("")),
        None => uri.to_string(),
    }
}

/// Which files a glTF file's URIs may name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UriAccess {
    /// Files in the glTF file's own folder and below, after following links: what a scene
    /// from anywhere may read. An absolute path, a `file:` URI or a `../` that leads outside
    /// the folder is an error naming the URI and this rule.
    #[default]
    Confined,
    /// Any file the process may read (`--trust-scene`), for trusted scenes that share
    /// resources with other folders.
    Anywhere,
}

/// How much of a URI's file to read.
#[derive(Clone, Copy, Debug)]
pub(super) enum Want {
    /// A buffer: exactly its declared `byteLength`, which the file must have.
    Exactly(u64),
    /// An image: the whole file, at most this many bytes.
    AtMost(u64),
}

/// The bytes behind a glTF URI: `data:…;base64,…`, or a relative path or `file:` URI resolved
/// against `base` (the glTF file's folder) and, unless `access` is [`UriAccess::Anywhere`],
/// confined to it. Only regular files are read, and only as much as `want` says.
pub(super) fn read_uri(
    uri: &str,
    base: Option<&Path>,
    access: UriAccess,
    want: Want,
) -> Result<Vec<u8>, UriError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest.split_once(";base64,").ok_or(UriError::NotBase64)?;
        return base64::decode(payload).map_err(UriError::Base64);
    }
    let relative = if let Some(rest) = uri.strip_prefix("file:") {
        percent_decode(rest.strip_prefix("//").unwrap_or(rest))?
    } else if uri.contains(':') {
        return Err(UriError::Scheme);
    } else {
        percent_decode(uri)?
    };
    let base = base.ok_or(UriError::InMemory)?;
    // An absolute path replaces `base` in the join; the confinement below catches it.
    let path = base.join(&relative);
    if access == UriAccess::Confined {
        confine(&path, base)?;
    }
    let read = match want {
        Want::Exactly(len) => crate::input::read_prefix(&path, len),
        Want::AtMost(max) => crate::input::read_file(&path, max, "an image"),
    };
    read.map_err(|error| UriError::Read { path, error })
}

/// Checks that `path`, with every link followed, lies in `base` or below it.
fn confine(path: &Path, base: &Path) -> Result<(), UriError> {
    let canonical = |p: &Path| {
        p.canonicalize().map_err(|error| UriError::Read {
            path: p.to_owned(),
            error,
        })
    };
    let folder = canonical(base)?;
    let target = canonical(path)?;
    if target.starts_with(&folder) {
        return Ok(());
    }
    Err(UriError::Outside { target, folder })
}

/// RFC 3986 percent-decoding into UTF-8.
fn percent_decode(s: &str) -> Result<String, UriError> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| UriError::PercentEscape { uri: s.to_owned() })?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| UriError::NotUtf8 { uri: s.to_owned() })
}

/// The first bytes of every KTX2 file ("«KTX 20»\r\n\x1a\n").
const KTX2_MAGIC: [u8; 12] = [
    0xab, 0x4b, 0x54, 0x58, 0x20, 0x32, 0x30, 0xbb, 0x0d, 0x0a, 0x1a, 0x0a,
];

/// A decoded image: its texels, or why there are none (reported once per texture).
type Decoded = Result<(u32, u32, std::rc::Rc<Vec<[u8; 4]>>), Fallback>;

#[derive(Clone)]
enum Fallback {
    /// A format raygun does not decode (reported as unsupported).
    Format(String),
    /// A PNG or JPEG that failed to decode (a warning).
    Broken(String),
}

/// The file's buffers, and the textures converted so far.
pub(super) struct Resources<'a> {
    pub file: &'a str,
    base: Option<&'a Path>,
    access: UriAccess,
    pub buffers: Vec<Vec<u8>>,
    /// glTF image index → decoded texels.
    images: HashMap<usize, Decoded>,
    /// (glTF texture index, sRGB) → index in the scene's textures (None: not decodable).
    textures: HashMap<(usize, bool), Option<u32>>,
}

impl<'a> Resources<'a> {
    pub fn new(
        file: &'a str,
        base: Option<&'a Path>,
        access: UriAccess,
        buffers: Vec<Vec<u8>>,
    ) -> Self {
        Self {
            file,
            base,
            access,
            buffers,
            images: HashMap::new(),
            textures: HashMap::new(),
        }
    }

    /// The scene texture for glTF texture `tex` read as colour (`srgb`) or as data, converted
    /// once (a texture used both ways is stored twice); `None` (reported) where its image cannot
    /// be decoded. `what` names the use for messages ("its materials use the … factor").
    pub fn texture(
        &mut self,
        doc: &gltf::Document,
        tex: &gltf::Texture,
        srgb: bool,
        out: &mut Vec<Texture>,
        report: &mut Report,
    ) -> Result<Option<u32>, SceneError> {
        if let Some(&t) = self.textures.get(&(tex.index(), srgb)) {
            return Ok(t);
        }
        // KHR_texture_basisu: the KTX2 image is preferred; `source`, when there is one, is
        // the fallback for viewers without the extension (and raygun's when the KTX2 fails).
        let basisu = tex
            .extension_value("KHR_texture_basisu")
            .map(|ext| {
                ext.get("source")
                    .and_then(serde_json::Value::as_u64)
                    .and_then(|i| doc.images().nth(usize::try_from(i).ok()?))
                    .ok_or_else(|| SceneError::Element {
                        file: self.file.into(),
                        element: format!("texture {}", tex.index()),
                        problem: "KHR_texture_basisu: source does not name an image".into(),
                    })
            })
            .transpose()?;
        let fallback = tex.source();
        let Some(image) = basisu.clone().or(fallback.clone()) else {
            return Err(SceneError::Element {
                file: self.file.into(),
                element: format!("texture {}", tex.index()),
                problem: "it has no image (no source and no KHR_texture_basisu)".into(),
            });
        };
        let name = tex
            .name()
            .or(image.name())
            .map_or_else(|| format!("texture {}", tex.index()), str::to_string);
        let element = format!("texture '{name}'");
        let sampler = convert_sampler(&tex.sampler());
        let mut decoded = self.image(&image, &element)?;
        if let (Some(_), Some(fallback), Err(Fallback::Broken(why))) =
            (&basisu, &fallback, &decoded)
        {
            report.warn(format!(
                "{element}: cannot decode the {why}; its fallback image is used"
            ));
            decoded = self.image(fallback, &element)?;
        }
        let t = match decoded {
            Ok((width, height, texels)) => {
                out.push(Texture {
                    name,
                    width,
                    height,
                    texels: texels.as_ref().clone(),
                    sampler,
                    srgb,
                });
                Some(out.len() as u32 - 1)
            }
            Err(Fallback::Format(what)) => {
                report.unsupported(format!(
                    "image format {what} ({element}; its materials use their factors)"
                ));
                None
            }
            Err(Fallback::Broken(why)) => {
                report.warn(format!(
                    "{element}: cannot decode the {why}; its materials use their factors"
                ));
                None
            }
        };
        self.textures.insert((tex.index(), srgb), t);
        Ok(t)
    }

    /// Image `image` decoded, once.
    fn image(&mut self, image: &gltf::Image, element: &str) -> Result<Decoded, SceneError> {
        if let Some(d) = self.images.get(&image.index()) {
            return Ok(d.clone());
        }
        let d = self.decode(image, element)?;
        self.images.insert(image.index(), d.clone());
        Ok(d)
    }

    fn decode(&self, image: &gltf::Image, element: &str) -> Result<Decoded, SceneError> {
        let (bytes, mime, uri_ext) = match image.source() {
            gltf::image::Source::View { view, mime_type } => {
                let start = view.offset();
                let bytes = start
                    .checked_add(view.length())
                    .and_then(|end| self.buffers.get(view.buffer().index())?.get(start..end))
                    .ok_or_else(|| SceneError::Element {
                        file: self.file.into(),
                        element: element.into(),
                        problem: format!("buffer view {} runs past its buffer", view.index()),
                    })?;
                (bytes.to_vec(), Some(mime_type.to_string()), None)
            }
            gltf::image::Source::Uri { uri, mime_type } => {
                let bytes = read_uri(uri, self.base, self.access, Want::AtMost(MAX_IMAGE_BYTES))
                    .map_err(|reason| SceneError::Resource {
                        file: self.file.into(),
                        element: element.into(),
                        uri: short_uri(uri),
                        reason,
                    })?;
                let data_mime = uri
                    .strip_prefix("data:")
                    .and_then(|r| r.split(';').next())
                    .filter(|m| !m.is_empty());
                let mime = mime_type.or(data_mime).map(str::to_string);
                let ext = (!uri.starts_with("data:"))
                    .then(|| uri.rsplit('.').next().map(str::to_ascii_lowercase))
                    .flatten();
                (bytes, mime, ext)
            }
        };
        if mime.as_deref() == Some("image/ktx2")
            || (mime.is_none() && uri_ext.as_deref() == Some("ktx2"))
            || bytes.starts_with(&KTX2_MAGIC)
        {
            return Ok(match super::ktx2::decode(&bytes) {
                Ok((w, h, texels)) => Ok((w, h, std::rc::Rc::new(texels))),
                Err(e) => Err(Fallback::Broken(format!("KTX2 image ({e})"))),
            });
        }
        let format = match (mime.as_deref(), uri_ext.as_deref()) {
            (Some("image/png"), _) | (None, Some("png")) => Some(image::ImageFormat::Png),
            (Some("image/jpeg"), _) | (None, Some("jpg" | "jpeg")) => {
                Some(image::ImageFormat::Jpeg)
            }
            _ => image::guess_format(&bytes)
                .ok()
                .filter(|f| matches!(f, image::ImageFormat::Png | image::ImageFormat::Jpeg)),
        };
        let Some(format) = format else {
            let what = mime.or(uri_ext).unwrap_or_else(|| "unknown".into());
            return Ok(Err(Fallback::Format(what)));
        };
        Ok(match decode_rgba8(&bytes, format) {
            Ok(img) => Ok((
                img.width(),
                img.height(),
                std::rc::Rc::new(img.pixels().map(|p| p.0).collect()),
            )),
            Err(e) => Err(Fallback::Broken(format!("{format:?} image ({e})"))),
        })
    }
}

/// glTF sampler → [`Sampler`] (the minification filter does not matter: see [`Sampler`]).
fn convert_sampler(s: &gltf::texture::Sampler) -> Sampler {
    let wrap = |w| match w {
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
    };
    Sampler {
        wrap_s: wrap(s.wrap_s()),
        wrap_t: wrap(s.wrap_t()),
        nearest: s.mag_filter() == Some(gltf::texture::MagFilter::Nearest),
    }
}

/// Decodes PNG or JPEG into RGBA8 (grey, grey-alpha, RGB and 16-bit images are expanded the way
/// the `image` crate does: 16-bit channels are rounded to 8 bits, missing alpha is opaque).
/// Why a PNG or JPEG did not decode.
#[derive(Debug, thiserror::Error)]
enum ImageDecodeError {
    #[error("{0}")]
    Image(image::ImageError),
    #[error("{w}×{h} is larger than {MAX_IMAGE_BYTES} bytes of RGBA8")]
    TooLarge { w: u64, h: u64 },
    #[error("the image is empty")]
    Empty,
}

fn decode_rgba8(
    bytes: &[u8],
    format: image::ImageFormat,
) -> Result<image::RgbaImage, ImageDecodeError> {
    let mut reader = image::ImageReader::with_format(Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_IMAGE_BYTES);
    reader.limits(limits);
    let img = reader.decode().map_err(ImageDecodeError::Image)?;
    let (w, h) = (u64::from(img.width()), u64::from(img.height()));
    if w * h * 4 > MAX_IMAGE_BYTES {
        return Err(ImageDecodeError::TooLarge { w, h });
    }
    if w == 0 || h == 0 {
        return Err(ImageDecodeError::Empty);
    }
    Ok(img.to_rgba8())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_decoding_accepts_utf8_and_rejects_broken_escapes() {
        assert_eq!(percent_decode("a%20b%C3%A9.png").unwrap(), "a bé.png");
        assert_eq!(percent_decode("plain.bin").unwrap(), "plain.bin");
        // The gltf crate unwraps this decoding and panics; here it is an error.
        assert!(
            percent_decode("%FF.png")
                .unwrap_err()
                .to_string()
                .contains("UTF-8")
        );
        assert!(
            percent_decode("%G1")
                .unwrap_err()
                .to_string()
                .contains("percent-escape")
        );
        assert!(percent_decode("end%2").is_err());
    }

    #[test]
    fn uris_resolve_data_and_relative_paths_and_refuse_the_rest() {
        let any = Want::AtMost(1 << 20);
        let confined = UriAccess::Confined;
        assert_eq!(
            read_uri(
                "data:application/octet-stream;base64,AAEC",
                None,
                confined,
                any
            )
            .unwrap(),
            [0, 1, 2]
        );
        assert!(
            read_uri("data:text/plain,hello", None, confined, any)
                .unwrap_err()
                .to_string()
                .contains("base64")
        );
        assert!(
            read_uri(
                "https://example.com/a.bin",
                Some(Path::new(".")),
                confined,
                any
            )
            .is_err()
        );
        assert!(
            read_uri("a.bin", None, confined, any)
                .unwrap_err()
                .to_string()
                .contains("in-memory")
        );
        assert!(
            read_uri("file:///etc/hostname", None, UriAccess::Anywhere, any)
                .unwrap_err()
                .to_string()
                .contains("in-memory")
        );
        assert_eq!(short_uri("data:image/png;base64,AAAA"), "data:image/png…");
    }

    #[test]
    fn uris_stay_in_the_scenes_folder_unless_the_scene_is_trusted() {
        let root = std::env::temp_dir().join(format!("raygun-uris-{}", std::process::id()));
        let scene = root.join("scene");
        std::fs::create_dir_all(scene.join("textures")).unwrap();
        std::fs::write(scene.join("textures/a.bin"), b"inside").unwrap();
        std::fs::write(root.join("secret.bin"), b"outside").unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(root.join("secret.bin"), scene.join("link.bin")).unwrap();
        let base = Some(scene.as_path());
        let want = Want::AtMost(1 << 20);
        let read = |uri: &str, access| read_uri(uri, base, access, want);
        // Inside, by a relative path (percent-escaped or not) or a `file:` URI.
        assert_eq!(
            read("textures/a.bin", UriAccess::Confined).unwrap(),
            b"inside"
        );
        assert_eq!(
            read("textures/%61.bin", UriAccess::Confined).unwrap(),
            b"inside"
        );
        assert_eq!(
            read("textures/../textures/a.bin", UriAccess::Confined).unwrap(),
            b"inside"
        );
        let inside = format!("file://{}", scene.join("textures/a.bin").display());
        assert_eq!(read(&inside, UriAccess::Confined).unwrap(), b"inside");
        // Outside: climbing out, an absolute path, a `file:` URI, a link that leads out.
        let secret = root.join("secret.bin");
        let outside = [
            "../secret.bin".to_owned(),
            "textures/../../secret.bin".to_owned(),
            secret.display().to_string(),
            format!("file://{}", secret.display()),
            "link.bin".to_owned(),
        ];
        for uri in &outside {
            let e = read(uri, UriAccess::Confined).unwrap_err().to_string();
            assert!(
                e.contains("outside the scene's folder") && e.contains("--trust-scene"),
                "{uri}: {e}"
            );
            assert_eq!(read(uri, UriAccess::Anywhere).unwrap(), b"outside", "{uri}");
        }
        // A device is never read, trusted or not; a buffer reads its byteLength, which the
        // file must have.
        let e = read("/dev/zero", UriAccess::Anywhere)
            .unwrap_err()
            .to_string();
        assert!(e.contains("character device"), "{e}");
        let exactly = |n| {
            read_uri(
                "textures/a.bin",
                base,
                UriAccess::Confined,
                Want::Exactly(n),
            )
        };
        assert_eq!(exactly(3).unwrap(), b"ins");
        assert!(
            exactly(7)
                .unwrap_err()
                .to_string()
                .contains("has 6 bytes, fewer than the 7")
        );
        let e = read_uri("textures/a.bin", base, UriAccess::Confined, Want::AtMost(5))
            .unwrap_err()
            .to_string();
        assert!(e.contains("more than the 5 bytes an image may have"), "{e}");
        std::fs::remove_dir_all(&root).unwrap();
    }
}
