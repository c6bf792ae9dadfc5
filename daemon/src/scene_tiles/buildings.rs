//! Building meshes from the `buildings` layer.

use std::sync::Arc;

use relief_renderer::MeshTiles;
use relief_source::{Payload, Quality, TileKey};

use crate::graph::SceneSnapshot;
use crate::tiles::TileStore;

/// The `buildings` layer's mesh tiles.
pub struct SceneBuildings<'a> {
    store: &'a TileStore,
    snap: &'a SceneSnapshot,
    quality: Quality,
    index: usize,
    min_level: u8,
}

impl<'a> SceneBuildings<'a> {
    /// None when the scene has no `buildings` layer (or its source is not
    /// loaded): then no buildings pass is built.
    pub fn new(store: &'a TileStore, snap: &'a SceneSnapshot, quality: Quality) -> Option<Self> {
        let index = snap.layer_index("buildings")?;
        let source = snap.slots[index].source.as_ref()?;
        Some(Self { store, snap, quality, index, min_level: building_min_level(&source.info()) })
    }
}

/// The coarsest level a building source makes meshes at (`min_level`).
pub fn building_min_level(info: &relief_source::SourceInfo) -> u8 {
    info.details.get("min_level").and_then(|l| l.parse().ok()).unwrap_or(0)
}

impl MeshTiles for SceneBuildings<'_> {
    fn min_level(&self) -> u8 {
        self.min_level
    }

    fn meshes(&self, keys: &[TileKey]) -> Vec<Option<Arc<Payload>>> {
        super::layer::layer_tiles(self.store, self.snap, &self.quality, self.index, keys)
    }
}
