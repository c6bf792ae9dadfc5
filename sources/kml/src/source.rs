//! The `kml` source kind (KML and KMZ).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use relief_source::files::Fingerprint;
use relief_source::{
    CrsTransform, FeatureIndex, GenerateContext, Payload, PayloadKind, Refresh, Source, SourceError, SourceInfo,
    SourceSpec, TileGrid, TileKey,
};

use crate::load::{Limits, parse, text};
use crate::walk::walk;

pub const KIND: &str = "kml";

#[derive(Debug)]
pub struct KmlSource {
    spec: SourceSpec,
    path: PathBuf,
    crs: Arc<dyn CrsTransform>,
    fingerprint: Fingerprint,
    index: FeatureIndex,
    counted: usize,
    without_geometry: usize,
    network_links: Vec<String>,
}

impl KmlSource {
    pub fn open(spec: &SourceSpec, grid: &TileGrid, crs: Arc<dyn CrsTransform>) -> Result<Self, SourceError> {
        spec.only_options(&[])?;
        let [path] = spec.paths.as_slice() else {
            return Err(SourceError::option("path", "a kml source reads one .kml or .kmz"));
        };
        let fingerprint = Fingerprint::of(path, "kml")?;
        let text = text(path, &Limits::default())?;
        let found = walk(&parse(&text, path)?, &text);
        if Fingerprint::of(path, "kml")? != fingerprint {
            return Err(SourceError::Changing { path: path.clone() });
        }
        // KML is WGS84 longitude, latitude by definition.
        let index = FeatureIndex::new(found.features, "EPSG:4326", grid, crs.as_ref())?;
        Ok(Self {
            spec: spec.clone(),
            path: path.clone(),
            crs,
            fingerprint,
            index,
            counted: found.counted,
            without_geometry: found.without_geometry,
            network_links: found.network_links,
        })
    }
}

impl Source for KmlSource {
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
        details.insert("features".into(), self.counted.to_string());
        details.insert("without_geometry".into(), self.without_geometry.to_string());
        if !self.network_links.is_empty() {
            details.insert("network_links_not_followed".into(), self.network_links.join(" "));
        }
        SourceInfo {
            files: vec![self.path.clone()],
            extent: self.index.extent(),
            crs: "EPSG:4326 (KML)".into(),
            vertical_datum: "WGS84 ellipsoid or ground, per altitude mode".into(),
            details,
            ..SourceInfo::default()
        }
    }

    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        Ok(Payload::Features(self.index.tile(ctx.grid, key)))
    }

    fn refresh(&self, grid: &TileGrid) -> Result<Refresh, SourceError> {
        if Fingerprint::of(&self.path, "kml")? == self.fingerprint {
            return Ok(Refresh::Unchanged);
        }
        let new = Self::open(&self.spec, grid, Arc::clone(&self.crs))?;
        let dirty = new.index.dirt_since(&self.index);
        Ok(Refresh::Changed { source: Arc::new(new), dirty })
    }
}
