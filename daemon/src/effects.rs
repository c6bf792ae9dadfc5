//! The options of the effects a manifest declares (`[effects]`): each
//! effect takes exactly its own options, in range, or is refused naming the
//! option; none is accepted and ignored.

use relief_renderer::{Atmosphere, Fog};

/// What `[effects]` asks of the renderer beyond which effects are on.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EffectSettings {
    /// `atmosphere = { top_m }`, with `[quality] atmosphere_steps`.
    pub atmosphere: Option<Atmosphere>,
    /// `fog = { density, falloff_m, base_m, color }`.
    pub fog: Option<Fog>,
}

impl EffectSettings {
    /// Adds effect `name`'s options from `params`: Err(option, message).
    pub fn add(&mut self, name: &str, params: &toml::Table) -> Result<(), (String, String)> {
        match name {
            "fog" => self.fog = Some(fog(params)?),
            "atmosphere" => self.atmosphere = Some(atmosphere(params)?),
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
            "color" => {
                let toml::Value::String(text) = value else {
                    return Err((key.clone(), format!("{value} is not a colour (\"#rrggbb\")")));
                };
                // Fog has no opacity of its own: "#rrggbbaa" would be ignored.
                let c = relief_source_ops::parse_color(key, text)
                    .ok()
                    .filter(|_| text.trim_start_matches('#').len() == 6)
                    .ok_or_else(|| (key.clone(), format!("'{text}' is not #rrggbb")))?;
                fog.color = [c[0], c[1], c[2]];
            }
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

/// An option's number, or the option and what it is instead.
fn number(key: &str, value: &toml::Value) -> Result<f64, (String, String)> {
    match value {
        toml::Value::Float(v) => Ok(*v),
        toml::Value::Integer(v) => Ok(*v as f64),
        other => Err((key.to_owned(), format!("{other} is not a number"))),
    }
}
