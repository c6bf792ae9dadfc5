//! One raster file read into memory: its georeferencing, CRS, vertical
//! units, and a nodata-aware mip pyramid of f32 planes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use gdal::raster::{ColorInterpretation, GdalDataType, RasterBand};
use gdal::{Dataset, GeoTransformEx};
use relief_source::SourceError;

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

/// What a file looked like when it was read: a later refresh compares it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Fingerprint {
    len: u64,
    modified: Option<SystemTime>,
}

impl Fingerprint {
    pub(crate) fn of(path: &Path) -> Result<Self, SourceError> {
        let meta = std::fs::metadata(path).map_err(|source| SourceError::Io {
            what: "raster",
            path: path.to_path_buf(),
            source,
        })?;
        Ok(Self {
            len: meta.len(),
            modified: meta.modified().ok(),
        })
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
}

#[derive(Debug)]
pub(crate) struct Raster {
    pub path: PathBuf,
    pub fingerprint: Fingerprint,
    pub kind: RasterKind,
    /// Pixel-edge geotransform (GDAL's) and its inverse.
    pub geo: [f64; 6],
    pub inverse: [f64; 6],
    /// WKT of the raster's CRS.
    pub crs_wkt: String,
    pub crs_name: String,
    pub units: VerticalUnits,
    pub levels: Vec<Level>,
    pub details: BTreeMap<String, String>,
}

fn format_err(what: impl std::fmt::Display, path: &Path) -> SourceError {
    SourceError::format(what.to_string(), path)
}

impl Raster {
    pub(crate) fn open(path: &Path, options: &ReadOptions) -> Result<Self, SourceError> {
        crate::source::install_gdal_error_handler();
        let fingerprint = Fingerprint::of(path)?;
        let ds = open_dataset(path)?;
        let (width, height) = ds.raster_size();
        if width == 0 || height == 0 || ds.raster_count() == 0 {
            return Err(format_err("raster has no pixels or no bands", path));
        }
        let geo = ds
            .geo_transform()
            .map_err(|_| format_err("raster has no georeferencing (no geotransform)", path))?;
        let inverse = geo
            .invert()
            .map_err(|_| format_err("raster geotransform cannot be inverted", path))?;
        let srs = if let Some(def) = &options.crs_override {
            crs::spatial_ref(def, Some(path))?
        } else {
            let wkt = ds.projection();
            if wkt.trim().is_empty() {
                return Err(format_err(
                    "raster has no CRS (set 'crs' on the source in the manifest)",
                    path,
                ));
            }
            crs::spatial_ref(&wkt, Some(path))?
        };
        let crs_wkt = srs.to_wkt().map_err(|e| SourceError::Crs {
            crs: "raster CRS".into(),
            message: e.to_string(),
            path: Some(path.to_path_buf()),
        })?;
        let crs_name = crs::describe(&srs);

        let kind = options.kind.unwrap_or_else(|| guess_kind(&ds));
        let mut details = BTreeMap::new();
        details.insert("driver".into(), ds.driver().short_name());
        details.insert("size".into(), format!("{width}x{height}"));
        details.insert("bands".into(), ds.raster_count().to_string());
        details.insert(
            "pixel_size".into(),
            format!("{} x {}", geo[1], geo[5].abs()),
        );

        let (planes, units) = match kind {
            RasterKind::Height => {
                let (plane, units) = read_heights(&ds, options, path, &mut details)?;
                (vec![plane], units)
            }
            RasterKind::Color => (read_color(&ds, path, &mut details)?, VerticalUnits::Metres),
        };
        let levels = build_pyramid(
            Level {
                width,
                height,
                scale: 1.0,
                planes,
            },
            kind,
        );
        Ok(Self {
            path: path.to_path_buf(),
            fingerprint,
            kind,
            geo,
            inverse,
            crs_wkt,
            crs_name,
            units,
            levels,
            details,
        })
    }

    /// The raster's outer pixel edges in its own CRS: [min x, min y, max x, max y].
    pub(crate) fn bounds(&self) -> [f64; 4] {
        let (w, h) = (self.levels[0].width as f64, self.levels[0].height as f64);
        let corners = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)].map(|(p, l)| apply(&self.geo, p, l));
        let xs = corners.map(|c| c.0);
        let ys = corners.map(|c| c.1);
        [
            xs.into_iter().fold(f64::INFINITY, f64::min),
            ys.into_iter().fold(f64::INFINITY, f64::min),
            xs.into_iter().fold(f64::NEG_INFINITY, f64::max),
            ys.into_iter().fold(f64::NEG_INFINITY, f64::max),
        ]
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
        let message = match e {
            gdal::errors::GdalError::NullPointer { msg, .. } if !msg.trim().is_empty() => msg,
            gdal::errors::GdalError::NullPointer { .. } => {
                "no GDAL driver recognises it (corrupt, truncated or not a raster)".into()
            }
            other => other.to_string(),
        };
        // GDAL repeats the path inside its message; we put it last once.
        let message = message
            .replace(&format!("`{}' ", path.display()), "")
            .replace(&path.display().to_string(), "the file");
        format_err(format!("cannot open raster: {}", message.trim()), path)
    })
}

fn apply(gt: &[f64; 6], a: f64, b: f64) -> (f64, f64) {
    (gt[0] + a * gt[1] + b * gt[2], gt[3] + a * gt[4] + b * gt[5])
}

fn guess_kind(ds: &Dataset) -> RasterKind {
    let byte_bands = ds
        .rasterbands()
        .filter_map(Result::ok)
        .filter(|b| b.band_type() == GdalDataType::UInt8)
        .count();
    let paletted = ds
        .rasterband(1)
        .ok()
        .is_some_and(|b| b.color_table().is_some());
    if (byte_bands >= 3 && byte_bands == ds.raster_count()) || paletted {
        RasterKind::Color
    } else {
        RasterKind::Height
    }
}

/// Reads a whole band as f64; any block that fails to decode fails the read,
/// so a truncated or corrupt file never yields a partial raster.
fn read_band(band: &RasterBand<'_>, path: &Path) -> Result<Vec<f64>, SourceError> {
    let size = band.size();
    band.read_as::<f64>((0, 0), size, size, None)
        .map(|b| b.into_shape_and_vec().1)
        .map_err(|e| format_err(format!("cannot read raster data: {e}"), path))
}

/// Where the dataset's mask (per-dataset mask or alpha) says a pixel is
/// invalid. None when the mask is only the nodata value or all valid.
fn read_mask(band: &RasterBand<'_>, path: &Path) -> Result<Option<Vec<f64>>, SourceError> {
    let Ok(flags) = band.mask_flags() else {
        return Ok(None);
    };
    if flags.is_all_valid() || flags.is_nodata() {
        return Ok(None);
    }
    let mask = band
        .open_mask_band()
        .map_err(|e| format_err(format!("cannot open mask band: {e}"), path))?;
    read_band(&mask, path).map(Some)
}

fn read_heights(
    ds: &Dataset,
    options: &ReadOptions,
    path: &Path,
    details: &mut BTreeMap<String, String>,
) -> Result<(Vec<f32>, VerticalUnits), SourceError> {
    let band = ds.rasterband(options.band).map_err(|e| {
        format_err(
            format!(
                "raster has no band {} ({} bands): {e}",
                options.band,
                ds.raster_count()
            ),
            path,
        )
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
    details.insert(
        "nodata".into(),
        nodata.map_or_else(|| "none".into(), |v| v.to_string()),
    );
    details.insert(
        "unit_type".into(),
        if unit_type.is_empty() {
            "(unset: metres assumed)".into()
        } else {
            unit_type
        },
    );

    let values = read_band(&band, path)?;
    let mask = read_mask(&band, path)?;
    let mut voids = 0usize;
    let heights = values
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let masked = mask.as_ref().is_some_and(|m| m[i] == 0.0);
            if masked || v.is_nan() || nodata.is_some_and(|nd| v == nd) {
                voids += 1;
                f32::NAN
            } else {
                (v * scale + offset) as f32
            }
        })
        .collect();
    details.insert("nodata_pixels".into(), voids.to_string());
    Ok((heights, units))
}

fn read_color(
    ds: &Dataset,
    path: &Path,
    details: &mut BTreeMap<String, String>,
) -> Result<Vec<Vec<f32>>, SourceError> {
    let count = ds.raster_count();
    let first = ds.rasterband(1).map_err(|e| format_err(e, path))?;
    let n = first.size().0 * first.size().1;
    let mut rgba: Vec<Vec<f64>> = Vec::with_capacity(4);
    let mut valid = vec![true; n];

    if let Some(table) = first.color_table() {
        details.insert("palette".into(), format!("{} entries", table.entry_count()));
        let nodata = first.no_data_value();
        let index = read_band(&first, path)?;
        let mut planes: Vec<Vec<f64>> = (0..4).map(|_| Vec::with_capacity(n)).collect();
        for (i, &v) in index.iter().enumerate() {
            let entry = table.entry_as_rgb(v as usize);
            if nodata.is_some_and(|nd| v == nd) || entry.is_none() {
                valid[i] = false;
            }
            let c = entry.unwrap_or(gdal::raster::RgbaEntry {
                r: 0,
                g: 0,
                b: 0,
                a: 0,
            });
            for (plane, value) in planes.iter_mut().zip([c.r, c.g, c.b, c.a]) {
                plane.push(f64::from(value));
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
                    valid
                        .iter_mut()
                        .zip(&values)
                        .for_each(|(ok, v)| *ok = *v != nd);
                } else {
                    valid
                        .iter_mut()
                        .zip(&values)
                        .for_each(|(ok, v)| *ok = *ok || *v != nd);
                }
            }
            if let Some(mask) = read_mask(&band, path)? {
                valid
                    .iter_mut()
                    .zip(&mask)
                    .for_each(|(ok, m)| *ok = *ok && *m != 0.0);
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
    let alpha: Vec<f32> = rgba[3]
        .iter()
        .zip(&valid)
        .map(|(a, ok)| if *ok { (*a / 255.0) as f32 } else { 0.0 })
        .collect();
    let mut planes: Vec<Vec<f32>> = rgba[..3]
        .iter()
        .map(|p| {
            p.iter()
                .zip(&alpha)
                .map(|(c, a)| (*c / 255.0) as f32 * a)
                .collect()
        })
        .collect();
    planes.push(alpha);
    Ok(planes)
}

/// Halves the raster until it is one pixel, averaging valid pixels only.
fn build_pyramid(base: Level, kind: RasterKind) -> Vec<Level> {
    let mut levels = vec![base];
    loop {
        let prev = levels.last().expect("pyramid has a base level");
        if prev.width <= 1 && prev.height <= 1 {
            break;
        }
        let (w, h) = (prev.width.div_ceil(2), prev.height.div_ceil(2));
        let planes = match kind {
            RasterKind::Height => vec![halve(&prev.planes[0], prev.width, prev.height, true)],
            // Premultiplied colour averages plainly: transparent pixels weigh nothing.
            RasterKind::Color => prev
                .planes
                .iter()
                .map(|p| halve(p, prev.width, prev.height, false))
                .collect(),
        };
        levels.push(Level {
            width: w,
            height: h,
            scale: prev.scale * 2.0,
            planes,
        });
    }
    levels
}

fn halve(plane: &[f32], width: usize, height: usize, skip_nan: bool) -> Vec<f32> {
    let (w, h) = (width.div_ceil(2), height.div_ceil(2));
    let mut out = Vec::with_capacity(w * h);
    for j in 0..h {
        for i in 0..w {
            let mut sum = 0.0f64;
            let mut count = 0u32;
            let mut cells = 0u32;
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
            out.push(if count == 0 {
                f32::NAN
            } else {
                (sum / f64::from(divisor)) as f32
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halving_ignores_nodata_and_keeps_all_void_blocks_void() {
        let n = f32::NAN;
        let plane = [1.0, 3.0, n, n, 5.0, n, n, n, 2.0];
        let out = halve(&plane, 3, 3, true);
        assert_eq!(out.len(), 4);
        assert_eq!(out[0], 3.0); // (1 + 3 + 5) / 3: the void does not pull it down
        assert!(out[1].is_nan()); // n, n over n: nothing valid
        assert!(out[2].is_nan() && out[3] == 2.0);
    }

    #[test]
    fn unit_types_map_to_metres() {
        assert_eq!(
            VerticalUnits::from_unit_type("metre"),
            Some(VerticalUnits::Metres)
        );
        assert_eq!(
            VerticalUnits::from_unit_type(""),
            Some(VerticalUnits::Metres)
        );
        assert_eq!(
            VerticalUnits::from_unit_type("ft"),
            Some(VerticalUnits::Feet)
        );
        assert_eq!(VerticalUnits::from_unit_type("fathoms"), None);
    }
}
