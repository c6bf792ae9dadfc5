//! The options of the effects a manifest declares (`[effects]`): each
//! effect takes exactly its own options, in range, or is refused naming the
//! option; none is accepted and ignored.

use relief_renderer::{Atmosphere, Fog, Shadows, Water};

/// What `[effects]` asks of the renderer beyond which effects are on.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EffectSettings {
    /// `atmosphere = { top_m }`, with `[quality] atmosphere_steps` and
    /// `atmosphere_downsample`.
    pub atmosphere: Option<Atmosphere>,
    /// `fog = { density, falloff_m, base_m, color }`.
    pub fog: Option<Fog>,
    /// `shadows = { distance_m }`, with `[quality] shadow_cascades` and
    /// `shadow_map_size`.
    pub shadows: Option<Shadows>,
    /// `water = { level_m, color, clarity_m }`.
    pub water: Option<Water>,
    /// `detail = {}`: the octaves synthesized below the data, `[quality]
    /// detail_octaves`.
    pub detail_octaves: Option<u32>,
}

impl EffectSettings {
    /// The declared effects' quality knobs and their values, for the
    /// scene's state (a knob of an undeclared effect is not there).
    pub fn quality(&self) -> Vec<(String, String)> {
        let mut out = Vec::new();
        let mut put = |name: &str, value: String| out.push((name.to_owned(), value));
        if let Some(a) = &self.atmosphere {
            put("atmosphere_steps", a.steps.to_string());
            put("atmosphere_downsample", a.downsample.to_string());
        }
        if let Some(s) = &self.shadows {
            put("shadow_cascades", s.cascades.to_string());
            put("shadow_map_size", s.map_size.to_string());
        }
        if let Some(octaves) = self.detail_octaves {
            put("detail_octaves", octaves.to_string());
        }
        out
    }

    /// Sets an effect's quality knob `name` to `value`:
    /// Err(knob, message) when the scene does not declare its effect or
    /// the value is out of range.
    pub fn set_quality(&mut self, name: &str, value: u32) -> Result<(), (String, String)> {
        let undeclared =
            |effect: &str| (name.to_owned(), format!("the scene declares no {effect} ([effects] {effect})"));
        let checked = |r: Result<(), (&str, String)>| r.map_err(|(knob, message)| (knob.to_owned(), message));
        match name {
            "atmosphere_steps" | "atmosphere_downsample" => {
                let a = self.atmosphere.as_mut().ok_or_else(|| undeclared("atmosphere"))?;
                if name == "atmosphere_steps" {
                    a.steps = value;
                } else {
                    a.downsample = value;
                }
                checked(a.validate())
            }
            "shadow_cascades" | "shadow_map_size" => {
                let s = self.shadows.as_mut().ok_or_else(|| undeclared("shadows"))?;
                if name == "shadow_cascades" {
                    s.cascades = value;
                } else {
                    s.map_size = value;
                }
                checked(s.validate())
            }
            "detail_octaves" => {
                let octaves = self.detail_octaves.as_mut().ok_or_else(|| undeclared("detail"))?;
                if !(1..=relief_renderer::Detail::MAX_OCTAVES).contains(&value) {
                    let most = relief_renderer::Detail::MAX_OCTAVES;
                    return Err((name.to_owned(), format!("{value} is not from 1 to {most}")));
                }
                *octaves = value;
                Ok(())
            }
            _ => Err((name.to_owned(), "not an effect's quality knob".into())),
        }
    }

    /// Adds effect `name`'s options from `params`: Err(option, message).
    pub fn add(&mut self, name: &str, params: &toml::Table) -> Result<(), (String, String)> {
        match name {
            "fog" => self.fog = Some(fog(params)?),
            "atmosphere" => self.atmosphere = Some(atmosphere(params)?),
            "shadows" => self.shadows = Some(shadows(params)?),
            "water" => self.water = Some(water(params)?),
            "detail" => {
                if let Some(key) = params.keys().next() {
                    return Err((
                        key.clone(),
                        "unknown option (detail takes none; its octaves are [quality] detail_octaves)".into(),
                    ));
                }
                self.detail_octaves = Some(relief_renderer::Detail::DEFAULT_OCTAVES);
            }
            _ => {
                if let Some(key) = params.keys().next() {
                    return Err((key.clone(), "unknown option (this effect takes none)".into()));
                }
            }
        }
        Ok(())
    }
}

/// `fog`: density per metre at the base height, the falloff height, the
/// base height and the colour; each defaulted from `Fog::DEFAULT`.
fn fog(params: &toml::Table) -> Result<Fog, (String, String)> {
    let mut fog = Fog::DEFAULT;
    for (key, value) in params {
        let number = || number(key, value);
        match key.as_str() {
            "density" => fog.density_per_m = number()?,
            "falloff_m" => fog.falloff_m = number()?,
            "base_m" => fog.base_m = number()?,
            // Fog has no opacity of its own: "#rrggbbaa" would be ignored.
            "color" => fog.color = rgb(key, value)?,
            _ => return Err((key.clone(), "unknown option (fog takes density, falloff_m, base_m, color)".into())),
        }
    }
    fog.validate().map_err(|(option, message)| (option.to_owned(), message))?;
    Ok(fog)
}

/// `atmosphere`: where its top is (the steps are a quality knob).
fn atmosphere(params: &toml::Table) -> Result<Atmosphere, (String, String)> {
    let mut atmosphere = Atmosphere::DEFAULT;
    for (key, value) in params {
        match key.as_str() {
            "top_m" => atmosphere.top_m = number(key, value)?,
            _ => {
                return Err((
                    key.clone(),
                    "unknown option (atmosphere takes top_m; its steps are [quality] atmosphere_steps)".into(),
                ));
            }
        }
    }
    atmosphere.validate().map_err(|(option, message)| (option.to_owned(), message))?;
    Ok(atmosphere)
}

/// `shadows`: how far from the eye they are cast (cascades and map size
/// are quality knobs).
fn shadows(params: &toml::Table) -> Result<Shadows, (String, String)> {
    let mut shadows = Shadows::DEFAULT;
    for (key, value) in params {
        match key.as_str() {
            "distance_m" => shadows.distance_m = number(key, value)?,
            _ => {
                return Err((
                    key.clone(),
                    "unknown option (shadows take distance_m; cascades and map size are [quality] shadow_cascades \
                     and shadow_map_size)"
                        .into(),
                ));
            }
        }
    }
    shadows.validate().map_err(|(option, message)| (option.to_owned(), message))?;
    Ok(shadows)
}

/// `water`: the surface's level (on the terrain without one), its colour
/// and clarity.
fn water(params: &toml::Table) -> Result<Water, (String, String)> {
    let mut water = Water::DEFAULT;
    for (key, value) in params {
        match key.as_str() {
            "level_m" => water.level_m = Some(number(key, value)?),
            "clarity_m" => water.clarity_m = number(key, value)?,
            // Water's opacity comes from its depth: "#rrggbbaa" is refused.
            "color" => water.color = rgb(key, value)?,
            _ => return Err((key.clone(), "unknown option (water takes level_m, color, clarity_m)".into())),
        }
    }
    water.validate().map_err(|(option, message)| (option.to_owned(), message))?;
    Ok(water)
}

/// An option's "#rrggbb" colour as straight RGB, 0..1.
fn rgb(key: &str, value: &toml::Value) -> Result<[f64; 3], (String, String)> {
    let toml::Value::String(text) = value else {
        return Err((key.to_owned(), format!("{value} is not a colour (\"#rrggbb\")")));
    };
    let c = relief_source_ops::parse_color(key, text)
        .ok()
        .filter(|_| text.trim_start_matches('#').len() == 6)
        .ok_or_else(|| (key.to_owned(), format!("'{text}' is not #rrggbb")))?;
    Ok([c[0], c[1], c[2]])
}

/// An option's number, or the option and what it is instead.
fn number(key: &str, value: &toml::Value) -> Result<f64, (String, String)> {
    match value {
        toml::Value::Float(v) => Ok(*v),
        toml::Value::Integer(v) => Ok(*v as f64),
        other => Err((key.to_owned(), format!("{other} is not a number"))),
    }
}
