//! The scene engine: the manifest, the registry of source kinds, the
//! source graph and its snapshots, the tile store and its memory cache,
//! content addresses and the outer stores (disk, Redis), the watcher,
//! refresh and publish. Public is what a server needs: load a scene
//! (`scene::Scene::load`), take a snapshot (`graph::SceneSnapshot`), ask for
//! tiles (`tiles::TileStore`), subscribe to generations, reload, and the
//! manifest it was loaded from; the rest is the engine's own.
//!
//! It knows no transport, no renderer and no proto: its dependencies are
//! the source crates and plain libraries (`tests/tests/architecture.rs`
//! checks `cargo tree -p relief-engine` for the serving crates).

mod addressing;
mod backing;
mod content;
pub mod graph;
pub mod manifest;
pub mod parameters;
mod priority;
mod registry;
pub mod scene;
#[cfg(test)]
mod testing;
mod tile;
pub mod tiles;
pub mod watcher;
