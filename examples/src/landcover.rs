//! Land cover for the instances layer: classified rasters (one Byte band
//! of class codes, 0 for nodata) that `scatter` turns into trees.

use std::path::{Path, PathBuf};

use crate::{RasterSpec, demo_terrain, in_demo_void, write_geotiff};

/// The class codes the examples use (CORINE-like, as small integers).
pub const NODATA: u8 = 0;
pub const CONIFER_FOREST: u8 = 1;
pub const BROADLEAF_FOREST: u8 = 2;
pub const SHRUBLAND: u8 = 3;
/// Grassland and rock: no rule places anything there.
pub const GRASSLAND: u8 = 4;

/// Writes a Byte GeoTIFF of class codes, `class(x, y)` at each pixel's
/// centre, 0 declared as nodata.
pub fn write_classes(path: &Path, spec: &RasterSpec<'_>, class: impl Fn(f64, f64) -> u8) -> anyhow::Result<PathBuf> {
    let data = spec.pixels().map(|(x, y)| class(x, y)).collect();
    let spec = RasterSpec { nodata: Some(f64::from(NODATA)), ..*spec };
    write_geotiff(path, &spec, vec![data])
}

/// The demo's land cover, from the demo terrain's height with a ragged
/// tree line: broadleaf woods in the valleys, conifers on the slopes,
/// shrubs above them, grass and rock on top and in the town; nodata over
/// the DEM's void.
pub fn demo_landcover(lon: f64, lat: f64) -> u8 {
    if in_demo_void(lon, lat) {
        return NODATA;
    }
    // The town's square (its 2,000 lots on a 60 m lattice) and a margin: grass.
    let (cx, cy) = crate::DEMO_TOWN_CENTRE;
    let half_m = 1500.0;
    if ((lat - cy) * 111_320.0).abs() < half_m && ((lon - cx) * 111_320.0 * cy.to_radians().cos()).abs() < half_m {
        return GRASSLAND;
    }
    let h = demo_terrain(lon, lat);
    // Borders that wander by about 150 m of height, so classes mix.
    let ragged = 150.0 * ((lon * 140.0).sin() * (lat * 170.0).cos() + 0.5 * (lon * 410.0 + lat * 290.0).sin());
    match h + ragged {
        h if h < 900.0 => BROADLEAF_FOREST,
        h if h < 1700.0 => CONIFER_FOREST,
        h if h < 2100.0 => SHRUBLAND,
        _ => GRASSLAND,
    }
}
