//! What a cached block holds. Heights stored as 16-bit integers with no
//! scale or offset (most DEMs) stay 16-bit integers: half the memory of
//! f32, so twice the blocks under the same budget, and one pass fewer
//! when a block is decoded. Anything else is decoded f32 planes. Readers
//! see f32 either way, the same values: nodata as NaN. Windows of a
//! level are copied out of blocks into planes each thread keeps for its
//! next window, not into fresh memory a tile.

use std::borrow::Cow;
use std::cell::RefCell;

/// A block of a level, `width` x `height` pixels.
#[derive(Debug)]
pub(crate) struct Block {
    pub width: usize,
    pub height: usize,
    pub pixels: Pixels,
}

/// A block's pixels.
#[derive(Debug)]
pub(crate) enum Pixels {
    /// Decoded planes: heights in metres with nodata as NaN, or premultiplied RGBA.
    Planes(Vec<Vec<f32>>),
    /// Heights in metres as the file's 16-bit integers; `nodata`, when the
    /// band's nodata value is such an integer, reads as NaN.
    Int16 { values: Vec<i16>, nodata: Option<i16> },
}

impl Pixels {
    /// The pixels as f32 planes.
    pub(crate) fn into_planes(self) -> Vec<Vec<f32>> {
        match self {
            Self::Planes(planes) => planes,
            Self::Int16 { values, nodata } => vec![widened(&values, nodata)],
        }
    }
}

impl Block {
    /// What the block weighs in the cache.
    pub(crate) fn bytes(&self) -> u32 {
        let payload = match &self.pixels {
            Pixels::Planes(planes) => planes.iter().map(Vec::len).sum::<usize>() * 4,
            Pixels::Int16 { values, .. } => values.len() * 2,
        };
        (payload + 64).min(u32::MAX as usize) as u32
    }

    /// Appends `n` values of plane `plane` from `from` (row-major, `width`
    /// a row), as f32, to `out`.
    pub(crate) fn extend(&self, plane: usize, from: usize, n: usize, out: &mut Vec<f32>) {
        match &self.pixels {
            Pixels::Planes(planes) => out.extend_from_slice(&planes[plane][from..from + n]),
            Pixels::Int16 { values, nodata } => {
                debug_assert_eq!(plane, 0, "16-bit heights are one plane");
                let at = out.len();
                out.resize(at + n, 0.0);
                widen(&values[from..from + n], *nodata, &mut out[at..]);
            }
        }
    }

    /// Every plane as f32 (16-bit heights widened into a copy).
    pub(crate) fn planes(&self) -> Vec<Cow<'_, [f32]>> {
        match &self.pixels {
            Pixels::Planes(planes) => planes.iter().map(|p| Cow::Borrowed(p.as_slice())).collect(),
            Pixels::Int16 { values, nodata } => vec![Cow::Owned(widened(values, *nodata))],
        }
    }
}

/// A rectangle of one level's pixels, copied out of its blocks.
#[derive(Debug)]
pub(crate) struct Window {
    pub width: usize,
    pub height: usize,
    pub planes: Vec<Vec<f32>>,
}

/// Planes a thread keeps for its next windows, and the largest kept (in
/// values: 4 MB).
const SPARE_PLANES: usize = 4;
const SPARE_LARGEST: usize = 1 << 20;

thread_local! {
    static SPARE: RefCell<Vec<Vec<f32>>> = const { RefCell::new(Vec::new()) };
}

impl Window {
    /// An empty plane with room for `n` values: one this thread kept, if any.
    pub(crate) fn plane(n: usize) -> Vec<f32> {
        let mut plane = SPARE.with(|s| s.borrow_mut().pop()).unwrap_or_default();
        plane.clear();
        plane.reserve_exact(n);
        plane
    }
}

impl Drop for Window {
    fn drop(&mut self) {
        let planes = std::mem::take(&mut self.planes);
        // A thread being torn down keeps nothing.
        let _ = SPARE.try_with(|s| {
            let mut spare = s.borrow_mut();
            for plane in planes.into_iter().filter(|p| p.capacity() <= SPARE_LARGEST) {
                if spare.len() < SPARE_PLANES {
                    spare.push(plane);
                }
            }
        });
    }
}

/// `v` as a 16-bit signed integer, when it is one exactly.
pub(crate) fn exact_i16(v: f32) -> Option<i16> {
    (v == v.trunc() && (f32::from(i16::MIN)..=f32::from(i16::MAX)).contains(&v)).then_some(v as i16)
}

/// Heights from 16-bit values, `nodata` as NaN, in a plane of their own.
fn widened(values: &[i16], nodata: Option<i16>) -> Vec<f32> {
    let mut plane = vec![0.0; values.len()];
    widen(values, nodata, &mut plane);
    plane
}

/// Heights from 16-bit values, `nodata` as NaN, in a loop the compiler
/// can vectorise.
fn widen(values: &[i16], nodata: Option<i16>, out: &mut [f32]) {
    // Outside i16's range: matches no value.
    let nodata = nodata.map_or(i32::MIN, i32::from);
    for (o, &v) in out.iter_mut().zip(values) {
        *o = if i32::from(v) == nodata { f32::NAN } else { f32::from(v) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sixteen_bit_heights_read_as_their_f32_planes() {
        let values: Vec<i16> = vec![-32768, -9999, -1, 0, 1, 8848, 32767, -9999];
        let block = |nodata| Block { width: 4, height: 2, pixels: Pixels::Int16 { values: values.clone(), nodata } };
        let with = block(Some(-9999));
        let planes = with.planes();
        let want = [-32768.0, f32::NAN, -1.0, 0.0, 1.0, 8848.0, 32767.0, f32::NAN];
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
        assert_eq!(bits(&planes[0]), bits(&want));
        let mut row = vec![1.0f32];
        with.extend(0, 5, 3, &mut row);
        assert_eq!(bits(&row), bits(&[1.0, 8848.0, 32767.0, f32::NAN]));
        assert_eq!(with.bytes(), 8 * 2 + 64, "two bytes a pixel");
        // No nodata: every value is a height.
        let without = block(None).planes()[0].to_vec();
        assert_eq!(without, values.iter().map(|&v| f32::from(v)).collect::<Vec<f32>>());
        assert_eq!(bits(&block(Some(-9999)).pixels.into_planes()[0]), bits(&want));
    }

    #[test]
    fn only_whole_numbers_in_range_are_sixteen_bit_nodata() {
        assert_eq!(exact_i16(-9999.0), Some(-9999));
        assert_eq!(exact_i16(-32768.0), Some(i16::MIN));
        assert_eq!(exact_i16(32767.0), Some(i16::MAX));
        for v in [-32769.0, 32768.0, 0.5, f32::NAN, f32::INFINITY, -3.4e38] {
            assert_eq!(exact_i16(v), None, "{v}");
        }
    }
}
