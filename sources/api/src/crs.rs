//! Coordinate transforms, as a service the daemon hands to sources that
//! read files in their own CRS. The daemon gives the one it has (GDAL's
//! OSR over Debian's PROJ), so one PROJ serves every source and no source
//! crate links a second one.

use crate::error::SourceError;

pub trait CrsTransform: Send + Sync + std::fmt::Debug {
    /// Transforms points in place from `from` to `to` (any definition PROJ
    /// accepts: "EPSG:4326", WKT, a PROJ string), longitude or easting
    /// first. Points that cannot be transformed become NaN.
    fn transform(&self, from: &str, to: &str, xs: &mut [f64], ys: &mut [f64]) -> Result<(), SourceError>;
}
