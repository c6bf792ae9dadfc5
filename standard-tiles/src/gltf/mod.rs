//! 3D Tiles 1.1 content: relief's buildings and instances as glTF 2.0
//! binaries (GLB), positions as f32 offsets from an f64 centre in ECEF
//! (WGS84), y-up as 3D Tiles reads glTF, the centre handed back as the
//! tile's transform.
//!
//! - `buildings.rs`: [`buildings_glb`], a mesh tile with flat normals,
//!   per-vertex colours and `EXT_mesh_features` ids, parts on the ground set
//!   on the terrain.
//! - `instances.rs`: [`instances_glb`] and [`ModelMesh`], an instance tile
//!   as one mesh per model placed with `EXT_mesh_gpu_instancing`.
//! - `glb.rs`: [`Glb`], the bytes with the transform and region the
//!   tileset entry needs.
//! - `document.rs`: the glTF JSON and binary buffer, and the GLB container.
//! - `frame.rs`: ECEF offsets, y-up axes, regions and colours as glTF
//!   holds them.

mod buildings;
mod document;
mod frame;
mod glb;
mod instances;

#[cfg(test)]
mod read;

pub use buildings::buildings_glb;
pub use glb::Glb;
pub use instances::{InstancesGlb, ModelMesh, instances_glb};
