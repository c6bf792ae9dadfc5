//! Prometheus metrics on a loopback listener: scraped before and after a
//! render, a tile, an edit, a failed read and an open event stream, and
//! each number moves as it must.

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::fixtures;
use relief_tests::{edit, http, scenes};

/// The value of the sample `name` (with its labels, as printed), if any.
fn value(page: &str, name: &str) -> Option<f64> {
    page.lines().filter(|l| !l.starts_with('#')).find_map(|l| {
        let (n, v) = l.rsplit_once(' ')?;
        (n == name).then(|| v.parse().ok()).flatten()
    })
}

async fn scrape(url: &str) -> anyhow::Result<String> {
    let url = url.to_owned();
    let reply = tokio::task::spawn_blocking(move || http::get(&url)).await??;
    anyhow::ensure!(reply.status == 200, "metrics answered {}", reply.status);
    Ok(String::from_utf8(reply.body)?)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_move_with_reloads_tiles_renders_streams_and_errors() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "[effects]\nlighting = {}\n")?;
    let daemon = Reliefd::start(&manifest, &["--metrics-listen", "127.0.0.1:0"])?;
    let url = daemon.printed("metrics: ").ok_or_else(|| anyhow::anyhow!("no metrics line"))?;
    assert!(url.starts_with("http://127.0.0.1:") && url.ends_with("/metrics"), "{url}");
    let channel = daemon.channel().await?;

    let before = scrape(&url).await?;
    assert!(before.contains("# TYPE relief_tile_cache_hits_total counter"), "{before}");
    assert_eq!(value(&before, "relief_generations_total").unwrap_or(0.0), 0.0);
    assert_eq!(value(&before, r#"relief_streams_active{kind="events"}"#).unwrap_or(0.0), 0.0);

    // A render and a tile.
    scenes::render_rgba(&channel, scenes::camera(10.25, 45.1, 9000.0, 0.0, -45.0), (160, 90)).await?;
    edit::tile_hash(channel.clone(), "dem", (0, 0, 0)).await?;
    // An open event stream.
    let mut events =
        SceneServiceClient::new(channel.clone()).watch(pb::WatchRequest { from_generation: 0 }).await?.into_inner();
    events.message().await?;
    // An edit, and a failed read.
    let path = dir.path().join("hill.tif");
    edit::rewrite_window(&path, 100, 100, 16, 16, |_, _, h| h + 40.0)?;
    edit::wait_for(channel.clone(), 2).await?;
    std::fs::write(&path, b"not a GeoTIFF any more")?;
    let mut scene = SceneServiceClient::new(channel.clone());
    let state = edit::wait_for_status(&mut scene, "dem", pb::SourceStatus::Error).await?;

    let after = scrape(&url).await?;
    assert!(after.contains("# HELP relief_reload_seconds"), "{after}");
    let generations = value(&after, "relief_generations_total").unwrap_or(0.0);
    // Generation 1 is the load; each after it was published.
    assert_eq!(generations, (state.generation - 1) as f64, "{after}");
    assert_eq!(value(&after, r#"relief_reload_seconds_count{kind="gdal"}"#), Some(1.0), "{after}");
    assert_eq!(value(&after, r#"relief_reload_seconds_bucket{kind="gdal",le="30"}"#), Some(1.0), "{after}");
    assert!(value(&after, "relief_tiles_rebuilt_total").is_some(), "{after}");
    assert!(value(&after, "relief_tiles_carried_total").is_some(), "{after}");
    assert!(value(&after, "relief_tile_cache_misses_total").unwrap_or(0.0) > 0.0, "{after}");
    assert!(value(&after, "relief_tile_cache_bytes").unwrap_or(0.0) > 0.0, "{after}");
    // The tile at level 0 read the DEM's coarse levels, which the raster
    // cache holds (the base level of a small raster is held whole, apart).
    let raster_bytes = value(&after, "relief_raster_cache_bytes").unwrap_or(0.0);
    assert!(raster_bytes > 0.0, "{after}");
    let counters = state.counters.clone().unwrap_or_default();
    assert_eq!(counters.raster_cache_budget_bytes, 512 << 20, "the default raster_mb: {counters:?}");
    assert!(counters.raster_cache_bytes > 0, "{counters:?}");
    assert!(value(&after, r#"relief_tiles_generated_total{source="dem"}"#).unwrap_or(0.0) > 0.0, "{after}");
    assert_eq!(value(&after, r#"relief_render_pass_seconds_count{pass="terrain"}"#), Some(1.0), "{after}");
    assert_eq!(value(&after, r#"relief_streams_active{kind="events"}"#), Some(1.0), "{after}");
    assert_eq!(value(&after, r#"relief_source_errors_total{source="dem"}"#), Some(1.0), "{after}");

    // The tile again: a hit.
    let hits = value(&after, "relief_tile_cache_hits_total").unwrap_or(0.0);
    // The stream closed: the server sees it at its next event, the restore.
    drop(events);
    fixtures::write_dem(&path, &fixtures::hill_spec(), fixtures::hill)?;
    edit::wait_for(channel.clone(), state.generation + 1).await?;
    edit::tile_hash(channel.clone(), "dem", (0, 0, 0)).await?;
    edit::tile_hash(channel.clone(), "dem", (0, 0, 0)).await?;
    let last = scrape(&url).await?;
    assert!(value(&last, "relief_tile_cache_hits_total").unwrap_or(0.0) > hits, "{last}");
    assert!(value(&last, "relief_generations_total").unwrap_or(0.0) > generations, "{last}");
    assert_eq!(value(&last, r#"relief_streams_active{kind="events"}"#), Some(0.0), "{last}");
    daemon.stop(&["keeping the last good version"])?;
    Ok(())
}
