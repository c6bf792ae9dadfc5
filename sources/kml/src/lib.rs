//! relief-source-kml: KML and KMZ into feature tiles.
//!
//! Placemarks (points, lines, polygons with holes, MultiGeometry) and
//! ground overlays become features, counted as GDAL's LIBKML driver counts
//! them. Altitude mode and extrude are kept as properties, with z; line
//! and polygon styles become default styling properties. A KMZ is read
//! within limits (size, entries, inflation ratio), XML entity declarations
//! are refused (billion laughs), and a NetworkLink is reported, never
//! followed. What the kml crate refuses but other readers open (sea-floor
//! altitude modes, HTML in descriptions) is tidied first (`tidy`), with a
//! warning where the reading differs from the file; no message shows the
//! kml crate's `Debug` output.

mod load;
mod source;
mod tidy;
mod walk;

pub use load::Limits;
pub use source::{KIND, Kml, KmlSource};
