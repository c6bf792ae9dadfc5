//! What the engine's bench binaries share: loading a scene, and the
//! helpers of every crate's benches.

#![allow(dead_code, unused_imports, reason = "each bench binary uses part of it")]

use std::path::Path;

use relief_engine::scene::Scene;
pub use relief_tests::bench::*;

/// The scene of `manifest` with a tile pool of `threads`; every source must load.
pub fn load(manifest: &Path, threads: usize) -> anyhow::Result<Scene> {
    match Scene::load(manifest, false, threads) {
        Ok((scene, _)) => Ok(scene),
        Err(errors) => anyhow::bail!("bench scene {} does not load: {errors:?}", manifest.display()),
    }
}
