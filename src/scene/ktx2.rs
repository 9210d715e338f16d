//! KTX2 textures with Basis Universal payloads (glTF's `KHR_texture_basisu`), decoded to RGBA8
//! for the path tracer, which samples every texture itself.
//!
//! The container is read by the `ktx2` crate; the texels come from Binomial's Basis Universal
//! transcoder (the `basis-universal` crate, which builds its C++). That crate transcodes
//! `.basis` files, whose content is the same as a Basis KTX2's: ETC1S (BasisLZ) keeps its
//! endpoint and selector codebooks and Huffman tables in the KTX2's supercompression global
//! data and its slices in the levels; UASTC keeps its 16-byte blocks in the levels, optionally
//! Zstandard-compressed (decompressed here with `ruzstd`). So the largest level is rewrapped
//! as a one-image `.basis` file in memory — the header, one or two slice descriptions (colour,
//! and alpha for ETC1S with alpha), the codebooks and the slice data, with the format's CRCs —
//! and transcoded to RGBA32. Only the largest level is decoded: the tracer filters the full
//! image itself. Arrays, cube maps and volumes are not textures glTF uses and are refused.
//!
//! Every length and offset is checked against the file before anything is handed to the C++
//! transcoder, and the decoded size is bounded ([`MAX_TEXELS`]); the fuzz target `ktx2` runs
//! this decoder on arbitrary bytes.

use basis_universal::{TranscodeParameters, Transcoder, TranscoderTextureFormat};
use ktx2::{ColorModel, SupercompressionScheme};

/// The largest texture decoded (texels): 64 Mi, 256 MiB of RGBA8, the loader's image bound.
pub const MAX_TEXELS: u64 = 1 << 26;

/// What in a KTX2 file is wrong or unsupported.
#[derive(Debug, thiserror::Error)]
pub enum Ktx2Error {
    #[error("not a valid KTX2 file ({0})")]
    Container(ktx2::ParseError),
    #[error(
        "not a valid KTX2 file (its data format descriptor has {len} bytes, fewer than its \
         length field)"
    )]
    ShortDescriptor { len: usize },
    #[error(
        "not a valid KTX2 file (its data format descriptor has a texel block dimension of 256)"
    )]
    BlockDimension256,
    #[error(
        "a KTX2 {kind} (depth {depth}, {layers} layers, {faces} faces): glTF textures are \
         single 2D images"
    )]
    Not2d {
        kind: &'static str,
        depth: u32,
        layers: u32,
        faces: u32,
    },
    #[error("a KTX2 image without pixels")]
    NoPixels,
    #[error("a {width}×{height} KTX2 image is larger than {MAX_TEXELS} texels")]
    TooLarge { width: u32, height: u32 },
    #[error(
        "KTX2 format {0:?}: KHR_texture_basisu textures hold Basis Universal data (ETC1S or UASTC)"
    )]
    Format(ktx2::Format),
    #[error("a KTX2 file without a basic data format descriptor")]
    NoDescriptor,
    #[error("a KTX2 file without levels")]
    NoLevels,
    #[error("UASTC with supercompression {0:?}")]
    UastcSupercompression(SupercompressionScheme),
    #[error("its UASTC level 0 holds {bytes} bytes, {width}×{height} needs {expected}")]
    UastcLength {
        bytes: usize,
        width: u32,
        height: u32,
        expected: u64,
    },
    #[error(
        "KTX2 colour model {model:?} with supercompression {scheme:?}: not Basis Universal \
         ETC1S (BasisLZ) or UASTC"
    )]
    NotBasis {
        model: Option<ColorModel>,
        scheme: Option<SupercompressionScheme>,
    },
    #[error("a level of {0} bytes")]
    LevelTooLarge(u64),
    #[error("its Zstandard level does not decode ({0})")]
    Zstd(String),
    #[error("its Zstandard level decodes to {got} bytes, its index says {expected}")]
    ZstdLength { got: usize, expected: u64 },
    #[error("its BasisLZ global data ends inside the {0}")]
    GlobalDataEnds(String),
    #[error("its BasisLZ global data has empty codebooks")]
    EmptyCodebooks,
    #[error("its {0} slice lies outside level 0")]
    SliceOutside(&'static str),
    #[error("its {what} ({n}) does not fit a Basis Universal file")]
    DoesNotFit { what: String, n: u64 },
    #[error("its Basis Universal data is inconsistent")]
    Inconsistent,
    #[error("its Basis Universal codebooks do not decode")]
    Codebooks,
    #[error("its Basis Universal blocks do not transcode ({0})")]
    Blocks(String),
    #[error("the transcoder returned fewer texels than the image has")]
    FewerTexels,
}

/// A decoded KTX2: width, height and RGBA8 texels, row-major from the top.
pub type Rgba8 = (u32, u32, Vec<[u8; 4]>);

/// Decodes the largest level of a Basis Universal KTX2 (`KHR_texture_basisu`) into RGBA8; the
/// error says what in the file is wrong or unsupported.
pub fn decode(bytes: &[u8]) -> Result<Rgba8, Ktx2Error> {
    refuse_what_the_parser_panics_on(bytes)?;
    let reader = ktx2::Reader::new(bytes).map_err(Ktx2Error::Container)?;
    let header = reader.header();
    let (width, height) = (header.pixel_width, header.pixel_height);
    if header.pixel_depth > 1 || header.layer_count > 1 || header.face_count != 1 {
        return Err(Ktx2Error::Not2d {
            kind: if header.face_count == 6 {
                "cube map"
            } else {
                "array or volume"
            },
            depth: header.pixel_depth,
            layers: header.layer_count,
            faces: header.face_count,
        });
    }
    if width == 0 || height == 0 {
        return Err(Ktx2Error::NoPixels);
    }
    if u64::from(width) * u64::from(height) > MAX_TEXELS {
        return Err(Ktx2Error::TooLarge { width, height });
    }
    if let Some(format) = header.format {
        return Err(Ktx2Error::Format(format));
    }
    let dfd = reader.basic_dfd().ok_or(Ktx2Error::NoDescriptor)?;
    let level = reader.levels().next().ok_or(Ktx2Error::NoLevels)?;
    let blocks = [width.div_ceil(4), height.div_ceil(4)];
    let basis = match (dfd.color_model, header.supercompression_scheme) {
        (Some(ColorModel::ETC1S), Some(SupercompressionScheme::BasisLZ)) => {
            let alpha = dfd.sample_information.len() == 2;
            // Image descriptions: one per level, layer and face (KTX2 §3.12.2).
            let images = header.level_count.max(1);
            let global = reader.supercompression_global_data();
            etc1s_basis(global, images, level.data, width, height, alpha)?
        }
        (Some(ColorModel::UASTC), scheme) => {
            let data = match scheme {
                None => level.data.to_vec(),
                Some(SupercompressionScheme::Zstandard) => {
                    zstd(level.data, level.uncompressed_byte_length)?
                }
                Some(other) => {
                    return Err(Ktx2Error::UastcSupercompression(other));
                }
            };
            let expected = u64::from(blocks[0]) * u64::from(blocks[1]) * 16;
            if data.len() as u64 != expected {
                return Err(Ktx2Error::UastcLength {
                    bytes: data.len(),
                    width,
                    height,
                    expected,
                });
            }
            // Channel type 3 (RGBA) or 5 (RRRG) carries alpha (KTX2 §3.10.2).
            let alpha = dfd
                .sample_information
                .first()
                .is_some_and(|s| matches!(s.channel_type, 3 | 5));
            let flags = if alpha { SLICE_HAS_ALPHA } else { 0 };
            basis_file(BasisHeader {
                etc1s: false,
                width,
                height,
                has_alpha_slices: alpha,
                codebooks: &[],
                slices: &[(flags, data.as_slice())],
            })?
        }
        (model, scheme) => {
            return Err(Ktx2Error::NotBasis { model, scheme });
        }
    };
    transcode(&basis, width, height)
}

/// The two malformed data format descriptors on which the `ktx2` crate (0.5) panics instead of
/// returning an error (found by the fuzz target): a descriptor shorter than its own length
/// field, and a basic block with a texel block dimension byte of 255 (dimension 256, which
/// the crate's `NonZeroU8` cannot hold). Everything else the crate checks itself.
fn refuse_what_the_parser_panics_on(bytes: &[u8]) -> Result<(), Ktx2Error> {
    let u32_at = |at: usize| -> Option<usize> {
        Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?) as usize)
    };
    let u16_at = |at: usize| -> Option<usize> {
        Some(u16::from_le_bytes(bytes.get(at..at + 2)?.try_into().ok()?) as usize)
    };
    let (Some(start), Some(len)) = (u32_at(48), u32_at(52)) else {
        return Ok(()); // too short: the crate says so
    };
    if len < 4 {
        return Err(Ktx2Error::ShortDescriptor { len });
    }
    let end = (start + len).min(bytes.len());
    let mut at = start + 4;
    while at + 8 <= end {
        let (Some(kind), Some(version), Some(size)) = (u32_at(at), u16_at(at + 4), u16_at(at + 6))
        else {
            break;
        };
        if size < 8 {
            break; // the crate reports it
        }
        // Vendor 0, type 0, version 2: a basic block, whose bytes 12..16 are the dimensions − 1.
        if kind == 0
            && version == 2
            && size >= 16
            && at + 16 <= end
            && bytes[at + 12..at + 16].contains(&255)
        {
            return Err(Ktx2Error::BlockDimension256);
        }
        at += size;
    }
    Ok(())
}

/// Zstandard-decompresses a UASTC level to exactly `expected` bytes.
fn zstd(data: &[u8], expected: u64) -> Result<Vec<u8>, Ktx2Error> {
    use std::io::Read;
    if expected > MAX_TEXELS * 4 {
        return Err(Ktx2Error::LevelTooLarge(expected));
    }
    let mut decoder = ruzstd::decoding::StreamingDecoder::new(data)
        .map_err(|e| Ktx2Error::Zstd(e.to_string()))?;
    let mut out = Vec::with_capacity(expected as usize);
    // One byte more than expected tells a longer stream from an exact one.
    (&mut decoder)
        .take(expected + 1)
        .read_to_end(&mut out)
        .map_err(|e| Ktx2Error::Zstd(e.to_string()))?;
    if out.len() as u64 != expected {
        return Err(Ktx2Error::ZstdLength {
            got: out.len(),
            expected,
        });
    }
    Ok(out)
}

/// Little-endian reads from the supercompression global data.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], Ktx2Error> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| Ktx2Error::GlobalDataEnds(what.to_owned()))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u16(&mut self, what: &str) -> Result<u16, Ktx2Error> {
        Ok(u16::from_le_bytes(self.take(2, what)?.try_into().unwrap()))
    }

    fn u32(&mut self, what: &str) -> Result<u32, Ktx2Error> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
}

/// An ETC1S KTX2's level 0 as a `.basis` file: the global data (KTX2 §3.12.2: endpoint and
/// selector counts, the four section lengths, one image description per image, then the
/// endpoint codebook, selector codebook, Huffman tables and extended data) and its first
/// image's colour (and alpha) slice.
fn etc1s_basis(
    global: &[u8],
    images: u32,
    level: &[u8],
    width: u32,
    height: u32,
    alpha: bool,
) -> Result<Vec<u8>, Ktx2Error> {
    let mut c = Cursor {
        bytes: global,
        at: 0,
    };
    let endpoints = c.u16("endpoint count")?;
    let selectors = c.u16("selector count")?;
    let endpoints_len = c.u32("endpoint codebook length")?;
    let selectors_len = c.u32("selector codebook length")?;
    let tables_len = c.u32("tables length")?;
    let _extended_len = c.u32("extended data length")?;
    // One 20-byte description per image, level 0's first: its flags (P-frames matter only
    // to video), then its colour and alpha slices' offsets and lengths within the level.
    let first = c.take(20, "image descriptions")?;
    let word = |i: usize| u32::from_le_bytes(first[4 * i..4 * i + 4].try_into().unwrap());
    let (rgb, a) = ((word(1), word(2)), (word(3), word(4)));
    c.take(20 * (images as usize - 1), "image descriptions")?;
    let ep = c.take(endpoints_len as usize, "endpoint codebook")?;
    let sel = c.take(selectors_len as usize, "selector codebook")?;
    let tables = c.take(tables_len as usize, "Huffman tables")?;
    if endpoints == 0 || selectors == 0 || ep.is_empty() || sel.is_empty() || tables.is_empty() {
        return Err(Ktx2Error::EmptyCodebooks);
    }
    let slice = |(off, len): (u32, u32), what: &'static str| {
        (off as usize)
            .checked_add(len as usize)
            .and_then(|end| level.get(off as usize..end))
            .filter(|s| !s.is_empty())
            .ok_or(Ktx2Error::SliceOutside(what))
    };
    let mut slices = vec![(0u32, slice(rgb, "colour")?)];
    if alpha {
        slices.push((SLICE_HAS_ALPHA, slice(a, "alpha")?));
    }
    basis_file(BasisHeader {
        etc1s: true,
        width,
        height,
        has_alpha_slices: alpha,
        codebooks: &[
            (u32::from(endpoints), ep),
            (u32::from(selectors), sel),
            (0, tables),
        ],
        slices: &slices,
    })
}

/// `basis_slice_desc_flags`: the slice holds alpha.
const SLICE_HAS_ALPHA: u32 = 1;

/// What a one-image, one-level `.basis` file holds.
struct BasisHeader<'a> {
    etc1s: bool,
    width: u32,
    height: u32,
    has_alpha_slices: bool,
    /// ETC1S: (endpoint count, codebook), (selector count, codebook), (0, Huffman tables).
    codebooks: &'a [(u32, &'a [u8])],
    /// (flags, data) per slice: colour, then alpha.
    slices: &'a [(u32, &'a [u8])],
}

/// `sizeof(basis_file_header)` and `sizeof(basis_slice_desc)` (packed, little-endian).
const HEADER_LEN: usize = 77;
const SLICE_DESC_LEN: usize = 23;

/// Writes `n`'s low `bytes` bytes (little-endian), refusing values that do not fit.
fn put(out: &mut Vec<u8>, n: u64, bytes: usize, what: &str) -> Result<(), Ktx2Error> {
    if bytes < 8 && n >> (8 * bytes) != 0 {
        return Err(Ktx2Error::DoesNotFit {
            what: what.to_owned(),
            n,
        });
    }
    out.extend_from_slice(&n.to_le_bytes()[..bytes]);
    Ok(())
}

/// Basis Universal's CRC-16 (`basist::crc16`).
fn crc16(bytes: &[u8]) -> u16 {
    let mut crc: u16 = !0;
    for &b in bytes {
        let q = u16::from(b) ^ (crc >> 8);
        let k = (q >> 4) ^ q;
        crc = (crc << 8) ^ k ^ (k << 5) ^ (k << 12);
    }
    !crc
}

/// A `.basis` file (format version 0x13) with one image of one level.
fn basis_file(h: BasisHeader) -> Result<Vec<u8>, Ktx2Error> {
    let descs_at = HEADER_LEN;
    let mut at = descs_at + SLICE_DESC_LEN * h.slices.len();
    let mut sections = Vec::new();
    for (_, data) in h.codebooks {
        sections.push((at, data.len()));
        at += data.len();
    }
    let mut slice_at = Vec::new();
    for (_, data) in h.slices {
        slice_at.push(at);
        at += data.len();
    }
    let section = |i: usize| sections.get(i).copied().unwrap_or((0, 0));
    let count = |i: usize| h.codebooks.get(i).map_or(0, |c| c.0);

    let mut data = Vec::with_capacity(at - HEADER_LEN);
    let blocks = [h.width.div_ceil(4), h.height.div_ceil(4)];
    for ((flags, slice), &ofs) in h.slices.iter().zip(&slice_at) {
        put(&mut data, 0, 3, "image index")?;
        put(&mut data, 0, 1, "level index")?;
        put(&mut data, u64::from(*flags), 1, "slice flags")?;
        put(&mut data, u64::from(h.width), 2, "width")?;
        put(&mut data, u64::from(h.height), 2, "height")?;
        put(&mut data, u64::from(blocks[0]), 2, "block columns")?;
        put(&mut data, u64::from(blocks[1]), 2, "block rows")?;
        put(&mut data, ofs as u64, 4, "slice offset")?;
        put(&mut data, slice.len() as u64, 4, "slice length")?;
        put(&mut data, u64::from(crc16(slice)), 2, "slice CRC")?;
    }
    for (_, cb) in h.codebooks {
        data.extend_from_slice(cb);
    }
    for (_, slice) in h.slices {
        data.extend_from_slice(slice);
    }

    let mut head = Vec::with_capacity(HEADER_LEN);
    put(
        &mut head,
        u64::from(u16::from_be_bytes([b'B', b's'])),
        2,
        "signature",
    )?;
    put(&mut head, 0x13, 2, "version")?;
    put(&mut head, HEADER_LEN as u64, 2, "header size")?;
    put(&mut head, 0, 2, "header CRC")?; // filled in below
    put(&mut head, data.len() as u64, 4, "data size")?;
    put(&mut head, u64::from(crc16(&data)), 2, "data CRC")?;
    put(&mut head, h.slices.len() as u64, 3, "slice count")?;
    put(&mut head, 1, 3, "image count")?;
    put(&mut head, u64::from(!h.etc1s), 1, "texture format")?;
    let flags = u64::from(h.etc1s) | if h.has_alpha_slices { 4 } else { 0 };
    put(&mut head, flags, 2, "flags")?;
    put(&mut head, 0, 1, "texture type")?; // 2D
    put(&mut head, 0, 3, "frame time")?;
    put(&mut head, 0, 4, "reserved")?;
    put(&mut head, 0, 4, "user data")?;
    put(&mut head, 0, 4, "user data")?;
    for (i, what) in [(0, "endpoint"), (1, "selector")] {
        put(&mut head, u64::from(count(i)), 2, &format!("{what} count"))?;
        put(
            &mut head,
            section(i).0 as u64,
            4,
            &format!("{what} codebook offset"),
        )?;
        put(
            &mut head,
            section(i).1 as u64,
            3,
            &format!("{what} codebook length"),
        )?;
    }
    put(&mut head, section(2).0 as u64, 4, "tables offset")?;
    put(&mut head, section(2).1 as u64, 4, "tables length")?;
    put(&mut head, descs_at as u64, 4, "slice descriptions offset")?;
    put(&mut head, 0, 4, "extended data offset")?;
    put(&mut head, 0, 4, "extended data length")?;
    debug_assert_eq!(head.len(), HEADER_LEN);
    let crc = crc16(&head[8..]);
    head[6..8].copy_from_slice(&crc.to_le_bytes());
    head.extend_from_slice(&data);
    Ok(head)
}

/// Transcodes a `.basis` file's one image to RGBA8.
fn transcode(basis: &[u8], width: u32, height: u32) -> Result<Rgba8, Ktx2Error> {
    let mut transcoder = Transcoder::new();
    if !transcoder.validate_header(basis) {
        return Err(Ktx2Error::Inconsistent);
    }
    transcoder
        .prepare_transcoding(basis)
        .map_err(|()| Ktx2Error::Codebooks)?;
    let rgba = transcoder
        .transcode_image_level(
            basis,
            TranscoderTextureFormat::RGBA32,
            TranscodeParameters {
                image_index: 0,
                level_index: 0,
                ..Default::default()
            },
        )
        .map_err(|e| Ktx2Error::Blocks(format!("{e:?}")))?;
    transcoder.end_transcoding();
    let n = width as usize * height as usize;
    if rgba.len() < 4 * n {
        return Err(Ktx2Error::FewerTexels);
    }
    Ok((
        width,
        height,
        rgba.chunks_exact(4)
            .take(n)
            .map(|p| [p[0], p[1], p[2], p[3]])
            .collect(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `.basis` wrapper of a file carries the CRCs Basis Universal's own check computes.
    #[test]
    fn the_basis_wrapper_passes_basis_universals_checksums() {
        let blocks = vec![0x5au8; 16 * 4];
        let basis = basis_file(BasisHeader {
            etc1s: false,
            width: 8,
            height: 7,
            has_alpha_slices: false,
            codebooks: &[],
            slices: &[(0, blocks.as_slice())],
        })
        .unwrap();
        let t = Transcoder::new();
        assert!(t.validate_header(&basis));
        assert!(t.validate_file_checksums(&basis, true));
        let mut broken = basis.clone();
        *broken.last_mut().unwrap() ^= 1;
        assert!(!t.validate_file_checksums(&broken, true));
    }
}
