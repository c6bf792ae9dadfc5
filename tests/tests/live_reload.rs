//! Live reload against a real reliefd: edits made the way GIS tools make
//! them, and what the scene shows afterwards.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::Path;
use std::time::Duration;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::edit::{self, Events};
use relief_tests::fixtures;

/// The hill fixture covers 10..10.5 E, 45..45.5 N with 0.00125-degree pixels.
const DEM: [f64; 4] = [10.0, 45.0, 10.5, 45.5];
const PIXEL: f64 = 0.00125;
const TILE_SIZE: f64 = 256.0;

/// Every tile of levels `levels` over the DEM, by plain grid maths: level l
/// has 2^(l+1) x 2^l tiles of 180 / 2^l degrees, numbered from the north-west.
fn dem_tiles(levels: std::ops::RangeInclusive<u32>) -> Vec<(u32, u32, u32)> {
    let mut keys = Vec::new();
    for l in levels {
        let span = 180.0 / f64::from(1u32 << l);
        let (x0, x1) = (((DEM[0] + 180.0) / span).floor() as u32, ((DEM[2] + 180.0) / span).ceil() as u32);
        let (y0, y1) = (((90.0 - DEM[3]) / span).floor() as u32, ((90.0 - DEM[1]) / span).ceil() as u32);
        for y in y0..y1 {
            for x in x0..x1 {
                keys.push((l, x, y));
            }
        }
    }
    keys
}

/// Does tile `key`, widened by `margin` samples of its level, touch `area`?
fn touches(key: (u32, u32, u32), margin: f64, area: [f64; 4]) -> bool {
    let span = 180.0 / f64::from(1u32 << key.0);
    let m = margin * span / TILE_SIZE;
    let (w, n) = (-180.0 + f64::from(key.1) * span, 90.0 - f64::from(key.2) * span);
    w - m <= area[2] && w + span + m >= area[0] && n - span - m <= area[3] && n + m >= area[1]
}

fn scene(dir: &Path, sources: &str) -> std::path::PathBuf {
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    fixtures::write_manifest(dir, &format!("[scene]\nname = \"live\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n{sources}\n[layers]\nheight = \"dem\"\n")).unwrap()
}

async fn hashes(channel: &tonic::transport::Channel, source: &str, keys: &[(u32, u32, u32)]) -> Vec<u64> {
    let mut out = Vec::with_capacity(keys.len());
    for k in keys {
        out.push(edit::tile_hash(channel.clone(), source, *k).await.unwrap());
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_window_edit_rebuilds_only_the_tiles_it_touches() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let keys = dem_tiles(0..=11);
    let before = hashes(&channel, "dem", &keys).await;

    // One 64 x 64 window, raised by 100 m, through GDAL in update mode.
    let (px, py) = (192, 128);
    edit::rewrite_window(&dir.path().join("hill.tif"), px, py, 64, 64, |_, _, h| h + 100.0).unwrap();
    let window = [
        DEM[0] + px as f64 * PIXEL,
        DEM[3] - (py + 64) as f64 * PIXEL,
        DEM[0] + (px + 64) as f64 * PIXEL,
        DEM[3] - py as f64 * PIXEL,
    ];
    let g = events.generation(2).await.unwrap();
    assert_eq!(g.changed_sources, ["dem"]);
    let d = &g.dirty[0].extents[0];
    assert!(
        (d.min_x - window[0]).abs() < 1e-9 && (d.max_y - window[3]).abs() < 1e-9,
        "dirt {d:?} vs window {window:?}"
    );

    // The rebuilt tiles are exactly those that read the window: the tiles it
    // touches at each level, widened by the widest kernel's reach of 4 samples.
    let expected: Vec<bool> = keys.iter().map(|k| touches(*k, 4.0, window)).collect();
    let n_expected = expected.iter().filter(|t| **t).count() as u64;
    assert_eq!(g.tiles_rebuilt, n_expected, "rebuilt {} of {} cached tiles", g.tiles_rebuilt, keys.len());
    assert_eq!(g.tiles_carried_over, keys.len() as u64 - n_expected);
    assert!(n_expected < keys.len() as u64 / 2, "{n_expected} of {}", keys.len());

    let after = hashes(&channel, "dem", &keys).await;
    for (i, k) in keys.iter().enumerate() {
        if !expected[i] {
            assert_eq!(after[i], before[i], "untouched tile {k:?} changed");
        }
    }
    assert!(keys.iter().zip(before.iter().zip(&after)).any(|(k, (b, a))| k.0 == 11 && b != a));

    // Byte-identical to a build from scratch of the edited file.
    let fresh = Reliefd::start(&dir.path().join("scene.toml"), &[]).unwrap();
    let scratch = hashes(&fresh.channel().await.unwrap(), "dem", &keys).await;
    assert_eq!(after, scratch, "incremental and from-scratch tiles differ");
    fresh.stop(&[]).unwrap();
    assert!(events.errors().is_empty(), "{:?}", events.errors());
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rename_into_place_is_picked_up() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    // Written under a temporary name (ignored), then renamed over the original.
    let tmp = dir.path().join("hill.tif.tmp");
    fixtures::write_dem(&tmp, &fixtures::hill_spec(), |lon, lat| fixtures::hill(lon, lat) + 50.0).unwrap();
    std::fs::rename(&tmp, dir.path().join("hill.tif")).unwrap();
    let state = edit::wait_for(channel.clone(), 2).await.unwrap();
    assert_eq!(state.generation, 2);
    let h = edit::height_at(channel, 10.25, 45.25).await.unwrap().unwrap();
    assert!((h - 2050.0).abs() < 0.1, "{h}");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_writer_is_never_read_half_way() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let peak = (10u32, 1082u32, 254u32);
    let old_hash = edit::tile_hash(channel.clone(), "dem", peak).await.unwrap();

    // The new version, made elsewhere, then written over the file in 12
    // chunks 60 ms apart (0.7 s in all) through one open file.
    let staging = tempfile::tempdir().unwrap();
    let new = fixtures::write_dem(&staging.path().join("new.tif"), &fixtures::hill_spec(), |lon, lat| {
        fixtures::hill(lon, lat) + 7.0
    })
    .unwrap();
    let bytes = std::fs::read(new).unwrap();
    let path = dir.path().join("hill.tif");
    let watcher_channel = channel.clone();
    let seen = tokio::spawn(async move {
        let mut seen = std::collections::BTreeSet::new();
        for _ in 0..60 {
            seen.insert(edit::tile_hash(watcher_channel.clone(), "dem", peak).await.unwrap());
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        seen
    });
    let writer = std::thread::Builder::new()
        .name("slow-writer".into())
        .spawn(move || {
            use std::io::Write;
            let mut file = std::fs::File::create(&path).unwrap();
            for chunk in bytes.chunks(bytes.len().div_ceil(12)) {
                file.write_all(chunk).unwrap();
                file.flush().unwrap();
                std::thread::sleep(Duration::from_millis(60));
            }
        })
        .unwrap();
    writer.join().unwrap();
    let g = events.generation(2).await.unwrap();
    assert_eq!(g.changed_sources, ["dem"]);
    let new_hash = edit::tile_hash(channel.clone(), "dem", peak).await.unwrap();
    assert_ne!(new_hash, old_hash);
    let seen = seen.await.unwrap();
    assert!(seen.iter().all(|h| *h == old_hash || *h == new_hash), "a partial tile was served: {seen:?}");
    tokio::time::sleep(Duration::from_millis(1500)).await;
    assert!(events.errors().is_empty(), "errors during a slow write: {:?}", events.errors());
    assert_eq!(events.generations().len(), 1, "one generation for one save: {:?}", events.generations());
    let h = edit::height_at(channel, 10.25, 45.25).await.unwrap().unwrap();
    assert!((h - 2007.0).abs() < 0.1, "{h}");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_deleted_file_keeps_its_tiles_until_restored() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let peak = (10u32, 1082u32, 254u32);
    let before = edit::tile_hash(channel.clone(), "dem", peak).await.unwrap();
    let path = dir.path().join("hill.tif");
    std::fs::remove_file(&path).unwrap();
    let state = edit::wait_for(channel.clone(), 2).await.unwrap();
    let dem = state.sources.iter().find(|s| s.id == "dem").unwrap();
    assert_eq!(dem.status, pb::SourceStatus::Error as i32);
    assert!(dem.error.contains("No such file") && dem.error.contains("hill.tif"), "{}", dem.error);
    assert_eq!(edit::tile_hash(channel.clone(), "dem", peak).await.unwrap(), before, "last good tiles are served");
    assert_eq!(events.errors().len(), 1);

    fixtures::write_dem(&path, &fixtures::hill_spec(), |lon, lat| fixtures::hill(lon, lat) + 3.0).unwrap();
    let state = edit::wait_for(channel.clone(), 3).await.unwrap();
    let dem = state.sources.iter().find(|s| s.id == "dem").unwrap();
    assert_eq!(dem.status, pb::SourceStatus::Ready as i32, "{}", dem.error);
    let h = edit::height_at(channel, 10.25, 45.25).await.unwrap().unwrap();
    assert!((h - 2003.0).abs() < 0.1, "{h}");
    daemon.stop(&["keeping the last good version"]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_burst_of_saves_ends_in_the_last_one() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let path = dir.path().join("hill.tif");
    for k in 1..=50 {
        fixtures::write_dem(&path, &fixtures::hill_spec(), |lon, lat| fixtures::hill(lon, lat) + f64::from(k)).unwrap();
    }
    // It settles on the last save, and stays there.
    let mut last = None;
    for _ in 0..200 {
        last = edit::height_at(channel.clone(), 10.25, 45.25).await.unwrap();
        if last.is_some_and(|h| (h - 2050.0).abs() < 0.1) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(last.is_some_and(|h| (h - 2050.0).abs() < 0.1), "{last:?}");
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let h = edit::height_at(channel, 10.25, 45.25).await.unwrap().unwrap();
    assert!((h - 2050.0).abs() < 0.1, "{h}");
    assert!(events.errors().is_empty(), "{:?}", events.errors());
    let generations = events.generations();
    assert!(!generations.is_empty() && generations.len() <= 50, "{} generations", generations.len());
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_change_invisible_at_coarse_levels_stops_there() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = scene(dir.path(), "\n[[source]]\nid = \"shade\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\n");
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let keys = dem_tiles(4..=11);
    hashes(&channel, "shade", &keys).await;
    // +1 m and -1 m on two pixels of one 2 x 2 block on the plain (500 m):
    // every mip level averages them away, so tiles that read mips come out
    // the same, and so do the hillshade tiles made from them.
    edit::rewrite_window(&dir.path().join("hill.tif"), 10, 10, 2, 1, |x, _, h| if x == 10 { h + 1.0 } else { h - 1.0 })
        .unwrap();
    let g = events.generation(2).await.unwrap();
    assert!(g.tiles_cut_off > 0, "{g:?}");
    assert!(g.tiles_rebuilt > 0, "{g:?}");
    let after = hashes(&channel, "shade", &keys).await;
    let fresh = Reliefd::start(&manifest, &[]).unwrap();
    assert_eq!(after, hashes(&fresh.channel().await.unwrap(), "shade", &keys).await);
    fresh.stop(&[]).unwrap();
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn manifest_edits_rebuild_only_what_they_affect() {
    let dir = tempfile::tempdir().unwrap();
    let shade = "\n[[source]]\nid = \"shade\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\n";
    let manifest = scene(dir.path(), shade);
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let keys = dem_tiles(8..=9);
    let dem_before = hashes(&channel, "dem", &keys).await;
    let shade_before = hashes(&channel, "shade", &keys).await;
    let text = std::fs::read_to_string(&manifest).unwrap();

    // Add a source: nothing else is rebuilt.
    let shade2 = "\n[[source]]\nid = \"shade2\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\nazimuth_deg = 90\n";
    std::fs::write(&manifest, text.replace(shade, &format!("{shade}{shade2}"))).unwrap();
    let g = events.generation(2).await.unwrap();
    assert_eq!(g.changed_sources, ["shade2"]);
    assert_eq!(g.tiles_rebuilt, 0);
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    assert!(state.sources.iter().any(|s| s.id == "shade2"));
    assert_eq!(hashes(&channel, "dem", &keys).await, dem_before);

    // Change one: only its tiles are rebuilt.
    std::fs::write(&manifest, text.replace(shade, &format!("{shade}azimuth_deg = 200\n{shade2}"))).unwrap();
    let g = events.generation(3).await.unwrap();
    assert_eq!(g.changed_sources, ["shade"]);
    assert_eq!(g.tiles_rebuilt, keys.len() as u64, "the cached shade tiles: {g:?}\n{:#?}", daemon.log());
    assert_eq!(hashes(&channel, "dem", &keys).await, dem_before);
    let shade_after = hashes(&channel, "shade", &keys).await;
    assert!(shade_after.iter().zip(&shade_before).all(|(a, b)| a != b), "the light moved");

    // A broken edit is refused and the scene stays; the next good one is taken.
    std::fs::write(&manifest, "[scene\nname = ").unwrap();
    for _ in 0..100 {
        let state =
            SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
        if !state.manifest_error.is_empty() {
            assert!(state.manifest_error.contains("scene.toml"), "{}", state.manifest_error);
            assert_eq!(state.generation, 3);
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(hashes(&channel, "dem", &keys).await, dem_before);

    // Remove the new source: nothing is rebuilt.
    std::fs::write(&manifest, text.replace(shade, &format!("{shade}azimuth_deg = 200\n"))).unwrap();
    let g = events.generation(4).await.unwrap();
    assert_eq!(g.changed_sources, ["shade2"]);
    assert_eq!(g.tiles_rebuilt, 0);
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    assert!(state.manifest_error.is_empty());
    assert!(!state.sources.iter().any(|s| s.id == "shade2"));
    daemon.stop(&["keeping the scene as it was"]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn lock_files_and_temporaries_never_trigger_a_read() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    // LibreOffice/QGIS-style lock, an editor back-up and a temporary copy.
    for name in [".~lock.hill.tif#", "hill.tif~", "hill.tif.tmp"] {
        std::fs::write(dir.path().join(name), b"not data").unwrap();
    }
    std::fs::remove_file(dir.path().join(".~lock.hill.tif#")).unwrap();
    tokio::time::sleep(Duration::from_millis(900)).await;
    assert!(events.generations().is_empty(), "{:?}", events.generations());
    assert!(events.errors().is_empty(), "{:?}", events.errors());
    let state = SceneServiceClient::new(channel).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    assert_eq!(state.generation, 1);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sidecar_written_after_its_raster_is_picked_up() {
    let dir = tempfile::tempdir().unwrap();
    // A DEM with a flat 123 m terrace in its north-west corner.
    let path = fixtures::write_dem(&dir.path().join("hill.tif"), &fixtures::hill_spec(), |lon, lat| {
        if lon < 10.1 && lat > 45.4 { 123.0 } else { fixtures::hill(lon, lat) }
    })
    .unwrap();
    let manifest = fixtures::write_manifest(dir.path(), "[scene]\nname = \"pam\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n[layers]\nheight = \"dem\"\n").unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    assert_eq!(edit::height_at(channel.clone(), 10.05, 45.45).await.unwrap(), Some(123.0));
    // QGIS or gdal_edit.py records a nodata value in the .aux.xml sidecar.
    let aux = path.with_extension("tif.aux.xml");
    std::fs::write(&aux, "<PAMDataset>\n  <PAMRasterBand band=\"1\">\n    <NoDataValue>123</NoDataValue>\n  </PAMRasterBand>\n</PAMDataset>\n").unwrap();
    let state = edit::wait_for(channel.clone(), 2).await.unwrap();
    let dem = state.sources.iter().find(|s| s.id == "dem").unwrap();
    assert!(dem.files.iter().any(|f| f.ends_with("hill.tif")), "{:?}", dem.files);
    assert_eq!(edit::height_at(channel.clone(), 10.05, 45.45).await.unwrap(), None, "the terrace is nodata now");
    assert!(edit::height_at(channel, 10.25, 45.25).await.unwrap().is_some());
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_file_in_a_new_folder_that_a_vrt_comes_to_name_is_watched_from_then_on() {
    let dir = tempfile::tempdir().unwrap();
    let (west, east) = (dir.path().join("west"), dir.path().join("east"));
    std::fs::create_dir_all(&west).unwrap();
    std::fs::create_dir_all(&east).unwrap();
    let west_dem = fixtures::write_dem(&west.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    // The same hill's eastern neighbour, 10.5..11 E, in a folder of its own.
    let east_spec = fixtures::RasterSpec { origin_x: 10.5, ..fixtures::hill_spec() };
    let east_dem = fixtures::write_dem(&east.join("hill.tif"), &east_spec, |_, _| 700.0).unwrap();
    let vrt = dir.path().join("mosaic.vrt");
    let build = |files: &[&Path]| {
        let status = std::process::Command::new("gdalbuildvrt").arg("-q").arg(&vrt).args(files).status().unwrap();
        assert!(status.success(), "gdalbuildvrt (gdal-bin)");
    };
    build(&[&west_dem]);
    let manifest = fixtures::write_manifest(dir.path(), "[scene]\nname = \"grows\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"mosaic.vrt\"\n\n[layers]\nheight = \"dem\"\n").unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    assert_eq!(edit::height_at(channel.clone(), 10.75, 45.25).await.unwrap(), None);

    // The VRT now names the eastern file too: read once the VRT is saved.
    build(&[&west_dem, &east_dem]);
    edit::wait_for(channel.clone(), 2).await.unwrap();
    assert_eq!(edit::height_at(channel.clone(), 10.75, 45.25).await.unwrap(), Some(700.0));

    // An edit to the eastern file alone, in a folder no file of the scene
    // was in when reliefd started, is seen too.
    edit::rewrite_window(&east_dem, 0, 0, 400, 400, |_, _, h| h + 100.0).unwrap();
    let state = edit::wait_for(channel.clone(), 3).await.unwrap();
    assert_eq!(state.generation, 3, "the edit in the new folder was not seen");
    assert_eq!(edit::height_at(channel, 10.75, 45.25).await.unwrap(), Some(800.0));
    daemon.stop(&[]).unwrap();
}

/// A save that leaves the manifest's text as it was, and a file beside it
/// sharing its name's stem (`scene.log`, an editor's `scene.toml.bak`),
/// make no generation; an edit of the text does.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unchanged_manifest_makes_no_generation() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = relief_tests::scenes::hill(dir.path(), "").unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let text = std::fs::read_to_string(&manifest).unwrap();
    std::fs::write(&manifest, &text).unwrap();
    for n in 0..5 {
        std::fs::write(dir.path().join("scene.log"), format!("line {n}\n")).unwrap();
        tokio::time::sleep(Duration::from_millis(150)).await;
    }
    tokio::time::sleep(Duration::from_millis(800)).await;
    assert!(events.generations().is_empty(), "{:?}", events.generations());
    std::fs::write(&manifest, text.replace("name = \"hill\"", "name = \"hill edited\"")).unwrap();
    let state = edit::wait_for(channel, 2).await.unwrap();
    assert_eq!(state.name, "hill edited");
    daemon.stop(&[]).unwrap();
}
