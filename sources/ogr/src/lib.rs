//! relief-source-ogr: one layer of any vector dataset GDAL's OGR opens
//! (GeoPackage, GeoJSON, FlatGeobuf, GML, shapefile, KML...) read into
//! feature tiles.
//!
//! The dataset is opened read-only and its layer read in one pass: points,
//! lines and polygons (with their holes) and collections of one of those
//! families become features; every attribute becomes text. Ids are the
//! OGR FIDs where the driver keeps them stable (GeoPackage, SQLite,
//! FileGDB), else the read order. Reprojection, tiles and refreshes are
//! `relief_source::VectorSource`'s; the CRS transform comes from the daemon.
//!
//! It depends on relief-source and the gdal crate only, never on the
//! daemon or another source crate.

mod gdb;
mod read;
mod source;

pub use source::{KIND, Ogr, OgrSource};
