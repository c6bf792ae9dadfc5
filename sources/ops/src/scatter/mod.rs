//! `scatter`: vegetation amplification (Amara et al. 2007; Savelli et al.).
//! Instances of models are placed on the fly from a classified land-cover
//! raster, one rule per class (models and their shares, density, spacing,
//! scale and rotation ranges), deterministically per seed, and anchored on
//! the ground; an optional density raster thins each rule, and an optional
//! point layer adds instances where the user put them.
//!
//! Inputs: `[classes, ground, density?, points?]`. The extra inputs are
//! taken in that order unless `density_input` / `points_input` name them.
//!
//! Every tile reads its inputs at one fixed level (`level`), never its
//! own, and takes its candidates from a global lattice (`lattice.rs`): the
//! same inputs and seed give the same instances in a tile whatever the
//! order tiles are asked in, and a tile holds exactly the union of its
//! children's instances.

mod counts;
mod lattice;
mod place;
mod rules;
#[cfg(test)]
mod tests;

use std::sync::{Arc, OnceLock};

use relief_source::{
    DirtySet, Extent, GenerateContext, Payload, PayloadKind, Refresh, Source, SourceError, SourceInfo, SourceSpec,
    TileGrid, TileKey,
};

use self::counts::Counts;
use self::lattice::{JitteredLattice, hash, offsets};
use self::rules::{Rule, parse_rules};
use crate::models::{ModelFile, STOCK_MODELS, known_models, reopen_changed};

pub const SCATTER_KIND: &str = "scatter";
/// By position, when `density_input` and `points_input` are not given: the
/// class raster, the ground, a density raster, a point layer. The first two
/// are required; see [`scatter_input_kinds`] for a given declaration.
pub const SCATTER_INPUTS: &[PayloadKind] =
    &[PayloadKind::Height, PayloadKind::Height, PayloadKind::Height, PayloadKind::Features];

/// The default `level` is the first whose tile is at most this wide (at the
/// equator on the geodetic grid: level 14, 1.22 km).
const DEFAULT_TILE_SPAN_M: f64 = 2000.0;
/// Tiles this many levels coarser than `level` are the coarsest built: a
/// tile holds the instances of 4^3 = 64 tiles of `level` (up to about two
/// million at the default level and the highest density).
const COARSER_LEVELS: u8 = 3;
/// Metres per degree along the equator.
const EQUATOR_M_PER_DEG: f64 = relief_source::geodesy::WGS84_A * std::f64::consts::PI / 180.0;
/// Samples of `level` an input's dirt may already reach beyond its changed
/// area (a gdal source's kernel margin), added to the scatter's own reach.
const INPUT_MARGIN_SAMPLES: f64 = 4.0;

const OPTIONS: &[&str] = &["rule", "seed", "level", "anchor_radius", "density_input", "points_input"];

/// Which input is which.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Roles {
    density: Option<usize>,
    points: Option<usize>,
}

impl Roles {
    /// Reads `density_input` and `points_input`; extra inputs not named
    /// fill the roles left, density first.
    fn of(spec: &SourceSpec) -> Result<Self, SourceError> {
        if !(2..=4).contains(&spec.inputs.len()) {
            return Err(SourceError::option(
                "inputs",
                format!(
                    "scatter takes inputs = [classes, ground], then optionally a density raster and a point layer; got {}",
                    spec.inputs.len()
                ),
            ));
        }
        let extra = &spec.inputs[2..];
        let named = |option: &str| -> Result<Option<usize>, SourceError> {
            let Some(id) = spec.text(option)? else { return Ok(None) };
            match extra.iter().position(|input| input == id) {
                Some(n) => Ok(Some(n + 2)),
                None => Err(SourceError::option(
                    option,
                    format!(
                        "'{id}' is not one of the inputs after the class raster and the ground (those are: [{}])",
                        extra.join(", ")
                    ),
                )),
            }
        };
        let (density, points) = (named("density_input")?, named("points_input")?);
        if density.is_some() && density == points {
            return Err(SourceError::option("points_input", "the density input and the points input are one source"));
        }
        let mut free = (2..spec.inputs.len()).filter(|n| Some(*n) != density && Some(*n) != points);
        let density = density.or_else(|| free.next());
        let points = points.or_else(|| free.next());
        if let Some(n) = free.next() {
            return Err(SourceError::option(
                "inputs",
                format!("'{}' is neither the density input nor the points input", spec.inputs[n]),
            ));
        }
        Ok(Self { density, points })
    }
}

/// The payload each input of `spec` must have, in order: the graph checks
/// a scatter's inputs with this (a third input is a density raster or a
/// point layer, as the options say).
pub fn scatter_input_kinds(spec: &SourceSpec) -> Vec<PayloadKind> {
    let n = spec.inputs.len().min(SCATTER_INPUTS.len());
    match Roles::of(spec) {
        Ok(roles) => (0..spec.inputs.len())
            .map(|i| if Some(i) == roles.points { PayloadKind::Features } else { PayloadKind::Height })
            .collect(),
        // Open refuses the declaration and says why; check by position meanwhile.
        Err(_) => SCATTER_INPUTS[..n].to_vec(),
    }
}

#[derive(Debug, Clone)]
pub struct Scatter {
    id: String,
    inputs: Vec<String>,
    roles: Roles,
    /// By class.
    rules: Vec<Rule>,
    /// Each rule's lattice; None for a density of 0.
    lattices: Vec<Option<JitteredLattice>>,
    seed: u64,
    /// `level`; None: the default for the grid (see `level`).
    level: Option<u8>,
    anchor_radius_m: f64,
    models: Vec<ModelFile>,
    known_models: Vec<String>,
    /// The grid tiles are built in: the one given at open on the geodetic
    /// grid, the first one a tile is built in otherwise (a projected grid's
    /// extent is only known once the scene is built).
    grid: OnceLock<TileGrid>,
    counts: Counts,
}

impl Scatter {
    pub fn open(spec: &SourceSpec, grid: &TileGrid) -> Result<Self, SourceError> {
        spec.only_options(OPTIONS)?;
        let roles = Roles::of(spec)?;
        let models = ModelFile::open_all(&spec.paths, &spec.id)?;
        let known = known_models(&models);
        let rule_list = spec
            .list("rule")?
            .filter(|rules| !rules.is_empty())
            .ok_or_else(|| SourceError::option("rule", "scatter needs at least one [[source.rule]]"))?;
        let mut rules = parse_rules(rule_list, &known)?;
        rules.sort_by_key(|r| r.class);
        let seed = match spec.number("seed")? {
            None => 0,
            Some(s) if s >= 0.0 && s.fract() == 0.0 && s <= 2f64.powi(53) => s as u64,
            Some(s) => return Err(SourceError::option("seed", format!("{s} is not a whole number from 0 to 2^53"))),
        };
        let level = match spec.number("level")? {
            None => None,
            Some(l) if (0.0..=f64::from(relief_source::MAX_LEVEL)).contains(&l) && l.fract() == 0.0 => Some(l as u8),
            Some(l) => return Err(SourceError::option("level", format!("{l} is not a level of the grid"))),
        };
        let anchor_radius_m = spec.number("anchor_radius")?.unwrap_or(0.5);
        if anchor_radius_m < 0.0 {
            return Err(SourceError::option("anchor_radius", "an anchor radius is 0 m or more"));
        }
        let lattices = rules
            .iter()
            .map(|r| {
                JitteredLattice::cell_size_m(r.density_per_km2).map(|cell_m| JitteredLattice {
                    cell_m,
                    spacing_m: r.spacing_m,
                    key: hash(&[seed, r.class as u64]),
                })
            })
            .collect();
        let known_grid = OnceLock::new();
        if grid.is_geodetic() {
            let _ = known_grid.set(grid.clone());
        }
        Ok(Self {
            id: spec.id.clone(),
            inputs: spec.inputs.clone(),
            roles,
            rules,
            lattices,
            seed,
            level,
            anchor_radius_m,
            models,
            known_models: known,
            grid: known_grid,
            counts: Counts::default(),
        })
    }

    /// The level every input is read at: `level`, else the first level
    /// whose tile is at most 2 km across (at the equator on the geodetic
    /// grid; in grid units, taken as metres, on a projected one).
    fn level(&self, grid: &TileGrid) -> u8 {
        self.level.unwrap_or_else(|| default_level(grid))
    }

    fn rule_of(&self, class: i64) -> Option<&Rule> {
        self.rules.binary_search_by_key(&class, |r| r.class).ok().map(|i| &self.rules[i])
    }

    /// How far an instance's placement reads the ground from its
    /// position: the largest footprint radius, metres.
    fn reach_m(&self) -> f64 {
        let scale = self.rules.iter().map(|r| r.scale[1]).fold(1.0, f64::max);
        self.anchor_radius_m * scale
    }
}

/// The first level whose tile is at most `DEFAULT_TILE_SPAN_M` across.
pub fn default_level(grid: &TileGrid) -> u8 {
    let m_per_unit = if grid.is_geodetic() { EQUATOR_M_PER_DEG } else { 1.0 };
    (0..=relief_source::MAX_LEVEL)
        .find(|l| grid.tile_span(*l).0 * m_per_unit <= DEFAULT_TILE_SPAN_M)
        .unwrap_or(relief_source::MAX_LEVEL)
}

impl Source for Scatter {
    fn id(&self) -> &str {
        &self.id
    }

    fn kind(&self) -> &'static str {
        SCATTER_KIND
    }

    fn output(&self) -> PayloadKind {
        PayloadKind::Instances
    }

    fn inputs(&self) -> &[String] {
        &self.inputs
    }

    fn info(&self) -> SourceInfo {
        let mut info = SourceInfo::default();
        let d = &mut info.details;
        d.insert("seed".into(), self.seed.to_string());
        let default = "default: the first level whose tile is at most 2 km across";
        let level = match (self.level, self.grid.get()) {
            (Some(l), _) => {
                d.insert("level".into(), l.to_string());
                Some(l)
            }
            (None, Some(grid)) => {
                let l = default_level(grid);
                d.insert("level".into(), format!("{l} ({default})"));
                Some(l)
            }
            (None, None) => {
                d.insert("level".into(), default.into());
                None
            }
        };
        if let Some(l) = level {
            d.insert(
                "coarsest_level".into(),
                format!(
                    "{} (coarser tiles would hold too many instances and are refused)",
                    l.saturating_sub(COARSER_LEVELS)
                ),
            );
        }
        d.insert("anchor_radius_m".into(), self.anchor_radius_m.to_string());
        d.insert("rules".into(), self.rules.iter().map(Rule::summary).collect::<Vec<_>>().join("; "));
        let files: Vec<String> = self.models.iter().map(|m| format!("{} ({})", m.name, m.path.display())).collect();
        d.insert(
            "models".into(),
            format!(
                "stock: {}; files: {}",
                STOCK_MODELS.join(", "),
                if files.is_empty() { "none".into() } else { files.join(", ") }
            ),
        );
        let input = |n: Option<usize>| n.map_or_else(|| "none".to_owned(), |n| self.inputs[n].clone());
        d.insert("classes_input".into(), self.inputs[0].clone());
        d.insert("ground_input".into(), self.inputs[1].clone());
        d.insert("density_input".into(), input(self.roles.density));
        d.insert("points_input".into(), input(self.roles.points));
        d.insert(
            "counts".into(),
            format!("class counts cover the {} tiles of the scatter's level built so far", self.counts.tiles()),
        );
        let ruled: Vec<i64> = self.rules.iter().map(|r| r.class).collect();
        info.classes = self.counts.classes(&ruled);
        info.files = self.models.iter().flat_map(ModelFile::files).collect();
        info
    }

    fn generate(&self, key: TileKey, ctx: &GenerateContext<'_>) -> Result<Payload, SourceError> {
        self.build(key, ctx).map(Payload::Instances)
    }

    /// A model file that changed dirties everything; one that is gone or
    /// unreadable is an error naming it (the last good version stays).
    fn refresh(&self, _grid: &TileGrid) -> Result<Refresh, SourceError> {
        let Some(models) = reopen_changed(&self.models, &self.id)? else {
            return Ok(Refresh::Unchanged);
        };
        // Instances do not move when a model file changes: counts carry over.
        Ok(Refresh::Changed { source: Arc::new(Self { models, ..self.clone() }), dirty: DirtySet::everything() })
    }

    /// Dirt on any input reaches the instances whose class sample, density,
    /// footprint or point lie in it: the dirt grown by the largest
    /// footprint and a few samples of the scatter's level.
    fn dirty_from_input(&self, _input: usize, dirt: &DirtySet) -> DirtySet {
        if dirt.is_none() || dirt.is_everything() {
            return dirt.clone();
        }
        let Some(grid) = self.grid.get() else {
            // No tile built yet on a projected grid: its extent is not known here.
            return DirtySet::everything();
        };
        let step = grid.sample_step(self.level(grid)) * (1.0 + INPUT_MARGIN_SAMPLES);
        let reach_m = self.reach_m();
        let mut grown = Vec::new();
        for e in dirt.extents(grid) {
            // Degrees of longitude are widest at the latitude nearest a
            // pole, degrees of latitude at the equator.
            let (east, _) = offsets(grid, e.min_y.abs().max(e.max_y.abs()), reach_m);
            let (_, north) = offsets(grid, 0.0, reach_m);
            let mut d = e.dilate(east + step, north + step);
            if grid.is_geodetic() {
                // A footprint over a pole reads the far side; one over the
                // antimeridian the other end of the grid.
                if d.max_y >= 90.0 || d.min_y <= -90.0 || d.width() >= 360.0 {
                    d = Extent::new(-180.0, d.min_y, 180.0, d.max_y);
                }
                if d.max_x > 180.0 {
                    grown.push(Extent::new(-180.0, d.min_y, d.max_x - 360.0, d.max_y));
                }
                if d.min_x < -180.0 {
                    grown.push(Extent::new(d.min_x + 360.0, d.min_y, 180.0, d.max_y));
                }
            }
            grown.push(d);
        }
        dirt.union(&DirtySet::from_extents(grown))
    }
}
