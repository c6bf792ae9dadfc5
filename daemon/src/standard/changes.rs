//! Change notices: for each generation, the tiles of each standard format
//! it changed, from the extents the engine marked dirty. A terrain tile's
//! neighbours count as changed too: they share its edge vertices and the
//! normals there.

use std::sync::Arc;
use std::sync::atomic::Ordering;

use relief_source::TileGrid;
use serde::Serialize;
use tokio::sync::broadcast::error::RecvError;
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;

use super::layer::TerrainLayer;
use super::layer::{TileRange, covering, tms_rows};
use super::tiles::{StandardError, StandardTiles};
use super::tileset::TilesetLayers;
use super::xyz::{XyzKind, XyzLayer};
use crate::graph::SceneSnapshot;
use crate::scene::{DirtyRegion, EventKind};
use relief_standard_tiles::XyzRange;

/// Most `/tiles/changes` streams open at once.
pub const MAX_CHANGE_STREAMS: u64 = 256;

/// The version of each format a generation offers (None: not offered).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Schemes {
    pub generation: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub terrain: Option<Versioned>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub terrarium: Option<Versioned>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub imagery: Option<Versioned>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tileset: Option<Versioned>,
}

#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Versioned {
    pub version: String,
}

/// What one generation changed, format by format; a format absent did not
/// change.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Notice {
    pub generation: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub terrain: Option<Change>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub terrarium: Option<Change<XyzRange>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub imagery: Option<Change<XyzRange>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tileset: Option<ContentChange>,
}

/// The changed content of the 3D tileset.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ContentChange {
    /// The tileset's new `asset.tilesetVersion`.
    pub version: String,
    pub all: bool,
    /// Content URIs, relative to `tileset.json`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub content: Vec<String>,
}

/// The changed tiles of one format.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Change<R = TileRange> {
    /// The format's new version (its URLs' `v`).
    pub version: String,
    /// Every tile changed (an option of all of them, or notices missed):
    /// then `tiles` is empty.
    pub all: bool,
    /// Inclusive ranges, in the format's own rows (TMS for terrain).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tiles: Vec<R>,
}

impl Notice {
    pub fn is_empty(&self) -> bool {
        self.terrain.is_none() && self.terrarium.is_none() && self.imagery.is_none() && self.tileset.is_none()
    }
}

/// The terrain tiles `dirty` changes: at each level, the tiles each dirty
/// extent of the height or water source overlaps and their neighbours
/// (wrapping across the antimeridian), within what the layer has.
pub fn terrain_tiles(layer: &TerrainLayer, snap: &SceneSnapshot, dirty: &[DirtyRegion]) -> Vec<TileRange> {
    let ids: Vec<&str> =
        [Some(layer.height), layer.water].into_iter().flatten().map(|i| snap.slots[i].spec.id.as_str()).collect();
    let grid = &snap.grid;
    let mut out = Vec::new();
    for extent in dirty.iter().filter(|d| ids.contains(&d.source_id.as_str())).flat_map(|d| &d.extents) {
        for z in 0..=layer.max_zoom {
            let Some(available) = layer.available_at(grid, z) else { continue };
            let Some(hit) = covering(grid, z, extent) else { continue };
            for r in with_neighbours(grid, hit) {
                let r = tms_rows(grid, r);
                let x = [r.x[0].max(available.x[0]), r.x[1].min(available.x[1])];
                let y = [r.y[0].max(available.y[0]), r.y[1].min(available.y[1])];
                if x[0] <= x[1] && y[0] <= y[1] && !out.contains(&TileRange { z, x, y }) {
                    out.push(TileRange { z, x, y });
                }
            }
        }
    }
    out
}

/// A range (rows from the north) grown by one tile each way: columns wrap
/// across the antimeridian (as a second range), rows stop at the poles.
fn with_neighbours(grid: &TileGrid, r: TileRange) -> Vec<TileRange> {
    let (cols, rows) = grid.tiles_at(r.z);
    let y = [r.y[0].saturating_sub(1), (r.y[1] + 1).min(rows - 1)];
    if r.x[1] - r.x[0] + 3 >= cols {
        return vec![TileRange { z: r.z, x: [0, cols - 1], y }];
    }
    let mut out = vec![TileRange { z: r.z, x: [r.x[0].saturating_sub(1), (r.x[1] + 1).min(cols - 1)], y }];
    if r.x[0] == 0 {
        out.push(TileRange { z: r.z, x: [cols - 1, cols - 1], y });
    }
    if r.x[1] == cols - 1 {
        out.push(TileRange { z: r.z, x: [0, 0], y });
    }
    out
}

impl StandardTiles {
    /// The versions `snap` offers.
    pub fn schemes(&self, snap: &SceneSnapshot) -> Schemes {
        let xyz = |kind| XyzLayer::of(snap, self.boot, kind).ok().map(|l| Versioned { version: l.version });
        Schemes {
            generation: snap.generation,
            terrain: TerrainLayer::of(snap, self.boot).ok().map(|l| Versioned { version: l.version }),
            terrarium: xyz(XyzKind::Terrarium),
            imagery: xyz(XyzKind::Imagery),
            tileset: TilesetLayers::of(snap, self.boot).ok().map(|l| Versioned { version: l.version }),
        }
    }

    /// What changed from `before` to `snap`, given the generations'
    /// dirty extents (None: not known, so all of a changed format).
    fn notice(&self, before: &Schemes, snap: &SceneSnapshot, dirty: Option<&[DirtyRegion]>) -> (Schemes, Notice) {
        let now = self.schemes(snap);
        let mut notice = Notice { generation: snap.generation, ..Notice::default() };
        if let Some(t) = now.terrain.as_ref().filter(|t| before.terrain.as_ref() != Some(*t))
            && let Ok(layer) = TerrainLayer::of(snap, self.boot)
        {
            let tiles = dirty.map(|d| terrain_tiles(&layer, snap, d)).unwrap_or_default();
            notice.terrain = Some(Change { version: t.version.clone(), all: tiles.is_empty(), tiles });
        }
        for kind in [XyzKind::Terrarium, XyzKind::Imagery] {
            let (was, is) = match kind {
                XyzKind::Terrarium => (&before.terrarium, &now.terrarium),
                XyzKind::Imagery => (&before.imagery, &now.imagery),
            };
            let Some(v) = is.as_ref().filter(|v| was.as_ref() != Some(*v)) else { continue };
            let Ok(layer) = XyzLayer::of(snap, self.boot, kind) else { continue };
            let tiles = dirty.map(|d| super::xyz::dirty_tiles(&layer, snap, d)).unwrap_or_default();
            let change = Some(Change { version: v.version.clone(), all: tiles.is_empty(), tiles });
            match kind {
                XyzKind::Terrarium => notice.terrarium = change,
                XyzKind::Imagery => notice.imagery = change,
            }
        }
        if let Some(v) = now.tileset.as_ref().filter(|v| before.tileset.as_ref() != Some(*v))
            && let Ok(layers) = TilesetLayers::of(snap, self.boot)
        {
            let content = dirty.and_then(|d| layers.dirty_content(snap, d)).unwrap_or_default();
            notice.tileset = Some(ContentChange { version: v.version.clone(), all: content.is_empty(), content });
        }
        (now, notice)
    }

    /// `versions` (the formats offered now), then a `changes` notice for
    /// each generation that changed a format. Ends when the client goes
    /// or reliefd shuts down; past [`MAX_CHANGE_STREAMS`] open at once, a
    /// new one is refused.
    pub fn changes(self: &Arc<Self>) -> Result<ReceiverStream<(&'static str, serde_json::Value)>, StandardError> {
        let open = self.counters.change_streams.fetch_add(1, Ordering::AcqRel);
        if open >= MAX_CHANGE_STREAMS {
            self.counters.change_streams.fetch_sub(1, Ordering::AcqRel);
            return Err(StandardError::TooMany(format!(
                "{MAX_CHANGE_STREAMS} /tiles/changes streams are open already; close one"
            )));
        }
        let mut events = self.scene.events();
        let (tx, rx) = mpsc::channel(16);
        let this = Arc::clone(self);
        tokio::spawn(async move {
            let mut now = this.schemes(&this.scene.snapshot());
            let first = serde_json::to_value(&now).unwrap_or_default();
            if tx.send(("versions", first)).await.is_ok() {
                loop {
                    let event = tokio::select! {
                        () = this.shutdown.cancelled() => break,
                        () = tx.closed() => break,
                        e = events.recv() => e,
                    };
                    match event {
                        Ok(e) if matches!(e.kind, EventKind::Generation { .. }) => {}
                        // Missed events: the snapshot and the dirt log say
                        // what changed meanwhile.
                        Ok(_) | Err(RecvError::Lagged(_)) => {}
                        Err(RecvError::Closed) => break,
                    }
                    // Each notice goes from the last generation noticed to the
                    // one served now, with the dirt of every generation
                    // between (all of a format when the log no longer has it).
                    let snap = this.scene.snapshot();
                    if snap.generation <= now.generation {
                        continue;
                    }
                    let dirty = this.scene.dirt_between(now.generation, snap.generation);
                    let (next, notice) = this.notice(&now, &snap, dirty.as_deref());
                    now = next;
                    if notice.is_empty() {
                        continue;
                    }
                    if tx.send(("changes", serde_json::to_value(&notice).unwrap_or_default())).await.is_err() {
                        break;
                    }
                    this.counters.notices_sent.fetch_add(1, Ordering::Relaxed);
                }
            }
            this.counters.change_streams.fetch_sub(1, Ordering::Relaxed);
        });
        Ok(ReceiverStream::new(rx))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbours_wrap_across_the_antimeridian_and_stop_at_the_poles() {
        let grid = TileGrid::geodetic(256).unwrap();
        // Level 2: 8 x 4.
        let r = with_neighbours(&grid, TileRange { z: 2, x: [0, 0], y: [0, 0] });
        assert_eq!(r, [TileRange { z: 2, x: [0, 1], y: [0, 1] }, TileRange { z: 2, x: [7, 7], y: [0, 1] }]);
        let r = with_neighbours(&grid, TileRange { z: 2, x: [3, 4], y: [3, 3] });
        assert_eq!(r, [TileRange { z: 2, x: [2, 5], y: [2, 3] }]);
        let r = with_neighbours(&grid, TileRange { z: 1, x: [0, 1], y: [0, 1] });
        assert_eq!(r, [TileRange { z: 1, x: [0, 3], y: [0, 1] }]);
    }
}
