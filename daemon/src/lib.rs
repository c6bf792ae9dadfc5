//! reliefd's library: the scene manifest, the source graph, the tile store
//! and scheduler, file watching and the gRPC service.
//!
//! It depends on the source crates (registered in `registry`) and on
//! relief-proto at the gRPC edge only (`service`). Frames are drawn by
//! relief-renderer; `view` feeds it the scene's tiles and owns the camera.

pub mod addressing;
pub mod backing;
pub mod camera;
pub mod codec;
pub mod content;
pub mod effects;
pub mod frames;
pub mod graph;
pub mod manifest;
pub mod navigate;
pub mod picture;
mod priority;
pub mod registry;
pub mod scene;
pub mod scene_tiles;
pub mod service;
pub mod sun;
#[cfg(test)]
mod testing;
pub mod tile;
pub mod tiles;
pub mod view;
pub mod watcher;
