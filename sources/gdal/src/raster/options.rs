//! How the manifest asks a raster to be read, what it is read as, and
//! the little records of a file the rest compares.

use super::changes::ChangeDetection;
use crate::resample::LevelAxis;

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
    pub(super) fn from_unit_type(unit: &str) -> Option<Self> {
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
    /// Whole when the base level, as the block cache keeps it (2 bytes a
    /// pixel for heights kept 16-bit, else 4 a plane), is at most a quarter
    /// of the block budget, else windowed.
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

/// One level of the mip pyramid: `width` x `height` pixels, `scale` times
/// coarser than the base level in name (a power of two); read from the
/// file's overview number `overview` when it has one of this size, else
/// halved from the level below.
///
/// Where a pixel stands: a full pixel is `pixel` base pixels wide and
/// high. A file's overview spreads its pixels evenly over the raster
/// (GDAL's convention, `pixel` = base size / level size), so every pixel
/// is full. A halved level's pixels are twice those of the level below, so
/// where the base size is not a multiple its last column and row hang
/// over the raster's edge: only `cover` of them (a fraction) lies on it,
/// and they stand at the middle of that part.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LevelInfo {
    pub width: usize,
    pub height: usize,
    pub scale: f64,
    pub overview: Option<usize>,
    /// Base pixels per full pixel of this level, across and down.
    pub pixel: (f64, f64),
    /// The part of the last column and of the last row on the raster.
    pub cover: (f64, f64),
    /// What a block of this level takes in the block cache a pixel: 2
    /// for heights kept 16-bit as stored, else 4 a plane (the header sets
    /// it, as `Store::read_pixels` keeps the level). Read-ahead and
    /// reading whole are sized by it.
    pub cache_pixel_bytes: usize,
}

impl LevelInfo {
    /// A level of `width` x `height` pixels of `pixel` base pixels over a
    /// raster of `base` pixels.
    pub(crate) fn new(
        (width, height): (usize, usize),
        scale: f64,
        overview: Option<usize>,
        pixel: (f64, f64),
        base: (usize, usize),
    ) -> Self {
        let cover = |base: usize, pixel: f64, size: usize| (base as f64 / pixel - (size - 1) as f64).clamp(1e-9, 1.0);
        Self {
            width,
            height,
            scale,
            overview,
            pixel,
            cover: (cover(base.0, pixel.0, width), cover(base.1, pixel.1, height)),
            cache_pixel_bytes: 4,
        }
    }

    /// True when this level's blocks are kept as the 16-bit heights the
    /// file stores (`Store::read_pixels` reads them so).
    pub(crate) fn kept_i16(&self) -> bool {
        self.cache_pixel_bytes == 2
    }

    /// How much of column `x` lies on the raster (1 but for a partial last one).
    pub(crate) fn column_cover(&self, x: usize) -> f64 {
        if x + 1 == self.width { self.cover.0 } else { 1.0 }
    }

    /// How much of row `y` lies on the raster.
    pub(crate) fn row_cover(&self, y: usize) -> f64 {
        if y + 1 == self.height { self.cover.1 } else { 1.0 }
    }

    /// This level's columns and rows over a raster of `base` pixels, as
    /// the kernels see them.
    pub(crate) fn axes(&self, base: (usize, usize), wraps_x: bool) -> (LevelAxis, LevelAxis) {
        (
            LevelAxis { size: self.width, pixel: self.pixel.0, base: base.0, wrap: wraps_x },
            LevelAxis { size: self.height, pixel: self.pixel.1, base: base.1, wrap: false },
        )
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_types_map_to_metres() {
        assert_eq!(VerticalUnits::from_unit_type("metre"), Some(VerticalUnits::Metres));
        assert_eq!(VerticalUnits::from_unit_type(""), Some(VerticalUnits::Metres));
        assert_eq!(VerticalUnits::from_unit_type("ft"), Some(VerticalUnits::Feet));
        assert_eq!(VerticalUnits::from_unit_type("fathoms"), None);
    }

    /// An overview of an odd base spreads its pixels evenly (100,001 base
    /// pixels over 50,001: each 1.99998 wide), so a base edit at [448, 512)
    /// touches overview pixels 224 to 256, not 224 to 255 as halving by 2
    /// would say; a halved level's partial last pixel covers what is left.
    #[test]
    fn levels_place_their_pixels_over_the_base() {
        let overview = LevelInfo::new((50_001, 3), 2.0, Some(0), (100_001.0 / 50_001.0, 1.0), (100_001, 3));
        assert_eq!(overview.cover, (1.0, 1.0));
        let rect = super::super::PixelRect { x0: 448, y0: 0, x1: 512, y1: 1 }.on_level(&overview);
        assert_eq!((rect.x0, rect.x1), (224, 257));
        let halved = LevelInfo::new((13, 13), 8.0, None, (8.0, 8.0), (100, 100));
        assert_eq!((halved.cover, halved.column_cover(12), halved.column_cover(11)), ((0.5, 0.5), 0.5, 1.0));
    }
}
