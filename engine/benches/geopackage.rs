//! GeoPackage benchmark. Prints tables; never asserts a time.
//!
//! 1. A QGIS commit on a GeoPackage layer to a new generation: a real QGIS
//!    (headless, `tests/scripts/qgis_editor.py`) edits the `parcels` layer
//!    of the town scene served by the real reliefd; each commit moves a
//!    vertex and edits an attribute of one parcel. The clock runs from just
//!    before `commitChanges()` (QGIS's wall clock) to WaitForGeneration
//!    returning, for the default `[watch]` (the database's close ends the
//!    commit: read after `settle_ms`) and for `fast_path = false` (every
//!    commit waits out the quiet period, `debounce_ms`): the knob's cost.
//! 2. Natural Earth's countries (`../shared/data/shp`) as a GeoPackage
//!    (ogr2ogr) through the `ogr` kind, against the same shapefile through
//!    the `shapefile` kind: scene load time, then feature tiles and drawn
//!    (rasterize) tiles per second over levels 0..=5, with the ratios.
//!
//! `cargo bench -p relief-engine --bench geopackage` (RELIEF_BENCH_COMMITS,
//! default 25).

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

mod common;

use std::path::Path;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_source::{Quality, TileKey};
use relief_tests::daemon::Reliefd;
use relief_tests::edit;
use relief_tests::qgis::{self, Edit, QgisEditor};
use serde_json::json;

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn wall() -> f64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0.0, |d| d.as_secs_f64())
}

/// Milliseconds from each commit's start to its generation, and from
/// QGIS's commit returning to it.
async fn commits(dir: &Path, watch: &str, n: usize) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let (manifest, gpkg) = relief_tests::scenes::town(dir, watch)?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let channel = daemon.channel().await?;
    let (editor, _) = QgisEditor::start(&gpkg, "parcels", &[])?;
    let editor = std::sync::Arc::new(std::sync::Mutex::new(editor));
    let (mut from_start, mut from_return) = (Vec::new(), Vec::new());
    for i in 0..n {
        // Each round starts idle.
        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
        let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await?.into_inner();
        let step = if i % 2 == 0 { 0.002 } else { -0.002 };
        let edits = vec![
            Edit::MoveVertex { fid: 8, vertex: 1, dx: step, dy: step },
            Edit::Set { fid: 8, field: "height".into(), value: json!(i) },
        ];
        let qgis = std::sync::Arc::clone(&editor);
        let committing = tokio::task::spawn_blocking(move || {
            qgis.lock().map_err(|_| anyhow::anyhow!("the editor lock"))?.commit(&edits, false)
        });
        edit::wait_for(channel.clone(), state.generation + 1).await?;
        let seen = wall();
        let commit = committing.await??;
        from_start.push((seen - commit.t0) * 1e3);
        from_return.push((seen - commit.t1) * 1e3);
    }
    if let Ok(editor) = std::sync::Arc::try_unwrap(editor) {
        editor.into_inner().map_err(|_| anyhow::anyhow!("the editor lock"))?.quit()?;
    }
    daemon.stop(&[])?;
    Ok((from_start, from_return))
}

async fn qgis_table(n: usize) -> anyhow::Result<()> {
    if !qgis::available("the QGIS commit benchmark") {
        return Ok(());
    }
    println!("QGIS commit on a GeoPackage layer to a new generation ({n} commits each; ms)");
    println!("{:<66}{:>9}{:>9}{:>9}{:>9}", "[watch]", "p50", "p95", "min", "max");
    let mut p50s = Vec::new();
    for (label, watch) in [
        ("default (close of the database ends it)", ""),
        ("fast_path = false (quiet period, 500 ms)", "\n[watch]\nfast_path = false\n"),
    ] {
        let dir = tempfile::tempdir()?;
        let (mut from_start, mut from_return) = commits(dir.path(), watch, n).await?;
        from_start.sort_by(f64::total_cmp);
        from_return.sort_by(f64::total_cmp);
        for (what, v) in [("commit start", &from_start), ("commit returned", &from_return)] {
            println!(
                "{:<66}{:>9.1}{:>9.1}{:>9.1}{:>9.1}",
                format!("{label}, from {what}"),
                percentile(v, 0.5),
                percentile(v, 0.95),
                v[0],
                v[v.len() - 1]
            );
        }
        p50s.push(percentile(&from_start, 0.5));
    }
    println!("quiet period / default, p50 from commit start: {:.2}x\n", p50s[1] / p50s[0]);
    Ok(())
}

/// Load time (median of 5, ms), and feature and drawn tiles per second
/// over levels 0..=5, for `source` (a manifest fragment) as `countries`.
fn countries(dir: &Path, source: &str) -> anyhow::Result<(f64, f64, f64)> {
    let manifest = relief_examples::write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"countries\"\n\n[[source]]\nid = \"countries\"\n{source}\n\n[[source]]\nid = \"drawn\"\nkind = \"rasterize\"\ninputs = [\"countries\"]\nstroke = \"none\"\nfill = \"#ff0000ff\"\n\n[layers]\ncolor = \"drawn\"\n\n[cache]\nmemory_mb = 4096\ndisk_mb = 0\n"
        ),
    )?;
    let mut loads = Vec::new();
    let mut scene = None;
    for _ in 0..5 {
        let started = Instant::now();
        let loaded = common::load(&manifest, 2)?;
        loads.push(started.elapsed().as_secs_f64() * 1e3);
        scene = Some(loaded);
    }
    let scene = scene.context("loaded")?;
    let snap = scene.snapshot();
    let keys: Vec<TileKey> = (0..=5).flat_map(|l| snap.grid.keys_overlapping(l, &snap.grid.extent())).collect();
    let mut rates = Vec::new();
    for id in ["countries", "drawn"] {
        let index = snap.index_of(id).context("the bench scene's sources")?;
        let requests: Vec<(usize, TileKey)> = keys.iter().map(|k| (index, *k)).collect();
        let started = Instant::now();
        for tile in scene.store.build(&snap, &requests, &Quality::default()) {
            tile?;
        }
        rates.push(keys.len() as f64 / started.elapsed().as_secs_f64());
    }
    Ok((common::median(loads), rates[0], rates[1]))
}

fn countries_table() -> anyhow::Result<()> {
    let Some(data) = relief_tests::shared_data("the Natural Earth GeoPackage benchmark") else {
        return Ok(());
    };
    let shp = data.join("shp/naturalearth_lowres.shp");
    let dir = tempfile::tempdir()?;
    let gpkg = dir.path().join("countries.gpkg");
    let out = std::process::Command::new("ogr2ogr").args(["-q", "-f", "GPKG"]).arg(&gpkg).arg(&shp).output()?;
    anyhow::ensure!(out.status.success(), "ogr2ogr: {}", String::from_utf8_lossy(&out.stderr));
    println!("Natural Earth countries (177 polygons), levels 0..=5 (2,730 tiles), 2 tile threads");
    println!("{:<40}{:>12}{:>16}{:>16}", "source", "load ms", "feature tiles/s", "drawn tiles/s");
    let rows = [
        ("GeoPackage, kind ogr", format!("kind = \"ogr\"\npath = \"{}\"", gpkg.display())),
        ("shapefile, kind shapefile", format!("kind = \"shapefile\"\npath = \"{}\"", shp.display())),
    ];
    let mut results = Vec::new();
    for (label, source) in &rows {
        let (load, features, drawn) = countries(dir.path(), source)?;
        println!("{label:<40}{load:>12.1}{features:>16.0}{drawn:>16.0}");
        results.push((load, features, drawn));
    }
    let (g, s) = (results[0], results[1]);
    println!(
        "ogr GeoPackage / shapefile: load time {:.2}x, feature tiles/s {:.2}x, drawn tiles/s {:.2}x",
        g.0 / s.0,
        g.1 / s.1,
        g.2 / s.2
    );
    Ok(())
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let n = std::env::var("RELIEF_BENCH_COMMITS").ok().and_then(|v| v.parse().ok()).unwrap_or(25);
    println!("machine: {}\n", relief_tests::machine());
    qgis_table(n).await?;
    countries_table()
}
