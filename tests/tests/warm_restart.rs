//! Warm restarts: tiles kept on disk under their content address are
//! served by the next reliefd without generating them; a file edited while
//! reliefd was down gets a new address, so its new content is served; the
//! cache folder deleted under a running daemon costs only its tiles.

use std::path::Path;
use std::time::Duration;

use anyhow::Context;
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::{edit, scenes};
use tonic::transport::Channel;

/// Tiles over the hill's peak, levels 5 to 10.
const KEYS: &[(u32, u32, u32)] = &[(5, 33, 7), (6, 67, 15), (7, 135, 31), (8, 270, 63), (9, 541, 127), (10, 1082, 254)];

/// The state, once the `dem` source's content address is worked out.
async fn addressed(channel: &Channel) -> anyhow::Result<pb::SceneState> {
    let mut scene = SceneServiceClient::new(channel.clone());
    for _ in 0..400 {
        let state = scene.get_state(pb::GetStateRequest {}).await?.into_inner();
        if state.sources.iter().any(|s| s.id == "dem" && s.details.contains_key("content_address")) {
            return Ok(state);
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    anyhow::bail!("the dem's content address was never worked out")
}

fn address(state: &pb::SceneState) -> String {
    state
        .sources
        .iter()
        .find(|s| s.id == "dem")
        .and_then(|s| s.details.get("content_address").cloned())
        .unwrap_or_default()
}

fn generated(state: &pb::SceneState) -> u64 {
    state.sources.iter().find(|s| s.id == "dem").map_or(0, |s| s.tiles_generated)
}

fn disk(state: &pb::SceneState) -> pb::OuterStore {
    let counters = state.counters.clone().unwrap_or_default();
    counters.outer_stores.into_iter().find(|o| o.name == "disk").unwrap_or_default()
}

async fn hashes(channel: &Channel) -> anyhow::Result<Vec<u64>> {
    let mut out = Vec::new();
    for &key in KEYS {
        out.push(edit::tile_hash(channel.clone(), "dem", key).await?);
    }
    Ok(out)
}

fn tiles_in(dir: &Path) -> usize {
    walk(dir).iter().filter(|p| p.extension().is_some_and(|e| e == "tile")).count()
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    entries.flatten().flat_map(|e| if e.path().is_dir() { walk(&e.path()) } else { vec![e.path()] }).collect()
}

async fn wait_for_tiles(dir: &Path, at_least: usize) -> anyhow::Result<()> {
    for _ in 0..400 {
        if tiles_in(dir) >= at_least {
            return Ok(());
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    anyhow::bail!("{} tiles on disk, expected {at_least}", tiles_in(dir))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restarted_daemon_serves_its_tiles_from_disk_and_never_stale_ones() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "[cache]\ndisk_dir = \"tile-cache\"\n")?;
    let cache = dir.path().join("tile-cache");

    // Cold: every tile generated, then written to disk.
    let first = Reliefd::start(&manifest, &[])?;
    let channel = first.channel().await?;
    let cold_state = addressed(&channel).await?;
    let cold = hashes(&channel).await?;
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await?.into_inner();
    assert!(generated(&state) >= KEYS.len() as u64, "{}", generated(&state));
    wait_for_tiles(&cache, KEYS.len()).await?;
    first.stop(&[])?;

    // Warm: the same tiles, none generated.
    let second = Reliefd::start(&manifest, &[])?;
    let channel = second.channel().await?;
    let warm_state = addressed(&channel).await?;
    assert_eq!(address(&warm_state), address(&cold_state), "the same files give the same address");
    assert_eq!(hashes(&channel).await?, cold);
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await?.into_inner();
    assert_eq!(generated(&state), 0, "a warm restart generated tiles");
    assert!(disk(&state).hits >= KEYS.len() as u64, "{:?}", disk(&state));
    second.stop(&[])?;

    // An edit while no daemon runs: a new address, and the new content.
    edit::rewrite_window(&dir.path().join("hill.tif"), 0, 0, 400, 400, |_, _, h| h + 25.0)?;
    let third = Reliefd::start(&manifest, &[])?;
    let channel = third.channel().await?;
    let edited_state = addressed(&channel).await?;
    assert_ne!(address(&edited_state), address(&cold_state), "an edited file kept its address");
    let edited = hashes(&channel).await?;
    for (k, (new, old)) in edited.iter().zip(&cold).enumerate() {
        assert_ne!(new, old, "tile {:?} of the edited DEM is the old one", KEYS[k]);
    }
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await?.into_inner();
    assert!(generated(&state) > 0, "nothing was generated for the edited file");

    // The cache folder deleted under the daemon: it goes on, and writes anew.
    std::fs::remove_dir_all(&cache).context("cannot delete the cache")?;
    let quality = pb::QualityOverrides { resampling: Some("cubic".into()), ..Default::default() };
    let request = pb::GetTileRequest {
        source_id: "dem".into(),
        key: Some(pb::TileKey { level: 6, x: 67, y: 15 }),
        quality: Some(quality),
    };
    relief_proto::v1::tile_service_client::TileServiceClient::new(channel.clone()).get_tile(request).await?;
    wait_for_tiles(&cache, 1).await?;
    assert_eq!(hashes(&channel).await?, edited, "tiles in memory are untouched");
    third.stop(&[])?;
    Ok(())
}
