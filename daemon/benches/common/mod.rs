//! What the bench binaries share: loading a scene, and medians.

#![allow(dead_code, reason = "each bench binary uses part of it")]

use std::path::Path;

use relief_daemon::scene::Scene;

/// The scene of `manifest` with a tile pool of `threads`; every source must load.
pub fn load(manifest: &Path, threads: usize) -> anyhow::Result<Scene> {
    match Scene::load(manifest, false, threads) {
        Ok((scene, _)) => Ok(scene),
        Err(errors) => anyhow::bail!("bench scene {} does not load: {errors:?}", manifest.display()),
    }
}

pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}
