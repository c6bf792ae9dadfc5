//! The `shapefile` source kind.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use relief_source::files::Fingerprint;
use relief_source::{
    CrsTransform, FeatureIndex, GenerateContext, Payload, PayloadKind, Refresh, Source, SourceError, SourceInfo,
    SourceSpec, TileGrid, TileKey,
};

use crate::check::{check, sibling};
use crate::read::read;

pub const KIND: &str = "shapefile";

/// A shapefile's features, in the grid's CRS.
#[derive(Debug)]
pub struct ShapefileSource {
    spec: SourceSpec,
    path: PathBuf,
    crs: Arc<dyn CrsTransform>,
    /// The CRS as the .prj states it (or the manifest overrides it).
    file_crs: String,
    crs_note: String,
    fingerprint: Fingerprint,
    index: FeatureIndex,
    null_shapes: usize,
    shape_types: BTreeMap<String, usize>,
}

impl ShapefileSource {
    pub fn open(spec: &SourceSpec, grid: &TileGrid, crs: Arc<dyn CrsTransform>) -> Result<Self, SourceError> {
        spec.only_options(&["crs"])?;
        let [path] = spec.paths.as_slice() else {
            return Err(SourceError::option("path", "a shapefile source reads one .shp (its sidecars come with it)"));
        };
        if !path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("shp")) {
            return Err(SourceError::option("path", format!("'{}' is not a .shp file", path.display())));
        }
        let fingerprint = Fingerprint::of(path, "shapefile")?;
        let records = check(path)?;
        let read = read(path)?;
        if Fingerprint::of(path, "shapefile")? != fingerprint {
            return Err(SourceError::Changing { path: path.clone() });
        }
        debug_assert_eq!(records, read.features.len() + read.null_shapes);
        let (file_crs, crs_note) = match (spec.text("crs")?, std::fs::read_to_string(sibling(path, "prj"))) {
            (Some(c), _) => (c.to_owned(), "from the manifest".to_owned()),
            (None, Ok(wkt)) if !wkt.trim().is_empty() => (wkt.trim().to_owned(), "from the .prj".to_owned()),
            _ => ("EPSG:4326".to_owned(), "no .prj: WGS84 longitude/latitude assumed".to_owned()),
        };
        let index = FeatureIndex::new(read.features, &file_crs, grid, crs.as_ref()).map_err(|e| match e {
            SourceError::Crs { crs, message, .. } => {
                SourceError::Crs { crs, message, path: Some(sibling(path, "prj")) }
            }
            other => other,
        })?;
        Ok(Self {
            spec: spec.clone(),
            path: path.clone(),
            crs,
            file_crs,
            crs_note,
            fingerprint,
            index,
            null_shapes: read.null_shapes,
            shape_types: read.shape_types,
        })
    }
}

impl Source for ShapefileSource {
    fn id(&self) -> &str {
        &self.spec.id
    }

    fn kind(&self) -> &'static str {
        KIND
    }

    fn output(&self) -> PayloadKind {
        PayloadKind::Features
    }

    fn info(&self) -> SourceInfo {
        let mut details = BTreeMap::new();
        details.insert("features".into(), self.index.len().to_string());
        details.insert("null_shapes".into(), self.null_shapes.to_string());
        for (kind, count) in &self.shape_types {
            details.insert(format!("shapes.{kind}"), count.to_string());
        }
        details.insert("crs_source".into(), self.crs_note.clone());
        if let Ok(cpg) = std::fs::read_to_string(sibling(&self.path, "cpg")) {
            details.insert("encoding".into(), cpg.trim().to_owned());
        }
        SourceInfo {
            files: relief_source::files::dataset_files(&self.path),
            extent: self.index.extent(),
            crs: self.file_crs.lines().next().unwrap_or_default().chars().take(80).collect(),
            details,
            ..SourceInfo::default()
        }
    }

    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        Ok(Payload::Features(self.index.tile(ctx.grid, key)))
    }

    /// Reads the dataset again when any of its files changed; the dirt is
    /// the old and new parts of every feature that changed, came or went.
    fn refresh(&self, grid: &TileGrid) -> Result<Refresh, SourceError> {
        if Fingerprint::of(&self.path, "shapefile")? == self.fingerprint {
            return Ok(Refresh::Unchanged);
        }
        let new = Self::open(&self.spec, grid, Arc::clone(&self.crs))?;
        let dirty = new.index.dirt_since(&self.index);
        Ok(Refresh::Changed { source: Arc::new(new), dirty })
    }
}
