//! What changed in a raster's files between two versions, found without
//! decoding the blocks that did not. Each file of the raster (the file, or
//! each member of a VRT mosaic) gets a signature per block of every level
//! (base and overviews): for a GeoTIFF, the block's offset and size in the
//! file and, when `exact` is asked for, a hash of its compressed bytes;
//! for any other format, a hash of the block's values read through GDAL
//! (base level only). Two versions' signatures differ exactly where their
//! blocks may.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use gdal::raster::RasterBand;
use rayon::prelude::*;
use relief_source::SourceError;
use xxhash_rust::xxh3::{xxh3_64, xxh3_64_with_seed};

use super::{FileStamp, PixelRect, Raster, format_err, open_dataset, tiff};

/// How a reload tells changed blocks of a GeoTIFF from unchanged ones: a
/// knob that trades certainty for time (the `bigdem` bench reports both).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChangeDetection {
    /// Offsets and sizes alone (the default): a reload reads only the
    /// file's block tables, and costs what the edit costs whatever the
    /// file's size. A block rewritten in place to exactly its old
    /// compressed size is missed (an uncompressed GeoTIFF, whose blocks
    /// keep their sizes, is always checked exactly). A block that moved
    /// unchanged is read and found equal to the old pixels: no dirt.
    Layout,
    /// Offsets, sizes and a hash of each block's compressed bytes: every
    /// change is found; a reload reads the file's compressed bytes (not
    /// decoding them), so it grows with the file.
    Exact,
}

impl ChangeDetection {
    pub fn name(self) -> &'static str {
        match self {
            Self::Layout => "layout",
            Self::Exact => "exact",
        }
    }
}

/// Block signatures of every file of a raster version.
#[derive(Debug, Clone)]
pub(crate) struct Signatures {
    parts: Vec<Part>,
}

/// Where two versions' blocks differ, in base pixels of the raster.
#[derive(Debug, Default)]
pub(crate) struct Changes {
    /// Blocks of the base level (or of a whole file whose layout changed).
    pub base: Vec<PixelRect>,
    /// Blocks of the files' overviews. An overview block changes with the
    /// base under it; one that changed where the base did not is a change
    /// of its own.
    pub overviews: Vec<PixelRect>,
}

/// One file of the raster, placed in the raster's pixels.
#[derive(Debug, Clone)]
struct Part {
    path: PathBuf,
    /// The file as it was signed (a member whose stamp is the same is not signed again).
    stamp: Option<FileStamp>,
    /// Raster pixel = offset + part pixel * scale, per axis.
    offset: (f64, f64),
    scale: (f64, f64),
    size: (usize, usize),
    levels: Vec<Level>,
}

/// Signatures of one level of one file.
#[derive(Debug, Clone, PartialEq)]
struct Level {
    size: (usize, usize),
    block: (usize, usize),
    sigs: Vec<u64>,
}

impl Signatures {
    /// The signatures of `raster`'s files; a mosaic member unchanged since
    /// `previous` keeps its signatures from there.
    /// A file that is not a TIFF is signed from its decoded base blocks:
    /// the ones the raster holds when `held` (a raster just read whole),
    /// else read afresh.
    pub(crate) fn of(
        raster: &Raster,
        mode: ChangeDetection,
        previous: Option<&Self>,
        held: bool,
    ) -> Result<Self, SourceError> {
        if raster.members.is_empty() || raster.warped {
            let stamp = FileStamp::of(&raster.path);
            // A warp's blocks are not the file's: only their values tell.
            let images = if raster.warped { None } else { tiff::images(&raster.path) };
            let levels = match images {
                Some(images) => tiff_levels(&raster.path, &images, mode)?,
                None => vec![decoded(raster, held)?],
            };
            return Ok(Self {
                parts: vec![Part {
                    path: raster.path.clone(),
                    stamp,
                    offset: (0.0, 0.0),
                    scale: (1.0, 1.0),
                    size: raster.size,
                    levels,
                }],
            });
        }
        // The last signatures by file (hundreds of members: no search through them all for each).
        let before: HashMap<&Path, &Part> =
            previous.map(|p| p.parts.iter().map(|part| (part.path.as_path(), part)).collect()).unwrap_or_default();
        let parts = raster
            .members
            .par_iter()
            .map(|(path, _)| {
                let stamp = FileStamp::of(path);
                if let Some(same) = before.get(path.as_path()).filter(|p| p.stamp == stamp && stamp.is_some()) {
                    return Ok((*same).clone());
                }
                // A member the mosaic reads itself is where its VRT places it.
                if let Some((offset, size)) = raster.store.tiling.as_ref().and_then(|t| t.placement(path)) {
                    return Ok(Part {
                        path: path.clone(),
                        stamp,
                        offset,
                        scale: (1.0, 1.0),
                        size,
                        levels: levels(path, mode)?,
                    });
                }
                let ds = open_dataset(path)?;
                let gt = ds.geo_transform().map_err(|_| format_err("mosaic member has no geotransform", path))?;
                let rg = raster.geo;
                // The member's origin in the mosaic's pixels, and its pixel
                // sides in the mosaic's (both along the same axes).
                let (offset, scale) = if rg[2] == 0.0 && rg[4] == 0.0 {
                    (((gt[0] - rg[0]) / rg[1], (gt[3] - rg[3]) / rg[5]), (gt[1] / rg[1], gt[5] / rg[5]))
                } else {
                    let sides = (gt[1].hypot(gt[4]) / rg[1].hypot(rg[4]), gt[2].hypot(gt[5]) / rg[2].hypot(rg[5]));
                    (raster.pixel_of(gt[0], gt[3]), sides)
                };
                Ok(Part {
                    path: path.clone(),
                    stamp,
                    offset,
                    scale,
                    size: ds.raster_size(),
                    levels: levels(path, mode)?,
                })
            })
            .collect::<Result<_, SourceError>>()?;
        Ok(Self { parts })
    }

    /// The base pixels of a raster of `size` where `new` may differ from
    /// `self`: every block whose signature changed, at any level.
    pub(crate) fn diff(&self, new: &Self, size: (usize, usize)) -> Changes {
        let everything = PixelRect { x0: 0, y0: 0, x1: size.0, y1: size.1 };
        if self.parts.len() != new.parts.len() || self.parts.iter().zip(&new.parts).any(|(a, b)| a.path != b.path) {
            return Changes { base: vec![everything], overviews: Vec::new() };
        }
        let mut changes = Changes::default();
        for (old, new) in self.parts.iter().zip(&new.parts) {
            let place = |x0: f64, y0: f64, x1: f64, y1: f64| {
                let (ax, ay) = (new.offset.0 + x0 * new.scale.0, new.offset.1 + y0 * new.scale.1);
                let (bx, by) = (new.offset.0 + x1 * new.scale.0, new.offset.1 + y1 * new.scale.1);
                let clip = |v: f64, max: usize| (v.max(0.0) as usize).min(max);
                PixelRect {
                    x0: clip(ax.min(bx).floor(), size.0),
                    y0: clip(ay.min(by).floor(), size.1),
                    x1: clip(ax.max(bx).ceil(), size.0),
                    y1: clip(ay.max(by).ceil(), size.1),
                }
            };
            let layout = |l: &Level| (l.size, l.block, l.sigs.len());
            if old.size != new.size
                || old.offset != new.offset
                || old.levels.len() != new.levels.len()
                || old.levels.iter().zip(&new.levels).any(|(a, b)| layout(a) != layout(b))
            {
                changes.base.push(place(0.0, 0.0, new.size.0 as f64, new.size.1 as f64));
                continue;
            }
            for (level, (a, b)) in old.levels.iter().zip(&new.levels).enumerate() {
                let rects = if level == 0 { &mut changes.base } else { &mut changes.overviews };
                let across = b.size.0.div_ceil(b.block.0);
                let factor = (new.size.0 as f64 / b.size.0 as f64, new.size.1 as f64 / b.size.1 as f64);
                for (i, _) in a.sigs.iter().zip(&b.sigs).enumerate().filter(|(_, (x, y))| x != y) {
                    let (bx, by) = (i % across, i / across);
                    let x0 = (bx * b.block.0) as f64;
                    let y0 = (by * b.block.1) as f64;
                    let x1 = ((bx + 1) * b.block.0).min(b.size.0) as f64;
                    let y1 = ((by + 1) * b.block.1).min(b.size.1) as f64;
                    rects.push(place(x0 * factor.0, y0 * factor.1, x1 * factor.0, y1 * factor.1));
                }
            }
        }
        changes.base.retain(|r| r.width() > 0 && r.height() > 0);
        changes.overviews.retain(|r| r.width() > 0 && r.height() > 0);
        changes
    }
}

/// The signatures of every level of one file: from its TIFF block tables
/// when it is a TIFF (the base image, then its overviews, internal and in a
/// `.ovr`), else of its base level's values.
fn levels(path: &Path, mode: ChangeDetection) -> Result<Vec<Level>, SourceError> {
    let Some(images) = tiff::images(path) else {
        let ds = open_dataset(path)?;
        let band = |b: usize| ds.rasterband(b).map_err(|e| format_err(e, path));
        let bands: Vec<RasterBand<'_>> = (1..=ds.raster_count()).map(band).collect::<Result<_, _>>()?;
        return Ok(vec![values(&bands, path)?]);
    };
    tiff_levels(path, &images, mode)
}

/// The signatures of a TIFF's images: the base, then its overviews,
/// internal and in a `.ovr`.
fn tiff_levels(path: &Path, images: &[tiff::Image], mode: ChangeDetection) -> Result<Vec<Level>, SourceError> {
    let external = PathBuf::from(format!("{}.ovr", path.display()));
    let overviews = tiff::images(&external).unwrap_or_default();
    let mut out = Vec::new();
    let reduced = |i: &tiff::Image| i.subfile & 4 == 0;
    for (file, image) in images
        .iter()
        .filter(|i| reduced(i))
        .map(|i| (path, i))
        .chain(overviews.iter().filter(|i| reduced(i)).map(|i| (external.as_path(), i)))
    {
        out.push(image_level(file, image, mode == ChangeDetection::Exact || !image.compressed())?);
    }
    if out.is_empty() {
        return Err(format_err("TIFF holds no image", path));
    }
    Ok(out)
}

/// One TIFF image's signatures: per block, its offsets and sizes (every
/// plane's), and a hash of its bytes in `file` when `hash_bytes`.
fn image_level(file: &Path, image: &tiff::Image, hash_bytes: bool) -> Result<Level, SourceError> {
    let blocks = image.blocks();
    let planes = image.offsets.len() / blocks;
    image.check_within(file)?;
    let handle = if hash_bytes {
        Some(crate::objects::RangeFile::open(file).map_err(|source| SourceError::Io {
            what: "raster",
            path: file.into(),
            source,
        })?)
    } else {
        None
    };
    let sigs = (0..blocks)
        .into_par_iter()
        .map_init(Vec::new, |buffer, i| {
            let mut h = 0u64;
            for p in 0..planes {
                let (offset, bytes) = (image.offsets[p * blocks + i], image.sizes[p * blocks + i]);
                h = xxh3_64_with_seed(&[offset.to_le_bytes(), bytes.to_le_bytes()].concat(), h);
                if let Some(f) = &handle
                    && bytes > 0
                {
                    buffer.resize(bytes as usize, 0);
                    f.read_exact_at(buffer, offset).map_err(|source| SourceError::Io {
                        what: "raster",
                        path: file.into(),
                        source,
                    })?;
                    h = xxh3_64_with_seed(buffer, h);
                }
            }
            Ok(h)
        })
        .collect::<Result<Vec<u64>, SourceError>>()?;
    Ok(Level { size: image.size, block: image.block, sigs })
}

/// Signatures of a raster's decoded base blocks (a format whose blocks
/// cannot be located in the file): those it holds when `held`, else read.
fn decoded(raster: &Raster, held: bool) -> Result<Level, SourceError> {
    let store = &raster.store;
    let (bw, bh) = (raster.width().div_ceil(super::BLOCK), raster.height().div_ceil(super::BLOCK));
    let sigs = (0..bw * bh)
        .into_par_iter()
        .map(|b| {
            let (bx, by) = (b % bw, b / bw);
            let block = match store.cached(0, bx, by).filter(|_| held) {
                Some(block) => block,
                None => std::sync::Arc::new(store.load(0, bx, by)?),
            };
            let mut h = xxh3_64(b"decoded");
            for plane in &block.planes() {
                // Every NaN is f32::NAN once decoded: the bytes are the values.
                h = xxh3_64_with_seed(bytemuck::cast_slice(plane), h);
            }
            Ok(h)
        })
        .collect::<Result<Vec<u64>, SourceError>>()?;
    Ok(Level { size: raster.size, block: (super::BLOCK, super::BLOCK), sigs })
}

/// Signatures of the base level's values, 256 x 256 pixels at a time, for
/// formats whose blocks cannot be located in the file.
fn values(bands: &[RasterBand<'_>], path: &Path) -> Result<Level, SourceError> {
    const SIDE: usize = super::BLOCK;
    let size = bands[0].size();
    let (nx, ny) = (size.0.div_ceil(SIDE), size.1.div_ceil(SIDE));
    let mut sigs = vec![0u64; nx * ny];
    let mut values = Vec::new();
    for band in bands {
        for (i, sig) in sigs.iter_mut().enumerate() {
            let (x0, y0) = ((i % nx) * SIDE, (i / nx) * SIDE);
            let window = ((SIDE).min(size.0 - x0), SIDE.min(size.1 - y0));
            values.resize(window.0 * window.1, 0.0f64);
            band.read_into_slice::<f64>((x0 as isize, y0 as isize), window, window, &mut values, None)
                .map_err(|e| format_err(format!("cannot read raster data: {e}"), path))?;
            *sig = xxh3_64_with_seed(bytemuck::cast_slice(&values), *sig ^ xxh3_64(b"values"));
        }
    }
    Ok(Level { size, block: (SIDE, SIDE), sigs })
}
