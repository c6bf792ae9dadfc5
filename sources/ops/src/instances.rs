//! `instances`: points (trees, street lights, signs) become placed models or
//! billboards, with the id, scale and rotation taken from attributes.

use relief_source::{
    GenerateContext, Geometry, Instance, InstanceKind, InstanceTile, Payload, PayloadKind, Skipped, Source,
    SourceError, SourceInfo, SourceSpec, TileKey,
};

use crate::placement::{AltitudeMode, AttributeOr, Ground, check_inputs};

pub const INSTANCES_KIND: &str = "instances";
/// Points, then (optional) the terrain they stand on.
pub const INSTANCES_INPUTS: &[PayloadKind] = &[PayloadKind::Features, PayloadKind::Height];

#[derive(Debug)]
pub struct Instances {
    id: String,
    inputs: Vec<String>,
    kind: InstanceKind,
    /// `model_attribute` names the attribute holding the id; `model` is
    /// the id for points without one.
    model_attribute: Option<String>,
    model: String,
    scale: AttributeOr,
    rotation: AttributeOr,
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
        check_inputs(spec, INSTANCES_KIND)?;
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
            model_attribute: spec.text("model_attribute")?.map(str::to_owned),
            model: spec.text("model")?.unwrap_or("default").to_owned(),
            scale,
            rotation,
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
        info
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
            let model = self
                .model_attribute
                .as_ref()
                .and_then(|a| props.get(a))
                .filter(|m| !m.trim().is_empty())
                .map_or_else(|| self.model.clone(), |m| m.trim().to_owned());
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
