//! The `shapefile` format: a .shp and its sidecars, or a zip holding them.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;

use relief_source::{SourceError, SourceSpec, VectorFormat, VectorRead, VectorSource};

use crate::check;
use crate::dataset::{Dataset, sibling};
use crate::read::read;
use crate::shx;
use crate::zipped::{self, Limits};

pub const KIND: &str = "shapefile";

#[derive(Debug)]
pub struct Shapefile;

/// A shapefile's features as a source.
pub type ShapefileSource = VectorSource<Shapefile>;

fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

impl VectorFormat for Shapefile {
    const KIND: &'static str = KIND;

    /// `path` is a .shp, or a .zip holding one (the `layer` option names
    /// it when the zip holds several). The zip is the file watched: an edit
    /// of it reloads the source.
    fn read(spec: &SourceSpec, path: &Path, _stamped: &[std::path::PathBuf]) -> Result<VectorRead, SourceError> {
        spec.only_options(&[&["crs", "layer"], relief_source::patches::OPTIONS].concat())?;
        let layer = spec.text("layer")?;
        let (dataset, zip_member) = if has_extension(path, "zip") {
            let dataset = zipped::open(path, layer, &Limits::default())?;
            let member = dataset.shp.path.strip_prefix(path).map(|m| m.display().to_string()).ok();
            (dataset, member)
        } else if has_extension(path, "shp") {
            if layer.is_some() {
                return Err(SourceError::option(
                    "layer",
                    format!("chooses a shapefile inside a .zip, and '{}' is a .shp", path.display()),
                ));
            }
            (Dataset::beside(path)?, None)
        } else {
            return Err(SourceError::option(
                "path",
                format!("'{}' is neither a .shp file nor a .zip holding one", path.display()),
            ));
        };

        let mut warnings = Vec::new();
        let mut dataset = dataset;
        let shp = check::shp(&dataset.shp)?;
        // Bytes past the header's length are no record: read without them.
        dataset.shp.bytes.truncate(shp.len);
        warnings.extend(shp.warning);
        let (shx, records, counted_by): (Cow<'_, [u8]>, usize, &str) = match &dataset.shx {
            Some(shx) => {
                let checked = check::shx(shx, &dataset.shp)?;
                let index = match checked.warning {
                    Some(warning) => {
                        warnings.push(warning);
                        // The header's length made true, for the reader.
                        let mut fixed = shx.bytes.clone();
                        let words = i32::try_from(fixed.len() / 2).unwrap_or(i32::MAX);
                        fixed[24..28].copy_from_slice(&words.to_be_bytes());
                        Cow::Owned(fixed)
                    }
                    None => Cow::Borrowed(shx.bytes.as_slice()),
                };
                (index, checked.records, "the .shx indexes")
            }
            None => {
                let (rebuilt, records) = shx::rebuild(&dataset.shp)?;
                warnings
                    .push(format!("no .shx beside the .shp: the index was rebuilt by walking its {records} records"));
                (Cow::Owned(rebuilt), records, "the .shp holds")
            }
        };
        match &dataset.dbf {
            Some(dbf) => check::dbf(dbf, records, counted_by)?,
            None => warnings.push("no .dbf: geometry read without attributes".to_owned()),
        }
        let read = read(&dataset, &shx, records)?;

        let prj = dataset.prj.as_ref().map(|p| String::from_utf8_lossy(&p.bytes).trim().to_owned());
        let (crs, crs_note) = match (spec.text("crs")?, prj) {
            (Some(c), _) => (c.to_owned(), "from the manifest".to_owned()),
            (None, Some(wkt)) if !wkt.is_empty() => (wkt, "from the .prj".to_owned()),
            _ => ("EPSG:4326".to_owned(), "no .prj: WGS84 longitude/latitude assumed".to_owned()),
        };
        let mut details = BTreeMap::new();
        details.insert("features".into(), read.features.len().to_string());
        details.insert("null_shapes".into(), read.null_shapes.to_string());
        if read.deleted > 0 {
            details.insert("deleted_records".into(), read.deleted.to_string());
        }
        for (kind, count) in &read.shape_types {
            details.insert(format!("shapes.{kind}"), count.to_string());
        }
        details.insert("crs_source".into(), crs_note);
        if let Some(cpg) = &dataset.cpg {
            details.insert("encoding".into(), String::from_utf8_lossy(&cpg.bytes).trim().to_owned());
        }
        if let Some(member) = zip_member {
            details.insert("zip_member".into(), member);
        }
        Ok(VectorRead {
            surfaces: read.surfaces,
            features: read.features,
            crs_name: crs.lines().next().unwrap_or_default().chars().take(80).collect(),
            crs,
            crs_file: Some(dataset.prj.map_or_else(|| sibling(&dataset.shp.path, "prj"), |p| p.path)),
            files: relief_source::files::dataset_files(path),
            vertical_datum: String::new(),
            details,
            warnings,
        })
    }
}
