//! What crosses the link, as bytes (all little-endian): rank 0's control of a frame, the
//! schedule's slot masks, samples, owned pixels' sums and counts, and f32 arrays such as the DGI.

use glam::{DVec2, DVec3, Vec3};

use crate::roi::cone::Cone;
use crate::roi::dgi::Roi;
use crate::schedule::SlotMask;

/// What rank 0 tells every rank before a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameControl {
    pub iteration: u32,
    /// No frame: the render ends here.
    pub stop: bool,
    /// After this frame, the owners send rank 0 the sums of the ROI's pixels
    /// ([`crate::frame::Render::roi_progress`]: a stop condition on the ROI's progress).
    pub measure: bool,
    /// `Some`: the ROI changed to this (`Some(None)`: no ROI, sample everything).
    pub roi: Option<Option<Roi>>,
    /// `Some`: rank 0's tracked head moved the wall camera's eye here (room frame) and
    /// restarted the accumulation (DESIGN.md §11); every other rank does the same before
    /// this frame.
    pub eye: Option<DVec3>,
}

impl FrameControl {
    /// Little-endian bytes: iteration, flags, ROI kind, then the ROI's and the eye's f64s.
    #[must_use]
    pub fn encode(&self) -> Vec<u8> {
        let mut b = self.iteration.to_le_bytes().to_vec();
        let flags = u8::from(self.stop) | u8::from(self.roi.is_some()) << 1;
        let flags = flags | u8::from(self.eye.is_some()) << 2 | u8::from(self.measure) << 3;
        b.push(flags);
        let mut f = Vec::new();
        let kind = match self.roi {
            Some(Some(Roi::Cone(c))) => {
                for v in [c.apex, c.axis, c.right, c.up] {
                    f.extend(v.to_array());
                }
                f.extend([c.tan_h, c.tan_v]);
                1
            }
            Some(Some(Roi::CanvasEllipse { center, semi_axes })) => {
                f.extend([center.x, center.y, semi_axes.x, semi_axes.y]);
                2
            }
            _ => 0,
        };
        b.push(kind);
        if let Some(e) = self.eye {
            f.extend(e.to_array());
        }
        for v in f {
            b.extend(v.to_le_bytes());
        }
        b
    }

    /// The inverse of [`Self::encode`]; `None` for bytes it does not produce.
    #[must_use]
    pub fn decode(b: &[u8]) -> Option<Self> {
        let iteration = u32::from_le_bytes(b.get(..4)?.try_into().ok()?);
        let (flags, kind) = (*b.get(4)?, *b.get(5)?);
        let f: Vec<f64> = b
            .get(6..)?
            .chunks(8)
            .map(|c| c.try_into().ok().map(f64::from_le_bytes))
            .collect::<Option<_>>()?;
        let roi_len = [0, 14, 4][usize::from(kind.min(2))];
        let eye_len = if flags & 4 != 0 { 3 } else { 0 };
        if kind > 2 || f.len() != roi_len + eye_len || flags > 15 {
            return None;
        }
        let v3 = |i: usize| DVec3::new(f[i], f[i + 1], f[i + 2]);
        let roi = match kind {
            1 => Some(Roi::Cone(Cone {
                apex: v3(0),
                axis: v3(3),
                right: v3(6),
                up: v3(9),
                tan_h: f[12],
                tan_v: f[13],
            })),
            2 => Some(Roi::CanvasEllipse {
                center: DVec2::new(f[0], f[1]),
                semi_axes: DVec2::new(f[2], f[3]),
            }),
            _ => None,
        };
        Some(Self {
            iteration,
            stop: flags & 1 != 0,
            measure: flags & 8 != 0,
            roi: (flags & 2 != 0).then_some(roi),
            eye: (eye_len > 0).then(|| v3(roi_len)),
        })
    }
}

/// Blocks' selected slots as bytes: per block a flag byte (0: none), then its mask's 128
/// bytes when the flag is 1.
pub(super) fn encode_masks(masks: &[SlotMask]) -> Vec<u8> {
    let mut b = Vec::new();
    for m in masks {
        if m.iter().all(|&w| w == 0) {
            b.push(0);
        } else {
            b.push(1);
            for w in m {
                b.extend(w.to_le_bytes());
            }
        }
    }
    b
}

/// What is wrong with bytes that should hold blocks' slot masks ([`decode_masks`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub(super) enum MaskBytesError {
    #[error("block {block} of {blocks}: its mask is cut short")]
    CutShort { block: usize, blocks: usize },
    #[error("block {block} of {blocks}: flag {flag}, not 0 or 1")]
    Flag {
        block: usize,
        blocks: usize,
        flag: u8,
    },
    #[error("{len} bytes for {blocks} blocks")]
    TooFew { len: usize, blocks: usize },
    #[error("{len} bytes for {blocks} blocks, {extra} past them")]
    TooMany {
        len: usize,
        blocks: usize,
        extra: usize,
    },
}

/// The inverse of [`encode_masks`] for `blocks` blocks, or what is wrong with the bytes.
pub(super) fn decode_masks(b: &[u8], blocks: usize) -> Result<Vec<SlotMask>, MaskBytesError> {
    let mut out = Vec::with_capacity(blocks);
    let mut at = 0;
    for k in 0..blocks {
        match b.get(at) {
            Some(0) => {
                out.push([0; 32]);
                at += 1;
            }
            Some(1) => {
                let words = b
                    .get(at + 1..at + 129)
                    .ok_or(MaskBytesError::CutShort { block: k, blocks })?;
                let mut m = [0u32; 32];
                for (w, c) in m.iter_mut().zip(words.chunks_exact(4)) {
                    *w = u32::from_le_bytes(c.try_into().expect("4 bytes"));
                }
                out.push(m);
                at += 129;
            }
            Some(&flag) => {
                return Err(MaskBytesError::Flag {
                    block: k,
                    blocks,
                    flag,
                });
            }
            None => {
                return Err(MaskBytesError::TooFew {
                    len: b.len(),
                    blocks,
                });
            }
        }
    }
    if at != b.len() {
        return Err(MaskBytesError::TooMany {
            len: b.len(),
            blocks,
            extra: b.len() - at,
        });
    }
    Ok(out)
}

/// A sample's RGB as it travels: three f32, little-endian.
pub(super) fn rgb_bytes(s: &[f32; 4]) -> [u8; 12] {
    let mut b = [0u8; 12];
    for (c, v) in b.chunks_exact_mut(4).zip(&s[..3]) {
        c.copy_from_slice(&v.to_le_bytes());
    }
    b
}

/// The RGB of a sample's 12 travelling bytes.
pub(super) fn rgb_of(b: &[u8]) -> Vec3 {
    let f = |k: usize| f32::from_le_bytes(b[4 * k..4 * k + 4].try_into().expect("4 bytes"));
    Vec3::new(f(0), f(1), f(2))
}

/// Bytes a pixel's sums and count take on the link: 16 of sums (f32), 4 of count (u32).
pub const PIXEL_BYTES: usize = 20;

/// `pixels` pairs of sums and count from `b` ([`PIXEL_BYTES`] each), or `None` if `b` is not
/// that long.
pub(super) fn sums_and_counts(b: &[u8], pixels: usize) -> Option<Vec<([f32; 4], u32)>> {
    (b.len() == PIXEL_BYTES * pixels).then(|| {
        b.chunks_exact(PIXEL_BYTES)
            .map(|c| {
                let f = |k: usize| f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().expect("4"));
                let n = u32::from_le_bytes(c[16..20].try_into().expect("4"));
                ([f(0), f(1), f(2), f(3)], n)
            })
            .collect()
    })
}

/// f32s as little-endian bytes.
#[must_use]
pub fn f32_bytes(v: &[f32]) -> Vec<u8> {
    if cfg!(target_endian = "little") {
        // The bytes as they lie: a copy, not a value at a time (a DGI is tens of MB).
        bytemuck::cast_slice(v).to_vec()
    } else {
        let mut b = Vec::with_capacity(4 * v.len());
        for x in v {
            b.extend_from_slice(&x.to_le_bytes());
        }
        b
    }
}

/// Little-endian bytes as f32s (a multiple of `group` values; a shorter tail is dropped, and
/// the callers check lengths first).
pub(super) fn f32s(b: &[u8], group: usize) -> Vec<f32> {
    let whole = b.len() / (4 * group) * 4 * group;
    b[..whole]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect()
}
