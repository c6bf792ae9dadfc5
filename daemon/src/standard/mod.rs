//! The scene in the standard tile formats other 3D tools read, built only
//! when a client asks, from the same tile store and generations as every
//! other call:
//!
//! - `terrain.rs`: quantized-mesh-1.0 terrain (CesiumJS, Cesium-native)
//!   from the height layer, meshed to `[quality] terrain_mesh_error_m`,
//!   and its `layer.json` (`layer.rs`: levels, availability, version);
//! - `xyz.rs`: Web Mercator XYZ tiles (MapLibre GL JS, deck.gl): heights
//!   as Terrarium PNG and the colour layer as PNG, and their TileJSON;
//! - `tileset.rs`: 3D Tiles 1.1 (`tileset.json` over GLB content) of the
//!   buildings and instances layers;
//! - `changes.rs`: for each generation, which tiles of each format it
//!   changed (the `/tiles/changes` notices).
//!
//! Encoded tiles are kept by what they are made of (their inputs' content
//! hashes and the options), so a tile a generation did not touch is never
//! encoded again; the counters in the scene state show what was built.
//! The HTTP adapter is `service::http::tiles`.

mod changes;
mod ground;
mod layer;
mod terrain;
mod tiles;
mod tileset;
mod xyz;

pub use layer::TerrainLayer;
pub use tiles::{Answer, CacheRule, Encoded, StandardError, StandardTiles};
pub use tileset::Content;
pub use xyz::XyzKind;
