//! The block tables of a TIFF file (classic or BigTIFF), read straight from
//! its directories: for each image (the full-resolution one, its reduced
//! resolution overviews), the size, the block size and every block's offset
//! and byte count. A few hundred kilobytes for a 3 GB raster, where asking
//! GDAL block by block costs a call per block. A file's tables are read
//! once per version of it (its stamp): opening it, signing its blocks and
//! decoding them ask for the same ones.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use moka::sync::Cache;

use super::FileStamp;
use crate::objects::RangeFile;

/// One image of the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Image {
    pub size: (usize, usize),
    pub block: (usize, usize),
    /// Offsets and byte counts, block by block (row-major), every plane of
    /// a band-separate file after the first plane's.
    pub offsets: Vec<u64>,
    pub sizes: Vec<u64>,
    /// NewSubfileType: 0 the full image, 1 a reduced-resolution one (an
    /// overview), 4 a mask.
    pub subfile: u32,
    /// How blocks are stored: Compression (1 raw), Predictor (1 none),
    /// BitsPerSample and SampleFormat of the first sample, SamplesPerPixel
    /// and PlanarConfiguration (2: one plane per sample).
    pub compression: u16,
    pub predictor: u16,
    pub bits: u16,
    pub sample_format: u16,
    pub samples: u16,
    pub planar: u16,
    /// Blocks are tiles (each holds all its rows), not strips.
    pub tiled: bool,
    /// The file's byte order is little-endian.
    pub little: bool,
}

impl Image {
    /// Fails when a block lies past the end of `file` (a file cut short).
    pub(crate) fn check_within(&self, file: &Path) -> Result<(), relief_source::SourceError> {
        let length = RangeFile::open(file).and_then(|f| f.size()).map_err(|source| relief_source::SourceError::Io {
            what: "raster",
            path: file.into(),
            source,
        })?;
        match (0..self.offsets.len()).find(|&i| self.offsets[i].saturating_add(self.sizes[i]) > length) {
            None => Ok(()),
            Some(i) => Err(super::format_err(
                format!(
                    "cannot read raster data: the file is cut short (block {i} of its {} x {} image lies past its \
                     end, {length} bytes)",
                    self.size.0, self.size.1
                ),
                file,
            )),
        }
    }

    /// The blocks are compressed (Compression is not 1).
    pub(crate) fn compressed(&self) -> bool {
        self.compression != 1
    }

    /// Blocks per plane.
    pub(crate) fn blocks(&self) -> usize {
        self.size.0.div_ceil(self.block.0) * self.size.1.div_ceil(self.block.1)
    }
}

const MAX_IMAGES: usize = 64;
const MAX_ENTRIES: u64 = 1 << 12;
const MAX_BLOCKS: u64 = 1 << 28;

/// Bytes of block tables kept for files read again (a 3 GB raster's take
/// under a megabyte).
const KEPT_BYTES: u64 = 64 << 20;

/// A file's tables, with the stamp the file had throughout their read.
type Kept = (FileStamp, Arc<[Image]>);

/// The tables last read of each file.
fn kept() -> &'static Cache<PathBuf, Kept> {
    static KEPT: OnceLock<Cache<PathBuf, Kept>> = OnceLock::new();
    KEPT.get_or_init(|| {
        Cache::builder()
            .max_capacity(KEPT_BYTES)
            .weigher(|_, (_, images): &Kept| {
                let entries: usize = images.iter().map(|i| i.offsets.len() + i.sizes.len()).sum();
                u32::try_from(entries * 8 + 256).unwrap_or(u32::MAX)
            })
            .build()
    })
}

/// Every image of the TIFF at `path` (None when it is not a TIFF or its
/// directories cannot be followed): read from the file, or the answer kept
/// from a read of this same version of it.
pub(crate) fn images(path: &Path) -> Option<Arc<[Image]>> {
    let stamp = FileStamp::of(path)?;
    if let Some((kept_stamp, images)) = kept().get(path)
        && kept_stamp == stamp
    {
        return Some(images);
    }
    let images: Arc<[Image]> = read(path)?.into();
    // Kept only when no write came between (the stamp held throughout).
    if FileStamp::of(path) == Some(stamp) {
        kept().insert(path.to_path_buf(), (stamp, Arc::clone(&images)));
    }
    Some(images)
}

/// Every image of the TIFF at `path`, read from its directories.
fn read(path: &Path) -> Option<Vec<Image>> {
    let file = RangeFile::open(path).ok()?;
    let mut head = [0u8; 16];
    file.read_exact_at(&mut head[..8], 0).ok()?;
    let little = match &head[..2] {
        b"II" => true,
        b"MM" => false,
        _ => return None,
    };
    let r = Reader { file: &file, little };
    let big = match r.u16_at(&head[2..4]) {
        42 => false,
        43 => true,
        _ => return None,
    };
    let mut next = if big {
        file.read_exact_at(&mut head[..16], 0).ok()?;
        r.u64_at(&head[8..16])
    } else {
        u64::from(r.u32_at(&head[4..8]))
    };
    let mut images = Vec::new();
    while next != 0 && images.len() < MAX_IMAGES {
        let (image, after) = r.directory(next, big)?;
        images.extend(image);
        next = after;
    }
    Some(images)
}

struct Reader<'a> {
    file: &'a RangeFile,
    little: bool,
}

impl Reader<'_> {
    fn u16_at(&self, b: &[u8]) -> u16 {
        let b = [b[0], b[1]];
        if self.little { u16::from_le_bytes(b) } else { u16::from_be_bytes(b) }
    }

    fn u32_at(&self, b: &[u8]) -> u32 {
        let b = [b[0], b[1], b[2], b[3]];
        if self.little { u32::from_le_bytes(b) } else { u32::from_be_bytes(b) }
    }

    fn u64_at(&self, b: &[u8]) -> u64 {
        let b: [u8; 8] = b[..8].try_into().expect("eight bytes");
        if self.little { u64::from_le_bytes(b) } else { u64::from_be_bytes(b) }
    }

    /// The values of one entry: (type, count, the value field's bytes).
    fn values(&self, kind: u16, count: u64, field: &[u8], big: bool) -> Option<Vec<u64>> {
        let width = match kind {
            3 => 2,
            4 | 13 => 4,
            16 | 18 => 8,
            _ => return Some(Vec::new()),
        };
        if count > MAX_BLOCKS {
            return None;
        }
        let bytes = count as usize * width;
        let inline = if big { 8 } else { 4 };
        let data = if bytes <= inline {
            field[..bytes].to_vec()
        } else {
            let at = if big { self.u64_at(field) } else { u64::from(self.u32_at(field)) };
            let mut buf = vec![0u8; bytes];
            self.file.read_exact_at(&mut buf, at).ok()?;
            buf
        };
        Some(
            data.chunks_exact(width)
                .map(|c| match width {
                    2 => u64::from(self.u16_at(c)),
                    4 => u64::from(self.u32_at(c)),
                    _ => self.u64_at(c),
                })
                .collect(),
        )
    }

    /// The image of the directory at `at` (None inside when it is not a
    /// blocked image), and the next directory's offset.
    fn directory(&self, at: u64, big: bool) -> Option<(Option<Image>, u64)> {
        let (count_len, entry_len, next_len) = if big { (8, 20, 8) } else { (2, 12, 4) };
        let mut head = [0u8; 8];
        self.file.read_exact_at(&mut head[..count_len], at).ok()?;
        let n = if big { self.u64_at(&head) } else { u64::from(self.u16_at(&head)) };
        if n > MAX_ENTRIES {
            return None;
        }
        let mut entries = vec![0u8; n as usize * entry_len + next_len];
        self.file.read_exact_at(&mut entries, at + count_len as u64).ok()?;
        let (mut width, mut height, mut tile, mut rows, mut subfile) = (0, 0, (0, 0), 0, 0u32);
        let (mut compression, mut predictor, mut bits, mut sample_format, mut samples, mut planar) = (1, 1, 1, 1, 1, 1);
        let (mut offsets, mut sizes) = (Vec::new(), Vec::new());
        for e in entries[..n as usize * entry_len].chunks_exact(entry_len) {
            let tag = self.u16_at(&e[0..2]);
            let kind = self.u16_at(&e[2..4]);
            let (count, field) =
                if big { (self.u64_at(&e[4..12]), &e[12..20]) } else { (u64::from(self.u32_at(&e[4..8])), &e[8..12]) };
            let first = || self.values(kind, count.min(1), field, big).and_then(|v| v.first().copied());
            match tag {
                254 => subfile = first().unwrap_or(0) as u32,
                259 => compression = first().unwrap_or(1) as u16,
                317 => predictor = first().unwrap_or(1) as u16,
                258 => bits = first().unwrap_or(1) as u16,
                339 => sample_format = first().unwrap_or(1) as u16,
                277 => samples = first().unwrap_or(1) as u16,
                284 => planar = first().unwrap_or(1) as u16,
                256 => width = first()? as usize,
                257 => height = first()? as usize,
                278 => rows = first()? as usize,
                322 => tile.0 = first()? as usize,
                323 => tile.1 = first()? as usize,
                273 | 324 => offsets = self.values(kind, count, field, big)?,
                279 | 325 => sizes = self.values(kind, count, field, big)?,
                _ => {}
            }
        }
        let tail = &entries[n as usize * entry_len..];
        let next = if big { self.u64_at(tail) } else { u64::from(self.u32_at(tail)) };
        // No RowsPerStrip: one strip.
        let rows = if rows == 0 { height } else { rows.min(height) };
        let block = if tile.0 > 0 { tile } else { (width, rows) };
        let image = (width > 0 && height > 0 && block.0 > 0 && block.1 > 0 && offsets.len() == sizes.len())
            .then_some(Image {
                size: (width, height),
                block,
                offsets,
                sizes,
                subfile,
                compression,
                predictor,
                bits,
                sample_format,
                samples,
                planar,
                tiled: tile.0 > 0,
                little: self.little,
            })
            .filter(|i| i.blocks() > 0 && i.offsets.len() % i.blocks() == 0);
        Some((image, next))
    }
}

#[cfg(test)]
mod tests {
    use gdal::raster::{Buffer, RasterBand, RasterCreationOptions};
    use gdal::{DriverManager, Metadata};

    use super::*;

    /// GDAL's own offset and size of block (x, y) of a band.
    fn gdal_block(band: &RasterBand<'_>, x: usize, y: usize) -> (u64, u64) {
        let item = |what: &str| {
            band.metadata_item(&format!("BLOCK_{what}_{x}_{y}"), "TIFF").and_then(|v| v.parse().ok()).unwrap_or(0)
        };
        (item("OFFSET"), item("SIZE"))
    }

    #[test]
    fn block_tables_match_gdals_for_every_layout() {
        let dir = tempfile::tempdir().expect("temp dir");
        let layouts: [&[&str]; 5] = [
            &[],
            &["TILED=YES", "BLOCKXSIZE=32", "BLOCKYSIZE=32", "COMPRESS=DEFLATE"],
            &["TILED=YES", "BIGTIFF=YES", "COMPRESS=LZW"],
            &["BLOCKYSIZE=7", "BIGTIFF=YES"],
            &["TILED=YES", "BLOCKXSIZE=16", "BLOCKYSIZE=16", "INTERLEAVE=BAND", "ENDIANNESS=BIG"],
        ];
        for (n, options) in layouts.iter().enumerate() {
            let path = dir.path().join(format!("t{n}.tif"));
            let (w, h, bands) = (100usize, 70usize, 2usize);
            {
                let driver = DriverManager::get_driver_by_name("GTiff").expect("GTiff");
                let options: RasterCreationOptions = options.iter().copied().collect();
                let mut ds =
                    driver.create_with_band_type_with_options::<u16, _>(&path, w, h, bands, &options).expect("create");
                for b in 1..=bands {
                    let data: Vec<u16> = (0..w * h).map(|i| ((i * 7 + b * 13) % 1000) as u16).collect();
                    ds.rasterband(b)
                        .expect("band")
                        .write((0, 0), (w, h), &mut Buffer::new((w, h), data))
                        .expect("write");
                }
                ds.build_overviews("AVERAGE", &[2, 4], &[]).expect("overviews");
            }
            let images = images(&path).expect("a TIFF");
            let reduced: Vec<&Image> = images.iter().filter(|i| i.subfile & 4 == 0).collect();
            assert_eq!(reduced.len(), 3, "layout {n}: base and two overviews: {images:?}");
            let ds = gdal::Dataset::open(&path).expect("open");
            for (level, image) in reduced.iter().enumerate() {
                let blocks = image.blocks();
                for b in 1..=bands {
                    let band = ds.rasterband(b).expect("band");
                    let band = if level == 0 { band } else { band.overview(level - 1).expect("overview") };
                    assert_eq!(image.size, band.size(), "layout {n}, level {level}");
                    assert_eq!(image.block, band.block_size(), "layout {n}, level {level}");
                    // A pixel-interleaved file has one block for all bands.
                    let plane = if image.offsets.len() == blocks { 0 } else { b - 1 };
                    let across = image.size.0.div_ceil(image.block.0);
                    for i in 0..blocks {
                        let ours = (image.offsets[plane * blocks + i], image.sizes[plane * blocks + i]);
                        assert_eq!(
                            ours,
                            gdal_block(&band, i % across, i / across),
                            "layout {n}, level {level}, band {b}, block {i}"
                        );
                    }
                }
            }
            assert_eq!(reduced[0].compressed(), options.iter().any(|o| o.starts_with("COMPRESS")), "layout {n}");
        }
        assert!(images(&dir.path().join("missing.tif")).is_none());
        std::fs::write(dir.path().join("text.tif"), b"not a tiff at all").expect("write");
        assert!(images(&dir.path().join("text.tif")).is_none());
    }

    #[test]
    fn tables_are_read_once_per_version_of_the_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("t.tif");
        let write = |side: &str| {
            let driver = DriverManager::get_driver_by_name("GTiff").expect("GTiff");
            let options: RasterCreationOptions =
                ["TILED=YES", &format!("BLOCKXSIZE={side}"), &format!("BLOCKYSIZE={side}")].into_iter().collect();
            let ds = driver.create_with_band_type_with_options::<i16, _>(&path, 64, 64, 1, &options).expect("create");
            ds.rasterband(1)
                .expect("band")
                .write((0, 0), (64, 64), &mut Buffer::new((64, 64), vec![7i16; 64 * 64]))
                .expect("write");
        };
        write("16");
        let first = images(&path).expect("a TIFF");
        assert!(Arc::ptr_eq(&first, &images(&path).expect("a TIFF")), "the same version: the tables kept");
        assert_eq!(first[0].block, (16, 16));
        // Rewritten (a new version, whatever its size): read afresh.
        write("32");
        let second = images(&path).expect("a TIFF");
        assert!(!Arc::ptr_eq(&first, &second));
        assert_eq!(second[0].block, (32, 32));
    }
}
