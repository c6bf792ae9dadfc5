//! Web Mercator XYZ tiles for MapLibre GL JS and deck.gl: the height layer
//! as Terrarium-encoded PNG (`raster-dem`), the colour layer as PNG
//! (`raster`), each reprojected from the scene's geodetic tiles at the
//! level whose samples match the zoom's pixels, and their TileJSON.

use std::sync::Arc;
use std::sync::atomic::Ordering;

use relief_source::{Extent, SampleKind, TileKey};
use relief_standard_tiles::{
    MERCATOR_MAX_LAT, XyzRange, geodetic_level_for, resample_colors, resample_heights, rgba_png, source_keys,
    terrarium_png, xyz_range,
};
use serde_json::json;

use super::layer::data_level;
use super::tiles::{Answer, CacheRule, Encoded, FORMAT_XYZ, StandardError, StandardTiles, address_of, version_of};
use crate::graph::SceneSnapshot;

/// Which XYZ tiles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum XyzKind {
    /// The height layer, Terrarium-encoded.
    Terrarium,
    /// The colour layer.
    Imagery,
}

impl XyzKind {
    pub fn name(self) -> &'static str {
        match self {
            Self::Terrarium => "terrarium",
            Self::Imagery => "imagery",
        }
    }

    fn layer(self) -> &'static str {
        match self {
            Self::Terrarium => "height",
            Self::Imagery => "color",
        }
    }
}

/// One XYZ layer of a scene.
#[derive(Debug, Clone)]
pub struct XyzLayer {
    pub kind: XyzKind,
    slot: usize,
    /// The geodetic level of the source's own samples.
    native_level: u8,
    /// The zoom whose pixels match them.
    pub max_zoom: u8,
    /// Where the source has data, within Web Mercator's latitudes.
    pub data: Extent,
    pub version: String,
}

impl XyzLayer {
    pub fn of(snap: &SceneSnapshot, boot: u64, kind: XyzKind) -> Result<Self, StandardError> {
        let grid = &snap.grid;
        if !grid.is_geodetic() {
            return Err(StandardError::NotFound(format!(
                "this scene is a local projected one ({}): its {} tiles are not reprojected to Web Mercator; \
                 its tiles are at /api/tiles",
                grid.crs(),
                kind.name()
            )));
        }
        let slot = snap.layer_index(kind.layer()).ok_or_else(|| {
            StandardError::NotFound(format!(
                "the scene has no {} layer, so it has no {} tiles",
                kind.layer(),
                kind.name()
            ))
        })?;
        let info = snap.slots[slot].source.as_ref().map(|s| s.info()).unwrap_or_default();
        let native_level = data_level(grid, info.resolution);
        let world = Extent::new(-180.0, -MERCATOR_MAX_LAT, 180.0, MERCATOR_MAX_LAT);
        let data = info.extent.and_then(|e| e.intersection(&world)).unwrap_or(world);
        // A geodetic level's tiles span 180 / 2^l degrees, a zoom's 360 / 2^z.
        let max_zoom = native_level + 1;
        let version = version_of(&[boot, snap.slots[slot].effective_version, kind as u64]);
        Ok(Self { kind, slot, native_level, max_zoom, data, version })
    }

    /// The tiles of zoom `z` that hold data.
    pub fn available_at(&self, z: u8) -> Option<XyzRange> {
        if z > self.max_zoom {
            return None;
        }
        xyz_range(z, &self.data)
    }

    /// TileJSON 3.0.0, its tiles' URLs under `base` (`http://host:port`).
    pub fn tilejson(&self, base: &str, name: &str, generation: u64) -> serde_json::Value {
        let kind = self.kind.name();
        let mut doc = json!({
            "tilejson": "3.0.0",
            "name": format!("{name} {kind}"),
            "version": self.version,
            "scheme": "xyz",
            "tiles": [format!("{base}/tiles/{kind}/{{z}}/{{x}}/{{y}}.png?v={}", self.version)],
            "minzoom": 0,
            "maxzoom": self.max_zoom,
            "bounds": [self.data.min_x, self.data.min_y, self.data.max_x, self.data.max_y],
            "tileSize": relief_standard_tiles::XYZ_TILE_SIZE,
            "attribution": "",
            "relief:generation": generation,
        });
        if self.kind == XyzKind::Terrarium {
            doc["encoding"] = json!("terrarium");
        }
        doc
    }
}

/// The XYZ tiles `dirty` changes: at each zoom, the tiles each dirty extent
/// of the layer's source overlaps, grown by two samples of the geodetic
/// level read there (what a pixel's bilinear kernel reaches).
pub fn dirty_tiles(layer: &XyzLayer, snap: &SceneSnapshot, dirty: &[crate::scene::DirtyRegion]) -> Vec<XyzRange> {
    let id = snap.slots[layer.slot].spec.id.as_str();
    let mut out = Vec::new();
    for extent in dirty.iter().filter(|d| d.source_id == id).flat_map(|d| &d.extents) {
        for z in 0..=layer.max_zoom {
            let reach = 2.0 * snap.grid.sample_step(geodetic_level_for(&snap.grid, z, layer.native_level));
            let grown = extent.dilate(reach, reach);
            // Pixels wrap across the antimeridian: what reaches past it
            // changes tiles on the other side too.
            let mut areas = vec![grown];
            if grown.min_x < -180.0 {
                areas.push(Extent::new(grown.min_x + 360.0, grown.min_y, 180.0, grown.max_y));
            }
            if grown.max_x > 180.0 {
                areas.push(Extent::new(-180.0, grown.min_y, grown.max_x - 360.0, grown.max_y));
            }
            let Some(a) = layer.available_at(z) else { continue };
            for r in areas.iter().filter_map(|area| xyz_range(z, area)) {
                let x = [r.x[0].max(a.x[0]), r.x[1].min(a.x[1])];
                let y = [r.y[0].max(a.y[0]), r.y[1].min(a.y[1])];
                if x[0] <= x[1] && y[0] <= y[1] && !out.contains(&XyzRange { z, x, y }) {
                    out.push(XyzRange { z, x, y });
                }
            }
        }
    }
    out
}

impl StandardTiles {
    fn xyz_layer(&self, kind: XyzKind) -> Result<(Arc<SceneSnapshot>, XyzLayer), StandardError> {
        let snap = self.scene.snapshot();
        let layer = XyzLayer::of(&snap, self.boot, kind)?;
        Ok((snap, layer))
    }

    /// The TileJSON of `kind`, with tile URLs under `base`.
    pub fn tilejson(&self, kind: XyzKind, base: &str) -> Result<serde_json::Value, StandardError> {
        let (snap, layer) = self.xyz_layer(kind)?;
        Ok(layer.tilejson(base, &snap.manifest.name, snap.generation))
    }

    /// XYZ tile `z/x/y` of `kind` (rows from the north) as PNG.
    pub async fn xyz_tile(
        &self,
        kind: XyzKind,
        z: u8,
        x: u32,
        y: u32,
        v: Option<&str>,
    ) -> Result<Answer, StandardError> {
        let (snap, layer) = self.xyz_layer(kind)?;
        let name = kind.name();
        if !layer.available_at(z).is_some_and(|r| r.contains(x, y)) {
            let has = match layer.available_at(z) {
                Some(r) => format!("zoom {z} has x {}..={}, y {}..={}", r.x[0], r.x[1], r.y[0], r.y[1]),
                None => format!("zooms run 0..={}", layer.max_zoom),
            };
            return Err(StandardError::NotFound(format!(
                "{name} tile {z}/{x}/{y} holds none of the scene's data: {has}"
            )));
        }
        let cache = CacheRule::for_version(v, &layer.version);
        let grid = snap.grid.clone();
        let level = geodetic_level_for(&grid, z, layer.native_level);
        let sample = if kind == XyzKind::Terrarium { SampleKind::Corner } else { SampleKind::TexelWithBorder };
        let keys = source_keys(&grid, level, z, x, y, sample);
        let store = Arc::clone(&self.scene.store);
        let (job_snap, slot) = (Arc::clone(&snap), layer.slot);
        let quality = snap.manifest.quality;
        let tiles = self
            .scene
            .store
            .run(move || {
                let requests: Vec<(usize, TileKey)> = keys.iter().map(|&k| (slot, k)).collect();
                keys.into_iter()
                    .zip(store.build(&job_snap, &requests, &quality))
                    .map(|(k, t)| (k, t.ok()))
                    .collect::<Vec<_>>()
            })
            .await
            .map_err(|e| StandardError::Unavailable(format!("{name} tile {z}/{x}/{y}: {e}")))?;
        if tiles.iter().all(|(_, t)| t.is_none()) {
            return Err(StandardError::Unavailable(format!(
                "{name} tile {z}/{x}/{y}: the {} layer's tiles are not ready (see the scene state's errors)",
                kind.layer()
            )));
        }
        // A tile made without some of its inputs (one failed to build) is
        // served briefly and not kept: the next request tries them again.
        let partial = tiles.iter().any(|(_, t)| t.is_none());
        let cache = if partial { CacheRule::Short } else { cache };
        let mut made_of = vec![FORMAT_XYZ, kind as u64, u64::from(z), u64::from(x), u64::from(y)];
        made_of.extend(tiles.iter().map(|(_, t)| t.as_ref().map_or(u64::MAX, |t| t.content_hash)));
        let address = address_of(&made_of);
        let encoded = match self.encoded.get(&address) {
            Some(e) => e,
            None => {
                let payloads: Vec<_> = tiles.into_iter().map(|(k, t)| (k, t.map(|t| Arc::clone(&t.payload)))).collect();
                let made = self
                    .scene
                    .store
                    .run(move || match kind {
                        XyzKind::Terrarium => terrarium_png(&resample_heights(&grid, level, z, x, y, &payloads)),
                        XyzKind::Imagery => rgba_png(&resample_colors(&grid, level, z, x, y, &payloads)),
                    })
                    .await
                    .map_err(|e| StandardError::Unavailable(format!("{name} tile {z}/{x}/{y}: {e}")))?
                    .map_err(|e| StandardError::Unavailable(format!("{name} tile {z}/{x}/{y}: {e}")))?;
                let counter = match kind {
                    XyzKind::Terrarium => &self.counters.terrarium_built,
                    XyzKind::Imagery => &self.counters.imagery_built,
                };
                counter.fetch_add(1, Ordering::Relaxed);
                let made = Arc::new(Encoded::new(made, "image/png"));
                if !partial {
                    self.encoded.insert(address, Arc::clone(&made));
                }
                made
            }
        };
        Ok(Answer { encoded, cache, version: layer.version, generation: snap.generation })
    }
}
