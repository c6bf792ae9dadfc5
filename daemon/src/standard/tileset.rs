//! 3D Tiles 1.1 of the scene's buildings and instances, in two steps so
//! that nothing is built before a client comes near it:
//!
//! - `tileset.json`: one child per *group* (a scene tile [`GROUP_LEVELS`]
//!   levels above the content's) that the layer's data overlaps, its
//!   region from the ground's heights there, its content an external
//!   tileset `{layer}/{z}/{x}/{y}.json`;
//! - a group's tileset: one leaf per content tile in the group that has
//!   anything to draw, GLB at `{layer}/{z}/{x}/{y}.glb`, built when the
//!   group is asked for.
//!
//! Content tiles are the scene tiles at the level the layer's source makes
//! them (a building source's `min_level`, at least [`BUILDING_LEVEL`]; an
//! instance source's `level`). Geometric errors are those levels' ground
//! sizes: a group is opened within some tens of kilometres, as the renderer
//! draws buildings and trees. Each GLB is kept by what it is made of (its
//! tile's content hash, and the ground under `on_ground` buildings), so an
//! edit elsewhere costs nothing again.

use std::sync::Arc;
use std::sync::atomic::Ordering;

use std::cell::RefCell;

use rayon::prelude::*;
use relief_source::GenerateContext;
use relief_source::{Payload, TileKey};
use relief_source_ops::HeightWindow;
use relief_standard_tiles::{
    ModelMesh, TilesetEntry, buildings_glb, geometric_error_for_level, instances_glb, tileset_json,
};

use super::ground::HeightLayer;
use super::layer::{covering, data_level};
use super::tiles::{
    Answer, CacheRule, Encoded, FORMAT_GLB, Placement, StandardError, StandardTiles, address_of, version_of,
};
use crate::graph::SceneSnapshot;
use crate::scene_tiles::{ModelCache, building_min_level, instance_level};

/// The level of building content unless the source asks for a finer one:
/// tiles about 1.2 km tall, what the renderer draws buildings at near the
/// camera.
pub const BUILDING_LEVEL: u8 = 14;

/// Levels between a group and its content: up to 8 x 8 content tiles in
/// one group's tileset.
pub const GROUP_LEVELS: u8 = 3;

/// Most groups `tileset.json` lists for a layer: a larger layer is refused
/// with a message (every answer has a limit).
pub const MAX_GROUPS: u64 = 4096;

/// Most content tiles one notice names; past them it says `all`.
const MAX_NOTICED: u64 = 4096;

/// Room above the ground in a group's region: the tallest building or
/// tree relief expects (a region too tall only culls a little later).
const HEADROOM_M: f64 = 1000.0;

/// Which layer a tile of content draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Content {
    Buildings,
    Instances,
}

impl Content {
    pub fn name(self) -> &'static str {
        match self {
            Self::Buildings => "buildings",
            Self::Instances => "instances",
        }
    }
}

/// The 3D layers a scene has: for each, its slot and content level.
#[derive(Debug, Clone)]
pub struct TilesetLayers {
    pub layers: Vec<(Content, usize, u8)>,
    /// The height layer's slot (the ground under `on_ground` buildings).
    height: Option<usize>,
    pub version: String,
}

impl TilesetLayers {
    pub fn of(snap: &SceneSnapshot, boot: u64) -> Result<Self, StandardError> {
        let grid = &snap.grid;
        if !grid.is_geodetic() {
            return Err(StandardError::NotFound(format!(
                "this scene is a local projected one ({}): 3D Tiles are placed on the globe (ECEF), so it has none",
                grid.crs()
            )));
        }
        let mut layers = Vec::new();
        if let Some(i) = snap.layer_index("buildings") {
            let info = snap.slots[i].source.as_ref().map(|s| s.info()).unwrap_or_default();
            layers.push((Content::Buildings, i, building_min_level(&info).max(BUILDING_LEVEL)));
        }
        if let Some(i) = snap.layer_index("instances") {
            let info = snap.slots[i].source.as_ref().map(|s| s.info()).unwrap_or_default();
            layers.push((Content::Instances, i, instance_level(&info, grid)));
        }
        if layers.is_empty() {
            return Err(StandardError::NotFound(
                "the scene has no buildings or instances layer, so it has no 3D Tiles".into(),
            ));
        }
        let height = snap.layer_index("height");
        let mut made_of = vec![boot];
        made_of.extend(layers.iter().map(|&(_, i, _)| snap.slots[i].effective_version));
        made_of.extend(height.map(|h| snap.slots[h].effective_version));
        let version = version_of(&made_of);
        Ok(Self { layers, height, version })
    }

    fn layer(&self, content: Content) -> Option<(usize, u8)> {
        self.layers.iter().find(|(c, ..)| *c == content).map(|&(_, i, l)| (i, l))
    }

    /// The groups of one layer that its source's data overlaps (rows from
    /// the north), and the layer's content level.
    fn groups(&self, snap: &SceneSnapshot, content: Content) -> Result<Vec<TileKey>, StandardError> {
        let Some((slot, level)) = self.layer(content) else { return Ok(Vec::new()) };
        let grid = &snap.grid;
        let extent = data_extent(snap, slot, 0).unwrap_or_else(|| grid.extent());
        let group_level = level.saturating_sub(GROUP_LEVELS);
        let Some(r) = covering(grid, group_level, &extent) else { return Ok(Vec::new()) };
        let count = u64::from(r.x[1] - r.x[0] + 1) * u64::from(r.y[1] - r.y[0] + 1);
        if count > MAX_GROUPS {
            return Err(StandardError::Unavailable(format!(
                "the {} layer spans {count} tiles at level {group_level}, past the {MAX_GROUPS} one tileset lists",
                content.name()
            )));
        }
        Ok((r.y[0]..=r.y[1]).flat_map(|y| (r.x[0]..=r.x[1]).map(move |x| TileKey::new(group_level, x, y))).collect())
    }

    /// The content tiles of `group` that the layer's data overlaps.
    fn contents(&self, snap: &SceneSnapshot, content: Content, group: TileKey) -> Vec<TileKey> {
        let Some((slot, level)) = self.layer(content) else { return Vec::new() };
        let grid = &snap.grid;
        let extent = data_extent(snap, slot, 0).unwrap_or_else(|| grid.extent());
        let Some(area) = extent.intersection(&grid.tile_extent(group)) else { return Vec::new() };
        let Some(r) = covering(grid, level, &area) else { return Vec::new() };
        (r.y[0]..=r.y[1]).flat_map(|y| (r.x[0]..=r.x[1]).map(move |x| TileKey::new(level, x, y))).collect()
    }

    /// The URIs (relative to `tileset.json`) of the content tiles `dirty`
    /// changes, and of their groups' tilesets: tiles over a dirty extent of
    /// a layer's source, or of the ground under its buildings.
    pub fn dirty_content(&self, snap: &SceneSnapshot, dirty: &[crate::scene::DirtyRegion]) -> Option<Vec<String>> {
        let mut out = std::collections::BTreeSet::new();
        for &(content, slot, level) in &self.layers {
            let mut ids = vec![snap.slots[slot].spec.id.as_str()];
            // The ground under buildings is read bilinearly at the height
            // layer's own level: its dirt reaches a sample further.
            let mut reach = 0.0;
            if content == Content::Buildings
                && let Some(h) = self.height
            {
                ids.push(snap.slots[h].spec.id.as_str());
                let resolution = snap.slots[h].source.as_ref().and_then(|s| s.info().resolution);
                reach = snap.grid.sample_step(data_level(&snap.grid, resolution).min(level));
            }
            // Only where the layer has content.
            let Some(data) = data_extent(snap, slot, 0) else { continue };
            for extent in dirty.iter().filter(|d| ids.contains(&d.source_id.as_str())).flat_map(|d| &d.extents) {
                let Some(area) = extent.dilate(reach, reach).intersection(&data) else { continue };
                let Some(r) = covering(&snap.grid, level, &area) else { continue };
                let count = u64::from(r.x[1] - r.x[0] + 1) * u64::from(r.y[1] - r.y[0] + 1);
                if count + out.len() as u64 > MAX_NOTICED {
                    return None;
                }
                for y in r.y[0]..=r.y[1] {
                    for x in r.x[0]..=r.x[1] {
                        let key = TileKey::new(level, x, y);
                        let group =
                            TileKey::new(level.saturating_sub(GROUP_LEVELS), x >> GROUP_LEVELS, y >> GROUP_LEVELS);
                        out.insert(uri(content, group, "json"));
                        out.insert(uri(content, key, "glb"));
                    }
                }
            }
        }
        Some(out.into_iter().collect())
    }
}

/// Where a source has data: its own extent, else where all its inputs
/// have data (an extrusion draws where its footprints and its ground are).
fn data_extent(snap: &SceneSnapshot, slot: usize, depth: usize) -> Option<relief_source::Extent> {
    let s = &snap.slots[slot];
    if let Some(e) = s.source.as_ref().and_then(|src| src.info().extent) {
        return Some(e);
    }
    if depth > 16 {
        return None;
    }
    let mut extents = s.inputs.iter().filter_map(|&i| data_extent(snap, i, depth + 1));
    let first = extents.next()?;
    extents.try_fold(first, |a, b| a.intersection(&b))
}

/// The content hashes of the height tiles at `level` under a mesh tile's
/// footprint (grown by a sample: the ground is read bilinearly), or the
/// height layer's version where that is more than 64 tiles.
fn ground_read(
    snap: &SceneSnapshot,
    store: &crate::tiles::TileStore,
    height: usize,
    level: u8,
    mesh: &relief_source::MeshTile,
) -> Result<Vec<u64>, crate::tiles::TileError> {
    let Some(footprint) =
        mesh.positions.iter().map(|p| relief_source::Extent::new(p[0], p[1], p[0], p[1])).reduce(|a, b| a.union(&b))
    else {
        return Ok(Vec::new());
    };
    let step = snap.grid.sample_step(level);
    let Some(r) = covering(&snap.grid, level, &footprint.dilate(step, step)) else { return Ok(Vec::new()) };
    if u64::from(r.x[1] - r.x[0] + 1) * u64::from(r.y[1] - r.y[0] + 1) > 64 {
        return Ok(vec![snap.slots[height].effective_version]);
    }
    let mut hashes = Vec::new();
    for y in r.y[0]..=r.y[1] {
        for x in r.x[0]..=r.x[1] {
            hashes.push(store.tile(snap, height, TileKey::new(level, x, y), &snap.manifest.quality)?.content_hash);
        }
    }
    Ok(hashes)
}

/// A group's tileset (`json`) or a content tile (`glb`), relative to
/// `tileset.json`.
fn uri(content: Content, key: TileKey, extension: &str) -> String {
    format!("{}/{}/{}/{}.{extension}", content.name(), key.level, key.x, key.y)
}

/// The identity, for a group's tile (its content places itself).
const IDENTITY: [f64; 16] = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];

impl StandardTiles {
    fn tileset_layers(&self) -> Result<(Arc<SceneSnapshot>, TilesetLayers), StandardError> {
        let snap = self.scene.snapshot();
        let layers = TilesetLayers::of(&snap, self.boot)?;
        Ok((snap, layers))
    }

    /// Builds (or finds) the GLB of `content` tile `key`: blocking, on the
    /// pool.
    fn content_tile(
        &self,
        snap: &SceneSnapshot,
        layers: &TilesetLayers,
        content: Content,
        key: TileKey,
        models: &ModelCache,
    ) -> Result<Arc<Encoded>, StandardError> {
        let (slot, _) = layers
            .layer(content)
            .ok_or_else(|| StandardError::NotFound(format!("the scene has no {} layer", content.name())))?;
        let store = &self.scene.store;
        let quality = &snap.manifest.quality;
        let failed = |e: &dyn std::fmt::Display| {
            StandardError::Unavailable(format!("3D Tiles {} tile {key}: {e}", content.name()))
        };
        let tile = store.tile(snap, slot, key, quality).map_err(|e| failed(&e))?;
        // What the GLB is made of, known before it is built: the layer's
        // tile, and the ground under it (the height tiles its footprint
        // reads) or the models (an edited model file is a new version).
        let mut parts = vec![FORMAT_GLB, content as u64, u64::from(key.level), u64::from(key.x), u64::from(key.y)];
        parts.push(tile.content_hash);
        let height_level = layers.height.and_then(|h| {
            let r = snap.slots[h].source.as_ref()?.info().resolution?;
            Some(data_level(&snap.grid, Some(r)).min(key.level))
        });
        match (&*tile.payload, layers.height) {
            (Payload::Mesh(mesh), Some(h)) => {
                let level = height_level.unwrap_or(key.level);
                parts.extend(ground_read(snap, store, h, level, mesh).map_err(|e| failed(&e))?);
            }
            (Payload::Instances(_), _) => parts.push(snap.slots[slot].effective_version),
            _ => {}
        }
        let address = address_of(&parts);
        if let Some(e) = self.encoded.get(&address) {
            return Ok(e);
        }
        let glb = match (content, &*tile.payload) {
            (Content::Buildings, Payload::Mesh(mesh)) => {
                let layer = layers.height.map(|slot| HeightLayer { store, snap, slot });
                let ctx = layer.as_ref().map(|inputs| GenerateContext { grid: &snap.grid, quality, inputs });
                let level = height_level.unwrap_or(key.level);
                let window = ctx.as_ref().map(|ctx| RefCell::new(HeightWindow::new(ctx, 0, level)));
                let ground = |lon, lat| {
                    let h = window.as_ref().and_then(|w| w.borrow_mut().height_at(lon, lat).ok());
                    h.map_or(f64::NAN, f64::from)
                };
                buildings_glb(mesh, &snap.grid, key, &ground).map_err(|e| failed(&e))?
            }
            (Content::Instances, Payload::Instances(instances)) => {
                let scene_models = crate::scene_tiles::SceneInstances::new(store, snap, snap.manifest.quality, models);
                let model = |name: &str| {
                    use relief_renderer::InstanceTiles as _;
                    let m = scene_models.as_ref()?.model(name)?;
                    Some(ModelMesh {
                        positions: m.positions.clone(),
                        normals: m.normals.clone(),
                        colors: m.colors.clone(),
                        indices: m.indices.clone(),
                    })
                };
                instances_glb(instances, &model, &snap.grid, key).map_err(|e| failed(&e))?.glb
            }
            (_, other) => {
                return Err(failed(&format!("the layer's source gave a {} tile", other.kind().name())));
            }
        };
        let encoded = Arc::new(match glb {
            Some(glb) => {
                self.counters.glb_built.fetch_add(1, Ordering::Relaxed);
                Encoded::placed(
                    glb.bytes,
                    "model/gltf-binary",
                    Placement { region: glb.region, transform: glb.transform },
                )
            }
            // Nothing to draw: kept too, so it is not made again.
            None => Encoded::new(Vec::new(), "model/gltf-binary"),
        });
        self.encoded.insert(address, Arc::clone(&encoded));
        Ok(encoded)
    }

    /// The region of group `key`: its extent, and the ground's heights
    /// there (the height layer's tile at the group's level) with room above.
    fn group_region(&self, snap: &SceneSnapshot, layers: &TilesetLayers, key: TileKey) -> [f64; 6] {
        let e = snap.grid.tile_extent(key);
        let heights = layers.height.and_then(|h| self.scene.store.tile(snap, h, key, &snap.manifest.quality).ok());
        let (low, high) = match heights.as_deref().map(|t| &*t.payload) {
            Some(Payload::Height(h)) => {
                h.heights.iter().filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(f64::from(v)), hi.max(f64::from(v)))
                })
            }
            _ => (f64::INFINITY, f64::NEG_INFINITY),
        };
        let (low, high) = if low <= high { (low - 10.0, high + HEADROOM_M) } else { (-500.0, 9000.0) };
        [e.min_x.to_radians(), e.min_y.to_radians(), e.max_x.to_radians(), e.max_y.to_radians(), low, high]
    }

    /// `tileset.json`: a child per group, each an external tileset.
    pub async fn tileset(self: &Arc<Self>) -> Result<serde_json::Value, StandardError> {
        let (snap, layers) = self.tileset_layers()?;
        let this = Arc::clone(self);
        let job_snap = Arc::clone(&snap);
        self.scene
            .store
            .run(move || {
                let snap = &job_snap;
                let grid = &snap.grid;
                let mut entries = Vec::new();
                let mut coarsest = u8::MAX;
                for &(content, _, level) in &layers.layers {
                    coarsest = coarsest.min(level.saturating_sub(GROUP_LEVELS));
                    for group in layers.groups(snap, content)? {
                        entries.push(TilesetEntry {
                            uri: uri(content, group, "json"),
                            region: this.group_region(snap, &layers, group),
                            transform: IDENTITY,
                            geometric_error_m: geometric_error_for_level(grid, level),
                        });
                    }
                }
                let mut doc = tileset_json(&layers.version, &entries, geometric_error_for_level(grid, coarsest));
                doc["extras"] = serde_json::json!({"relief:generation": snap.generation});
                Ok(doc)
            })
            .await
            .map_err(|e| StandardError::Unavailable(format!("tileset.json: {e}")))?
    }

    /// A group's tileset (`.json`) or a content tile (`.glb`) of `content`
    /// at `z/x/y`.
    pub async fn tileset_part(
        self: &Arc<Self>,
        content: Content,
        key: TileKey,
        glb: bool,
        v: Option<&str>,
    ) -> Result<Answer, StandardError> {
        let (snap, layers) = self.tileset_layers()?;
        let name = uri(content, key, if glb { "glb" } else { "json" });
        let Some((_, level)) = layers.layer(content) else {
            return Err(StandardError::NotFound(format!("the scene has no {} layer", content.name())));
        };
        let group = TileKey::new(level.saturating_sub(GROUP_LEVELS), key.x >> GROUP_LEVELS, key.y >> GROUP_LEVELS);
        let listed = if glb {
            key.level == level && layers.contents(&snap, content, group).contains(&key)
        } else {
            key.level == group.level && layers.groups(&snap, content)?.contains(&key)
        };
        if !listed {
            return Err(StandardError::NotFound(format!("{name} is not part of tileset.json")));
        }
        let cache = CacheRule::for_version(v, &layers.version);
        let (this, job_snap, job_layers, job_name) =
            (Arc::clone(self), Arc::clone(&snap), layers.clone(), name.clone());
        let encoded = self
            .scene
            .store
            .run(move || {
                let (name, models) = (job_name, &this.models);
                if glb {
                    let made = this.content_tile(&job_snap, &job_layers, content, key, models)?;
                    return if made.placement.is_some() {
                        Ok(made)
                    } else {
                        Err(StandardError::NotFound(format!("{name} has nothing to draw")))
                    };
                }
                // The group's tiles in parallel, on the tile pool.
                let made: Vec<(TileKey, Arc<Encoded>)> = job_layers
                    .contents(&job_snap, content, key)
                    .into_par_iter()
                    .map(|tile| Ok((tile, this.content_tile(&job_snap, &job_layers, content, tile, models)?)))
                    .collect::<Result<_, StandardError>>()?;
                // Leaves: their content is drawn whole. Their URIs go from
                // `{layer}/{z}/{x}/{y}.json` up to `tileset.json`'s folder.
                let entries: Vec<TilesetEntry> = made
                    .iter()
                    .filter_map(|(tile, m)| {
                        let p = m.placement.as_ref()?;
                        Some(TilesetEntry {
                            uri: format!("../../../{}", uri(content, *tile, "glb")),
                            region: p.region,
                            transform: p.transform,
                            geometric_error_m: 0.0,
                        })
                    })
                    .collect();
                let doc = tileset_json(&job_layers.version, &entries, geometric_error_for_level(&job_snap.grid, level));
                Ok(Arc::new(Encoded::new(doc.to_string().into_bytes(), "application/json")))
            })
            .await
            .map_err(|e| StandardError::Unavailable(format!("{name}: {e}")))??;
        Ok(Answer { encoded, cache, version: layers.version, generation: snap.generation })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn content_uris_are_relative_to_the_tileset() {
        assert_eq!(uri(Content::Buildings, TileKey::new(14, 8514, 3200), "glb"), "buildings/14/8514/3200.glb");
        assert_eq!(uri(Content::Instances, TileKey::new(12, 1, 2), "json"), "instances/12/1/2.json");
    }
}
