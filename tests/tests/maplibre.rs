//! relief's Terrarium tiles as MapLibre GL JS terrain (issue 40), in a
//! real headless Chromium (WebGL on SwiftShader) with no network but
//! loopback: a `raster-dem` source from `/tiles/terrarium.json`,
//! `map.setTerrain`, and `map.queryTerrainElevation` against reliefd's
//! `/api/elevation` on a tilted plane, before and after an edit that
//! relief-tiles.js brings to the map through `/tiles/changes`.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::f64::consts::PI;
use std::time::Duration;

use relief_tests::browser::Browser;
use relief_tests::consumers::{self, PAGE_TIMEOUT};
use relief_tests::edit;
use serde_json::json;

/// Terrarium's step: heights are written in 1/256 m.
const STEP_M: f64 = 1.0 / 256.0;
/// Bilinear interpolation gives a plane back exactly; what is left is
/// float32 rounding of the DEM's heights and of reliefd's resampled ones
/// (1.2e-4 m at 1300 m), once each side.
const INTERPOLATION_M: f64 = 0.002;
/// The edited window, raised by `RAISE_M`; the points lie inside it, far
/// enough from its edges (0.02 degrees: 16 DEM pixels, 29 Terrarium
/// pixels at zoom 11) that every sample they read was raised.
const EDITED: [f64; 4] = [10.19, 45.21, 10.31, 45.29];
const INSIDE: [f64; 4] = [10.215, 45.232, 10.285, 45.268];
const RAISE_M: f32 = 50.0;
/// How long the map may take to show an edit: a poll deadline.
const EDIT_DEADLINE: Duration = Duration::from_secs(30);

/// Web Mercator pixel coordinates (256-pixel tiles) of (lon, lat) at `zoom`.
fn pixel(zoom: u32, (lon, lat): (f64, f64)) -> (f64, f64) {
    let size = 256.0 * f64::from(1u32 << zoom);
    let y = (1.0 - (lat.to_radians().tan() + 1.0 / lat.to_radians().cos()).ln() / PI) / 2.0;
    ((lon + 180.0) / 360.0 * size, y * size)
}

async fn elevations(page: &Browser, points: &[(f64, f64)]) -> Vec<Option<f64>> {
    let list: Vec<[f64; 2]> = points.iter().map(|&(lon, lat)| [lon, lat]).collect();
    serde_json::from_value(page.eval(&format!("page.elevations({})", json!(list))).await.unwrap()).unwrap()
}

/// How far MapLibre's heights at `points` are from reliefd's there, at
/// worst; and the page's heights. MapLibre reads pixel (i, j) as the
/// height at the tile coordinate (i, j), its north-west corner
/// (`Terrain#getDEMElevation` floors `coord * dim` and interpolates from
/// there), and reliefd writes each Terrarium pixel's height there (not at
/// its centre, as Mapzen's tiles do, which MapLibre shows half a pixel
/// off): the same points, no offset.
async fn worst(page: &Browser, relief: &str, points: &[(f64, f64)]) -> (f64, Vec<Option<f64>>, Vec<f64>) {
    let shown = elevations(page, points).await;
    let (_, want) = consumers::elevations(relief, points).unwrap();
    let worst = shown.iter().zip(&want).map(|(s, w)| s.map_or(f64::INFINITY, |s| (s - w).abs())).fold(0.0, f64::max);
    (worst, shown, want)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn maplibre_terrain_from_terrarium_agrees_with_relief_before_and_after_an_edit() {
    let Some(pages) = consumers::pages("maplibre_terrain_from_terrarium_agrees_with_relief_before_and_after_an_edit")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (manifest, dem) = consumers::plane_scene(dir.path()).unwrap();
    let daemon = consumers::reliefd(&manifest, &pages).unwrap();
    let relief = daemon.url();
    let tilejson = relief_tests::http::get(&format!("{relief}/tiles/terrarium.json")).unwrap().json().unwrap();
    let zoom = u32::try_from(tilejson["maxzoom"].as_u64().unwrap()).unwrap();

    // The map's terrain tiles are the source's deepest: MapLibre reads
    // terrain at its covering tiles' zoom, about one under the map's (at
    // zoom 11.5 it reads zoom 10), capped at the source's maxzoom.
    let page = consumers::open(&pages, "/maplibre.html", &relief, (800, 600)).await.unwrap();
    let started =
        page.eval(&format!("page.start({{center: [10.25, 45.25], zoom: {}}})", f64::from(zoom) + 1.5)).await.unwrap();
    assert_eq!(started["tilejson"]["encoding"], "terrarium", "{started}");
    page.wait_for("page.settled()", PAGE_TIMEOUT).await.unwrap();

    // Points inside the edited window, away from tile edges (where a
    // tile's border is its neighbour's).
    let points: Vec<(f64, f64)> = consumers::points(60, INSIDE)
        .into_iter()
        .filter(|&p| {
            let (x, y) = pixel(zoom, p);
            [x, y].iter().all(|v| (1.0..254.0).contains(&v.rem_euclid(256.0)))
        })
        .take(20)
        .collect();
    assert!(points.len() >= 10, "{points:?}");
    let tolerance = STEP_M + INTERPOLATION_M;
    let (error, shown, want) = worst(&page, &relief, &points).await;
    assert!(
        error <= tolerance,
        "MapLibre {shown:?} against reliefd {want:?}: {error} m apart (tolerance {tolerance} m)"
    );

    // The edit: the plane raised inside the window.
    let (x, y, w, h) = consumers::window(EDITED);
    edit::rewrite_window(&dem, x, y, w, h, |_, _, v| v + RAISE_M).unwrap();
    let raised: Vec<f64> = want.iter().map(|w| w + f64::from(RAISE_M)).collect();
    let deadline = tokio::time::Instant::now() + EDIT_DEADLINE;
    loop {
        let (error, shown, want) = worst(&page, &relief, &points).await;
        let moved = want.iter().zip(&raised).all(|(w, r)| (w - r).abs() <= INTERPOLATION_M);
        if moved && error <= tolerance {
            break;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "{EDIT_DEADLINE:?} after the edit: MapLibre {shown:?}, reliefd {want:?} (raised: {raised:?}); changes: {}",
            page.eval("JSON.stringify(page.changes)").await.unwrap()
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let changes = page.eval("page.changes").await.unwrap();
    // A window's edit: only its tiles reloaded (map.refreshTiles), not the source.
    assert!(
        changes.to_string().contains("tiles of relief-dem refreshed"),
        "the helper did not refresh the changed tiles alone: {changes}"
    );
    eprintln!("the helper applied: {changes}");
    let tiles = page.eval("page.tiles()").await.unwrap();
    assert!(
        tiles[0].as_str().unwrap().starts_with(&format!("{relief}/tiles/terrarium/")),
        "the source's tiles: {tiles}"
    );

    page.wait_for("page.settled()", PAGE_TIMEOUT).await.unwrap();
    assert_eq!(consumers::page_errors(&page).await.unwrap(), Vec::<String>::new());
    drop(page);
    daemon.stop(&[]).unwrap();
}
