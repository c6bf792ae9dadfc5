//! The standard tiles under `/tiles/` over HTTP, as a tile client meets
//! them: quantized-mesh terrain and its layer.json, cache headers that
//! follow the version, ETags and 304s, gzip, clear 4xx answers for bad
//! requests (and the daemon serving on), a projected scene's 404, nothing
//! built until asked, and change notices after an edit that name the
//! edited tiles while the others keep their bytes (O(edit): counters).

use std::io::Read as _;

use relief_tests::daemon::Reliefd;
use relief_tests::fixtures;
use relief_tests::http::{Events, get, request_with};
use serde_json::Value;

const NORMALS: &str = "application/vnd.quantized-mesh;extensions=octvertexnormals,application/octet-stream;q=0.9";

fn standard_counters(base: &str) -> anyhow::Result<Value> {
    let state = get(&format!("{base}/api/state"))?.json()?;
    Ok(state["counters"]["standardTiles"].clone())
}

/// A proto3 JSON uint64 counter (a string, absent when 0).
fn count(counters: &Value, name: &str) -> u64 {
    counters[name].as_str().and_then(|s| s.parse().ok()).unwrap_or(0)
}

fn tile_url(base: &str, (z, x, y): (u64, u64, u64), version: &str) -> String {
    format!("{base}/tiles/terrain/{z}/{x}/{y}.terrain?v={version}")
}

/// The TMS address of the maxzoom tile holding (lon, lat).
fn tms_at(layer: &Value, lon: f64, lat: f64) -> (u64, u64, u64) {
    let z = layer["maxzoom"].as_u64().expect("layer.json has a maxzoom");
    let span = 180.0 / f64::from(1u32 << z);
    ((z), ((lon + 180.0) / span) as u64, ((lat + 90.0) / span) as u64)
}

#[test]
fn terrain_is_served_with_cache_rules_and_built_only_when_asked() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = relief_tests::scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let base = daemon.url();
    // Loaded and asked for its own tiles: no standard tile is built.
    let hash = get(&format!("{base}/api/tiles/dem/10/1052/251"))?;
    assert_eq!(hash.status, 200);
    assert_eq!(count(&standard_counters(&base)?, "terrainTilesBuilt"), 0);

    let reply = get(&format!("{base}/tiles/terrain/layer.json"))?;
    assert_eq!(reply.status, 200);
    assert_eq!(reply.header("cache-control"), Some("no-cache"));
    let layer = reply.json()?;
    assert_eq!(layer["format"], "quantized-mesh-1.0");
    assert_eq!(layer["scheme"], "tms");
    assert_eq!(layer["projection"], "EPSG:4326");
    assert_eq!(layer["tiles"][0], "{z}/{x}/{y}.terrain?v={version}");
    // The hill's 0.00125-degree pixels: level 10's 0.00069-degree samples.
    assert_eq!(layer["maxzoom"], 10);
    assert_eq!(layer["extensions"], serde_json::json!(["octvertexnormals"]), "no water layer, no watermask");
    assert_eq!(layer["available"][0][0], serde_json::json!({"startX": 0, "endX": 1, "startY": 0, "endY": 0}));
    let bounds: Vec<f64> = serde_json::from_value(layer["bounds"].clone())?;
    assert_eq!(bounds, [10.0, 45.0, 10.5, 45.5]);
    assert_eq!(layer["relief:level_error_m"][10], 1.0);
    assert_eq!(layer["relief:level_error_m"][9], 2.0);
    let version = layer["version"].as_str().unwrap().to_owned();
    // A description has an ETag too: asking again with it is a 304.
    let described = reply.header("etag").expect("layer.json has an ETag").to_owned();
    let again =
        request_with("GET", &format!("{base}/tiles/terrain/layer.json"), None, &[("if-none-match", &described)])?;
    assert_eq!(again.status, 304);

    let at = tms_at(&layer, 10.25, 45.25);
    let url = tile_url(&base, at, &version);
    let tile = request_with("GET", &url, None, &[("accept", NORMALS)])?;
    assert_eq!(tile.status, 200, "{}", String::from_utf8_lossy(&tile.body));
    assert_eq!(tile.header("content-type"), Some("application/vnd.quantized-mesh"));
    assert_eq!(tile.header("cache-control"), Some("public, max-age=31536000, immutable"));
    assert_eq!(tile.header("x-relief-version"), Some(version.as_str()));
    let etag = tile.header("etag").expect("an ETag").to_owned();
    // The header's heights hold the hill's summit within the level's error.
    let min = f32::from_le_bytes(tile.body[24..28].try_into()?);
    let max = f32::from_le_bytes(tile.body[28..32].try_into()?);
    assert!(min >= 499.0 && (max - 2000.0).abs() < 2.0, "heights {min}..{max}");

    // The same tile again: 304 for its ETag, gzip that inflates to it.
    let again = request_with("GET", &url, None, &[("accept", NORMALS), ("if-none-match", &etag)])?;
    assert_eq!(again.status, 304);
    let zipped = request_with("GET", &url, None, &[("accept", NORMALS), ("accept-encoding", "gzip")])?;
    assert_eq!(zipped.header("content-encoding"), Some("gzip"));
    let zipped_etag = zipped.header("etag").expect("an ETag");
    assert_ne!(zipped_etag, etag, "each encoding has its own ETag");
    let again = request_with(
        "GET",
        &url,
        None,
        &[("accept", NORMALS), ("accept-encoding", "gzip"), ("if-none-match", zipped_etag)],
    )?;
    assert_eq!(again.status, 304);
    let mut inflated = Vec::new();
    flate2::read::GzDecoder::new(&zipped.body[..]).read_to_end(&mut inflated)?;
    assert_eq!(inflated, tile.body);
    assert_eq!(zipped.header("vary"), Some("Accept, Accept-Encoding, Origin"));
    // gzip;q=0 refuses it.
    let refused = request_with("GET", &url, None, &[("accept", NORMALS), ("accept-encoding", "gzip;q=0, identity")])?;
    assert_eq!((refused.header("content-encoding"), refused.body.len()), (None, tile.body.len()));
    // Without a version: ask each time; an old version: the current tile,
    // kept briefly.
    let bare = request_with("GET", &url.replace(&format!("?v={version}"), ""), None, &[("accept", NORMALS)])?;
    assert_eq!((bare.status, bare.header("cache-control")), (200, Some("no-cache")));
    let old = request_with("GET", &tile_url(&base, at, "0123456789ab"), None, &[("accept", NORMALS)])?;
    assert_eq!((old.status, old.header("cache-control")), (200, Some("public, max-age=10")));
    assert_eq!(old.body, tile.body);

    let c = standard_counters(&base)?;
    assert_eq!(count(&c, "terrainTilesBuilt"), 1, "one tile, with normals, built once: {c}");
    assert_eq!(count(&c, "terrainTilesServed"), 7, "304s included: {c}");
    assert_eq!(count(&c, "notModified"), 2, "{c}");
    assert_eq!(count(&c, "terrariumTilesBuilt") + count(&c, "glbTilesBuilt"), 0, "nothing else asked for: {c}");
    daemon.stop(&[])?;
    Ok(())
}

/// The XYZ address (rows from the north) of the tile holding (lon, lat).
fn xyz_at(z: u32, lon: f64, lat: f64) -> (u64, u64, u64) {
    let n = f64::from(1u32 << z);
    let y = (1.0 - lat.to_radians().tan().asinh() / std::f64::consts::PI) / 2.0 * n;
    (u64::from(z), ((lon + 180.0) / 360.0 * n) as u64, y as u64)
}

#[test]
fn xyz_tiles_reproject_the_scene_for_maplibre() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = relief_tests::scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let base = daemon.url();
    let doc = get(&format!("{base}/tiles/terrarium.json"))?.json()?;
    assert_eq!((doc["tilejson"].as_str(), doc["encoding"].as_str()), (Some("3.0.0"), Some("terrarium")));
    // Level 10's samples are 360 / 2^11 / 256 degrees: zoom 11's pixels.
    assert_eq!(doc["maxzoom"], 11);
    let template = doc["tiles"][0].as_str().unwrap();
    assert!(template.starts_with(&format!("{base}/tiles/terrarium/{{z}}/{{x}}/{{y}}.png?v=")), "{template}");
    // The summit's tile: each pixel's Terrarium height against the hill's
    // formula at the pixel's north-west corner (where MapLibre and deck.gl
    // read it), within bilinear resampling (twice, DEM to lattice to
    // pixel) of a smooth hill: 0.5 m.
    let (z, x, y) = xyz_at(11, 10.25, 45.25);
    let url = template.replace("{z}", &z.to_string()).replace("{x}", &x.to_string()).replace("{y}", &y.to_string());
    let png = get(&url)?;
    assert_eq!((png.status, png.header("content-type")), (200, Some("image/png")));
    assert_eq!(png.header("cache-control"), Some("public, max-age=31536000, immutable"));
    let image = image::load_from_memory(&png.body)?.to_rgb8();
    let n = f64::from(1u32 << z);
    let mut worst = 0.0f64;
    for (i, j, p) in image.enumerate_pixels() {
        let h = f64::from(p[0]) * 256.0 + f64::from(p[1]) + f64::from(p[2]) / 256.0 - 32768.0;
        let lon = (x as f64 + f64::from(i) / 256.0) / n * 360.0 - 180.0;
        let lat =
            (std::f64::consts::PI * (1.0 - 2.0 * (y as f64 + f64::from(j) / 256.0) / n)).sinh().atan().to_degrees();
        worst = worst.max((h - fixtures::hill(lon, lat)).abs());
    }
    assert!(worst < 0.5, "Terrarium heights off the hill by up to {worst} m");
    // The colour layer likewise, and both outside the data: 404.
    let imagery = get(&format!("{base}/tiles/imagery.json"))?.json()?;
    assert!(imagery.get("encoding").is_none());
    let colour = get(&format!("{base}/tiles/imagery/{z}/{x}/{y}.png"))?;
    assert_eq!((colour.status, colour.header("cache-control")), (200, Some("no-cache")));
    let far = get(&format!("{base}/tiles/terrarium/11/0/0.png"))?;
    assert_eq!(far.status, 404);
    assert!(far.json()?["message"].as_str().unwrap_or_default().contains("holds none of the scene's data"));
    let c = standard_counters(&base)?;
    assert_eq!((count(&c, "terrariumTilesBuilt"), count(&c, "imageryTilesBuilt")), (1, 1), "{c}");
    assert_eq!(count(&c, "terrainTilesBuilt"), 0, "no quantized-mesh asked for, none built: {c}");
    daemon.stop(&[])?;
    Ok(())
}

#[test]
fn bad_requests_get_clear_4xx_answers_and_the_daemon_serves_on() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = relief_tests::scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let base = daemon.url();
    let layer = get(&format!("{base}/tiles/terrain/layer.json"))?.json()?;
    let version = layer["version"].as_str().unwrap();
    // (URL, request headers, status, what the message says)
    type Case<'a> = (String, &'a [(&'a str, &'a str)], u16, &'a str);
    let cases: [Case<'_>; 6] = [
        // Outside `available`: past the finest level, and beside the data.
        (tile_url(&base, (11, 0, 0), version), &[], 404, "levels run 0..=10"),
        (tile_url(&base, (10, 0, 0), version), &[], 404, "level 10 has x"),
        (
            tile_url(&base, tms_at(&layer, 10.25, 45.25), version),
            &[("accept", "application/vnd.quantized-mesh;extensions=octvertexnormals-metadata")],
            406,
            "'metadata'",
        ),
        (
            tile_url(&base, tms_at(&layer, 10.25, 45.25), version),
            &[("accept", "application/vnd.quantized-mesh;extensions=watermask")],
            406,
            "no water layer",
        ),
        (format!("{base}/tiles/terrain/10/x/3.terrain"), &[], 400, "column 'x' is not a number"),
        (format!("{base}/tiles/terrain/10/1/3.png"), &[], 404, "{z}/{x}/{y}.terrain"),
    ];
    for (url, headers, status, says) in cases {
        let reply = request_with("GET", &url, None, headers)?;
        let body = reply.json()?;
        let message = body["message"].as_str().unwrap_or_default();
        assert_eq!(reply.status, status, "{url}: {body}");
        assert!(message.contains(says), "{url}: '{message}' should say '{says}'");
        assert!(!message.contains("Error {") && !message.contains("Some("), "no Debug output: {message}");
    }
    assert_eq!(get(&format!("{base}/tiles/terrain/layer.json"))?.status, 200);
    daemon.stop(&[])?;
    Ok(())
}

#[test]
fn a_projected_scene_has_no_quantized_mesh_and_says_why() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    fixtures::write_dem(&dir.path().join("utm.tif"), &fixtures::utm_spec(), fixtures::utm_surface)?;
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"utm\"\ngrid = { crs = \"EPSG:32612\" }\n\n\
         [[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"utm.tif\"\n\n[layers]\nheight = \"dem\"\n",
    )?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let base = daemon.url();
    for path in [
        "/tiles/terrain/layer.json",
        "/tiles/terrain/0/0/0.terrain",
        "/tiles/terrarium.json",
        "/tiles/imagery/0/0/0.png",
    ] {
        let reply = get(&format!("{base}{path}"))?;
        assert_eq!(reply.status, 404, "{path}");
        let message = reply.json()?["message"].as_str().unwrap_or_default().to_owned();
        assert!(message.contains("projected") && message.contains("EPSG:32612"), "{path}: {message}");
    }
    daemon.stop(&[])?;
    Ok(())
}

#[test]
fn an_edit_names_its_tiles_and_only_they_are_built_again() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = relief_tests::scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let base = daemon.url();
    let layer = get(&format!("{base}/tiles/terrain/layer.json"))?.json()?;
    let version = layer["version"].as_str().unwrap().to_owned();
    // The edit: a 20-pixel square near the south-west corner (10.0125 E,
    // 45.0125 N); the far tile holds the north-east corner.
    let (near, far) = (tms_at(&layer, 10.0125, 45.0125), tms_at(&layer, 10.49, 45.49));
    let etag = |at, v: &str| -> anyhow::Result<String> {
        let reply = request_with("GET", &tile_url(&base, at, v), None, &[("accept", NORMALS)])?;
        anyhow::ensure!(reply.status == 200, "{}", String::from_utf8_lossy(&reply.body));
        Ok(reply.header("etag").unwrap_or_default().to_owned())
    };
    let (near_before, far_before) = (etag(near, &version)?, etag(far, &version)?);
    let built_before = count(&standard_counters(&base)?, "terrainTilesBuilt");

    let mut notices = Events::open(&format!("{base}/tiles/changes"))?;
    let (name, data) = notices.next_event()?.expect("the versions event");
    assert_eq!(name, "versions");
    let versions: Value = serde_json::from_str(&data)?;
    assert_eq!(versions["terrain"]["version"], version.as_str());

    let hill = dir.path().join("hill.tif");
    relief_tests::edit::rewrite_window(&hill, 0, 380, 20, 20, |_, _, h| h + 100.0)?;
    let (name, data) = notices.next_event()?.expect("a changes event");
    assert_eq!(name, "changes");
    let notice: Value = serde_json::from_str(&data)?;
    let terrain = &notice["terrain"];
    let new_version = terrain["version"].as_str().unwrap().to_owned();
    assert_ne!(new_version, version);
    assert_eq!(terrain["all"], false);
    let covers = |(z, x, y): (u64, u64, u64)| {
        terrain["tiles"].as_array().unwrap().iter().any(|r| {
            r["z"] == z
                && (r["x"][0].as_u64().unwrap()..=r["x"][1].as_u64().unwrap()).contains(&x)
                && (r["y"][0].as_u64().unwrap()..=r["y"][1].as_u64().unwrap()).contains(&y)
        })
    };
    assert!(covers(near), "the edited tile is named: {notice}");
    // The Web Mercator tiles of the heights changed too, the colour's not.
    let terrarium = &notice["terrarium"];
    assert_eq!(terrarium["all"], false, "{notice}");
    let (mz, mx, my) = xyz_at(11, 10.0125, 45.0125);
    assert!(
        terrarium["tiles"].as_array().unwrap().iter().any(|r| r["z"] == mz
            && (r["x"][0].as_u64().unwrap()..=r["x"][1].as_u64().unwrap()).contains(&mx)
            && (r["y"][0].as_u64().unwrap()..=r["y"][1].as_u64().unwrap()).contains(&my)),
        "{notice}"
    );
    assert!(notice.get("imagery").is_none(), "{notice}");
    assert!(!covers(far), "a tile two away is not: {notice}");
    for z in 0..=10 {
        assert!(terrain["tiles"].as_array().unwrap().iter().any(|r| r["z"] == z), "level {z} named: {notice}");
    }
    // The far tile keeps its bytes and is not built again; the near one
    // is new.
    assert_eq!(etag(far, &new_version)?, far_before);
    assert_ne!(etag(near, &new_version)?, near_before);
    let built = count(&standard_counters(&base)?, "terrainTilesBuilt") - built_before;
    assert_eq!(built, 1, "only the edited tile was built again");
    assert_eq!(count(&standard_counters(&base)?, "changeNoticesSent"), 1);
    drop(notices);
    daemon.stop(&[])?;
    Ok(())
}

/// The demo scene has a water layer (its lake): `layer.json` offers the
/// `watermask` extension, and a tile asked for with it carries it after the
/// normals: one byte where the tile is all land, else 256 x 256.
#[test]
fn a_water_layer_offers_the_watermask() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = fixtures::write_demo_scene(dir.path())?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let base = daemon.url();
    let layer = get(&format!("{base}/tiles/terrain/layer.json"))?.json()?;
    assert_eq!(layer["extensions"], serde_json::json!(["octvertexnormals", "watermask"]));
    let version = layer["version"].as_str().unwrap();
    let z = layer["maxzoom"].as_u64().unwrap();
    let r = &layer["available"][z as usize][0];
    let at = (z, r["startX"].as_u64().unwrap(), r["startY"].as_u64().unwrap());
    let ask = |extensions: &str| -> anyhow::Result<Vec<u8>> {
        let accept = format!("application/vnd.quantized-mesh;extensions={extensions}");
        let reply = request_with("GET", &tile_url(&base, at, version), None, &[("accept", &accept)])?;
        anyhow::ensure!(reply.status == 200, "{}", String::from_utf8_lossy(&reply.body));
        Ok(reply.body)
    };
    let (normals, both) = (ask("octvertexnormals")?, ask("octvertexnormals-watermask")?);
    assert_eq!(&both[..normals.len()], &normals[..], "the same tile, then the mask");
    let mask = &both[normals.len()..];
    assert_eq!(mask[0], 2, "the watermask extension's id");
    let length = u32::from_le_bytes(mask[1..5].try_into()?) as usize;
    assert!(length == 1 || length == 256 * 256, "{length}");
    assert_eq!(mask.len(), 5 + length);
    daemon.stop(&[])?;
    Ok(())
}

/// A page from another site reads the tiles only when reliefd allows its
/// origin; then its answers say so (CORS), and a page that sends its token
/// in a header is granted the preflight, for the tiles only.
#[test]
fn pages_of_allowed_origins_read_the_tiles() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = relief_tests::scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &["--allow-origin", "http://maps.example.test"])?;
    let base = daemon.url();
    let url = format!("{base}/tiles/terrain/layer.json");
    let allowed = [("origin", "http://maps.example.test")];
    let reply = request_with("GET", &url, None, &allowed)?;
    assert_eq!(reply.status, 200);
    assert_eq!(reply.header("access-control-allow-origin"), Some("http://maps.example.test"));
    assert!(reply.header("access-control-expose-headers").is_some_and(|h| h.contains("etag")));
    let preflight = [("origin", "http://maps.example.test"), ("access-control-request-method", "GET")];
    let reply = request_with("OPTIONS", &url, None, &preflight)?;
    assert_eq!(reply.status, 204);
    assert!(reply.header("access-control-allow-headers").is_some_and(|h| h.contains("authorization")));
    // No preflight for the routes that steer, nor for other sites.
    let reply = request_with("OPTIONS", &format!("{base}/api/camera"), None, &preflight)?;
    assert_ne!(reply.status, 204);
    let other = request_with("GET", &url, None, &[("origin", "http://evil.example.test")])?;
    assert_eq!(other.status, 403);
    assert!(other.header("access-control-allow-origin").is_none());
    daemon.stop(&[])?;
    Ok(())
}

/// A group's tileset builds its GLBs once: asked again, and its content
/// asked for, nothing is built again (each GLB is kept by what it is made
/// of, known before it is built).
#[test]
fn a_tileset_group_builds_its_content_once() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = fixtures::write_demo_scene(dir.path())?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let base = format!("{}/tiles/3d", daemon.url());
    let tileset = get(&format!("{base}/tileset.json"))?.json()?;
    assert_eq!(count(&standard_counters(&daemon.url())?, "glbTilesBuilt"), 0, "groups are built when opened");
    let group = tileset["root"]["children"]
        .as_array()
        .and_then(|c| c.iter().find(|g| g["content"]["uri"].as_str().is_some_and(|u| u.starts_with("buildings/"))))
        .map(|g| g["content"]["uri"].as_str().unwrap_or_default().to_owned())
        .expect("a group of buildings");
    let inner = get(&format!("{base}/{group}"))?.json()?;
    let built = count(&standard_counters(&daemon.url())?, "glbTilesBuilt");
    let leaves = inner["root"]["children"].as_array().map_or(0, Vec::len) as u64;
    assert!(built >= leaves && leaves > 0, "{built} built for {leaves} leaves");
    assert_eq!(get(&format!("{base}/{group}"))?.json()?, inner);
    let leaf =
        inner["root"]["children"][0]["content"]["uri"].as_str().unwrap_or_default().trim_start_matches("../../../");
    assert_eq!(get(&format!("{base}/{leaf}"))?.status, 200);
    assert_eq!(count(&standard_counters(&daemon.url())?, "glbTilesBuilt"), built, "nothing built again");
    daemon.stop(&[])?;
    Ok(())
}
