//! A real QGIS (headless) editing a GeoPackage layer of a running scene:
//! every commit becomes exactly one generation holding the whole commit,
//! only the changed features' tiles are rebuilt, and no generation ever
//! shows a state between the transactions of one commit. Edits from
//! `ogr2ogr -update -append` and from Python's `sqlite3` are picked up too.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

use relief_examples::Lcg;
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::edit::{self, Events};
use relief_tests::qgis::{self, Edit, QgisEditor, QgisFeature};
use relief_tests::{scenes, tiles};
use serde_json::{Value, json};
use tonic::transport::Channel;

/// Vertices are served in the grid's CRS, the same EPSG:4326 here: they
/// come back as written but for the last bits of a PROJ round trip.
const COORD_TOLERANCE: f64 = 1e-9;
/// Level-12 tiles (0.044 degrees): each parcel lies in its own few.
const LEVEL: u32 = 12;

/// Served features by fid: attributes as text, vertices.
type Served = BTreeMap<u64, (BTreeMap<String, String>, Vec<[f64; 2]>)>;

/// The parcels reliefd serves now, by fid: the generation, and each
/// feature's attributes (as text) and vertices.
async fn served(channel: &Channel) -> (u64, Served) {
    // Level 0's eastern tile holds every parcel whole.
    let tile = tiles::get(channel.clone(), "parcels", (0, 1, 0)).await.unwrap();
    let json = tiles::geojson(&tile);
    let mut out = BTreeMap::new();
    for f in json["features"].as_array().unwrap() {
        let props = f["properties"].as_object().unwrap();
        let attrs = props.iter().map(|(k, v)| (k.clone(), v.as_str().unwrap().to_owned())).collect();
        let mut coords = Vec::new();
        flatten(&f["geometry"]["coordinates"], &mut coords);
        out.insert(f["id"].as_u64().unwrap(), (attrs, coords));
    }
    (tile.generation, out)
}

fn flatten(v: &Value, out: &mut Vec<[f64; 2]>) {
    match v.as_array() {
        Some(a) if a.first().is_some_and(Value::is_number) => {
            out.push([a[0].as_f64().unwrap(), a[1].as_f64().unwrap()]);
        }
        Some(a) => a.iter().for_each(|p| flatten(p, out)),
        None => {}
    }
}

/// Why the served parcels differ from what QGIS committed, if they do.
fn difference(served: &Served, committed: &[QgisFeature]) -> Option<String> {
    let fids: BTreeSet<u64> = committed.iter().map(|f| f.fid).collect();
    if fids != served.keys().copied().collect() {
        return Some(format!("fids {:?} served, {fids:?} committed", served.keys().collect::<Vec<_>>()));
    }
    for f in committed {
        let (attrs, coords) = &served[&f.fid];
        for (name, value) in &f.attrs {
            let ours = attrs.get(name);
            let same = match value {
                Value::Null => ours.is_none(),
                Value::Number(n) => {
                    ours.and_then(|t| t.parse::<f64>().ok()).is_some_and(|v| (v - n.as_f64().unwrap()).abs() < 1e-9)
                }
                Value::String(s) => ours == Some(s),
                other => ours == Some(&other.to_string()),
            };
            if !same {
                return Some(format!("feature {} attribute '{name}': {ours:?} served, {value} committed", f.fid));
            }
        }
        let close = coords.len() == f.coords.len()
            && coords
                .iter()
                .zip(&f.coords)
                .all(|(a, b)| (a[0] - b[0]).abs() < COORD_TOLERANCE && (a[1] - b[1]).abs() < COORD_TOLERANCE);
        if !close {
            return Some(format!("feature {} vertices: {coords:?} served, {:?} committed", f.fid, f.coords));
        }
    }
    None
}

fn bbox(coords: &[[f64; 2]]) -> [f64; 4] {
    coords.iter().fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |b, p| {
        [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])]
    })
}

/// The boxes of every feature a commit changed, added or deleted: where it
/// was and where it is.
fn changed_boxes(before: &[QgisFeature], after: &[QgisFeature]) -> Vec<[f64; 4]> {
    let old: BTreeMap<u64, &QgisFeature> = before.iter().map(|f| (f.fid, f)).collect();
    let new: BTreeMap<u64, &QgisFeature> = after.iter().map(|f| (f.fid, f)).collect();
    let fids: BTreeSet<u64> = old.keys().chain(new.keys()).copied().collect();
    let mut boxes = Vec::new();
    for fid in fids {
        let (o, n) = (old.get(&fid), new.get(&fid));
        if o != n {
            boxes.extend(o.map(|f| bbox(&f.coords)));
            boxes.extend(n.map(|f| bbox(&f.coords)));
        }
    }
    boxes
}

fn sorted_unique(mut boxes: Vec<[f64; 4]>) -> Vec<[f64; 4]> {
    boxes.sort_by(|a, b| a.partial_cmp(b).unwrap());
    boxes.dedup_by(|a, b| a.iter().zip(b.iter()).all(|(x, y)| (x - y).abs() < COORD_TOLERANCE));
    boxes
}

/// The level-12 tile over each parcel's centre.
fn parcel_tiles(features: &[QgisFeature]) -> BTreeSet<(u32, u32, u32)> {
    let span = 180.0 / f64::from(1u32 << LEVEL);
    features
        .iter()
        .map(|f| {
            let b = bbox(&f.coords);
            let (lon, lat) = (f64::midpoint(b[0], b[2]), f64::midpoint(b[1], b[3]));
            (LEVEL, ((lon + 180.0) / span) as u32, ((90.0 - lat) / span) as u32)
        })
        .collect()
}

/// True when tile `key` reaches (with a margin of a few texels) into any of `boxes`.
fn touches(key: (u32, u32, u32), boxes: &[[f64; 4]]) -> bool {
    let span = 180.0 / f64::from(1u32 << key.0);
    let margin = span * 0.02;
    let (w, n) = (f64::from(key.1) * span - 180.0, 90.0 - f64::from(key.2) * span);
    boxes
        .iter()
        .any(|b| b[0] <= w + span + margin && b[2] >= w - margin && b[1] <= n + margin && b[3] >= n - span - margin)
}

async fn hashes(channel: &Channel, keys: &BTreeSet<(u32, u32, u32)>) -> BTreeMap<(u32, u32, u32), u64> {
    let mut out = BTreeMap::new();
    for key in keys {
        out.insert(*key, edit::tile_hash(channel.clone(), "drawn", *key).await.unwrap());
    }
    out
}

/// One commit checked: exactly the next generation, the whole commit in
/// it, dirt only where changed features were and are, and only their
/// tiles redrawn. Returns the committed features.
async fn commit_and_check(
    channel: &Channel,
    events: &Events,
    editor: &mut QgisEditor,
    before: &[QgisFeature],
    edits: &[Edit],
    stay_editing: bool,
    what: &str,
) -> Vec<QgisFeature> {
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let keys = parcel_tiles(before);
    let old_hashes = hashes(channel, &keys).await;
    let commit = editor.commit(edits, stay_editing).unwrap();
    let after = edit::wait_for(channel.clone(), state.generation + 1).await.unwrap();
    assert_eq!(after.generation, state.generation + 1, "{what}: one commit, one generation");
    let (generation, now) = served(channel).await;
    assert_eq!(generation, after.generation, "{what}: nothing after the commit's generation");
    if let Some(why) = difference(&now, &commit.features) {
        panic!("{what}: generation {generation} is not what QGIS committed: {why}");
    }
    let event = events.generation(after.generation).await.unwrap();
    assert!(event.changed_sources.contains(&"parcels".to_owned()), "{what}: {event:?}");
    assert!(!event.changed_sources.contains(&"roads".to_owned()), "{what}: the other layer is untouched");
    assert_eq!(edit::version(&after, "roads"), edit::version(&state, "roads"), "{what}");
    let dirt: Vec<[f64; 4]> = event
        .dirty
        .iter()
        .filter(|d| d.source_id == "parcels")
        .flat_map(|d| d.extents.iter().map(|e| [e.min_x, e.min_y, e.max_x, e.max_y]))
        .collect();
    let expected = changed_boxes(before, &commit.features);
    let (dirt, expected) = (sorted_unique(dirt), sorted_unique(expected.clone()));
    assert_eq!(dirt.len(), expected.len(), "{what}: dirt {dirt:?}, changed {expected:?}");
    for (d, e) in dirt.iter().zip(&expected) {
        assert!(
            d.iter().zip(e).all(|(a, b)| (a - b).abs() < COORD_TOLERANCE),
            "{what}: dirt {dirt:?}, changed {expected:?}"
        );
    }
    let new_hashes = hashes(channel, &keys).await;
    let mut kept = 0;
    for key in &keys {
        if !touches(*key, &expected) {
            assert_eq!(new_hashes[key], old_hashes[key], "{what}: tile {key:?} holds no changed parcel");
            kept += 1;
        }
    }
    assert!(kept >= keys.len() - 6, "{what}: {kept} of {} tiles kept", keys.len());
    assert!(event.tiles_carried_over >= 1, "{what}: {event:?}");
    commit.features
}

/// The town scene served, followed, and QGIS editing its parcels (with
/// `also` loaded beside them); None when QGIS is not installed.
struct Session {
    _dir: tempfile::TempDir,
    daemon: Reliefd,
    channel: Channel,
    events: Events,
    editor: QgisEditor,
    features: Vec<QgisFeature>,
}

async fn session(test: &str, also: &[&str]) -> Option<Session> {
    if !qgis::available(test) {
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let (manifest, gpkg) = scenes::town(dir.path(), "").unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let (editor, features) = QgisEditor::start(&gpkg, "parcels", also).unwrap();
    Some(Session { _dir: dir, daemon, channel, events, editor, features })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_qgis_edit_is_one_generation_with_the_whole_commit() {
    let Some(Session { _dir, daemon, channel, events, mut editor, mut features }) =
        session("each_qgis_edit_is_one_generation_with_the_whole_commit", &[]).await
    else {
        return;
    };
    let first = events.all()[0].generation;
    assert_eq!(difference(&served(&channel).await.1, &features), None, "as loaded");

    let square = |x: f64, y: f64| {
        format!("POLYGON(({x} {y},{} {y},{} {},{x} {},{x} {y}))", x + 0.01, x + 0.01, y + 0.01, y + 0.01)
    };
    let commits: Vec<(&str, Vec<Edit>, bool)> = vec![
        ("a vertex moved", vec![Edit::MoveVertex { fid: 6, vertex: 2, dx: 0.004, dy: 0.003 }], false),
        (
            "a feature added",
            vec![Edit::Add { wkt: square(10.47, 45.47), attrs: json!({"name": "new", "height": 99.0}) }],
            false,
        ),
        ("a feature deleted", vec![Edit::Delete { fid: 13 }], false),
        ("an attribute edited", vec![Edit::Set { fid: 20, field: "height".into(), value: json!(123.5) }], false),
        (
            "all four in one commit",
            vec![
                Edit::MoveVertex { fid: 2, vertex: 1, dx: 0.002, dy: 0.001 },
                Edit::Set { fid: 2, field: "name".into(), value: json!("moved") },
                Edit::Add { wkt: square(10.11, 45.47), attrs: json!({"name": "added", "height": 42.0}) },
                Edit::Delete { fid: 25 },
            ],
            false,
        ),
        // "Save Layer Edits" keeps the layer in edit mode: no close of the
        // file marks the end, the quiet period does.
        ("saved, still editing", vec![Edit::MoveVertex { fid: 9, vertex: 0, dx: -0.003, dy: 0.0 }], true),
        ("the edit session ended", vec![Edit::Set { fid: 9, field: "name".into(), value: json!("nine") }], false),
    ];
    for (what, edits, stay) in &commits {
        features = commit_and_check(&channel, &events, &mut editor, &features, edits, *stay, what).await;
    }
    editor.quit().unwrap();
    // Nothing more comes of it: no generation besides the commits' own.
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let generations: Vec<u64> = events.generations().iter().map(|g| g.0).filter(|g| *g > first).collect();
    assert_eq!(generations.len(), commits.len(), "one generation per commit: {generations:?}");
    assert_eq!(difference(&served(&channel).await.1, &features), None, "after QGIS quit");
    assert!(events.errors().is_empty(), "{:?}", events.errors());
    daemon.stop(&[]).unwrap();
}

/// 1 to 4 random edits of live parcels: moves, attribute edits, adds, deletes.
fn random_edits(rng: &mut Lcg, live: &[QgisFeature], n: usize) -> Vec<Edit> {
    let count = 1 + rng.range(0.0, 4.0) as usize;
    let mut used = BTreeSet::new();
    let mut edits = Vec::new();
    for _ in 0..count {
        let f = &live[rng.range(0.0, live.len() as f64) as usize % live.len()];
        if !used.insert(f.fid) {
            continue;
        }
        edits.push(match rng.range(0.0, 4.0) as u32 {
            0 => Edit::MoveVertex { fid: f.fid, vertex: 1, dx: rng.range(-0.004, 0.004), dy: rng.range(-0.004, 0.004) },
            1 => Edit::Set { fid: f.fid, field: "height".into(), value: json!(rng.range(0.0, 300.0).round()) },
            2 if live.len() > 10 => Edit::Delete { fid: f.fid },
            _ => {
                let (x, y) = (rng.range(10.02, 10.45), rng.range(45.02, 45.45));
                Edit::Add {
                    wkt: format!("POLYGON(({x} {y},{} {y},{} {},{x} {y}))", x + 0.01, x + 0.01, y + 0.01),
                    attrs: json!({"name": format!("n{n}"), "height": 7.0}),
                }
            }
        });
    }
    edits
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twenty_qgis_commits_in_a_row_never_show_a_state_between_transactions() {
    // The roads layer loaded too: QGIS keeps the file in WAL mode, its log
    // and index stay, and every reader of the file uses them.
    let Some(Session { _dir, daemon, channel, events, mut editor, mut features }) =
        session("twenty_qgis_commits_in_a_row_never_show_a_state_between_transactions", &["roads"]).await
    else {
        return;
    };
    let mut rng = Lcg(12);

    // Twenty commits, each waited for: every generation checked.
    for n in 0..20 {
        let edits = random_edits(&mut rng, &features, n);
        features =
            commit_and_check(&channel, &events, &mut editor, &features, &edits, false, &format!("commit {n}")).await;
    }

    // Twenty more back to back, each straight after the last, while the
    // served parcels are read as often as they can be: every state seen is
    // one QGIS committed, in order.
    let mut planned = features.clone();
    let mut batches = Vec::new();
    for n in 20..40 {
        let edits = random_edits(&mut rng, &planned, n);
        // Plan the next batch against a copy with deletes applied, so no
        // batch deletes a parcel an earlier one did.
        planned.retain(|f| !edits.iter().any(|e| matches!(e, Edit::Delete { fid } if *fid == f.fid)));
        batches.push(edits);
    }
    let committer = std::thread::Builder::new()
        .name("qgis-commits".into())
        .spawn(move || {
            for edits in &batches {
                editor.send(edits, false).unwrap();
            }
            let commits: Vec<_> = (0..batches.len()).map(|_| editor.committed().unwrap()).collect();
            editor.quit().unwrap();
            commits
        })
        .unwrap();
    let mut seen = Vec::new();
    while !committer.is_finished() {
        seen.push(served(&channel).await);
    }
    let commits = committer.join().unwrap();
    tokio::time::sleep(Duration::from_millis(1500)).await;
    seen.push(served(&channel).await);
    let states: Vec<&[QgisFeature]> =
        std::iter::once(features.as_slice()).chain(commits.iter().map(|c| c.features.as_slice())).collect();
    let mut last = 0;
    let mut distinct = BTreeSet::new();
    for (generation, parcels) in &seen {
        let Some(k) = (last..states.len()).find(|&k| difference(parcels, states[k]).is_none()) else {
            let why = difference(parcels, states[last]).unwrap_or_default();
            panic!("generation {generation} is no state QGIS committed (after commit {last}: {why})");
        };
        last = k;
        distinct.insert(*generation);
    }
    assert_eq!(last, states.len() - 1, "the last commit is served in the end");
    eprintln!("burst: {} reads, generations {distinct:?}, last state {last}", seen.len());
    assert!(distinct.len() >= 2, "the reads saw the commits land: {distinct:?}");
    let roads = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    assert_eq!(edit::version(&roads, "roads"), 1, "the roads never changed");
    assert!(events.errors().is_empty(), "{:?}", events.errors());
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ogr2ogr_appends_and_python_sqlite3_deletes_are_picked_up() {
    let dir = tempfile::tempdir().unwrap();
    let (manifest, gpkg) = scenes::town(dir.path(), "").unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let (g0, start) = served(&channel).await;
    assert_eq!(start.len(), 30);

    // ogr2ogr -update -append: one more parcel, as a script importing a survey would.
    let extra = dir.path().join("survey.geojson");
    std::fs::write(
        &extra,
        relief_tests::vectors::squares(&[(r#"{"name": "surveyed", "height": 5.5}"#, 10.33, 45.48, 0.01)]),
    )
    .unwrap();
    let out = std::process::Command::new("ogr2ogr")
        .args(["-q", "-update", "-append", "-nln", "parcels"])
        .arg(&gpkg)
        .arg(&extra)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    edit::wait_for(channel.clone(), g0 + 1).await.unwrap();
    let (g1, appended) = served(&channel).await;
    assert_eq!(appended.len(), 31);
    let (attrs, coords) = &appended[&31];
    assert_eq!(attrs["name"], "surveyed");
    assert!(
        (coords[0][0] - 10.33).abs() < COORD_TOLERANCE && (coords[0][1] - 45.48).abs() < COORD_TOLERANCE,
        "{coords:?}"
    );

    // Python's sqlite3, no GDAL: a row deleted and committed, the
    // connection closed.
    let script = "import sqlite3, sys\nc = sqlite3.connect(sys.argv[1])\nc.execute('DELETE FROM parcels WHERE fid = 3')\nc.commit()\nc.close()\n";
    let out = std::process::Command::new("python3").args(["-c", script]).arg(&gpkg).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    edit::wait_for(channel.clone(), g1 + 1).await.unwrap();
    let (_, deleted) = served(&channel).await;
    assert_eq!(deleted.len(), 30);
    assert!(!deleted.contains_key(&3) && deleted.contains_key(&31));
    daemon.stop(&[]).unwrap();
}
