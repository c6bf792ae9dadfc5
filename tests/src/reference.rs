//! Reference values from GDAL itself (`gdalwarp`), independent of relief's
//! resampling code.

use std::path::Path;
use std::process::Command;

use anyhow::{Context, bail};
use gdal::Dataset;

/// GDAL's value of `raster` at (lon, lat) with `kernel`: a one-pixel warp
/// whose pixel centre is the point, with exact reprojection (-et 0).
/// None where GDAL finds no data.
pub fn gdal_value_at(
    raster: &Path,
    lon: f64,
    lat: f64,
    kernel: &str,
    scratch: &Path,
) -> anyhow::Result<Option<f64>> {
    const HALF: f64 = 1e-7;
    let out = scratch.join(format!("ref-{lon:.9}-{lat:.9}.tif"));
    let warp = Command::new("gdalwarp")
        .args([
            "-q",
            "-overwrite",
            "-r",
            kernel,
            "-et",
            "0",
            "-t_srs",
            "EPSG:4326",
            "-ot",
            "Float64",
            "-dstnodata",
            "nan",
        ])
        .args(["-ts", "1", "1", "-te"])
        .args([lon - HALF, lat - HALF, lon + HALF, lat + HALF].map(|v| format!("{v:.12}")))
        .arg(raster)
        .arg(&out)
        .output()
        .context("cannot run gdalwarp (Debian package gdal-bin)")?;
    if !warp.status.success() {
        bail!("gdalwarp failed: {}", String::from_utf8_lossy(&warp.stderr));
    }
    let ds = Dataset::open(&out)?;
    let v = ds
        .rasterband(1)?
        .read_as::<f64>((0, 0), (1, 1), (1, 1), None)?
        .data()[0];
    std::fs::remove_file(&out)?;
    Ok((!v.is_nan()).then_some(v))
}

/// GDAL's warp of `raster` onto a lattice of `n` x `n` point samples whose
/// outer samples lie on `extent` ([min x, min y, max x, max y] in `crs`).
/// Row-major from the north-west; NaN for nodata.
pub fn gdal_lattice(
    raster: &Path,
    extent: [f64; 4],
    n: usize,
    crs: &str,
    kernel: &str,
    scratch: &Path,
) -> anyhow::Result<Vec<f64>> {
    let (sx, sy) = (
        (extent[2] - extent[0]) / (n - 1) as f64,
        (extent[3] - extent[1]) / (n - 1) as f64,
    );
    let out = scratch.join("lattice.tif");
    let te = [
        extent[0] - sx / 2.0,
        extent[1] - sy / 2.0,
        extent[2] + sx / 2.0,
        extent[3] + sy / 2.0,
    ];
    let warp = Command::new("gdalwarp")
        .args([
            "-q",
            "-overwrite",
            "-r",
            kernel,
            "-et",
            "0",
            "-t_srs",
            crs,
            "-ot",
            "Float64",
            "-dstnodata",
            "nan",
        ])
        .args(["-ts", &n.to_string(), &n.to_string(), "-te"])
        .args(te.map(|v| format!("{v:.12}")))
        .arg(raster)
        .arg(&out)
        .output()
        .context("cannot run gdalwarp (Debian package gdal-bin)")?;
    if !warp.status.success() {
        bail!("gdalwarp failed: {}", String::from_utf8_lossy(&warp.stderr));
    }
    let ds = Dataset::open(&out)?;
    Ok(ds
        .rasterband(1)?
        .read_as::<f64>((0, 0), (n, n), (n, n), None)?
        .into_shape_and_vec()
        .1)
}
