//! The quantized-mesh terrain layer of a scene: which levels and tiles it
//! has, how true each level's mesh is, its version, and `layer.json`.

use relief_source::{Extent, TileGrid, TileKey};
use serde_json::json;

use super::tiles::{StandardError, version_of};
use crate::graph::SceneSnapshot;
use crate::picture::Picture;

/// An inclusive range of tiles at one level (quantized-mesh's
/// `available` entries; rows as the scheme numbers them).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct TileRange {
    pub z: u8,
    pub x: [u32; 2],
    pub y: [u32; 2],
}

/// The terrain a scene offers as quantized-mesh.
#[derive(Debug, Clone)]
pub struct TerrainLayer {
    /// The height layer's slot.
    pub height: usize,
    /// The water layer's slot, when the scene has one (`watermask`).
    pub water: Option<usize>,
    /// The finest level: the one whose samples are the data's own.
    pub max_zoom: u8,
    /// Where the height layer has data (the whole planet when unknown).
    pub data: Extent,
    /// `[quality] terrain_mesh_error_m`: the error at `max_zoom`.
    pub error_m: f64,
    pub version: String,
}

impl TerrainLayer {
    /// The terrain `snap` offers, or why it offers none.
    pub fn of(snap: &SceneSnapshot, boot: u64) -> Result<Self, StandardError> {
        let grid = &snap.grid;
        if !grid.is_geodetic() {
            return Err(StandardError::NotFound(format!(
                "this scene is a local projected one ({}): quantized-mesh terrain is EPSG:4326 or EPSG:3857 only, \
                 so the scene has none; its heights are at /api/tiles and /api/elevation",
                grid.crs()
            )));
        }
        let height = snap.layer_index("height").ok_or_else(|| {
            StandardError::NotFound("the scene has no height layer, so it has no terrain to serve".into())
        })?;
        let slot = &snap.slots[height];
        let info = slot.source.as_ref().map(|s| s.info()).unwrap_or_default();
        let max_zoom = data_level(grid, info.resolution);
        let data = info.extent.and_then(|e| e.intersection(&grid.extent())).unwrap_or_else(|| grid.extent());
        let water = snap.layer_index("water");
        let error_m = Picture::of(&snap.manifest).terrain_mesh_error_m;
        let mut made_of = vec![boot, slot.effective_version, error_m.to_bits()];
        made_of.extend(water.map(|w| snap.slots[w].effective_version));
        let version = version_of(&made_of);
        Ok(Self { height, water, max_zoom, data, error_m, version })
    }

    /// The largest vertical error of level `z`'s meshes: the knob at the
    /// finest level, twice as much each level up (a tile's footprint
    /// doubles each level, as the error CesiumJS expects of it does).
    pub fn error_at(&self, z: u8) -> f64 {
        self.error_m * f64::from(1u32 << self.max_zoom.saturating_sub(z).min(30))
    }

    /// The tiles of level `z` that hold data (level 0: both), TMS rows.
    pub fn available_at(&self, grid: &TileGrid, z: u8) -> Option<TileRange> {
        if z > self.max_zoom {
            return None;
        }
        let (cols, rows) = grid.tiles_at(z);
        if z == 0 {
            return Some(TileRange { z, x: [0, cols - 1], y: [0, rows - 1] });
        }
        covering(grid, z, &self.data).map(|r| tms_rows(grid, r))
    }

    pub fn is_available(&self, grid: &TileGrid, key: TileKey) -> bool {
        let (_, rows) = grid.tiles_at(key.level);
        self.available_at(grid, key.level).is_some_and(|r| {
            let tms_y = rows - 1 - key.y;
            (r.x[0]..=r.x[1]).contains(&key.x) && (r.y[0]..=r.y[1]).contains(&tms_y)
        })
    }

    /// Which extensions a tile can carry.
    pub fn extensions(&self) -> Vec<&'static str> {
        let mut e = vec!["octvertexnormals"];
        if self.water.is_some() {
            e.push("watermask");
        }
        e
    }

    /// `layer.json`, as CesiumJS's `CesiumTerrainProvider` reads it.
    pub fn layer_json(&self, grid: &TileGrid, name: &str, generation: u64) -> serde_json::Value {
        let available: Vec<Vec<serde_json::Value>> = (0..=self.max_zoom)
            .map(|z| {
                self.available_at(grid, z)
                    .map(|r| vec![json!({"startX": r.x[0], "endX": r.x[1], "startY": r.y[0], "endY": r.y[1]})])
                    .unwrap_or_default()
            })
            .collect();
        json!({
            "tilejson": "2.1.0",
            "name": name,
            "description": "relief's live terrain: the height layer meshed to [quality] terrain_mesh_error_m",
            "format": "quantized-mesh-1.0",
            "scheme": "tms",
            "projection": "EPSG:4326",
            "version": self.version,
            "tiles": ["{z}/{x}/{y}.terrain?v={version}"],
            "bounds": [self.data.min_x, self.data.min_y, self.data.max_x, self.data.max_y],
            "minzoom": 0,
            "maxzoom": self.max_zoom,
            "available": available,
            "extensions": self.extensions(),
            "attribution": "",
            "relief:generation": generation,
            "relief:terrain_mesh_error_m": self.error_m,
            "relief:level_error_m": (0..=self.max_zoom).map(|z| self.error_at(z)).collect::<Vec<_>>(),
        })
    }
}

/// The level whose samples are a source's own (the first at or finer than
/// its data's `resolution`, in grid units); 12 when it is not known.
pub fn data_level(grid: &TileGrid, resolution: Option<f64>) -> u8 {
    resolution.map_or(12, |r| grid.level_for_spacing(r).min(20))
}

/// The tiles of level `z` an extent overlaps (rows from the north), or
/// None when it misses the grid. An extent's edge on a tile boundary does
/// not reach into the next tile.
pub fn covering(grid: &TileGrid, z: u8, area: &Extent) -> Option<TileRange> {
    let e = grid.extent();
    let area = area.intersection(&e)?;
    let (cols, rows) = grid.tiles_at(z);
    let (w, h) = grid.tile_span(z);
    let column = |x: f64| ((x - e.min_x) / w).floor().clamp(0.0, f64::from(cols - 1)) as u32;
    let row = |y: f64| ((e.max_y - y) / h).floor().clamp(0.0, f64::from(rows - 1)) as u32;
    // Inclusive ends: the last tile starts before the far edge.
    let last = |v: f64, span: f64, count: u32| ((v / span).ceil() - 1.0).clamp(0.0, f64::from(count - 1)) as u32;
    let x = [column(area.min_x), last(area.max_x - e.min_x, w, cols).max(column(area.min_x))];
    let y = [row(area.max_y), last(e.max_y - area.min_y, h, rows).max(row(area.max_y))];
    Some(TileRange { z, x, y })
}

/// A range with rows from the north as TMS rows (from the south).
pub fn tms_rows(grid: &TileGrid, r: TileRange) -> TileRange {
    let (_, rows) = grid.tiles_at(r.z);
    TileRange { z: r.z, x: r.x, y: [rows - 1 - r.y[1], rows - 1 - r.y[0]] }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covering_ranges_hold_exactly_the_overlapping_tiles() {
        let grid = TileGrid::geodetic(256).unwrap();
        // Level 3: 16 x 8 tiles of 22.5 degrees.
        let r = covering(&grid, 3, &Extent::new(7.0, 43.5, 8.0, 44.5)).unwrap();
        assert_eq!((r.x, r.y), ([8, 8], [2, 2]));
        // On a boundary: 22.5 to 45 east is column 9 only.
        let r = covering(&grid, 3, &Extent::new(22.5, 0.0, 45.0, 22.5)).unwrap();
        assert_eq!((r.x, r.y), ([9, 9], [3, 3]));
        let whole = covering(&grid, 2, &grid.extent()).unwrap();
        assert_eq!((whole.x, whole.y), ([0, 7], [0, 3]));
        let t = tms_rows(&grid, TileRange { z: 3, x: [8, 8], y: [1, 2] });
        assert_eq!(t.y, [5, 6]);
        assert!(covering(&grid, 3, &Extent::new(200.0, 0.0, 210.0, 1.0)).is_none());
    }
}
