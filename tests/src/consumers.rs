//! The real consumers of relief's standard tiles (issue 40) in headless
//! Chromium: CesiumJS and MapLibre GL JS from `tests/npm`, on the pages in
//! `tests/pages`, served from loopback by `pages::Pages` with
//! `clients/web/js/relief-tiles.js` (the helper that keeps them live); the
//! scenes they read, made from analytic fixtures; reliefd's own heights
//! to compare with. Chromium runs with no network but loopback.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context;
use serde_json::Value;

use crate::browser::{self, Browser};
use crate::pages::Pages;
use crate::{fixtures, http, npm};

/// How long a page may take to load its libraries and first tiles (a
/// debug reliefd making every tile, WebGL on SwiftShader, two cores).
pub const PAGE_TIMEOUT: Duration = Duration::from_secs(120);

/// The pages' server, with Cesium's build, MapLibre's dist, the pages and
/// the helper; None, with a note, where Chromium, node or npm is missing
/// (or npm cannot install outside CI).
pub fn pages(test: &str) -> Option<Pages> {
    if !browser::available() || !npm::available() {
        eprintln!("skipping {test}: it needs chromium, node and npm (scripts/setup.sh installs them)");
        return None;
    }
    let modules = match npm::node_modules() {
        Ok(m) => m,
        Err(e) if std::env::var_os("CI").is_none() => {
            eprintln!("skipping {test}: the npm packages cannot be installed here: {e:#}");
            return None;
        }
        Err(e) => panic!("{test}: CI must install the npm packages: {e:#}"),
    };
    let root = crate::workspace_root();
    let mounts = vec![
        ("/cesium/".to_owned(), modules.join("cesium/Build/Cesium")),
        ("/maplibre/".to_owned(), modules.join("maplibre-gl/dist")),
        ("/relief-tiles.js".to_owned(), root.join("clients/web/js/relief-tiles.js")),
        ("/".to_owned(), root.join("tests/pages")),
    ];
    Some(Pages::start(mounts).expect("a server on loopback"))
}

/// Chromium, kept off every network but loopback, showing `page`
/// (`/cesium.html`) of `pages` for reliefd at `relief`, once its module
/// has run. WebGL runs on SwiftShader, as headless Chromium gives it with
/// browser.rs's flags (`--disable-gpu` included; the pages check WebGL is there).
pub async fn open(pages: &Pages, page: &str, relief: &str, (width, height): (u32, u32)) -> anyhow::Result<Browser> {
    let browser = Browser::start_with(width, height, browser::LOOPBACK_ONLY).await?;
    browser.navigate(&format!("{}?relief={relief}", pages.url(page))).await?;
    if let Err(e) = browser.wait_for("document.body.dataset.ready === '1'", PAGE_TIMEOUT).await {
        let state = browser
            .eval("JSON.stringify([location.href, document.readyState, performance.getEntriesByType('resource').map(r => [r.name, r.duration|0, r.responseStatus])])")
            .await
            .unwrap_or_default();
        anyhow::bail!("{e:#}; the page's errors: {:?}; its state: {state}", browser.errors());
    }
    Ok(browser)
}

/// Starts reliefd on `manifest` letting `pages`' origin call it: a page
/// from another origin is refused unless named (`--allow-origin`).
pub fn reliefd(manifest: &Path, pages: &Pages) -> anyhow::Result<crate::daemon::Reliefd> {
    crate::daemon::Reliefd::start(manifest, &["--allow-origin", &pages.url("")])
}

/// reliefd's heights at `points` (lon, lat) from `GET /api/elevation`, and
/// the generation it read them in. A missing height (nodata) is an error.
pub fn elevations(relief: &str, points: &[(f64, f64)]) -> anyhow::Result<(u64, Vec<f64>)> {
    let list = points.iter().map(|(lon, lat)| format!("{lon},{lat}")).collect::<Vec<_>>().join(";");
    let reply = http::get(&format!("{relief}/api/elevation?points={list}"))?;
    anyhow::ensure!(
        reply.status == 200,
        "GET /api/elevation: {} {}",
        reply.status,
        String::from_utf8_lossy(&reply.body)
    );
    let answer = reply.json()?;
    let generation = match &answer["generation"] {
        Value::String(s) => s.parse()?,
        v => v.as_u64().unwrap_or(0),
    };
    let samples = answer["samples"].as_array().context("no samples")?;
    anyhow::ensure!(samples.len() == points.len(), "{} samples for {} points: {answer}", samples.len(), points.len());
    // proto3 JSON leaves a height of 0 out.
    let heights = samples.iter().map(|s| s.get("heightM").and_then(Value::as_f64).unwrap_or(0.0)).collect();
    Ok((generation, heights))
}

/// `count` points spread over `[west, east] x [south, north]`, the same
/// every run.
pub fn points(count: usize, [west, south, east, north]: [f64; 4]) -> Vec<(f64, f64)> {
    let mut random = fixtures::Lcg(0x5eed_0040);
    (0..count).map(|_| (random.range(west, east), random.range(south, north))).collect()
}

/// The Cesium scene: the Gaussian hill (`fixtures::hill`) as the height
/// layer and a town of 64 extruded buildings (6 to 24 m, footprints from
/// `fixtures::write_town`) at `TOWN` as the buildings layer. The manifest
/// and the DEM, which a test edits in place.
pub fn hill_and_town(dir: &Path) -> anyhow::Result<(PathBuf, PathBuf)> {
    let dem = fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill)?;
    let town = fixtures::write_town(&dir.join("town.shp"), TOWN, 64)?;
    let manifest = fixtures::write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"hill and town\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n[[source]]\nid = \"footprints\"\nkind = \"shapefile\"\npath = \"{}\"\n\n[[source]]\nid = \"buildings\"\nkind = \"extrude\"\ninputs = [\"footprints\", \"dem\"]\nheight_attribute = \"height\"\nheight = 8\nmin_level = 8\n\n[layers]\nheight = \"dem\"\nbuildings = \"buildings\"\n",
            town.display()
        ),
    )?;
    Ok((manifest, dem))
}

/// Where `hill_and_town` puts its town (lon, lat).
pub const TOWN: (f64, f64) = (10.30, 45.30);

/// A tilted plane over `fixtures::hill_spec()`'s extent: bilinear
/// interpolation gives it back exactly, so a reader's error is only its
/// encoding's.
pub fn plane(lon: f64, lat: f64) -> f64 {
    1000.0 + 2000.0 * (lon - 10.25) + 1000.0 * (lat - 45.25)
}

/// The plane scene (`plane` as the height layer, nothing else): the
/// manifest and the DEM.
pub fn plane_scene(dir: &Path) -> anyhow::Result<(PathBuf, PathBuf)> {
    let dem = fixtures::write_dem(&dir.join("plane.tif"), &fixtures::hill_spec(), plane)?;
    let manifest = fixtures::write_manifest(
        dir,
        "[scene]\nname = \"plane\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"plane.tif\"\n\n[layers]\nheight = \"dem\"\n",
    )?;
    Ok((manifest, dem))
}

/// The DEM pixel window (x, y, width, height) covering `[west, south,
/// east, north]` of `fixtures::hill_spec()`.
pub fn window([west, south, east, north]: [f64; 4]) -> (usize, usize, usize, usize) {
    let spec = fixtures::hill_spec();
    let x = ((west - spec.origin_x) / spec.pixel).round() as usize;
    let y = ((spec.origin_y - north) / spec.pixel).round() as usize;
    let w = ((east - west) / spec.pixel).round() as usize;
    let h = ((north - south) / spec.pixel).round() as usize;
    (x, y, w, h)
}

/// A page's collected errors (tile failures, exceptions, console errors).
pub async fn page_errors(page: &Browser) -> anyhow::Result<Vec<String>> {
    let mut errors: Vec<String> = serde_json::from_value(page.eval("page.errors").await?)?;
    errors.extend(page.errors());
    Ok(errors)
}
