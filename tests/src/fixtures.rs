//! Fixtures the tests make themselves: rasters of analytic terrains with
//! known heights, written through GDAL, and manifests around them.

use std::path::{Path, PathBuf};

use anyhow::Context;
use gdal::DriverManager;
use gdal::raster::Buffer;
use gdal::spatial_ref::SpatialRef;

/// A north-up raster: origin is the north-west pixel edge.
pub struct RasterSpec<'a> {
    pub width: usize,
    pub height: usize,
    pub origin_x: f64,
    pub origin_y: f64,
    pub pixel: f64,
    pub crs: &'a str,
    pub nodata: Option<f64>,
}

impl RasterSpec<'_> {
    /// World coordinates of the centre of pixel (i, j).
    pub fn centre(&self, i: usize, j: usize) -> (f64, f64) {
        (self.origin_x + (i as f64 + 0.5) * self.pixel, self.origin_y - (j as f64 + 0.5) * self.pixel)
    }
}

/// Writes a Float32 GeoTIFF whose pixel (i, j) holds `height(x, y)` at the
/// pixel's centre.
pub fn write_dem(path: &Path, spec: &RasterSpec<'_>, height: impl Fn(f64, f64) -> f64) -> anyhow::Result<PathBuf> {
    let mut data = Vec::with_capacity(spec.width * spec.height);
    for j in 0..spec.height {
        for i in 0..spec.width {
            let (x, y) = spec.centre(i, j);
            data.push(height(x, y) as f32);
        }
    }
    let driver = DriverManager::get_driver_by_name("GTiff")?;
    let mut ds = driver
        .create_with_band_type::<f32, _>(path, spec.width, spec.height, 1)
        .with_context(|| format!("cannot create {}", path.display()))?;
    ds.set_geo_transform(&[spec.origin_x, spec.pixel, 0.0, spec.origin_y, 0.0, -spec.pixel])?;
    ds.set_spatial_ref(&SpatialRef::from_definition(spec.crs)?)?;
    let mut band = ds.rasterband(1)?;
    band.set_no_data_value(spec.nodata)?;
    band.write((0, 0), (spec.width, spec.height), &mut Buffer::new((spec.width, spec.height), data))?;
    Ok(path.to_path_buf())
}

/// A Gaussian hill: 500 m plain, 1500 m peak at (10.25 E, 45.25 N), sigma
/// 0.08 degrees.
pub fn hill(lon: f64, lat: f64) -> f64 {
    let (dx, dy) = (lon - 10.25, lat - 45.25);
    500.0 + 1500.0 * (-(dx * dx + dy * dy) / (2.0 * 0.08 * 0.08)).exp()
}

/// The hill on a 0.00125-degree grid over 10..10.5 E, 45..45.5 N (EPSG:4326).
pub fn hill_spec() -> RasterSpec<'static> {
    RasterSpec { width: 400, height: 400, origin_x: 10.0, origin_y: 45.5, pixel: 0.00125, crs: "EPSG:4326", nodata: None }
}

/// A smooth analytic surface in UTM 12N metres, around Storm Lake, Montana.
pub fn utm_surface(x: f64, y: f64) -> f64 {
    2500.0 + 0.05 * (x - 300_000.0) - 0.02 * (y - 5_100_000.0) + 80.0 * ((x / 700.0).sin() * (y / 900.0).cos())
}

/// 300 x 200 pixels of 30 m in EPSG:32612.
pub fn utm_spec() -> RasterSpec<'static> {
    RasterSpec { width: 300, height: 200, origin_x: 300_000.0, origin_y: 5_106_000.0, pixel: 30.0, crs: "EPSG:32612", nodata: None }
}

/// Writes a manifest beside the data and returns its path.
pub fn write_manifest(dir: &Path, text: &str) -> anyhow::Result<PathBuf> {
    let path = dir.join("scene.toml");
    std::fs::write(&path, text)?;
    Ok(path)
}

/// A tiny deterministic generator for test points (no dependency needed).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}
