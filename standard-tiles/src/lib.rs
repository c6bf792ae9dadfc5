//! relief's tiles in the standard formats that 3D clients already read:
//! quantized-mesh-1.0 terrain (CesiumJS, Cesium-native), Web Mercator
//! Terrarium and imagery PNG (MapLibre GL JS, deck.gl) and 3D Tiles 1.1 GLB
//! content. The daemon's `standard/` serves them under `/tiles/`.
//!
//! - `rtin.rs`: [`Rtin`], the right-triangulated irregular network (Evans et
//!   al. 2001, as in Mapbox's Martini) over a height tile's (2^k+1)^2 samples,
//!   with one accuracy knob, `terrain_mesh_error_m`, held exactly (every
//!   sample within it of the mesh).
//! - `quantized_mesh.rs`: [`encode_quantized_mesh`], the quantized-mesh-1.0
//!   encoder (header, vertices, high-water-mark indices, edge lists, the
//!   `octvertexnormals` extension) and [`gzip`].
//! - `tms.rs`: relief's tile keys (y from the north) and quantized-mesh's TMS
//!   rows (y from the south).
//! - `gltf/`: [`buildings_glb`] and [`instances_glb`], mesh and instance
//!   tiles as 3D Tiles 1.1 glTF content (GLB, ECEF offsets, y-up, feature
//!   ids); `tileset.rs`: [`tileset_json`] over them.
//! - `stats.rs`: [`mesh_stats`], triangles, bytes and measured error of one
//!   tile at one knob, for benches and `make accuracy`.
//! - `xyz.rs`: the Web Mercator XYZ grid that MapLibre GL JS and deck.gl read
//!   ([`xyz_extent`], [`xyz_range`]) and the geodetic level that feeds a zoom
//!   ([`geodetic_level_for`]).
//! - `resample.rs`: geodetic tiles read at an XYZ tile's pixel centres
//!   ([`source_keys`], [`resample_heights`], [`resample_colors`]).
//! - `xyz_png.rs`: those pixels as PNG, heights in Mapzen's Terrarium
//!   encoding ([`terrarium_png`]) and imagery as RGBA ([`rgba_png`]).
//!
//! **Architecture invariant:** depends on relief-source only (its grid,
//! payloads and geodesy) of relief's crates; never on GDAL, the engine or the
//! renderer.

mod error;
mod gltf;
mod quantized_mesh;
mod resample;
mod rtin;
mod stats;
mod tileset;
mod tms;
mod xyz;
mod xyz_png;

#[cfg(test)]
mod decode;

pub use error::StandardTileError;
pub use gltf::{Glb, InstancesGlb, ModelMesh, buildings_glb, instances_glb};
pub use quantized_mesh::{
    EncodeOptions, QuantizedMeshHeader, WATER_MASK_SIZE, encode_quantized_mesh, gzip, horizon_occlusion_point,
    oct_encode,
};
pub use resample::{resample_colors, resample_heights, source_keys};
pub use rtin::{EdgeVertices, Rtin, TerrainMesh};
pub use stats::{MeshStats, mesh_stats};
pub use tileset::{TilesetEntry, geometric_error_for_level, tileset_json};
pub use tms::{key_from_tms, tms_from_key};
pub use xyz::{
    MERCATOR_MAX_LAT, XYZ_MAX_ZOOM, XYZ_TILE_SIZE, XyzRange, geodetic_level_for, xyz_extent, xyz_pixel_lonlat,
    xyz_range,
};
pub use xyz_png::{rgba_png, terrarium_png, terrarium_rgb};
