//! What extrusion and instancing share: the ground under a feature (from
//! an optional height input), KML altitude modes, and numeric attributes.

use std::collections::BTreeMap;

use relief_source::{GenerateContext, SourceError, SourceSpec, TileKey};

use crate::window::HeightWindow;

/// How a feature's z is meant, as KML states it (`altitude_mode` property);
/// features without one sit on the ground.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AltitudeMode {
    ClampToGround,
    RelativeToGround,
    Absolute,
}

impl AltitudeMode {
    pub fn of(properties: &BTreeMap<String, String>) -> Self {
        match properties.get("altitude_mode").map(String::as_str) {
            Some("relativeToGround" | "relativeToSeaFloor") => Self::RelativeToGround,
            Some("absolute") => Self::Absolute,
            _ => Self::ClampToGround,
        }
    }
}

/// The ground under features of one tile: the op's optional second input
/// (a height source), sampled at the tile's level; 0 m without one.
pub struct Ground<'a, 'c> {
    window: Option<HeightWindow<'a, 'c>>,
}

impl<'a, 'c> Ground<'a, 'c> {
    pub fn new(ctx: &'a GenerateContext<'c>, key: TileKey, has_terrain: bool) -> Self {
        Self { window: has_terrain.then(|| HeightWindow::new(ctx, 1, key.level)) }
    }

    /// The ground height at (x, y); None where the terrain has no data.
    pub fn at(&mut self, x: f64, y: f64) -> Result<Option<f64>, SourceError> {
        match &mut self.window {
            None => Ok(Some(0.0)),
            Some(w) => {
                let h = w.height_at(x, y)?;
                Ok(h.is_finite().then_some(f64::from(h)))
            }
        }
    }
}

/// A numeric attribute of a feature: None when absent or empty, an error
/// text naming the attribute and value when it is not a finite number.
pub fn number_attribute(properties: &BTreeMap<String, String>, name: &str) -> Result<Option<f64>, String> {
    match properties.get(name).map(|v| v.trim()) {
        None | Some("") => Ok(None),
        Some(text) => match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            _ => Err(format!("attribute '{name}' is '{text}', not a number")),
        },
    }
}

/// Options naming an attribute and giving a fallback value: `{what}_attribute`
/// and `{what}` (for example `scale_attribute` and `scale`).
#[derive(Debug, Clone)]
pub struct AttributeOr {
    pub attribute: Option<String>,
    pub value: Option<f64>,
}

impl AttributeOr {
    pub fn from_spec(spec: &SourceSpec, what: &str) -> Result<Self, SourceError> {
        Ok(Self { attribute: spec.text(&format!("{what}_attribute"))?.map(str::to_owned), value: spec.number(what)? })
    }

    /// The feature's value: its attribute when it has one, else the fallback.
    pub fn of(&self, properties: &BTreeMap<String, String>) -> Result<Option<f64>, String> {
        let from_attribute = match &self.attribute {
            Some(name) => number_attribute(properties, name)?,
            None => None,
        };
        Ok(from_attribute.or(self.value))
    }
}

/// Checks an op's input list: one features input, and optionally a height
/// input for the ground. `model_files`: its `paths` are glTF models.
pub fn check_inputs(spec: &SourceSpec, kind: &str, model_files: bool) -> Result<(), SourceError> {
    if !(1..=2).contains(&spec.inputs.len()) {
        return Err(SourceError::option(
            "inputs",
            format!("{kind} takes a features input and optionally a height input for the ground"),
        ));
    }
    if !model_files && !spec.paths.is_empty() {
        return Err(SourceError::option("path", format!("{kind} reads no files: give it 'inputs'")));
    }
    Ok(())
}
