//! The scene's tiles as the renderer asks for them, each answered from the
//! tile store (built in parallel when missing): terrain samples from the
//! height and colour layers (`terrain.rs`), building meshes from the
//! `buildings` layer (`buildings.rs`), instances and their models from the
//! `instances` layer (`instances.rs`).

mod buildings;
mod instances;
mod terrain;

use std::sync::Arc;

pub use buildings::SceneBuildings;
pub use instances::{ModelCache, SceneInstances};
use relief_source::{Payload, Quality, TileKey};
pub use terrain::SceneTerrain;

use crate::graph::SceneSnapshot;
use crate::tiles::TileStore;

/// Tiles `keys` of source `index`, built when needed; None for one that
/// is not ready (every frame asks again: the source's own error is in the
/// scene state, so it is logged at debug only).
fn layer_tiles(
    store: &TileStore,
    snap: &SceneSnapshot,
    quality: &Quality,
    index: usize,
    keys: &[TileKey],
) -> Vec<Option<Arc<Payload>>> {
    let requests: Vec<(usize, TileKey)> = keys.iter().map(|&k| (index, k)).collect();
    store
        .build(snap, &requests, quality)
        .into_iter()
        .zip(keys)
        .map(|(tile, key)| match tile {
            Ok(t) => Some(Arc::clone(&t.payload)),
            Err(e) => {
                let id = &snap.slots[index].spec.id;
                tracing::debug!(source = %id, level = key.level, x = key.x, y = key.y, error = %e, "a layer's tile is not ready");
                None
            }
        })
        .collect()
}
