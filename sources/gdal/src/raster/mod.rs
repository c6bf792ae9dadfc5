//! One raster (a file, or a mosaic through a VRT): its georeferencing,
//! CRS and vertical units, read from the header at once, and its pixels on
//! demand, as blocks of a nodata-aware mip pyramid (`blocks`). A raster
//! small enough is read whole when it opens; a larger one only where tiles
//! need it. A reload finds the changed blocks (`changes`) and reads only those.
//! A raster georeferenced by GCPs is opened through a north-up warp (`warp`).
//! Overviews are checked against the base when the raster opens
//! (`checks`): a lossless file's that disagree are refused; a lossy file's
//! (JPEG, WebP, LERC) within what the compression may change are used, and
//! beyond it left out (the coarse levels halved from the base), with a
//! warning.

mod blocks;
mod changes;
mod checks;
mod decode;
mod halve;
mod header;
mod native;
mod options;
mod pixels;
mod prefetch;
mod reload;
mod tiff;
mod tiling;
mod vrt;
mod warp;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use rayon::prelude::*;
use relief_source::SourceError;
pub(crate) use relief_source::files::Fingerprint;

use blocks::BLOCK;
pub(crate) use blocks::GDAL_CACHE_MB;
pub use blocks::{DEFAULT_BLOCK_BUDGET, block_budget, cached_bytes, set_block_budget};
pub use changes::ChangeDetection;
use changes::Signatures;
use decode::Decoder;
use halve::Halving;
use header::apply;
pub(crate) use header::open_dataset;
pub(crate) use options::{LevelInfo, ReadOptions};
pub use options::{RasterKind, Residency, VerticalUnits};
use pixels::Block;
pub(crate) use pixels::Window;
pub(crate) use relief_source::files::FileStamp;
pub(crate) use reload::Reloaded;

/// Where one version of a raster's pixels come from, and what of them is
/// held: shared by every tile of that version.
#[derive(Debug)]
pub(crate) struct Store {
    /// The identity of the raster's blocks in the cache; kept by a reload
    /// that changes only pixels.
    uid: u64,
    /// This version of the file (dataset handles are per version).
    version: u64,
    path: PathBuf,
    /// What GDAL opens: the file, a VRT rewritten without its missing
    /// members, or the file's warp.
    open_path: PathBuf,
    /// The warp `open_path` names, kept while this version reads it.
    warp: Option<Arc<warp::MemFile>>,
    /// Base pixels of missing members: nodata.
    holes: Vec<PixelRect>,
    /// A mosaic read from its members rather than through its VRT.
    tiling: Option<Arc<tiling::Tiling>>,
    /// A plain GeoTIFF whose blocks relief decodes itself.
    native: Option<Arc<native::Native>>,
    file_stamp: FileStamp,
    decoder: Decoder,
    bytes_per_pixel: usize,
    levels: Vec<LevelInfo>,
    halving: Halving,
    /// Per level, per block: bumped where the pixels changed.
    stamps: Vec<Vec<u32>>,
    /// The base level's blocks, when the raster is read whole.
    pinned: Option<Vec<Arc<Block>>>,
    /// Bytes of pixels read from the files (through GDAL or decoded here), all versions together.
    bytes_read: Arc<AtomicU64>,
    poles: [OnceLock<Option<f32>>; 2],
    /// The blocks' signatures for the next reload, found in the background
    /// (None when the file changed meanwhile).
    signatures: Arc<OnceLock<Option<Signatures>>>,
    /// Blocks a newer version replaced: they leave the cache when this
    /// version goes, not before, since a generation still serving it may
    /// read them meanwhile.
    replaced: blocks::Departing,
}

#[derive(Debug, Clone)]
pub(crate) struct Raster {
    pub path: PathBuf,
    pub fingerprint: Fingerprint,
    /// A mosaic's member files (a VRT's sources) and how they looked.
    pub members: Vec<(PathBuf, Option<FileStamp>)>,
    /// Members the VRT names that are not there (left out; their area is nodata).
    pub missing: Vec<PathBuf>,
    pub kind: RasterKind,
    /// Width and height of the base level, in pixels.
    pub size: (usize, usize),
    /// Pixel-edge geotransform (GDAL's) and its inverse.
    pub geo: [f64; 6],
    pub inverse: [f64; 6],
    /// WKT of the raster's CRS.
    pub crs_wkt: String,
    pub crs_name: String,
    pub units: VerticalUnits,
    /// Columns wrap round (a global geographic raster).
    pub wraps_x: bool,
    /// The raster's CRS is geographic (degrees).
    pub geographic: bool,
    pub details: BTreeMap<String, String>,
    /// Read through a warp (GCPs): the pixels are the warp's, not the file's blocks.
    pub warped: bool,
    /// Sentences for the scene state: what was read differently from how the file says it.
    pub warnings: Vec<String>,
    store: Arc<Store>,
}

pub(crate) fn format_err(what: impl std::fmt::Display, path: &Path) -> SourceError {
    SourceError::format(what.to_string(), path)
}

/// A rectangle of pixels, half open: [x0, x1) x [y0, y1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct PixelRect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

impl PixelRect {
    pub(crate) fn width(&self) -> usize {
        self.x1.saturating_sub(self.x0)
    }

    pub(crate) fn height(&self) -> usize {
        self.y1.saturating_sub(self.y0)
    }

    /// This rectangle of the base level, over `level` (every pixel it
    /// touches, by the level's own pixel size: an overview's need not be a
    /// power of two).
    pub(crate) fn on_level(&self, level: &LevelInfo) -> Self {
        let (px, py) = level.pixel;
        let floor = |v: usize, p: f64| (v as f64 / p).floor() as usize;
        let ceil = |v: usize, p: f64, size: usize| ((v as f64 / p).ceil() as usize).min(size);
        Self {
            x0: floor(self.x0, px),
            y0: floor(self.y0, py),
            x1: ceil(self.x1, px, level.width),
            y1: ceil(self.y1, py, level.height),
        }
    }

    /// This rectangle of the base level, over a level `scale` times coarser
    /// (every pixel it touches).
    pub(crate) fn shrink(&self, scale: usize) -> Self {
        Self { x0: self.x0 / scale, y0: self.y0 / scale, x1: self.x1.div_ceil(scale), y1: self.y1.div_ceil(scale) }
    }
}

impl Raster {
    pub(crate) fn open(path: &Path, options: &ReadOptions) -> Result<Self, SourceError> {
        let header = Self::header(path, options)?;
        let residency = match options.residency {
            Residency::Auto => {
                let bytes = header.raster.size.0 * header.raster.size.1 * header.levels[0].cache_pixel_bytes;
                if bytes as u64 <= block_budget() / 4 { Residency::Whole } else { Residency::Windowed }
            }
            other => other,
        };
        let raster = header.into_raster(blocks::new_uid(), None)?;
        let raster = if residency == Residency::Whole { raster.read_whole()? } else { raster.probe()? };
        let mut raster = raster;
        match raster.check_overviews()? {
            checks::Overviews::Agree(detail) => {
                if let Some(detail) = detail {
                    raster.details.insert("overview_check".into(), detail);
                }
            }
            checks::Overviews::Rebuild { detail, warning } => {
                tracing::warn!(raster = %path.display(), "{warning}");
                // The same read as with `overviews = false`: coarse levels
                // halved from the base.
                let mut rebuilt = Self::open(path, &ReadOptions { overviews: false, ..options.clone() })?;
                rebuilt.details.insert("overview_check".into(), detail);
                rebuilt.details.insert(
                    "overviews".into(),
                    "the file's left out (lossy beyond tolerance): coarse levels are halved from the base".into(),
                );
                rebuilt.warnings.push(warning);
                return Ok(rebuilt);
            }
        }
        raster.sign_in_background(options.changes);
        Ok(raster)
    }

    pub(crate) fn width(&self) -> usize {
        self.size.0
    }

    pub(crate) fn height(&self) -> usize {
        self.size.1
    }

    pub(crate) fn levels(&self) -> &[LevelInfo] {
        &self.store.levels
    }

    /// The pixels of `rect` of mip `level` (the file blocks under it read
    /// side by side first: `prefetch`).
    pub(crate) fn window(&self, level: usize, rect: PixelRect) -> Result<Window, SourceError> {
        prefetch::file_blocks(&self.store, level, &rect);
        self.store.window(level, rect)
    }

    /// Bytes of pixels read from the files so far, by this raster and the
    /// versions before it.
    pub(crate) fn bytes_read(&self) -> u64 {
        self.store.bytes_read.load(Ordering::Relaxed)
    }

    /// True when the raster reads its pixels as tiles need them.
    pub(crate) fn windowed(&self) -> bool {
        self.store.pinned.is_none()
    }

    /// True when the files differ from what this version read.
    pub(crate) fn files_changed(&self) -> Result<bool, SourceError> {
        Ok(Fingerprint::of(&self.path, "raster")? != self.fingerprint
            || self.members.iter().any(|(p, stamp)| FileStamp::of(p) != *stamp)
            || self.missing.iter().any(|p| p.exists()))
    }

    /// Every file the raster reads or waits for.
    pub(crate) fn files(&self) -> Vec<PathBuf> {
        std::iter::once(self.path.clone())
            .chain(self.members.iter().map(|(p, _)| p.clone()))
            .chain(self.missing.iter().cloned())
            .collect()
    }

    /// Reads every base block now and keeps them (in parallel, a handle per thread).
    fn read_whole(self) -> Result<Self, SourceError> {
        let store = &self.store;
        let (bw, bh) = (store.levels[0].width.div_ceil(BLOCK), store.levels[0].height.div_ceil(BLOCK));
        let blocks = (0..bw * bh)
            .into_par_iter()
            .map(|b| store.load(0, b % bw, b / bw).map(Arc::new))
            .collect::<Result<Vec<_>, _>>()?;
        if Fingerprint::of(&self.path, "raster")? != self.fingerprint {
            return Err(SourceError::Changing { path: self.path.clone() });
        }
        let store = Store { pinned: Some(blocks), ..store.fork(store.uid) };
        Ok(Self { store: Arc::new(store), ..self })
    }

    /// The raster's outer pixel edges in its own CRS: [min x, min y, max x, max y].
    pub(crate) fn bounds(&self) -> [f64; 4] {
        self.rect_bounds(&PixelRect { x0: 0, y0: 0, x1: self.size.0, y1: self.size.1 })
    }

    /// The outer edges of a pixel rectangle in the raster's CRS.
    pub(crate) fn rect_bounds(&self, rect: &PixelRect) -> [f64; 4] {
        let (x0, y0, w, h) = (rect.x0 as f64, rect.y0 as f64, rect.x1 as f64, rect.y1 as f64);
        let corners = [(x0, y0), (w, y0), (x0, h), (w, h)].map(|(p, l)| apply(&self.geo, p, l));
        let xs = corners.map(|c| c.0);
        let ys = corners.map(|c| c.1);
        [
            xs.into_iter().fold(f64::INFINITY, f64::min),
            ys.into_iter().fold(f64::INFINITY, f64::min),
            xs.into_iter().fold(f64::NEG_INFINITY, f64::max),
            ys.into_iter().fold(f64::NEG_INFINITY, f64::max),
        ]
    }

    /// The one height of a pole the raster reaches (its edge row there,
    /// averaged over its valid pixels), so every tile and every longitude
    /// agree on it. None when the raster does not reach that pole.
    pub(crate) fn pole_height(&self, north: bool) -> Result<Option<f32>, SourceError> {
        if !self.geographic {
            return Ok(None);
        }
        let [_, min_y, _, max_y] = self.bounds();
        let reaches = if north { max_y >= 90.0 - 1e-9 } else { min_y <= -90.0 + 1e-9 };
        if !reaches {
            return Ok(None);
        }
        let cell = &self.store.poles[usize::from(!north)];
        if let Some(h) = cell.get() {
            return Ok(*h);
        }
        let row = if north { 0 } else { self.height() - 1 };
        let w = self.window(0, PixelRect { x0: 0, y0: row, x1: self.width(), y1: row + 1 })?;
        let (sum, n) =
            w.planes[0].iter().filter(|v| !v.is_nan()).fold((0.0f64, 0u32), |(s, n), v| (s + f64::from(*v), n + 1));
        let h = (n > 0).then(|| (sum / f64::from(n)) as f32);
        Ok(*cell.get_or_init(|| h))
    }

    /// Pixel-edge coordinates (column, row) of a point in the raster's CRS.
    pub(crate) fn pixel_of(&self, x: f64, y: f64) -> (f64, f64) {
        apply(&self.inverse, x, y)
    }
}

impl Store {
    fn placeholder() -> Self {
        Self {
            uid: 0,
            version: 0,
            path: PathBuf::new(),
            open_path: PathBuf::new(),
            warp: None,
            holes: Vec::new(),
            tiling: None,
            native: None,
            file_stamp: FileStamp::NONE,
            decoder: Decoder::Height { band: 1, nodata: None, scale: 1.0, offset: 0.0 },
            bytes_per_pixel: 0,
            levels: Vec::new(),
            halving: Halving::HeightMean,
            stamps: Vec::new(),
            pinned: None,
            bytes_read: Arc::new(AtomicU64::new(0)),
            poles: [OnceLock::new(), OnceLock::new()],
            signatures: Arc::new(OnceLock::new()),
            replaced: blocks::Departing::default(),
        }
    }

    /// A copy of this store (same version and file) under `uid`.
    fn fork(&self, uid: u64) -> Self {
        Self {
            uid,
            version: self.version,
            path: self.path.clone(),
            open_path: self.open_path.clone(),
            warp: self.warp.clone(),
            holes: self.holes.clone(),
            tiling: self.tiling.clone(),
            native: self.native.clone(),
            file_stamp: self.file_stamp,
            decoder: self.decoder.clone(),
            bytes_per_pixel: self.bytes_per_pixel,
            levels: self.levels.clone(),
            halving: self.halving,
            stamps: self.stamps.clone(),
            pinned: self.pinned.clone(),
            bytes_read: Arc::clone(&self.bytes_read),
            poles: [OnceLock::new(), OnceLock::new()],
            signatures: Arc::new(OnceLock::new()),
            replaced: blocks::Departing::default(),
        }
    }
}
