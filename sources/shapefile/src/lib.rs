//! relief-source-shapefile: a shapefile (.shp, .shx, .dbf, .prj, .cpg) read
//! as one dataset into feature tiles, from a folder or from inside a zip.
//!
//! Before a shapefile is taken in, its files are checked against each other
//! (the torn states EDITORS.md records: an index that does not match its
//! shapes, a table whose record count disagrees), so a half-saved dataset
//! is an error, never a partial one. What no writer leaves mid-save but
//! GDAL reads (a stray byte after the last record, a .shx header length off
//! by less than an entry) is read, with a warning in the source's state;
//! whole records past the .shp header's length are a record being
//! appended, read again later. Only the .shp is required, as other
//! readers have it: a missing .shx is rebuilt by walking the .shp's records
//! (GDAL's SHAPE_RESTORE_SHX) and a missing .dbf gives features without
//! attributes, each with a warning in the source's state; but a sidecar
//! missing while QGIS repacks the dataset is a writer at work, read again
//! later. A zip is inflated within limits (a zip bomb is refused). Null
//! shapes are skipped and counted; MultiPatch shapes are read as OGR reads them
//! (`multipatch`), and the source draws them as buildings. The CRS comes
//! from the .prj through the `CrsTransform` the daemon provides; there is
//! no GDAL here, and none may be added.

mod check;
mod dataset;
mod message;
mod multipatch;
mod read;
mod shx;
mod source;
mod zipped;

pub use source::{KIND, Shapefile, ShapefileSource};
