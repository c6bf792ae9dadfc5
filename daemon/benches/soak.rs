//! A soak on loopback: many StreamFrames viewers, a tile client and an
//! edit a second against one reliefd for minutes. Prints a row every 10 s
//! and totals; never asserts a time.
//!
//! The real reliefd serves the demo scene (lavapipe without a GPU), with
//! `--metrics-listen`. At once:
//! - viewers: gRPC StreamFrames streams at 320 x 180, max_fps 5, on the
//!   scene camera, each counting its frames and errors (a failed stream
//!   is counted and opened again);
//! - a tile client: GetTile for random keys over the DEM's extent, levels
//!   8 to 13, of the DEM, the orthophoto and the hillshade, at a steady
//!   rate, each call's latency kept;
//! - an editor: a 64 x 64 window of the DEM in view of the camera
//!   rewritten through GDAL once a second, to 2000 m and to 1000 m in
//!   turn (so the file alternates between two contents).
//!
//! Every 10 s a row: reliefd's resident set (VmRSS) beside what each of
//! its caches holds (GetState's `counters.memory`: the tile cache, the
//! raster blocks, the renderers' passes and targets, the frames held for
//! the streams) and the resident set less all of them (nobody's), frames
//! delivered and tiles requested in the interval, GetTile p50 and p99 in
//! the interval, the generation and the errors so far.
//! Then totals: p99 of GetTile over the run, errors of every kind (source
//! errors from GetState and the Watch stream too), the resident set
//! against the memory cache budget, and the relief_* lines of /metrics
//! for reloads and rebuilt tiles.
//!
//! With RELIEF_BENCH_SLOW and RELIEF_BENCH_IDLE (200 and 2000 for issue
//! 36's run; none by default), the second half of the run adds that many
//! slowloris connections (headers a byte a second) and idle ones (nothing
//! sent), each opened again when reliefd closes it, and the totals print
//! the viewers' frame rate and the resident set without them and with.
//!
//! `cargo bench -p relief-daemon --bench soak`; RELIEF_BENCH_SOAK_SECS
//! (default 600), RELIEF_BENCH_VIEWERS (default 50),
//! RELIEF_BENCH_TILES_PER_SEC (default 20), RELIEF_BENCH_CACHE (lines for
//! a `[cache]` section added to the demo manifest, as `memory_mb = 256`;
//! none by default).

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

#[path = "soak/abuse.rs"]
mod abuse;
mod common;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use common::{env_u64, state};
use relief_proto::v1 as pb;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::edit;
use tokio_stream::StreamExt;
use tonic::transport::Channel;

/// What the resident set may hold beyond what the two memory caches hold
/// (tiles, decoded raster blocks), stated from its parts: the renderer and
/// its device (lavapipe keeps its buffers and compiled shaders in process
/// memory: about 230 MB alone, of which GetState's `memory` counts the
/// renderers' passes and targets), rasters small enough to be held whole
/// (not in the raster cache's count), GDAL's own block cache (64 MB), the
/// disk store's write queue (up to about 90 MB), the sources, the frame
/// streams and the allocator's slack.
const OVERHEAD_ALLOWED_MB: f64 = 700.0;

/// The goal for the resident set: at most the two budgets and this.
const OVER_BUDGETS_MB: f64 = 150.0;

const SOURCES: [&str; 3] = ["dem", "ortho", "shade"];
const LEVELS: std::ops::RangeInclusive<u32> = 8..=13;

/// The edited window: DEM pixels, 500 to 564 east and 400 to 464 south of
/// the north-west corner (6.5 to 6.564 E, 45.136 to 45.2 N), in the
/// scene camera's view.
const WINDOW: (usize, usize) = (500, 400);

/// Counters every task adds to.
#[derive(Default)]
struct Tally {
    frames: AtomicU64,
    stream_errors: AtomicU64,
    tile_errors: AtomicU64,
    edit_errors: AtomicU64,
    edits: AtomicU64,
    tiles: AtomicU64,
    /// GetTile latencies (ms) since the last row.
    latencies: Mutex<Vec<f64>>,
    /// The first few error messages, each once.
    messages: Mutex<Vec<String>>,
}

impl Tally {
    fn note(&self, what: &str, message: impl std::fmt::Display) {
        let text = format!("{what}: {message}");
        let mut messages = self.messages.lock().expect("tally lock");
        if messages.len() < 8 && !messages.contains(&text) {
            messages.push(text);
        }
    }

    fn errors(&self) -> u64 {
        self.stream_errors.load(Ordering::Relaxed)
            + self.tile_errors.load(Ordering::Relaxed)
            + self.edit_errors.load(Ordering::Relaxed)
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn rss_mb(pid: u32) -> f64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmRSS:")).and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn mb(bytes: u64) -> f64 {
    bytes as f64 / f64::from(1 << 20)
}

/// One viewer: a stream of the scene camera's frames, opened again after
/// an error, until `stop`.
fn viewer(channel: Channel, tally: Arc<Tally>, stop: Arc<AtomicBool>) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let mut client = ViewServiceClient::new(channel).max_decoding_message_size(64 << 20);
        while !stop.load(Ordering::Relaxed) {
            let request = pb::StreamFramesRequest { width: 320, height: 180, max_fps: 5.0, ..Default::default() };
            let mut stream = match client.stream_frames(request).await {
                Ok(s) => s.into_inner(),
                Err(e) => {
                    tally.stream_errors.fetch_add(1, Ordering::Relaxed);
                    tally.note("StreamFrames open", e.message());
                    tokio::time::sleep(Duration::from_secs(1)).await;
                    continue;
                }
            };
            while !stop.load(Ordering::Relaxed) {
                match tokio::time::timeout(Duration::from_millis(500), stream.next()).await {
                    Ok(Some(Ok(_))) => {
                        tally.frames.fetch_add(1, Ordering::Relaxed);
                    }
                    Ok(Some(Err(e))) => {
                        tally.stream_errors.fetch_add(1, Ordering::Relaxed);
                        tally.note("StreamFrames", e.message());
                        tokio::time::sleep(Duration::from_secs(1)).await;
                        break;
                    }
                    Ok(None) => {
                        if !stop.load(Ordering::Relaxed) {
                            tally.stream_errors.fetch_add(1, Ordering::Relaxed);
                            tally.note("StreamFrames", "the stream ended");
                        }
                        break;
                    }
                    Err(_) => {}
                }
            }
        }
    })
}

/// Random tile keys of the scene's grid over `extent`, at `LEVELS`.
struct KeyRange {
    grid: pb::GridInfo,
    extent: pb::Extent,
}

impl KeyRange {
    fn random(&self, rng: &mut relief_examples::Lcg) -> (u32, u32, u32) {
        let level = rng.range(f64::from(*LEVELS.start()), f64::from(*LEVELS.end() + 1)).floor() as u32;
        let g = self.grid.extent.unwrap_or_default();
        let cols = f64::from(self.grid.level0_columns << level);
        let rows = f64::from(self.grid.level0_rows << level);
        let (w, h) = ((g.max_x - g.min_x) / cols, (g.max_y - g.min_y) / rows);
        let e = &self.extent;
        let x = rng.range((e.min_x - g.min_x) / w, (e.max_x - g.min_x) / w).floor().clamp(0.0, cols - 1.0);
        let y = rng.range((g.max_y - e.max_y) / h, (g.max_y - e.min_y) / h).floor().clamp(0.0, rows - 1.0);
        (level, x as u32, y as u32)
    }
}

/// GetTile at `per_sec` calls a second (or as fast as answers come).
fn tile_client(
    channel: Channel,
    keys: KeyRange,
    per_sec: u64,
    tally: Arc<Tally>,
    stop: Arc<AtomicBool>,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let mut client = TileServiceClient::new(channel).max_decoding_message_size(64 << 20);
        let mut rng = relief_examples::Lcg(11);
        let period = Duration::from_secs_f64(1.0 / per_sec.max(1) as f64);
        let mut next = Instant::now();
        while !stop.load(Ordering::Relaxed) {
            let source = SOURCES[(rng.next_f64() * SOURCES.len() as f64) as usize % SOURCES.len()];
            let (level, x, y) = keys.random(&mut rng);
            let request =
                pb::GetTileRequest { source_id: source.into(), key: Some(pb::TileKey { level, x, y }), quality: None };
            let asked = Instant::now();
            let answer = client.get_tile(request).await;
            let ms = asked.elapsed().as_secs_f64() * 1e3;
            tally.tiles.fetch_add(1, Ordering::Relaxed);
            match answer {
                Ok(_) => tally.latencies.lock().expect("tally lock").push(ms),
                Err(e) => {
                    tally.tile_errors.fetch_add(1, Ordering::Relaxed);
                    tally.note(&format!("GetTile {source} {level}/{x}/{y}"), e.message());
                }
            }
            next += period;
            let now = Instant::now();
            if next > now {
                tokio::time::sleep(next - now).await;
            } else {
                next = now;
            }
        }
    })
}

/// Rewrites the window once a second, to 2000 m and 1000 m in turn.
fn editor(dem: PathBuf, tally: Arc<Tally>, stop: Arc<AtomicBool>) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_secs(1));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        tick.tick().await;
        let mut k = 0u64;
        while !stop.load(Ordering::Relaxed) {
            tick.tick().await;
            let height = if k.is_multiple_of(2) { 2000.0 } else { 1000.0 };
            k += 1;
            let path = dem.clone();
            let written = tokio::task::spawn_blocking(move || {
                edit::rewrite_window(&path, WINDOW.0, WINDOW.1, 64, 64, |_, _, _| height)
            })
            .await;
            match written {
                Ok(Ok(())) => {
                    tally.edits.fetch_add(1, Ordering::Relaxed);
                }
                Ok(Err(e)) => {
                    tally.edit_errors.fetch_add(1, Ordering::Relaxed);
                    tally.note("edit", format!("{e:#}"));
                }
                Err(e) => {
                    tally.edit_errors.fetch_add(1, Ordering::Relaxed);
                    tally.note("edit", e);
                }
            }
        }
    })
}

/// Sources that are not healthy in `state`: (id, error).
fn unhealthy(state: &pb::SceneState) -> Vec<(String, String)> {
    state
        .sources
        .iter()
        .filter(|s| s.status != pb::SourceStatus::Ready as i32 || !s.error.is_empty())
        .map(|s| (s.id.clone(), s.error.clone()))
        .collect()
}

/// The lines of /metrics a soak reads: reloads, rebuilt tiles, errors.
fn metrics_lines(text: &str) -> Vec<&str> {
    const WANTED: [&str; 6] = [
        "relief_reload_seconds_count",
        "relief_reload_seconds_sum",
        "relief_tiles_rebuilt_total",
        "relief_tiles_cut_off_total",
        "relief_generations_total",
        "relief_source_errors_total",
    ];
    text.lines().filter(|l| WANTED.iter().any(|w| l.starts_with(w))).collect()
}

async fn start(manifest: &Path) -> anyhow::Result<(Reliefd, Option<String>)> {
    let manifest = manifest.to_owned();
    tokio::task::spawn_blocking(move || {
        let daemon = Reliefd::start(&manifest, &["--metrics-listen", "127.0.0.1:0"])?;
        let metrics = daemon.printed("metrics: ");
        Ok((daemon, metrics))
    })
    .await?
}

async fn run() -> anyhow::Result<()> {
    let secs = env_u64("RELIEF_BENCH_SOAK_SECS", 600);
    let viewers = env_u64("RELIEF_BENCH_VIEWERS", 50) as usize;
    let per_sec = env_u64("RELIEF_BENCH_TILES_PER_SEC", 20);
    let (slow, idle) = (env_u64("RELIEF_BENCH_SLOW", 0) as usize, env_u64("RELIEF_BENCH_IDLE", 0) as usize);
    if slow + idle > 0 {
        raise_open_file_limit();
    }

    let dir = tempfile::tempdir()?;
    let manifest = relief_examples::write_demo_scene(dir.path())?;
    let cache_lines = std::env::var("RELIEF_BENCH_CACHE").unwrap_or_default().replace("\\n", "\n");
    if !cache_lines.is_empty() {
        let mut text = std::fs::read_to_string(&manifest)?;
        anyhow::ensure!(!text.contains("\n[cache]"), "the demo manifest has a [cache] section of its own now");
        text.push_str("\n[cache]\n");
        text.push_str(&cache_lines);
        text.push('\n');
        std::fs::write(&manifest, text)?;
    }
    let dem = manifest.with_file_name("dem.tif");
    let (daemon, metrics_url) = start(&manifest).await?;
    let channel = daemon.channel().await?;
    // Warm up: the device opened, the first frame's tiles built.
    ViewServiceClient::new(channel.clone())
        .max_decoding_message_size(64 << 20)
        .render(pb::RenderRequest { width: 320, height: 180, ..Default::default() })
        .await
        .context("the warm-up frame")?;
    let first = state(&channel).await?;
    let counters = first.counters.clone().unwrap_or_default();
    // Both memory caches: tiles ([cache] memory_mb) and decoded raster
    // blocks ([cache] raster_mb).
    let (tile_budget_mb, raster_budget_mb) = (mb(counters.cache_budget_bytes), mb(counters.raster_cache_budget_bytes));
    let budget_mb = tile_budget_mb + raster_budget_mb;
    let keys = KeyRange {
        grid: first.grid.clone().context("GetState has no grid")?,
        extent: first.sources.iter().find(|s| s.id == "dem").and_then(|s| s.extent).unwrap_or_else(|| {
            let [min_x, min_y, max_x, max_y] = relief_examples::DEMO_EXTENT;
            pb::Extent { min_x, min_y, max_x, max_y }
        }),
    };

    println!("# Soak: {viewers} StreamFrames viewers, GetTile and an edit a second, for {secs} s, on loopback\n");
    println!("machine: {}", relief_tests::machine());
    let gpu = Path::new("/dev/nvidia0").exists() || Path::new("/dev/dri").exists();
    println!("renderer: {}", if gpu { "a GPU (wgpu's first adapter)" } else { "Mesa lavapipe (no GPU here)" });
    println!(
        "scene: the demo scene; viewers at 320 x 180, max_fps 5, the scene camera; GetTile at {per_sec}/s, random keys over the DEM's extent, levels {}-{}, sources {}; a 64 x 64 DEM window rewritten each second (2000 m, 1000 m in turn)",
        LEVELS.start(),
        LEVELS.end(),
        SOURCES.join(", ")
    );
    if slow + idle > 0 {
        println!(
            "abuse: from {} s on, {slow} slowloris connections (headers a byte a second) and {idle} idle ones (nothing sent), each opened again when reliefd closes it",
            secs / 2
        );
    }
    if !cache_lines.is_empty() {
        println!("[cache] added to the manifest: {}", cache_lines.replace('\n', "; "));
    }
    println!(
        "memory cache budgets: tiles ([cache] memory_mb) {tile_budget_mb:.0} MB + raster blocks ([cache] raster_mb) {raster_budget_mb:.0} MB = {budget_mb:.0} MB; goals: the resident set within the budgets + {OVER_BUDGETS_MB:.0} MB, and what no cache holds (RSS - every cache counted) flat\n"
    );
    println!(
        "| t s | RSS MB | tile cache MB | raster cache MB | renderers MB | frames held MB | RSS - tile and raster caches MB | nobody's (RSS - all) MB | frames delivered | tiles requested | GetTile p50 ms | GetTile p99 ms | generation | errors so far | abusive connections open |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");

    let events = edit::Events::follow(channel.clone()).await?;
    let tally = Arc::new(Tally::default());
    let stop = Arc::new(AtomicBool::new(false));
    let mut tasks = Vec::new();
    for _ in 0..viewers {
        tasks.push(viewer(channel.clone(), Arc::clone(&tally), Arc::clone(&stop)));
    }
    tasks.push(tile_client(channel.clone(), keys, per_sec, Arc::clone(&tally), Arc::clone(&stop)));
    tasks.push(editor(dem, Arc::clone(&tally), Arc::clone(&stop)));

    let started = Instant::now();
    let mut all_latencies = Vec::new();
    let mut rss = Vec::new();
    // RSS less what the two caches hold, at each row.
    let mut beyond_caches = Vec::new();
    // And less what the renderers and the frames hold too: nobody's.
    let mut nobodys = Vec::new();
    let mut unhealthy_seen: Vec<(String, String)> = Vec::new();
    let (mut frames_before, mut tiles_before) = (0, 0);
    let mut next_row = started;
    // Frame streams and the distinct views they show, at the last row.
    let mut streams: (u64, u64);
    // The abusive connections, once started; each row's (abused through
    // its interval, viewers' frames a second, RSS, nobody's).
    let abuse_at = (slow + idle > 0).then(|| started + Duration::from_secs(secs / 2));
    let mut abuse: Option<Arc<abuse::Abuse>> = None;
    let mut phases: Vec<(bool, f64, f64, f64)> = Vec::new();
    loop {
        let abused = abuse.is_some();
        next_row += Duration::from_secs(10);
        let end = started + Duration::from_secs(secs);
        tokio::time::sleep_until(next_row.min(end).into()).await;
        let t = started.elapsed().as_secs_f64();
        let r = rss_mb(daemon.pid());
        let s = state(&channel).await?;
        let c = s.counters.clone().unwrap_or_default();
        for bad in unhealthy(&s) {
            if !unhealthy_seen.contains(&bad) {
                unhealthy_seen.push(bad);
            }
        }
        let frames = tally.frames.load(Ordering::Relaxed);
        let tiles = tally.tiles.load(Ordering::Relaxed);
        let mut interval = std::mem::take(&mut *tally.latencies.lock().expect("tally lock"));
        interval.sort_by(f64::total_cmp);
        let errors = tally.errors() + events.errors().len() as u64;
        let caches = mb(c.cache_bytes) + mb(c.raster_cache_bytes);
        let part = |prefix: &str| mb(c.memory.iter().filter(|m| m.name.starts_with(prefix)).map(|m| m.bytes).sum());
        let (renderers, frames_held) = (part("renderer: "), part("frames held"));
        println!(
            "| {t:.0} | {r:.0} | {:.0} | {:.0} | {renderers:.0} | {frames_held:.0} | {:.0} | {:.0} | {} | {} | {:.1} | {:.1} | {} | {errors} | {} |",
            mb(c.cache_bytes),
            mb(c.raster_cache_bytes),
            r - caches,
            r - caches - renderers - frames_held,
            frames - frames_before,
            tiles - tiles_before,
            percentile(&interval, 0.5),
            percentile(&interval, 0.99),
            s.generation,
            abuse.as_ref().map_or(0, |a| a.open.load(Ordering::Relaxed)),
        );
        let interval_s = t - phases.len() as f64 * 10.0;
        let each = (frames - frames_before) as f64 / interval_s.max(1.0) / viewers.max(1) as f64;
        phases.push((abused, each, r, r - caches - renderers - frames_held));
        (frames_before, tiles_before) = (frames, tiles);
        all_latencies.extend(interval);
        rss.push(r);
        beyond_caches.push(r - caches);
        nobodys.push(r - caches - renderers - frames_held);
        streams = (c.frame_streams, c.frame_views);
        if Instant::now() >= end {
            break;
        }
        if abuse.is_none() && abuse_at.is_some_and(|at| Instant::now() >= at) {
            let (started_abuse, abusers) = abuse::Abuse::start(&daemon.addr, slow, idle, &stop);
            abuse = Some(started_abuse);
            tasks.extend(abusers);
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    stop.store(true, Ordering::Relaxed);
    for task in tasks {
        let _ = task.await;
    }
    all_latencies.extend(std::mem::take(&mut *tally.latencies.lock().expect("tally lock")));
    all_latencies.sort_by(f64::total_cmp);

    let last = state(&channel).await?;
    let c = last.counters.clone().unwrap_or_default();
    for bad in unhealthy(&last) {
        if !unhealthy_seen.contains(&bad) {
            unhealthy_seen.push(bad);
        }
    }
    let source_events = events.errors();
    let frames = tally.frames.load(Ordering::Relaxed);
    let (min, max) = rss.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &r| (lo.min(r), hi.max(r)));
    let last_rss = rss.last().copied().unwrap_or(f64::NAN);
    // Growth from the second row (20 s) on, when the caches have filled.
    let settled = rss.get(1).copied().unwrap_or(f64::NAN);

    if let Some(a) = &abuse {
        println!("\n## Viewers without and with the abusive connections\n");
        println!(
            "| phase | rows | viewers' frames a second (each) | RSS MB mean / max | nobody's (RSS - every cache) MB mean |\n|---|---|---|---|---|"
        );
        // The first row (the caches filling) is left out of the first phase.
        for (label, with) in [("without", false), ("with", true)] {
            let rows: Vec<&(bool, f64, f64, f64)> = phases.iter().skip(1).filter(|p| p.0 == with).collect();
            let n = rows.len().max(1) as f64;
            let fps = rows.iter().map(|p| p.1).sum::<f64>() / n;
            let rss_mean = rows.iter().map(|p| p.2).sum::<f64>() / n;
            let rss_max = rows.iter().map(|p| p.2).fold(0.0f64, f64::max);
            let nobodys_mean = rows.iter().map(|p| p.3).sum::<f64>() / n;
            println!("| {label} | {} | {fps:.2} | {rss_mean:.0} / {rss_max:.0} | {nobodys_mean:.0} |", rows.len());
        }
        println!(
            "\nabusive connections: {} opened, {} closed by reliefd, the longest held {:.1} s",
            a.opened.load(Ordering::Relaxed),
            a.closed.load(Ordering::Relaxed),
            a.longest_ms.load(Ordering::Relaxed) as f64 / 1000.0
        );
    }
    println!("\n## Totals over {elapsed:.0} s\n");
    println!("| what | value |\n|---|---|");
    println!(
        "| GetTile calls; p50 / p99 / max ms | {}; {:.1} / {:.1} / {:.1} |",
        tally.tiles.load(Ordering::Relaxed),
        percentile(&all_latencies, 0.5),
        percentile(&all_latencies, 0.99),
        percentile(&all_latencies, 1.0)
    );
    println!(
        "| frames delivered (all viewers); per viewer per second | {frames}; {:.2} |",
        frames as f64 / viewers.max(1) as f64 / elapsed
    );
    println!(
        "| frames the hub rendered for streams; streams and distinct views at the last row | {}; {} and {} |",
        c.stream_frames_rendered, streams.0, streams.1
    );
    println!(
        "| edits written; generations | {}; {} (from {}) |",
        tally.edits.load(Ordering::Relaxed),
        last.generation,
        first.generation
    );
    println!("| reads retried (a writer still at work) | {} |", c.reads_retried);
    println!("| errors: viewer streams | {} |", tally.stream_errors.load(Ordering::Relaxed));
    println!("| errors: GetTile | {} |", tally.tile_errors.load(Ordering::Relaxed));
    println!("| errors: edits (GDAL writes) | {} |", tally.edit_errors.load(Ordering::Relaxed));
    println!(
        "| errors: sources (SourceError events; sources not ready in GetState) | {}; {} |",
        source_events.len(),
        unhealthy_seen.len()
    );
    println!("| reliefd RSS MB: min / max / last | {min:.0} / {max:.0} / {last_rss:.0} |");
    println!("| RSS growth from 20 s to the end MB | {:+.0} |", last_rss - settled);
    println!(
        "| memory cache budgets MB: tiles + raster blocks (counters.cache_budget_bytes, raster_cache_budget_bytes) | {tile_budget_mb:.0} + {raster_budget_mb:.0} |"
    );
    println!(
        "| caches at the end MB: tiles (entries); raster blocks | {:.0} ({}); {:.0} |",
        mb(c.cache_bytes),
        c.cache_entries,
        mb(c.raster_cache_bytes)
    );
    let (low, high) = beyond_caches.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &r| (lo.min(r), hi.max(r)));
    println!(
        "| RSS less what the caches hold MB: min / max / last | {low:.0} / {high:.0} / {:.0} |",
        beyond_caches.last().copied().unwrap_or(f64::NAN)
    );
    println!("| overhead = max (RSS - what the caches hold) MB (allowed {OVERHEAD_ALLOWED_MB:.0}) | {high:.0} |");
    let settled_nobody = nobodys.get(1).copied().unwrap_or(f64::NAN);
    println!(
        "| nobody's (RSS - every cache counted) MB: at 20 s / last; growth | {settled_nobody:.0} / {:.0}; {:+.0} |",
        nobodys.last().copied().unwrap_or(f64::NAN),
        nobodys.last().copied().unwrap_or(f64::NAN) - settled_nobody
    );
    for m in &c.memory {
        println!("| held at the end: {} MB | {:.1} |", m.name, mb(m.bytes));
    }
    println!("| max RSS - both budgets MB (goal: at most +{OVER_BUDGETS_MB:.0}) | {:+.0} |", max - budget_mb);
    for o in &c.outer_stores {
        println!("| outer store '{}': hits / misses / writes | {} / {} / {} |", o.name, o.hits, o.misses, o.writes);
    }
    let messages = tally.messages.lock().expect("tally lock").clone();
    for m in messages {
        println!("\nerror: {m}");
    }
    for e in source_events.iter().take(8) {
        println!("\nsource error: {}: {}", e.source_id, e.error);
    }
    for (id, error) in &unhealthy_seen {
        println!("\nsource not ready: {id}: {error}");
    }

    match metrics_url {
        Some(url) => {
            let scraped = tokio::task::spawn_blocking(move || relief_tests::http::request("GET", &url, None)).await??;
            let text = String::from_utf8_lossy(&scraped.body).into_owned();
            println!("\n## /metrics at the end (reloads and rebuilt tiles)\n\n```");
            for line in metrics_lines(&text) {
                println!("{line}");
            }
            println!("```");
        }
        None => println!("\n(reliefd printed no metrics address)"),
    }

    drop(channel);
    let log = daemon.log();
    let warnings: Vec<&String> = log.iter().filter(|l| l.contains(" WARN ") || l.contains(" ERROR ")).collect();
    println!("\nreliefd logged {} WARN or ERROR line(s)", warnings.len());
    for w in warnings.iter().take(5) {
        println!("    {w}");
    }
    // Its warnings are reported above; stop checks the clean exit.
    tokio::task::spawn_blocking(move || daemon.stop(&[" WARN ", " ERROR "])).await??;
    Ok(())
}

/// Thousands of sockets need more than the usual 1024 descriptors.
fn raise_open_file_limit() {
    use rustix::process::{Resource, Rlimit, getrlimit, setrlimit};
    let limit = getrlimit(Resource::Nofile);
    if let Some(maximum) = limit.maximum {
        let _ = setrlimit(Resource::Nofile, Rlimit { current: Some(maximum), maximum: Some(maximum) });
    }
}

fn main() -> anyhow::Result<()> {
    tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?.block_on(run())
}
