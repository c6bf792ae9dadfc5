//! Two replicas of one scene sharing a real Redis: a tile one replica
//! built is served by the other without generating it, and an edit, which
//! each replica sees through its own watcher, reaches both with the same
//! tile content.

use std::time::Duration;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::redis::Redis;
use relief_tests::{edit, scenes};
use tonic::transport::Channel;

const PEAK: (u32, u32, u32) = (10, 1082, 254);

async fn state(channel: &Channel) -> anyhow::Result<pb::SceneState> {
    Ok(SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await?.into_inner())
}

/// The dem's content address, once worked out.
async fn address(channel: &Channel) -> anyhow::Result<String> {
    for _ in 0..400 {
        let s = state(channel).await?;
        if let Some(a) = s.sources.iter().find(|s| s.id == "dem").and_then(|s| s.details.get("content_address")) {
            return Ok(a.clone());
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    anyhow::bail!("no content address")
}

fn generated(s: &pb::SceneState) -> u64 {
    s.sources.iter().find(|s| s.id == "dem").map_or(0, |s| s.tiles_generated)
}

fn redis_hits(s: &pb::SceneState) -> u64 {
    s.counters.as_ref().and_then(|c| c.outer_stores.iter().find(|o| o.name == "redis")).map_or(0, |o| o.hits)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn replicas_share_tiles_through_redis_and_both_see_an_edit() -> anyhow::Result<()> {
    let redis = Redis::start()?;
    let dir = tempfile::tempdir()?;
    let cache = format!("[cache]\ndisk_mb = 0\nredis = \"{}\"\n", redis.url());
    let manifest = scenes::hill(dir.path(), &cache)?;
    let one = Reliefd::start(&manifest, &[])?;
    let two = Reliefd::start(&manifest, &[])?;
    let (a, b) = (one.channel().await?, two.channel().await?);
    assert_eq!(address(&a).await?, address(&b).await?, "replicas of one scene share content addresses");

    // Replica one builds the tile; replica two takes it from Redis.
    let built = edit::tile_hash(a.clone(), "dem", PEAK).await?;
    assert!(generated(&state(&a).await?) > 0);
    // The write to Redis is in the background: wait until it is there.
    for _ in 0..200 {
        if redis.count("relief:tile:*")? > 0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    let hash = edit::tile_hash(b.clone(), "dem", PEAK).await?;
    let after = state(&b).await?;
    assert!(redis_hits(&after) > 0, "replica two did not take the tile from Redis: {:?}", after.counters);
    assert_eq!(hash, built, "the shared tile is the one replica one built");
    assert_eq!(generated(&after), 0, "replica two generated tiles");

    // An edit: each replica sees it itself, and both serve the same new tile.
    edit::rewrite_window(&dir.path().join("hill.tif"), 150, 150, 100, 100, |_, _, h| h + 60.0)?;
    edit::wait_for(a.clone(), 2).await?;
    edit::wait_for(b.clone(), 2).await?;
    let (new_a, new_b) =
        (edit::tile_hash(a.clone(), "dem", PEAK).await?, edit::tile_hash(b.clone(), "dem", PEAK).await?);
    assert_ne!(new_a, built, "the edit did not reach replica one");
    assert_eq!(new_a, new_b, "the replicas disagree after the edit");
    one.stop(&[])?;
    two.stop(&[])?;
    Ok(())
}
