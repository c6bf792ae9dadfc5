//! relief's standard tiles in CesiumJS (issue 40), in a real headless
//! Chromium with no network but loopback (Cesium itself from loopback, no
//! ion): the terrain (quantized-mesh-1.0 from /tiles/terrain/) and the
//! buildings' 3D tileset load with no tile failing; Cesium's heights equal
//! reliefd's `/api/elevation` within the mesh's stated error; a DEM edited
//! in place reaches the page through `/tiles/changes` and relief-tiles.js,
//! with no reload; the buildings show.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::time::{Duration, Instant};

use relief_tests::browser::Browser;
use relief_tests::consumers::{self, PAGE_TIMEOUT};
use relief_tests::{edit, http};
use serde_json::json;

/// What Cesium's height may differ from reliefd's beyond the mesh's
/// stated error. The mesh holds the height grid's samples within that
/// error; between samples Cesium interpolates linearly on the mesh's
/// triangles and reliefd bilinearly on the grid, which differ by at most
/// h^2/8 |f''| on the hill's curvature (about 1.9e5 m per square degree,
/// samples under 0.0007 degrees apart at the terrain's deepest level: 0.03
/// m); heights quantized to 16 bits over a tile's range add under 0.02 m.
const RESAMPLING_M: f64 = 0.1;
/// How far the edit raises the DEM.
const RAISE_M: f32 = 200.0;
/// The edited window, and a point well inside it.
const EDITED: [f64; 4] = [10.175, 45.225, 10.225, 45.275];
const PROBE: (f64, f64) = (10.2, 45.25);
/// How soon after the file's write the page must give the new height: a
/// poll deadline, not a timing.
const EDIT_DEADLINE: Duration = Duration::from_secs(2);

/// Pixels that differ between two screenshots by more than `threshold`
/// in some channel.
fn differing(a: &[u8], b: &[u8], threshold: u8) -> usize {
    let (a, b) = (image::load_from_memory(a).unwrap().to_rgb8(), image::load_from_memory(b).unwrap().to_rgb8());
    assert_eq!(a.dimensions(), b.dimensions());
    a.pixels().zip(b.pixels()).filter(|(p, q)| p.0.iter().zip(q.0).any(|(x, y)| x.abs_diff(y) > threshold)).count()
}

/// Multiplies every footprint's `height` in the shapefile at `path` by
/// `factor` through GDAL in update mode, as a GIS saves an attribute edit;
/// returns how many it changed.
fn heighten_every_building(path: &std::path::Path, factor: f64) -> anyhow::Result<usize> {
    use gdal::vector::LayerAccess;
    let options = gdal::DatasetOptions {
        open_flags: gdal::GdalOpenFlags::GDAL_OF_UPDATE | gdal::GdalOpenFlags::GDAL_OF_VECTOR,
        ..gdal::DatasetOptions::default()
    };
    let ds = gdal::Dataset::open_ex(path, options)?;
    let mut layer = ds.layer(0)?;
    let field = layer.defn().field_index("height")?;
    let fids: Vec<u64> = layer.features().filter_map(|f| f.fid()).collect();
    for &fid in &fids {
        let mut feature = layer.feature(fid).ok_or_else(|| anyhow::anyhow!("feature {fid} is gone"))?;
        let height = feature.field_as_double(field)?.unwrap_or(0.0);
        feature.set_field_double(field, height * factor)?;
        layer.set_feature(feature)?;
    }
    ds.close()?;
    Ok(fids.len())
}

async fn sample(page: &Browser, points: &[(f64, f64)]) -> anyhow::Result<Vec<f64>> {
    let list: Vec<[f64; 2]> = points.iter().map(|&(lon, lat)| [lon, lat]).collect();
    Ok(serde_json::from_value(page.eval(&format!("page.sample({})", json!(list))).await?)?)
}

/// The mesh's stated error: layer.json's `relief:terrain_mesh_error_m`,
/// else the state's `quality.terrainMeshErrorM`.
fn mesh_error_m(relief: &str, layer: &serde_json::Value) -> f64 {
    if let Some(e) = layer["relief:terrain_mesh_error_m"].as_f64() {
        return e;
    }
    let state = http::get(&format!("{relief}/api/state")).unwrap().json().unwrap();
    state["quality"]["terrainMeshErrorM"]
        .as_f64()
        .unwrap_or_else(|| panic!("neither layer.json nor the state states the mesh's error: {layer} {state}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cesium_runs_offline_from_loopback() {
    let Some(pages) = consumers::pages("cesium_runs_offline_from_loopback") else { return };
    let page = consumers::open(&pages, "/cesium.html", "http://127.0.0.1:9", (640, 400)).await.unwrap();
    let started = page.eval("page.start({})").await.unwrap();
    assert!(started["webgl"].as_u64().unwrap() >= 1, "{started}");
    page.eval("page.look(10.25, 45.25, 2000000, 0, -90)").await.unwrap();
    page.wait_for("page.settled()", PAGE_TIMEOUT).await.unwrap();
    // The ellipsoid alone, drawn in the globe's plain grey under the eye.
    let shot = image::load_from_memory(&page.screenshot().await.unwrap()).unwrap().to_rgb8();
    let centre = shot.get_pixel(shot.width() / 2, shot.height() / 2).0;
    assert!(centre.iter().all(|c| c.abs_diff(0x7f) <= 8), "the globe's centre is {centre:?}");
    // Off loopback nothing answers: no name resolves, no address is reached.
    for url in ["http://example.com/", "http://192.0.2.1/"] {
        let got = page.eval(&format!("page.offLoopback({})", json!(url))).await.unwrap();
        assert_eq!(got, "refused", "{url}");
    }
    assert_eq!(consumers::page_errors(&page).await.unwrap(), Vec::<String>::new());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cesium_terrain_equals_relief_heights_and_follows_an_edit_without_a_reload() {
    let Some(pages) = consumers::pages("cesium_terrain_equals_relief_heights_and_follows_an_edit_without_a_reload")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (manifest, dem) = consumers::hill_and_town(dir.path()).unwrap();
    let daemon = consumers::reliefd(&manifest, &pages).unwrap();
    let relief = daemon.url();
    let page = consumers::open(&pages, "/cesium.html", &relief, (960, 600)).await.unwrap();
    let started = page.eval("page.start({terrain: true})").await.unwrap();
    let tolerance = mesh_error_m(&relief, &started["layer"]) + RESAMPLING_M;

    // Heights at 20 points over the hill, from the most detailed tiles.
    let points = consumers::points(20, [10.02, 45.02, 10.48, 45.48]);
    let cesium = sample(&page, &points).await.unwrap();
    let (_, expected) = consumers::elevations(&relief, &points).unwrap();
    for ((p, c), r) in points.iter().zip(&cesium).zip(&expected) {
        assert!((c - r).abs() <= tolerance, "at {p:?}: Cesium {c} m, reliefd {r} m (tolerance {tolerance} m)");
    }

    // An edit in place, as an editor saves it: the page gives the new
    // height within the deadline, without reloading.
    page.eval("window.stayed = 'this page'").await.unwrap();
    let (_, before) = consumers::elevations(&relief, &[PROBE]).unwrap();
    // The page has the probe's tile under the version before the edit (in
    // the browser's cache for good: immutable), so only a change followed
    // gives the new height.
    let shown = sample(&page, &[PROBE]).await.unwrap()[0];
    assert!((shown - before[0]).abs() <= tolerance, "Cesium {shown} m at {PROBE:?}, reliefd {} m", before[0]);
    let want = before[0] + f64::from(RAISE_M);
    let (x, y, w, h) = consumers::window(EDITED);
    let written = Instant::now();
    edit::rewrite_window(&dem, x, y, w, h, |_, _, v| v + RAISE_M).unwrap();
    let mut got = f64::NAN;
    while written.elapsed() < EDIT_DEADLINE {
        got = sample(&page, &[PROBE]).await.unwrap()[0];
        if (got - want).abs() <= tolerance {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert!(
        (got - want).abs() <= tolerance,
        "{EDIT_DEADLINE:?} after the edit the page gives {got} m at {PROBE:?}, not {want} m; changes: {}",
        page.eval("JSON.stringify(page.changes)").await.unwrap()
    );
    eprintln!("the page gave the new height {:?} after the write", written.elapsed());
    let (_, after) = consumers::elevations(&relief, &[PROBE]).unwrap();
    assert!((after[0] - want).abs() <= 1e-3, "reliefd gives {} m after the edit, not {want} m", after[0]);
    assert_eq!(page.eval("window.stayed").await.unwrap(), "this page", "the page reloaded");
    let changes = page.eval("page.changes").await.unwrap();
    assert!(
        changes.to_string().contains("terrain: provider replaced"),
        "the helper applied no terrain change: {changes}"
    );

    page.eval(&format!("page.look({}, {}, 6000, 0, -45)", PROBE.0, PROBE.1 - 0.05)).await.unwrap();
    page.wait_for("page.settled()", PAGE_TIMEOUT).await.unwrap();
    assert_eq!(consumers::page_errors(&page).await.unwrap(), Vec::<String>::new());
    drop(page);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cesium_shows_the_buildings_tileset_on_relief_terrain() {
    let Some(pages) = consumers::pages("cesium_shows_the_buildings_tileset_on_relief_terrain") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (manifest, _) = consumers::hill_and_town(dir.path()).unwrap();
    let town = dir.path().join("town.shp");
    let daemon = consumers::reliefd(&manifest, &pages).unwrap();
    let page = consumers::open(&pages, "/cesium.html", &daemon.url(), (960, 600)).await.unwrap();
    page.eval("page.start({terrain: true, tileset: true})").await.unwrap();

    // The same view with and without the tileset.
    let (lon, lat) = consumers::TOWN;
    page.eval(&format!("page.look({lon}, {}, 2400, 0, -35)", lat - 0.012)).await.unwrap();
    page.wait_for("page.settled()", PAGE_TIMEOUT).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let with = page.screenshot().await.unwrap();
    page.eval("page.showTileset(false)").await.unwrap();
    page.wait_for("page.settled()", PAGE_TIMEOUT).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let without = page.screenshot().await.unwrap();
    if let Some(out) = std::env::var_os("RELIEF_TEST_SCREENSHOTS") {
        std::fs::write(std::path::Path::new(&out).join("cesium-town.png"), &with).unwrap();
        std::fs::write(std::path::Path::new(&out).join("cesium-town-without.png"), &without).unwrap();
    }
    let changed = differing(&with, &without, 24);
    assert!(changed > 2000, "the buildings changed only {changed} pixels of the view");

    // The town's buildings three times as tall, saved as an editor saves
    // the attribute table: relief-tiles.js reloads the changed contents or
    // swaps the tileset, and the view shows the taller town.
    page.eval("page.showTileset(true)").await.unwrap();
    page.wait_for("page.settled()", PAGE_TIMEOUT).await.unwrap();
    let edited = heighten_every_building(&town, 3.0).unwrap();
    assert_eq!(edited, 64);
    page.wait_for("page.changes.some((c) => c.applied.some((a) => a.startsWith('tileset:')))", PAGE_TIMEOUT)
        .await
        .unwrap();
    page.wait_for("page.settled()", PAGE_TIMEOUT).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let taller = page.screenshot().await.unwrap();
    if let Some(out) = std::env::var_os("RELIEF_TEST_SCREENSHOTS") {
        std::fs::write(std::path::Path::new(&out).join("cesium-town-taller.png"), &taller).unwrap();
    }
    let grown = differing(&taller, &with, 24);
    assert!(grown > 500, "the taller town changed only {grown} pixels of the view");
    eprintln!("the helper applied: {}", page.eval("JSON.stringify(page.changes)").await.unwrap());

    assert_eq!(consumers::page_errors(&page).await.unwrap(), Vec::<String>::new());
    drop(page);
    daemon.stop(&[]).unwrap();
}
