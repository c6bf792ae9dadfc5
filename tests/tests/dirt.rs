//! Every renderer cache follows the generation's dirt (issue "live on a
//! full scene"): counters in each frame and in the state show what a cache
//! rebuilt, never timings. On the hill scene with a lake (the water layer),
//! shadows and lighting:
//! - a DEM edit away from the lake rebuilds no water coverage, and
//!   redraws only regions of the shadow maps; an edit of the lake rebuilds
//!   only its window of the coverage and no shadow map;
//! - the frames after those edits are the frames a new daemon draws of the
//!   edited files (incremental = full);
//! - a generation that changes nothing drawn (a source no layer reads, a
//!   file saved again as it was, a source turning to error) renders no
//!   frame, yet the stream's viewers get its generation, carried over;
//! - with detail, the noise is fitted again only when the height layer
//!   changes where the fit reads.

#![allow(clippy::unwrap_used, reason = "a test")]

use std::path::Path;
use std::time::Duration;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::{edit, fixtures, scenes};
use tokio_stream::StreamExt;

const SIZE: (u32, u32) = (320, 180);
/// The water layer's lake, as in the water test: 0.03 degrees across.
const LAKE: (f64, f64, f64) = (10.1, 45.1, 0.03);

fn lake(lon: f64, lat: f64) -> f64 {
    let (dx, dy) = ((lon - LAKE.0) * (LAKE.1.to_radians().cos()), lat - LAKE.1);
    if dx.hypot(dy) < LAKE.2 { 1.0 } else { 0.0 }
}

/// The hill scene with the lake as its water layer, a raster no layer
/// reads (`spare`), and `effects` besides lighting.
fn scene(dir: &Path, effects: &str) -> std::path::PathBuf {
    fixtures::write_dem(&dir.join("lake.tif"), &fixtures::hill_spec(), lake).unwrap();
    fixtures::write_dem(&dir.join("spare.tif"), &fixtures::hill_spec(), |_, _| 7.0).unwrap();
    let extra = format!(
        "water = \"lake\"\n\n[[source]]\nid = \"lake\"\nkind = \"gdal\"\npath = \"lake.tif\"\n\n\
         [[source]]\nid = \"spare\"\nkind = \"gdal\"\npath = \"spare.tif\"\n\n[effects]\nlighting = {{}}\n{effects}"
    );
    scenes::hill(dir, &extra).unwrap()
}

/// South of the lake, 2 km up, looking north over it and the hill.
fn over_the_lake() -> pb::Camera {
    scenes::camera(10.1, 45.04, 2500.0, 10.0, -30.0)
}

fn drawn(f: &pb::RenderResponse) -> pb::FrameDrawn {
    f.drawn.unwrap()
}

async fn state(channel: &tonic::transport::Channel) -> pb::SceneState {
    SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner()
}

/// Pixels of `a` and `b` that differ by more than `tolerance` in a channel.
fn differing(a: &pb::RenderResponse, b: &pb::RenderResponse, tolerance: u8) -> usize {
    a.image
        .chunks(4)
        .zip(b.image.chunks(4))
        .filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| x.abs_diff(*y) > tolerance))
        .count()
}

/// DEM pixels (column, row) of the hill raster at (lon, lat).
fn pixel(lon: f64, lat: f64) -> (usize, usize) {
    let spec = fixtures::hill_spec();
    (((lon - spec.origin_x) / spec.pixel) as usize, ((spec.origin_y - lat) / spec.pixel) as usize)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edit_rebuilds_only_the_caches_and_regions_it_touches() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = scene(dir.path(), "water = {}\nshadows = {}\n");
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let camera = over_the_lake();
    let first = scenes::render_rgba(&channel, camera, SIZE).await.unwrap();
    let d = drawn(&first);
    assert_eq!(d.water_coverage_texels, 1024 * 1024, "the first frame reads the coverage window whole: {d:?}");
    assert!(d.shadow_maps_drawn >= 1, "{d:?}");
    let still = scenes::render_rgba(&channel, camera, SIZE).await.unwrap();
    let d = drawn(&still);
    assert_eq!((d.water_coverage_texels, d.shadow_maps_drawn, d.shadow_texels, d.level_samples_written), (0, 0, 0, 0));
    let maps = d.shadow_maps_kept;
    assert!(maps >= 1, "{d:?}");

    // The DEM raised by 300 m over 16 x 16 pixels 4.7 km east of the lake.
    let (x, y) = pixel(10.16, 45.11);
    edit::rewrite_window(&dir.path().join("hill.tif"), x, y, 16, 16, |_, _, h| h + 300.0).unwrap();
    let g = first.generation + 1;
    edit::wait_for(channel.clone(), g).await.unwrap();
    let after_dem = scenes::render_rgba(&channel, camera, SIZE).await.unwrap();
    assert_eq!(after_dem.generation, g);
    let d = drawn(&after_dem);
    assert_eq!(d.water_coverage_texels, 0, "a DEM edit away from the lake rebuilt water coverage: {d:?}");
    assert_eq!(d.shadow_maps_drawn, 0, "a small DEM edit redrew whole shadow maps: {d:?}");
    assert!(d.shadow_maps_redrawn_in_part >= 1 && d.shadow_regions >= 1, "the edit's shadows were not redrawn: {d:?}");
    assert_eq!(d.shadow_maps_redrawn_in_part + d.shadow_maps_kept, maps);
    let whole = u64::from(maps) * 1024 * 1024;
    assert!(d.shadow_texels * 8 < whole, "{} of {whole} shadow texels redrawn for a 1.5 km edit", d.shadow_texels);
    // The levels read again only over the edit: far less than a refill.
    assert!(d.level_samples_written > 0 && d.level_samples_written < 20_000, "{d:?}");

    // The lake grown by 16 x 16 pixels at its east shore.
    let (x, y) = pixel(LAKE.0 + 0.035, LAKE.1 + 0.01);
    edit::rewrite_window(&dir.path().join("lake.tif"), x, y, 16, 16, |_, _, _| 1.0).unwrap();
    edit::wait_for(channel.clone(), g + 1).await.unwrap();
    let after_lake = scenes::render_rgba(&channel, camera, SIZE).await.unwrap();
    let d = drawn(&after_lake);
    assert!(d.water_coverage_texels > 0, "the lake's edit was not read: {d:?}");
    assert!(
        d.water_coverage_texels * 20 < 1024 * 1024,
        "a 2 km edit of the lake read {} texels",
        d.water_coverage_texels
    );
    assert_eq!((d.shadow_maps_drawn, d.shadow_maps_redrawn_in_part, d.level_samples_written), (0, 0, 0), "{d:?}");
    assert_ne!(differing(&after_lake, &after_dem, 0), 0, "the lake's edit does not show");

    // What the caches did shows in the state too.
    let caches = state(&channel).await.counters.unwrap().renderer_caches.unwrap();
    assert!(caches.shadow_regions >= 1 && caches.shadow_maps_kept >= u64::from(maps), "{caches:?}");
    daemon.stop(&[]).unwrap();

    // A new daemon on the edited files draws the same frame.
    let fresh = Reliefd::start(&manifest, &[]).unwrap();
    let again = scenes::render_rgba(&fresh.channel().await.unwrap(), camera, SIZE).await.unwrap();
    fresh.stop(&[]).unwrap();
    let off = differing(&after_lake, &again, 2);
    assert!(off * 1000 <= after_lake.image.len() / 4, "{off} pixels differ from a fresh daemon's frame");
}

/// The number of stream frames the hub rendered, and carried over.
async fn hub_frames(channel: &tonic::transport::Channel) -> (u64, u64) {
    let c = state(channel).await.counters.unwrap();
    (c.stream_frames_rendered, c.stream_frames_carried_over)
}

/// The next frame of `stream`, within 60 s.
async fn next(stream: &mut tonic::Streaming<pb::RenderResponse>) -> pb::RenderResponse {
    tokio::time::timeout(Duration::from_secs(60), stream.next()).await.unwrap().unwrap().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_generation_that_changes_nothing_drawn_renders_no_frame_yet_viewers_see_it() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = scene(dir.path(), "");
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let request = pb::StreamFramesRequest { width: SIZE.0, height: SIZE.1, max_fps: 30.0, ..Default::default() };
    let mut stream = ViewServiceClient::new(channel.clone()).stream_frames(request).await.unwrap().into_inner();
    let first = next(&mut stream).await;
    assert!(!first.carried_over);
    let (rendered, carried) = hub_frames(&channel).await;

    // A source no layer reads changes: a generation, no render.
    edit::rewrite_window(&dir.path().join("spare.tif"), 10, 10, 8, 8, |_, _, _| 9.0).unwrap();
    let frame = next(&mut stream).await;
    assert_eq!(frame.generation, first.generation + 1);
    assert!(frame.carried_over, "a frame was rendered for a source no layer reads");
    assert_eq!(frame.image, first.image);
    assert_eq!(hub_frames(&channel).await, (rendered, carried + 1));

    // The manifest edited where no frame looks: the spare raster read
    // "nearest". A generation (the spare's tiles change), no render.
    let text = std::fs::read_to_string(&manifest).unwrap();
    let edited = text.replace("path = \"spare.tif\"", "path = \"spare.tif\"\nresampling = \"nearest\"");
    assert_ne!(edited, text);
    std::fs::write(&manifest, edited).unwrap();
    let frame = next(&mut stream).await;
    assert_eq!(frame.generation, first.generation + 2);
    assert!(frame.carried_over, "a frame was rendered for a manifest edit no layer sees");
    assert_eq!(hub_frames(&channel).await, (rendered, carried + 2));

    // The DEM saved again as it was: nothing drawn changes, nothing renders.
    let dem = dir.path().join("hill.tif");
    let bytes = std::fs::read(&dem).unwrap();
    std::fs::write(&dem, &bytes).unwrap();
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let now = state(&channel).await;
    assert_eq!(hub_frames(&channel).await.0, rendered, "saving the DEM as it was rendered a frame");
    if now.generation > frame.generation {
        let carried = next(&mut stream).await;
        assert!(carried.carried_over && carried.generation == now.generation);
    }

    // The DEM turns bad: its last good version stays, the generation moves,
    // the frame is carried over.
    let before = state(&channel).await.generation;
    std::fs::write(&dem, b"not a GeoTIFF").unwrap();
    let mut scene = SceneServiceClient::new(channel.clone());
    edit::wait_for_status(&mut scene, "dem", pb::SourceStatus::Error).await.unwrap();
    let bad = state(&channel).await;
    if bad.generation > before {
        let frame = tokio::time::timeout(Duration::from_secs(60), async {
            loop {
                let f = next(&mut stream).await;
                if f.generation >= bad.generation {
                    break f;
                }
            }
        })
        .await
        .unwrap();
        assert!(frame.carried_over, "a source turning to error rendered a frame");
    }
    assert_eq!(hub_frames(&channel).await.0, rendered, "an error rendered a frame");

    // A real edit renders again.
    std::fs::write(&dem, &bytes).unwrap();
    edit::rewrite_window(&dem, 200, 200, 8, 8, |_, _, h| h + 100.0).unwrap();
    let fixed = tokio::time::timeout(Duration::from_secs(60), async {
        loop {
            let f = next(&mut stream).await;
            if !f.carried_over {
                break f;
            }
        }
    })
    .await
    .unwrap();
    assert!(fixed.generation > bad.generation);
    assert!(hub_frames(&channel).await.0 > rendered);
    drop(stream);
    daemon.stop(&["keeping the last good version"]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_detail_noise_is_fitted_again_only_when_the_heights_it_read_change() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = scene(dir.path(), "detail = {}\n");
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let camera = scenes::camera(10.2, 45.15, 3000.0, 45.0, -30.0);
    let first = scenes::render_rgba(&channel, camera, SIZE).await.unwrap();
    let fits = |s: &pb::SceneState| s.counters.as_ref().unwrap().renderer_caches.unwrap().detail_fits;
    assert_eq!(fits(&state(&channel).await), 1);

    // An edit at the raster's corner, far from its middle where the fit reads.
    edit::rewrite_window(&dir.path().join("hill.tif"), 4, 4, 16, 16, |_, _, h| h + 50.0).unwrap();
    edit::wait_for(channel.clone(), first.generation + 1).await.unwrap();
    let after = scenes::render_rgba(&channel, camera, SIZE).await.unwrap();
    assert_eq!(fits(&state(&channel).await), 1, "an edit away from the fit fitted the noise again");
    let d = drawn(&after);
    assert!(d.level_samples_written < 20_000, "a corner edit refreshed {} level samples", d.level_samples_written);

    // An edit in the middle, where the fit reads: fitted again.
    edit::rewrite_window(&dir.path().join("hill.tif"), 192, 192, 16, 16, |i, j, h| h + ((i * 7 + j * 3) % 11) as f32)
        .unwrap();
    edit::wait_for(channel.clone(), first.generation + 2).await.unwrap();
    scenes::render_rgba(&channel, camera, SIZE).await.unwrap();
    assert_eq!(fits(&state(&channel).await), 2);
    daemon.stop(&[]).unwrap();
}

/// The resident set of process `pid`, MB.
fn rss_mb(pid: u32) -> f64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmRSS:"))?.split_whitespace().nth(1)?.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twenty_edits_a_second_for_half_a_minute_keep_frames_coming_with_no_backlog_and_flat_memory() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = scene(dir.path(), "shadows = {}\nwater = {}\n");
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let request = pb::StreamFramesRequest { width: SIZE.0, height: SIZE.1, max_fps: 30.0, ..Default::default() };
    let mut stream = ViewServiceClient::new(channel.clone()).stream_frames(request).await.unwrap().into_inner();
    next(&mut stream).await;
    // Each frame: when it came (s from the start) and its generation.
    let frames = std::sync::Arc::new(std::sync::Mutex::new(Vec::<(f64, u64)>::new()));
    let started = std::time::Instant::now();
    let reader = {
        let frames = std::sync::Arc::clone(&frames);
        tokio::spawn(async move {
            while let Some(Ok(f)) = stream.next().await {
                frames.lock().unwrap().push((started.elapsed().as_secs_f64(), f.generation));
            }
        })
    };
    let dem = dir.path().join("hill.tif");
    let (x, y) = pixel(10.2, 45.2);
    let mut rss = Vec::new();
    let mut k = 0u32;
    let mut tick = tokio::time::interval(Duration::from_millis(50));
    while started.elapsed() < Duration::from_secs(30) {
        tick.tick().await;
        let height = if k.is_multiple_of(2) { 1900.0 } else { 1200.0 };
        let path = dem.clone();
        tokio::task::spawn_blocking(move || edit::rewrite_window(&path, x, y, 16, 16, |_, _, _| height))
            .await
            .unwrap()
            .unwrap();
        k += 1;
        if k.is_multiple_of(200) {
            rss.push(rss_mb(daemon.pid()));
        }
    }
    // Once the edits stop, the stream catches up with the last generation
    // and then stays quiet: nothing was queued behind.
    let last = {
        let mut scene = SceneServiceClient::new(channel.clone());
        let mut g = 0;
        for _ in 0..40 {
            tokio::time::sleep(Duration::from_millis(250)).await;
            let now = scene.get_state(pb::GetStateRequest {}).await.unwrap().into_inner().generation;
            if now == g {
                break;
            }
            g = now;
        }
        g
    };
    let caught_up = tokio::time::timeout(Duration::from_secs(30), async {
        while frames.lock().unwrap().last().is_none_or(|(_, g)| *g < last) {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    })
    .await;
    assert!(caught_up.is_ok(), "the stream did not reach generation {last} within 30 s of the last edit");
    let shown = frames.lock().unwrap().len();
    tokio::time::sleep(Duration::from_secs(2)).await;
    assert_eq!(frames.lock().unwrap().len(), shown, "frames kept coming after the last generation: a backlog");
    let got = frames.lock().unwrap().clone();
    // Frames kept coming throughout: none of the six 5 s spans went without.
    for span in 0..6 {
        let (from, to) = (f64::from(span) * 5.0, f64::from(span + 1) * 5.0);
        assert!(got.iter().any(|(t, _)| (from..to).contains(t)), "no frame from {from} to {to} s: {got:?}");
    }
    assert!(got.windows(2).all(|w| w[0].1 <= w[1].1), "generations went back: {got:?}");
    assert!(last > 10, "only {last} generations from {k} edits");
    // Memory flat: from 10 s (the caches filled) to 30 s.
    let (early, late) = (rss[0], *rss.last().unwrap());
    eprintln!("{k} edits, {last} generations, {} frames; resident set every 10 s: {rss:?} MB", got.len());
    assert!(late - early < 48.0, "reliefd's resident set grew from {early:.0} to {late:.0} MB over 20 s of edits");
    reader.abort();
    daemon.stop(&[]).unwrap();
}
