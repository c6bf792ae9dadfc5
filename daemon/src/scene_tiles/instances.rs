//! Instances from the `instances` layer, and the models they name: the
//! stock models, or the glTF files the layer's source lists.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};

use relief_models::Model;
use relief_renderer::InstanceTiles;
use relief_source::{Payload, Quality, TileKey};

use crate::graph::SceneSnapshot;
use crate::tiles::TileStore;

/// Models read once: the stock ones, and each file once per version of
/// the source that lists it (an edited model file is a new version).
#[derive(Default)]
pub struct ModelCache {
    stock: OnceLock<HashMap<&'static str, Arc<Model>>>,
    files: Mutex<HashMap<(PathBuf, u64), Arc<Model>>>,
}

impl ModelCache {
    fn stock(&self, name: &str) -> Option<Arc<Model>> {
        let stock = self.stock.get_or_init(|| {
            relief_models::STOCK
                .iter()
                .filter_map(|&name| relief_models::stock(name).map(|m| (name, Arc::new(m))))
                .collect()
        });
        stock.get(name).cloned()
    }

    fn file(&self, path: &Path, version: u64) -> Option<Arc<Model>> {
        let key = (path.to_path_buf(), version);
        let mut files = self.files.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(model) = files.get(&key) {
            return Some(Arc::clone(model));
        }
        match relief_models::load(path) {
            Ok(model) => {
                // Older versions of this file are let go.
                files.retain(|(p, _), _| p != path);
                let model = Arc::new(model);
                files.insert(key, Arc::clone(&model));
                Some(model)
            }
            Err(e) => {
                // The source checks its models when it loads and refreshes:
                // its error is in the scene state.
                tracing::warn!(error = %e, "a model is not drawn");
                None
            }
        }
    }
}

/// The `instances` layer's tiles and models.
pub struct SceneInstances<'a> {
    store: &'a TileStore,
    snap: &'a SceneSnapshot,
    quality: Quality,
    index: usize,
    level: u8,
    /// The source's model files by name (file stem).
    files: HashMap<String, PathBuf>,
    models: &'a ModelCache,
}

impl<'a> SceneInstances<'a> {
    /// None when the scene has no `instances` layer (or its source is not
    /// loaded): then no instances pass is built.
    pub fn new(
        store: &'a TileStore,
        snap: &'a SceneSnapshot,
        quality: Quality,
        models: &'a ModelCache,
    ) -> Option<Self> {
        let index = snap.layer_index("instances")?;
        let info = snap.slots[index].source.as_ref()?.info();
        let level = instance_level(&info, &snap.grid);
        let files = info
            .files
            .iter()
            .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf")))
            .filter_map(|p| Some((p.file_stem()?.to_str()?.to_owned(), p.clone())))
            .collect();
        Some(Self { store, snap, quality, index, level, files, models })
    }
}

/// The level an instance source places its instances at: its own
/// ("15", or "14 (default: ...)"); else the level scatter would choose for
/// this grid (tiles about 2 km across).
pub fn instance_level(info: &relief_source::SourceInfo, grid: &relief_source::TileGrid) -> u8 {
    info.details
        .get("level")
        .and_then(|l| l.split_whitespace().next()?.parse().ok())
        .unwrap_or_else(|| relief_source_ops::scatter_default_level(grid))
}

impl InstanceTiles for SceneInstances<'_> {
    fn level(&self) -> u8 {
        self.level
    }

    fn instances(&self, keys: &[TileKey]) -> Vec<Option<Arc<Payload>>> {
        super::layer::layer_tiles(self.store, self.snap, &self.quality, self.index, keys)
    }

    /// The source's own file of that name first, then a stock model.
    fn model(&self, name: &str) -> Option<Arc<Model>> {
        match self.files.get(name) {
            Some(path) => self.models.file(path, self.snap.slots[self.index].version),
            None => self.models.stock(name),
        }
    }
}
