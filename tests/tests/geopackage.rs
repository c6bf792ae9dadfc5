//! GeoPackage against a real reliefd: two sources on two layers of one
//! `.gpkg` (an edit to one layer's features changes only its source); a
//! raster GeoPackage (tiled gridded coverage) served by the `gdal` kind
//! with the heights it was written with; and bad input (a truncated file,
//! a locked database, a layer gone, a GeoJSON that is not JSON) named with
//! file, source and layer while the last good state is served.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use gdal::vector::LayerAccess;
use gdal::{Dataset, DatasetOptions, DriverManager, GdalOpenFlags};
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::edit::{self, height_at, wait_for, wait_for_status};
use relief_tests::{fixtures, scenes};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edit_to_one_layer_changes_only_the_sources_of_that_layer() {
    let dir = tempfile::tempdir().unwrap();
    let (manifest, gpkg) = scenes::town(dir.path(), "").unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let before = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let details = &before.sources.iter().find(|s| s.id == "roads").unwrap().details;
    assert_eq!(details["features"], "3", "{details:?}");
    assert_eq!(details["driver"], "GPKG");

    // A road renamed through GDAL in update mode, as a script would.
    {
        let options = DatasetOptions {
            open_flags: GdalOpenFlags::GDAL_OF_UPDATE | GdalOpenFlags::GDAL_OF_VECTOR,
            ..DatasetOptions::default()
        };
        let ds = Dataset::open_ex(&gpkg, options).unwrap();
        let layer = ds.layer_by_name("roads").unwrap();
        let mut feature = layer.feature(1).unwrap();
        feature.set_field_string(0, "renamed").unwrap();
        layer.set_feature(feature).unwrap();
        ds.close().unwrap();
    }
    let after = wait_for(channel.clone(), before.generation + 1).await.unwrap();
    assert!(edit::version(&after, "roads") > edit::version(&before, "roads"), "the edited layer's source is new");
    assert_eq!(edit::version(&after, "parcels"), edit::version(&before, "parcels"), "the other layer's is not");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_raster_geopackage_is_served_by_the_gdal_kind() {
    let dir = tempfile::tempdir().unwrap();
    let tif = fixtures::write_dem(&dir.path().join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    let gpkg = dir.path().join("hill.gpkg");
    {
        // Float32 heights as a tiled gridded coverage (TIFF tiles), as
        // `gdal_translate -of GPKG` writes them.
        let source = Dataset::open(&tif).unwrap();
        let driver = DriverManager::get_driver_by_name("GPKG").unwrap();
        let mut options = gdal::cpl::CslStringList::new();
        options.set_name_value("TILE_FORMAT", "TIFF").unwrap();
        source.create_copy(&driver, &gpkg, &options).unwrap();
    }
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"hill\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.gpkg\"\n\n[layers]\nheight = \"dem\"\n",
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    for (lon, lat) in [(10.25, 45.25), (10.1, 45.4), (10.37, 45.12)] {
        let h = height_at(channel.clone(), lon, lat).await.unwrap().unwrap();
        // The hill's samples are 0.00125 degrees apart: bilinear between
        // them is within a metre of the formula here.
        assert!((h - fixtures::hill(lon, lat)).abs() < 1.0, "({lon}, {lat}): {h} vs {}", fixtures::hill(lon, lat));
    }
    daemon.stop(&[]).unwrap();
}

/// The number of parcels reliefd serves now, and the `parcels` source's
/// error (empty when none).
async fn parcels_now(channel: &tonic::transport::Channel) -> (usize, String) {
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let tile = relief_tests::tiles::get(channel.clone(), "parcels", (0, 1, 0)).await.unwrap();
    let served = relief_tests::tiles::geojson(&tile)["features"].as_array().unwrap().len();
    (served, state.sources.iter().find(|s| s.id == "parcels").unwrap().error.clone())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_geopackages_are_named_with_file_source_and_layer_and_the_last_good_state_stays() {
    let dir = tempfile::tempdir().unwrap();
    let (manifest, gpkg) = scenes::town(dir.path(), "").unwrap();
    // A GeoJSON source beside the GeoPackage's two.
    let survey = dir.path().join("survey.geojson");
    std::fs::write(&survey, relief_tests::vectors::squares(&[(r#"{"name": "s"}"#, 10.3, 45.3, 0.01)])).unwrap();
    let text = std::fs::read_to_string(&manifest).unwrap();
    std::fs::write(
        &manifest,
        text.replace("[layers]", "[[source]]\nid = \"survey\"\nkind = \"ogr\"\npath = \"survey.geojson\"\n\n[layers]"),
    )
    .unwrap();
    let mut daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let mut scene = SceneServiceClient::new(channel.clone());
    assert_eq!(parcels_now(&channel).await, (30, String::new()));
    let named = |error: &str, what: &str, words: &[&str]| {
        for w in [gpkg.to_str().unwrap(), "source 'parcels'", "'parcels'"].iter().chain(words) {
            assert!(error.contains(w), "{what}: '{error}' should say '{w}'");
        }
        assert!(!error.contains("NullPointer") && !error.contains("{ "), "{what}: no Debug output: {error}");
    };

    // Truncated in place: named, the 30 parcels still served; restored, well again.
    let good = std::fs::read(&gpkg).unwrap();
    std::fs::write(&gpkg, &good[..good.len() / 2]).unwrap();
    wait_for_status(&mut scene, "parcels", pb::SourceStatus::Error).await.unwrap();
    let (served, error) = parcels_now(&channel).await;
    named(&error, "truncated", &[]);
    assert_eq!(served, 30, "truncated: the last good parcels");
    std::fs::write(&gpkg, &good).unwrap();
    wait_for_status(&mut scene, "parcels", pb::SourceStatus::Ready).await.unwrap();

    // The layer renamed away (DB Manager, ogrinfo -sql): the layers there are listed.
    let rename = |from: &str, to: &str| {
        let out = std::process::Command::new("ogrinfo")
            .arg(&gpkg)
            .args(["-q", "-sql", &format!("ALTER TABLE {from} RENAME TO {to}")])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    rename("parcels", "lots");
    wait_for_status(&mut scene, "parcels", pb::SourceStatus::Error).await.unwrap();
    let (served, error) = parcels_now(&channel).await;
    named(&error, "renamed", &["no layer 'parcels'", "lots", "roads"]);
    assert_eq!(served, 30, "renamed: the last good parcels");
    rename("lots", "parcels");
    wait_for_status(&mut scene, "parcels", pb::SourceStatus::Ready).await.unwrap();

    // Locked: a script deletes a parcel, commits, and at once holds the
    // database in an exclusive transaction. Shown while it lasts, then the
    // commit is read.
    let script = "import sqlite3, sys\nc = sqlite3.connect(sys.argv[1], isolation_level=None)\n\
                  c.execute('DELETE FROM parcels WHERE fid = 7')\nc.execute('BEGIN EXCLUSIVE')\n\
                  print('locked', flush=True)\nsys.stdin.read()\nc.execute('ROLLBACK')\nc.close()\n";
    let mut lock = std::process::Command::new("python3")
        .args(["-c", script])
        .arg(&gpkg)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(lock.stdout.as_mut().unwrap()), &mut line).unwrap();
    assert_eq!(line.trim(), "locked");
    wait_for_status(&mut scene, "parcels", pb::SourceStatus::Error).await.unwrap();
    let (served, error) = parcels_now(&channel).await;
    named(&error, "locked", &["locked by another program"]);
    assert_eq!(served, 30, "locked: the last good parcels");
    drop(lock.stdin.take());
    assert!(lock.wait().unwrap().success());
    wait_for_status(&mut scene, "parcels", pb::SourceStatus::Ready).await.unwrap();
    assert_eq!(parcels_now(&channel).await, (29, String::new()), "the delete, once the lock is gone");

    // A GeoJSON that is not JSON.
    std::fs::write(&survey, "{\"type\": \"FeatureCollection\", \"features\": [").unwrap();
    let state = wait_for_status(&mut scene, "survey", pb::SourceStatus::Error).await.unwrap();
    let error = &state.sources.iter().find(|s| s.id == "survey").unwrap().error;
    for w in ["source 'survey'", survey.to_str().unwrap(), "not a vector dataset GDAL can read"] {
        assert!(error.contains(w), "not JSON: '{error}' should say '{w}'");
    }
    let tile = relief_tests::tiles::get(channel.clone(), "survey", (0, 1, 0)).await.unwrap();
    assert_eq!(relief_tests::tiles::geojson(&tile)["features"].as_array().unwrap().len(), 1, "the last good survey");
    assert!(daemon.is_running());
    daemon.stop(&["keeping the last good version"]).unwrap();
}
