//! Coordinate reference systems through GDAL's OSR (PROJ underneath).
//!
//! `CoordTransform` is neither Send nor Sync, so each thread keeps its own
//! transforms in a small cache keyed by the pair of CRS definitions.

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::Path;

use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
use relief_source::SourceError;

/// A CRS definition GDAL accepts ("EPSG:4326", WKT, PROJ string...).
pub(crate) fn spatial_ref(definition: &str, path: Option<&Path>) -> Result<SpatialRef, SourceError> {
    let mut srs = SpatialRef::from_definition(definition).map_err(|e| SourceError::Crs {
        crs: definition.chars().take(80).collect(),
        message: e.to_string(),
        path: path.map(Path::to_path_buf),
    })?;
    // x = longitude/easting, y = latitude/northing, whatever the authority says.
    srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    Ok(srs)
}

/// A short human name for a CRS: "EPSG:26912 (NAD83 / UTM zone 12N)".
pub fn describe(srs: &SpatialRef) -> String {
    let name = srs.name().unwrap_or_else(|| "unnamed CRS".into());
    match (srs.auth_name(), srs.auth_code()) {
        (Some(auth), Ok(code)) => format!("{auth}:{code} ({name})"),
        _ => name,
    }
}

thread_local! {
    static TRANSFORMS: RefCell<HashMap<(String, String), CoordTransform>> = RefCell::new(HashMap::new());
}

/// Transforms points in place from `from` to `to` (both WKT or definitions
/// that `spatial_ref` accepts). Points PROJ cannot transform become NaN.
pub(crate) fn transform(from: &str, to: &str, xs: &mut [f64], ys: &mut [f64]) -> Result<(), SourceError> {
    TRANSFORMS.with(|cell| {
        let mut cache = cell.borrow_mut();
        let key = (from.to_owned(), to.to_owned());
        if !cache.contains_key(&key) {
            if cache.len() > 64 {
                cache.clear();
            }
            let t = CoordTransform::new(&spatial_ref(from, None)?, &spatial_ref(to, None)?).map_err(|e| {
                SourceError::Crs {
                    crs: to.chars().take(80).collect(),
                    message: format!("no transformation from the source CRS: {e}"),
                    path: None,
                }
            })?;
            cache.insert(key.clone(), t);
        }
        let t = &cache[&key];
        // On partial failure OCTTransform still fills the points it could and
        // marks the others with HUGE_VAL; we keep the good ones.
        let _partial_failure = t.transform_coords(xs, ys, &mut []);
        for (x, y) in xs.iter_mut().zip(ys.iter_mut()) {
            if !(x.is_finite() && y.is_finite() && x.abs() < 1e30 && y.abs() < 1e30) {
                *x = f64::NAN;
                *y = f64::NAN;
            }
        }
        Ok(())
    })
}

/// The extent of `bounds` (min x, min y, max x, max y in `from`) in `to`.
pub(crate) fn transform_bounds(from: &str, to: &str, bounds: [f64; 4]) -> Option<[f64; 4]> {
    const EDGE_POINTS: usize = 21;
    let mut xs = Vec::with_capacity(EDGE_POINTS * EDGE_POINTS);
    let mut ys = Vec::with_capacity(EDGE_POINTS * EDGE_POINTS);
    for j in 0..EDGE_POINTS {
        for i in 0..EDGE_POINTS {
            let fx = i as f64 / (EDGE_POINTS - 1) as f64;
            let fy = j as f64 / (EDGE_POINTS - 1) as f64;
            xs.push(bounds[0] + fx * (bounds[2] - bounds[0]));
            ys.push(bounds[1] + fy * (bounds[3] - bounds[1]));
        }
    }
    transform(from, to, &mut xs, &mut ys).ok()?;
    let mut out = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
    for (x, y) in xs.iter().zip(&ys) {
        if x.is_finite() {
            out = [out[0].min(*x), out[1].min(*y), out[2].max(*x), out[3].max(*y)];
        }
    }
    out[0].is_finite().then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utm_round_trip_matches_proj() {
        // `echo "46.0 -113.6" | cs2cs EPSG:4326 EPSG:26912` = 298678.3092 5097334.4387
        let mut xs = [-113.6];
        let mut ys = [46.0];
        transform("EPSG:4326", "EPSG:26912", &mut xs, &mut ys).unwrap();
        assert!((xs[0] - 298_678.309_2).abs() < 1e-3 && (ys[0] - 5_097_334.438_7).abs() < 1e-3, "{xs:?} {ys:?}");
        transform("EPSG:26912", "EPSG:4326", &mut xs, &mut ys).unwrap();
        assert!((xs[0] + 113.6).abs() < 1e-9 && (ys[0] - 46.0).abs() < 1e-9);
    }

    #[test]
    fn unknown_crs_is_a_clear_error() {
        let err = spatial_ref("EPSG:999999", Some(Path::new("/data/x.tif"))).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("EPSG:999999") && msg.contains("/data/x.tif"), "{msg}");
    }
}
