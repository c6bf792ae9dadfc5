//! The ground under `on_ground` buildings, for their 3D Tiles content: the
//! height layer's tiles from the tile store as an op's input, for
//! `relief_source_ops::HeightWindow` (bilinear, across tile edges).

use std::sync::Arc;

use relief_source::{InputTiles, Payload, SourceError, TileKey};

use crate::graph::SceneSnapshot;
use crate::tiles::TileStore;

/// The height layer's tiles as the one input of a window.
pub(super) struct HeightLayer<'a> {
    pub(super) store: &'a TileStore,
    pub(super) snap: &'a SceneSnapshot,
    pub(super) slot: usize,
}

impl InputTiles for HeightLayer<'_> {
    fn tile(&self, _input: usize, key: TileKey) -> Result<Arc<Payload>, SourceError> {
        let tile = self.store.tile(self.snap, self.slot, key, &self.snap.manifest.quality).map_err(|e| {
            SourceError::Input { input: self.snap.slots[self.slot].spec.id.clone(), message: e.to_string() }
        })?;
        Ok(Arc::clone(&tile.payload))
    }
}
