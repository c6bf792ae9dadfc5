//! relief-source-shapefile: a shapefile (.shp, .shx, .dbf, .prj, .cpg) read
//! as one dataset into feature tiles.
//!
//! Before a shapefile is taken in, its files are checked against each other
//! (the torn states EDITORS.md records: an index that does not match its
//! shapes, a table whose record count disagrees), so a half-saved dataset
//! is an error, never a partial one. Null shapes are skipped and counted;
//! MultiPatch is rejected. The CRS comes from the .prj through the
//! `CrsTransform` the daemon provides; there is no GDAL here.

mod check;
mod read;
mod source;

pub use source::{KIND, Shapefile, ShapefileSource};
