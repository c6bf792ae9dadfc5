//! The `kml` format (KML and KMZ).

use std::collections::BTreeMap;
use std::path::Path;

use relief_source::{SourceError, SourceSpec, VectorFormat, VectorRead, VectorSource};

use crate::load::{Limits, parse, text};
use crate::tidy::tidy;
use crate::walk::walk;

pub const KIND: &str = "kml";

#[derive(Debug)]
pub struct Kml;

/// A KML or KMZ file's features as a source.
pub type KmlSource = VectorSource<Kml>;

impl VectorFormat for Kml {
    const KIND: &'static str = KIND;

    fn read(spec: &SourceSpec, path: &Path, _stamped: &[std::path::PathBuf]) -> Result<VectorRead, SourceError> {
        spec.only_options(&[])?;
        let text = text(path, &Limits::default())?;
        let tidied = tidy(&text, path)?;
        let found = walk(&parse(&tidied.text, path)?, &tidied.text);
        let mut details = BTreeMap::new();
        details.insert("features".into(), found.counted.to_string());
        details.insert("without_geometry".into(), found.without_geometry.to_string());
        if !found.network_links.is_empty() {
            details.insert("network_links_not_followed".into(), found.network_links.join(" "));
        }
        Ok(VectorRead {
            surfaces: false,
            features: found.features,
            // KML is WGS84 longitude, latitude by definition.
            crs: "EPSG:4326".into(),
            crs_file: None,
            files: vec![path.to_path_buf()],
            crs_name: "EPSG:4326 (KML)".into(),
            vertical_datum: "WGS84 ellipsoid or ground, per altitude mode".into(),
            details,
            warnings: tidied.warnings,
        })
    }
}
