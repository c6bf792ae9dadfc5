//! The `Source` trait: what every source crate implements.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use crate::dirty::DirtySet;
use crate::error::SourceError;
use crate::grid::{Extent, TileGrid, TileKey};
use crate::payload::{Payload, PayloadKind};
use crate::quality::Quality;

/// A longitude and latitude in degrees on WGS84.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeodeticPoint {
    pub lon_deg: f64,
    pub lat_deg: f64,
}

/// A manifest option value, as the source receives it.
#[derive(Debug, Clone, PartialEq)]
pub enum OptionValue {
    Text(String),
    Number(f64),
    Bool(bool),
}

/// How the manifest declares a source: everything a source crate needs to
/// open it. Paths are already resolved against the manifest's folder.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SourceSpec {
    pub id: String,
    pub kind: String,
    pub paths: Vec<PathBuf>,
    pub inputs: Vec<String>,
    pub options: BTreeMap<String, OptionValue>,
}

impl SourceSpec {
    pub fn text(&self, field: &str) -> Result<Option<&str>, SourceError> {
        match self.options.get(field) {
            None => Ok(None),
            Some(OptionValue::Text(s)) => Ok(Some(s)),
            Some(other) => Err(SourceError::option(field, format!("expected a string, found {other:?}"))),
        }
    }

    pub fn number(&self, field: &str) -> Result<Option<f64>, SourceError> {
        match self.options.get(field) {
            None => Ok(None),
            Some(OptionValue::Number(n)) if n.is_finite() => Ok(Some(*n)),
            Some(other) => Err(SourceError::option(field, format!("expected a finite number, found {other:?}"))),
        }
    }

    /// Rejects options the source does not know, naming the first one.
    pub fn only_options(&self, known: &[&str]) -> Result<(), SourceError> {
        match self.options.keys().find(|k| !known.contains(&k.as_str())) {
            Some(unknown) => Err(SourceError::option(
                unknown.clone(),
                format!("unknown option for kind '{}' (known: {})", self.kind, known.join(", ")),
            )),
            None => Ok(()),
        }
    }
}

/// Facts about a source for the scene state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SourceInfo {
    /// Every file the source reads, sidecars included.
    pub files: Vec<PathBuf>,
    /// Extent of the data in the grid's CRS, when known.
    pub extent: Option<Extent>,
    pub crs: String,
    pub vertical_datum: String,
    pub vertical_units: String,
    /// The finest sample spacing the data has, in grid units (a renderer
    /// stops refining there).
    pub resolution: Option<f64>,
    pub details: BTreeMap<String, String>,
}

/// Access to the tiles of a source's inputs while it generates a tile.
pub trait InputTiles: Sync {
    /// The tile `key` of input number `input` (in the order of `Source::inputs`).
    fn tile(&self, input: usize, key: TileKey) -> Result<Arc<Payload>, SourceError>;
}

/// Inputs for a source that has none.
pub struct NoInputs;

impl InputTiles for NoInputs {
    fn tile(&self, input: usize, _key: TileKey) -> Result<Arc<Payload>, SourceError> {
        Err(SourceError::Input { input: input.to_string(), message: "this source has no inputs".into() })
    }
}

/// What tile generation may read besides the source itself.
pub struct GenerateContext<'a> {
    pub grid: &'a TileGrid,
    pub quality: &'a Quality,
    pub inputs: &'a dyn InputTiles,
}

/// The outcome of `Source::refresh`.
#[derive(Debug)]
pub enum Refresh {
    Unchanged,
    /// A new version of the source, and where its output changed.
    Changed {
        source: Arc<dyn Source>,
        dirty: DirtySet,
    },
}

/// A node of the scene's source graph: a file-backed source or an op over
/// other sources' tiles. A source value is immutable: a new version of its
/// data is a new value (see `refresh`), so a tile request that holds one sees
/// one consistent version.
pub trait Source: Send + Sync + std::fmt::Debug {
    fn id(&self) -> &str;

    /// The manifest kind, for example "gdal" or "hillshade".
    fn kind(&self) -> &'static str;

    fn output(&self) -> PayloadKind;

    /// Ids of the sources this one reads, in order.
    fn inputs(&self) -> &[String] {
        &[]
    }

    fn info(&self) -> SourceInfo {
        SourceInfo::default()
    }

    /// Produces one tile. Pure: the same source value, key, context and
    /// input tiles give the same bytes.
    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError>;

    /// Reads the source's files again and reports what changed since this
    /// value was loaded. Sources without files never change.
    fn refresh(&self, _grid: &TileGrid) -> Result<Refresh, SourceError> {
        Ok(Refresh::Unchanged)
    }

    /// Maps dirt on input number `input` to dirt on this source's output.
    fn dirty_from_input(&self, _input: usize, dirt: &DirtySet) -> DirtySet {
        dirt.clone()
    }

    /// Heights at points, at the source's native resolution; None where the
    /// source has no data.
    fn sample_heights(&self, _points: &[GeodeticPoint], _quality: &Quality) -> Result<Vec<Option<f64>>, SourceError> {
        Err(SourceError::Unsupported("sampling elevations"))
    }
}
