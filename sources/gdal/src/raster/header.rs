//! A raster's header: frame, CRS, units, decoder and levels, read with
//! no pixels; and how GDAL opens the file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use gdal::raster::GdalDataType;
use gdal::{Dataset, GeoTransformEx};
use relief_source::SourceError;

use super::blocks::BLOCK;
use super::decode::Decoder;
use super::halve::Halving;
use super::native::Native;
use super::tiling::Tiling;
use super::warp::{self, MemFile};
use super::{FileStamp, Fingerprint, LevelInfo, PixelRect, Raster, RasterKind, ReadOptions, Store, format_err, vrt};
use crate::crs;

/// The header of a raster: everything but its pixels.
pub(super) struct Header {
    pub(super) raster: Raster,
    pub(super) decoder: Decoder,
    pub(super) levels: Vec<LevelInfo>,
    open_path: PathBuf,
    /// The warped VRT `open_path` names, kept while a version reads it.
    warp: Option<Arc<MemFile>>,
    holes: Vec<PixelRect>,
    tiling: Option<Tiling>,
    native: Option<Native>,
    bytes_per_pixel: usize,
    categorical: bool,
}

pub(super) static VERSION: AtomicU64 = AtomicU64::new(1);

impl Raster {
    /// Reads the file's header (no pixels): frame, CRS, units, decoder,
    /// levels. A VRT that names missing files is opened without them.
    pub(super) fn header(path: &Path, options: &ReadOptions) -> Result<Header, SourceError> {
        crate::source::configure_gdal();
        // Checked before relief reads a member itself, as GDAL's opens are.
        crate::guard::check_dataset(path).map_err(|e| format_err(format!("cannot open raster: {e}"), path))?;
        let fingerprint = Fingerprint::of(path, "raster")?;
        let members = vrt::members(path)?;
        let ds = open_dataset_named(&members.open_path, path)?;
        let (width, height) = ds.raster_size();
        if width == 0 || height == 0 || ds.raster_count() == 0 {
            return Err(format_err("raster has no pixels or no bands", path));
        }
        let kind = options.kind.unwrap_or_else(|| guess_kind(&ds));
        let (driver, bands) = (ds.driver().short_name(), ds.raster_count());
        // A raster georeferenced by GCPs is read through its warp, north-up.
        let warped = match ds.geo_transform() {
            Ok(_) => None,
            Err(_) => Some(
                warp::from_gcps(&ds, &members.open_path, path, kind, options)?
                    .ok_or_else(|| format_err("raster has no georeferencing (no geotransform and no GCPs)", path))?,
            ),
        };
        let band_options;
        let (ds, options, open_path, holes) = match &warped {
            Some(w) => {
                band_options = ReadOptions { band: w.band, ..options.clone() };
                // Missing mosaic members read as the VRT says (its nodata);
                // their holes are in the file's pixels, not the warp's.
                (open_dataset_named(&w.file.path, path)?, &band_options, w.file.path.clone(), Vec::new())
            }
            None => (ds, options, members.open_path.clone(), members.holes.clone()),
        };
        let (width, height) = ds.raster_size();
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
        let mut details = BTreeMap::new();
        details.insert("driver".into(), driver);
        details.insert("size".into(), format!("{width}x{height}"));
        details.insert("bands".into(), bands.to_string());
        let rotated = geo[2] != 0.0 || geo[4] != 0.0;
        if rotated {
            // Pixel sides along the raster's own axes, and how far they turn.
            details.insert("pixel_size".into(), format!("{} x {}", geo[1].hypot(geo[4]), geo[2].hypot(geo[5])));
            details.insert(
                "georeferencing".into(),
                format!(
                    "rotated geotransform (its rows run {:.3} degrees anticlockwise of east): sampled through it \
                     as it is, no warp",
                    geo[4].atan2(geo[1]).to_degrees()
                ),
            );
        } else {
            details.insert("pixel_size".into(), format!("{} x {}", geo[1], geo[5].abs()));
        }
        let mut warnings = Vec::new();
        if let Some(w) = &warped {
            details.insert("georeferencing".into(), w.description.clone());
            warnings.push(w.warning.clone());
        }
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
        let mut levels = level_infos(&ds, &decoder, (width, height), options.overviews && !categorical);
        // A mosaic of whole files placed pixel for pixel is read from them.
        let tiling = match (&decoder, &warped) {
            (Decoder::Height { band, .. }, None) => Tiling::plan(&members, *band, &ds, path),
            _ => None,
        };
        if tiling.is_some() {
            details.insert("mosaic_reads".into(), "from the member files (the VRT places them pixel for pixel)".into());
        }
        // A plain GeoTIFF read as it is (no warp, no mosaic) is decoded here.
        let native = match (&decoder, &warped) {
            (Decoder::Height { band, .. }, None) if members.files.is_empty() => Native::plan(&ds, *band, path),
            _ => None,
        };
        if let Some(native) = &native {
            details.insert("block_decoding".into(), native.describe());
        }
        let as_stored = decoder.heights_as_stored() && holes.is_empty();
        let kept = Kept { ds: &ds, decoder: &decoder, tiling: tiling.as_ref(), native: native.as_ref(), as_stored };
        details.insert("block_cache".into(), kept.size(&mut levels));
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
            warped: warped.is_some(),
            warnings,
            store: Arc::new(Store::placeholder()),
        };
        Ok(Header {
            raster,
            decoder,
            levels,
            open_path,
            warp: warped.map(|w| w.file),
            holes,
            tiling,
            native,
            bytes_per_pixel,
            categorical,
        })
    }

    /// The header of this raster's next version when only mosaic members
    /// changed: a mosaic read from its members whose VRT is unchanged and
    /// names the same members, none newly missing or back. GDAL's VRT is
    /// then not opened again (its frame, CRS, decoder and levels are as
    /// they were). None otherwise: read the header afresh.
    pub(super) fn header_again(&self, options: &ReadOptions) -> Result<Option<Header>, SourceError> {
        let store = &self.store;
        let Some(tiling) = &store.tiling else { return Ok(None) };
        if FileStamp::of(&self.path) != Some(store.file_stamp) {
            return Ok(None);
        }
        let members = vrt::members(&self.path)?;
        let same_files = members.files.len() == self.members.len()
            && members.files.iter().zip(&self.members).all(|(a, (b, _))| a == b);
        if !same_files || members.missing != self.missing {
            return Ok(None);
        }
        let stamped: Vec<(PathBuf, Option<FileStamp>)> = members
            .files
            .into_iter()
            .map(|p| {
                let stamp = FileStamp::of(&p);
                (p, stamp)
            })
            .collect();
        let Some(tiling) = tiling.restamped(&stamped) else { return Ok(None) };
        let mut raster = self.clone();
        raster.fingerprint = Fingerprint::of(&self.path, "raster")?;
        raster.members = stamped;
        Ok(Some(Header {
            raster,
            decoder: store.decoder.clone(),
            levels: store.levels.clone(),
            open_path: store.open_path.clone(),
            warp: None,
            holes: store.holes.clone(),
            tiling: Some(tiling),
            native: None,
            bytes_per_pixel: store.bytes_per_pixel,
            categorical: options.categorical,
        }))
    }
}

impl Header {
    /// The raster of this header with a store of its own: blocks under
    /// `uid`, stamps and counters carried from `previous` when given.
    pub(super) fn into_raster(self, uid: u64, previous: Option<&Store>) -> Result<Raster, SourceError> {
        let Self { mut raster, decoder, levels, open_path, warp, holes, tiling, native, bytes_per_pixel, categorical } =
            self;
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
            warp,
            holes,
            tiling: tiling.map(Arc::new),
            // Decoded here only while the file is as its tables were read.
            native: native.filter(|n| n.stamp == file_stamp).map(Arc::new),
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
            replaced: super::blocks::Departing::default(),
        });
        Ok(raster)
    }
}

/// What decides how a raster's file levels are kept in the block cache.
struct Kept<'a> {
    ds: &'a Dataset,
    decoder: &'a Decoder,
    tiling: Option<&'a Tiling>,
    native: Option<&'a Native>,
    /// Heights read as the file stores them, with no holes punched.
    as_stored: bool,
}

impl Kept<'_> {
    /// Sets each level's `cache_pixel_bytes`: 2 where the level's heights
    /// can be read as the 16-bit integers stored, by the path
    /// `Store::read_pixels` takes for it (the mosaic's members, the blocks
    /// decoded here, or GDAL), which then reads it so; else f32 (a level
    /// halved here too). Says how, for the state's `block_cache`.
    fn size(&self, levels: &mut [LevelInfo]) -> String {
        let f32_bytes = 4 * self.decoder.planes();
        for (index, level) in levels.iter_mut().enumerate() {
            let size = (level.width, level.height);
            let sixteen = self.as_stored
                && (index == 0 || level.overview.is_some())
                && match (self.tiling, self.native) {
                    (Some(tiling), _) => tiling.gives_i16(index),
                    (None, Some(native)) if native.decodes(size) => native.keeps_i16(size),
                    _ => self.decoder.reads_i16(self.ds, level.overview),
                };
            level.cache_pixel_bytes = if sixteen { 2 } else { f32_bytes };
        }
        if !levels[0].kept_i16() {
            return format!("decoded f32 ({f32_bytes} bytes a pixel)");
        }
        let overviews = levels.iter().filter(|l| l.overview.is_some());
        let (all, wide) = overviews.fold((0, 0), |(all, wide), l| (all + 1, wide + usize::from(!l.kept_i16())));
        let wide = if wide > 0 { format!("; {wide} of its {all} overviews decoded f32") } else { String::new() };
        format!("16-bit heights as the file stores them (2 bytes a pixel){wide}; a level halved here, decoded f32")
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
    let base = (width, height);
    let mut levels = vec![LevelInfo::new(base, 1.0, None, (1.0, 1.0), base)];
    loop {
        let prev = levels.last().expect("the base level is there");
        if prev.width <= 1 && prev.height <= 1 {
            break;
        }
        let (w, h) = (prev.width.div_ceil(2), prev.height.div_ceil(2));
        let overview = overviews.iter().position(|&s| s == (w, h));
        // An overview spreads its pixels evenly over the raster; a halved
        // level's are twice the level below's.
        let pixel = match overview {
            Some(_) => (width as f64 / w as f64, height as f64 / h as f64),
            None => (prev.pixel.0 * 2.0, prev.pixel.1 * 2.0),
        };
        levels.push(LevelInfo::new((w, h), prev.scale * 2.0, overview, pixel, base));
    }
    levels
}

/// Opens a raster read-only, with GDAL's own words when it cannot.
pub(crate) fn open_dataset(path: &Path) -> Result<Dataset, SourceError> {
    use gdal::{DatasetOptions, GdalOpenFlags};
    // GDAL opens it, and the side files it looks for, itself: a pipe in
    // their place would block it for good.
    // (relief's own VRTs in GDAL's memory were written from checked files.)
    let object = relief_source::objects::is_object(path);
    if !path.starts_with(crate::guard::OWN_MEMORY_FILES) {
        if !object {
            relief_source::regular::check_for_gdal(path, false)
                .map_err(|e| format_err(format!("cannot open raster: {e}"), path))?;
        }
        crate::guard::check_dataset(path).map_err(|e| format_err(format!("cannot open raster: {e}"), path))?;
    }
    let options = DatasetOptions {
        open_flags: GdalOpenFlags::GDAL_OF_RASTER
            | GdalOpenFlags::GDAL_OF_READONLY
            | GdalOpenFlags::GDAL_OF_VERBOSE_ERROR,
        ..DatasetOptions::default()
    };
    // An object's "folder" is never listed, nor side objects asked for one
    // by one: a request each, and a COG has none.
    let _empty_folder = object.then(crate::objects::EmptyFolder::set);
    Dataset::open_ex(path, options).map_err(|e| {
        let message = crate::gdal_message(e, path, "no GDAL driver recognises it (corrupt, truncated or not a raster)");
        format_err(format!("cannot open raster: {message}"), path)
    })
}

pub(super) fn apply(gt: &[f64; 6], a: f64, b: f64) -> (f64, f64) {
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
