//! What the daemon's bench binaries share: loading a scene (its picture
//! checked, as reliefd loads it), and the helpers of every crate's benches.

#![allow(dead_code, unused_imports, reason = "each bench binary uses part of it")]

use std::path::Path;

use relief_daemon::scene::Scene;
pub use relief_tests::bench::*;

/// The scene of `manifest` with a tile pool of `threads`; every source must load.
pub fn load(manifest: &Path, threads: usize) -> anyhow::Result<Scene> {
    match Scene::load_checked(manifest, false, threads, relief_daemon::picture::check) {
        Ok((scene, _)) => Ok(scene),
        Err(errors) => anyhow::bail!("bench scene {} does not load: {errors:?}", manifest.display()),
    }
}
