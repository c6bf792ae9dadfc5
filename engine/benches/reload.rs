//! Live-reload latency benchmark. Prints tables; never asserts a time.
//!
//! A 3601 x 3601 DEM (one SRTM1 tile's worth) is served by the real
//! reliefd with every tile of levels 0..=12 over it cached. Each edit
//! rewrites a random 64 x 64 window through GDAL in update mode; the time
//! runs from the start of the edit until WaitForGeneration returns, which
//! includes reading the file, finding the changed blocks, and rebuilding
//! the cached tiles they touch. Repeated for each `[watch]` setting.
//!
//! `cargo bench -p relief-engine --bench reload` (RELIEF_BENCH_EDITS, default 25).

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

use std::time::Instant;

use relief_examples::{Lcg, RasterSpec, write_dem, write_manifest};
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::edit::{self, Events};

const SIDE: usize = 3601;
const MAX_LEVEL: u32 = 12;

fn terrain(lon: f64, lat: f64) -> f64 {
    relief_examples::demo_terrain(6.0 + (lon - 7.0), 45.0 + (lat - 43.0) * 0.6)
}

/// Every tile of levels 0..=MAX_LEVEL over lon 7..8, lat 43..44.
fn keys() -> Vec<(u32, u32, u32)> {
    let mut keys = Vec::new();
    for l in 0..=MAX_LEVEL {
        let span = 180.0 / f64::from(1u32 << l);
        for y in ((90.0 - 44.0) / span).floor() as u32..((90.0 - 43.0) / span).ceil() as u32 {
            for x in ((7.0 + 180.0) / span).floor() as u32..((8.0 + 180.0) / span).ceil() as u32 {
                keys.push((l, x, y));
            }
        }
    }
    keys
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

struct Run {
    label: String,
    latencies_ms: Vec<f64>,
    rebuilt: Vec<u64>,
    cached: usize,
    full_ms: f64,
    retried: u64,
}

async fn run(dir: &std::path::Path, label: &str, watch: &str, edits: usize, seed: u64) -> anyhow::Result<Run> {
    let manifest = write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"reload-bench\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"dem.tif\"\n\n[layers]\nheight = \"dem\"\n\n[cache]\nmemory_mb = 2048\n\n[watch]\n{watch}\n"
        ),
    )?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let channel = daemon.channel().await?;
    let keys = keys();
    let started = Instant::now();
    for k in &keys {
        edit::tile_hash(channel.clone(), "dem", *k).await?;
    }
    let full_ms = started.elapsed().as_secs_f64() * 1e3;
    let events = Events::follow(channel.clone()).await?;
    let mut rng = Lcg(seed);
    let (mut latencies_ms, mut rebuilt) = (Vec::new(), Vec::new());
    let mut generation = 1;
    let path = dir.join("dem.tif");
    for n in 0..edits {
        let (x, y) = (rng.range(0.0, (SIDE - 64) as f64) as usize, rng.range(0.0, (SIDE - 64) as f64) as usize);
        let t0 = Instant::now();
        edit::rewrite_window(&path, x, y, 64, 64, |_, _, h| h + 10.0 + n as f32)?;
        let state = edit::wait_for(channel.clone(), generation + 1).await?;
        latencies_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        generation = state.generation;
        rebuilt.push(events.generation(generation).await?.tiles_rebuilt);
    }
    let state = SceneServiceClient::new(channel).get_state(pb::GetStateRequest {}).await?.into_inner();
    if std::env::var_os("RELIEF_TEST_LOG").is_some() {
        for line in daemon.log().iter().rev().take(12).rev() {
            println!("{line}");
        }
    }
    daemon.stop(&[])?;
    Ok(Run {
        label: label.into(),
        latencies_ms,
        rebuilt,
        cached: keys.len(),
        full_ms,
        retried: state.counters.unwrap_or_default().reads_retried,
    })
}

fn main() -> anyhow::Result<()> {
    let edits: usize = std::env::var("RELIEF_BENCH_EDITS").ok().and_then(|v| v.parse().ok()).unwrap_or(25);
    let dir = tempfile::tempdir()?;
    let pixel = 1.0 / 3600.0;
    let spec = RasterSpec {
        width: SIDE,
        height: SIDE,
        origin_x: 7.0 - pixel / 2.0,
        origin_y: 44.0 + pixel / 2.0,
        pixel,
        crs: "EPSG:4326",
        nodata: Some(-32768.0),
    };
    write_dem(&dir.path().join("dem.tif"), &spec, terrain)?;

    let settings = [
        ("fast path + 500 ms quiet period (default)", "fast_path = true\ndebounce_ms = 500", edits),
        ("quiet period only, 50 ms", "fast_path = false\ndebounce_ms = 50", edits.min(10)),
        ("quiet period only, 100 ms", "fast_path = false\ndebounce_ms = 100", edits.min(10)),
        ("quiet period only, 250 ms", "fast_path = false\ndebounce_ms = 250", edits.min(10)),
        ("quiet period only, 500 ms", "fast_path = false\ndebounce_ms = 500", edits.min(10)),
    ];
    let runtime = tokio::runtime::Runtime::new()?;
    let runs: Vec<Run> = settings
        .iter()
        .enumerate()
        .map(|(i, (label, watch, n))| runtime.block_on(run(dir.path(), label, watch, *n, 17 + i as u64)))
        .collect::<anyhow::Result<_>>()?;

    println!("\n## Edit to WaitForGeneration: 64 x 64 window rewritten through GDAL in a {SIDE} x {SIDE} Float32 DEM");
    println!(
        "machine: {}; reliefd release build; every tile of levels 0..={MAX_LEVEL} over the DEM cached",
        relief_tests::machine()
    );
    println!(
        "| [watch] setting | edits | p50 ms | p95 ms | max ms | tiles rebuilt per edit (mean) | cached tiles (full rebuild) | full rebuild ms | reads retried |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for r in &runs {
        let mut sorted = r.latencies_ms.clone();
        sorted.sort_by(f64::total_cmp);
        let mean_rebuilt = r.rebuilt.iter().sum::<u64>() as f64 / r.rebuilt.len() as f64;
        println!(
            "| {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:.0} | {} |",
            r.label,
            sorted.len(),
            percentile(&sorted, 0.5),
            percentile(&sorted, 0.95),
            sorted[sorted.len() - 1],
            mean_rebuilt,
            r.cached,
            r.full_ms,
            r.retried
        );
    }
    Ok(())
}
