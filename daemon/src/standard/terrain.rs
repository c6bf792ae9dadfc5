//! Quantized-mesh terrain tiles: the height layer's tile meshed at its
//! level's error, with the extensions the client's `Accept` asks for.

use std::sync::Arc;
use std::sync::atomic::Ordering;

use relief_source::{Payload, TileKey};
use relief_standard_tiles::{EncodeOptions, Rtin, WATER_MASK_SIZE, encode_quantized_mesh, key_from_tms};

use super::layer::TerrainLayer;
use super::tiles::{Answer, CacheRule, Encoded, FORMAT_TERRAIN, StandardError, StandardTiles, address_of};
use crate::graph::SceneSnapshot;

/// The media type of a quantized-mesh tile.
const QUANTIZED_MESH: &str = "application/vnd.quantized-mesh";

/// The extensions a client asked for.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Extensions {
    pub octvertexnormals: bool,
    pub watermask: bool,
}

/// The extensions an `Accept` header asks of `layer`: those named in the
/// `extensions` parameter of `application/vnd.quantized-mesh` (joined
/// with `-`, as CesiumJS sends them). One the layer does not offer is
/// refused, naming what it offers.
pub fn wanted(accept: Option<&str>, layer: &TerrainLayer) -> Result<Extensions, StandardError> {
    let mut wanted = Extensions::default();
    let offered = layer.extensions();
    for range in accept.unwrap_or("").split(',') {
        let mut parts = range.split(';').map(str::trim);
        if !parts.next().is_some_and(|t| t.eq_ignore_ascii_case(QUANTIZED_MESH)) {
            continue;
        }
        for param in parts {
            let Some((name, value)) = param.split_once('=') else { continue };
            if !name.trim().eq_ignore_ascii_case("extensions") {
                continue;
            }
            for extension in value.trim().trim_matches('"').split('-').filter(|e| !e.is_empty()) {
                match extension {
                    "octvertexnormals" | "vertexnormals" => wanted.octvertexnormals = true,
                    "watermask" if offered.contains(&"watermask") => wanted.watermask = true,
                    "watermask" => {
                        return Err(StandardError::NotAcceptable(
                            "Accept asks for the 'watermask' extension, but the scene has no water layer; \
                             this layer offers: octvertexnormals"
                                .into(),
                        ));
                    }
                    other => {
                        return Err(StandardError::NotAcceptable(format!(
                            "Accept asks for the quantized-mesh extension '{}', which this layer does not offer; \
                             it offers: {}",
                            relief_source::echo::echoed(other),
                            offered.join(", ")
                        )));
                    }
                }
            }
        }
    }
    Ok(wanted)
}

impl StandardTiles {
    /// The current terrain layer.
    pub fn terrain_layer(&self) -> Result<(Arc<SceneSnapshot>, TerrainLayer), StandardError> {
        let snap = self.scene.snapshot();
        let layer = TerrainLayer::of(&snap, self.boot)?;
        Ok((snap, layer))
    }

    /// `layer.json` of the current generation.
    pub fn layer_json(&self) -> Result<serde_json::Value, StandardError> {
        let (snap, layer) = self.terrain_layer()?;
        Ok(layer.layer_json(&snap.grid, &snap.manifest.name, snap.generation))
    }

    /// Tile `z/x/y` (TMS rows), for a client whose URL named version `v`
    /// and who sent `accept`.
    pub async fn terrain_tile(
        &self,
        z: u8,
        x: u32,
        tms_y: u32,
        v: Option<&str>,
        accept: Option<&str>,
    ) -> Result<Answer, StandardError> {
        let (snap, layer) = self.terrain_layer()?;
        let grid = &snap.grid;
        let key = key_from_tms(grid, z, x, tms_y)
            .filter(|&k| layer.is_available(grid, k))
            .ok_or_else(|| not_available(&layer, grid, z, x, tms_y))?;
        let extensions = wanted(accept, &layer)?;
        let cache = CacheRule::for_version(v, &layer.version);
        let store = Arc::clone(&self.scene.store);
        let job_snap = Arc::clone(&snap);
        let quality = snap.manifest.quality;
        let (height, water) = (layer.height, layer.water.filter(|_| extensions.watermask));
        let inputs = self
            .scene
            .store
            .run(move || {
                let h = store.tile(&job_snap, height, key, &quality)?;
                let w = water.map(|w| store.tile(&job_snap, w, key, &quality)).transpose()?;
                Ok::<_, crate::tiles::TileError>((h, w))
            })
            .await
            .and_then(|r| r)
            .map_err(|e| StandardError::Unavailable(format!("terrain tile {z}/{x}/{tms_y}: {e}")))?;
        let (height_tile, water_tile) = inputs;
        let error_m = layer.error_at(z);
        let address = {
            let mut made_of = vec![
                FORMAT_TERRAIN,
                u64::from(z),
                u64::from(x),
                u64::from(tms_y),
                height_tile.content_hash,
                error_m.to_bits(),
                u64::from(extensions.octvertexnormals),
            ];
            made_of.extend(water_tile.as_ref().map(|w| w.content_hash));
            // Where the data ends decides which gaps are 0 m and which filled.
            let d = layer.data;
            made_of.extend([d.min_x, d.min_y, d.max_x, d.max_y].map(f64::to_bits));
            address_of(&made_of)
        };
        let encoded = match self.encoded.get(&address) {
            Some(e) => e,
            None => {
                let data = layer.data;
                let job_snap = Arc::clone(&snap);
                let made = self
                    .scene
                    .store
                    .run(move || {
                        encode(
                            &job_snap,
                            key,
                            &height_tile.payload,
                            water_tile.as_ref().map(|w| &*w.payload),
                            data,
                            error_m,
                            extensions,
                        )
                    })
                    .await
                    .map_err(|e| StandardError::Unavailable(format!("terrain tile {z}/{x}/{tms_y}: {e}")))??;
                self.counters.terrain_built.fetch_add(1, Ordering::Relaxed);
                let made = Arc::new(made);
                self.encoded.insert(address, Arc::clone(&made));
                made
            }
        };
        self.counters.terrain_served.fetch_add(1, Ordering::Relaxed);
        Ok(Answer { encoded, cache, version: layer.version, generation: snap.generation })
    }
}

/// Why `z/x/y` is not served, with what level `z` has.
fn not_available(layer: &TerrainLayer, grid: &relief_source::TileGrid, z: u8, x: u32, tms_y: u32) -> StandardError {
    let has = match layer.available_at(grid, z) {
        Some(r) => format!("level {z} has x {}..={}, y {}..={} (TMS rows)", r.x[0], r.x[1], r.y[0], r.y[1]),
        None => format!("levels run 0..={}", layer.max_zoom),
    };
    StandardError::NotFound(format!("terrain tile {z}/{x}/{tms_y} is not in layer.json's available tiles: {has}"))
}

/// Meshes and encodes one tile. Samples without data are 0 m outside the
/// height layer's data (the ellipsoid, as CesiumJS draws where there is
/// no terrain) and filled from their neighbours inside it (holes).
fn encode(
    snap: &SceneSnapshot,
    key: TileKey,
    height: &Payload,
    water: Option<&Payload>,
    data: relief_source::Extent,
    error_m: f64,
    extensions: Extensions,
) -> Result<Encoded, StandardError> {
    let grid = &snap.grid;
    let Payload::Height(tile) = height else {
        return Err(StandardError::Unavailable(format!("the height layer gave a {} tile", height.kind().name())));
    };
    let mut tile = tile.clone();
    let lattice = grid.lattice(key, relief_source::SampleKind::Corner);
    for j in 0..tile.size {
        for i in 0..tile.size {
            let h = &mut tile.heights[j * tile.size + i];
            if h.is_nan() && !data.contains(lattice.x(i), lattice.y(j)) {
                *h = 0.0;
            }
        }
    }
    let failed = |e: relief_standard_tiles::StandardTileError| StandardError::Unavailable(format!("terrain tile: {e}"));
    let mesh = Rtin::new(&tile).map_err(failed)?.mesh(error_m);
    let mask = water.map(water_mask);
    let options = EncodeOptions { octvertexnormals: extensions.octvertexnormals, watermask: mask.as_deref() };
    let bytes = encode_quantized_mesh(&mesh, grid, key, options).map_err(failed)?;
    Ok(Encoded::new(bytes, QUANTIZED_MESH))
}

/// The water layer's tile as a 256 x 256 mask (255 water), from the north
/// west: a colour tile's alpha over 127 (its texels without the border),
/// a raster's value over 0.5 (its corner samples, nearest).
fn water_mask(water: &Payload) -> Vec<u8> {
    let n = WATER_MASK_SIZE;
    let mut mask = vec![0u8; n * n];
    for (k, m) in mask.iter_mut().enumerate() {
        let (i, j) = (k % n, k / n);
        *m = match water {
            Payload::Color(c) => {
                let cells = c.size - 2;
                let (ti, tj) = (1 + i * cells / n, 1 + j * cells / n);
                if c.rgba[(tj * c.size + ti) * 4 + 3] > 127 { 255 } else { 0 }
            }
            Payload::Height(h) => {
                let cells = h.size - 1;
                let (si, sj) = ((2 * i + 1) * cells / (2 * n), (2 * j + 1) * cells / (2 * n));
                if h.get(si, sj) > 0.5 { 255 } else { 0 }
            }
            _ => 0,
        };
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(water: bool) -> TerrainLayer {
        TerrainLayer {
            height: 0,
            water: water.then_some(1),
            max_zoom: 10,
            data: relief_source::Extent::new(7.0, 43.0, 8.0, 44.0),
            error_m: 1.0,
            version: "v".into(),
        }
    }

    #[test]
    fn accept_names_the_extensions_cesium_asks_for() {
        let cesium =
            "application/vnd.quantized-mesh;extensions=octvertexnormals,application/octet-stream;q=0.9,*/*;q=0.01";
        assert_eq!(
            wanted(Some(cesium), &layer(false)).unwrap(),
            Extensions { octvertexnormals: true, watermask: false }
        );
        let both = "application/vnd.quantized-mesh;extensions=octvertexnormals-watermask";
        assert_eq!(wanted(Some(both), &layer(true)).unwrap(), Extensions { octvertexnormals: true, watermask: true });
        assert_eq!(wanted(None, &layer(false)).unwrap(), Extensions::default());
        assert_eq!(wanted(Some("*/*"), &layer(false)).unwrap(), Extensions::default());
        let Err(StandardError::NotAcceptable(m)) = wanted(Some(both), &layer(false)) else { panic!() };
        assert!(m.contains("no water layer"), "{m}");
        let odd = "application/vnd.quantized-mesh;extensions=octvertexnormals-metadata";
        let Err(StandardError::NotAcceptable(m)) = wanted(Some(odd), &layer(true)) else { panic!() };
        assert!(m.contains("'metadata'") && m.contains("octvertexnormals, watermask"), "{m}");
    }

    #[test]
    fn a_water_mask_reads_alpha_or_height_from_the_north_west() {
        // A colour tile of 258 x 258 texels (a border of one): water (alpha
        // 255) in the western half of the core.
        let size = 258;
        let mut rgba = vec![0u8; size * size * 4];
        for j in 0..size {
            for i in 0..size {
                rgba[(j * size + i) * 4 + 3] = if (1..129).contains(&i) { 255 } else { 0 };
            }
        }
        let mask = water_mask(&Payload::Color(relief_source::ColorTile { size, rgba }));
        assert_eq!(mask.len(), WATER_MASK_SIZE * WATER_MASK_SIZE);
        assert!(
            mask.chunks(WATER_MASK_SIZE)
                .all(|row| row[..128].iter().all(|&m| m == 255) && row[128..].iter().all(|&m| m == 0))
        );
        // A raster of 257 x 257 corner samples: water (1) in the northern rows.
        let size = 257;
        let heights = (0..size * size).map(|k| if k / size < 128 { 1.0 } else { 0.0 }).collect();
        let mask = water_mask(&Payload::Height(relief_source::HeightTile { size, heights }));
        assert!(mask[..128 * WATER_MASK_SIZE].iter().all(|&m| m == 255));
        assert!(mask[128 * WATER_MASK_SIZE..].iter().all(|&m| m == 0));
    }

    #[test]
    fn the_error_doubles_each_level_up() {
        let l = layer(false);
        assert_eq!(l.error_at(10), 1.0);
        assert_eq!(l.error_at(9), 2.0);
        assert_eq!(l.error_at(0), 1024.0);
        assert_eq!(l.error_at(12), 1.0);
    }
}
