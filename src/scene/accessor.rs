//! Bounds-checked accessor reads.
//!
//! The `gltf` crate's own reader trusts the file: an accessor whose byte range runs past its
//! buffer view, a zero `count`, or a sparse index past the end makes it panic or underflow
//! (found by fuzzing `Scene::from_glb_bytes`). These readers check every range with checked
//! arithmetic and return an error naming what is wrong; the caller adds the mesh and primitive.

use gltf::accessor::{DataType, Dimensions};

/// The most elements an accessor without a buffer view (all zeros plus sparse overrides) may
/// declare: such an accessor costs memory without costing file bytes, so an unchecked `count`
/// from a hostile file could ask for terabytes. 2^24 vertices is far beyond any single mesh
/// primitive a scene here needs.
const MAX_ZERO_FILLED: usize = 1 << 24;

/// Reads a float vector attribute (`dims` components per element), converting normalized
/// integer components to [0, 1] / [−1, 1] as glTF specifies (so KHR_mesh_quantization-style
/// data reads correctly too). Returns `count × dims` values.
pub(super) fn read_floats(
    acc: &gltf::Accessor,
    buffers: &[Vec<u8>],
    dims: Dimensions,
) -> Result<Vec<f32>, AccessorError> {
    if acc.dimensions() != dims {
        return Err(AccessorError::Type {
            accessor: acc.index(),
            found: acc.dimensions(),
            expected: dims,
        });
    }
    let ty = acc.data_type();
    if ty == DataType::U32 {
        return Err(AccessorError::UnsignedIntAttribute(acc.index()));
    }
    let n = dims.multiplicity();
    let csize = ty.size();
    let normalized = acc.normalized();
    let elements = read_elements(acc, buffers, |bytes| {
        let mut v = [0.0f32; 4];
        for (c, out) in v.iter_mut().enumerate().take(n) {
            *out = component(&bytes[c * csize..(c + 1) * csize], ty, normalized);
        }
        v
    })?;
    Ok(elements
        .iter()
        .flat_map(|v| v[..n].iter().copied())
        .collect())
}

/// Reads a SCALAR unsigned index accessor.
pub(super) fn read_indices(
    acc: &gltf::Accessor,
    buffers: &[Vec<u8>],
) -> Result<Vec<u32>, AccessorError> {
    if acc.dimensions() != Dimensions::Scalar || acc.normalized() {
        return Err(AccessorError::IndexNotScalar(acc.index()));
    }
    let ty = acc.data_type();
    if !matches!(ty, DataType::U8 | DataType::U16 | DataType::U32) {
        return Err(AccessorError::IndexSigned {
            accessor: acc.index(),
            component: ty,
        });
    }
    read_elements(acc, buffers, |bytes| uint(bytes, ty.size()))
}

fn uint(bytes: &[u8], size: usize) -> u32 {
    match size {
        1 => u32::from(bytes[0]),
        2 => u32::from(u16::from_le_bytes([bytes[0], bytes[1]])),
        _ => u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]),
    }
}

/// One component as f32 (glTF 2.0 §3.11: normalized signed values clamp at −1).
fn component(bytes: &[u8], ty: DataType, normalized: bool) -> f32 {
    match ty {
        DataType::F32 => f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]),
        DataType::U8 if normalized => f32::from(bytes[0]) / 255.0,
        DataType::U8 => f32::from(bytes[0]),
        DataType::I8 if normalized => (f32::from(bytes[0] as i8) / 127.0).max(-1.0),
        DataType::I8 => f32::from(bytes[0] as i8),
        DataType::U16 if normalized => {
            f32::from(u16::from_le_bytes([bytes[0], bytes[1]])) / 65535.0
        }
        DataType::U16 => f32::from(u16::from_le_bytes([bytes[0], bytes[1]])),
        DataType::I16 if normalized => {
            (f32::from(i16::from_le_bytes([bytes[0], bytes[1]])) / 32767.0).max(-1.0)
        }
        DataType::I16 => f32::from(i16::from_le_bytes([bytes[0], bytes[1]])),
        DataType::U32 => uint(bytes, 4) as f32,
    }
}

/// Decodes every element of `acc` (dense part, then sparse overrides) with `decode`, which gets
/// exactly `acc.size()` bytes.
fn read_elements<T: Copy + Default>(
    acc: &gltf::Accessor,
    buffers: &[Vec<u8>],
    decode: impl Fn(&[u8]) -> T,
) -> Result<Vec<T>, AccessorError> {
    let count = acc.count();
    let elem = acc.size();
    let mut out: Vec<T> = match acc.view() {
        Some(view) => {
            let stride = view.stride().unwrap_or(elem);
            if stride < elem {
                return Err(AccessorError::Stride {
                    accessor: acc.index(),
                    view: view.index(),
                    stride,
                    elem,
                });
            }
            let bytes = strided_bytes(&view, acc.offset(), count, stride, elem, buffers).map_err(
                |range| AccessorError::Range {
                    accessor: acc.index(),
                    part: "",
                    range,
                },
            )?;
            (0..count)
                .map(|i| decode(&bytes[i * stride..i * stride + elem]))
                .collect()
        }
        None if count > MAX_ZERO_FILLED => {
            return Err(AccessorError::ZeroFilled {
                accessor: acc.index(),
                count,
            });
        }
        None => vec![T::default(); count],
    };
    if let Some(sparse) = acc.sparse() {
        let n = sparse.count();
        let indices = sparse.indices();
        let isize = indices.index_type().size();
        // Sparse index and value views are tightly packed (glTF 2.0 §5.1.7: no byteStride).
        let ib = strided_bytes(&indices.view(), indices.offset(), n, isize, isize, buffers)
            .map_err(|range| AccessorError::Range {
                accessor: acc.index(),
                part: " sparse indices",
                range,
            })?;
        let values = sparse.values();
        let vb = strided_bytes(&values.view(), values.offset(), n, elem, elem, buffers).map_err(
            |range| AccessorError::Range {
                accessor: acc.index(),
                part: " sparse values",
                range,
            },
        )?;
        for k in 0..n {
            let i = uint(&ib[k * isize..(k + 1) * isize], isize) as usize;
            let slot = out.get_mut(i).ok_or(AccessorError::SparseIndex {
                accessor: acc.index(),
                index: i,
                count,
            })?;
            *slot = decode(&vb[k * elem..(k + 1) * elem]);
        }
    }
    Ok(out)
}

/// Why an accessor cannot be read; the caller adds the mesh and primitive.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub(super) enum AccessorError {
    #[error("accessor {accessor} has type {found:?}, expected {expected:?}")]
    Type {
        accessor: usize,
        found: Dimensions,
        expected: Dimensions,
    },
    #[error("accessor {0} has component type UNSIGNED_INT, which vertex attributes may not use")]
    UnsignedIntAttribute(usize),
    #[error("index accessor {0} must be an unnormalized SCALAR")]
    IndexNotScalar(usize),
    #[error("index accessor {accessor} has component type {component:?}; indices must be unsigned")]
    IndexSigned {
        accessor: usize,
        component: DataType,
    },
    #[error(
        "accessor {accessor}: buffer view {view} has byteStride {stride}, less than the {elem}-byte element"
    )]
    Stride {
        accessor: usize,
        view: usize,
        stride: usize,
        elem: usize,
    },
    /// `part` is empty for the dense elements, else " sparse indices" / " sparse values".
    #[error("accessor {accessor}{part}: {range}")]
    Range {
        accessor: usize,
        part: &'static str,
        range: ByteRangeError,
    },
    #[error(
        "accessor {accessor} has no buffer view and declares {count} elements (at most {MAX_ZERO_FILLED})"
    )]
    ZeroFilled { accessor: usize, count: usize },
    #[error("accessor {accessor}: sparse index {index} is past its {count} elements")]
    SparseIndex {
        accessor: usize,
        index: usize,
        count: usize,
    },
}

/// Why a strided byte range does not lie in its buffer view and buffer.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub(super) enum ByteRangeError {
    #[error("byte range overflows (count {count}, stride {stride})")]
    Overflow { count: usize, stride: usize },
    #[error("bytes {start}..{end} run past the end of buffer view {view} ({view_end})")]
    PastView {
        start: usize,
        end: usize,
        view: usize,
        view_end: usize,
    },
    #[error("buffer {0} is not loaded")]
    NotLoaded(usize),
    #[error("buffer view {view} ends at byte {view_end}, past the {len} bytes of buffer {buffer}")]
    PastBuffer {
        view: usize,
        view_end: usize,
        len: usize,
        buffer: usize,
    },
}

/// The bytes of `count` elements of `elem` bytes, `stride` apart, starting `offset` bytes into
/// `view`; relative to the returned slice element i starts at `i * stride`.
fn strided_bytes<'b>(
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    stride: usize,
    elem: usize,
    buffers: &'b [Vec<u8>],
) -> Result<&'b [u8], ByteRangeError> {
    if count == 0 {
        return Ok(&[]);
    }
    let too_big = || ByteRangeError::Overflow { count, stride };
    let start = view.offset().checked_add(offset).ok_or_else(too_big)?;
    let end = stride
        .checked_mul(count - 1)
        .and_then(|b| b.checked_add(elem))
        .and_then(|b| b.checked_add(start))
        .ok_or_else(too_big)?;
    let view_end = view
        .offset()
        .checked_add(view.length())
        .ok_or_else(too_big)?;
    if end > view_end {
        return Err(ByteRangeError::PastView {
            start,
            end,
            view: view.index(),
            view_end,
        });
    }
    let buffer = buffers
        .get(view.buffer().index())
        .ok_or_else(|| ByteRangeError::NotLoaded(view.buffer().index()))?;
    if view_end > buffer.len() {
        return Err(ByteRangeError::PastBuffer {
            view: view.index(),
            view_end,
            len: buffer.len(),
            buffer: view.buffer().index(),
        });
    }
    Ok(&buffer[start..end])
}
