//! How a window of the file becomes f32 planes: heights in metres with
//! nodata as NaN, or premultiplied RGBA in 0..1. The decoder is worked out
//! once from the file's header; each read then takes one window of the base
//! band or of one of its overviews.

use std::collections::BTreeMap;
use std::path::Path;

use gdal::Dataset;
use gdal::raster::{ColorInterpretation, GdalDataType, RasterBand};
use relief_source::SourceError;

use super::{PixelRect, RasterKind, ReadOptions, VerticalUnits, format_err};

/// What turns a window of the file's bands into planes.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Decoder {
    /// One band of heights.
    Height { band: usize, nodata: Option<f32>, scale: f64, offset: f64 },
    /// Indices into a colour table (None: no entry, drawn transparent).
    Palette { nodata: Option<f32>, entries: Vec<Option<[u8; 4]>> },
    /// Byte bands: up to three colour bands (grey repeated) and an alpha.
    Bands { colour: Vec<(usize, Option<f32>)>, alpha: Option<usize> },
}

impl Decoder {
    /// The decoder for `kind`, from the dataset's header; also the vertical
    /// units of heights, and facts for the scene state in `details`.
    pub(crate) fn new(
        ds: &Dataset,
        kind: RasterKind,
        options: &ReadOptions,
        path: &Path,
        details: &mut BTreeMap<String, String>,
    ) -> Result<(Self, VerticalUnits), SourceError> {
        match kind {
            RasterKind::Height => Self::heights(ds, options, path, details),
            RasterKind::Color => Self::colour(ds, path, details).map(|d| (d, VerticalUnits::Metres)),
        }
    }

    fn heights(
        ds: &Dataset,
        options: &ReadOptions,
        path: &Path,
        details: &mut BTreeMap<String, String>,
    ) -> Result<(Self, VerticalUnits), SourceError> {
        let band = ds.rasterband(options.band).map_err(|e| {
            format_err(format!("raster has no band {} ({} bands): {e}", options.band, ds.raster_count()), path)
        })?;
        let unit_type = band.unit();
        let units = match options.units_override {
            Some(u) => u,
            None => VerticalUnits::from_unit_type(&unit_type).ok_or_else(|| {
                format_err(
                    format!(
                        "unknown vertical unit '{unit_type}' (set 'vertical_units' on the source to m, ft or us-ft)"
                    ),
                    path,
                )
            })?,
        };
        let nodata = band.no_data_value();
        details.insert("band_type".into(), band.band_type().name());
        details.insert("nodata".into(), nodata.map_or_else(|| "none".into(), |v| v.to_string()));
        details.insert(
            "unit_type".into(),
            if unit_type.is_empty() { "(unset: metres assumed)".into() } else { unit_type },
        );
        let decoder = Self::Height {
            band: options.band,
            nodata: nodata.map(|nd| nd as f32),
            scale: band.scale().unwrap_or(1.0) * units.to_metres(),
            offset: band.offset().unwrap_or(0.0) * units.to_metres(),
        };
        Ok((decoder, units))
    }

    fn colour(ds: &Dataset, path: &Path, details: &mut BTreeMap<String, String>) -> Result<Self, SourceError> {
        let first = ds.rasterband(1).map_err(|e| format_err(e, path))?;
        if let Some(table) = first.color_table() {
            details.insert("palette".into(), format!("{} entries", table.entry_count()));
            let entries = (0..table.entry_count())
                .map(|i| table.entry_as_rgb(i).map(|c| [c.r, c.g, c.b, c.a].map(|v| v.clamp(0, 255) as u8)))
                .collect();
            return Ok(Self::Palette { nodata: first.no_data_value().map(|nd| nd as f32), entries });
        }
        let (mut colour, mut alpha) = (Vec::new(), None);
        for b in 1..=ds.raster_count().min(4) {
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
            if band.color_interpretation() == ColorInterpretation::AlphaBand {
                alpha = Some(b);
            } else if colour.len() < 3 {
                colour.push((b, band.no_data_value().map(|nd| nd as f32)));
            }
        }
        Ok(Self::Bands { colour, alpha })
    }

    /// Planes a decoded window has: heights, or premultiplied RGBA.
    pub(crate) fn planes(&self) -> usize {
        if matches!(self, Self::Height { .. }) { 1 } else { 4 }
    }

    /// Bytes per pixel the file holds for what this decoder reads (the
    /// figure a read is counted in).
    pub(crate) fn bytes_per_pixel(&self, ds: &Dataset) -> usize {
        let size = |b: usize| ds.rasterband(b).map_or(4, |b| b.band_type().bytes() as usize);
        match self {
            Self::Height { band, .. } => size(*band),
            Self::Palette { .. } => size(1),
            Self::Bands { colour, alpha } => {
                colour.iter().map(|(b, _)| size(*b)).sum::<usize>() + alpha.map_or(0, size)
            }
        }
    }

    /// True for a height band whose values are its heights as they are
    /// (no scale or offset): only its nodata value becomes NaN.
    pub(crate) fn heights_as_stored(&self) -> bool {
        matches!(self, Self::Height { scale, offset, .. } if *scale == 1.0 && *offset == 0.0)
    }

    /// A height band's nodata value.
    pub(crate) fn nodata(&self) -> Option<f32> {
        match self {
            Self::Height { nodata, .. } => *nodata,
            _ => None,
        }
    }

    /// Heights in metres from a height band's values as the file holds
    /// them: nodata, NaN or masked out (`mask` 0) become NaN. Any other
    /// decoder hands the values back.
    pub(crate) fn to_heights(&self, mut raw: Vec<f32>, mask: Option<&[f32]>) -> Vec<f32> {
        let Self::Height { nodata, scale, offset, .. } = self else { return raw };
        if mask.is_none() && *scale == 1.0 && *offset == 0.0 {
            // The common case, in a loop the compiler can vectorise.
            let nodata = nodata.unwrap_or(f32::NAN);
            for v in &mut raw {
                if *v == nodata || v.is_nan() {
                    *v = f32::NAN;
                }
            }
            return raw;
        }
        for (i, v) in raw.iter_mut().enumerate() {
            let masked = mask.is_some_and(|m| m[i] == 0.0);
            if masked || v.is_nan() || *nodata == Some(*v) {
                *v = f32::NAN;
            } else if *scale != 1.0 || *offset != 0.0 {
                *v = (f64::from(*v) * scale + offset) as f32;
            }
        }
        raw
    }

    /// True when GDAL reads this decoder's heights from `ds` (the base
    /// level, or overview number `overview`) as 16-bit integers that are
    /// the heights as they are: an Int16 height band with no scale or
    /// offset, whose only mask is its nodata value.
    pub(crate) fn reads_i16(&self, ds: &Dataset, overview: Option<usize>) -> bool {
        let Self::Height { band, .. } = self else { return false };
        let Ok(band) = ds.rasterband(*band) else { return false };
        match overview {
            None => self.reads_i16_from(&band),
            Some(o) => band.overview(o).is_ok_and(|o| self.reads_i16_from(&o)),
        }
    }

    fn reads_i16_from(&self, band: &RasterBand<'_>) -> bool {
        self.heights_as_stored()
            && band.band_type() == GdalDataType::Int16
            && band.mask_flags().is_ok_and(|f| f.is_all_valid() || f.is_nodata())
    }

    /// `rect` of the base level or of overview `overview` as the 16-bit
    /// integers GDAL reads (what `read` widens, with no mask to apply);
    /// None for any other band.
    pub(crate) fn read_i16(
        &self,
        ds: &Dataset,
        overview: Option<usize>,
        rect: PixelRect,
        path: &Path,
    ) -> Result<Option<Vec<i16>>, SourceError> {
        let Self::Height { band: b, .. } = self else { return Ok(None) };
        let band = ds.rasterband(*b).map_err(|e| format_err(e, path))?;
        let band = match overview {
            None => band,
            Some(o) => band.overview(o).map_err(|e| format_err(format!("cannot open overview {o}: {e}"), path))?,
        };
        if !self.reads_i16_from(&band) {
            return Ok(None);
        }
        read_values::<i16>(&band, rect, path).map(Some)
    }

    /// Decodes `rect` of the base level (`overview` None) or of overview
    /// number `overview`. Any block that fails to decode fails the read.
    pub(crate) fn read(
        &self,
        ds: &Dataset,
        overview: Option<usize>,
        rect: PixelRect,
        path: &Path,
    ) -> Result<Vec<Vec<f32>>, SourceError> {
        let band = |b: usize| -> Result<RasterBand<'_>, SourceError> {
            let band = ds.rasterband(b).map_err(|e| format_err(e, path))?;
            match overview {
                None => Ok(band),
                Some(o) => band.overview(o).map_err(|e| format_err(format!("cannot open overview {o}: {e}"), path)),
            }
        };
        match self {
            Self::Height { band: b, .. } => {
                let band = band(*b)?;
                let raw = read_window(&band, rect, path)?;
                let mask = read_mask(&band, rect, path)?;
                Ok(vec![self.to_heights(raw, mask.as_deref())])
            }
            Self::Palette { nodata, entries } => {
                let band = band(1)?;
                let index = read_window(&band, rect, path)?;
                // A mask (a warp's alpha, outside the file) hides pixels too.
                let mask = read_mask(&band, rect, path)?;
                let mut planes: Vec<Vec<f32>> = (0..4).map(|_| Vec::with_capacity(index.len())).collect();
                for (i, v) in index.into_iter().enumerate() {
                    let masked = mask.as_ref().is_some_and(|m| m[i] == 0.0);
                    let entry = entries.get(v as usize).copied().flatten().filter(|_| *nodata != Some(v) && !masked);
                    let [r, g, b, a] = entry.map_or([0.0; 4], |c| c.map(|c| f32::from(c) / 255.0));
                    // A missing entry or the nodata index is transparent.
                    let a = if entry.is_some() { a } else { 0.0 };
                    for (plane, value) in planes.iter_mut().zip([r * a, g * a, b * a, a]) {
                        plane.push(value);
                    }
                }
                Ok(planes)
            }
            Self::Bands { colour, alpha } => {
                let n = rect.width() * rect.height();
                let mut valid = vec![true; n];
                let mut rgb: Vec<Vec<f32>> = Vec::with_capacity(3);
                for (k, (b, nodata)) in colour.iter().enumerate() {
                    let band = band(*b)?;
                    let values = read_window(&band, rect, path)?;
                    if let Some(nd) = nodata {
                        // A pixel is nodata when every colour band holds the nodata value.
                        valid.iter_mut().zip(&values).for_each(|(ok, v)| *ok = (k > 0 && *ok) || v != nd);
                    }
                    if let Some(mask) = read_mask(&band, rect, path)? {
                        valid.iter_mut().zip(&mask).for_each(|(ok, m)| *ok = *ok && *m != 0.0);
                    }
                    rgb.push(values);
                }
                while rgb.len() < 3 {
                    // Greyscale: repeat the one band.
                    rgb.push(rgb[0].clone());
                }
                let alpha: Vec<f32> = match alpha {
                    Some(b) => read_window(&band(*b)?, rect, path)?,
                    None => vec![255.0; n],
                };
                let alpha: Vec<f32> =
                    alpha.iter().zip(&valid).map(|(a, ok)| if *ok { *a / 255.0 } else { 0.0 }).collect();
                let mut planes: Vec<Vec<f32>> =
                    rgb.iter().map(|p| p.iter().zip(&alpha).map(|(c, a)| *c / 255.0 * a).collect()).collect();
                planes.push(alpha);
                Ok(planes)
            }
        }
    }
}

/// Reads a window of a band as f32. A band of small integers is read in
/// its own type and widened here: GDAL's word-by-word conversion cost more
/// than decoding the block (the profile of a pyramid over a 3.2 GB Int16
/// DEM: 60% of the tile threads' time in `GDALCopyWords64`).
pub(super) fn read_window(band: &RasterBand<'_>, rect: PixelRect, path: &Path) -> Result<Vec<f32>, SourceError> {
    match band.band_type() {
        GdalDataType::Int16 => read_as::<i16>(band, rect, path),
        GdalDataType::UInt16 => read_as::<u16>(band, rect, path),
        GdalDataType::UInt8 => read_as::<u8>(band, rect, path),
        _ => read_as::<f32>(band, rect, path),
    }
}

/// Reads a window of a band as `T`, widened to f32 (exactly: every `T`
/// read here is an f32 value).
fn read_as<T>(band: &RasterBand<'_>, rect: PixelRect, path: &Path) -> Result<Vec<f32>, SourceError>
where
    T: gdal::raster::GdalType + Copy + Default + Into<f32>,
{
    Ok(read_values::<T>(band, rect, path)?.into_iter().map(Into::into).collect())
}

/// Reads a window of a band as `T`.
pub(super) fn read_values<T>(band: &RasterBand<'_>, rect: PixelRect, path: &Path) -> Result<Vec<T>, SourceError>
where
    T: gdal::raster::GdalType + Copy + Default,
{
    let size = (rect.width(), rect.height());
    let mut values = vec![T::default(); size.0 * size.1];
    band.read_into_slice::<T>((rect.x0 as isize, rect.y0 as isize), size, size, &mut values, None)
        .map_err(|e| format_err(format!("cannot read raster data: {e}"), path))?;
    Ok(values)
}

/// Where the dataset's mask (per-dataset mask or alpha) says a pixel of the
/// window is invalid. None when the mask is only the nodata value or all valid.
fn read_mask(band: &RasterBand<'_>, rect: PixelRect, path: &Path) -> Result<Option<Vec<f32>>, SourceError> {
    let Ok(flags) = band.mask_flags() else {
        return Ok(None);
    };
    if flags.is_all_valid() || flags.is_nodata() {
        return Ok(None);
    }
    let mask = band.open_mask_band().map_err(|e| format_err(format!("cannot open mask band: {e}"), path))?;
    read_window(&mask, rect, path).map(Some)
}
