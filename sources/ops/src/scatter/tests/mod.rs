//! Tests of the scatter op against analytic inputs: rasters computed from
//! closures at each sample's position, point layers held in memory.

mod density;
mod determinism;
mod placement;
mod state;

use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex};

use relief_source::{
    Feature, FeatureTile, GenerateContext, Geometry, GridKind, HeightTile, InputTiles, Instance, InstanceTile,
    OptionValue, Payload, ProjectedGrid, Quality, SampleKind, Source, SourceError, SourceSpec, TileGrid, TileKey,
};

use super::Scatter;

/// A raster as a function of a sample's position (grid CRS).
pub type Field = Box<dyn Fn(f64, f64) -> f32 + Send + Sync>;

pub enum Input {
    Raster(Field),
    Points(Vec<Feature>),
}

/// A scene of analytic inputs: serves their tiles to a scatter (cached,
/// as the daemon's store would).
pub struct Scene {
    pub grid: TileGrid,
    pub inputs: Vec<Input>,
    quality: Quality,
    cache: Mutex<HashMap<(usize, TileKey), Arc<Payload>>>,
}

impl InputTiles for Scene {
    fn tile(&self, input: usize, key: TileKey) -> Result<Arc<Payload>, SourceError> {
        if let Some(t) = self.cache.lock().unwrap().get(&(input, key)) {
            return Ok(Arc::clone(t));
        }
        let payload = match &self.inputs[input] {
            Input::Raster(f) => {
                let l = self.grid.lattice(key, SampleKind::Corner);
                let heights =
                    (0..l.rows).flat_map(|j| (0..l.cols).map(move |i| (i, j))).map(|(i, j)| f(l.x(i), l.y(j)));
                Payload::Height(HeightTile { size: l.cols, heights: heights.collect() })
            }
            Input::Points(features) => Payload::Features(FeatureTile { features: features.clone() }),
        };
        let payload = Arc::new(payload);
        self.cache.lock().unwrap().insert((input, key), Arc::clone(&payload));
        Ok(payload)
    }
}

impl Scene {
    pub fn new(grid: TileGrid, inputs: Vec<Input>) -> Self {
        Self { grid, inputs, quality: Quality::default(), cache: Mutex::default() }
    }

    pub fn ctx(&self) -> GenerateContext<'_> {
        GenerateContext { grid: &self.grid, quality: &self.quality, inputs: self }
    }

    pub fn try_tile(&self, source: &Scatter, key: TileKey) -> Result<InstanceTile, SourceError> {
        match source.generate(key, &self.ctx())? {
            Payload::Instances(t) => Ok(t),
            other => panic!("scatter gave a {} tile", other.kind()),
        }
    }

    pub fn tile(&self, source: &Scatter, key: TileKey) -> InstanceTile {
        self.try_tile(source, key).unwrap_or_else(|e| panic!("tile {key}: {e}"))
    }

    /// Every instance of the tiles, checking that no feature id repeats.
    pub fn instances(&self, source: &Scatter, keys: &[TileKey]) -> Vec<Instance> {
        let all: Vec<Instance> = keys.iter().flat_map(|k| self.tile(source, *k).instances).collect();
        let mut ids: Vec<u64> = all.iter().map(|i| i.feature_id).filter(|id| id >> 63 == 1).collect();
        let n = ids.len();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), n, "an instance is in two tiles");
        all
    }
}

/// A 65.536 km square local grid in metres, tiles of 64 samples: level 6
/// (1024 m tiles, 16 m samples) is the scatter's default level there.
pub fn projected() -> TileGrid {
    let p = ProjectedGrid { crs: "EPSG:32632".into(), min_x: 0.0, min_y: 0.0, size: 65_536.0 };
    TileGrid::new(GridKind::Projected(p), 64).unwrap()
}

pub fn geodetic() -> TileGrid {
    TileGrid::geodetic(64).unwrap()
}

pub fn num(n: f64) -> OptionValue {
    OptionValue::Number(n)
}

pub fn text(s: &str) -> OptionValue {
    OptionValue::Text(s.into())
}

pub fn list(items: &[f64]) -> OptionValue {
    OptionValue::List(items.iter().map(|n| num(*n)).collect())
}

pub fn table(entries: &[(&str, OptionValue)]) -> OptionValue {
    OptionValue::Table(entries.iter().map(|(k, v)| ((*k).to_owned(), v.clone())).collect())
}

/// A rule: class, one model (share 1), density, and any other keys.
pub fn rule(class: i64, model: &str, density: f64, more: &[(&str, OptionValue)]) -> OptionValue {
    let mut entries =
        vec![("class", num(class as f64)), ("models", table(&[(model, num(1.0))])), ("density", num(density))];
    entries.extend(more.iter().cloned());
    table(&entries)
}

/// A scatter declaration named "forest" over `inputs`, with `rules` and
/// other options.
pub fn spec(inputs: &[&str], rules: Vec<OptionValue>, options: &[(&str, OptionValue)]) -> SourceSpec {
    let mut map: BTreeMap<String, OptionValue> = options.iter().map(|(k, v)| ((*k).to_owned(), v.clone())).collect();
    map.insert("rule".into(), OptionValue::List(rules));
    SourceSpec {
        id: "forest".into(),
        kind: super::SCATTER_KIND.into(),
        inputs: inputs.iter().map(|s| (*s).to_owned()).collect(),
        options: map,
        ..SourceSpec::default()
    }
}

pub fn open(spec: &SourceSpec, grid: &TileGrid) -> Scatter {
    Scatter::open(spec, grid).unwrap_or_else(|e| panic!("{e}"))
}

/// The tiles of `level` from (x0, y0), `cols` x `rows` of them.
pub fn block(level: u8, x0: u32, y0: u32, cols: u32, rows: u32) -> Vec<TileKey> {
    (y0..y0 + rows).flat_map(|y| (x0..x0 + cols).map(move |x| TileKey::new(level, x, y))).collect()
}

/// Instances as a set: sorted by feature id, then position.
pub fn sorted(mut instances: Vec<Instance>) -> Vec<Instance> {
    instances.sort_by(|a, b| a.feature_id.cmp(&b.feature_id).then(a.position[0].total_cmp(&b.position[0])));
    instances
}

/// A flat ground at 100 m.
pub fn flat() -> Input {
    Input::Raster(Box::new(|_, _| 100.0))
}

/// The same class everywhere.
pub fn uniform(class: f32) -> Input {
    Input::Raster(Box::new(move |_, _| class))
}

/// A point feature.
pub fn point(id: u64, x: f64, y: f64, properties: &[(&str, &str)]) -> Feature {
    Feature {
        id,
        geometry: Geometry::Points(vec![[x, y, f64::NAN]]),
        properties: properties.iter().map(|(k, v)| ((*k).to_owned(), (*v).to_owned())).collect(),
    }
}
