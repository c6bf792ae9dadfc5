//! One layer's tiles from the tile store, for every kind of scene tile.

use std::sync::Arc;

use relief_source::{Payload, Quality, TileKey};

use crate::graph::SceneSnapshot;
use crate::tiles::TileStore;

/// Tiles `keys` of source `index`, built when needed; None for one that
/// is not ready (every frame asks again: the source's own error is in the
/// scene state, so it is logged at debug only).
pub fn layer_tiles(
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
