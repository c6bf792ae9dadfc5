//! Sources on object storage, on real servers: moto (an S3-compatible
//! server) and npm's http-server (a plain HTTP host with ranges). A COG
//! and a VRT of objects give the tiles the same files give on disk; an
//! overwrite is picked up by polling and by an S3 event notice, reading the
//! changed block only; a missing object, a refused key, a non-raster and a
//! store that is down each show an error naming the URL while the last
//! good tiles serve on, and no secret reaches the state, the log, the
//! metrics or the errors.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use gdal::{Dataset, DriverManager};
use relief_examples as fixtures;
use relief_tests::daemon::Reliefd;
use relief_tests::s3::{ACCESS_KEY_ID, HttpServer, S3Server, SECRET_ACCESS_KEY};
use relief_tests::{edit, http};

/// Tiles (level, x, y) over the hill, coarse to fine.
const TILES: [(u32, u32, u32); 4] = [(7, 135, 31), (9, 541, 127), (10, 1082, 254), (10, 1083, 254)];
/// The hill's peak, and a place on its slope inside one 128-pixel block.
const PEAK: (f64, f64) = (10.25, 45.25);
const SLOPE: (f64, f64) = (10.3, 45.3);

/// The hill as a tiled, DEFLATE-compressed GeoTIFF with 128-pixel blocks
/// (16 blocks): a COG's layout.
fn tiled(dir: &Path, name: &str, window: Option<(usize, usize, usize, usize)>) -> anyhow::Result<PathBuf> {
    let plain = fixtures::write_dem(&dir.join(format!("plain-{name}")), &fixtures::hill_spec(), fixtures::hill)?;
    let source = match window {
        None => Dataset::open(&plain)?,
        Some((x, y, w, h)) => {
            let cut = dir.join(format!("cut-{name}"));
            let status = std::process::Command::new("gdal_translate")
                .args(["-q", "-srcwin", &x.to_string(), &y.to_string(), &w.to_string(), &h.to_string()])
                .arg(&plain)
                .arg(&cut)
                .status()?;
            anyhow::ensure!(status.success(), "gdal_translate failed");
            Dataset::open(&cut)?
        }
    };
    let path = dir.join(name);
    let options = gdal::raster::RasterCreationOptions::from_iter([
        "TILED=YES",
        "BLOCKXSIZE=128",
        "BLOCKYSIZE=128",
        "COMPRESS=DEFLATE",
    ]);
    source.create_copy(&DriverManager::get_driver_by_name("GTiff")?, &path, &options)?;
    Ok(path)
}

/// The S3 server with the hill's tiled COG at `s3://{bucket}/hill.tif`,
/// the folder holding its file, and the file.
fn hill_object(bucket: &str) -> anyhow::Result<(S3Server, tempfile::TempDir, PathBuf)> {
    let s3 = S3Server::start()?;
    s3.create_bucket(bucket)?;
    let dir = tempfile::tempdir()?;
    let cog = tiled(dir.path(), "hill.tif", None)?;
    s3.put_file(bucket, "hill.tif", &cog)?;
    Ok((s3, dir, cog))
}

fn manifest(dir: &Path, name: &str, path: &str, extra: &str) -> anyhow::Result<PathBuf> {
    let text = format!(
        "[scene]\nname = \"objects\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"{path}\"\n\n[layers]\nheight \
         = \"dem\"\n\n[cache]\ndisk_mb = 0\n{extra}\n"
    );
    let file = dir.join(name);
    std::fs::write(&file, text)?;
    Ok(file)
}

fn state(daemon: &Reliefd) -> anyhow::Result<serde_json::Value> {
    http::get(&format!("{}/api/state", daemon.url()))?.json()
}

fn counter(state: &serde_json::Value, name: &str) -> u64 {
    state["counters"][name].as_str().and_then(|s| s.parse().ok()).unwrap_or(0)
}

fn generation(state: &serde_json::Value) -> u64 {
    state["generation"].as_str().and_then(|s| s.parse().ok()).unwrap_or(0)
}

fn source_error(state: &serde_json::Value) -> String {
    state["sources"][0]["error"].as_str().unwrap_or_default().to_owned()
}

async fn hashes(daemon: &Reliefd) -> anyhow::Result<Vec<u64>> {
    let channel = daemon.channel().await?;
    let mut out = Vec::new();
    for key in TILES {
        out.push(edit::tile_hash(channel.clone(), "dem", key).await?);
    }
    Ok(out)
}

async fn height(daemon: &Reliefd, (lon, lat): (f64, f64)) -> anyhow::Result<f64> {
    edit::height_at(daemon.channel().await?, lon, lat).await?.ok_or_else(|| anyhow::anyhow!("no height at {lon} {lat}"))
}

/// Waits up to `deadline` for a state that `ok` accepts; the last state.
fn until(
    daemon: &Reliefd,
    deadline: Duration,
    ok: impl Fn(&serde_json::Value) -> bool,
) -> anyhow::Result<serde_json::Value> {
    let start = Instant::now();
    loop {
        let s = state(daemon)?;
        if ok(&s) || start.elapsed() > deadline {
            return Ok(s);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The pixel window of the hill's block under `SLOPE` raised by 100 m.
fn raise_slope_block(path: &Path) -> anyhow::Result<()> {
    let spec = fixtures::hill_spec();
    let x = ((SLOPE.0 - spec.origin_x) / spec.pixel) as usize;
    let y = ((spec.origin_y - SLOPE.1) / spec.pixel) as usize;
    edit::rewrite_window(path, x - 4, y - 4, 8, 8, |_, _, v| v + 100.0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cog_and_a_vrt_of_objects_give_the_same_tiles_as_the_files_on_disk() -> anyhow::Result<()> {
    let s3 = S3Server::start()?;
    s3.create_bucket("same")?;
    let dir = tempfile::tempdir()?;
    let cog = tiled(dir.path(), "hill.tif", None)?;
    // A mosaic of the hill's two halves, its members beside it.
    tiled(dir.path(), "west.tif", Some((0, 0, 200, 400)))?;
    tiled(dir.path(), "east.tif", Some((200, 0, 200, 400)))?;
    let status = std::process::Command::new("gdalbuildvrt")
        .current_dir(dir.path())
        .args(["-q", "mosaic.vrt", "west.tif", "east.tif"])
        .status()?;
    anyhow::ensure!(status.success(), "gdalbuildvrt failed");
    for name in ["hill.tif", "west.tif", "east.tif", "mosaic.vrt"] {
        s3.put_file("same", name, &dir.path().join(name))?;
    }
    assert!(std::fs::read_to_string(dir.path().join("mosaic.vrt"))?.contains("relativeToVRT=\"1\""));
    assert!(cog.exists());

    for (local, object) in [("hill.tif", "s3://same/hill.tif"), ("mosaic.vrt", "s3://same/mosaic.vrt")] {
        let on_disk = Reliefd::start(&manifest(dir.path(), "local.toml", local, "")?, &[])?;
        let remote = Reliefd::start_with_env(&manifest(dir.path(), "remote.toml", object, "")?, &[], &s3.env())?;
        let (a, b) = (hashes(&on_disk).await?, hashes(&remote).await?);
        assert_eq!(a, b, "{object} gives the tiles {local} gives");
        assert_eq!(height(&on_disk, PEAK).await?, height(&remote, PEAK).await?);
        let s = state(&remote)?;
        assert_eq!(s["sources"][0]["status"], "SOURCE_STATUS_READY", "{s}");
        assert!(counter(&s, "objectVersionChecks") > 0, "{s}");
        remote.stop(&[])?;
        on_disk.stop(&[])?;
    }

    // A local VRT naming its members as object URLs, in a bucket its
    // manifest lists under [scene] roots: the same tiles; a member
    // overwritten is read again (members are polled as objects are).
    let vrt = std::fs::read_to_string(dir.path().join("mosaic.vrt"))?
        .replace("relativeToVRT=\"1\">west.tif", "relativeToVRT=\"0\">s3://same/west.tif")
        .replace("relativeToVRT=\"1\">east.tif", "relativeToVRT=\"0\">s3://same/east.tif");
    assert!(vrt.contains("s3://same/west.tif") && vrt.contains("s3://same/east.tif"), "{vrt}");
    std::fs::write(dir.path().join("urls.vrt"), vrt)?;
    let text = std::fs::read_to_string(manifest(dir.path(), "urls.toml", "urls.vrt", "[watch]\npoll_s = 0.25\n")?)?
        .replace("[scene]\n", "[scene]\nroots = [\"s3://same\"]\n");
    std::fs::write(dir.path().join("urls.toml"), text)?;
    let on_disk = Reliefd::start(&manifest(dir.path(), "local.toml", "mosaic.vrt", "")?, &[])?;
    let urls = Reliefd::start_with_env(&dir.path().join("urls.toml"), &[], &s3.env())?;
    assert_eq!(hashes(&on_disk).await?, hashes(&urls).await?, "a VRT of object URLs gives the mosaic's tiles");
    let s0 = state(&urls)?;
    assert_eq!(s0["sources"][0]["status"], "SOURCE_STATUS_READY", "{s0}");
    let before = height(&urls, SLOPE).await?;
    let east = dir.path().join("east.tif");
    let spec = fixtures::hill_spec();
    let x = ((SLOPE.0 - spec.origin_x) / spec.pixel) as usize - 200;
    let y = ((spec.origin_y - SLOPE.1) / spec.pixel) as usize;
    edit::rewrite_window(&east, x - 4, y - 4, 8, 8, |_, _, v| v + 100.0)?;
    s3.put_file("same", "east.tif", &east)?;
    until(&urls, Duration::from_secs(10), |s| generation(s) > generation(&s0))?;
    assert!((height(&urls, SLOPE).await? - before - 100.0).abs() < 1e-3, "the member's overwrite was read");
    urls.stop(&[])?;
    on_disk.stop(&[])?;

    // Without the root, the VRT may not reach into that bucket.
    let (code, said) = relief_tests::daemon::check(&manifest(dir.path(), "unrooted.toml", "urls.vrt", "")?)?;
    assert_ne!(code, 0, "{said}");
    assert!(said.contains("s3://same/west.tif") && said.contains("outside the scene's buckets"), "{said}");
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_overwrite_is_read_by_polling_and_by_a_notice_one_block_at_a_time() -> anyhow::Result<()> {
    let (s3, dir, cog) = hill_object("dem")?;
    let object_len = std::fs::metadata(&cog)?.len();
    // Polling every second.
    let polled = Reliefd::start_with_env(
        &manifest(dir.path(), "polled.toml", "s3://dem/hill.tif", "[watch]\npoll_s = 1\n")?,
        &[],
        &s3.env(),
    )?;
    let before = height(&polled, SLOPE).await?;
    let peak = height(&polled, PEAK).await?;
    let events = edit::Events::follow(polled.channel().await?).await?;
    let s0 = state(&polled)?;

    raise_slope_block(&cog)?;
    s3.put_file("dem", "hill.tif", &cog)?;
    // Picked up within poll_s + 1 s of the overwrite.
    let s1 = until(&polled, Duration::from_secs(2), |s| generation(s) > generation(&s0))?;
    assert_eq!(generation(&s1), generation(&s0) + 1, "the overwrite was picked up within poll_s + 1 s: {s1}");
    assert!((height(&polled, SLOPE).await? - before - 100.0).abs() < 1e-3);
    assert_eq!(height(&polled, PEAK).await?, peak, "the other blocks are as they were");
    // The bytes read: the block tables, the changed block and, for the
    // level halved from the base, the other three of its 2 x 2 group (a
    // 128 x 128 float block is 64 KiB before compression); not the object.
    let fetched = counter(&s1, "objectBytesRead") - counter(&s0, "objectBytesRead");
    assert!(
        fetched > 0 && fetched <= 4 * 65_536 + 4096,
        "{fetched} bytes read for a one-block change of a {object_len}-byte object"
    );
    assert!(fetched * 2 < object_len, "{fetched} of {object_len} bytes");
    // The dirt is the changed block: inside the block around SLOPE.
    let change = events.generation(generation(&s1)).await?;
    let spec = fixtures::hill_spec();
    let block = 128.0 * spec.pixel;
    for region in &change.dirty {
        for e in &region.extents {
            let margin = 2.0 * spec.pixel;
            let bx = ((SLOPE.0 - spec.origin_x) / block).floor() * block + spec.origin_x;
            let by = spec.origin_y - ((spec.origin_y - SLOPE.1) / block).floor() * block;
            assert!(e.min_x >= bx - margin && e.max_x <= bx + block + margin, "dirt {e:?} outside the block");
            assert!(e.max_y <= by + margin && e.min_y >= by - block - margin, "dirt {e:?} outside the block");
            assert!(e.min_x <= SLOPE.0 && e.max_x >= SLOPE.0 && e.min_y <= SLOPE.1 && e.max_y >= SLOPE.1);
        }
    }
    assert!(!change.dirty.is_empty());
    polled.stop(&[])?;

    // No polling: an S3 event notice reads the object at once.
    let noticed = Reliefd::start_with_env(
        &manifest(dir.path(), "noticed.toml", "s3://dem/hill.tif", "[watch]\npoll_s = 0\n")?,
        &[],
        &s3.env(),
    )?;
    let s0 = state(&noticed)?;
    let before = height(&noticed, SLOPE).await?;
    raise_slope_block(&cog)?;
    s3.put_file("dem", "hill.tif", &cog)?;
    let event = serde_json::json!({"Records": [{
        "eventName": "ObjectCreated:Put",
        "s3": {"bucket": {"name": "dem"}, "object": {"key": "hill.tif"}}
    }]});
    let started = Instant::now();
    let reply = http::request("POST", &format!("{}/api/notify", noticed.url()), Some(&event.to_string()))?;
    let took = started.elapsed();
    assert_eq!(reply.status, 200, "{}", String::from_utf8_lossy(&reply.body));
    // The answer is the state with the object read: no wait for a poll.
    assert_eq!(generation(&reply.json()?), generation(&s0) + 1, "{took:?}");
    eprintln!("notice to new generation: {took:?}");
    assert!((height(&noticed, SLOPE).await? - before - 100.0).abs() < 1e-3);
    // A notice about an object the scene does not read changes nothing;
    // one that is not an S3 event is refused, naming what is wrong.
    let other = serde_json::json!({"Records": [{"s3": {"bucket": {"name": "dem"}, "object": {"key": "other.tif"}}}]});
    let reply = http::request("POST", &format!("{}/api/notify", noticed.url()), Some(&other.to_string()))?;
    assert_eq!(generation(&reply.json()?), generation(&s0) + 1);
    let reply = http::request("POST", &format!("{}/api/notify", noticed.url()), Some("{\"hello\": 1}"))?;
    assert_eq!(reply.status, 400);
    assert!(String::from_utf8_lossy(&reply.body).contains("Records"));
    noticed.stop(&[])?;
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_objects_keep_the_last_good_tiles_and_no_secret_leaks() -> anyhow::Result<()> {
    let (s3, dir, cog) = hill_object("bad")?;
    let daemon = Reliefd::start_with_env(
        &manifest(dir.path(), "scene.toml", "s3://bad/hill.tif", "[watch]\npoll_s = 0.25\n")?,
        &["--metrics-listen", "127.0.0.1:0"],
        &s3.env(),
    )?;
    let metrics = daemon.printed("metrics: ").ok_or_else(|| anyhow::anyhow!("no metrics line"))?;
    let good = hashes(&daemon).await?;
    let peak = height(&daemon, PEAK).await?;
    let mut errors = Vec::new();
    let mut check = |why: &str, expect: &str, daemon: &Reliefd| -> anyhow::Result<()> {
        let s = until(daemon, Duration::from_secs(10), |s| source_error(s).contains(expect))?;
        let error = source_error(&s);
        assert!(error.contains("s3://bad/hill.tif") && error.contains(expect), "{why}: {error}");
        errors.push(error);
        Ok(())
    };

    // Missing.
    s3.delete("bad", "hill.tif")?;
    check("a missing object", "not found", &daemon)?;
    assert_eq!(hashes(&daemon).await?, good, "the last good tiles serve on");
    assert_eq!(height(&daemon, PEAK).await?, peak);
    // Replaced by a non-raster.
    s3.put("bad", "hill.tif", &b"<html>not a raster</html>".repeat(50))?;
    check("a non-raster", "cannot open raster", &daemon)?;
    assert_eq!(hashes(&daemon).await?, good);
    // Back again.
    s3.put_file("bad", "hill.tif", &cog)?;
    until(&daemon, Duration::from_secs(10), |s| source_error(s).is_empty())?;
    assert_eq!(hashes(&daemon).await?, good);
    // The key refused.
    s3.refuse_unknown_keys()?;
    check("a refused key", "access denied", &daemon)?;
    assert_eq!(hashes(&daemon).await?, good);
    s3.accept_any_keys()?;
    until(&daemon, Duration::from_secs(10), |s| source_error(s).is_empty())?;
    // The store down.
    drop(s3);
    check("a store that is down", "the store is down", &daemon)?;
    assert_eq!(hashes(&daemon).await?, good);
    assert_eq!(height(&daemon, PEAK).await?, peak);

    let shown = [
        state(&daemon)?.to_string(),
        String::from_utf8_lossy(&http::get(&metrics)?.body).into_owned(),
        errors.join("\n"),
    ];
    let log = daemon.stop(&["cannot read raster", "cannot open raster", "failed"])?.join("\n");
    for (what, text) in ["state", "metrics", "errors"].iter().zip(&shown).chain([(&"log", &log)]) {
        assert!(!text.contains(SECRET_ACCESS_KEY), "the secret key in the {what}");
        assert!(!text.contains(ACCESS_KEY_ID), "the access key id in the {what}");
    }
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cog_on_a_plain_http_host_is_read_by_ranges_and_its_etag_change_reloads_it() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let served = dir.path().join("www");
    std::fs::create_dir(&served)?;
    let cog = tiled(&served, "hill.tif", None)?;
    let host = HttpServer::start(&served)?;
    let url = host.url("/hill.tif");
    let etag = host.head("/hill.tif")?.map(|h| h.etag).unwrap_or_default();
    let local = Reliefd::start(&manifest(dir.path(), "local.toml", &cog.to_string_lossy(), "")?, &[])?;
    let good = hashes(&local).await?;
    local.stop(&[])?;
    let daemon = Reliefd::start(&manifest(dir.path(), "scene.toml", &url, "[watch]\npoll_s = 0.25\n")?, &[])?;
    assert_eq!(hashes(&daemon).await?, good, "{url} gives the tiles the file gives");
    assert!(host.log().iter().any(|l| l.contains("GET")), "{:?}", host.log());
    let before = height(&daemon, SLOPE).await?;
    let s0 = state(&daemon)?;
    std::thread::sleep(Duration::from_millis(5));
    raise_slope_block(&cog)?;
    assert_ne!(host.head("/hill.tif")?.map(|h| h.etag).unwrap_or_default(), etag, "the ETag changed");
    let s1 = until(&daemon, Duration::from_secs(10), |s| generation(s) > generation(&s0))?;
    assert!(generation(&s1) > generation(&s0), "{s1}");
    assert!((height(&daemon, SLOPE).await? - before - 100.0).abs() < 1e-3);
    daemon.stop(&[])?;
    Ok(())
}

/// Vector data on object storage: a GeoPackage, a FlatGeobuf and a
/// shapefile in a zip, read as the same files on disk are; a GeoPackage
/// overwritten with one parcel more is read again on its notice.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn vector_objects_are_read_and_reloaded() -> anyhow::Result<()> {
    use std::io::Write;
    let s3 = S3Server::start()?;
    s3.create_bucket("vectors")?;
    let dir = tempfile::tempdir()?;
    let parcels = |n: usize| {
        let squares: Vec<(&str, f64, f64, f64)> =
            (0..n).map(|i| ("{\"name\": \"p\"}", 10.2 + 0.01 * i as f64, 45.2, 0.005)).collect();
        relief_tests::vectors::squares(&squares)
    };
    let gpkg = relief_tests::vectors::geopackage(&dir.path().join("town.gpkg"), &[("parcels", &parcels(3))])?;
    let fgb = dir.path().join("parcels.fgb");
    let status =
        std::process::Command::new("ogr2ogr").args(["-q", "-f", "FlatGeobuf"]).arg(&fgb).arg(&gpkg).status()?;
    anyhow::ensure!(status.success(), "ogr2ogr failed");
    let shp_dir = dir.path().join("shp");
    std::fs::create_dir(&shp_dir)?;
    relief_tests::vectors::shapefile(&shp_dir, "lots", &parcels(4))?;
    let zipped = dir.path().join("lots.zip");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&zipped)?);
    for entry in std::fs::read_dir(&shp_dir)? {
        let path = entry?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default().to_owned();
        zip.start_file(name, zip::write::SimpleFileOptions::default())?;
        zip.write_all(&std::fs::read(&path)?)?;
    }
    zip.finish()?;
    for (key, path) in [("town.gpkg", &gpkg), ("parcels.fgb", &fgb), ("lots.zip", &zipped)] {
        s3.put_file("vectors", key, path)?;
    }
    fixtures::write_dem(&dir.path().join("hill.tif"), &fixtures::hill_spec(), fixtures::hill)?;
    let text = "[scene]\nname = \"vectors\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n\
                [[source]]\nid = \"gpkg\"\nkind = \"ogr\"\npath = \"s3://vectors/town.gpkg\"\nlayer = \"parcels\"\n\n\
                [[source]]\nid = \"fgb\"\nkind = \"ogr\"\npath = \"s3://vectors/parcels.fgb\"\n\n\
                [[source]]\nid = \"zipped\"\nkind = \"ogr\"\npath = \"s3://vectors/lots.zip\"\n\n\
                [layers]\nheight = \"dem\"\n\n[cache]\ndisk_mb = 0\n\n[watch]\npoll_s = 0\n";
    let manifest = dir.path().join("scene.toml");
    std::fs::write(&manifest, text)?;
    let daemon = Reliefd::start_with_env(&manifest, &[], &s3.env())?;
    let features = |s: &serde_json::Value, id: &str| -> String {
        let source = s["sources"].as_array().and_then(|a| a.iter().find(|x| x["id"] == id)).cloned();
        let source = source.unwrap_or_default();
        format!("{} {}", source["status"], source["details"]["features"])
    };
    let s = state(&daemon)?;
    assert_eq!(features(&s, "gpkg"), "\"SOURCE_STATUS_READY\" \"3\"", "{s}");
    assert_eq!(features(&s, "fgb"), "\"SOURCE_STATUS_READY\" \"3\"", "{s}");
    assert_eq!(features(&s, "zipped"), "\"SOURCE_STATUS_READY\" \"4\"", "{s}");

    std::fs::remove_file(&gpkg)?;
    relief_tests::vectors::geopackage(&gpkg, &[("parcels", &parcels(4))])?;
    s3.put_file("vectors", "town.gpkg", &gpkg)?;
    let event =
        serde_json::json!({"Records": [{"s3": {"bucket": {"name": "vectors"}, "object": {"key": "town.gpkg"}}}]});
    let reply = http::request("POST", &format!("{}/api/notify", daemon.url()), Some(&event.to_string()))?;
    assert_eq!(features(&reply.json()?, "gpkg"), "\"SOURCE_STATUS_READY\" \"4\"");
    assert_eq!(features(&reply.json()?, "fgb"), "\"SOURCE_STATUS_READY\" \"3\"", "only the named object's source");
    daemon.stop(&[])?;
    Ok(())
}

/// Credentials from a named profile in `~/.aws/credentials` (no key in the
/// environment), and the endpoint from the manifest's `[storage]`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_profile_and_a_storage_section_reach_the_store() -> anyhow::Result<()> {
    let (s3, dir, _) = hill_object("profiled")?;
    let home = dir.path().join("home");
    std::fs::create_dir_all(home.join(".aws"))?;
    std::fs::write(
        home.join(".aws/credentials"),
        format!("[relief-test]\naws_access_key_id = {ACCESS_KEY_ID}\naws_secret_access_key = {SECRET_ACCESS_KEY}\n"),
    )?;
    let env = [
        ("HOME".to_owned(), home.to_string_lossy().into_owned()),
        ("AWS_PROFILE".to_owned(), "relief-test".to_owned()),
    ];
    let storage = format!("[storage]\nendpoint = \"{}\"\nregion = \"us-east-1\"\n", s3.endpoint());
    let daemon =
        Reliefd::start_with_env(&manifest(dir.path(), "scene.toml", "s3://profiled/hill.tif", &storage)?, &[], &env)?;
    let s = state(&daemon)?;
    assert_eq!(s["sources"][0]["status"], "SOURCE_STATUS_READY", "{s}");
    assert!((height(&daemon, PEAK).await? - fixtures::hill(PEAK.0, PEAK.1)).abs() < 1.0);
    let log = daemon.stop(&[])?.join("\n");
    assert!(!log.contains(SECRET_ACCESS_KEY) && !s.to_string().contains(SECRET_ACCESS_KEY));
    Ok(())
}

/// A notice reloads sources: it needs a control token where reliefd has
/// tokens; a read token is refused and nothing is read.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_notice_needs_the_control_scope() -> anyhow::Result<()> {
    use relief_tests::probe::{CONTROL, READ, token_file};
    let (s3, dir, cog) = hill_object("scoped")?;
    let tokens = token_file(dir.path())?;
    let scene = manifest(dir.path(), "scene.toml", "s3://scoped/hill.tif", "[watch]\npoll_s = 0\n")?;
    let daemon = Reliefd::start_with_env(&scene, &["--token-file", &tokens], &s3.env())?;
    raise_slope_block(&cog)?;
    s3.put_file("scoped", "hill.tif", &cog)?;
    let event = serde_json::json!({"Records": [{"s3": {"bucket": {"name": "scoped"}, "object": {"key": "hill.tif"}}}]});
    let notify = |token: &str| {
        let bearer = format!("Bearer {token}");
        let headers = [("authorization", bearer.as_str()), ("content-type", "application/json")];
        http::request_with("POST", &format!("{}/api/notify", daemon.url()), Some(&event.to_string()), &headers)
    };
    let denied = notify(READ)?;
    assert_eq!(denied.status, 403, "{}", String::from_utf8_lossy(&denied.body));
    assert!(String::from_utf8_lossy(&denied.body).contains("control token"));
    let taken = notify(CONTROL)?;
    assert_eq!(taken.status, 200, "{}", String::from_utf8_lossy(&taken.body));
    assert_eq!(generation(&taken.json()?), 2, "the control token's notice read the object");
    daemon.stop(&[])?;
    Ok(())
}

/// A public bucket: with no credentials anywhere (no keys, no profile, no
/// `~/.aws`), requests go unsigned and a public object is read.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_public_object_is_read_without_credentials() -> anyhow::Result<()> {
    let s3 = S3Server::start()?;
    s3.create_bucket("public")?;
    let dir = tempfile::tempdir()?;
    let cog = tiled(dir.path(), "hill.tif", None)?;
    s3.put_public("public", "hill.tif", &cog)?;
    let home = dir.path().join("empty-home");
    std::fs::create_dir(&home)?;
    let env = [
        ("HOME".to_owned(), home.to_string_lossy().into_owned()),
        ("AWS_ENDPOINT_URL".to_owned(), s3.endpoint()),
        ("AWS_REGION".to_owned(), "us-east-1".to_owned()),
    ];
    let daemon = Reliefd::start_with_env(&manifest(dir.path(), "scene.toml", "s3://public/hill.tif", "")?, &[], &env)?;
    let s = state(&daemon)?;
    assert_eq!(s["sources"][0]["status"], "SOURCE_STATUS_READY", "{s}");
    assert!((height(&daemon, PEAK).await? - fixtures::hill(PEAK.0, PEAK.1)).abs() < 1.0);
    daemon.stop(&[])?;
    // The requests were unsigned: a private object is refused to them.
    s3.put_file("public", "private.tif", &cog)?;
    let private = manifest(dir.path(), "private.toml", "s3://public/private.tif", "")?;
    let refused = Reliefd::start_with_env(&private, &["--keep-going"], &env);
    let said = match refused {
        Ok(daemon) => {
            let error = source_error(&state(&daemon)?);
            daemon.stop(&["access denied", "cannot read raster"])?;
            error
        }
        Err(e) => e.to_string(),
    };
    assert!(said.contains("access denied") && said.contains("s3://public/private.tif"), "{said}");
    Ok(())
}
