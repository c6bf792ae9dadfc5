//! Reference values from GDAL itself (`gdalwarp`) and PROJ, independent of
//! relief's resampling code.

use std::path::Path;
use std::process::Command;

use anyhow::{Context, bail};
use gdal::Dataset;
use relief_proto::v1::GeodeticPoint;

/// `gdalwarp` of `raster` onto `n` x `n` pixels covering `te` in `crs`,
/// exact reprojection (-et 0), Float64 with NaN for nodata; the pixels,
/// row-major from the north-west.
fn warp(raster: &Path, te: [f64; 4], n: usize, crs: &str, kernel: &str, out: &Path) -> anyhow::Result<Vec<f64>> {
    let size = n.to_string();
    let result = Command::new("gdalwarp")
        .args(["-q", "-overwrite", "-r", kernel, "-et", "0", "-t_srs", crs, "-ot", "Float64", "-dstnodata", "nan"])
        .args(["-ts", &size, &size, "-te"])
        .args(te.map(|v| format!("{v:.12}")))
        .arg(raster)
        .arg(out)
        .output()
        .context("cannot run gdalwarp (Debian package gdal-bin)")?;
    if !result.status.success() {
        bail!("gdalwarp failed: {}", String::from_utf8_lossy(&result.stderr));
    }
    let ds = Dataset::open(out)?;
    Ok(ds.rasterband(1)?.read_as::<f64>((0, 0), (n, n), (n, n), None)?.into_shape_and_vec().1)
}

/// GDAL's value of `raster` at (lon, lat) with `kernel`: a one-pixel warp
/// whose pixel centre is the point. None where GDAL finds no data.
pub fn gdal_value_at(raster: &Path, lon: f64, lat: f64, kernel: &str, scratch: &Path) -> anyhow::Result<Option<f64>> {
    const HALF: f64 = 1e-7;
    let out = scratch.join(format!("ref-{lon:.9}-{lat:.9}.tif"));
    let v = warp(raster, [lon - HALF, lat - HALF, lon + HALF, lat + HALF], 1, "EPSG:4326", kernel, &out)?[0];
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
    let (sx, sy) = ((extent[2] - extent[0]) / (n - 1) as f64, (extent[3] - extent[1]) / (n - 1) as f64);
    let te = [extent[0] - sx / 2.0, extent[1] - sy / 2.0, extent[2] + sx / 2.0, extent[3] + sy / 2.0];
    warp(raster, te, n, crs, kernel, &scratch.join("lattice.tif"))
}

/// Points in `crs` taken to WGS84 longitude/latitude by PROJ (through
/// GDAL's OSR), as request points.
pub fn lon_lat_points(crs: &str, xs: &[f64], ys: &[f64]) -> anyhow::Result<Vec<GeodeticPoint>> {
    use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
    let srs = |def: &str| -> anyhow::Result<SpatialRef> {
        let mut s = SpatialRef::from_definition(def)?;
        s.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        Ok(s)
    };
    let (mut xs, mut ys) = (xs.to_vec(), ys.to_vec());
    CoordTransform::new(&srs(crs)?, &srs("EPSG:4326")?)?.transform_coords(&mut xs, &mut ys, &mut [])?;
    Ok(xs.into_iter().zip(ys).map(|(lon_deg, lat_deg)| GeodeticPoint { lon_deg, lat_deg }).collect())
}
