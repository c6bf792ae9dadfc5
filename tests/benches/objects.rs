//! Sources on object storage (issue 41), on real servers: moto's S3 and
//! Redis. Prints tables; never asserts a time.
//!
//! - start to first frame: from spawning reliefd to the first 200 of
//!   `GET /api/render` (256 x 256 PNG, lit), for a COG of over 1 GB on the
//!   S3 server against the same file on local disk (its pages cached by
//!   the kernel: the bench just made or read it), with the range GETs the
//!   S3 start made. moto copies the whole object for each range it serves
//!   (about a second a GET for this one), so the S3 time is mostly moto's:
//!   the GETs times a real store's latency say more;
//! - overwrite to new generation: one base block of a COG rewritten in
//!   place through GDAL (as an editor saves it) and the object uploaded
//!   whole; from the end of the PUT until `GET /api/wait` answers with the
//!   next generation, by polling (`poll_s = 1`) and by an S3 event notice
//!   (`poll_s = 0`, `POST /api/notify` right after the PUT). This uses a
//!   4096-pixel COG of the same layout: uploading the big one on every
//!   trial would time moto, not relief, which reads the block tables and
//!   the changed blocks whatever the object's size;
//! - bytes fetched per one-block change: `counters.objectBytesRead` across
//!   each overwrite, against the rewritten block's compressed size;
//! - replicas: a fixed list of distinct tiles over the small COG (over
//!   the big one moto's second a range would be the measure), requested
//!   round-robin from 1 and from 3 replicas sharing one Redis and the S3
//!   server by a few client threads; tiles per second in total, cold (each
//!   tile new) and warm (each tile asked of the next replica: Redis, or the
//!   one replica's memory), tiles generated per replica and Redis hits.
//!
//! `cargo bench -p relief-tests --bench objects` (the reliefd beside the
//! bench binary: `cargo build --release --bins` first). The COGs are made
//! once into target/objects-bench/ and reused. RELIEF_BENCH_RUNS (starts,
//! default 3), RELIEF_BENCH_EDITS (overwrites per mode, default 10),
//! RELIEF_BENCH_CLIENTS (client threads, default 4). moto keeps objects
//! in Python temporary files: TMPDIR decides where the big one lands.

#![expect(clippy::print_stdout, reason = "a bench binary prints its tables")]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, ensure};
use gdal::raster::{Buffer, RasterCreationOptions};
use gdal::{Dataset, DriverManager, Metadata as _};
use relief_source::{Extent, TileGrid, TileKey};
use relief_tests::bench::{env_u64, median};
use relief_tests::daemon::Reliefd;
use relief_tests::redis::Redis;
use relief_tests::s3::S3Server;
use relief_tests::{edit, http};

/// The DEMs' area in EPSG:4326: one degree square from its north-west corner.
const WEST: f64 = 10.0;
const NORTH: f64 = 46.0;
const SPAN_DEG: f64 = 1.0;
/// The big COG's side (3.4 m pixels) and the overwritten one's.
const BIG_PX: usize = 32768;
const SMALL_PX: usize = 4096;
const BLOCK_PX: usize = 512;
/// The base block the overwrites rewrite (column, row).
const EDITED_BLOCK: (usize, usize) = (3, 4);
const BUCKET: &str = "dems";
/// The replicas' tiles: level 12 has 24 x 23 tiles over the area.
const LEVEL: u8 = 12;
/// South of the area, 20 km up, looking north 45 degrees down.
const CAMERA: &str = "10.5,45.0,20000,0,-45,0";
const GIVE_UP: Duration = Duration::from_secs(120);

/// The nearest-rank percentile `p` (0..=100) of `v`.
fn percentile(mut v: Vec<f64>, p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    let rank = ((p / 100.0) * v.len() as f64).ceil() as usize;
    v.get(rank.saturating_sub(1)).copied().unwrap_or(f64::NAN)
}

/// A proto3 JSON number: 64-bit integers come as strings, zero not at all.
fn num(v: &serde_json::Value) -> u64 {
    v.as_u64().or_else(|| v.as_str().and_then(|s| s.parse().ok())).unwrap_or(0)
}

fn get_json(url: &str) -> anyhow::Result<serde_json::Value> {
    let reply = http::get(url)?;
    ensure!(reply.status == 200, "GET {url}: {} {}", reply.status, String::from_utf8_lossy(&reply.body));
    reply.json()
}

/// A COG of `size` x `size` Int16 heights over the area: smooth hills plus
/// 7 bits of noise that DEFLATE cannot shrink (so the 32768-pixel one is
/// over 1 GB), 512-pixel blocks, overviews by averaging down to one block.
/// Made in memory (GDAL's MEM driver, row by row of blocks), then copied
/// by GDAL's COG driver; a COG already there with this size is kept.
fn cog(path: &Path, size: usize) -> anyhow::Result<bool> {
    if Dataset::open(path).is_ok_and(|ds| ds.raster_size() == (size, size)) {
        return Ok(false);
    }
    let mut mem = DriverManager::get_driver_by_name("MEM")?.create_with_band_type::<i16, _>("", size, size, 1)?;
    let pixel_deg = SPAN_DEG / size as f64;
    mem.set_geo_transform(&[WEST, pixel_deg, 0.0, NORTH, 0.0, -pixel_deg])?;
    mem.set_spatial_ref(&gdal::spatial_ref::SpatialRef::from_epsg(4326)?)?;
    let wave = |i: usize, phase: f64| 250.0 * (i as f64 * 37.0 / size as f64 + phase).sin();
    let across: Vec<f64> = (0..size).map(|i| wave(i, 0.0)).collect();
    let mut band = mem.rasterband(1)?;
    let mut rng = 0x9E37_79B9_7F4A_7C15_u64;
    for top in (0..size).step_by(BLOCK_PX) {
        let mut rows = Vec::with_capacity(size * BLOCK_PX);
        for j in top..top + BLOCK_PX {
            let down = 600.0 + wave(j, 1.0);
            for a in &across {
                // xorshift64: the top 7 bits are the noise.
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                rows.push((down + a) as i16 + (rng >> 57) as i16);
            }
        }
        band.write((0, top as isize), (size, BLOCK_PX), &mut Buffer::new((size, BLOCK_PX), rows))?;
    }
    let factors: Vec<i32> =
        (1..usize::BITS).map(|k| 1_usize << k).take_while(|f| size / f >= BLOCK_PX).map(|f| f as i32).collect();
    mem.build_overviews("AVERAGE", &factors, &[])?;
    std::fs::create_dir_all(path.parent().context("the COG has a folder")?)?;
    let part = path.with_extension("part");
    let options = ["COMPRESS=DEFLATE", "BLOCKSIZE=512", "NUM_THREADS=ALL_CPUS", "BIGTIFF=IF_SAFER"];
    mem.create_copy(&DriverManager::get_driver_by_name("COG")?, &part, &RasterCreationOptions::from_iter(options))?;
    std::fs::rename(&part, path)?;
    Ok(true)
}

/// The offset and compressed size of base block (x, y) in a TIFF.
fn block_layout(path: &Path, (x, y): (usize, usize)) -> anyhow::Result<(u64, u64)> {
    let ds = Dataset::open(path)?;
    let band = ds.rasterband(1)?;
    let item = |what: &str| {
        band.metadata_item(&format!("BLOCK_{what}_{x}_{y}"), "TIFF")
            .and_then(|v| v.parse().ok())
            .with_context(|| format!("GDAL does not say block {x},{y}'s {what}: {}", path.display()))
    };
    Ok((item("OFFSET")?, item("SIZE")?))
}

/// Rewrites `EDITED_BLOCK` in place, every pixel raised by a step; again
/// with a larger step in the rare case it lands in place at its old size,
/// which a layout check cannot tell. The block's new compressed size.
fn rewrite_block(path: &Path) -> anyhow::Result<u64> {
    let (bx, by) = EDITED_BLOCK;
    let before = block_layout(path, EDITED_BLOCK)?;
    for step in 1..=4 {
        let step = step as f32;
        edit::rewrite_window(path, bx * BLOCK_PX, by * BLOCK_PX, BLOCK_PX, BLOCK_PX, |_, _, v| v + step)?;
        let after = block_layout(path, EDITED_BLOCK)?;
        if after != before {
            return Ok(after.1);
        }
    }
    anyhow::bail!("block {bx},{by} kept its offset and size through four rewrites: {}", path.display())
}

fn manifest(dir: &Path, name: &str, path: &str, extra: &str) -> anyhow::Result<PathBuf> {
    let text = format!(
        "[scene]\nname = \"objects-bench\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"{path}\"\n\n\
         [layers]\nheight = \"dem\"\n\n[effects]\nlighting = {{}}\n\n[cache]\ndisk_mb = 0\n{extra}\n"
    );
    let file = dir.join(name);
    std::fs::write(&file, text)?;
    Ok(file)
}

/// The range GETs (and plain GETs) moto has served of the big COG.
fn big_gets(s3: &S3Server) -> usize {
    s3.log().iter().filter(|l| l.contains(&format!("GET /{BUCKET}/big.tif "))).count()
}

/// Seconds from spawning reliefd to its first frame.
fn first_frame(manifest: &Path, env: &[(String, String)]) -> anyhow::Result<f64> {
    let start = Instant::now();
    let daemon = Reliefd::start_with_env(manifest, &[], env)?;
    let url = format!("{}/api/render?camera={CAMERA}&width=256&height=256&format=png", daemon.url());
    loop {
        let reply = http::get(&url)?;
        if reply.status == 200 {
            break;
        }
        ensure!(start.elapsed() < GIVE_UP, "no frame: {} {}", reply.status, String::from_utf8_lossy(&reply.body));
        std::thread::sleep(Duration::from_millis(20));
    }
    let secs = start.elapsed().as_secs_f64();
    daemon.stop(&[])?;
    Ok(secs)
}

/// One overwrite: ms from the PUT's end to the new generation, object
/// bytes relief read for it, and the rewritten block's compressed size.
struct Overwrite {
    ms: f64,
    bytes_read: u64,
    block_bytes: u64,
    /// Generations from the one before the upload to the new one.
    generations: u64,
}

/// `trials` overwrites of a copy of `small`, picked up by polling or by
/// an S3 event notice.
fn overwrites(s3: &S3Server, dir: &Path, small: &Path, webhook: bool, trials: u64) -> anyhow::Result<Vec<Overwrite>> {
    let key = if webhook { "notified.tif" } else { "polled.tif" };
    let copy = dir.join(key);
    std::fs::copy(small, &copy)?;
    s3.put_file(BUCKET, key, &copy)?;
    // Polled every second, or not at all (notices only).
    let watch = if webhook { "\n[watch]\npoll_s = 0\n" } else { "\n[watch]\npoll_s = 1\n" };
    let manifest = manifest(dir, &format!("scene-{key}.toml"), &format!("s3://{BUCKET}/{key}"), watch)?;
    let daemon = Reliefd::start_with_env(&manifest, &[], &s3.env())?;
    let url = daemon.url();
    let notice = serde_json::json!({"Records": [{"s3": {"bucket": {"name": BUCKET}, "object": {"key": key}}}]});
    let mut out = Vec::new();
    for _ in 0..trials {
        let before = get_json(&format!("{url}/api/state"))?;
        let block_bytes = rewrite_block(&copy)?;
        s3.put_file(BUCKET, key, &copy)?;
        let put = Instant::now();
        if webhook {
            let reply = http::request("POST", &format!("{url}/api/notify"), Some(&notice.to_string()))?;
            ensure!(reply.status == 200, "notify: {} {}", reply.status, String::from_utf8_lossy(&reply.body));
        }
        // The new generation is the first served after the change was
        // read: generations that read nothing (a poll's) do not count.
        let read = |s: &serde_json::Value| num(&s["counters"]["objectBytesRead"]);
        let mut after = before.clone();
        while read(&after) == read(&before) {
            ensure!(put.elapsed() < GIVE_UP, "no generation read s3://{BUCKET}/{key}'s change");
            let next = num(&after["generation"]) + 1;
            after = get_json(&format!("{url}/api/wait?generation={next}&timeout_ms={}", GIVE_UP.as_millis()))?;
        }
        let ms = put.elapsed().as_secs_f64() * 1000.0;
        let generations = num(&after["generation"]) - num(&before["generation"]);
        out.push(Overwrite { ms, bytes_read: read(&after) - read(&before), block_bytes, generations });
    }
    daemon.stop(&[])?;
    Ok(out)
}

/// Replicas of the big COG's scene: tiles per second cold and warm, tiles
/// generated by each, and Redis hits in total.
struct Served {
    per_s: [f64; 2],
    generated: Vec<u64>,
    redis_hits: u64,
}

fn replicas(s3: &S3Server, dir: &Path, replicas: usize, keys: &[TileKey], clients: usize) -> anyhow::Result<Served> {
    let redis = Redis::start()?;
    let cache = format!("redis = \"{}\"\n", redis.url());
    let manifest = manifest(dir, &format!("replicas-{replicas}.toml"), &format!("s3://{BUCKET}/small.tif"), &cache)?;
    let daemons =
        (0..replicas).map(|_| Reliefd::start_with_env(&manifest, &[], &s3.env())).collect::<Result<Vec<_>, _>>()?;
    let urls: Vec<String> = daemons.iter().map(Reliefd::url).collect();
    let mut per_s = [0.0; 2];
    for (pass, rate) in per_s.iter_mut().enumerate() {
        let start = Instant::now();
        request_all(&urls, keys, pass, clients)?;
        *rate = keys.len() as f64 / start.elapsed().as_secs_f64();
        // The writes to Redis are in the background: let them land.
        let mut last = usize::MAX;
        while redis.count("*")? != last {
            last = redis.count("*")?;
            std::thread::sleep(Duration::from_millis(200));
        }
    }
    let (mut generated, mut redis_hits) = (Vec::new(), 0);
    for url in &urls {
        let state = get_json(&format!("{url}/api/state"))?;
        generated.push(num(&state["sources"][0]["tilesGenerated"]));
        let stores = state["counters"]["outerStores"].as_array().cloned().unwrap_or_default();
        redis_hits += stores.iter().filter(|s| s["name"] == "redis").map(|s| num(&s["hits"])).sum::<u64>();
    }
    for daemon in daemons {
        daemon.stop(&[])?;
    }
    Ok(Served { per_s, generated, redis_hits })
}

/// Every tile of `keys` once, tile i from replica (i + pass) mod n, by
/// `clients` threads taking the next tile as each finishes one.
fn request_all(urls: &[String], keys: &[TileKey], pass: usize, clients: usize) -> anyhow::Result<()> {
    let next = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        let client = || -> anyhow::Result<()> {
            loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(k) = keys.get(i) else { return Ok(()) };
                let url = format!("{}/api/tiles/dem/{}/{}/{}", urls[(i + pass) % urls.len()], k.level, k.x, k.y);
                let reply = http::get(&url)?;
                ensure!(reply.status == 200, "GET {url}: {} {}", reply.status, String::from_utf8_lossy(&reply.body));
            }
        };
        let threads: Vec<_> = (0..clients).map(|_| scope.spawn(client)).collect();
        threads.into_iter().try_for_each(|t| t.join().map_err(|_| anyhow::anyhow!("a client thread panicked"))?)
    })
}

fn main() -> anyhow::Result<()> {
    let began = Instant::now();
    let (runs, edits) = (env_u64("RELIEF_BENCH_RUNS", 3), env_u64("RELIEF_BENCH_EDITS", 10));
    let clients = env_u64("RELIEF_BENCH_CLIENTS", 4) as usize;
    let store = relief_tests::workspace_root().join("target/objects-bench");
    let (big, small) = (store.join(format!("dem-{BIG_PX}.tif")), store.join(format!("dem-{SMALL_PX}.tif")));
    let made = Instant::now();
    let fresh = cog(&big, BIG_PX)? | cog(&small, SMALL_PX)?;
    let made_s = made.elapsed().as_secs_f64();
    let (big_bytes, small_bytes) = (std::fs::metadata(&big)?.len(), std::fs::metadata(&small)?.len());

    let s3 = S3Server::start()?;
    s3.create_bucket(BUCKET)?;
    let uploaded = Instant::now();
    s3.put_file(BUCKET, "big.tif", &big)?;
    let upload_s = uploaded.elapsed().as_secs_f64();
    s3.put_file(BUCKET, "small.tif", &small)?;
    let dir = tempfile::tempdir()?;
    let dir = dir.path();

    let on_s3 = manifest(dir, "s3.toml", &format!("s3://{BUCKET}/big.tif"), "")?;
    let on_disk = manifest(dir, "disk.toml", &big.display().to_string(), "")?;
    let (mut s3_s, mut disk_s, mut gets) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..runs {
        let before = big_gets(&s3);
        s3_s.push(first_frame(&on_s3, &s3.env())?);
        gets.push((big_gets(&s3) - before) as f64);
        disk_s.push(first_frame(&on_disk, &[])?);
    }

    let polled = overwrites(&s3, dir, &small, false, edits)?;
    let notified = overwrites(&s3, dir, &small, true, edits)?;

    let grid = TileGrid::geodetic(256).map_err(anyhow::Error::msg)?;
    let keys = grid.keys_overlapping(LEVEL, &Extent::new(WEST, NORTH - SPAN_DEG, WEST + SPAN_DEG, NORTH));
    let one = replicas(&s3, dir, 1, &keys, clients)?;
    let three = replicas(&s3, dir, 3, &keys, clients)?;

    println!("objects: {} (reliefd: {})", relief_tests::machine(), relief_tests::bin("reliefd").display());
    let gb = |b: u64| b as f64 / 1e9;
    println!(
        "big COG: {BIG_PX} x {BIG_PX} Int16, DEFLATE, 512-pixel blocks, overviews: {big_bytes} bytes ({:.2} GB), \
         uploaded to moto in {upload_s:.1} s; small COG (overwrites): {SMALL_PX} x {SMALL_PX}, same layout, \
         {small_bytes} bytes ({:.3} GB); {} in {made_s:.0} s",
        gb(big_bytes),
        gb(small_bytes),
        if fresh { "made" } else { "reused from target/objects-bench" },
    );
    println!();
    println!("| start to first frame (256 x 256 PNG), big COG | runs | p50 s | GETs p50 |");
    println!("|---|---:|---:|---:|");
    let (s3_p50, disk_p50) = (median(s3_s.clone()), median(disk_s.clone()));
    println!("| on the S3 server (moto, loopback) | {} | {s3_p50:.2} | {:.0} |", s3_s.len(), median(gets));
    println!("| the same file on local disk (page cache warm) | {} | {disk_p50:.2} | |", disk_s.len());
    println!("| ratio S3 / local | | {:.1} | |", s3_p50 / disk_p50);
    println!();
    println!(
        "| overwrite to new generation, small COG, one base block | trials | p50 ms | p95 ms | bytes read p50 | \
         block bytes p50 | read / block | generations p50 |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for (name, trials) in [("polling (poll_s = 1)", &polled), ("S3 event notice (POST /api/notify)", &notified)] {
        let ms: Vec<f64> = trials.iter().map(|t| t.ms).collect();
        let read = median(trials.iter().map(|t| t.bytes_read as f64).collect());
        let block = median(trials.iter().map(|t| t.block_bytes as f64).collect());
        let (p50, p95) = (median(ms.clone()), percentile(ms, 95.0));
        let generations = median(trials.iter().map(|t| t.generations as f64).collect());
        println!(
            "| {name} | {} | {p50:.0} | {p95:.0} | {read:.0} | {block:.0} | {:.2} | {generations:.0} |",
            trials.len(),
            read / block
        );
    }
    println!();
    println!(
        "| replicas, one Redis, small COG on S3, {} tiles of level {LEVEL}, {clients} clients | cold tiles/s | \
         warm tiles/s | tiles generated per replica | Redis hits |",
        keys.len()
    );
    println!("|---|---:|---:|---|---:|");
    for (name, s) in [("1 replica", &one), ("3 replicas", &three)] {
        let generated = s.generated.iter().map(u64::to_string).collect::<Vec<_>>().join(" + ");
        let sum: u64 = s.generated.iter().sum();
        println!("| {name} | {:.1} | {:.1} | {generated} = {sum} | {} |", s.per_s[0], s.per_s[1], s.redis_hits);
    }
    println!("| ratio 3 / 1 | {:.2} | {:.2} | | |", three.per_s[0] / one.per_s[0], three.per_s[1] / one.per_s[1]);
    println!(
        "(the replicas share this machine's cores with each other, moto and Redis; the warm pass asks each \
         tile of the replica after the one that built it)"
    );
    println!("whole bench: {:.0} s", began.elapsed().as_secs_f64());
    Ok(())
}
