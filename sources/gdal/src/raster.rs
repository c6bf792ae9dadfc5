//! One raster file read into memory: its georeferencing, CRS, vertical
//! units, and a nodata-aware mip pyramid of f32 planes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use gdal::raster::{ColorInterpretation, GdalDataType, RasterBand};
use gdal::{Dataset, GeoTransformEx};
use rayon::prelude::*;
use relief_source::SourceError;
pub(crate) use relief_source::files::Fingerprint;

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

/// One level of the mip pyramid: planes of `width` x `height` pixels, each
/// pixel `scale` source pixels wide.
#[derive(Debug)]
pub(crate) struct Level {
    pub width: usize,
    pub height: usize,
    pub scale: f64,
    pub planes: Vec<Vec<f32>>,
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
}

#[derive(Debug, Clone)]
pub(crate) struct Raster {
    pub path: PathBuf,
    pub fingerprint: Fingerprint,
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
    /// Mip pixels are the most common value under them (see ReadOptions).
    pub categorical: bool,
    /// The mip pyramid, base level first; shared between versions whose
    /// pixels are the same.
    pub levels: Arc<Vec<Level>>,
    pub details: BTreeMap<String, String>,
}

fn format_err(what: impl std::fmt::Display, path: &Path) -> SourceError {
    SourceError::format(what.to_string(), path)
}

/// A rectangle of base-level pixels, half open: [x0, x1) x [y0, y1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct PixelRect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
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

/// Side of the square blocks compared on reload.
const DIFF_BLOCK: usize = 64;

impl Raster {
    pub(crate) fn open(path: &Path, options: &ReadOptions) -> Result<Self, SourceError> {
        let (raster, planes) = Self::read(path, options)?;
        Ok(raster.with_base(planes))
    }

    /// This raster with `planes` as its base level and a full pyramid.
    fn with_base(self, planes: Vec<Vec<f32>>) -> Self {
        let base = Level { width: self.width(), height: self.height(), scale: 1.0, planes };
        Self { levels: Arc::new(build_pyramid(base, self.halving())), ..self }
    }

    /// Reads the file again and compares it with this version block by
    /// block. Where only pixels changed, the mip pyramid is updated there
    /// alone, so a small edit of a large DEM costs a read and a compare.
    pub(crate) fn reload(&self, options: &ReadOptions) -> Result<Reloaded, SourceError> {
        let t = std::time::Instant::now();
        let (raster, planes) = Self::read(&self.path, options)?;
        tracing::debug!(read_ms = t.elapsed().as_secs_f64() * 1e3, "raster read");
        let same_frame = raster.width() == self.width()
            && raster.height() == self.height()
            && raster.geo == self.geo
            && raster.crs_wkt == self.crs_wkt
            && raster.kind == self.kind
            && raster.units == self.units;
        if !same_frame {
            return Ok(Reloaded::Everything(raster.with_base(planes)));
        }
        let t = std::time::Instant::now();
        let rects = diff_blocks(&self.levels[0].planes, &planes, self.width(), self.height());
        tracing::debug!(diff_ms = t.elapsed().as_secs_f64() * 1e3, "raster compared");
        if rects.is_empty() {
            return Ok(Reloaded::Same(Self { levels: Arc::clone(&self.levels), ..raster }));
        }
        let mut levels: Vec<Level> = Vec::with_capacity(self.levels.len());
        levels.push(Level { width: self.width(), height: self.height(), scale: 1.0, planes });
        for old in &self.levels[1..] {
            let prev = levels.last().expect("the base level is there");
            let mut planes = old.planes.clone();
            for rect in &rects {
                update_halved(prev, &mut planes, old.width, old.height, rect, old.scale as usize, self.halving());
            }
            levels.push(Level { width: old.width, height: old.height, scale: old.scale, planes });
        }
        Ok(Reloaded::Pixels(Self { levels: Arc::new(levels), ..raster }, rects))
    }

    pub(crate) fn width(&self) -> usize {
        self.size.0
    }

    pub(crate) fn height(&self) -> usize {
        self.size.1
    }

    /// Reads the raster's frame and base planes (no pyramid yet). The
    /// dataset's files are stat'ed before and after: a writer at work
    /// makes the read fail as `Changing`, never half-read.
    fn read(path: &Path, options: &ReadOptions) -> Result<(Self, Vec<Vec<f32>>), SourceError> {
        crate::source::install_gdal_error_handler();
        let fingerprint = Fingerprint::of(path, "raster")?;
        let (raster, planes) = Self::read_unguarded(path, options, fingerprint.clone())?;
        if Fingerprint::of(path, "raster")? != fingerprint {
            return Err(SourceError::Changing { path: path.to_path_buf() });
        }
        Ok((raster, planes))
    }

    fn read_unguarded(
        path: &Path,
        options: &ReadOptions,
        fingerprint: Fingerprint,
    ) -> Result<(Self, Vec<Vec<f32>>), SourceError> {
        let ds = open_dataset(path)?;
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

        let (planes, units) = match kind {
            RasterKind::Height => {
                let (plane, units) = read_heights(&ds, options, path, &mut details)?;
                (vec![plane], units)
            }
            RasterKind::Color => (read_color(&ds, path, &mut details)?, VerticalUnits::Metres),
        };
        let raster = Self {
            path: path.to_path_buf(),
            fingerprint,
            kind,
            size: (width, height),
            geo,
            inverse,
            crs_wkt,
            crs_name,
            units,
            wraps_x,
            geographic: srs.is_geographic(),
            categorical: options.categorical,
            levels: Arc::new(Vec::new()),
            details,
        };
        Ok((raster, planes))
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
    pub(crate) fn pole_height(&self, north: bool) -> Option<f32> {
        if !self.geographic {
            return None;
        }
        let [_, min_y, _, max_y] = self.bounds();
        let reaches = if north { max_y >= 90.0 - 1e-9 } else { min_y <= -90.0 + 1e-9 };
        if !reaches {
            return None;
        }
        let base = &self.levels[0];
        let row = if north { 0 } else { base.height - 1 };
        let values = &base.planes[0][row * base.width..(row + 1) * base.width];
        let (sum, n) =
            values.iter().filter(|v| !v.is_nan()).fold((0.0f64, 0u32), |(s, n), v| (s + f64::from(*v), n + 1));
        (n > 0).then(|| (sum / f64::from(n)) as f32)
    }

    /// Pixel-edge coordinates (column, row) of a point in the raster's CRS.
    pub(crate) fn pixel_of(&self, x: f64, y: f64) -> (f64, f64) {
        apply(&self.inverse, x, y)
    }
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

/// Reads a whole band as f64; any block that fails to decode fails the read,
/// so a truncated or corrupt file never yields a partial raster.
fn read_band(band: &RasterBand<'_>, path: &Path) -> Result<Vec<f32>, SourceError> {
    let size = band.size();
    band.read_as::<f32>((0, 0), size, size, None)
        .map(|b| b.into_shape_and_vec().1)
        .map_err(|e| format_err(format!("cannot read raster data: {e}"), path))
}

/// Reads a whole band as f32, bands of rows in parallel, each task with its
/// own dataset handle (a GDAL dataset must not be shared between threads).
/// Any block that fails to decode fails the read.
fn read_band_parallel(
    path: &Path,
    band_index: usize,
    (width, height): (usize, usize),
) -> Result<Vec<f32>, SourceError> {
    let mut values = vec![0.0f32; width * height];
    values.par_chunks_mut(width * DIFF_BLOCK).enumerate().try_for_each_init(
        || open_dataset(path),
        |ds, (chunk, rows)| {
            let ds = ds.as_ref().map_err(|e| format_err(e.to_string(), path))?;
            let band = ds.rasterband(band_index).map_err(|e| format_err(e, path))?;
            let n_rows = rows.len() / width;
            band.read_into_slice::<f32>(
                (0, (chunk * DIFF_BLOCK) as isize),
                (width, n_rows),
                (width, n_rows),
                rows,
                None,
            )
            .map_err(|e| format_err(format!("cannot read raster data: {e}"), path))
        },
    )?;
    Ok(values)
}

/// Where the dataset's mask (per-dataset mask or alpha) says a pixel is
/// invalid. None when the mask is only the nodata value or all valid.
fn read_mask(band: &RasterBand<'_>, path: &Path) -> Result<Option<Vec<f32>>, SourceError> {
    let Ok(flags) = band.mask_flags() else {
        return Ok(None);
    };
    if flags.is_all_valid() || flags.is_nodata() {
        return Ok(None);
    }
    let mask = band.open_mask_band().map_err(|e| format_err(format!("cannot open mask band: {e}"), path))?;
    read_band(&mask, path).map(Some)
}

fn read_heights(
    ds: &Dataset,
    options: &ReadOptions,
    path: &Path,
    details: &mut BTreeMap<String, String>,
) -> Result<(Vec<f32>, VerticalUnits), SourceError> {
    let band = ds.rasterband(options.band).map_err(|e| {
        format_err(format!("raster has no band {} ({} bands): {e}", options.band, ds.raster_count()), path)
    })?;
    let unit_type = band.unit();
    let units = match options.units_override {
        Some(u) => u,
        None => VerticalUnits::from_unit_type(&unit_type).ok_or_else(|| {
            format_err(
                format!("unknown vertical unit '{unit_type}' (set 'vertical_units' on the source to m, ft or us-ft)"),
                path,
            )
        })?,
    };
    let nodata = band.no_data_value();
    let scale = band.scale().unwrap_or(1.0) * units.to_metres();
    let offset = band.offset().unwrap_or(0.0) * units.to_metres();
    details.insert("band_type".into(), band.band_type().name());
    details.insert("nodata".into(), nodata.map_or_else(|| "none".into(), |v| v.to_string()));
    details.insert("unit_type".into(), if unit_type.is_empty() { "(unset: metres assumed)".into() } else { unit_type });

    let (width, height) = band.size();
    let mut heights = read_band_parallel(path, options.band, (width, height))?;
    let mask = read_mask(&band, path)?;
    let nodata = nodata.map(|nd| nd as f32);
    // Map nodata to NaN and apply scale, offset and units, a band of rows
    // per task.
    let voids: usize = heights
        .par_chunks_mut(width * DIFF_BLOCK)
        .enumerate()
        .map(|(chunk, values)| {
            let first = chunk * width * DIFF_BLOCK;
            let mut voids = 0;
            for (i, v) in values.iter_mut().enumerate() {
                let masked = mask.as_ref().is_some_and(|m| m[first + i] == 0.0);
                if masked || v.is_nan() || nodata == Some(*v) {
                    voids += 1;
                    *v = f32::NAN;
                } else if scale != 1.0 || offset != 0.0 {
                    *v = (f64::from(*v) * scale + offset) as f32;
                }
            }
            voids
        })
        .sum();
    details.insert("nodata_pixels".into(), voids.to_string());
    Ok((heights, units))
}

fn read_color(ds: &Dataset, path: &Path, details: &mut BTreeMap<String, String>) -> Result<Vec<Vec<f32>>, SourceError> {
    let count = ds.raster_count();
    let first = ds.rasterband(1).map_err(|e| format_err(e, path))?;
    let n = first.size().0 * first.size().1;
    let mut rgba: Vec<Vec<f32>> = Vec::with_capacity(4);
    let mut valid = vec![true; n];

    if let Some(table) = first.color_table() {
        details.insert("palette".into(), format!("{} entries", table.entry_count()));
        let nodata = first.no_data_value();
        let index = read_band(&first, path)?;
        let mut planes: Vec<Vec<f32>> = (0..4).map(|_| Vec::with_capacity(n)).collect();
        for (i, &v) in index.iter().enumerate() {
            let entry = table.entry_as_rgb(v as usize);
            if nodata.is_some_and(|nd| v == nd as f32) || entry.is_none() {
                valid[i] = false;
            }
            let c = entry.unwrap_or(gdal::raster::RgbaEntry { r: 0, g: 0, b: 0, a: 0 });
            for (plane, value) in planes.iter_mut().zip([c.r, c.g, c.b, c.a]) {
                plane.push(f32::from(value));
            }
        }
        rgba = planes;
    } else {
        let mut alpha = None;
        for b in 1..=count.min(4) {
            let band = ds.rasterband(b).map_err(|e| format_err(e, path))?;
            if band.band_type() != GdalDataType::UInt8 {
                return Err(format_err(
                    format!(
                        "colour band {b} is {} (expected Byte; read it as output = \"height\")",
                        band.band_type().name()
                    ),
                    path,
                ));
            }
            let values = read_band(&band, path)?;
            if band.color_interpretation() == ColorInterpretation::AlphaBand {
                alpha = Some(values);
                continue;
            }
            if let Some(nd) = band.no_data_value() {
                // A pixel is nodata when every colour band holds the nodata value.
                if rgba.is_empty() {
                    valid.iter_mut().zip(&values).for_each(|(ok, v)| *ok = *v != nd as f32);
                } else {
                    valid.iter_mut().zip(&values).for_each(|(ok, v)| *ok = *ok || *v != nd as f32);
                }
            }
            if let Some(mask) = read_mask(&band, path)? {
                valid.iter_mut().zip(&mask).for_each(|(ok, m)| *ok = *ok && *m != 0.0);
            }
            if rgba.len() < 3 {
                rgba.push(values);
            }
        }
        while rgba.len() < 3 {
            // Greyscale: repeat the one band.
            rgba.push(rgba[0].clone());
        }
        rgba.push(alpha.unwrap_or_else(|| vec![255.0; n]));
    }

    let voids = valid.iter().filter(|v| !**v).count();
    details.insert("nodata_pixels".into(), voids.to_string());
    let alpha: Vec<f32> = rgba[3].iter().zip(&valid).map(|(a, ok)| if *ok { *a / 255.0 } else { 0.0 }).collect();
    let mut planes: Vec<Vec<f32>> =
        rgba[..3].iter().map(|p| p.iter().zip(&alpha).map(|(c, a)| *c / 255.0 * a).collect()).collect();
    planes.push(alpha);
    Ok(planes)
}

/// How a mip pixel is made from the (up to) four under it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Halving {
    /// Heights: the mean of the valid ones (NaN when none is).
    HeightMean,
    /// Premultiplied colour: the plain mean (transparent weighs nothing).
    ColorMean,
    /// Codes: the most common valid value (the first of equals, row by row).
    Mode,
}

impl Raster {
    fn halving(&self) -> Halving {
        match (self.kind, self.categorical) {
            (RasterKind::Height, true) => Halving::Mode,
            (RasterKind::Height, false) => Halving::HeightMean,
            (RasterKind::Color, _) => Halving::ColorMean,
        }
    }
}

/// Halves the raster until it is one pixel.
fn build_pyramid(base: Level, halving: Halving) -> Vec<Level> {
    let mut levels = vec![base];
    loop {
        let prev = levels.last().expect("pyramid has a base level");
        if prev.width <= 1 && prev.height <= 1 {
            break;
        }
        let (w, h) = (prev.width.div_ceil(2), prev.height.div_ceil(2));
        let planes = prev.planes.iter().map(|p| halve(p, prev.width, prev.height, halving)).collect();
        levels.push(Level { width: w, height: h, scale: prev.scale * 2.0, planes });
    }
    levels
}

/// One pixel of the next level, from the (up to) four pixels under it.
fn halved_pixel(plane: &[f32], width: usize, height: usize, i: usize, j: usize, halving: Halving) -> f32 {
    if halving == Halving::Mode {
        let under: Vec<f32> = [(0, 0), (1, 0), (0, 1), (1, 1)]
            .iter()
            .map(|(dx, dy)| (2 * i + dx, 2 * j + dy))
            .filter(|&(x, y)| x < width && y < height)
            .map(|(x, y)| plane[y * width + x])
            .filter(|v| !v.is_nan())
            .collect();
        let count = |v: f32| under.iter().filter(|u| **u == v).count();
        return under
            .iter()
            .copied()
            .fold(None, |best: Option<f32>, v| match best {
                Some(b) if count(b) >= count(v) => Some(b),
                _ => Some(v),
            })
            .unwrap_or(f32::NAN);
    }
    let skip_nan = halving == Halving::HeightMean;
    let mut sum = 0.0f64;
    let (mut count, mut cells) = (0u32, 0u32);
    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let (x, y) = (2 * i + dx, 2 * j + dy);
        if x < width && y < height {
            cells += 1;
            let v = plane[y * width + x];
            if !(skip_nan && v.is_nan()) {
                sum += f64::from(v);
                count += 1;
            }
        }
    }
    let divisor = if skip_nan { count } else { cells };
    if count == 0 { f32::NAN } else { (sum / f64::from(divisor)) as f32 }
}

fn halve(plane: &[f32], width: usize, height: usize, halving: Halving) -> Vec<f32> {
    let (w, h) = (width.div_ceil(2), height.div_ceil(2));
    (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| halved_pixel(plane, width, height, i, j, halving))
        .collect()
}

/// Recomputes the pixels of one pyramid level (`width` x `height`, each
/// `scale` base pixels wide) that lie over `rect` of the base level, from
/// the level below it (`prev`, already updated).
fn update_halved(
    prev: &Level,
    planes: &mut [Vec<f32>],
    width: usize,
    height: usize,
    rect: &PixelRect,
    scale: usize,
    halving: Halving,
) {
    let (i0, j0) = (rect.x0 / scale, rect.y0 / scale);
    let (i1, j1) = (rect.x1.div_ceil(scale).min(width), rect.y1.div_ceil(scale).min(height));
    for (plane, below) in planes.iter_mut().zip(&prev.planes) {
        for j in j0..j1 {
            for i in i0..i1 {
                plane[j * width + i] = halved_pixel(below, prev.width, prev.height, i, j, halving);
            }
        }
    }
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
    fn halving_ignores_nodata_and_keeps_all_void_blocks_void() {
        let n = f32::NAN;
        let plane = [1.0, 3.0, n, n, 5.0, n, n, n, 2.0];
        let out = halve(&plane, 3, 3, Halving::HeightMean);
        // Codes: the most common valid value, never a mean of classes.
        let codes = [3.0, 7.0, 7.0, f32::NAN];
        assert_eq!(halve(&codes, 2, 2, Halving::Mode), vec![7.0]);
        assert_eq!(halve(&[5.0, 9.0, f32::NAN, f32::NAN], 2, 2, Halving::Mode), vec![5.0]);
        assert!(halve(&[f32::NAN; 4], 2, 2, Halving::Mode)[0].is_nan());
        assert_eq!(out.len(), 4);
        assert_eq!(out[0], 3.0); // (1 + 3 + 5) / 3: the void does not pull it down
        assert!(out[1].is_nan()); // n, n over n: nothing valid
        assert!(out[2].is_nan() && out[3] == 2.0);
    }

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
    fn incremental_pyramids_equal_full_rebuilds() {
        let (w, h) = (150, 90);
        let base: Vec<f32> = (0..w * h).map(|i| (i % 97) as f32).collect();
        let old =
            build_pyramid(Level { width: w, height: h, scale: 1.0, planes: vec![base.clone()] }, Halving::HeightMean);
        let mut edited = base;
        for y in 20..41 {
            for x in 65..99 {
                edited[y * w + x] = if (x + y) % 7 == 0 { f32::NAN } else { 500.0 + x as f32 };
            }
        }
        let rects = diff_blocks(&old[0].planes, &[edited.clone()], w, h);
        let full =
            build_pyramid(Level { width: w, height: h, scale: 1.0, planes: vec![edited.clone()] }, Halving::HeightMean);
        let mut levels = vec![Level { width: w, height: h, scale: 1.0, planes: vec![edited] }];
        for o in &old[1..] {
            let mut planes = o.planes.clone();
            for r in &rects {
                update_halved(
                    levels.last().unwrap(),
                    &mut planes,
                    o.width,
                    o.height,
                    r,
                    o.scale as usize,
                    Halving::HeightMean,
                );
            }
            levels.push(Level { width: o.width, height: o.height, scale: o.scale, planes });
        }
        for (a, b) in levels.iter().zip(&full) {
            let bits =
                |p: &[f32]| p.iter().map(|v| if v.is_nan() { u32::MAX } else { v.to_bits() }).collect::<Vec<_>>();
            assert_eq!(bits(&a.planes[0]), bits(&b.planes[0]), "level of scale {}", a.scale);
        }
    }

    #[test]
    fn unit_types_map_to_metres() {
        assert_eq!(VerticalUnits::from_unit_type("metre"), Some(VerticalUnits::Metres));
        assert_eq!(VerticalUnits::from_unit_type(""), Some(VerticalUnits::Metres));
        assert_eq!(VerticalUnits::from_unit_type("ft"), Some(VerticalUnits::Feet));
        assert_eq!(VerticalUnits::from_unit_type("fathoms"), None);
    }
}
