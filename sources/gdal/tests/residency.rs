//! `read = "auto"` sizes a raster as the block cache keeps it: 16-bit
//! heights at 2 bytes a pixel, f32 at 4. Its own binary: the block budget
//! it sets is the process's.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::Path;

use gdal::DriverManager;
use gdal::raster::{Buffer, GdalType, RasterCreationOptions};
use relief_source::{Source, SourceSpec, TileGrid};
use relief_source_gdal::GdalSource;

const SIDE: usize = 1000;

/// A tiled, deflated DEM of SIDE x SIDE samples of type T.
fn write<T: GdalType + Copy>(path: &Path, value: impl Fn(usize, usize) -> T) {
    let driver = DriverManager::get_driver_by_name("GTiff").unwrap();
    let options = RasterCreationOptions::from_iter(["TILED=YES", "COMPRESS=DEFLATE"]);
    let mut ds = driver.create_with_band_type_with_options::<T, _>(path, SIDE, SIDE, 1, &options).unwrap();
    ds.set_geo_transform(&[7.0, 1e-4, 0.0, 47.0, 0.0, -1e-4]).unwrap();
    ds.set_spatial_ref(&gdal::spatial_ref::SpatialRef::from_epsg(4326).unwrap()).unwrap();
    let data: Vec<T> = (0..SIDE * SIDE).map(|k| value(k % SIDE, k / SIDE)).collect();
    ds.rasterband(1).unwrap().write((0, 0), (SIDE, SIDE), &mut Buffer::new((SIDE, SIDE), data)).unwrap();
}

fn details(path: &Path) -> std::collections::BTreeMap<String, String> {
    let spec = SourceSpec { id: "dem".into(), kind: "gdal".into(), paths: vec![path.into()], ..SourceSpec::default() };
    let source = GdalSource::open(&spec, &TileGrid::geodetic(256).unwrap()).unwrap();
    source.info().details.into_iter().collect()
}

#[test]
fn auto_reads_whole_what_fits_a_quarter_of_the_budget_as_the_cache_keeps_it() {
    // A quarter of 8 MiB is 2 MiB: a million 16-bit heights (2 MB) fit,
    // the same as f32 (4 MB) do not.
    relief_source_gdal::set_block_budget(8 << 20);
    let dir = tempfile::tempdir().unwrap();
    let (int16, float32) = (dir.path().join("int16.tif"), dir.path().join("float32.tif"));
    write::<i16>(&int16, |i, j| (i + j) as i16);
    write::<f32>(&float32, |i, j| (i + j) as f32);
    let (int16, float32) = (details(&int16), details(&float32));
    assert!(int16["block_cache"].starts_with("16-bit"), "{int16:?}");
    assert!(int16["read"].starts_with("whole"), "{int16:?}");
    assert!(float32["block_cache"].starts_with("decoded f32"), "{float32:?}");
    assert!(float32["read"].starts_with("windowed"), "{float32:?}");
}

/// A VRT placing two Int16 halves of a DEM side by side.
fn mosaic(dir: &Path, member_overviews: bool) -> std::path::PathBuf {
    let halves = ["west", "east"].map(|name| dir.join(format!("{name}.tif")));
    for (k, half) in halves.iter().enumerate() {
        write::<i16>(half, |i, j| (i + j + k) as i16);
        let mut ds = gdal::Dataset::open(half).unwrap();
        ds.set_geo_transform(&[7.0 + k as f64 * 0.1, 1e-4, 0.0, 47.0, 0.0, -1e-4]).unwrap();
        if member_overviews {
            ds.build_overviews("AVERAGE", &[2, 4], &[]).unwrap();
        }
    }
    let vrt = dir.join("mosaic.vrt");
    let status = std::process::Command::new("gdalbuildvrt").arg("-q").arg(&vrt).args(&halves).status().unwrap();
    assert!(status.success(), "gdalbuildvrt (gdal-bin)");
    vrt
}

#[test]
fn a_mosaics_overviews_are_sized_as_the_cache_keeps_them() {
    // The members' own overviews are read 16-bit through them; the VRT's
    // own (a .vrt.ovr) are read through GDAL, decoded f32: read-ahead
    // counts their blocks at 4 bytes a pixel.
    let dir = tempfile::tempdir().unwrap();
    let through_members = details(&mosaic(dir.path(), true));
    assert!(through_members["block_cache"].starts_with("16-bit"), "{through_members:?}");
    assert!(!through_members["block_cache"].contains("overviews decoded f32"), "{through_members:?}");
    let dir = tempfile::tempdir().unwrap();
    let vrt = mosaic(dir.path(), false);
    gdal::Dataset::open(&vrt).unwrap().build_overviews("AVERAGE", &[2, 4], &[]).unwrap();
    let own = details(&vrt);
    assert!(own["block_cache"].starts_with("16-bit"), "{own:?}");
    assert!(own["block_cache"].contains("2 of its 2 overviews decoded f32"), "{own:?}");
}
