//! Reading accessors out of buffer bytes, with every offset checked.
//!
//! The gltf crate's own reader assumes valid data (it may panic or read
//! garbage on a short buffer or a wrong component type), so this module
//! reads the bytes itself: dense and sparse accessors, every component type,
//! normalized integers scaled as the specification says.

use std::borrow::Cow;

use gltf::accessor::{DataType, sparse::IndexType};
use gltf::{Accessor, buffer::View};

/// The bytes of each buffer, by index; `None` for a buffer nothing reads.
pub(crate) struct Buffers<'a>(pub(crate) Vec<Option<Cow<'a, [u8]>>>);

impl Buffers<'_> {
    fn view(&self, view: &View<'_>) -> Result<&[u8], String> {
        let buffer = view.buffer().index();
        let data =
            self.0.get(buffer).and_then(Option::as_deref).ok_or_else(|| format!("buffer {buffer} is not loaded"))?;
        let end = view.offset().saturating_add(view.length());
        data.get(view.offset()..end).ok_or_else(|| {
            format!(
                "buffer view {} reaches byte {end} of buffer {buffer}, which has {} bytes",
                view.index(),
                data.len()
            )
        })
    }
}

/// An accessor's components as `f32`, element after element
/// (`width` components each, as its type says: 3 for a VEC3).
pub(crate) fn read_floats(accessor: &Accessor<'_>, buffers: &Buffers<'_>) -> Result<Vec<f32>, String> {
    let width = accessor.dimensions().multiplicity();
    let (kind, normalized) = (accessor.data_type(), accessor.normalized());
    let size = kind.size();
    let mut out = vec![0.0; accessor.count() * width];
    for_each_element(accessor, buffers, |i, bytes| {
        for (c, component) in bytes.chunks_exact(size).take(width).enumerate() {
            out[i * width + c] = float(component, kind, normalized);
        }
    })?;
    Ok(out)
}

/// A scalar integer accessor's values (the indices of a primitive).
pub(crate) fn read_indices(accessor: &Accessor<'_>, buffers: &Buffers<'_>) -> Result<Vec<u32>, String> {
    let kind = accessor.data_type();
    if accessor.dimensions().multiplicity() != 1 || !matches!(kind, DataType::U8 | DataType::U16 | DataType::U32) {
        return Err(format!("accessor {} of indices is not unsigned integer scalars", accessor.index()));
    }
    let mut out = vec![0; accessor.count()];
    for_each_element(accessor, buffers, |i, bytes| out[i] = unsigned(bytes, kind.size()))?;
    Ok(out)
}

/// Calls `f(index, bytes)` for each element stored in the accessor's buffer
/// view, then for each sparse substitute; elements with no bytes (no view)
/// are left to the caller's zeros.
fn for_each_element(
    accessor: &Accessor<'_>,
    buffers: &Buffers<'_>,
    mut f: impl FnMut(usize, &[u8]),
) -> Result<(), String> {
    let index = accessor.index();
    let element = accessor.data_type().size() * accessor.dimensions().multiplicity();
    let count = accessor.count();
    if let Some(view) = accessor.view() {
        let stride = view.stride().unwrap_or(element);
        if stride < element {
            return Err(format!(
                "buffer view {} has a stride of {stride} bytes, shorter than an element",
                view.index()
            ));
        }
        let bytes = buffers.view(&view)?;
        for (i, e) in elements(bytes, accessor.offset(), stride, count, element)
            .map_err(|end| format!("accessor {index} reaches byte {end} of buffer view {}", view.index()))?
            .enumerate()
        {
            f(i, e);
        }
    }
    if let Some(sparse) = accessor.sparse() {
        let n = sparse.count();
        let (indices, values) = (sparse.indices(), sparse.values());
        let index_size = match indices.index_type() {
            IndexType::U8 => 1,
            IndexType::U16 => 2,
            IndexType::U32 => 4,
        };
        let index_bytes = elements(buffers.view(&indices.view())?, indices.offset(), index_size, n, index_size)
            .map_err(|end| format!("accessor {index}'s sparse indices reach byte {end} of their buffer view"))?;
        let value_bytes = elements(buffers.view(&values.view())?, values.offset(), element, n, element)
            .map_err(|end| format!("accessor {index}'s sparse values reach byte {end} of their buffer view"))?;
        for (at, value) in index_bytes.zip(value_bytes) {
            let at = unsigned(at, index_size) as usize;
            if at >= count {
                return Err(format!("accessor {index} has a sparse index {at}, past its {count} elements"));
            }
            f(at, value);
        }
    }
    Ok(())
}

/// `count` slices of `element` bytes, `stride` apart from `offset`; the end
/// byte needed when `bytes` is too short.
fn elements(
    bytes: &[u8],
    offset: usize,
    stride: usize,
    count: usize,
    element: usize,
) -> Result<impl Iterator<Item = &[u8]>, usize> {
    if count > 0 {
        let end = (count - 1).saturating_mul(stride).saturating_add(offset).saturating_add(element);
        if end > bytes.len() {
            return Err(end);
        }
    }
    Ok((0..count).map(move |i| &bytes[offset + i * stride..offset + i * stride + element]))
}

fn unsigned(bytes: &[u8], size: usize) -> u32 {
    match size {
        1 => u32::from(bytes[0]),
        2 => u32::from(u16::from_le_bytes([bytes[0], bytes[1]])),
        _ => u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]),
    }
}

/// One component as `f32`; normalized integers map to 0..1 (unsigned) or
/// -1..1 (signed) as the glTF specification says.
fn float(bytes: &[u8], kind: DataType, normalized: bool) -> f32 {
    match kind {
        DataType::F32 => f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]),
        DataType::U8 if normalized => f32::from(bytes[0]) / 255.0,
        DataType::U8 => f32::from(bytes[0]),
        DataType::I8 if normalized => (f32::from(bytes[0] as i8) / 127.0).max(-1.0),
        DataType::I8 => f32::from(bytes[0] as i8),
        DataType::U16 if normalized => f32::from(u16::from_le_bytes([bytes[0], bytes[1]])) / 65535.0,
        DataType::U16 => f32::from(u16::from_le_bytes([bytes[0], bytes[1]])),
        DataType::I16 if normalized => (f32::from(i16::from_le_bytes([bytes[0], bytes[1]])) / 32767.0).max(-1.0),
        DataType::I16 => f32::from(i16::from_le_bytes([bytes[0], bytes[1]])),
        DataType::U32 => unsigned(bytes, 4) as f32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalized_integers_scale_as_the_spec_says() {
        assert_eq!(float(&[255], DataType::U8, true), 1.0);
        assert_eq!(float(&[0x81], DataType::I8, true), -1.0);
        assert_eq!(float(&[0x80], DataType::I8, true), -1.0);
        assert_eq!(float(&[0xff, 0x7f], DataType::I16, true), 1.0);
        assert_eq!(float(&[7, 0], DataType::U16, false), 7.0);
        assert_eq!(float(&1.5f32.to_le_bytes(), DataType::F32, false), 1.5);
    }

    #[test]
    fn elements_respect_stride_and_bounds() {
        let bytes: Vec<u8> = (0..10).collect();
        let got: Vec<&[u8]> = elements(&bytes, 0, 4, 3, 2).unwrap().collect();
        assert_eq!(got, [&[0, 1][..], &[4, 5], &[8, 9]]);
        assert_eq!(elements(&bytes, 1, 4, 3, 2).err(), Some(11));
        assert_eq!(elements(&bytes, 100, 4, 0, 2).map(Iterator::count).ok(), Some(0));
    }
}
