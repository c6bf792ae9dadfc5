//! Bad input: every kind gets a clear error naming the file, the source id
//! and the field, and a running daemon keeps serving its last good state.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::Path;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_tests::daemon::{Reliefd, check};
use relief_tests::edit::wait_for_status;
use relief_tests::fixtures;

fn hill(dir: &Path) -> std::path::PathBuf {
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap()
}

/// `reliefd check` and `reliefd serve` both refuse the manifest, exit 2,
/// and say every one of `expected`.
fn assert_rejected(manifest: &Path, expected: &[&str]) {
    let (code, stderr) = check(manifest).unwrap();
    assert_eq!(code, 2, "reliefd check should fail: {stderr}");
    for text in expected {
        assert!(stderr.contains(text), "error should mention {text:?}:\n{stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    let err = Reliefd::start(manifest, &[]).err().expect("reliefd serve refuses a bad scene");
    assert!(err.to_string().contains(expected[0]), "{err:#}");
}

const HEAD: &str = "[scene]\nname = \"bad\"\n\n";

/// A scene of one `gdal` source "dem" reading `file`, with `extra` lines.
fn one_dem(dir: &Path, file: &str, extra: &str) -> std::path::PathBuf {
    fixtures::write_manifest(
        dir,
        &format!("{HEAD}[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"{file}\"\n{extra}"),
    )
    .unwrap()
}

#[test]
fn a_cycle_is_rejected_naming_the_sources() {
    let dir = tempfile::tempdir().unwrap();
    hill(dir.path());
    let m = fixtures::write_manifest(
        dir.path(),
        &format!("{HEAD}[[source]]\nid = \"a\"\nkind = \"hillshade\"\ninputs = [\"b\"]\n\n[[source]]\nid = \"b\"\nkind = \"hillshade\"\ninputs = [\"a\"]\n"),
    )
    .unwrap();
    assert_rejected(&m, &["cycle a -> b -> a", "source 'a'", "field 'inputs'", "scene.toml"]);
}

#[test]
fn an_unknown_kind_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let m = fixtures::write_manifest(
        dir.path(),
        &format!("{HEAD}[[source]]\nid = \"dem\"\nkind = \"geotiff\"\npath = \"x.tif\"\n"),
    )
    .unwrap();
    assert_rejected(
        &m,
        &[
            "unknown kind 'geotiff'",
            "source 'dem'",
            "field 'kind'",
            "known: gdal, shapefile, kml, ogr, rasterize, overlay, hillshade",
            "scene.toml",
        ],
    );
}

#[test]
fn a_missing_input_and_a_type_mismatch_are_rejected() {
    let dir = tempfile::tempdir().unwrap();
    hill(dir.path());
    let m = fixtures::write_manifest(
        dir.path(),
        &format!("{HEAD}[[source]]\nid = \"shade\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\n"),
    )
    .unwrap();
    assert_rejected(&m, &["no source has id 'dem'", "source 'shade'", "field 'inputs'"]);
    let m = fixtures::write_manifest(
        dir.path(),
        &format!(
            "{HEAD}[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n[[source]]\nid = \"s1\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\n\n\
             [[source]]\nid = \"s2\"\nkind = \"hillshade\"\ninputs = [\"s1\"]\n"
        ),
    )
    .unwrap();
    assert_rejected(&m, &["'s1' gives color tiles, kind 'hillshade' needs height", "source 's2'", "field 'inputs[0]'"]);
}

#[test]
fn a_missing_file_is_rejected_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let m = one_dem(dir.path(), "nowhere.tif", "");
    let file = dir.path().join("nowhere.tif");
    assert_rejected(&m, &["source 'dem'", "field 'path'", "No such file", file.to_str().unwrap()]);
}

#[test]
fn a_corrupt_raster_is_rejected_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("garbage.tif");
    std::fs::write(&file, b"II*\0this is not really a tiff at all, just bytes").unwrap();
    let m = one_dem(dir.path(), "garbage.tif", "");
    assert_rejected(&m, &["source 'dem'", "field 'path'", "cannot open raster", file.to_str().unwrap()]);
}

#[test]
fn a_truncated_raster_is_rejected_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = hill(dir.path());
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() / 2]).unwrap();
    let m = one_dem(dir.path(), "hill.tif", "");
    assert_rejected(&m, &["source 'dem'", "field 'path'", "cannot read raster data", file.to_str().unwrap()]);
}

#[test]
fn a_glob_that_matches_nothing_is_rejected_and_one_that_matches_loads() {
    let dir = tempfile::tempdir().unwrap();
    hill(dir.path());
    let m = one_dem(dir.path(), "tiles/*.tif", "");
    assert_rejected(
        &m,
        &["source 'dem'", "field 'path'", "'tiles/*.tif' matches no file", dir.path().to_str().unwrap()],
    );
    let m = fixtures::write_manifest(
        dir.path(),
        &format!("{HEAD}[[source]]\nid = \"dem\"\nkind = \"gdal\"\npaths = [\"*.tif\", \"[\"]\n"),
    )
    .unwrap();
    assert_rejected(&m, &["source 'dem'", "field 'paths'", "'[' is not a valid pattern"]);
    let m = fixtures::write_manifest(
        dir.path(),
        &format!("{HEAD}[[source]]\nid = \"dem\"\nkind = \"gdal\"\npaths = [\"h?ll*.tif\"]\n"),
    )
    .unwrap();
    let (code, out) = check(&m).unwrap();
    assert_eq!(code, 0, "a pattern matching hill.tif loads: {out}");
}

#[test]
fn a_raster_whose_overviews_disagree_with_its_base_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let file = hill(dir.path());
    // Overviews of the hill, then the base rewritten as a flat plain.
    {
        let mut ds = gdal::Dataset::open_ex(
            &file,
            gdal::DatasetOptions { open_flags: gdal::GdalOpenFlags::GDAL_OF_UPDATE, ..Default::default() },
        )
        .unwrap();
        ds.build_overviews("AVERAGE", &[2, 4], &[]).unwrap();
        let mut band = ds.rasterband(1).unwrap();
        let flat = vec![-100.0f32; 400 * 400];
        band.write((0, 0), (400, 400), &mut gdal::raster::Buffer::new((400, 400), flat)).unwrap();
    }
    let m = one_dem(dir.path(), "hill.tif", "");
    assert_rejected(&m, &["source 'dem'", "overviews disagree with its base", file.to_str().unwrap()]);
}

#[test]
fn an_unknown_crs_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    hill(dir.path());
    let m = one_dem(dir.path(), "hill.tif", "crs = \"EPSG:999999\"\n");
    assert_rejected(&m, &["source 'dem'", "field 'crs'", "unknown or unusable CRS 'EPSG:999999'"]);
    let m = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"bad\"\ngrid = { crs = \"EPSG:999999\" }\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n",
    )
    .unwrap();
    assert_rejected(&m, &["field 'scene.grid.crs'", "EPSG:999999", "scene.toml"]);
}

#[test]
fn a_raster_without_georeferencing_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("plain.tif");
    let driver = gdal::DriverManager::get_driver_by_name("GTiff").unwrap();
    driver.create_with_band_type::<f32, _>(&file, 8, 8, 1).unwrap();
    let m = one_dem(dir.path(), "plain.tif", "");
    assert_rejected(&m, &["source 'dem'", "field 'path'", "no georeferencing", file.to_str().unwrap()]);
}

#[test]
fn keep_going_serves_what_loaded_and_shows_what_failed() {
    let dir = tempfile::tempdir().unwrap();
    hill(dir.path());
    let m = one_dem(dir.path(), "hill.tif", "\n[[source]]\nid = \"gone\"\nkind = \"gdal\"\npath = \"gone.tif\"\n");
    let daemon = Reliefd::start(&m, &["--keep-going"]).unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let channel = daemon.channel().await.unwrap();
        let state =
            SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
        let gone = state.sources.iter().find(|s| s.id == "gone").unwrap();
        assert_eq!(gone.status, pb::SourceStatus::Failed as i32);
        assert!(gone.error.contains("gone.tif"), "{}", gone.error);
        let status = TileServiceClient::new(channel)
            .get_tile(pb::GetTileRequest {
                source_id: "gone".into(),
                key: Some(pb::TileKey { level: 0, x: 0, y: 0 }),
                quality: None,
            })
            .await
            .unwrap_err();
        assert_eq!(status.code(), tonic::Code::FailedPrecondition);
        assert!(status.message().contains("gone.tif"), "{}", status.message());
    });
    daemon.stop(&["gone.tif"]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_file_that_turns_bad_keeps_the_last_good_tiles_and_shows_the_error() {
    let dir = tempfile::tempdir().unwrap();
    let file = hill(dir.path());
    let good = std::fs::read(&file).unwrap();
    let m = one_dem(dir.path(), "hill.tif", "\n[layers]\nheight = \"dem\"");
    let mut daemon = Reliefd::start(&m, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let (mut scene, mut tiles) = (SceneServiceClient::new(channel.clone()), TileServiceClient::new(channel));
    let key = Some(pb::TileKey { level: 10, x: 1082, y: 254 });
    let get = || pb::GetTileRequest { source_id: "dem".into(), key, quality: None };
    let before = tiles.get_tile(get()).await.unwrap().into_inner();

    for (what, bytes) in [("garbage", b"not a raster".to_vec()), ("truncated", good[..good.len() / 3].to_vec())] {
        std::fs::write(&file, &bytes).unwrap();
        let state = wait_for_status(&mut scene, "dem", pb::SourceStatus::Error).await.unwrap();
        let dem = state.sources.iter().find(|s| s.id == "dem").unwrap();
        assert!(
            dem.error.contains("source 'dem'") && dem.error.contains(file.to_str().unwrap()),
            "{what}: {}",
            dem.error
        );
        // The last good tiles are still served, byte for byte.
        let during = tiles.get_tile(get()).await.unwrap().into_inner();
        assert_eq!(during.content_hash, before.content_hash, "{what}");
        let e = tiles
            .sample_elevation(pb::SampleElevationRequest {
                points: vec![pb::GeodeticPoint { lon_deg: 10.25, lat_deg: 45.25 }],
                source_id: String::new(),
            })
            .await
            .unwrap()
            .into_inner();
        assert!((e.samples[0].height_m.unwrap() - 2000.0).abs() < 0.1);
        assert!(daemon.is_running());
    }

    // Deleted, then restored with new heights: the error clears and the new data shows.
    std::fs::remove_file(&file).unwrap();
    wait_for_status(&mut scene, "dem", pb::SourceStatus::Error).await.unwrap();
    fixtures::write_dem(&file, &fixtures::hill_spec(), |lon, lat| fixtures::hill(lon, lat) + 10.0).unwrap();
    let state = wait_for_status(&mut scene, "dem", pb::SourceStatus::Ready).await.unwrap();
    assert!(state.generation > 1);
    let after = tiles.get_tile(get()).await.unwrap().into_inner();
    assert_ne!(after.content_hash, before.content_hash);
    assert_eq!(after.generation, state.generation);
    let e = tiles
        .sample_elevation(pb::SampleElevationRequest {
            points: vec![pb::GeodeticPoint { lon_deg: 10.25, lat_deg: 45.25 }],
            source_id: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    assert!((e.samples[0].height_m.unwrap() - 2010.0).abs() < 0.1);
    daemon.stop(&["keeping the last good version"]).unwrap();
}
