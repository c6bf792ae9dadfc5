//! The scene engine: the manifest, the registry of source kinds, the
//! source graph and its snapshots, the tile store and its memory cache,
//! content addresses and the outer stores (disk, Redis), the watcher,
//! refresh and publish. What a server needs: load a scene
//! (`scene::Scene::load`), take a snapshot, ask for tiles, subscribe to
//! generations, reload.
//!
//! It knows no transport, no renderer and no proto: its dependencies are
//! the source crates and plain libraries (`tests/tests/architecture.rs`
//! checks `cargo tree -p relief-engine` for the serving crates).

pub mod addressing;
pub mod backing;
pub mod content;
pub mod graph;
pub mod manifest;
mod priority;
pub mod registry;
pub mod scene;
#[cfg(test)]
mod testing;
pub mod tile;
pub mod tiles;
pub mod watcher;
