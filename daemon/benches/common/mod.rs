//! What the bench binaries share: loading a scene, medians, settings from
//! the environment, and a running reliefd's state.

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

/// The number in environment variable `name`, or `default`.
pub fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

/// The daemon's GetState answer.
pub async fn state(channel: &tonic::transport::Channel) -> anyhow::Result<relief_proto::v1::SceneState> {
    let mut client = relief_proto::v1::scene_service_client::SceneServiceClient::new(channel.clone());
    Ok(client.get_state(relief_proto::v1::GetStateRequest {}).await?.into_inner())
}
