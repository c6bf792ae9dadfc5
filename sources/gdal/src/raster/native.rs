//! Blocks of a plain GeoTIFF decoded by relief itself: one band of bytes,
//! 16-bit integers or 32-bit floats, tiled or in strips, stored raw or
//! deflated, with or without a predictor. GDAL decodes the same bytes to
//! the same values (a test compares every such layout), but a block read
//! through GDAL is inflated into GDAL's block cache, copied into the
//! window asked for and widened to f32 there: three passes and two fresh
//! buffers a block. Here the file's bytes go to f32 in one pass, through
//! buffers kept by each thread. Anything else (another compression or
//! type, pixel-interleaved bands, a mask, a block that will not inflate to
//! its size) is left to GDAL.

use std::cell::RefCell;
use std::path::Path;

use gdal::Dataset;
use gdal::raster::GdalDataType;
use libdeflater::Decompressor;

use super::pixels::exact_i16;
use super::tiff::{self, Image};
use super::{FileStamp, PixelRect};
use crate::objects::RangeFile;

/// A file whose images relief decodes, and the file they were read from,
/// open while this version is read.
#[derive(Debug)]
pub(crate) struct Native {
    /// The file as its block tables were read (reads check it still is).
    pub stamp: FileStamp,
    file: RangeFile,
    /// The band's base image and its overviews decoded here (any other
    /// level is read through GDAL or halved).
    images: Vec<Level>,
    /// What a block the file does not store holds, as GDAL reads it: the
    /// band's nodata value as the band's type holds it, else 0.
    fill: f32,
}

/// One image of the file decoded here.
#[derive(Debug)]
struct Level {
    image: Image,
    /// The plane of the band read (bands stored apart), else 0.
    plane: usize,
    sample: Sample,
    /// The predictor undone (libtiff applies none to raw blocks).
    predictor: u16,
}

/// How the samples of an image are stored, when relief can decode them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sample {
    U8,
    I16,
    U16,
    F32,
}

impl Sample {
    /// The storage of `image`'s samples, if it is one decoded here.
    fn of(image: &Image) -> Option<Self> {
        match (image.bits, image.sample_format) {
            (8, 1) => Some(Self::U8),
            (16, 2) => Some(Self::I16),
            (16, 1) => Some(Self::U16),
            (32, 3) => Some(Self::F32),
            _ => None,
        }
    }

    fn gdal(self) -> GdalDataType {
        match self {
            Self::U8 => GdalDataType::UInt8,
            Self::I16 => GdalDataType::Int16,
            Self::U16 => GdalDataType::UInt16,
            Self::F32 => GdalDataType::Float32,
        }
    }

    /// What GDAL reads from a block the file does not store: the band's
    /// nodata value as this type holds it (an integer type rounds it,
    /// clamps it to its range and takes NaN as 0), else 0.
    fn fill(self, nodata: Option<f64>) -> f32 {
        let Some(v) = nodata else { return 0.0 };
        let (lo, hi) = match self {
            Self::U8 => (0.0, 255.0),
            Self::I16 => (-32768.0, 32767.0),
            Self::U16 => (0.0, 65535.0),
            Self::F32 => return v as f32,
        };
        if v.is_nan() { 0.0 } else { v.round().clamp(lo, hi) as f32 }
    }

    fn bytes(self) -> usize {
        match self {
            Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::F32 => 4,
        }
    }
}

/// TIFF compressions decoded here: none, and deflate (Adobe's and the old code).
const NONE: u16 = 1;
const DEFLATE: [u16; 2] = [8, 32946];
/// TIFF predictors: none, horizontal differencing, floating point.
const PREDICTORS: [u16; 3] = [1, 2, 3];

impl Level {
    /// Band `band`'s plane of `image` when it is decoded here (None: GDAL reads it).
    fn of(image: &Image, band: usize) -> Option<Self> {
        let sample = Sample::of(image)?;
        let raw = image.compression == NONE;
        if !raw && !DEFLATE.contains(&image.compression) {
            return None;
        }
        let predictor = if raw { 1 } else { image.predictor };
        let predictor_ok = PREDICTORS.contains(&predictor)
            && (predictor != 3 || sample == Sample::F32)
            && (predictor != 2 || sample != Sample::F32);
        // One sample a pixel, or bands stored apart (one plane per band).
        let plane = band.checked_sub(1)?;
        let plane = match (image.samples, image.planar) {
            (1, _) if plane == 0 => 0,
            (n, 2) if plane < usize::from(n) => plane,
            _ => return None,
        };
        predictor_ok.then(|| Self { image: image.clone(), plane, sample, predictor })
    }
}

impl Native {
    /// The plan for reading band `band` of the GeoTIFF at `path` (opened by
    /// GDAL as `ds`): its base image and reduced-resolution images, each
    /// where its layout is one decoded here and agrees with what GDAL says
    /// of the band. None when the base is not: GDAL reads the file.
    pub(crate) fn plan(ds: &Dataset, band: usize, path: &Path) -> Option<Self> {
        if ds.driver().short_name() != "GTiff" {
            return None;
        }
        let gdal_band = ds.rasterband(band).ok()?;
        // A mask of its own (an alpha, a mask image) is read through GDAL.
        let flags = gdal_band.mask_flags().ok()?;
        if !(flags.is_all_valid() || flags.is_nodata()) {
            return None;
        }
        let stamp = FileStamp::of(path)?;
        let file = RangeFile::open(path).ok()?;
        let images = tiff::images(path)?;
        let gdal_type = gdal_band.band_type();
        // Masks aside, the base image first, then its overviews.
        let reduced: Vec<&Image> = images.iter().filter(|i| i.subfile & 4 == 0).collect();
        let base = reduced.first().filter(|i| i.subfile & 1 == 0 && i.size == ds.raster_size())?;
        let ours = |image: &Image| {
            Level::of(image, band)
                .filter(|l| l.sample.gdal() == gdal_type && image.check_within(path).is_ok())
                .filter(|_| reduced.iter().filter(|i| i.size == image.size).count() == 1)
        };
        let mut decoded = vec![ours(base)?];
        decoded.extend(reduced[1..].iter().filter(|i| i.subfile & 1 == 1).filter_map(|i| ours(i)));
        if FileStamp::of(path) != Some(stamp) {
            return None;
        }
        let fill = decoded[0].sample.fill(gdal_band.no_data_value());
        Some(Self { stamp, file, images: decoded, fill })
    }

    /// True when the image of `size` pixels (the base or an overview) is
    /// decoded here.
    pub(crate) fn decodes(&self, size: (usize, usize)) -> bool {
        self.images.iter().any(|l| l.image.size == size)
    }

    /// For the scene state: which levels are decoded here, and how stored.
    pub(crate) fn describe(&self) -> String {
        let mut ways: Vec<String> = self
            .images
            .iter()
            .map(|l| {
                let compression = if l.image.compression == NONE { "raw" } else { "deflate" };
                format!("{compression}, predictor {}", l.predictor)
            })
            .collect();
        ways.dedup();
        format!(
            "by relief from the file's blocks ({}): the base and {} overviews; the rest through GDAL",
            ways.join("; "),
            self.images.len() - 1
        )
    }

    /// The values of `rect` of the image of `size` pixels (the base or an
    /// overview), as the file holds them widened to f32. None when that
    /// image is not decoded here or a block does not decode: GDAL then
    /// reads the rectangle and says what is wrong with it.
    pub(crate) fn read(&self, size: (usize, usize), rect: PixelRect) -> Option<Vec<f32>> {
        let level = self.images.iter().find(|l| l.image.size == size)?;
        self.decode(level, rect, self.fill, |place, raw, out| place.widen(raw, out, level))
    }

    /// The same values as the file's 16-bit signed integers, for an image
    /// that holds those (half the memory of f32, and the same values
    /// widened). None where `read` gives None, and for any other image.
    /// (A 16-bit image's fill is always such an integer: `Sample::fill`.)
    pub(crate) fn read_i16(&self, size: (usize, usize), rect: PixelRect) -> Option<Vec<i16>> {
        let (level, fill) = self.i16_image(size)?;
        self.decode(level, rect, fill, |place, raw, out| place.keep(raw, out, level))
    }

    /// True when `read_i16` gives the image of `size` pixels.
    pub(crate) fn keeps_i16(&self, size: (usize, usize)) -> bool {
        self.i16_image(size).is_some()
    }

    /// The 16-bit image of `size` pixels, and its fill, where both are
    /// 16-bit integers.
    fn i16_image(&self, size: (usize, usize)) -> Option<(&Level, i16)> {
        let level = self.images.iter().find(|l| l.image.size == size && l.sample == Sample::I16)?;
        Some((level, exact_i16(self.fill)?))
    }

    /// Decodes the blocks under `rect` of `level`, each through `put`;
    /// a block the file does not store reads as `fill`.
    fn decode<T: Copy>(
        &self,
        level: &Level,
        rect: PixelRect,
        fill: T,
        put: impl Fn(&Place, &[u8], &mut [T]),
    ) -> Option<Vec<T>> {
        let (image, sample) = (&level.image, level.sample);
        let (tw, th) = image.block;
        let (width, height) = (rect.width(), rect.height());
        if rect.x1 > image.size.0 || rect.y1 > image.size.1 {
            return None;
        }
        if width == 0 || height == 0 {
            return Some(Vec::new());
        }
        let mut out = vec![fill; width * height];
        let across = image.size.0.div_ceil(tw);
        let blocks = image.blocks();
        SCRATCH.with(|scratch| {
            let mut scratch = scratch.borrow_mut();
            for by in rect.y0 / th..=(rect.y1.max(1) - 1) / th {
                for bx in rect.x0 / tw..=(rect.x1.max(1) - 1) / tw {
                    let i = level.plane * blocks + by * across + bx;
                    let (offset, size) = (*image.offsets.get(i)?, *image.sizes.get(i)?);
                    if offset == 0 || size == 0 {
                        continue;
                    }
                    // The part of the block inside both the image and the rectangle.
                    let (x0, y0) = (bx * tw, by * th);
                    let cols = (rect.x0.max(x0), rect.x1.min(x0 + tw));
                    let rows = (rect.y0.max(y0), rect.y1.min(y0 + th));
                    let place = Place {
                        out_stride: width,
                        out_at: (rows.0 - rect.y0) * width + (cols.0 - rect.x0),
                        col0: cols.0 - x0,
                        row0: rows.0 - y0,
                        cols: cols.1 - cols.0,
                        rows: rows.1 - rows.0,
                        row_bytes: tw * sample.bytes(),
                    };
                    // A tile holds all its rows; a strip, only the image's.
                    let block_rows = if image.tiled { th } else { th.min(image.size.1 - y0) };
                    let raw = scratch.block(&self.file, image, offset, size, tw * block_rows * sample.bytes())?;
                    // Floating-point differencing stores bytes in planes, whatever the byte order.
                    if !image.little && level.predictor != 3 {
                        to_little(raw, sample.bytes());
                    }
                    put(&place, raw, &mut out);
                }
            }
            Some(())
        })?;
        Some(out)
    }
}

/// Where one block's part of a rectangle goes.
struct Place {
    out_stride: usize,
    out_at: usize,
    /// The part's first column and row in the block, and its size.
    col0: usize,
    row0: usize,
    cols: usize,
    rows: usize,
    /// Bytes of one of the block's decoded rows.
    row_bytes: usize,
}

impl Place {
    /// Calls `f` with each of the part's rows: the block's decoded row
    /// (from the block's first column) and where its part goes.
    fn each_row<T>(&self, raw: &[u8], out: &mut [T], mut f: impl FnMut(&[u8], &mut [T])) {
        for r in 0..self.rows {
            let src = &raw[(self.row0 + r) * self.row_bytes..(self.row0 + r + 1) * self.row_bytes];
            let at = self.out_at + r * self.out_stride;
            f(src, &mut out[at..at + self.cols]);
        }
    }

    /// Writes the part from a block's decoded bytes, widened to f32,
    /// undoing the predictor row by row from the block's first column.
    fn widen(&self, raw: &[u8], out: &mut [f32], level: &Level) {
        let (sample, tw, col0) = (level.sample, level.image.block.0, self.col0);
        let u16_of = |b: &[u8]| u16::from_le_bytes([b[0], b[1]]);
        self.each_row(raw, out, |src, dst| match (sample, level.predictor) {
            (Sample::U8, 2) => accumulate(src, dst, col0, |b| b[0], u8::wrapping_add, f32::from),
            (Sample::U8, _) => copy(src, dst, col0, |b: &[u8; 1]| f32::from(b[0])),
            (Sample::I16, 2) => accumulate(src, dst, col0, le_i16, i16::wrapping_add, f32::from),
            (Sample::I16, _) => copy(src, dst, col0, |b: &[u8; 2]| f32::from(i16::from_le_bytes(*b))),
            (Sample::U16, 2) => accumulate(src, dst, col0, u16_of, u16::wrapping_add, f32::from),
            (Sample::U16, _) => copy(src, dst, col0, |b: &[u8; 2]| f32::from(u16::from_le_bytes(*b))),
            (Sample::F32, 3) => floating(src, dst, col0, tw),
            (Sample::F32, _) => copy(src, dst, col0, |b: &[u8; 4]| f32::from_le_bytes(*b)),
        });
    }

    /// Writes the part of a block of 16-bit signed samples as they are.
    fn keep(&self, raw: &[u8], out: &mut [i16], level: &Level) {
        let col0 = self.col0;
        self.each_row(raw, out, |src, dst| match level.predictor {
            2 => accumulate(src, dst, col0, le_i16, i16::wrapping_add, |v| v),
            _ => copy(src, dst, col0, |b: &[u8; 2]| i16::from_le_bytes(*b)),
        });
    }
}

/// A little-endian 16-bit signed sample.
fn le_i16(b: &[u8]) -> i16 {
    i16::from_le_bytes([b[0], b[1]])
}

/// Puts a block's samples of `width` bytes in little-endian order.
fn to_little(raw: &mut [u8], width: usize) {
    for sample in raw.chunks_exact_mut(width) {
        sample.reverse();
    }
}

/// Samples `col0..` of a row stored as they are, little-endian.
fn copy<const N: usize, O>(src: &[u8], dst: &mut [O], col0: usize, value: impl Fn(&[u8; N]) -> O) {
    let (samples, _) = src[col0 * N..].as_chunks::<N>();
    for (d, s) in dst.iter_mut().zip(samples) {
        *d = value(s);
    }
}

/// Samples `col0..` of a row stored as differences from the sample to the
/// left (TIFF predictor 2), little-endian: summed from the row's start, wrapping.
fn accumulate<T: Copy + Default, O>(
    src: &[u8],
    dst: &mut [O],
    col0: usize,
    value: impl Fn(&[u8]) -> T,
    add: impl Fn(T, T) -> T,
    widen: impl Fn(T) -> O,
) {
    let mut samples = src.chunks_exact(std::mem::size_of::<T>()).map(value);
    let mut sum = T::default();
    for v in samples.by_ref().take(col0) {
        sum = add(sum, v);
    }
    for (d, v) in dst.iter_mut().zip(samples) {
        sum = add(sum, v);
        *d = widen(sum);
    }
}

/// Samples `col0..` of a row of 32-bit floats stored with TIFF predictor 3:
/// the row's bytes differenced one from the next, each sample's four bytes
/// spread over four planes of `tw` bytes, most significant first.
fn floating(src: &[u8], dst: &mut [f32], col0: usize, tw: usize) {
    FLOATS.with(|row| {
        let mut row = row.borrow_mut();
        row.clear();
        let mut sum = 0u8;
        row.extend(src.iter().map(|b| {
            sum = sum.wrapping_add(*b);
            sum
        }));
        for (k, d) in dst.iter_mut().enumerate() {
            let c = col0 + k;
            *d = f32::from_bits(u32::from_be_bytes([row[c], row[tw + c], row[2 * tw + c], row[3 * tw + c]]));
        }
    });
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
    static FLOATS: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
}

/// Each thread's buffers and inflater, kept from block to block.
#[derive(Default)]
struct Scratch {
    packed: Vec<u8>,
    raw: Vec<u8>,
    inflater: Option<Decompressor>,
}

impl Scratch {
    /// The decoded bytes of one block: `expect` bytes, or None.
    fn block(&mut self, file: &RangeFile, image: &Image, offset: u64, size: u64, expect: usize) -> Option<&mut [u8]> {
        grow(&mut self.raw, expect);
        if image.compression == NONE {
            // A raw block shorter than its samples is GDAL's to read (and to complain of).
            if size < expect as u64 {
                return None;
            }
            file.read_exact_at(&mut self.raw[..expect], offset).ok()?;
            return Some(&mut self.raw[..expect]);
        }
        // Deflate never grows a block by more than a few bytes in a thousand.
        let size = usize::try_from(size).ok().filter(|&n| n <= expect + expect / 8 + 4096)?;
        grow(&mut self.packed, size);
        file.read_exact_at(&mut self.packed[..size], offset).ok()?;
        let inflater = self.inflater.get_or_insert_with(Decompressor::new);
        let n = inflater.zlib_decompress(&self.packed[..size], &mut self.raw[..expect]).ok()?;
        (n == expect).then_some(&mut self.raw[..expect])
    }
}

/// Makes `buffer` at least `len` long, zeroing only what it grows by.
fn grow(buffer: &mut Vec<u8>, len: usize) {
    if buffer.len() < len {
        buffer.resize(len, 0);
    }
}

#[cfg(test)]
mod tests {
    use std::os::unix::fs::FileExt;
    use std::path::PathBuf;

    use gdal::DriverManager;
    use gdal::raster::{Buffer, GdalType, RasterCreationOptions};

    use super::super::decode::read_window;
    use super::*;

    const NODATA: f64 = -9999.0;

    /// How much of a test raster is written.
    #[derive(Clone, Copy)]
    enum Written {
        /// Every pixel, nodata NODATA.
        Whole,
        /// Its top-left 40 x 30 pixels, with this nodata value (or none).
        Sparse(Option<f64>),
    }

    /// A 100 x 70 raster of `bands` bands of `T` (values from `value`, by
    /// band and pixel) written at `path` with `options`, with AVERAGE
    /// overviews 2 and 4. Returns `path`.
    fn write<T: GdalType + Copy>(
        path: PathBuf,
        options: &[&str],
        bands: usize,
        written: Written,
        value: impl Fn(usize, usize, usize) -> T,
    ) -> Result<PathBuf, Box<dyn std::error::Error>> {
        let (w, h) = (100usize, 70usize);
        let driver = DriverManager::get_driver_by_name("GTiff")?;
        let options: RasterCreationOptions = options.iter().copied().collect();
        let mut ds = driver.create_with_band_type_with_options::<T, _>(&path, w, h, bands, &options)?;
        ds.set_geo_transform(&[10.0, 1e-3, 0.0, 46.0, 0.0, -1e-3])?;
        ds.set_projection("EPSG:4326")?;
        let ((ww, wh), nodata) = match written {
            Written::Whole => ((w, h), Some(NODATA)),
            Written::Sparse(nodata) => ((40, 30), nodata),
        };
        for b in 1..=bands {
            let mut band = ds.rasterband(b)?;
            band.set_no_data_value(nodata)?;
            let data: Vec<T> = (0..ww * wh).map(|i| value(b, i % ww, i / ww)).collect();
            band.write((0, 0), (ww, wh), &mut Buffer::new((ww, wh), data))?;
        }
        ds.build_overviews("AVERAGE", &[2, 4], &[])?;
        Ok(path)
    }

    fn plan(path: &Path, band: usize) -> Result<Option<Native>, Box<dyn std::error::Error>> {
        Ok(Native::plan(&Dataset::open(path)?, band, path))
    }

    /// Every level decoded here equals GDAL's read of it, bit for bit: the
    /// whole level and a window across blocks' edges.
    fn assert_as_gdal(path: &Path, band: usize) -> Result<(), Box<dyn std::error::Error>> {
        let native = plan(path, band)?.ok_or("not decoded here")?;
        let ds = Dataset::open(path)?;
        let base = ds.rasterband(band)?;
        let overviews = base.overview_count()? as usize;
        assert_eq!(native.images.len(), 1 + overviews, "every level decoded here");
        for level in 0..=overviews {
            let through = if level == 0 { ds.rasterband(band)? } else { base.overview(level - 1)? };
            let (w, h) = through.size();
            for rect in [
                PixelRect { x0: 0, y0: 0, x1: w, y1: h },
                PixelRect { x0: w / 3, y0: h / 4, x1: w - 1, y1: h / 2 + 3 },
                PixelRect { x0: w - 1, y0: h - 1, x1: w, y1: h },
            ] {
                let ours = native.read((w, h), rect).ok_or(format!("level {level} {rect:?} not decoded"))?;
                let gdal = read_window(&through, rect, path)?;
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
                assert_eq!(bits(&ours), bits(&gdal), "{}: level {level}, {rect:?}", path.display());
                // 16-bit signed samples also as they are stored: the same values.
                let narrow = native.read_i16((w, h), rect);
                assert_eq!(narrow.is_some(), through.band_type() == GdalDataType::Int16, "{}", path.display());
                if let Some(narrow) = narrow {
                    let widened: Vec<f32> = narrow.into_iter().map(f32::from).collect();
                    assert_eq!(bits(&widened), bits(&gdal), "{}: level {level}, {rect:?} as i16", path.display());
                }
            }
        }
        Ok(())
    }

    const TILED: [&str; 3] = ["TILED=YES", "BLOCKXSIZE=32", "BLOCKYSIZE=32"];

    fn with(extra: &[&'static str]) -> Vec<&'static str> {
        TILED.iter().chain(extra).copied().collect()
    }

    #[test]
    fn every_plain_layout_decodes_as_gdal_does() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let path = |name: &str| dir.path().join(name);
        let int16 = |b: usize, x: usize, y: usize| ((x * 977 + y * 331 + b * 7919) % 65_000) as i32 as i16;
        let wide = |b: usize, x: usize, y: usize| ((x * 977 + y * 331 + b * 7919) % 65_535) as u16;
        let float = |b: usize, x: usize, y: usize| {
            if (x + y).is_multiple_of(37) { f32::NAN } else { (x as f32 - 50.3) * (y as f32 + 0.7) * 1.37 + b as f32 }
        };
        let byte = |_, x: usize, y: usize| (x * 7 + y * 3) as u8;
        let deflate = with(&["COMPRESS=DEFLATE"]);
        let deflate2 = with(&["COMPRESS=DEFLATE", "PREDICTOR=2"]);
        let deflate3 = with(&["COMPRESS=DEFLATE", "PREDICTOR=3"]);
        let big2 = with(&["COMPRESS=DEFLATE", "PREDICTOR=2", "ENDIANNESS=BIG"]);
        let big3 = with(&["COMPRESS=DEFLATE", "PREDICTOR=3", "ENDIANNESS=BIG"]);
        let sparse = with(&["COMPRESS=DEFLATE", "SPARSE_OK=TRUE"]);
        let apart = with(&["COMPRESS=DEFLATE", "PREDICTOR=2", "INTERLEAVE=BAND"]);
        // Strips of 8 rows: the last holds 6.
        let strips = ["BLOCKYSIZE=8", "COMPRESS=DEFLATE", "PREDICTOR=2"];
        let files = [
            write::<u8>(path("byte-strips.tif"), &[], 1, Written::Whole, byte)?,
            write::<u8>(path("byte.tif"), &deflate2, 1, Written::Whole, byte)?,
            write::<i16>(path("i16.tif"), &deflate, 1, Written::Whole, int16)?,
            write::<i16>(path("i16-p2.tif"), &deflate2, 1, Written::Whole, int16)?,
            write::<i16>(path("i16-big.tif"), &big2, 1, Written::Whole, int16)?,
            write::<i16>(path("i16-strips.tif"), &strips, 1, Written::Whole, int16)?,
            write::<i16>(path("i16-sparse.tif"), &sparse, 1, Written::Sparse(Some(NODATA)), int16)?,
            // Sparse blocks read as GDAL fills them: the nodata value as
            // Int16 holds it (rounded, clamped, NaN as 0), else 0.
            write::<i16>(path("i16-sparse-nan.tif"), &sparse, 1, Written::Sparse(Some(f64::NAN)), int16)?,
            write::<i16>(path("i16-sparse-half.tif"), &sparse, 1, Written::Sparse(Some(-9999.5)), int16)?,
            write::<i16>(path("i16-sparse-far.tif"), &sparse, 1, Written::Sparse(Some(-3.4e38)), int16)?,
            write::<i16>(path("i16-sparse-none.tif"), &sparse, 1, Written::Sparse(None), int16)?,
            write::<u8>(path("byte-sparse-high.tif"), &sparse, 1, Written::Sparse(Some(300.0)), byte)?,
            write::<u16>(path("u16.tif"), &deflate2, 1, Written::Whole, wide)?,
            write::<f32>(path("f32.tif"), &deflate3, 1, Written::Whole, float)?,
            write::<f32>(path("f32-big.tif"), &big3, 1, Written::Whole, float)?,
            write::<f32>(path("f32-raw.tif"), &with(&["BIGTIFF=YES"]), 1, Written::Whole, float)?,
        ];
        for file in &files {
            assert_as_gdal(file, 1)?;
        }
        // The second band of a band-separate file: its own plane.
        assert_as_gdal(&write::<i16>(path("i16-bands.tif"), &apart, 2, Written::Whole, int16)?, 2)
    }

    #[test]
    fn other_layouts_are_left_to_gdal() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let int16 = |_, x: usize, y: usize| (x + y) as i16;
        let write16 = |name: &str, options: &[&'static str], bands| {
            write::<i16>(dir.path().join(name), &with(options), bands, Written::Whole, int16)
        };
        let lzw = write16("lzw.tif", &["COMPRESS=LZW", "PREDICTOR=2"], 1)?;
        assert!(plan(&lzw, 1)?.is_none(), "LZW is GDAL's");
        let pixels = write16("pixels.tif", &["COMPRESS=DEFLATE", "INTERLEAVE=PIXEL"], 2)?;
        assert!(plan(&pixels, 1)?.is_none(), "pixel-interleaved bands are GDAL's");
        let wide =
            write::<i32>(dir.path().join("i32.tif"), &with(&["COMPRESS=DEFLATE"]), 1, Written::Whole, |_, x, y| {
                (x * y) as i32
            })?;
        assert!(plan(&wide, 1)?.is_none(), "Int32 is GDAL's");
        // A block that no longer inflates to its size: GDAL reads it (and says what is wrong).
        let cut = write16("cut.tif", &["COMPRESS=DEFLATE"], 1)?;
        let native = plan(&cut, 1)?.ok_or("decoded here")?;
        let base = &native.images[0].image;
        let (offset, size) = (base.offsets[0], base.sizes[0]);
        let file = std::fs::OpenOptions::new().write(true).open(&cut)?;
        file.write_all_at(&vec![0xAB; size as usize], offset)?;
        assert_eq!(native.read(base.size, PixelRect { x0: 0, y0: 0, x1: 32, y1: 32 }), None);
        Ok(())
    }
}
