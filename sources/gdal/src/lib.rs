//! relief-source-gdal: rasters through GDAL (DEMs and imagery).
//!
//! A `gdal` source reads one raster, or a mosaic of several (listed, or a
//! VRT), as blocks of a nodata-aware mip pyramid: whole when it opens if it
//! is small, else only the blocks tiles need, through one cache under a
//! byte budget; coarse levels come from the file's overviews where it has
//! them and they agree with the base (a lossy file's within what its
//! compression may change; beyond it they are left out and the levels
//! halved from the base, with a warning in the state). It resamples them into the scene's tile grid with the named kernel.
//! A raster georeferenced only by GCPs is read through GDAL's warp of it,
//! north-up; a rotated geotransform is sampled through as it is.
//! A reload reads only the blocks whose signatures changed. GDAL and PROJ
//! (through GDAL's OSR, so one PROJ serves GDAL and relief) stay inside this
//! crate.
//!
//! # Nodata fill policy
//!
//! A source pixel is nodata when it equals the band's nodata value, is NaN,
//! or is masked by the dataset's mask band. Nodata is never interpolated
//! into heights:
//! 1. kernel taps that fall on nodata are dropped and the remaining weights
//!    are renormalised, but only while the valid taps carry at least half of
//!    the kernel's weight; otherwise the sample is nodata (NaN in a tile,
//!    `null` from `relief elevation`);
//! 2. taps past the raster's edge take the edge pixel (the raster reaches its
//!    outer pixel edge, no farther); a point beyond that edge is nodata;
//! 3. coarser mip levels average the valid pixels of each 2 x 2 block, and
//!    are nodata only where all four are (a file's own overviews are used
//!    as they are, once checked against the base);
//! 4. holes are never filled from neighbours or other rasters, except that in
//!    a mosaic the first listed raster with data at a point wins.

mod crs;
pub mod guard;
pub mod objects;
mod raster;
mod resample;
mod source;

pub use crs::describe as describe_srs;
pub use raster::{
    ChangeDetection, DEFAULT_BLOCK_BUDGET, RasterKind, Residency, VerticalUnits, block_budget, cached_bytes,
    set_block_budget,
};
pub use source::{GdalSource, KIND, configure_gdal};

/// Sets one of GDAL's process-wide configuration options (an option this
/// GDAL does not know is harmless, and set anyway).
pub(crate) fn set_option(key: &str, value: &str) {
    let _unknown_option_is_harmless = gdal::config::set_config_option(key, value);
}

/// GDAL's message for a failed call on `path`, without GDAL's own copy of
/// the path (an error puts it last, once); `unrecognised` when GDAL gave
/// no words (no driver took the file).
pub fn gdal_message(e: gdal::errors::GdalError, path: &std::path::Path, unrecognised: &str) -> String {
    let message = match e {
        gdal::errors::GdalError::NullPointer { msg, .. } if !msg.trim().is_empty() => msg,
        gdal::errors::GdalError::NullPointer { .. } => unrecognised.to_owned(),
        other => other.to_string(),
    };
    let message = message
        .replace(&format!("`{}' ", path.display()), "")
        .replace(&path.display().to_string(), "the file")
        .trim()
        .to_owned();
    objects::redact(&message)
}

/// Checks that GDAL and PROJ know a CRS; returns its short description.
pub fn describe_crs(definition: &str) -> Result<String, relief_source::SourceError> {
    crs::spatial_ref(definition, None).map(|srs| crs::describe(&srs))
}

/// Coordinate transforms through GDAL's OSR, for sources that do not link
/// GDAL themselves.
#[derive(Debug, Clone, Copy, Default)]
pub struct OsrTransform;

impl relief_source::CrsTransform for OsrTransform {
    fn transform(
        &self,
        from: &str,
        to: &str,
        xs: &mut [f64],
        ys: &mut [f64],
    ) -> Result<(), relief_source::SourceError> {
        crs::transform(from, to, xs, ys)
    }
}
