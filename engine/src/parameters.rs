//! Parameters set by a call (SetSourceParameter): values laid over the
//! manifest's, each checked as the manifest checks it, because the scene is
//! built from the manifest with them in place, by the same code.
//!
//! A parameter is a source's option that does not change which files are
//! read (not `kind`, `path`, `paths`, `inputs` or `layer`), a `[quality]`
//! knob, a `[sun]` field, or an option of a declared effect. Targets are
//! named `SOURCE_ID`, `[quality]`, `[sun]` or `[effects.NAME]`. A value is
//! TOML (`270`, `true`, `[0.8, 1.2]`, `{ conifer = 1.0 }`); text that is
//! not TOML is a string (`#ff0000`, `cubic`). A call's value stays in force
//! over later manifest edits until it is reset (or reliefd restarts); a
//! target the manifest no longer has drops its values.

use std::collections::BTreeMap;

/// What a parameter belongs to.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Target {
    Source(String),
    Quality,
    Sun,
    Effect(String),
}

/// Options of a source that choose what it reads: never set by a call.
const READS: &[&str] = &["id", "kind", "path", "paths", "inputs", "layer"];

impl Target {
    /// The target a request names: `[quality]`, `[sun]`, `[effects.NAME]`
    /// or a source id.
    pub fn parse(text: &str) -> Result<Self, String> {
        match text.trim() {
            "[quality]" => Ok(Self::Quality),
            "[sun]" => Ok(Self::Sun),
            t if t.starts_with("[effects.") && t.ends_with(']') => {
                Ok(Self::Effect(t["[effects.".len()..t.len() - 1].to_owned()))
            }
            t if t.starts_with('[') => Err(format!(
                "'{t}' is not a section a call may set: [quality], [sun] or [effects.NAME] (or a source id)"
            )),
            "" => Err("no source id or section given".into()),
            t => Ok(Self::Source(t.to_owned())),
        }
    }

    pub fn name(&self) -> String {
        match self {
            Self::Source(id) => id.clone(),
            Self::Quality => "[quality]".into(),
            Self::Sun => "[sun]".into(),
            Self::Effect(e) => format!("[effects.{e}]"),
        }
    }

    /// The table of `manifest` this target's values go in; None when the
    /// manifest has no such source or effect.
    fn table<'a>(&self, manifest: &'a mut toml::Table) -> Option<&'a mut toml::Table> {
        let section = |m: &'a mut toml::Table, name: &str| {
            m.entry(name).or_insert_with(|| toml::Value::Table(toml::Table::new())).as_table_mut()
        };
        match self {
            Self::Source(id) => manifest
                .get_mut("source")?
                .as_array_mut()?
                .iter_mut()
                .filter_map(toml::Value::as_table_mut)
                .find(|s| s.get("id").and_then(toml::Value::as_str) == Some(id.as_str())),
            Self::Quality => section(manifest, "quality"),
            Self::Sun => section(manifest, "sun"),
            Self::Effect(name) => manifest.get_mut("effects")?.as_table_mut()?.get_mut(name)?.as_table_mut(),
        }
    }
}

/// A value as a call gives it: TOML, or else a string.
pub fn parse_value(text: &str) -> toml::Value {
    let wrapped = format!("v = {text}");
    match toml::from_str::<toml::Table>(&wrapped) {
        Ok(mut t) => t.remove("v").unwrap_or_else(|| toml::Value::String(text.to_owned())),
        Err(_) => toml::Value::String(text.to_owned()),
    }
}

/// One parameter in force, for the state: its value, and the manifest's
/// (None where the manifest leaves it to its default).
#[derive(Debug, Clone, PartialEq)]
pub struct InForce {
    pub target: String,
    pub name: String,
    pub value: String,
    pub manifest_value: Option<String>,
}

/// The values calls have set, laid over the manifest in this order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides(BTreeMap<(Target, String), toml::Value>);

impl Overrides {
    /// These overrides with `name` of `target` set to `value` (None: reset
    /// to the manifest's), if a call may set it.
    pub fn with(&self, target: Target, name: &str, value: Option<toml::Value>) -> Result<Self, String> {
        if let Target::Source(id) = &target
            && READS.contains(&name)
        {
            return Err(format!(
                "source '{id}', option '{name}': chooses what the source reads, which a call does not change; \
                 edit the manifest"
            ));
        }
        if name.is_empty() {
            return Err(format!("{}: no parameter name given", target.name()));
        }
        let mut next = self.clone();
        match value {
            Some(v) => next.0.insert((target, name.to_owned()), v),
            None => next.0.remove(&(target, name.to_owned())),
        };
        Ok(next)
    }

    /// `manifest` (its TOML) with every value laid over it. Err names a
    /// target the manifest does not have (a call's fault: checked before
    /// it is kept).
    pub fn apply(&self, manifest: &mut toml::Table) -> Result<(), String> {
        for ((target, name), value) in &self.0 {
            let table = target.table(manifest).ok_or_else(|| match target {
                Target::Source(id) => format!("no source has id '{id}'"),
                Target::Effect(e) => {
                    format!("effect '{e}' is not in this scene's [effects]: declare it in the manifest")
                }
                _ => format!("the manifest has no {}", target.name()),
            })?;
            table.insert(name.clone(), value.clone());
        }
        Ok(())
    }

    /// These overrides less those whose target `manifest` no longer has
    /// (a manifest edit removed the source or the effect).
    #[must_use]
    pub fn still_applicable(&self, manifest: &toml::Table) -> Self {
        let mut probe = manifest.clone();
        Self(
            self.0
                .iter()
                .filter(|((t, _), _)| t.table(&mut probe).is_some())
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect(),
        )
    }

    /// What is in force, with the manifest's own values beside.
    pub fn in_force(&self, manifest: &toml::Table) -> Vec<InForce> {
        let mut probe = manifest.clone();
        self.0
            .iter()
            .map(|((target, name), value)| InForce {
                target: target.name(),
                name: name.clone(),
                value: value.to_string(),
                manifest_value: target.table(&mut probe).and_then(|t| t.get(name)).map(ToString::to_string),
            })
            .collect()
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MANIFEST: &str = r#"
[scene]
name = "x"
[[source]]
id = "dem"
kind = "gdal"
path = "dem.tif"
[[source]]
id = "shade"
kind = "hillshade"
inputs = ["dem"]
azimuth_deg = 315
[effects]
fog = { density = 0.0003 }
"#;

    #[test]
    fn values_are_toml_or_else_text() {
        assert_eq!(parse_value("270"), toml::Value::Integer(270));
        assert_eq!(parse_value("0.5"), toml::Value::Float(0.5));
        assert_eq!(parse_value("true"), toml::Value::Boolean(true));
        assert_eq!(parse_value("\"a b\""), toml::Value::String("a b".into()));
        assert_eq!(parse_value("#ff0000"), toml::Value::String("#ff0000".into()));
        assert_eq!(parse_value("cubic"), toml::Value::String("cubic".into()));
        assert!(parse_value("[0.8, 1.2]").is_array());
        assert!(parse_value("{ conifer = 1.0 }").is_table());
    }

    #[test]
    fn targets_are_sources_or_sections() {
        assert_eq!(Target::parse("shade"), Ok(Target::Source("shade".into())));
        assert_eq!(Target::parse("[quality]"), Ok(Target::Quality));
        assert_eq!(Target::parse("[effects.fog]"), Ok(Target::Effect("fog".into())));
        assert!(Target::parse("[cache]").unwrap_err().contains("not a section a call may set"));
    }

    #[test]
    fn values_lie_over_the_manifest_and_reads_are_refused() {
        let manifest: toml::Table = toml::from_str(MANIFEST).unwrap();
        let o = Overrides::default()
            .with(Target::Source("shade".into()), "azimuth_deg", Some(parse_value("270")))
            .unwrap()
            .with(Target::Quality, "resampling", Some(parse_value("cubic")))
            .unwrap()
            .with(Target::Effect("fog".into()), "density", Some(parse_value("0.001")))
            .unwrap();
        let mut laid = manifest.clone();
        o.apply(&mut laid).unwrap();
        assert_eq!(laid["source"][1]["azimuth_deg"], toml::Value::Integer(270));
        assert_eq!(laid["quality"]["resampling"], toml::Value::String("cubic".into()));
        assert_eq!(laid["effects"]["fog"]["density"], toml::Value::Float(0.001));
        let shown = o.in_force(&manifest);
        let shade = shown.iter().find(|p| p.target == "shade").unwrap();
        assert_eq!((shade.value.as_str(), shade.manifest_value.as_deref()), ("270", Some("315")));
        assert!(shown.iter().any(|p| p.target == "[quality]" && p.manifest_value.is_none()));

        let err = o.with(Target::Source("dem".into()), "path", Some(parse_value("\"other.tif\""))).unwrap_err();
        assert!(err.contains("chooses what the source reads"), "{err}");
        let missing = o.with(Target::Effect("water".into()), "level_m", Some(parse_value("3"))).unwrap();
        assert!(missing.apply(&mut manifest.clone()).unwrap_err().contains("effect 'water' is not in this scene"));
        let gone = o.with(Target::Source("old".into()), "x", Some(parse_value("1"))).unwrap();
        assert_eq!(gone.still_applicable(&manifest), o);
        assert!(o.with(Target::Quality, "resampling", None).unwrap().0.len() == 2);
    }
}
