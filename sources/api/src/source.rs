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

/// A manifest option value, as the source receives it: a scalar, or (for
/// options such as `scatter`'s rules) a list or a table of values, nested.
#[derive(Debug, Clone, PartialEq)]
pub enum OptionValue {
    Text(String),
    Number(f64),
    Bool(bool),
    List(Vec<OptionValue>),
    Table(BTreeMap<String, OptionValue>),
}

impl OptionValue {
    /// What kind of value this is, for messages ("a string", "a table").
    pub fn kind_name(&self) -> &'static str {
        match self {
            Self::Text(_) => "a string",
            Self::Number(_) => "a number",
            Self::Bool(_) => "a boolean",
            Self::List(_) => "a list",
            Self::Table(_) => "a table",
        }
    }
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
            Some(other) => Err(SourceError::option(field, format!("expected a string, found {}", other.kind_name()))),
        }
    }

    pub fn number(&self, field: &str) -> Result<Option<f64>, SourceError> {
        match self.options.get(field) {
            None => Ok(None),
            Some(OptionValue::Number(n)) if n.is_finite() => Ok(Some(*n)),
            Some(OptionValue::Number(n)) => {
                Err(SourceError::option(field, format!("expected a finite number, found {n}")))
            }
            Some(other) => {
                Err(SourceError::option(field, format!("expected a finite number, found {}", other.kind_name())))
            }
        }
    }

    pub fn flag(&self, field: &str) -> Result<Option<bool>, SourceError> {
        match self.options.get(field) {
            None => Ok(None),
            Some(OptionValue::Bool(b)) => Ok(Some(*b)),
            Some(other) => {
                Err(SourceError::option(field, format!("expected true or false, found {}", other.kind_name())))
            }
        }
    }

    /// A tile level of the grid (a whole number, 0 to `MAX_LEVEL`).
    pub fn level(&self, field: &str) -> Result<Option<u8>, SourceError> {
        match self.number(field)? {
            None => Ok(None),
            Some(l) if (0.0..=f64::from(crate::MAX_LEVEL)).contains(&l) && l.fract() == 0.0 => Ok(Some(l as u8)),
            Some(l) => Err(SourceError::option(field, format!("{l} is not a level of the grid"))),
        }
    }

    /// A list option (a TOML array, or an array of tables such as
    /// `[[source.rule]]`).
    pub fn list(&self, field: &str) -> Result<Option<&[OptionValue]>, SourceError> {
        match self.options.get(field) {
            None => Ok(None),
            Some(OptionValue::List(items)) => Ok(Some(items)),
            Some(other) => Err(SourceError::option(field, format!("expected a list, found {}", other.kind_name()))),
        }
    }

    /// A table option (a TOML inline table or `[source.field]`).
    pub fn table(&self, field: &str) -> Result<Option<&BTreeMap<String, OptionValue>>, SourceError> {
        match self.options.get(field) {
            None => Ok(None),
            Some(OptionValue::Table(table)) => Ok(Some(table)),
            Some(other) => Err(SourceError::option(field, format!("expected a table, found {}", other.kind_name()))),
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
    /// What was read differently from how the file says it, or left out,
    /// in sentences for the user (a rebuilt .shx, a missing .dbf...).
    pub warnings: Vec<String>,
    /// Per class of a classified input (the `scatter` op): how many samples
    /// and instances the tiles built so far hold; empty for other sources.
    pub classes: Vec<ClassCount>,
}

/// One class of a land-cover input, as a source that places things by
/// class reports it in the scene state.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClassCount {
    /// The class code.
    pub class: i64,
    /// True when the source has a rule for this class.
    pub has_rule: bool,
    /// Instances placed on this class.
    pub instances: u64,
    /// Samples of the class raster holding this class.
    pub samples: u64,
}

/// Access to the tiles of a source's inputs while it generates a tile.
pub trait InputTiles: Sync {
    /// The tile `key` of input number `input` (in the order of `Source::inputs`).
    fn tile(&self, input: usize, key: TileKey) -> Result<Arc<Payload>, SourceError>;

    /// The files input number `input` reads, for an error about its data
    /// to name them; empty when unknown.
    fn files(&self, _input: usize) -> Vec<PathBuf> {
        Vec::new()
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_and_tables_read_as_such_and_scalars_as_before() -> Result<(), Box<dyn std::error::Error>> {
        let rule: BTreeMap<String, OptionValue> = [("class".to_owned(), OptionValue::Number(311.0))].into();
        let spec = SourceSpec {
            options: [
                ("rule".to_owned(), OptionValue::List(vec![OptionValue::Table(rule.clone())])),
                ("style".to_owned(), OptionValue::Table(rule.clone())),
                ("seed".to_owned(), OptionValue::Number(7.0)),
            ]
            .into(),
            ..SourceSpec::default()
        };
        assert_eq!(spec.list("rule")?, Some(&[OptionValue::Table(rule.clone())][..]));
        assert_eq!(spec.table("style")?, Some(&rule));
        assert_eq!(spec.list("none")?, None);
        assert_eq!(spec.number("seed")?, Some(7.0));
        let err = spec.list("style").unwrap_err().to_string();
        assert_eq!(err, "invalid option 'style': expected a list, found a table");
        assert!(spec.table("seed").unwrap_err().to_string().contains("expected a table, found a number"));
        assert!(spec.number("rule").is_err() && spec.text("rule").is_err());
        Ok(())
    }
}
