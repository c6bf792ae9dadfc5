//! The `shapefile` format.

use std::collections::BTreeMap;
use std::path::Path;

use relief_source::{SourceError, SourceSpec, VectorFormat, VectorRead, VectorSource};

use crate::check::{check, sibling};
use crate::read::read;

pub const KIND: &str = "shapefile";

#[derive(Debug)]
pub struct Shapefile;

/// A shapefile's features as a source.
pub type ShapefileSource = VectorSource<Shapefile>;

impl VectorFormat for Shapefile {
    const KIND: &'static str = KIND;

    fn read(spec: &SourceSpec, path: &Path) -> Result<VectorRead, SourceError> {
        spec.only_options(&["crs"])?;
        if !path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("shp")) {
            return Err(SourceError::option("path", format!("'{}' is not a .shp file", path.display())));
        }
        let records = check(path)?;
        let read = read(path)?;
        debug_assert_eq!(records, read.features.len() + read.null_shapes);
        let (crs, crs_note) = match (spec.text("crs")?, std::fs::read_to_string(sibling(path, "prj"))) {
            (Some(c), _) => (c.to_owned(), "from the manifest".to_owned()),
            (None, Ok(wkt)) if !wkt.trim().is_empty() => (wkt.trim().to_owned(), "from the .prj".to_owned()),
            _ => ("EPSG:4326".to_owned(), "no .prj: WGS84 longitude/latitude assumed".to_owned()),
        };
        let mut details = BTreeMap::new();
        details.insert("features".into(), read.features.len().to_string());
        details.insert("null_shapes".into(), read.null_shapes.to_string());
        for (kind, count) in &read.shape_types {
            details.insert(format!("shapes.{kind}"), count.to_string());
        }
        details.insert("crs_source".into(), crs_note);
        if let Ok(cpg) = std::fs::read_to_string(sibling(path, "cpg")) {
            details.insert("encoding".into(), cpg.trim().to_owned());
        }
        Ok(VectorRead {
            features: read.features,
            crs_name: crs.lines().next().unwrap_or_default().chars().take(80).collect(),
            crs,
            crs_file: Some(sibling(path, "prj")),
            files: relief_source::files::dataset_files(path),
            vertical_datum: String::new(),
            details,
        })
    }
}
