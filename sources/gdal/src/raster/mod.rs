//! One raster (a file, or a mosaic through a VRT): its georeferencing,
//! CRS and vertical units, read from the header at once, and its pixels on
//! demand, as blocks of a nodata-aware mip pyramid (`blocks`). A raster
//! small enough is read whole when it opens; a larger one only where tiles
//! need it. A reload finds the changed blocks (`changes`) and reads only those.

mod blocks;
mod changes;
mod decode;
mod halve;
mod tiff;
mod vrt;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use gdal::raster::GdalDataType;
use gdal::{Dataset, GeoTransformEx};
use rayon::prelude::*;
use relief_source::SourceError;
pub(crate) use relief_source::files::Fingerprint;

use blocks::{BLOCK, Block};
pub use blocks::{DEFAULT_BLOCK_BUDGET, block_budget, cached_bytes, set_block_budget};
pub(crate) use blocks::{GDAL_CACHE_MB, Window};
pub use changes::ChangeDetection;
use changes::{Changes, Signatures};
use decode::Decoder;
use halve::Halving;

use crate::crs;

/// What a raster is read as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RasterKind {
    /// Band 1 as heights in metres; NaN marks nodata.
    Height,
    /// Red, green, blue (and alpha) bytes, stored as premultiplied planes in 0..1.
    Color,
}

/// How heights in the file are scaled to metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VerticalUnits {
    Metres,
    Feet,
    UsSurveyFeet,
}

impl VerticalUnits {
    fn from_unit_type(unit: &str) -> Option<Self> {
        match unit.trim().to_ascii_lowercase().as_str() {
            "" | "m" | "metre" | "meter" | "metres" | "meters" => Some(Self::Metres),
            "ft" | "foot" | "feet" | "international foot" => Some(Self::Feet),
            "us-ft" | "us survey foot" | "ftus" => Some(Self::UsSurveyFeet),
            _ => None,
        }
    }

    pub fn to_metres(self) -> f64 {
        match self {
            Self::Metres => 1.0,
            Self::Feet => 0.3048,
            Self::UsSurveyFeet => 1200.0 / 3937.0,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Metres => "m",
            Self::Feet => "ft",
            Self::UsSurveyFeet => "us-ft",
        }
    }
}

/// How the pixels are held.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Residency {
    /// Whole when the decoded base level is at most a quarter of the block
    /// budget, else windowed.
    Auto,
    /// Read whole when the raster opens and kept: the last good pixels are
    /// served whatever then happens to the file.
    Whole,
    /// Read by blocks as tiles need them, through the block cache.
    Windowed,
}

impl Residency {
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Whole => "whole",
            Self::Windowed => "windowed",
        }
    }
}

/// One level of the mip pyramid: `width` x `height` pixels, each `scale`
/// base pixels wide; read from the file's overview number `overview` when
/// it has one of this size, else halved from the level below.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LevelInfo {
    pub width: usize,
    pub height: usize,
    pub scale: f64,
    pub overview: Option<usize>,
}

/// How the manifest asked the raster to be read.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ReadOptions {
    pub kind: Option<RasterKind>,
    pub crs_override: Option<String>,
    pub units_override: Option<VerticalUnits>,
    pub band: usize,
    /// The values are codes (land-cover classes), not quantities: coarser
    /// mip pixels take the most common valid value under them, never a mean.
    pub categorical: bool,
    pub residency: Residency,
    pub changes: ChangeDetection,
    /// Use the file's overviews for coarse levels.
    pub overviews: bool,
}

/// The primary file's size, modification time and inode: checked around
/// every read of a windowed raster.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FileStamp {
    len: u64,
    modified: Option<std::time::SystemTime>,
    ino: u64,
}

impl FileStamp {
    pub(crate) fn of(path: &Path) -> Option<Self> {
        use std::os::unix::fs::MetadataExt;
        let meta = std::fs::metadata(path).ok()?;
        Some(Self { len: meta.len(), modified: meta.modified().ok(), ino: meta.ino() })
    }
}

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
    /// What GDAL opens: the file, or a VRT rewritten without its missing members.
    open_path: PathBuf,
    /// Base pixels of missing members: nodata.
    holes: Vec<PixelRect>,
    file_stamp: FileStamp,
    decoder: Decoder,
    bytes_per_pixel: usize,
    levels: Vec<LevelInfo>,
    halving: Halving,
    /// Per level, per block: bumped where the pixels changed.
    stamps: Vec<Vec<u32>>,
    /// The base level's blocks, when the raster is read whole.
    pinned: Option<Vec<Arc<Block>>>,
    /// Bytes of pixels read through GDAL, all versions together.
    bytes_read: Arc<AtomicU64>,
    poles: [OnceLock<Option<f32>>; 2],
    /// The blocks' signatures for the next reload, found in the background
    /// (None when the file changed meanwhile).
    signatures: Arc<OnceLock<Option<Signatures>>>,
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

    /// This rectangle of the base level, over a level `scale` times coarser
    /// (every pixel it touches).
    pub(crate) fn shrink(&self, scale: usize) -> Self {
        Self { x0: self.x0 / scale, y0: self.y0 / scale, x1: self.x1.div_ceil(scale), y1: self.y1.div_ceil(scale) }
    }
}

/// What a reload found.
#[derive(Debug)]
pub(crate) enum Reloaded {
    /// Same size, georeferencing and pixels: the same data under the
    /// files' new fingerprint.
    Same(Raster),
    /// Same size and georeferencing; these pixels changed.
    Pixels(Raster, Vec<PixelRect>),
    /// Size, georeferencing, CRS or kind changed: everything did.
    Everything(Raster),
}

/// A base block a reload read: where, its new pixels, what of it changed.
type ReadBlock = ((usize, usize), Arc<Block>, Vec<PixelRect>);

/// Side of the square blocks compared on reload.
const DIFF_BLOCK: usize = 64;

/// The header of a raster: everything but its pixels.
struct Header {
    raster: Raster,
    decoder: Decoder,
    levels: Vec<LevelInfo>,
    open_path: PathBuf,
    holes: Vec<PixelRect>,
    bytes_per_pixel: usize,
    categorical: bool,
}

static VERSION: AtomicU64 = AtomicU64::new(1);

impl Raster {
    pub(crate) fn open(path: &Path, options: &ReadOptions) -> Result<Self, SourceError> {
        let header = Self::header(path, options)?;
        let residency = match options.residency {
            Residency::Auto => {
                let bytes = header.raster.size.0 * header.raster.size.1 * header.decoder_planes() * 4;
                if bytes as u64 <= block_budget() / 4 { Residency::Whole } else { Residency::Windowed }
            }
            other => other,
        };
        let raster = header.into_raster(blocks::new_uid(), None)?;
        let raster = if residency == Residency::Whole { raster.read_whole()? } else { raster.probe()? };
        raster.check_overviews()?;
        raster.sign_in_background(options.changes);
        Ok(raster)
    }

    /// Reads the file's header (no pixels): frame, CRS, units, decoder,
    /// levels. A VRT that names missing files is opened without them.
    fn header(path: &Path, options: &ReadOptions) -> Result<Header, SourceError> {
        crate::source::install_gdal_error_handler();
        let fingerprint = Fingerprint::of(path, "raster")?;
        let members = vrt::members(path)?;
        let ds = open_dataset_named(&members.open_path, path)?;
        let (width, height) = ds.raster_size();
        if width == 0 || height == 0 || ds.raster_count() == 0 {
            return Err(format_err("raster has no pixels or no bands", path));
        }
        let geo = ds.geo_transform().map_err(|_| format_err("raster has no georeferencing (no geotransform)", path))?;
        let inverse = geo.invert().map_err(|_| format_err("raster geotransform cannot be inverted", path))?;
        let srs = if let Some(def) = &options.crs_override {
            crs::spatial_ref(def, Some(path))?
        } else {
            let wkt = ds.projection();
            if wkt.trim().is_empty() {
                return Err(format_err("raster has no CRS (set 'crs' on the source in the manifest)", path));
            }
            crs::spatial_ref(&wkt, Some(path))?
        };
        let crs_wkt = srs.to_wkt().map_err(|e| SourceError::Crs {
            crs: "raster CRS".into(),
            message: e.to_string(),
            path: Some(path.to_path_buf()),
        })?;
        let crs_name = crs::describe(&srs);
        // A north-up geographic raster 360 degrees wide has no east or west
        // edge: its columns wrap round at the antimeridian.
        let wraps_x = srs.is_geographic()
            && geo[2] == 0.0
            && geo[4] == 0.0
            && ((width as f64 * geo[1]).abs() - 360.0).abs() < 1e-6;

        let kind = options.kind.unwrap_or_else(|| guess_kind(&ds));
        let mut details = BTreeMap::new();
        details.insert("driver".into(), ds.driver().short_name());
        details.insert("size".into(), format!("{width}x{height}"));
        details.insert("bands".into(), ds.raster_count().to_string());
        details.insert("pixel_size".into(), format!("{} x {}", geo[1], geo[5].abs()));
        if !members.missing.is_empty() {
            let names: Vec<String> = members.missing.iter().map(|p| p.display().to_string()).collect();
            tracing::warn!(vrt = %path.display(), "missing mosaic files left out: {}", names.join(", "));
            details.insert(
                "missing_files".into(),
                format!("{} (left out: their area is nodata; the rest is served)", names.join(", ")),
            );
        }
        let (decoder, units) = Decoder::new(&ds, kind, options, path, &mut details)?;
        let categorical = options.categorical;
        let levels = level_infos(&ds, &decoder, (width, height), options.overviews && !categorical);
        let overviews = levels.iter().filter(|l| l.overview.is_some()).count();
        details.insert(
            "overviews".into(),
            if overviews == 0 {
                "none: coarse levels are halved from the base where asked".into()
            } else {
                format!("{overviews} of the file's used for coarse levels")
            },
        );
        let bytes_per_pixel = decoder.bytes_per_pixel(&ds);
        let raster = Self {
            path: path.to_path_buf(),
            fingerprint,
            members: members.files.iter().map(|p| (p.clone(), FileStamp::of(p))).collect(),
            missing: members.missing,
            kind,
            size: (width, height),
            geo,
            inverse,
            crs_wkt,
            crs_name,
            units,
            wraps_x,
            geographic: srs.is_geographic(),
            details,
            store: Arc::new(Store::placeholder()),
        };
        Ok(Header {
            raster,
            decoder,
            levels,
            open_path: members.open_path,
            holes: members.holes,
            bytes_per_pixel,
            categorical,
        })
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

    /// The pixels of `rect` of mip `level`.
    pub(crate) fn window(&self, level: usize, rect: PixelRect) -> Result<Window, SourceError> {
        self.store.window(level, rect)
    }

    /// Bytes of pixels read through GDAL so far, by this raster and the
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

    /// Checks that a windowed raster's blocks are all in the file (a TIFF's
    /// block tables), or reads its first and last base blocks (any other
    /// format): a file cut short fails here, when it opens, not at its
    /// first tile.
    fn probe(self) -> Result<Self, SourceError> {
        if let Some(images) = tiff::images(&self.path) {
            for image in &images {
                image.check_within(&self.path)?;
            }
            return Ok(self);
        }
        let (bw, bh) = (self.width().div_ceil(BLOCK), self.height().div_ceil(BLOCK));
        self.store.block(0, 0, 0)?;
        self.store.block(0, bw - 1, bh - 1)?;
        Ok(self)
    }

    /// Refuses a raster whose first overview is not a reduction of its base:
    /// at up to 16 places, each overview pixel must lie within the range of
    /// the four base pixels under it (with a little slack for smoothing
    /// kernels), as nearest, average, bilinear or mode overviews all do.
    fn check_overviews(&self) -> Result<(), SourceError> {
        let levels = &self.store.levels;
        let Some(level) = levels.get(1).filter(|l| l.overview.is_some()) else {
            return Ok(());
        };
        const SIDE: usize = 8;
        let (mut checked, mut off) = (0usize, 0usize);
        let mut worst = (0.0f32, 0.0f32, 0.0f32);
        for k in 0..16 {
            let (fx, fy) = ((k % 4) as f64 / 3.0, (k / 4) as f64 / 3.0);
            let x0 = ((level.width.saturating_sub(SIDE)) as f64 * fx) as usize;
            let y0 = ((level.height.saturating_sub(SIDE)) as f64 * fy) as usize;
            let rect = PixelRect { x0, y0, x1: (x0 + SIDE).min(level.width), y1: (y0 + SIDE).min(level.height) };
            // Read straight from the file: a few pixels, not whole blocks.
            let over = self.store.read_file(level.overview, rect)?;
            let under = PixelRect {
                x0: 2 * rect.x0,
                y0: 2 * rect.y0,
                x1: (2 * rect.x1).min(self.width()),
                y1: (2 * rect.y1).min(self.height()),
            };
            let base = self.store.read_file(None, under)?;
            let (base_width, base_height) = (under.width(), under.height());
            for (o, b) in over.iter().zip(&base) {
                for j in 0..rect.height() {
                    for i in 0..rect.width() {
                        let v = o[j * rect.width() + i];
                        let below: Vec<f32> = [(0, 0), (1, 0), (0, 1), (1, 1)]
                            .iter()
                            .map(|(dx, dy)| (2 * i + dx, 2 * j + dy))
                            .filter(|&(x, y)| x < base_width && y < base_height)
                            .map(|(x, y)| b[y * base_width + x])
                            .filter(|h| !h.is_nan())
                            .collect();
                        if v.is_nan() || below.is_empty() {
                            continue;
                        }
                        let lo = below.iter().copied().fold(f32::INFINITY, f32::min);
                        let hi = below.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                        let slack = 0.25 * (hi - lo) + 0.01 * hi.abs().max(lo.abs()) + 0.5 / 255.0;
                        checked += 1;
                        if v < lo - slack || v > hi + slack {
                            off += 1;
                            worst = (v, lo, hi);
                        }
                    }
                }
            }
        }
        if checked > 0 && off * 10 > checked {
            return Err(format_err(
                format!(
                    "its overviews disagree with its base: {off} of {checked} sampled pixels of the first overview \
                     lie outside the range of the base pixels under them (e.g. {} over {}..{}); rebuild them \
                     (gdaladdo) or set overviews = false on the source",
                    worst.0, worst.1, worst.2
                ),
                &self.path,
            ));
        }
        Ok(())
    }

    /// Finds the blocks' signatures in the background, for the next reload.
    fn sign_in_background(&self, mode: ChangeDetection) {
        let (raster, cell) = (self.clone(), Arc::clone(&self.store.signatures));
        let spawned = std::thread::Builder::new().name("relief-sign".into()).spawn(move || {
            let t = std::time::Instant::now();
            let signed = Signatures::of(&raster, mode, None, true);
            let still = matches!(raster.files_changed(), Ok(false));
            tracing::debug!(ms = t.elapsed().as_secs_f64() * 1e3, ok = signed.is_ok(), "raster blocks signed");
            let _ = cell.set(signed.ok().filter(|_| still));
        });
        if spawned.is_err() {
            let _ = self.store.signatures.set(None);
        }
    }

    /// Reads the file's header again and finds what changed: the blocks
    /// whose signatures differ from the last version's are read (no other),
    /// and compared in 64 x 64 pieces with the old pixels where those are
    /// at hand (a raster read whole always has them; a windowed one when
    /// the cache does); the pieces that differ are the dirt. The mip levels
    /// above change only there.
    pub(crate) fn reload(&self, options: &ReadOptions) -> Result<Reloaded, SourceError> {
        let t = std::time::Instant::now();
        let header = Self::header(&self.path, options)?;
        let fresh = &header.raster;
        let same_frame = fresh.size == self.size
            && fresh.geo == self.geo
            && fresh.crs_wkt == self.crs_wkt
            && fresh.kind == self.kind
            && fresh.units == self.units
            && header.decoder == self.store.decoder
            && header.levels == self.store.levels
            && fresh.missing == self.missing;
        if !same_frame {
            return Self::open(&self.path, options).map(Reloaded::Everything);
        }
        let whole = !self.windowed();
        let mut raster = header.into_raster(self.store.uid, Some(&self.store))?;
        let (bw, bh) = (self.width().div_ceil(BLOCK), self.height().div_ceil(BLOCK));
        let old = self.store.signatures.wait().as_ref();
        let signatures = Signatures::of(&raster, options.changes, old, false)?;
        let changes = match old {
            Some(old) => old.diff(&signatures, self.size),
            None => Changes {
                base: vec![PixelRect { x0: 0, y0: 0, x1: self.width(), y1: self.height() }],
                overviews: Vec::new(),
            },
        };
        let rects = &changes.base;
        let mut candidates: Vec<(usize, usize)> = rects
            .iter()
            .flat_map(|r| {
                let b = r.shrink(BLOCK);
                (b.y0..b.y1.min(bh)).flat_map(move |y| (b.x0..b.x1.min(bw)).map(move |x| (x, y)))
            })
            .collect();
        candidates.sort_unstable_by_key(|&(x, y)| (y, x));
        candidates.dedup();
        tracing::debug!(ms = t.elapsed().as_secs_f64() * 1e3, blocks = candidates.len(), "raster changes found");
        // Read the candidate blocks of the new version, compare with the old.
        let new_store = &raster.store;
        let read: Vec<ReadBlock> = candidates
            .par_iter()
            .map(|&(bx, by)| {
                let new = Arc::new(new_store.load(0, bx, by)?);
                let old = self.store.cached(0, bx, by);
                let origin = (bx * BLOCK, by * BLOCK);
                let rects = match old {
                    Some(old) => diff_blocks(&old.planes, &new.planes, new.width, new.height),
                    None => vec![PixelRect { x0: 0, y0: 0, x1: new.width, y1: new.height }],
                };
                let rects = rects
                    .into_iter()
                    .map(|r| PixelRect {
                        x0: r.x0 + origin.0,
                        y0: r.y0 + origin.1,
                        x1: r.x1 + origin.0,
                        y1: r.y1 + origin.1,
                    })
                    .collect();
                Ok(((bx, by), new, rects))
            })
            .collect::<Result<_, SourceError>>()?;
        if raster.files_changed()? {
            return Err(SourceError::Changing { path: self.path.clone() });
        }
        let mut rects: Vec<PixelRect> = read.iter().flat_map(|(_, _, r)| r.iter().copied()).collect();
        // An overview block that changed where no base pixel did is a change
        // of its own (overviews rebuilt); one over changed base pixels came
        // with them, and the stamps above those pixels are bumped anyway.
        let overlaps = |a: &PixelRect, b: &PixelRect| a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1;
        let own: Vec<PixelRect> =
            changes.overviews.iter().filter(|o| !rects.iter().any(|r| overlaps(o, r))).copied().collect();
        rects.extend(own);
        let mut store = new_store.fork(self.store.uid);
        store.bump(&rects);
        if let Some(pinned) = &mut store.pinned {
            for ((bx, by), block, changed) in &read {
                if !changed.is_empty() {
                    pinned[by * bw + bx] = Arc::clone(block);
                }
            }
        }
        let _ = store.signatures.set(Some(signatures));
        raster.store = Arc::new(store);
        if !whole {
            for ((bx, by), block, changed) in read {
                if !changed.is_empty() {
                    raster.store.keep(0, bx, by, block);
                }
            }
        }
        tracing::debug!(ms = t.elapsed().as_secs_f64() * 1e3, rects = rects.len(), "raster reloaded");
        Ok(if rects.is_empty() { Reloaded::Same(raster) } else { Reloaded::Pixels(raster, rects) })
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

impl Header {
    fn decoder_planes(&self) -> usize {
        if self.raster.kind == RasterKind::Color { 4 } else { 1 }
    }

    /// The raster of this header with a store of its own: blocks under
    /// `uid`, stamps and counters carried from `previous` when given.
    fn into_raster(self, uid: u64, previous: Option<&Store>) -> Result<Raster, SourceError> {
        let Self { mut raster, decoder, levels, open_path, holes, bytes_per_pixel, categorical } = self;
        let file_stamp =
            FileStamp::of(&raster.path).ok_or_else(|| SourceError::Changing { path: raster.path.clone() })?;
        let halving = match (raster.kind, categorical) {
            (RasterKind::Color, _) => Halving::ColorMean,
            (RasterKind::Height, true) => Halving::Mode,
            (RasterKind::Height, false) => Halving::HeightMean,
        };
        let stamps = match previous {
            Some(p) => p.stamps.clone(),
            None => levels.iter().map(|l| vec![0u32; l.width.div_ceil(BLOCK) * l.height.div_ceil(BLOCK)]).collect(),
        };
        raster.store = Arc::new(Store {
            uid,
            version: VERSION.fetch_add(1, Ordering::Relaxed),
            path: raster.path.clone(),
            open_path,
            holes,
            file_stamp,
            decoder,
            bytes_per_pixel,
            levels,
            halving,
            stamps,
            pinned: previous.and_then(|p| p.pinned.clone()),
            bytes_read: previous.map_or_else(|| Arc::new(AtomicU64::new(0)), |p| Arc::clone(&p.bytes_read)),
            poles: [OnceLock::new(), OnceLock::new()],
            signatures: Arc::new(OnceLock::new()),
        });
        Ok(raster)
    }
}

impl Store {
    fn placeholder() -> Self {
        Self {
            uid: 0,
            version: 0,
            path: PathBuf::new(),
            open_path: PathBuf::new(),
            holes: Vec::new(),
            file_stamp: FileStamp { len: 0, modified: None, ino: 0 },
            decoder: Decoder::Height { band: 1, nodata: None, scale: 1.0, offset: 0.0 },
            bytes_per_pixel: 0,
            levels: Vec::new(),
            halving: Halving::HeightMean,
            stamps: Vec::new(),
            pinned: None,
            bytes_read: Arc::new(AtomicU64::new(0)),
            poles: [OnceLock::new(), OnceLock::new()],
            signatures: Arc::new(OnceLock::new()),
        }
    }

    /// A copy of this store (same version and file) under `uid`.
    fn fork(&self, uid: u64) -> Self {
        Self {
            uid,
            version: self.version,
            path: self.path.clone(),
            open_path: self.open_path.clone(),
            holes: self.holes.clone(),
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
        }
    }

    /// Bumps the stamp of every block, at every level, over `rects` of the base.
    fn bump(&mut self, rects: &[PixelRect]) {
        for (level, info) in self.levels.iter().enumerate() {
            let across = info.width.div_ceil(BLOCK);
            let scale = info.scale as usize;
            for rect in rects {
                let r = rect.shrink(scale).shrink(BLOCK);
                for by in r.y0..r.y1.min(info.height.div_ceil(BLOCK)) {
                    for bx in r.x0..r.x1.min(across) {
                        let s = &mut self.stamps[level][by * across + bx];
                        *s = s.wrapping_add(1);
                    }
                }
            }
        }
    }

    /// A block of this version if it is at hand (kept, or in the cache).
    fn cached(&self, level: usize, bx: usize, by: usize) -> Option<Arc<Block>> {
        match &self.pinned {
            Some(pinned) if level == 0 => pinned.get(by * self.levels[0].width.div_ceil(BLOCK) + bx).cloned(),
            _ => self.peek(level, bx, by),
        }
    }
}

/// The levels of the pyramid: halving the base until one pixel; each uses
/// the file's overview of exactly its size when `use_overviews`.
fn level_infos(
    ds: &Dataset,
    decoder: &Decoder,
    (width, height): (usize, usize),
    use_overviews: bool,
) -> Vec<LevelInfo> {
    let band_index = match decoder {
        Decoder::Height { band, .. } => *band,
        _ => 1,
    };
    let overviews: Vec<(usize, usize)> = ds
        .rasterband(band_index)
        .ok()
        .filter(|_| use_overviews)
        .map(|band| {
            let n = band.overview_count().unwrap_or(0).max(0) as usize;
            (0..n).map(|i| band.overview(i).map_or((0, 0), |o| o.size())).collect()
        })
        .unwrap_or_default();
    let mut levels = vec![LevelInfo { width, height, scale: 1.0, overview: None }];
    loop {
        let prev = levels.last().expect("the base level is there");
        if prev.width <= 1 && prev.height <= 1 {
            break;
        }
        let (w, h) = (prev.width.div_ceil(2), prev.height.div_ceil(2));
        let overview = overviews.iter().position(|&s| s == (w, h));
        levels.push(LevelInfo { width: w, height: h, scale: prev.scale * 2.0, overview });
    }
    levels
}

/// Opens a raster read-only, with GDAL's own words when it cannot.
fn open_dataset(path: &Path) -> Result<Dataset, SourceError> {
    use gdal::{DatasetOptions, GdalOpenFlags};
    let options = DatasetOptions {
        open_flags: GdalOpenFlags::GDAL_OF_RASTER
            | GdalOpenFlags::GDAL_OF_READONLY
            | GdalOpenFlags::GDAL_OF_VERBOSE_ERROR,
        ..DatasetOptions::default()
    };
    Dataset::open_ex(path, options).map_err(|e| {
        let message = crate::gdal_message(e, path, "no GDAL driver recognises it (corrupt, truncated or not a raster)");
        format_err(format!("cannot open raster: {message}"), path)
    })
}

fn apply(gt: &[f64; 6], a: f64, b: f64) -> (f64, f64) {
    (gt[0] + a * gt[1] + b * gt[2], gt[3] + a * gt[4] + b * gt[5])
}

fn guess_kind(ds: &Dataset) -> RasterKind {
    let byte_bands = ds.rasterbands().filter_map(Result::ok).filter(|b| b.band_type() == GdalDataType::UInt8).count();
    let paletted = ds.rasterband(1).ok().is_some_and(|b| b.color_table().is_some());
    if (byte_bands >= 3 && byte_bands == ds.raster_count()) || paletted {
        RasterKind::Color
    } else {
        RasterKind::Height
    }
}

/// Opens a raster read-only, naming `shown` in errors (a mosaic is opened
/// through a rewritten VRT).
fn open_dataset_named(open: &Path, shown: &Path) -> Result<Dataset, SourceError> {
    if open == shown {
        return open_dataset(open);
    }
    open_dataset(open).map_err(|e| format_err(e.to_string().replace(&open.display().to_string(), ""), shown))
}

/// The blocks whose pixels differ (bit for bit; all NaNs alike), merged
/// into rectangles: runs along each row of blocks, then runs of equal runs
/// down the rows.
fn diff_blocks(old: &[Vec<f32>], new: &[Vec<f32>], width: usize, height: usize) -> Vec<PixelRect> {
    let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
    let (bw, bh) = (width.div_ceil(DIFF_BLOCK), height.div_ceil(DIFF_BLOCK));
    let changed: Vec<bool> = (0..bw * bh)
        .into_par_iter()
        .map(|b| {
            let (x0, y0) = ((b % bw) * DIFF_BLOCK, (b / bw) * DIFF_BLOCK);
            let (x1, y1) = ((x0 + DIFF_BLOCK).min(width), (y0 + DIFF_BLOCK).min(height));
            old.iter().zip(new).any(|(o, n)| {
                (y0..y1).any(|y| {
                    let (o, n) = (&o[y * width + x0..y * width + x1], &n[y * width + x0..y * width + x1]);
                    // Plain float equality is the fast check; NaNs (nodata)
                    // fail it and get the exact one.
                    o != n && o.iter().zip(n).any(|(a, b)| !same(*a, *b))
                })
            })
        })
        .collect();
    let block_changed = |bx: usize, by: usize| changed[by * bw + bx];
    let mut rects: Vec<PixelRect> = Vec::new();
    let mut open: Vec<PixelRect> = Vec::new();
    for by in 0..bh {
        let mut runs = Vec::new();
        let mut bx = 0;
        while bx < bw {
            if block_changed(bx, by) {
                let start = bx;
                while bx < bw && block_changed(bx, by) {
                    bx += 1;
                }
                runs.push((start * DIFF_BLOCK, (bx * DIFF_BLOCK).min(width)));
            } else {
                bx += 1;
            }
        }
        let (y0, y1) = (by * DIFF_BLOCK, ((by + 1) * DIFF_BLOCK).min(height));
        let mut still_open = Vec::new();
        for rect in open.drain(..) {
            if let Some(pos) = runs.iter().position(|&(x0, x1)| x0 == rect.x0 && x1 == rect.x1) {
                runs.remove(pos);
                still_open.push(PixelRect { y1, ..rect });
            } else {
                rects.push(rect);
            }
        }
        still_open.extend(runs.into_iter().map(|(x0, x1)| PixelRect { x0, y0, x1, y1 }));
        open = still_open;
    }
    rects.extend(open);
    rects
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_diffs_find_exactly_the_changed_blocks() {
        let (w, h) = (300, 200);
        let old = vec![vec![1.0f32; w * h]];
        let mut new = old.clone();
        assert!(diff_blocks(&old, &new, w, h).is_empty());
        // Two pixels in one block, and a 2 x 2 run of blocks elsewhere.
        new[0][150 * w + 10] = 2.0;
        new[0][151 * w + 40] = f32::NAN;
        for (x, y) in [(130, 5), (200, 5), (130, 70), (200, 70)] {
            new[0][y * w + x] = 3.0;
        }
        let rects = diff_blocks(&old, &new, w, h);
        assert!(rects.contains(&PixelRect { x0: 0, y0: 128, x1: 64, y1: 192 }), "{rects:?}");
        assert!(rects.contains(&PixelRect { x0: 128, y0: 0, x1: 256, y1: 128 }), "{rects:?}");
        assert_eq!(rects.len(), 2, "{rects:?}");
        // NaN over NaN is no change.
        let holes = vec![vec![f32::NAN; 16]];
        assert!(diff_blocks(&holes, &holes.clone(), 4, 4).is_empty());
    }

    #[test]
    fn unit_types_map_to_metres() {
        assert_eq!(VerticalUnits::from_unit_type("metre"), Some(VerticalUnits::Metres));
        assert_eq!(VerticalUnits::from_unit_type(""), Some(VerticalUnits::Metres));
        assert_eq!(VerticalUnits::from_unit_type("ft"), Some(VerticalUnits::Feet));
        assert_eq!(VerticalUnits::from_unit_type("fathoms"), None);
    }
}
