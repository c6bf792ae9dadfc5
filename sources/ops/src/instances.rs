//! `instances`: points (trees, street lights, signs) become placed models or
//! billboards, with the model, scale and rotation taken from attributes.
//! Models are the stock ones or the glTF files in `paths` (named by stem);
//! a point naming another model is left out, and says so.

use std::sync::Arc;

use relief_source::{
    DirtySet, GenerateContext, Geometry, Instance, InstanceKind, InstanceTile, Payload, PayloadKind, Refresh, Skipped,
    Source, SourceError, SourceInfo, SourceSpec, TileGrid, TileKey,
};

use crate::models::{ModelFile, known_models, reopen_changed};
use crate::placement::{AltitudeMode, AttributeOr, Ground, check_inputs};

pub const INSTANCES_KIND: &str = "instances";
/// Points, then (optional) the terrain they stand on.
pub const INSTANCES_INPUTS: &[PayloadKind] = &[PayloadKind::Features, PayloadKind::Height];

#[derive(Debug, Clone)]
pub struct Instances {
    id: String,
    inputs: Vec<String>,
    kind: InstanceKind,
    /// `model_attribute` names the attribute holding the model's name;
    /// `model` is the name for points without one.
    model_attribute: Option<String>,
    model: Option<String>,
    scale: AttributeOr,
    rotation: AttributeOr,
    models: Vec<ModelFile>,
    known: Vec<String>,
}

impl Instances {
    pub fn open(spec: &SourceSpec) -> Result<Self, SourceError> {
        spec.only_options(&[
            "render_as",
            "model_attribute",
            "model",
            "scale_attribute",
            "scale",
            "rotation_attribute",
            "rotation",
        ])?;
        check_inputs(spec, INSTANCES_KIND, true)?;
        let models = ModelFile::open_all(&spec.paths, &spec.id)?;
        let known = known_models(&models);
        let model = spec.text("model")?.map(str::to_owned);
        let model_attribute = spec.text("model_attribute")?.map(str::to_owned);
        match &model {
            Some(m) if !known.contains(m) => {
                return Err(SourceError::option(
                    "model",
                    format!("'{m}' is not a model (known: {})", known.join(", ")),
                ));
            }
            None if model_attribute.is_none() => {
                return Err(SourceError::option(
                    "model",
                    format!("give 'model' (one of {}) or 'model_attribute'", known.join(", ")),
                ));
            }
            _ => {}
        }
        let kind = match spec.text("render_as")? {
            None | Some("model") => InstanceKind::Model,
            Some("billboard") => InstanceKind::Billboard,
            Some(other) => {
                return Err(SourceError::option("render_as", format!("'{other}' is not 'model' or 'billboard'")));
            }
        };
        let mut scale = AttributeOr::from_spec(spec, "scale")?;
        if scale.value.is_some_and(|s| s <= 0.0) {
            return Err(SourceError::option("scale", "a scale is more than 0"));
        }
        scale.value = scale.value.or(Some(1.0));
        let mut rotation = AttributeOr::from_spec(spec, "rotation")?;
        rotation.value = rotation.value.or(Some(0.0));
        Ok(Self {
            id: spec.id.clone(),
            inputs: spec.inputs.clone(),
            kind,
            model_attribute,
            model,
            scale,
            rotation,
            models,
            known,
        })
    }
}

impl Source for Instances {
    fn id(&self) -> &str {
        &self.id
    }

    fn kind(&self) -> &'static str {
        INSTANCES_KIND
    }

    fn output(&self) -> PayloadKind {
        PayloadKind::Instances
    }

    fn inputs(&self) -> &[String] {
        &self.inputs
    }

    fn info(&self) -> SourceInfo {
        let mut info = SourceInfo::default();
        let kind = match self.kind {
            InstanceKind::Model => "model",
            InstanceKind::Billboard => "billboard",
        };
        info.details.insert("render_as".into(), kind.into());
        info.details.insert("ground".into(), self.inputs.get(1).cloned().unwrap_or_else(|| "0 m".into()));
        info.details.insert("models".into(), self.known.join(", "));
        info.files = self.models.iter().flat_map(ModelFile::files).collect();
        info
    }

    /// A model file that changed dirties everything; one gone or unusable
    /// is an error naming it (the last good version stays).
    fn refresh(&self, _grid: &TileGrid) -> Result<Refresh, SourceError> {
        let Some(models) = reopen_changed(&self.models, &self.id)? else {
            return Ok(Refresh::Unchanged);
        };
        Ok(Refresh::Changed { source: Arc::new(Self { models, ..self.clone() }), dirty: DirtySet::everything() })
    }

    /// Points are owned by one tile each (the feature tiles already say
    /// so); a multipoint gives one instance per point.
    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        let input = ctx.inputs.tile(0, key)?;
        let Payload::Features(features) = input.as_ref() else {
            return Err(SourceError::Input { input: self.inputs[0].clone(), message: "expected feature tiles".into() });
        };
        let mut ground = Ground::new(ctx, key, self.inputs.len() > 1);
        let mut tile = InstanceTile::default();
        for feature in &features.features {
            let Geometry::Points(points) = &feature.geometry else { continue };
            let props = &feature.properties;
            let skip = |tile: &mut InstanceTile, reason: String| {
                tile.skipped.push(Skipped { feature_id: feature.id, reason });
            };
            let (scale, rotation) = match (self.scale.of(props), self.rotation.of(props)) {
                (Ok(s), Ok(r)) => (s.unwrap_or(1.0), r.unwrap_or(0.0)),
                (Err(reason), _) | (_, Err(reason)) => {
                    skip(&mut tile, reason);
                    continue;
                }
            };
            if scale <= 0.0 {
                skip(&mut tile, format!("scale {scale} is not more than 0"));
                continue;
            }
            let named = self
                .model_attribute
                .as_ref()
                .and_then(|a| props.get(a))
                .map(|m| m.trim())
                .filter(|m| !m.is_empty())
                .or(self.model.as_deref());
            let model = match named {
                Some(m) if self.known.iter().any(|k| k == m) => m.to_owned(),
                Some(m) => {
                    skip(&mut tile, format!("model '{m}' is not known (known: {})", self.known.join(", ")));
                    continue;
                }
                None => {
                    skip(&mut tile, "no model: the model attribute is empty and the source has no 'model'".into());
                    continue;
                }
            };
            for p in points.iter().filter(|p| ctx.grid.key_at(key.level, p[0], p[1]) == Some(key)) {
                let z = match (AltitudeMode::of(props), p[2].is_finite()) {
                    (AltitudeMode::Absolute, true) => Some(p[2]),
                    (AltitudeMode::RelativeToGround, true) => ground.at(p[0], p[1])?.map(|g| g + p[2]),
                    _ => ground.at(p[0], p[1])?,
                };
                let Some(z) = z else {
                    skip(&mut tile, "the terrain has no data under the point".into());
                    continue;
                };
                tile.instances.push(Instance {
                    feature_id: feature.id,
                    position: [p[0], p[1], z],
                    kind: self.kind,
                    model: model.clone(),
                    scale,
                    rotation_deg: rotation.rem_euclid(360.0),
                });
            }
        }
        Ok(Payload::Instances(tile))
    }
}
