//! relief-renderer: the scene drawn headless with wgpu.
//!
//! Geometry clipmaps (Losasso & Hoppe) nested under the camera, updated
//! coarse to fine as in Clasen's tiling chapter, on the WGS84 ellipsoid or a
//! flat projected grid, with eye-relative f32 on the GPU (Kooima). The
//! renderer knows tiles (through `TerrainSamples`) and cameras; never files
//! or gRPC.

mod camera;
mod clipmap;
mod detail;
mod dirt;
mod error;
mod gpu;
mod horizon;
mod navigate;
mod passes;
mod renderer;
mod surface;
mod target;
mod uniforms;

pub use camera::{MAX_ALTITUDE_M, NEAR_M, Pose, View};
pub use clipmap::{COLOR_DETAIL, ClipLevel, Clipmap, ClipmapConfig, Rect, StorageRect, TerrainSamples, UpdateStats};
pub use detail::{Detail, Detailed};
pub use dirt::Dirt;
pub use error::RenderError;
pub use gpu::Gpu;
pub use passes::atmosphere::Atmosphere;
pub use passes::buildings::MeshTiles;
pub use passes::counters::{ALL as PASSES, PassCounters, PassStats};
pub use passes::fog::Fog;
pub use passes::instances::{InstanceBands, InstanceTiles};
pub use passes::shadows::Shadows;
pub use passes::terrain::MAX_LEVELS;
pub use passes::water::{Water, WaterSamples};
pub use renderer::{Drawn, Frame, RenderSettings, Renderer, SceneLayers, SunAngles};
pub use surface::Surface;
