//! The ground under `on_ground` buildings, for their 3D Tiles content:
//! the height layer's tiles read bilinearly, each fetched once.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use relief_source::{Payload, TileKey};

use crate::graph::SceneSnapshot;
use crate::tiles::TileStore;

/// Heights of the ground for `on_ground` buildings: the height layer's
/// tiles at `level` (the content's, or the DEM's own if coarser), read
/// bilinearly, each tile fetched once.
pub(super) struct Ground<'a> {
    pub(super) store: &'a TileStore,
    pub(super) snap: &'a SceneSnapshot,
    pub(super) slot: Option<usize>,
    pub(super) level: u8,
    pub(super) tiles: Mutex<HashMap<TileKey, Option<Arc<Payload>>>>,
}

impl Ground<'_> {
    pub(super) fn height(&self, lon: f64, lat: f64) -> f64 {
        let Some(slot) = self.slot else { return f64::NAN };
        let grid = &self.snap.grid;
        let (gx, gy) = grid.sample_coords(self.level, lon, lat);
        let (x0, y0) = (gx.floor() as i64, gy.floor() as i64);
        let (fx, fy) = (gx - x0 as f64, gy - y0 as f64);
        let sample = |dx: i64, dy: i64| -> f64 {
            let (key, i, j) = grid.corner_sample(self.level, x0 + dx, y0 + dy);
            let mut tiles = self.tiles.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            let tile = tiles.entry(key).or_insert_with(|| {
                let t = self.store.tile(self.snap, slot, key, &self.snap.manifest.quality).ok();
                t.map(|t| Arc::clone(&t.payload))
            });
            match tile.as_deref() {
                Some(Payload::Height(h)) => f64::from(h.get(i, j)),
                _ => f64::NAN,
            }
        };
        let (a, b, c, d) = (sample(0, 0), sample(1, 0), sample(0, 1), sample(1, 1));
        (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy
    }
}
