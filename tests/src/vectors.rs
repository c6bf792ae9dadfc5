//! Vector fixtures: GeoJSON text written as real files by GDAL's own tools.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Writes `geojson` as the shapefile `dir/name.shp` through ogr2ogr (UTF-8
/// attributes, a .cpg saying so), as a GIS user's export would.
pub fn shapefile(dir: &Path, name: &str, geojson: &str) -> anyhow::Result<PathBuf> {
    let shp = dir.join(format!("{name}.shp"));
    ogr2ogr(&shp, geojson, &["-f", "ESRI Shapefile", "-lco", "ENCODING=UTF-8"])?;
    Ok(shp)
}

/// Writes each `(layer, geojson)` as a layer of the GeoPackage `path`
/// through ogr2ogr (EPSG:4326, a spatial index, FIDs from 1), as a QGIS
/// user's "Save as GeoPackage" would.
pub fn geopackage(path: &Path, layers: &[(&str, &str)]) -> anyhow::Result<PathBuf> {
    for (n, (layer, geojson)) in layers.iter().enumerate() {
        let update: &[&str] = if n == 0 { &[] } else { &["-update"] };
        ogr2ogr(path, geojson, &[&["-f", "GPKG", "-nln", layer], update].concat())?;
    }
    Ok(path.to_path_buf())
}

/// ogr2ogr `args` from `geojson` (in a hidden file beside `out`, part of
/// no dataset) into `out`.
fn ogr2ogr(out: &Path, geojson: &str, args: &[&str]) -> anyhow::Result<()> {
    let name = out.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    let src = out.with_file_name(format!(".{name}.source.geojson"));
    std::fs::write(&src, geojson)?;
    let result = Command::new("ogr2ogr").arg("-q").args(args).arg(out).arg(&src).output()?;
    std::fs::remove_file(&src)?;
    anyhow::ensure!(result.status.success(), "ogr2ogr failed: {}", String::from_utf8_lossy(&result.stderr));
    Ok(())
}

/// A GeoJSON FeatureCollection of square footprints `(properties, west,
/// south, side in degrees)`.
pub fn squares(squares: &[(&str, f64, f64, f64)]) -> String {
    let features: Vec<String> = squares
        .iter()
        .map(|(props, w, s, d)| {
            let (e, n) = (w + d, s + d);
            format!(
                r#"{{"type": "Feature", "properties": {props}, "geometry": {{"type": "Polygon", "coordinates": [[[{w}, {s}], [{e}, {s}], [{e}, {n}], [{w}, {n}], [{w}, {s}]]]}}}}"#
            )
        })
        .collect();
    format!(r#"{{"type": "FeatureCollection", "features": [{}]}}"#, features.join(",\n"))
}
