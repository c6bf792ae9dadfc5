//! Frames for viewers: edit to frame, frames per second delivered to many
//! viewers, and reliefd's memory under fifty of them. Prints tables; never
//! asserts a time.
//!
//! The real reliefd serves the demo scene (lavapipe without a GPU).
//! - Edit to frame: a 64 x 64 window of the DEM rewritten through GDAL;
//!   the time runs from the start of the write to the first frame of the
//!   new generation at a gRPC StreamFrames viewer and at the browser page
//!   (headless Chromium; arrival in its JavaScript, and the image decoded
//!   and shown), both at 1280 x 720 on the scene camera.
//! - Frames per second delivered at 640 x 360 while the camera flies (a
//!   new camera every 33 ms): to 1, 10 and 50 viewers sharing the scene
//!   camera, and to 10 viewers with cameras of their own (views opened
//!   with OpenView, each moved by UpdateView).
//! - First frame after an edit against a steady frame of the same camera
//!   (1280 x 720, Render as RGBA8: the frame's own cost, no encoding).
//! - Edit to frame at 50 StreamFrames viewers sharing the scene camera at
//!   320 x 180 while a client also asks for tiles (each viewer's arrival).
//! - The town as a GeoPackage (`ogr` kind): one commit moving all 2,000
//!   footprints, from the commit to the first frame of its generation.
//! - Bytes per frame and encode time of each codec (PNG, JPEG at several
//!   qualities) on a 1280 x 720 frame of the scene.
//! - Memory: reliefd's resident set every 10 s while 50 viewers watch the
//!   flight, against the cache budget.
//!
//! `cargo bench -p relief-daemon --bench frames`; RELIEF_BENCH_EDITS
//! (default 25), RELIEF_BENCH_FPS_SECS (default 10), RELIEF_BENCH_SOAK_SECS
//! (default 600; 0 skips it), RELIEF_BENCH_ONLY (tables by name, commas:
//! edit, first, many, bulk, codecs, fps, soak).

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

mod common;

use common::wanted;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant, SystemTime};

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::browser::{Browser, chromium_path};
use relief_tests::daemon::Reliefd;
use relief_tests::edit;
use tokio_stream::StreamExt;
use tonic::transport::Channel;

fn env(name: &str, default: u64) -> u64 {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn since_epoch_ms() -> f64 {
    SystemTime::now().duration_since(SystemTime::UNIX_EPOCH).map_or(0.0, |d| d.as_secs_f64() * 1e3)
}

fn rss_mb(pid: u32) -> f64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmRSS:")).and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn views(channel: &Channel) -> ViewServiceClient<Channel> {
    ViewServiceClient::new(channel.clone()).max_decoding_message_size(256 << 20)
}

/// The camera of the flight at step `k`: a slow circle over the range.
fn flight(k: u64) -> pb::Camera {
    let t = k as f64 * 0.01;
    pb::Camera {
        lon_deg: 6.5 + 0.15 * t.cos(),
        lat_deg: 45.2 + 0.1 * t.sin(),
        altitude_m: 9000.0,
        heading_deg: (t.to_degrees() + 90.0).rem_euclid(360.0),
        pitch_deg: -25.0,
        roll_deg: 0.0,
        vertical_fov_deg: 50.0,
    }
}

/// Moves the scene camera (or, with view ids, each view's camera) every
/// 33 ms until `stop`.
fn fly(channel: Channel, view_ids: Vec<String>, stop: Arc<AtomicBool>) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let mut client = views(&channel);
        let mut k = 0u64;
        while !stop.load(Ordering::Relaxed) {
            k += 1;
            if view_ids.is_empty() {
                let _ = client.set_camera(pb::SetCameraRequest { camera: Some(flight(k)) }).await;
            }
            for (i, id) in view_ids.iter().enumerate() {
                let mut c = flight(k + 40 * i as u64);
                c.heading_deg = (c.heading_deg + 36.0 * i as f64).rem_euclid(360.0);
                let update = pb::UpdateViewRequest { view_id: id.clone(), camera: Some(c), ..Default::default() };
                let _ = client.update_view(update).await;
            }
            tokio::time::sleep(Duration::from_millis(33)).await;
        }
    })
}

/// Opens `n` streams (on `view_ids` when given) and counts their frames.
async fn watchers(
    channel: &Channel,
    n: usize,
    view_ids: &[String],
    size: (u32, u32),
    stop: &Arc<AtomicBool>,
) -> anyhow::Result<Vec<(Arc<AtomicU64>, tokio::task::JoinHandle<()>)>> {
    let mut out = Vec::new();
    for i in 0..n {
        let request = pb::StreamFramesRequest {
            width: size.0,
            height: size.1,
            max_fps: 60.0,
            view_id: view_ids.get(i).cloned().unwrap_or_default(),
            ..Default::default()
        };
        let mut stream = views(channel).stream_frames(request).await?.into_inner();
        let (count, stop) = (Arc::new(AtomicU64::new(0)), Arc::clone(stop));
        let counter = Arc::clone(&count);
        let task = tokio::spawn(async move {
            while !stop.load(Ordering::Relaxed) {
                match tokio::time::timeout(Duration::from_millis(500), stream.next()).await {
                    Ok(Some(Ok(_))) => {
                        counter.fetch_add(1, Ordering::Relaxed);
                    }
                    Ok(Some(Err(e))) => {
                        eprintln!("a viewer's stream failed: {e}");
                        return;
                    }
                    Ok(None) => return,
                    Err(_) => {}
                }
            }
        });
        out.push((count, task));
    }
    Ok(out)
}

async fn state(channel: &Channel) -> anyhow::Result<pb::SceneState> {
    Ok(SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await?.into_inner())
}

/// Each pass's milliseconds per run between two states.
fn pass_ms(before: &pb::SceneState, after: &pb::SceneState) -> Vec<(String, f64)> {
    after
        .passes
        .iter()
        .filter_map(|p| {
            let b = before.passes.iter().find(|q| q.name == p.name)?;
            let runs = p.runs.checked_sub(b.runs).filter(|r| *r > 0)?;
            Some((p.name.clone(), (p.total_ms - b.total_ms) / runs as f64))
        })
        .collect()
}

/// Frames per second each of `n` viewers received over `secs` of flight,
/// and each pass's milliseconds per frame then.
async fn fps(
    daemon: &Reliefd,
    n: usize,
    own_cameras: bool,
    secs: u64,
) -> anyhow::Result<(f64, f64, f64, Vec<(String, f64)>)> {
    let channel = daemon.channel().await?;
    let mut view_ids = Vec::new();
    if own_cameras {
        for _ in 0..n {
            view_ids.push(views(&channel).open_view(pb::OpenViewRequest::default()).await?.into_inner().view_id);
        }
    }
    let stop = Arc::new(AtomicBool::new(false));
    let viewers = watchers(&channel, n, &view_ids, (640, 360), &stop).await?;
    // Warm up: every viewer has its first frame.
    let deadline = Instant::now() + Duration::from_secs(120);
    while viewers.iter().any(|(c, _)| c.load(Ordering::Relaxed) == 0) && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let flying = fly(channel.clone(), view_ids, Arc::clone(&stop));
    tokio::time::sleep(Duration::from_secs(1)).await;
    let state0 = state(&channel).await?;
    let rendered0 = state0.counters.clone().unwrap_or_default().stream_frames_rendered;
    let counts0: Vec<u64> = viewers.iter().map(|(c, _)| c.load(Ordering::Relaxed)).collect();
    let started = Instant::now();
    tokio::time::sleep(Duration::from_secs(secs)).await;
    let elapsed = started.elapsed().as_secs_f64();
    let counts: Vec<f64> =
        viewers.iter().zip(&counts0).map(|((c, _), c0)| (c.load(Ordering::Relaxed) - c0) as f64 / elapsed).collect();
    let state1 = state(&channel).await?;
    let rendered = state1.counters.clone().unwrap_or_default().stream_frames_rendered - rendered0;
    stop.store(true, Ordering::Relaxed);
    let _ = flying.await;
    for (_, t) in viewers {
        let _ = t.await;
    }
    let mean = counts.iter().sum::<f64>() / counts.len() as f64;
    let min = counts.iter().copied().fold(f64::INFINITY, f64::min);
    Ok((mean, min, rendered as f64 / elapsed, pass_ms(&state0, &state1)))
}

/// Milliseconds from the start of each edit.
struct EditToFrame {
    grpc: Vec<f64>,
    page_received: Vec<f64>,
    page_shown: Vec<f64>,
    daemon: Vec<f64>,
    /// The frame's passes (name, milliseconds of each edit's frame).
    passes: Vec<(String, Vec<f64>)>,
}

async fn edit_to_frame(daemon: &Reliefd, dem: &std::path::Path, edits: usize) -> anyhow::Result<EditToFrame> {
    let channel = daemon.channel().await?;
    let page = match chromium_path() {
        Some(_) => {
            // A 1700 x 720 window leaves the view 1280 x 720 beside the panel.
            let page = Browser::start(1700, 720).await?;
            page.navigate(&format!("{}/", daemon.url())).await?;
            page.wait_for("document.body.dataset.ready === '1'", Duration::from_secs(120)).await?;
            page.wait_for("window.relief.lastFrame.width === 1280", Duration::from_secs(60)).await?;
            Some(page)
        }
        None => {
            println!("(no chromium: the page's column is left out)");
            None
        }
    };
    let request = pb::StreamFramesRequest { width: 1280, height: 720, max_fps: 60.0, ..Default::default() };
    let mut stream = views(&channel).stream_frames(request).await?.into_inner();
    let mut generation = stream.next().await.ok_or_else(|| anyhow::anyhow!("no first frame"))??.generation;
    let mut rng = relief_examples::Lcg(7);
    let mut out =
        EditToFrame { grpc: vec![], page_received: vec![], page_shown: vec![], daemon: vec![], passes: vec![] };
    let events = edit::Events::follow(channel.clone()).await?;
    for _ in 0..edits {
        tokio::time::sleep(Duration::from_millis(300)).await;
        let started = Instant::now();
        let started_epoch = since_epoch_ms();
        random_edit(dem, &mut rng)?;
        let frame = loop {
            let f = tokio::time::timeout(Duration::from_secs(30), stream.next())
                .await?
                .ok_or_else(|| anyhow::anyhow!("the stream ended"))??;
            if f.generation > generation {
                break f;
            }
        };
        out.grpc.push(started.elapsed().as_secs_f64() * 1e3);
        for p in &frame.passes {
            match out.passes.iter_mut().find(|(n, _)| *n == p.pass) {
                Some((_, v)) => v.push(p.elapsed_ms),
                None => out.passes.push((p.pass.clone(), vec![p.elapsed_ms])),
            }
        }
        generation = frame.generation;
        if let Some((_, g)) = events.generations().into_iter().find(|(n, _)| *n == generation) {
            out.daemon.push(g.elapsed_ms);
        }
        if let Some(page) = &page {
            let expr = format!(
                "(() => {{ const f = window.relief.frameLog.find(f => f.generation >= {generation} && f.shown); return f ? [f.received, f.shown] : null; }})()"
            );
            let deadline = Instant::now() + Duration::from_secs(30);
            loop {
                let v = page.eval(&expr).await?;
                if let Some([r, s]) = v.as_array().map(|a| [a[0].as_f64(), a[1].as_f64()]) {
                    out.page_received.push(r.unwrap_or(f64::NAN) - started_epoch);
                    out.page_shown.push(s.unwrap_or(f64::NAN) - started_epoch);
                    break;
                }
                anyhow::ensure!(Instant::now() < deadline, "the page did not show generation {generation}");
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
        }
    }
    Ok(out)
}

/// A frame of `camera` at 1280 x 720 as RGBA8 (no encoding): the wall
/// time of the call, ms, and the frame.
async fn timed_render(channel: &Channel, camera: &pb::Camera) -> anyhow::Result<(f64, pb::RenderResponse)> {
    let request = pb::RenderRequest {
        camera: Some(*camera),
        width: 1280,
        height: 720,
        format: pb::ImageFormat::Rgba8 as i32,
        ..Default::default()
    };
    let started = Instant::now();
    let frame = views(channel).render(request).await?.into_inner();
    Ok((started.elapsed().as_secs_f64() * 1e3, frame))
}

/// A random 64 x 64 window of the demo DEM raised by 50-400 m (nodata
/// left as it is), as the edit tables make them.
fn random_edit(dem: &std::path::Path, rng: &mut relief_examples::Lcg) -> anyhow::Result<()> {
    let (x, y) = (rng.range(100.0, 800.0) as usize, rng.range(100.0, 450.0) as usize);
    let lift = rng.range(50.0, 400.0) as f32;
    edit::rewrite_window(dem, x, y, 64, 64, |_, _, h| if h > -1000.0 { h + lift } else { h })
}

/// Steady frames of the scene camera, and the first frame after each of
/// `edits` DEM edits: wall ms of each, and the passes of the last ones.
async fn first_after_edit(
    channel: &Channel,
    dem: &std::path::Path,
    edits: usize,
) -> anyhow::Result<(Vec<f64>, Vec<f64>, pb::RenderResponse, pb::RenderResponse)> {
    let camera = views(channel).get_camera(pb::GetCameraRequest {}).await?.into_inner();
    let (mut steady, mut first) = (Vec::new(), Vec::new());
    let mut rng = relief_examples::Lcg(23);
    let (_, mut last_steady) = timed_render(channel, &camera).await?;
    let mut last_first = last_steady.clone();
    for _ in 0..edits {
        for _ in 0..2 {
            let (ms, frame) = timed_render(channel, &camera).await?;
            steady.push(ms);
            last_steady = frame;
        }
        let generation = common::state(channel).await?.generation;
        random_edit(dem, &mut rng)?;
        edit::wait_for(channel.clone(), generation + 1).await?;
        let (ms, frame) = timed_render(channel, &camera).await?;
        first.push(ms);
        last_first = frame;
    }
    Ok((steady, first, last_steady, last_first))
}

/// Each of `n` viewers' time from the start of each edit to its first
/// frame of the edit's generation (320 x 180, the scene camera), while a
/// client asks for 20 tiles a second.
async fn many_viewers(channel: &Channel, dem: &std::path::Path, n: usize, edits: usize) -> anyhow::Result<Vec<f64>> {
    let stop = Arc::new(AtomicBool::new(false));
    // Each viewer's newest generation and when it came (ms since the epoch).
    let seen: Vec<Arc<std::sync::Mutex<(u64, f64)>>> =
        (0..n).map(|_| Arc::new(std::sync::Mutex::new((0, 0.0)))).collect();
    let mut tasks = Vec::new();
    for slot in &seen {
        let request = pb::StreamFramesRequest { width: 320, height: 180, max_fps: 30.0, ..Default::default() };
        let mut stream = views(channel).stream_frames(request).await?.into_inner();
        let (slot, stop) = (Arc::clone(slot), Arc::clone(&stop));
        tasks.push(tokio::spawn(async move {
            while !stop.load(Ordering::Relaxed) {
                if let Ok(Some(Ok(f))) = tokio::time::timeout(Duration::from_millis(500), stream.next()).await {
                    let mut s = slot.lock().expect("viewer lock");
                    if f.generation > s.0 {
                        *s = (f.generation, since_epoch_ms());
                    }
                }
            }
        }));
    }
    let tiles = {
        let (channel, stop) = (channel.clone(), Arc::clone(&stop));
        tokio::spawn(async move {
            let mut client = relief_proto::v1::tile_service_client::TileServiceClient::new(channel);
            let mut rng = relief_examples::Lcg(5);
            while !stop.load(Ordering::Relaxed) {
                let level = rng.range(8.0, 14.0) as u32;
                let (x0, y0) = (
                    (6.0 + 180.0) / 360.0 * f64::from(2u32 << level),
                    (90.0 - 45.6) / 180.0 * f64::from(1u32 << level),
                );
                let (x, y) = (
                    x0 + rng.range(0.0, f64::from(1u32 << level) / 360.0),
                    y0 + rng.range(0.0, f64::from(1u32 << level) * 0.6 / 180.0),
                );
                let key = pb::TileKey { level, x: x as u32, y: y as u32 };
                let _ = client
                    .get_tile(pb::GetTileRequest { source_id: "dem".into(), key: Some(key), quality: None })
                    .await;
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        })
    };
    let deadline = Instant::now() + Duration::from_secs(120);
    while seen.iter().any(|s| s.lock().expect("viewer lock").0 == 0) && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let mut rng = relief_examples::Lcg(31);
    let mut out = Vec::new();
    for _ in 0..edits {
        tokio::time::sleep(Duration::from_millis(500)).await;
        let generation = common::state(channel).await?.generation + 1;
        let started = since_epoch_ms();
        random_edit(dem, &mut rng)?;
        let deadline = Instant::now() + Duration::from_secs(30);
        while seen.iter().any(|s| s.lock().expect("viewer lock").0 < generation) && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        let arrivals: Vec<f64> = seen.iter().map(|s| s.lock().expect("viewer lock").1 - started).collect();
        let slowest = arrivals.iter().copied().fold(0.0, f64::max);
        let state = common::state(channel).await?;
        let renders = state.counters.unwrap_or_default().stream_frames_rendered;
        eprintln!(
            "edit to generation {generation}: slowest of {n} viewers {slowest:.0} ms; hub renders so far {renders}"
        );
        out.extend(arrivals);
    }
    stop.store(true, Ordering::Relaxed);
    for t in tasks {
        let _ = t.await;
    }
    let _ = tiles.await;
    Ok(out)
}

/// The demo scene with its town as a GeoPackage (`ogr` kind): the time
/// from the start of a commit moving all its footprints 20 m to the first
/// frame (1280 x 720, the scene camera over the town) of its generation,
/// and the frame's passes. `commits` commits, east and back in turn.
async fn bulk_commit(commits: usize) -> anyhow::Result<(Vec<f64>, Vec<(String, f64)>)> {
    let dir = tempfile::tempdir()?;
    let manifest = relief_examples::write_demo_scene(dir.path())?;
    let gpkg = dir.path().join("town.gpkg");
    relief_examples::write_town(&gpkg, relief_examples::DEMO_TOWN_CENTRE, relief_examples::DEMO_TOWN_BUILDINGS)?;
    let text = std::fs::read_to_string(&manifest)?.replace(
        "id = \"town-footprints\"\nkind = \"shapefile\"\npath = \"town.shp\"",
        "id = \"town-footprints\"\nkind = \"ogr\"\npath = \"town.gpkg\"\nlayer = \"town\"",
    );
    anyhow::ensure!(text.contains("town.gpkg"), "the demo manifest's town source changed");
    std::fs::write(&manifest, text)?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let channel = daemon.channel().await?;
    let (lon, lat) = relief_examples::DEMO_TOWN_CENTRE;
    let camera = pb::Camera {
        lon_deg: lon,
        lat_deg: lat - 0.03,
        altitude_m: 2500.0,
        heading_deg: 0.0,
        pitch_deg: -35.0,
        roll_deg: 0.0,
        vertical_fov_deg: 50.0,
    };
    let request = pb::StreamFramesRequest {
        width: 1280,
        height: 720,
        max_fps: 60.0,
        camera: Some(camera),
        format: pb::ImageFormat::Rgba8 as i32,
        ..Default::default()
    };
    let mut stream = views(&channel).stream_frames(request).await?.into_inner();
    let mut generation = stream.next().await.ok_or_else(|| anyhow::anyhow!("no first frame"))??.generation;
    let step = 20.0 / 111_320.0;
    let (mut out, mut passes) = (Vec::new(), Vec::new());
    for k in 0..commits {
        tokio::time::sleep(Duration::from_millis(500)).await;
        let dx = if k % 2 == 0 { step } else { -step };
        let started = Instant::now();
        let moved = edit::move_every_polygon(&gpkg, "town", (dx, 0.0))?;
        anyhow::ensure!(moved == relief_examples::DEMO_TOWN_BUILDINGS, "moved {moved} footprints");
        let frame = loop {
            let f = tokio::time::timeout(Duration::from_secs(60), stream.next())
                .await?
                .ok_or_else(|| anyhow::anyhow!("the stream ended"))??;
            if f.generation > generation && !f.carried_over {
                break f;
            }
        };
        out.push(started.elapsed().as_secs_f64() * 1e3);
        generation = frame.generation;
        passes = frame.passes.iter().map(|p| (p.pass.clone(), p.elapsed_ms)).collect();
    }
    drop(stream);
    daemon.stop(&[])?;
    Ok((out, passes))
}

/// Bytes and encode milliseconds (median of 5) of `frame` (RGBA8) by each codec.
fn codecs(frame: &pb::RenderResponse) -> anyhow::Result<Vec<(String, usize, f64)>> {
    use relief_daemon::codec::Codec;
    let mut out = Vec::new();
    for codec in [Codec::Png, Codec::Jpeg(95), Codec::Jpeg(90), Codec::Jpeg(80), Codec::Jpeg(70), Codec::Jpeg(50)] {
        let mut times = Vec::new();
        let mut bytes = 0;
        for _ in 0..5 {
            let started = Instant::now();
            bytes = codec.encode(&frame.image, frame.width, frame.height).map_err(anyhow::Error::msg)?.len();
            times.push(started.elapsed().as_secs_f64() * 1e3);
        }
        out.push((codec.name(), bytes, common::median(times)));
    }
    Ok(out)
}

fn row(label: &str, mut v: Vec<f64>) {
    v.sort_by(f64::total_cmp);
    println!(
        "| {label} | {} | {:.0} | {:.0} | {:.0} |",
        v.len(),
        percentile(&v, 0.5),
        percentile(&v, 0.95),
        percentile(&v, 1.0)
    );
}

async fn run() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = relief_examples::write_demo_scene(dir.path())?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let channel = daemon.channel().await?;
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("model name")).map(|l| l.split(':').nth(1).unwrap_or("").trim().to_owned())
        })
        .unwrap_or_default();
    println!("machine: {cpu}, {} cores", std::thread::available_parallelism().map_or(0, std::num::NonZero::get));
    // Warm up: the device opened, the first tiles built.
    views(&channel).render(pb::RenderRequest { width: 64, height: 36, ..Default::default() }).await?;
    let gpu = std::path::Path::new("/dev/nvidia0").exists() || std::path::Path::new("/dev/dri").exists();
    println!("renderer: {}", if gpu { "a GPU (wgpu's first adapter)" } else { "Mesa lavapipe (no GPU here)" });

    let edits = env("RELIEF_BENCH_EDITS", 25) as usize;
    if edits > 0 && wanted("RELIEF_BENCH_ONLY", "edit") {
        println!("\n## Edit to frame (64 x 64 DEM window, 1280 x 720, the scene camera), ms\n");
        println!("| viewer | edits | p50 | p95 | max |\n|---|---|---|---|---|");
        let e = edit_to_frame(&daemon, &manifest.with_file_name("dem.tif"), edits).await?;
        row("daemon: read, rebuild and publish (GenerationEvent.elapsed_ms)", e.daemon);
        row("gRPC StreamFrames viewer: frame received", e.grpc);
        if !e.page_received.is_empty() {
            row("browser page: frame received by its script", e.page_received);
            row("browser page: image decoded and shown", e.page_shown);
        }
        for (pass, ms) in e.passes {
            row(&format!("of which the frame's pass '{pass}'"), ms);
        }
    }

    let dem = manifest.with_file_name("dem.tif");
    if edits > 0 && wanted("RELIEF_BENCH_ONLY", "first") {
        println!(
            "\n## First frame after an edit against a steady frame (1280 x 720, the scene camera, Render as RGBA8), ms\n"
        );
        let (steady, first, last_steady, last_first) = first_after_edit(&channel, &dem, edits.min(15)).await?;
        let (s50, f50) = (common::median(steady.clone()), common::median(first.clone()));
        println!("| frame | frames | p50 | p95 | max |\n|---|---|---|---|---|");
        row("steady (the same camera, nothing changed)", steady);
        row("first after a 64 x 64 DEM edit", first);
        println!("\nfirst after an edit / steady, p50: **{:.2}x** (goal: at most 1.3x)\n", f50 / s50);
        println!("| pass | steady ms | first after an edit ms |\n|---|---|---|");
        for p in &last_first.passes {
            let was = last_steady.passes.iter().find(|q| q.pass == p.pass).map_or(f64::NAN, |q| q.elapsed_ms);
            println!("| {} | {was:.1} | {:.1} |", p.pass, p.elapsed_ms);
        }
        let work = |f: &pb::RenderResponse| f.drawn.unwrap_or_default();
        let (a, b) = (work(&last_steady), work(&last_first));
        println!(
            "\nthe last edit's frame: level samples {} (steady {}), water texels {} ({}), shadow maps drawn {} / in part {} / kept {}, shadow texels {} ({})",
            b.level_samples_written,
            a.level_samples_written,
            b.water_coverage_texels,
            a.water_coverage_texels,
            b.shadow_maps_drawn,
            b.shadow_maps_redrawn_in_part,
            b.shadow_maps_kept,
            b.shadow_texels,
            a.shadow_texels
        );
        if wanted("RELIEF_BENCH_ONLY", "codecs") {
            println!("\n## Bytes per frame and encode time of each codec (the 1280 x 720 frame above)\n");
            println!("| codec | KiB | encode ms (median of 5) |\n|---|---|---|");
            for (name, bytes, ms) in codecs(&last_first)? {
                println!("| {name} | {:.0} | {ms:.1} |", bytes as f64 / 1024.0);
            }
        }
    }
    if edits > 0 && wanted("RELIEF_BENCH_ONLY", "many") {
        println!("\n## Edit to frame at 50 viewers sharing the scene camera (320 x 180; tiles asked for beside), ms\n");
        println!("| viewer | arrivals | p50 | p95 | max |\n|---|---|---|---|---|");
        row("each of 50 StreamFrames viewers", many_viewers(&channel, &dem, 50, edits.min(15)).await?);
    }
    if wanted("RELIEF_BENCH_ONLY", "bulk") {
        println!(
            "\n## A GeoPackage commit moving all 2,000 town footprints, to the first frame of its generation (1280 x 720), ms\n"
        );
        let (times, passes) = bulk_commit(5).await?;
        println!("| commits | p50 | p95 | max |\n|---|---|---|---|");
        let mut sorted = times.clone();
        sorted.sort_by(f64::total_cmp);
        println!(
            "| {} | {:.0} | {:.0} | {:.0} |",
            sorted.len(),
            percentile(&sorted, 0.5),
            percentile(&sorted, 0.95),
            percentile(&sorted, 1.0)
        );
        println!(
            "\nthe last commit's frame: {}",
            passes.iter().map(|(p, ms)| format!("{p} {ms:.0} ms")).collect::<Vec<_>>().join(", ")
        );
    }

    let secs = env("RELIEF_BENCH_FPS_SECS", 10);
    if wanted("RELIEF_BENCH_ONLY", "fps") {
        println!("\n## Frames per second delivered, 640 x 360, camera moving every 33 ms ({secs} s each)\n");
        println!(
            "| viewers | cameras | fps per viewer (mean) | fps (slowest viewer) | distinct renders/s | ms per frame by pass |\n|---|---|---|---|---|---|"
        );
        for (n, own) in [(1, false), (10, false), (50, false), (10, true)] {
            let (mean, min, renders, passes) = fps(&daemon, n, own, secs).await?;
            let cameras = if own { "own camera each" } else { "shared (scene camera)" };
            let passes: Vec<String> = passes.iter().map(|(p, ms)| format!("{p} {ms:.0}")).collect();
            println!("| {n} | {cameras} | {mean:.1} | {min:.1} | {renders:.1} | {} |", passes.join(", "));
        }
    }

    let soak = env("RELIEF_BENCH_SOAK_SECS", 600);
    if soak > 0 && wanted("RELIEF_BENCH_ONLY", "soak") {
        let budget_mb =
            state(&channel).await?.counters.unwrap_or_default().cache_budget_bytes as f64 / (1 << 20) as f64;
        println!("\n## Memory: 50 viewers at 640 x 360 on a flying camera for {soak} s\n");
        println!("cache budget {budget_mb:.0} MB; goal: flat, within budget + 150 MB = {:.0} MB\n", budget_mb + 150.0);
        println!("| s | reliefd RSS MB | frames received (all viewers) | cache MB |\n|---|---|---|---|");
        let stop = Arc::new(AtomicBool::new(false));
        let viewers = watchers(&channel, 50, &[], (640, 360), &stop).await?;
        let flying = fly(channel.clone(), Vec::new(), Arc::clone(&stop));
        let started = Instant::now();
        let mut samples = Vec::new();
        loop {
            let s = started.elapsed().as_secs();
            let rss = rss_mb(daemon.pid());
            let frames: u64 = viewers.iter().map(|(c, _)| c.load(Ordering::Relaxed)).sum();
            let cache = state(&channel).await?.counters.unwrap_or_default().cache_bytes as f64 / (1 << 20) as f64;
            println!("| {s} | {rss:.0} | {frames} | {cache:.0} |");
            samples.push(rss);
            if s >= soak {
                break;
            }
            tokio::time::sleep(Duration::from_secs(10)).await;
        }
        stop.store(true, Ordering::Relaxed);
        let _ = flying.await;
        let max = samples.iter().copied().fold(0.0, f64::max);
        let after_warmup = &samples[samples.len().min(3) - 1..];
        let growth = after_warmup.last().copied().unwrap_or(0.0) - after_warmup.first().copied().unwrap_or(0.0);
        println!("\npeak {max:.0} MB; growth after the first 20 s {growth:+.0} MB");
    }
    daemon.stop(&[])?;
    Ok(())
}

fn main() -> anyhow::Result<()> {
    tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?.block_on(run())
}
