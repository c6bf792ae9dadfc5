//! Vector fixtures: GeoJSON text written as real files by GDAL's own tools.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Writes `geojson` as the shapefile `dir/name.shp` through ogr2ogr (UTF-8
/// attributes, a .cpg saying so), as a GIS user's export would.
pub fn shapefile(dir: &Path, name: &str, geojson: &str) -> anyhow::Result<PathBuf> {
    let src = dir.join(format!("{name}.geojson"));
    std::fs::write(&src, geojson)?;
    let shp = dir.join(format!("{name}.shp"));
    let out = Command::new("ogr2ogr")
        .args(["-q", "-f", "ESRI Shapefile", "-lco", "ENCODING=UTF-8"])
        .arg(&shp)
        .arg(&src)
        .output()?;
    anyhow::ensure!(out.status.success(), "ogr2ogr failed: {}", String::from_utf8_lossy(&out.stderr));
    std::fs::remove_file(&src)?;
    Ok(shp)
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
