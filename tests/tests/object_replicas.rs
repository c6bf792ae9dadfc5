//! Three replicas of one scene whose DEM is an object on a real
//! S3-compatible server (moto), sharing one real Redis: they agree on the
//! content addresses, each tile is generated once between them, an
//! overwritten object brings all three to the new content with each new
//! tile again generated once, and a replica killed outright loses nothing:
//! its viewer's event stream continues on another replica.

use std::time::{Duration, Instant};

use relief_examples as fixtures;
use relief_tests::daemon::Reliefd;
use relief_tests::redis::Redis;
use relief_tests::s3::S3Server;
use relief_tests::{edit, http};

/// Tiles over the hill (level, x, y).
const TILES: [(u32, u32, u32); 4] = [(7, 135, 31), (9, 541, 127), (10, 1082, 254), (10, 1083, 254)];
const SLOPE: (f64, f64) = (10.3, 45.3);

fn state(daemon: &Reliefd) -> anyhow::Result<serde_json::Value> {
    http::get(&format!("{}/api/state", daemon.url()))?.json()
}

fn number(value: &serde_json::Value) -> u64 {
    value.as_str().and_then(|s| s.parse().ok()).unwrap_or(0)
}

/// Tiles the replica generated for the DEM, and its Redis hits.
fn work(daemon: &Reliefd) -> anyhow::Result<(u64, u64)> {
    let s = state(daemon)?;
    let generated = number(&s["sources"][0]["tilesGenerated"]);
    let stores = s["counters"]["outerStores"].as_array().cloned().unwrap_or_default();
    let hits = stores.iter().find(|o| o["name"] == "redis").map_or(0, |o| number(&o["hits"]));
    Ok((generated, hits))
}

/// The DEM's content address once worked out, waiting for one other than
/// `not`.
fn address(daemon: &Reliefd, not: &str) -> anyhow::Result<String> {
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs(20) {
        let s = state(daemon)?;
        if let Some(a) = s["sources"][0]["details"]["content_address"].as_str()
            && a != not
        {
            return Ok(a.to_owned());
        }
        std::thread::sleep(Duration::from_millis(25));
    }
    anyhow::bail!("no new content address")
}

/// Asks every tile of `TILES` of `first`, waits for Redis to hold them,
/// then asks the others: the tiles' hashes, as every replica gave them.
async fn ask_everywhere(first: &Reliefd, others: &[&Reliefd], redis: &Redis, held: usize) -> anyhow::Result<Vec<u64>> {
    let mut hashes = Vec::new();
    for key in TILES {
        hashes.push(edit::tile_hash(first.channel().await?, "dem", key).await?);
    }
    let started = Instant::now();
    while redis.count("relief:tile:*")? < held + TILES.len() && started.elapsed() < Duration::from_secs(20) {
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    for other in others {
        for (key, hash) in TILES.iter().zip(&hashes) {
            assert_eq!(
                edit::tile_hash(other.channel().await?, "dem", *key).await?,
                *hash,
                "replicas disagree on {key:?}"
            );
        }
    }
    Ok(hashes)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn three_replicas_on_one_object_agree_generate_each_tile_once_and_survive_a_kill() -> anyhow::Result<()> {
    let redis = Redis::start()?;
    let s3 = S3Server::start()?;
    s3.create_bucket("replicas")?;
    let dir = tempfile::tempdir()?;
    let plain = fixtures::write_dem(&dir.path().join("plain.tif"), &fixtures::hill_spec(), fixtures::hill)?;
    let cog = dir.path().join("hill.tif");
    let status = std::process::Command::new("gdal_translate")
        .args(["-q", "-co", "TILED=YES", "-co", "BLOCKXSIZE=128", "-co", "BLOCKYSIZE=128", "-co", "COMPRESS=DEFLATE"])
        .arg(&plain)
        .arg(&cog)
        .status()?;
    anyhow::ensure!(status.success(), "gdal_translate failed");
    s3.put_file("replicas", "hill.tif", &cog)?;
    let text = format!(
        "[scene]\nname = \"replicas\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \
         \"s3://replicas/hill.tif\"\n\n[layers]\nheight = \"dem\"\n\n[cache]\ndisk_mb = 0\nredis = \"{}\"\n\n[watch]\npoll_s \
         = 0.5\n",
        redis.url()
    );
    let manifest = dir.path().join("scene.toml");
    std::fs::write(&manifest, text)?;
    let replicas: Vec<Reliefd> =
        (0..3).map(|_| Reliefd::start_with_env(&manifest, &[], &s3.env())).collect::<anyhow::Result<_>>()?;
    let first = address(&replicas[0], "")?;
    for r in &replicas[1..] {
        assert_eq!(address(r, "")?, first, "replicas of one object version share its content address");
    }

    // Replica 0 builds the tiles; replicas 1 and 2 read them from Redis.
    let before = ask_everywhere(&replicas[0], &[&replicas[1], &replicas[2]], &redis, 0).await?;
    let works: Vec<(u64, u64)> = replicas.iter().map(work).collect::<anyhow::Result<_>>()?;
    assert!(works[0].0 >= TILES.len() as u64, "{works:?}");
    assert_eq!((works[1].0, works[2].0), (0, 0), "only one replica generated tiles: {works:?}");
    assert!(works[1].1 >= TILES.len() as u64 && works[2].1 >= TILES.len() as u64, "{works:?}");

    // An overwrite reaches all three (each polls the store) with one new
    // content address; replica 1 builds the new tiles, the others read them.
    let gen_before: Vec<u64> =
        replicas.iter().map(|r| Ok(number(&state(r)?["generation"]))).collect::<anyhow::Result<_>>()?;
    let spec = fixtures::hill_spec();
    let (x, y) = (((SLOPE.0 - spec.origin_x) / spec.pixel) as usize, ((spec.origin_y - SLOPE.1) / spec.pixel) as usize);
    edit::rewrite_window(&cog, x - 4, y - 4, 8, 8, |_, _, v| v + 100.0)?;
    s3.put_file("replicas", "hill.tif", &cog)?;
    let second = address(&replicas[0], &first)?;
    for (r, g) in replicas.iter().zip(&gen_before) {
        assert_eq!(address(r, &first)?, second, "every replica took the new version");
        assert!(number(&state(r)?["generation"]) > *g);
    }
    let held = redis.count("relief:tile:*")?;
    let works_before: Vec<(u64, u64)> = replicas.iter().map(work).collect::<anyhow::Result<_>>()?;
    let after = ask_everywhere(&replicas[1], &[&replicas[0], &replicas[2]], &redis, held).await?;
    assert_ne!(after, before, "the overwrite changed the tiles");
    let works: Vec<(u64, u64)> = replicas.iter().map(work).collect::<anyhow::Result<_>>()?;
    let built: Vec<u64> = works.iter().zip(&works_before).map(|(now, then)| now.0 - then.0).collect();
    assert_eq!(built[0] + built[2], 0, "the new tiles were built once, by the replica asked first: {built:?}");
    // (A tile the changed block does not touch was carried over, not built.)
    assert!(built[1] > 0 && built[1] <= TILES.len() as u64, "{built:?}");

    // A viewer of replica 2 at its generation; replica 2 is killed; the
    // viewer goes on with replica 0 from that generation: the snapshot,
    // then the next change.
    let mut replicas = replicas;
    let lost = replicas.pop().ok_or_else(|| anyhow::anyhow!("three replicas"))?;
    let seen = number(&state(&lost)?["generation"]);
    std::process::Command::new("kill").args(["-9", &lost.pid().to_string()]).status()?;
    drop(lost);
    let mut events = http::Events::open(&format!("{}/api/events?from={}", replicas[0].url(), seen + 10))?;
    let (name, data) = events.next_event()?.ok_or_else(|| anyhow::anyhow!("no snapshot"))?;
    assert!(name == "scene" && data.contains("snapshot"), "{name}: {data}");
    edit::rewrite_window(&cog, x - 4, y - 4, 8, 8, |_, _, v| v + 50.0)?;
    s3.put_file("replicas", "hill.tif", &cog)?;

    let (name, data) = events.next_event()?.ok_or_else(|| anyhow::anyhow!("no event after the overwrite"))?;
    assert!(name == "scene" && data.contains("generationChanged"), "{name}: {data}");
    for r in &replicas {
        let h = edit::height_at(r.channel().await?, SLOPE.0, SLOPE.1).await?.unwrap_or_default();
        let expected = fixtures::hill(SLOPE.0, SLOPE.1) + 150.0;
        let started = Instant::now();
        let mut h = h;
        while (h - expected).abs() > 1.0 && started.elapsed() < Duration::from_secs(10) {
            tokio::time::sleep(Duration::from_millis(50)).await;
            h = edit::height_at(r.channel().await?, SLOPE.0, SLOPE.1).await?.unwrap_or_default();
        }
        assert!((h - expected).abs() <= 1.0, "{h} at the slope, {expected} expected");
    }
    for r in replicas {
        r.stop(&[])?;
    }
    Ok(())
}
