//! The scene's tiles as the renderer asks for them, each answered from the
//! tile store (built in parallel when missing): terrain samples from the
//! height and colour layers (`terrain.rs`), building meshes from the
//! `buildings` layer (`buildings.rs`), instances and their models from the
//! `instances` layer (`instances.rs`).

mod buildings;
mod instances;
mod layer;
mod terrain;

pub use buildings::{SceneBuildings, building_min_level};
pub use instances::{ModelCache, SceneInstances, instance_level};
pub use terrain::SceneTerrain;
