//! Terrain samples from the height and colour layers.

use std::collections::HashMap;
use std::ops::Range;
use std::sync::Arc;

use relief_renderer::{TerrainSamples, WaterSamples};
use relief_source::{Payload, Quality, TileKey};

use crate::graph::SceneSnapshot;
use crate::tiles::TileStore;

/// The scene's tiles as the renderer asks for them.
pub struct SceneTerrain<'a> {
    store: &'a TileStore,
    snap: &'a SceneSnapshot,
    quality: Quality,
    height: Option<usize>,
    color: Option<usize>,
    /// The water layer: read only when the renderer draws water.
    water: Option<usize>,
    max_level: u8,
}

impl<'a> SceneTerrain<'a> {
    pub fn new(store: &'a TileStore, snap: &'a SceneSnapshot, quality: Quality) -> Self {
        let layer = |name: &str| snap.layer_index(name);
        let height = layer("height");
        // Refine down to the finest data's own sample spacing (heights or
        // imagery: colour is stored per vertex, so a fine orthophoto over a
        // coarse DEM needs the finer levels too), one level past.
        let resolution = [height, layer("color")]
            .into_iter()
            .flatten()
            .filter_map(|i| snap.slots[i].source.as_ref().and_then(|s| s.info().resolution))
            .reduce(f64::min);
        let max_level =
            resolution.map_or(12, |r| (snap.grid.level_for_spacing(r).min(20) + 1).min(relief_source::MAX_LEVEL - 1));
        Self { store, snap, quality, height, color: layer("color"), water: layer("water"), max_level }
    }
}

impl SceneTerrain<'_> {
    /// The tile level whose samples are the height layer's own (its data's
    /// spacing), or None without one.
    pub fn height_level(&self) -> Option<u8> {
        let r = self.snap.slots[self.height?].source.as_ref()?.info().resolution?;
        Some(self.snap.grid.level_for_spacing(r))
    }

    /// The corner sample of `level` nearest the middle of the height
    /// layer's data; None without one.
    pub fn data_centre(&self, level: u8) -> Option<(i64, i64)> {
        let e = self.snap.slots[self.height?].source.as_ref()?.info().extent?;
        let (x, y) =
            self.snap.grid.sample_coords(level, f64::midpoint(e.min_x, e.max_x), f64::midpoint(e.min_y, e.max_y));
        Some((x.round() as i64, y.round() as i64))
    }

    /// One value per corner sample of the block from source `index`'s tiles
    /// (`default` without that layer), the tiles built in parallel first.
    fn read<T: Copy>(
        &self,
        index: Option<usize>,
        level: u8,
        xs: Range<i64>,
        ys: Range<i64>,
        default: T,
        value: impl Fn(&Payload, usize, usize) -> Option<T>,
    ) -> Option<Vec<T>> {
        let count = ((xs.end - xs.start) * (ys.end - ys.start)).max(0) as usize;
        let Some(index) = index else { return Some(vec![default; count]) };
        let grid = &self.snap.grid;
        let n = i64::from(grid.tile_size());
        // The tiles the block spans: every tile-size step across it and its
        // last sample, each with its south-east neighbour, wrapped like the
        // samples.
        let mut keys = std::collections::BTreeSet::new();
        let step = |r: &Range<i64>| (r.start..r.end).step_by(n as usize).chain(std::iter::once(r.end - 1));
        for gy in step(&ys) {
            for gx in step(&xs) {
                keys.insert(grid.corner_sample(level, gx, gy).0);
                keys.insert(grid.corner_sample(level, gx + 1, gy + 1).0);
            }
        }
        let requests: Vec<(usize, TileKey)> = keys.iter().map(|&k| (index, k)).collect();
        let mut tiles: HashMap<TileKey, Arc<Payload>> = HashMap::new();
        for ((_, key), tile) in requests.iter().zip(self.store.build(self.snap, &requests, &self.quality)) {
            match tile {
                Ok(t) => {
                    tiles.insert(*key, Arc::clone(&t.payload));
                }
                Err(e) => {
                    tracing::warn!(level, error = %e, "terrain for the renderer is not ready");
                    return None;
                }
            }
        }
        let mut out = Vec::with_capacity(count);
        for gy in ys {
            for gx in xs.clone() {
                let (key, i, j) = grid.corner_sample(level, gx, gy);
                out.push(tiles.get(&key).and_then(|t| value(t, i, j)).unwrap_or(default));
            }
        }
        Some(out)
    }
}

impl TerrainSamples for SceneTerrain<'_> {
    fn heights(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<f32>> {
        self.read(self.height, level, xs, ys, 0.0, |tile, i, j| match tile {
            Payload::Height(t) => Some(t.get(i, j)),
            _ => None,
        })
    }

    /// A corner sits between four texel centres (colour tiles have a
    /// one-texel border): their mean, weighted by alpha (the mean of the
    /// premultiplied colours, handed on straight), so a texel beside a
    /// transparent one keeps its colour and only its coverage halves.
    fn colors(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<[u8; 4]>> {
        self.read(self.color, level, xs, ys, [0; 4], |tile, i, j| match tile {
            Payload::Color(t) => {
                let (mut rgb, mut alpha) = ([0u32; 3], 0u32);
                for (di, dj) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let o = ((j + dj) * t.size + i + di) * 4;
                    let a = u32::from(t.rgba[o + 3]);
                    for (total, v) in rgb.iter_mut().zip(&t.rgba[o..o + 3]) {
                        *total += u32::from(*v) * a;
                    }
                    alpha += a;
                }
                if alpha == 0 {
                    return Some([0; 4]);
                }
                let [r, g, b] = rgb.map(|v| ((v + alpha / 2) / alpha) as u8);
                Some([r, g, b, ((alpha + 2) / 4) as u8])
            }
            _ => None,
        })
    }

    fn max_level(&self) -> u8 {
        self.max_level
    }
}

/// The water layer's coverage: a colour tile's alpha (the mean of the four
/// texels round the corner, as colours), or a raster's value above 0.5
/// (nodata is dry).
impl WaterSamples for SceneTerrain<'_> {
    fn coverage(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<u8>> {
        self.read(self.water, level, xs, ys, 0, |tile, i, j| match tile {
            Payload::Color(t) => {
                let alpha = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .map(|(di, dj)| u32::from(t.rgba[((j + dj) * t.size + i + di) * 4 + 3]))
                    .sum::<u32>();
                Some(((alpha + 2) / 4) as u8)
            }
            Payload::Height(t) => Some(if t.get(i, j) > 0.5 { 255 } else { 0 }),
            _ => None,
        })
    }

    fn finest_level(&self) -> u8 {
        self.max_level
    }
}
