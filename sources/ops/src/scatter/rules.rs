//! A scatter's rules, one per land-cover class, read from the manifest's
//! `[[source.rule]]` tables and checked whole at open: every refusal names
//! the field (`rule[1].density`) and what is wrong with it.

use std::collections::BTreeMap;

use relief_source::{OptionValue, SourceError};

use super::lattice::JitteredLattice;

/// The densest forest in Amara et al. 2007, instances per km².
pub const MAX_DENSITY_PER_KM2: f64 = 21_000.0;

const RULE_KEYS: &[&str] = &["class", "models", "density", "spacing", "scale", "rotation"];

/// What to place on one class.
#[derive(Debug, Clone, PartialEq)]
pub struct Rule {
    pub class: i64,
    /// Model name and share, shares normalised to sum to 1, by name.
    pub models: Vec<(String, f64)>,
    pub density_per_km2: f64,
    pub spacing_m: f64,
    /// Uniform range of the scale (min, max).
    pub scale: [f64; 2],
    /// Uniform range of the rotation, degrees clockwise from north.
    pub rotation_deg: [f64; 2],
}

impl Rule {
    /// The model for draw `u` in [0, 1): by the cumulative shares.
    pub fn model(&self, u: f64) -> &str {
        let mut total = 0.0;
        for (name, share) in &self.models {
            total += share;
            if u < total {
                return name;
            }
        }
        // `parse_rules` refuses a rule without models; should one come
        // here anyway, it names no model (the renderer skips unknown names).
        self.models.last().map_or("", |(name, _)| name.as_str())
    }

    pub fn scale(&self, u: f64) -> f64 {
        self.scale[0] + u * (self.scale[1] - self.scale[0])
    }

    pub fn rotation_deg(&self, u: f64) -> f64 {
        (self.rotation_deg[0] + u * (self.rotation_deg[1] - self.rotation_deg[0])).rem_euclid(360.0)
    }

    /// One line for the scene state: "311: conifer 70%, broadleaf 30%;
    /// 21000/km², spacing 1.5 m, scale 0.8..1.2, rotation 0..360".
    pub fn summary(&self) -> String {
        let models: Vec<String> =
            self.models.iter().map(|(name, share)| format!("{name} {:.0}%", share * 100.0)).collect();
        format!(
            "{}: {}; {}/km², spacing {} m, scale {}..{}, rotation {}..{}",
            self.class,
            models.join(", "),
            self.density_per_km2,
            self.spacing_m,
            self.scale[0],
            self.scale[1],
            self.rotation_deg[0],
            self.rotation_deg[1]
        )
    }
}

/// A finite number at `field`.
fn number(value: &OptionValue, field: &str) -> Result<f64, SourceError> {
    match value {
        OptionValue::Number(n) if n.is_finite() => Ok(*n),
        OptionValue::Number(n) => Err(SourceError::option(field, format!("{n} is not a finite number"))),
        other => Err(SourceError::option(field, format!("expected a number, found {}", other.kind_name()))),
    }
}

/// A range: `[min, max]`, or one number for both.
fn range(value: &OptionValue, field: &str) -> Result<[f64; 2], SourceError> {
    match value {
        OptionValue::List(items) if items.len() == 2 => {
            let (min, max) = (number(&items[0], &format!("{field}[0]"))?, number(&items[1], &format!("{field}[1]"))?);
            if min > max {
                return Err(SourceError::option(field, format!("min {min} is above max {max}")));
            }
            Ok([min, max])
        }
        OptionValue::List(items) => {
            Err(SourceError::option(field, format!("expected [min, max] or one number, found {} numbers", items.len())))
        }
        other => number(other, field).map(|n| [n, n]),
    }
}

/// Reads and checks every rule. `known_models` are the names a rule may
/// use (stock models and the stems of `paths`).
pub fn parse_rules(rules: &[OptionValue], known_models: &[String]) -> Result<Vec<Rule>, SourceError> {
    let mut out: Vec<Rule> = Vec::with_capacity(rules.len());
    for (n, value) in rules.iter().enumerate() {
        let at = |field: &str| format!("rule[{n}].{field}");
        let OptionValue::Table(table) = value else {
            return Err(SourceError::option(
                format!("rule[{n}]"),
                format!("expected a table ([[source.rule]]), found {}", value.kind_name()),
            ));
        };
        if let Some(unknown) = table.keys().find(|k| !RULE_KEYS.contains(&k.as_str())) {
            return Err(SourceError::option(
                at(unknown),
                format!("unknown key in a rule (known: {})", RULE_KEYS.join(", ")),
            ));
        }
        let required =
            |key: &str| table.get(key).ok_or_else(|| SourceError::option(at(key), format!("every rule needs a {key}")));
        let class = number(required("class")?, &at("class"))?;
        if class.fract() != 0.0 || class.abs() > 2f64.powi(53) {
            return Err(SourceError::option(at("class"), format!("{class} is not an integer class code")));
        }
        let class = class as i64;
        if let Some(other) = out.iter().position(|r| r.class == class) {
            return Err(SourceError::option(at("class"), format!("class {class} has a rule already (rule[{other}])")));
        }
        let density = number(required("density")?, &at("density"))?;
        if density < 0.0 {
            return Err(SourceError::option(at("density"), "a density is 0 or more instances per km²"));
        }
        if density > MAX_DENSITY_PER_KM2 {
            return Err(SourceError::option(
                at("density"),
                format!(
                    "{density} instances per km² is above {MAX_DENSITY_PER_KM2} (the densest forest in Amara et al. 2007)"
                ),
            ));
        }
        let models = models(required("models")?, &at("models"), known_models)?;
        let spacing = table.get("spacing").map(|v| number(v, &at("spacing"))).transpose()?.unwrap_or(0.0);
        if spacing < 0.0 {
            return Err(SourceError::option(at("spacing"), "a spacing is 0 m or more"));
        }
        if let Some(cell) = JitteredLattice::cell_size_m(density)
            && spacing > cell
        {
            return Err(SourceError::option(
                at("spacing"),
                format!(
                    "density {density} per km² leaves at most {cell:.2} m between instances; spacing {spacing} m cannot be kept"
                ),
            ));
        }
        let scale = table.get("scale").map(|v| range(v, &at("scale"))).transpose()?.unwrap_or([1.0, 1.0]);
        if scale[0] <= 0.0 {
            return Err(SourceError::option(at("scale"), "a scale is more than 0"));
        }
        let rotation_deg =
            table.get("rotation").map(|v| range(v, &at("rotation"))).transpose()?.unwrap_or([0.0, 360.0]);
        out.push(Rule { class, models, density_per_km2: density, spacing_m: spacing, scale, rotation_deg });
    }
    Ok(out)
}

/// `models = { name = share, ... }`: known names, positive shares,
/// normalised.
fn models(value: &OptionValue, field: &str, known: &[String]) -> Result<Vec<(String, f64)>, SourceError> {
    let OptionValue::Table(table) = value else {
        return Err(SourceError::option(
            field,
            format!("expected a table of model name = share, found {}", value.kind_name()),
        ));
    };
    if table.is_empty() {
        return Err(SourceError::option(field, "a rule places at least one model"));
    }
    let mut shares: BTreeMap<String, f64> = BTreeMap::new();
    for (name, share) in table {
        let at = format!("{field}.{name}");
        if !known.contains(name) {
            return Err(SourceError::option(at, format!("unknown model '{name}' (known: {})", known.join(", "))));
        }
        let share = number(share, &at)?;
        if share <= 0.0 {
            return Err(SourceError::option(at, format!("a share is more than 0, found {share}")));
        }
        shares.insert(name.clone(), share);
    }
    let total: f64 = shares.values().sum();
    Ok(shares.into_iter().map(|(name, share)| (name, share / total)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn known() -> Vec<String> {
        ["broadleaf", "conifer", "house", "oak", "shrub"].map(String::from).to_vec()
    }

    fn table(entries: &[(&str, OptionValue)]) -> OptionValue {
        OptionValue::Table(entries.iter().map(|(k, v)| ((*k).to_owned(), v.clone())).collect())
    }

    fn num(n: f64) -> OptionValue {
        OptionValue::Number(n)
    }

    fn good() -> Vec<(&'static str, OptionValue)> {
        vec![
            ("class", num(311.0)),
            ("models", table(&[("conifer", num(0.7)), ("broadleaf", num(0.3))])),
            ("density", num(21_000.0)),
            ("spacing", num(1.5)),
            ("scale", OptionValue::List(vec![num(0.8), num(1.2)])),
        ]
    }

    /// The good rule for class 312, with `key` set to `value`.
    fn with(key: &str, value: OptionValue) -> OptionValue {
        let OptionValue::Table(mut rule) = table(&good()) else { unreachable!("table() makes a table") };
        rule.insert("class".to_owned(), num(312.0));
        rule.insert(key.to_owned(), value);
        OptionValue::Table(rule)
    }

    #[test]
    fn a_good_rule_reads_with_defaults_and_normalised_shares() -> Result<(), Box<dyn std::error::Error>> {
        let rules = parse_rules(&[table(&good())], &known())?;
        let r = &rules[0];
        assert_eq!(r.class, 311);
        assert_eq!(r.spacing_m, 1.5);
        assert_eq!(r.scale, [0.8, 1.2]);
        assert_eq!(r.models, vec![("broadleaf".to_owned(), 0.3), ("conifer".to_owned(), 0.7)]);
        assert_eq!(r.rotation_deg, [0.0, 360.0]);
        assert_eq!(r.model(0.29), "broadleaf");
        assert_eq!(r.model(0.31), "conifer");
        assert_eq!(r.model(0.999_999_999), "conifer");
        let one = parse_rules(&[with("scale", num(2.0))], &known())?;
        assert_eq!(one[0].scale, [2.0, 2.0]);
        let shares = parse_rules(&[with("models", table(&[("oak", num(3.0)), ("shrub", num(1.0))]))], &known())?;
        assert_eq!(shares[0].models, vec![("oak".to_owned(), 0.75), ("shrub".to_owned(), 0.25)]);
        Ok(())
    }

    #[test]
    fn every_bad_rule_is_refused_naming_its_field() {
        let second = |rule: OptionValue| vec![table(&good()), rule];
        let cases: Vec<(Vec<OptionValue>, &str, &str)> = vec![
            (second(with("density", num(-1.0))), "rule[1].density", "a density is 0 or more instances per km²"),
            (second(with("density", num(21_001.0))), "rule[1].density", "is above 21000"),
            (second(with("density", num(f64::INFINITY))), "rule[1].density", "not a finite number"),
            (second(with("density", OptionValue::Text("dense".into()))), "rule[1].density", "expected a number"),
            (vec![table(&good()), table(&good())], "rule[1].class", "class 311 has a rule already (rule[0])"),
            (second(with("class", num(311.5))), "rule[1].class", "311.5 is not an integer class code"),
            (
                second(with("models", table(&[("pine", num(1.0))]))),
                "rule[1].models.pine",
                "unknown model 'pine' (known: broadleaf, conifer, house, oak, shrub)",
            ),
            (second(with("models", table(&[("oak", num(0.0))]))), "rule[1].models.oak", "a share is more than 0"),
            (second(with("models", table(&[]))), "rule[1].models", "at least one model"),
            (
                second(with("scale", OptionValue::List(vec![num(1.2), num(0.8)]))),
                "rule[1].scale",
                "min 1.2 is above max 0.8",
            ),
            (second(with("scale", num(0.0))), "rule[1].scale", "a scale is more than 0"),
            (second(with("rotation", OptionValue::List(vec![num(90.0)]))), "rule[1].rotation", "expected [min, max]"),
            (
                second(with("spacing", num(8.0))),
                "rule[1].spacing",
                "density 21000 per km² leaves at most 6.90 m between instances; spacing 8 m cannot be kept",
            ),
            (second(with("spacing", num(-1.0))), "rule[1].spacing", "0 m or more"),
            (second(with("colour", num(1.0))), "rule[1].colour", "unknown key in a rule (known: class, models"),
            (second(num(3.0)), "rule[1]", "expected a table"),
        ];
        for (rules, field, message) in cases {
            let err = parse_rules(&rules, &known()).unwrap_err();
            let SourceError::InvalidOption { field: f, message: m } = &err else { panic!("{err}") };
            assert_eq!(f, field, "{err}");
            assert!(m.contains(message), "{m:?} should contain {message:?}");
        }
        let mut no_class = good();
        no_class.remove(0);
        let err = parse_rules(&[table(&no_class)], &known()).unwrap_err().to_string();
        assert!(err.contains("rule[0].class") && err.contains("needs a class"), "{err}");
    }
}
