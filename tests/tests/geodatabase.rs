//! A file geodatabase edited live, as ArcGIS edits one: GDAL's OpenFileGDB
//! driver (Python) writes it, a real reliefd reads it through the `ogr`
//! kind. Update, insert and delete of one feature and a REPACK each reach
//! the scene; an edit to one table refreshes only the sources of that
//! table; an ArcGIS edit lock holds the read back until it goes, and a lock
//! left behind is read after `[watch] write_timeout_ms` with a warning; a
//! table caught mid-rewrite is never published.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::{Path, PathBuf};
use std::time::Duration;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::arcgis::{self, GdbEditor, LayerSpec, square_wkt};
use relief_tests::daemon::Reliefd;
use relief_tests::edit::{self, wait_for};
use relief_tests::{fixtures, tiles};
use serde_json::json;
use tonic::transport::Channel;

/// The level-10 tile that holds every fixture feature.
const TILE: (u32, u32, u32) = (10, 1082, 254);

/// A geodatabase of five parcels and three sites over the hill, and a scene
/// reading each table as a source; `watch` is a `[watch]` table or empty.
fn town(dir: &Path, watch: &str) -> (PathBuf, PathBuf, GdbEditor) {
    let gdb = dir.join("town.gdb");
    let mut editor = GdbEditor::start(&gdb).unwrap();
    let parcels =
        (0..5).map(|k| (square_wkt(10.2 + 0.02 * f64::from(k), 45.2, 0.01), json!({"name": format!("p{k}")})));
    let sites =
        (0..3).map(|k| (format!("POINT ({} 45.3)", 10.2 + 0.05 * f64::from(k)), json!({"name": format!("s{k}")})));
    editor
        .create(&[
            LayerSpec { name: "parcels", geom: "polygon", fields: &["name"], features: parcels.collect() },
            LayerSpec { name: "sites", geom: "point", fields: &["name"], features: sites.collect() },
        ])
        .unwrap();
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    let manifest = fixtures::write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"town\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n\
             [[source]]\nid = \"parcels\"\nkind = \"ogr\"\npath = \"town.gdb\"\nlayer = \"parcels\"\n\n\
             [[source]]\nid = \"sites\"\nkind = \"ogr\"\npath = \"town.gdb\"\nlayer = \"sites\"\n\n\
             [layers]\nheight = \"dem\"\n{watch}"
        ),
    )
    .unwrap();
    (manifest, gdb, editor)
}

async fn state(channel: &Channel) -> pb::SceneState {
    SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner()
}

fn source<'a>(state: &'a pb::SceneState, id: &str) -> &'a pb::SourceState {
    state.sources.iter().find(|s| s.id == id).unwrap_or_else(|| panic!("no source {id}: {state:#?}"))
}

/// The names of the parcels reliefd serves now, sorted.
async fn names(channel: &Channel) -> Vec<String> {
    let tile = tiles::get(channel.clone(), "parcels", TILE).await.unwrap();
    let json = tiles::geojson(&tile);
    let mut names: Vec<String> = json["features"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["properties"]["name"].as_str().unwrap_or_default().to_owned())
        .collect();
    names.sort();
    names
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn edits_saved_to_a_geodatabase_reach_the_scene_and_only_the_edited_tables_sources() {
    if !arcgis::available("edits_saved_to_a_geodatabase_reach_the_scene") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (manifest, _gdb, mut editor) = town(dir.path(), "");
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let before = state(&channel).await;
    let parcels = source(&before, "parcels");
    assert_eq!(parcels.details["features"], "5", "{parcels:#?}");
    assert_eq!(parcels.details["driver"], "OpenFileGDB");
    // The table's own files are what the source reads and watches.
    let table = parcels.details["table"].clone();
    let stem = table.trim_end_matches(".gdbtable");
    assert!(parcels.files.iter().any(|f| f.ends_with(&format!("town.gdb/{table}"))), "{:?}", parcels.files);
    assert!(parcels.files.iter().any(|f| f.ends_with(&format!("{stem}.gdbtablx"))), "{:?}", parcels.files);
    assert_ne!(source(&before, "sites").details["table"], table, "two tables");

    // Update one feature's attribute: the parcels source is new, the sites' is not.
    editor.update("parcels", 2, &json!({"name": "renamed"}), None).unwrap();
    let updated = wait_for(channel.clone(), before.generation + 1).await.unwrap();
    assert!(edit::version(&updated, "parcels") > edit::version(&before, "parcels"));
    assert_eq!(edit::version(&updated, "sites"), edit::version(&before, "sites"));
    assert_eq!(names(&channel).await, ["p0", "p2", "p3", "p4", "renamed"]);

    // Insert one.
    editor.insert("parcels", &square_wkt(10.3, 45.25, 0.01), &json!({"name": "new"})).unwrap();
    let inserted = wait_for(channel.clone(), updated.generation + 1).await.unwrap();
    assert_eq!(source(&inserted, "parcels").details["features"], "6");
    assert!(names(&channel).await.contains(&"new".to_owned()));

    // Delete one.
    editor.delete("parcels", 1).unwrap();
    let deleted = wait_for(channel.clone(), inserted.generation + 1).await.unwrap();
    assert_eq!(source(&deleted, "parcels").details["features"], "5");
    assert!(!names(&channel).await.contains(&"p0".to_owned()));

    // An edit to the other table refreshes only its source.
    editor.update("sites", 1, &json!({"name": "moved"}), Some("POINT (10.21 45.31)")).unwrap();
    let sited = wait_for(channel.clone(), deleted.generation + 1).await.unwrap();
    assert!(edit::version(&sited, "sites") > edit::version(&deleted, "sites"));
    assert_eq!(edit::version(&sited, "parcels"), edit::version(&deleted, "parcels"));

    // A REPACK rewrites the table without the deleted row's space: the same
    // features, read without error, and edits after it are still followed.
    editor.repack("parcels").unwrap();
    tokio::time::sleep(Duration::from_millis(800)).await;
    let repacked = state(&channel).await;
    let after_repack = source(&repacked, "parcels");
    assert!(after_repack.error.is_empty(), "{after_repack:#?}");
    assert_eq!(after_repack.details["features"], "5");
    assert_eq!(names(&channel).await, ["new", "p2", "p3", "p4", "renamed"]);
    editor.update("parcels", 3, &json!({"name": "after repack"}), None).unwrap();
    wait_for(channel.clone(), repacked.generation + 1).await.unwrap();
    assert!(names(&channel).await.contains(&"after repack".to_owned()));
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_arcgis_edit_lock_holds_the_read_back_and_a_stale_one_is_read_after_the_timeout_with_a_warning() {
    if !arcgis::available("an_arcgis_edit_lock_holds_the_read_back") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (manifest, gdb, mut editor) = town(dir.path(), "\n[watch]\nwrite_timeout_ms = 3000\n");
    // The schema lock every ArcGIS session holds while it shows the data
    // means nothing for the read.
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let before = state(&channel).await;
    let stem = source(&before, "parcels").details["table"].trim_end_matches(".gdbtable").to_owned();
    std::fs::write(gdb.join(format!("{stem}.DESKTOP-7.4242.9000.sr.lock")), b"").unwrap();
    std::fs::write(gdb.join("_gdb.DESKTOP-7.4242.9000.sr.lock"), b"").unwrap();
    editor.update("parcels", 2, &json!({"name": "schema-locked"}), None).unwrap();
    let seen = wait_for(channel.clone(), before.generation + 1).await.unwrap();
    assert!(names(&channel).await.contains(&"schema-locked".to_owned()));
    assert!(source(&seen, "parcels").warnings.is_empty(), "{:#?}", source(&seen, "parcels"));

    // An edit lock: the save is not read while it is there...
    let lock = gdb.join(format!("{stem}.DESKTOP-7.4242.9000.ed.lock"));
    std::fs::write(&lock, b"").unwrap();
    editor.update("parcels", 3, &json!({"name": "while locked"}), None).unwrap();
    tokio::time::sleep(Duration::from_millis(1200)).await;
    let held = state(&channel).await;
    assert_eq!(edit::version(&held, "parcels"), edit::version(&seen, "parcels"), "read while the lock was there");
    // ... and is read once it goes.
    std::fs::remove_file(&lock).unwrap();
    let released = wait_for(channel.clone(), held.generation + 1).await.unwrap();
    assert!(names(&channel).await.contains(&"while locked".to_owned()));
    assert!(source(&released, "parcels").warnings.is_empty());

    // A lock a crashed ArcGIS left: read after write_timeout_ms, and said.
    std::fs::write(&lock, b"").unwrap();
    editor.update("parcels", 4, &json!({"name": "stale lock"}), None).unwrap();
    let stale = wait_for(channel.clone(), released.generation + 1).await.unwrap();
    assert!(names(&channel).await.contains(&"stale lock".to_owned()));
    let warnings = source(&stale, "parcels").warnings.join("\n");
    assert!(warnings.contains(&format!("{stem}.DESKTOP-7.4242.9000.ed.lock")), "{warnings}");
    assert!(warnings.contains("crashed ArcGIS"), "{warnings}");
    // The other table's source saw none of it.
    assert_eq!(edit::version(&stale, "sites"), edit::version(&before, "sites"));
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_table_caught_mid_rewrite_is_retried_and_never_published() {
    if !arcgis::available("a_table_caught_mid_rewrite_is_retried") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (manifest, gdb, editor) = town(dir.path(), "");
    drop(editor);
    // The next save, made on a copy: an insert of ten parcels.
    let copy = dir.path().join("copy.gdb");
    std::fs::create_dir(&copy).unwrap();
    for entry in std::fs::read_dir(&gdb).unwrap().flatten() {
        std::fs::copy(entry.path(), copy.join(entry.file_name())).unwrap();
    }
    {
        let mut other = GdbEditor::start(&copy).unwrap();
        for k in 0..10 {
            other
                .insert("parcels", &square_wkt(10.2 + 0.01 * f64::from(k), 45.33, 0.005), &json!({"name": "more"}))
                .unwrap();
        }
    }
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let before = state(&channel).await;
    let table = source(&before, "parcels").details["table"].clone();
    let stem = table.trim_end_matches(".gdbtable").to_owned();
    let new_rows = std::fs::read(copy.join(&table)).unwrap();
    let new_index = std::fs::read(copy.join(format!("{stem}.gdbtablx"))).unwrap();

    // Caught mid-rewrite: the new index, and the rows written half way.
    std::fs::write(gdb.join(format!("{stem}.gdbtablx")), &new_index).unwrap();
    std::fs::write(gdb.join(&table), &new_rows[..new_rows.len() / 2]).unwrap();
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let torn = state(&channel).await;
    let parcels = source(&torn, "parcels");
    assert_eq!(edit::version(&torn, "parcels"), edit::version(&before, "parcels"), "a torn table was published");
    assert_eq!(parcels.details["features"], "5");
    assert!(parcels.error.contains("truncated or corrupt") && parcels.error.contains(&table), "{parcels:#?}");
    assert_eq!(names(&channel).await.len(), 5, "the last good version is served");

    // The writer finishes: read whole.
    std::fs::write(gdb.join(&table), &new_rows).unwrap();
    let done = wait_for(channel.clone(), torn.generation + 1).await.unwrap();
    let parcels = source(&done, "parcels");
    assert_eq!(parcels.details["features"], "15", "{parcels:#?}");
    assert!(parcels.error.is_empty());
    daemon.stop(&["truncated or corrupt", "keeping the last good version"]).unwrap();
}
