//! ArcGIS editing, live (issue 38). Prints tables; never asserts a time.
//!
//! The real reliefd (the release build beside this bench) on the analytic
//! hill, with ArcGIS's formats as GDAL writes them.
//! 1. A file geodatabase edit of one feature to a new generation: a
//!    `town.gdb` with a `parcels` table of 1,000 squares over the hill
//!    (10.2..10.4 E, 45.2..45.4 N, drawn by a `rasterize` source as the
//!    colour layer) and a second table (`sites`, points), each an `ogr`
//!    source. GDAL's OpenFileGDB driver (`tests/scripts/gdb_editor.py`, as
//!    ArcGIS's "Save edits": open, change, close) updates one parcel's
//!    attribute and geometry per round, each round starting idle. The clock
//!    runs from the editor's save closing (its `t`) to WaitForGeneration
//!    returning, and from the command being sent. Names are fixed-width
//!    (`p0001`, `e0001`): with Debian's GDAL 3.6.2, a second edit that grows
//!    a row (moved to the table's end) leaves a table that OGR's iteration
//!    ends early, one feature per grown row, which reliefd rightly refuses;
//!    the bench counts the refused reads it still sees.
//! 2. An edit of 1,000 features in one transaction and one save (GDAL's
//!    OpenFileGDB, as the editor's `move` but descending into the
//!    MULTIPOLYGONs the driver gives, which `move` leaves as they were):
//!    save to generation, and the generation's tiles rebuilt and dropped.
//! 3. 2,000 buildings as a MultiPatch shapefile (walls a TIN, roof a
//!    polygon, absolute heights on the hill) against the same buildings'
//!    footprints extruded by an `extrude` source: scene load, GetTile of
//!    the level-14 mesh tiles over them, triangles, and 1280 x 720 frames
//!    (Render as RGBA8, lit, 600 m up looking down 30 degrees), with the
//!    ratio MultiPatch / extruded.
//!
//! `cargo bench -p relief-daemon --bench arcgis`; RELIEF_BENCH_EDITS
//! (default 25), RELIEF_BENCH_ONLY (tables by name, commas: edit, bulk,
//! multipatch). Needs Debian's python3-gdal (scripts/setup.sh installs it);
//! without it the bench says so and skips the tables.

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

mod common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use common::{env_u64, median, state, wanted};
use relief_proto::v1 as pb;
use relief_tests::arcgis::{self, GdbEditor, LayerSpec, square_wkt};
use relief_tests::daemon::Reliefd;
use relief_tests::edit::{self, wait_for};
use relief_tests::{fixtures, scenes, tiles};
use serde_json::json;
use tonic::transport::Channel;

/// The parcels: 40 columns x 25 rows of squares over 10.2..10.4 E, 45.2..45.4 N.
const PARCEL_COLUMNS: u32 = 40;
const PARCEL_ROWS: u32 = 25;
const PARCEL_SIDE_DEG: f64 = 0.004;
/// The buildings: 50 x 40 of them, one per 50 m cell, south-west corner
/// of the district on the hill's south-east flank.
const DISTRICT: (f64, f64) = (10.29, 45.2);
const BUILDING_COLUMNS: u32 = 50;
const BUILDING_ROWS: u32 = 40;
const CELL_M: f64 = 50.0;
const MESH_LEVEL: u32 = 14;
/// reliefd's warning when it refuses a read of a changed file.
const KEPT_LAST_GOOD: &str = "keeping the last good version";

fn profile() -> &'static str {
    if cfg!(debug_assertions) { "debug (not what the issue's numbers mean)" } else { "release (bench profile)" }
}

fn wall() -> f64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(f64::NAN, |d| d.as_secs_f64())
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// p50, p95, min and max.
fn spread(mut v: Vec<f64>) -> (f64, f64, f64, f64) {
    v.sort_by(f64::total_cmp);
    (percentile(&v, 0.5), percentile(&v, 0.95), percentile(&v, 0.0), percentile(&v, 1.0))
}

fn header(title: &str) {
    println!("\n## {title}\n\nmachine: {}; build: {}\n", relief_tests::machine(), profile());
}

fn parcel_wkt(k: u32, shift_deg: f64) -> String {
    let (col, row) = (f64::from(k % PARCEL_COLUMNS), f64::from(k / PARCEL_COLUMNS));
    square_wkt(10.2 + 0.005 * col + shift_deg, 45.2 + 0.008 * row, PARCEL_SIDE_DEG)
}

/// The geodatabase of table 1 and 2 (`parcels`, `sites`), the hill, and a
/// scene reading both tables with the parcels drawn as its colour layer.
fn town(dir: &Path) -> anyhow::Result<(PathBuf, GdbEditor)> {
    let mut editor = GdbEditor::start(&dir.join("town.gdb"))?;
    let parcels = (0..PARCEL_COLUMNS * PARCEL_ROWS).map(|k| (parcel_wkt(k, 0.0), json!({"name": format!("p{k:04}")})));
    let sites =
        (0..50).map(|k| (format!("POINT ({} 45.3)", 10.2 + 0.004 * f64::from(k)), json!({"name": format!("s{k}")})));
    editor.create(&[
        LayerSpec { name: "parcels", geom: "polygon", fields: &["name"], features: parcels.collect() },
        LayerSpec { name: "sites", geom: "point", fields: &["name"], features: sites.collect() },
    ])?;
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill)?;
    let manifest = fixtures::write_manifest(
        dir,
        "[scene]\nname = \"town\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n\
         [[source]]\nid = \"parcels\"\nkind = \"ogr\"\npath = \"town.gdb\"\nlayer = \"parcels\"\n\n\
         [[source]]\nid = \"sites\"\nkind = \"ogr\"\npath = \"town.gdb\"\nlayer = \"sites\"\n\n\
         [[source]]\nid = \"drawn\"\nkind = \"rasterize\"\ninputs = [\"parcels\"]\n\n\
         [layers]\nheight = \"dem\"\ncolor = \"drawn\"\n",
    )?;
    Ok((manifest, editor))
}

/// The tile keys of the scene's grid at `level` over `extent` (grid CRS).
fn keys_over(grid: &pb::GridInfo, extent: &pb::Extent, level: u32) -> Vec<(u32, u32, u32)> {
    let g = grid.extent.unwrap_or_default();
    let (cols, rows) = (grid.level0_columns << level, grid.level0_rows << level);
    let (w, h) = ((g.max_x - g.min_x) / f64::from(cols), (g.max_y - g.min_y) / f64::from(rows));
    let column = |x: f64| ((x - g.min_x) / w).floor().clamp(0.0, f64::from(cols - 1)) as u32;
    let row = |y: f64| ((g.max_y - y) / h).floor().clamp(0.0, f64::from(rows - 1)) as u32;
    let mut keys = Vec::new();
    for y in row(extent.max_y)..=row(extent.min_y) {
        for x in column(extent.min_x)..=column(extent.max_x) {
            keys.push((level, x, y));
        }
    }
    keys
}

/// Waits for the generation after `generation` and for the editor's
/// reply to its save, failing at once when the save fails.
async fn saved_and_published(
    channel: &Channel,
    generation: u64,
    saving: tokio::task::JoinHandle<anyhow::Result<serde_json::Value>>,
) -> anyhow::Result<(pb::SceneState, serde_json::Value)> {
    let saved = async { saving.await.context("the editor's thread")?.context("the editor's save") };
    tokio::try_join!(wait_for(channel.clone(), generation + 1), saved)
}

/// Table 1's measures, and the editor back.
struct Edits {
    from_save: Vec<f64>,
    from_send: Vec<f64>,
    /// Cached tiles rebuilt or dropped by each edit's generation.
    rebuilt: Vec<f64>,
    /// Edits whose generation came with the parcels source in error (a
    /// read refused, the last good version kept).
    refused: usize,
    editor: GdbEditor,
}

/// Milliseconds from each save closing to its generation, and from each
/// command being sent; one feature's attribute and geometry per edit.
async fn one_feature_edits(channel: &Channel, editor: GdbEditor, edits: usize) -> anyhow::Result<Edits> {
    let events = edit::Events::follow(channel.clone()).await?;
    let editor = std::sync::Arc::new(std::sync::Mutex::new(editor));
    let (mut from_save, mut from_send, mut rebuilt, mut refused) = (Vec::new(), Vec::new(), Vec::new(), 0);
    for i in 0..edits {
        // Each round starts idle.
        tokio::time::sleep(Duration::from_millis(300)).await;
        let generation = state(channel).await?.generation;
        let k = (i as u32 * 37) % (PARCEL_COLUMNS * PARCEL_ROWS);
        let shift = if i % 2 == 0 { 0.0005 } else { 0.0 };
        let wkt = parcel_wkt(k, shift);
        let gdb = std::sync::Arc::clone(&editor);
        let sent = wall();
        let saving = tokio::task::spawn_blocking(move || {
            gdb.lock().map_err(|_| anyhow::anyhow!("the editor lock"))?.update(
                "parcels",
                u64::from(k) + 1,
                &json!({"name": format!("e{i:04}")}),
                Some(&wkt),
            )
        });
        let (published, reply) = saved_and_published(channel, generation, saving).await?;
        let seen = wall();
        if published.sources.iter().any(|s| s.id == "parcels" && !s.error.is_empty()) {
            refused += 1;
        }
        let saved = reply["t"].as_f64().with_context(|| format!("no t in the editor's reply {reply}"))?;
        from_save.push((seen - saved) * 1e3);
        from_send.push((seen - sent) * 1e3);
        if let Ok(g) = events.generation(published.generation).await {
            rebuilt.push((g.tiles_rebuilt + g.tiles_invalidated) as f64);
        }
    }
    let editor = std::sync::Arc::try_unwrap(editor)
        .map_err(|_| anyhow::anyhow!("the editor is still shared"))?
        .into_inner()
        .map_err(|_| anyhow::anyhow!("the editor lock"))?;
    Ok(Edits { from_save, from_send, rebuilt, refused, editor })
}

/// One bulk run: save to generation ms, tiles rebuilt, dropped, carried
/// over, and dirty extents of its generation.
struct Bulk {
    ms: f64,
    rebuilt: u64,
    invalidated: u64,
    carried: u64,
    extents: usize,
}

/// Moves the first `count` polygons of `layer` east by `dx` degrees in one
/// transaction and one save, as the editor's `move` would: that command
/// walks a geometry's rings one level deep, and OpenFileGDB gives polygon
/// layers as MULTIPOLYGONs, so it saves the table again unchanged (GDAL
/// 3.6.2). The reply is the editor's: `moved` and `t`, the save's close.
fn move_polygons(gdb: &Path, layer: &str, count: usize, dx: f64) -> anyhow::Result<serde_json::Value> {
    let script = r#"
import json, sys, time
from osgeo import gdal, ogr
gdal.UseExceptions()
path, name, count, dx = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
def shift(g):
    if g.GetGeometryCount():
        for k in range(g.GetGeometryCount()):
            shift(g.GetGeometryRef(k))
    else:
        for i in range(g.GetPointCount()):
            g.SetPoint_2D(i, g.GetX(i) + dx, g.GetY(i))
ds = gdal.OpenEx(path, gdal.OF_VECTOR | gdal.OF_UPDATE, allowed_drivers=["OpenFileGDB"])
layer = ds.GetLayerByName(name)
layer.StartTransaction()
moved = [f for _, f in zip(range(count), layer)]
for f in moved:
    g = f.GetGeometryRef()
    shift(g)
    f.SetGeometry(g)
    layer.SetFeature(f)
layer.CommitTransaction()
ds = None
print(json.dumps({"moved": len(moved), "t": time.time()}))
"#;
    let out = std::process::Command::new("/usr/bin/python3")
        .args(["-c", script])
        .arg(gdb)
        .args([layer, &count.to_string(), &dx.to_string()])
        .output()
        .context("cannot start GDAL's python")?;
    anyhow::ensure!(
        out.status.success(),
        "GDAL could not move the features of {}: {}",
        gdb.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).context("the move's reply")
}

async fn bulk_edits(channel: &Channel, gdb: &Path, runs: usize) -> anyhow::Result<Vec<Bulk>> {
    let events = edit::Events::follow(channel.clone()).await?;
    let mut out = Vec::new();
    for i in 0..runs {
        tokio::time::sleep(Duration::from_millis(300)).await;
        let generation = state(channel).await?.generation;
        let dx = if i % 2 == 0 { 0.0005 } else { -0.0005 };
        let count = (PARCEL_COLUMNS * PARCEL_ROWS) as usize;
        let path = gdb.to_path_buf();
        let saving = tokio::task::spawn_blocking(move || move_polygons(&path, "parcels", count, dx));
        let (published, reply) = saved_and_published(channel, generation, saving).await?;
        let seen = wall();
        anyhow::ensure!(reply["moved"].as_u64() == Some(count as u64), "the editor moved {}", reply["moved"]);
        let saved = reply["t"].as_f64().with_context(|| format!("no t in the editor's reply {reply}"))?;
        let g = events.generation(published.generation).await?;
        out.push(Bulk {
            ms: (seen - saved) * 1e3,
            rebuilt: g.tiles_rebuilt,
            invalidated: g.tiles_invalidated,
            carried: g.tiles_carried_over,
            extents: g.dirty.iter().map(|d| d.extents.len()).sum(),
        });
    }
    Ok(out)
}

async fn geodatabase_tables(edits: usize) -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let (manifest, editor) = town(dir.path())?;
    let daemon = Reliefd::start(&manifest, &[])?;
    if let Err(e) = geodatabase_measures(&daemon, editor, &dir.path().join("town.gdb"), edits).await {
        let log = daemon.log();
        let tail = log[log.len().saturating_sub(40)..].join("\n");
        return Err(e.context(format!("reliefd's log ends:\n{tail}")));
    }
    // A read caught mid-save is refused with a warning and read again: counted, not a failure.
    let log = daemon.stop(&[KEPT_LAST_GOOD])?;
    let kept = log.iter().filter(|l| l.contains(KEPT_LAST_GOOD)).count();
    println!("\nreliefd's warnings of a refused read (\"{KEPT_LAST_GOOD}\") over tables 1 and 2: {kept}");
    Ok(())
}

async fn geodatabase_measures(daemon: &Reliefd, editor: GdbEditor, gdb: &Path, edits: usize) -> anyhow::Result<()> {
    let channel = daemon.channel().await?;
    // A viewer's tiles cached: the drawn parcels at levels 9..=11 over them.
    let first = state(&channel).await?;
    let grid = first.grid.clone().unwrap_or_default();
    let extent = pb::Extent { min_x: 10.2, min_y: 45.2, max_x: 10.4, max_y: 45.4 };
    for level in 9..=11 {
        for key in keys_over(&grid, &extent, level) {
            tiles::get(channel.clone(), "drawn", key).await?;
        }
    }
    let parcels = first.sources.iter().find(|s| s.id == "parcels").context("no parcels source")?;
    anyhow::ensure!(parcels.details.get("features").map(String::as_str) == Some("1000"), "{parcels:#?}");

    let editor = if edits > 0 && wanted("RELIEF_BENCH_ONLY", "edit") {
        header(
            "A .gdb edit of one feature (attribute and geometry) to a new generation, ms (OpenFileGDB save, 1,000 parcels + a second table)",
        );
        let Edits { from_save, from_send, rebuilt, refused, editor } =
            one_feature_edits(&channel, editor, edits).await?;
        println!("| clock | edits | p50 | p95 | min | max | goal |\n|---|---|---|---|---|---|---|");
        let (p50, p95, min, max) = spread(from_save);
        let goal = if p50 < 100.0 { "p50 < 100 ms: met" } else { "p50 < 100 ms: not met" };
        println!(
            "| save closed (editor's t) to WaitForGeneration | {edits} | {p50:.0} | {p95:.0} | {min:.0} | {max:.0} | {goal} |"
        );
        let (p50, p95, min, max) = spread(from_send);
        println!("| command sent to WaitForGeneration | {edits} | {p50:.0} | {p95:.0} | {min:.0} | {max:.0} | |");
        println!("\ncached tiles rebuilt or dropped per generation (median): {:.0}", median(rebuilt));
        println!("edits whose generation came with the parcels refused (last good version kept): {refused} of {edits}");
        editor
    } else {
        editor
    };

    if wanted("RELIEF_BENCH_ONLY", "bulk") {
        header(
            "A .gdb edit of 1,000 features in one transaction and one save (every parcel moved 0.0005 degrees) to a new generation, ms",
        );
        drop(editor);
        let runs = bulk_edits(&channel, gdb, 5).await?;
        let ms: Vec<f64> = runs.iter().map(|r| r.ms).collect();
        let (p50, _, min, max) = spread(ms);
        println!("| runs | p50 | min | max |\n|---|---|---|---|\n| {} | {p50:.0} | {min:.0} | {max:.0} |", runs.len());
        println!(
            "\n| run | save to generation ms | tiles rebuilt | tiles dropped | tiles carried over | dirty extents |\n|---|---|---|---|---|---|"
        );
        for (k, r) in runs.iter().enumerate() {
            println!("| {} | {:.0} | {} | {} | {} | {} |", k + 1, r.ms, r.rebuilt, r.invalidated, r.carried, r.extents);
        }
    }
    Ok(())
}

/// One building: centre (lon, lat), east-west and north-south size and
/// height, metres.
struct Building {
    lon: f64,
    lat: f64,
    width_m: f64,
    depth_m: f64,
    height_m: f64,
}

/// Degrees per metre east and north at the district.
fn per_m() -> (f64, f64) {
    let r = relief_source::geodesy::MEAN_RADIUS_M.to_radians();
    (1.0 / (r * DISTRICT.1.to_radians().cos()), 1.0 / r)
}

/// 2,000 boxes, one per 50 m cell, 10-30 m wide and deep, 6-30 m high.
fn buildings() -> Vec<Building> {
    let mut rng = relief_examples::Lcg(38);
    let (dx, dy) = per_m();
    let mut out = Vec::new();
    for row in 0..BUILDING_ROWS {
        for col in 0..BUILDING_COLUMNS {
            let (e, n) = ((f64::from(col) + 0.5) * CELL_M, (f64::from(row) + 0.5) * CELL_M);
            let (e, n) = (e + rng.range(-5.0, 5.0), n + rng.range(-5.0, 5.0));
            out.push(Building {
                lon: DISTRICT.0 + e * dx,
                lat: DISTRICT.1 + n * dy,
                width_m: rng.range(10.0, 30.0),
                depth_m: rng.range(10.0, 30.0),
                height_m: rng.range(6.0, 30.0),
            });
        }
    }
    out
}

impl Building {
    /// The footprint's corners (lon, lat), counter-clockwise from south-west.
    fn corners(&self) -> [(f64, f64); 4] {
        let (dx, dy) = per_m();
        let (w, d) = (self.width_m / 2.0 * dx, self.depth_m / 2.0 * dy);
        [
            (self.lon - w, self.lat - d),
            (self.lon + w, self.lat - d),
            (self.lon + w, self.lat + d),
            (self.lon - w, self.lat + d),
        ]
    }

    /// As ArcGIS stores it: walls a TIN, the roof a polygon, heights
    /// absolute from the hill's lowest corner.
    fn multipatch_wkt(&self) -> String {
        let corners = self.corners();
        let ground = corners.iter().map(|&(x, y)| fixtures::hill(x, y)).fold(f64::INFINITY, f64::min);
        let top = ground + self.height_m;
        let p = |(x, y): (f64, f64), z: f64| format!("{x} {y} {z}");
        let mut walls = Vec::new();
        for k in 0..4 {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            walls.push(format!("(({},{},{},{}))", p(a, ground), p(b, ground), p(b, top), p(a, ground)));
            walls.push(format!("(({},{},{},{}))", p(a, ground), p(b, top), p(a, top), p(a, ground)));
        }
        let roof: Vec<String> = corners.iter().chain(&corners[..1]).map(|&c| p(c, top)).collect();
        format!("GEOMETRYCOLLECTION Z (TIN Z ({}),MULTIPOLYGON Z ((({}))))", walls.join(","), roof.join(","))
    }

    fn footprint_geojson(&self) -> String {
        let ring: Vec<String> =
            self.corners().iter().chain(&self.corners()[..1]).map(|(x, y)| format!("[{x}, {y}]")).collect();
        format!(
            r#"{{"type": "Feature", "properties": {{"height": {:.2}}}, "geometry": {{"type": "Polygon", "coordinates": [[{}]]}}}}"#,
            self.height_m,
            ring.join(", ")
        )
    }
}

/// A scene of the hill with `sources` (one of them `buildings`), lit.
fn building_scene(dir: &Path, sources: &str) -> anyhow::Result<PathBuf> {
    fixtures::write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"district\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n{sources}\n\
             [layers]\nheight = \"dem\"\nbuildings = \"buildings\"\n\n[effects]\nlighting = {{}}\n"
        ),
    )
}

/// What one building scene cost.
struct SceneCost {
    load_ms: f64,
    tiles: usize,
    tiles_cold_ms: f64,
    tiles_cached_ms: f64,
    triangles: usize,
    parts: usize,
    first_frame_ms: f64,
    steady_ms: f64,
    buildings_drawn: u32,
}

async fn measure_scene(manifest: &Path) -> anyhow::Result<SceneCost> {
    let started = Instant::now();
    let daemon = Reliefd::start(manifest, &[])?;
    let channel = daemon.channel().await?;
    let first = state(&channel).await?;
    let load_ms = started.elapsed().as_secs_f64() * 1e3;
    let source = first.sources.iter().find(|s| s.id == "buildings").context("no buildings source")?;
    anyhow::ensure!(source.error.is_empty(), "the buildings did not load: {source:#?}");
    // The level-14 mesh tiles over the district.
    let (dx, dy) = per_m();
    let extent = pb::Extent {
        min_x: DISTRICT.0,
        min_y: DISTRICT.1,
        max_x: DISTRICT.0 + f64::from(BUILDING_COLUMNS) * CELL_M * dx,
        max_y: DISTRICT.1 + f64::from(BUILDING_ROWS) * CELL_M * dy,
    };
    let keys = keys_over(&first.grid.unwrap_or_default(), &extent, MESH_LEVEL);
    let (mut cold, mut cached, mut triangles, mut parts) = (0.0, 0.0, 0, 0);
    for pass in 0..2 {
        for &key in &keys {
            let t = Instant::now();
            let tile = tiles::get(channel.clone(), "buildings", key).await?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            if pass == 0 {
                cold += ms;
                if let Some(pb::get_tile_response::Payload::Mesh(m)) = &tile.payload {
                    triangles += m.indices_u32_le.len() / 12;
                    parts += m.parts.len();
                }
            } else {
                cached += ms;
            }
        }
    }
    // 600 m over the ground south of the district, looking north 30 degrees down.
    let (lon, lat) = (DISTRICT.0 + 0.5 * f64::from(BUILDING_COLUMNS) * CELL_M * dx, DISTRICT.1 - 300.0 * dy);
    let camera = scenes::camera(lon, lat, fixtures::hill(lon, lat) + 600.0, 0.0, -30.0);
    let t = Instant::now();
    let frame = scenes::render_rgba(&channel, camera, (1280, 720)).await?;
    let first_frame_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut steady = Vec::new();
    for _ in 0..5 {
        let t = Instant::now();
        scenes::render_rgba(&channel, camera, (1280, 720)).await?;
        steady.push(t.elapsed().as_secs_f64() * 1e3);
    }
    daemon.stop(&[])?;
    Ok(SceneCost {
        load_ms,
        tiles: keys.len(),
        tiles_cold_ms: cold,
        tiles_cached_ms: cached,
        triangles,
        parts,
        first_frame_ms,
        steady_ms: median(steady),
        buildings_drawn: frame.drawn.map_or(0, |d| d.buildings),
    })
}

async fn multipatch_table() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let all = buildings();
    let multipatch = {
        let scene = dir.path().join("multipatch");
        std::fs::create_dir_all(&scene)?;
        fixtures::write_dem(&scene.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill)?;
        let patches: Vec<(String, &str)> = all.iter().map(|b| (b.multipatch_wkt(), "house")).collect();
        arcgis::write_multipatch_shapefile(&scene.join("patches.shp"), &patches)?;
        let manifest =
            building_scene(&scene, "[[source]]\nid = \"buildings\"\nkind = \"shapefile\"\npath = \"patches.shp\"\n")?;
        measure_scene(&manifest).await?
    };
    let extruded = {
        let scene = dir.path().join("extruded");
        std::fs::create_dir_all(&scene)?;
        fixtures::write_dem(&scene.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill)?;
        let footprints: Vec<String> = all.iter().map(Building::footprint_geojson).collect();
        relief_tests::vectors::shapefile(
            &scene,
            "footprints",
            &format!(r#"{{"type": "FeatureCollection", "features": [{}]}}"#, footprints.join(",\n")),
        )?;
        let manifest = building_scene(
            &scene,
            "[[source]]\nid = \"footprints\"\nkind = \"shapefile\"\npath = \"footprints.shp\"\n\n\
             [[source]]\nid = \"buildings\"\nkind = \"extrude\"\ninputs = [\"footprints\", \"dem\"]\nheight_attribute = \"height\"\n",
        )?;
        measure_scene(&manifest).await?
    };

    header(&format!(
        "2,000 buildings: a MultiPatch shapefile against the same footprints extruded (level-{MESH_LEVEL} mesh tiles, 1280 x 720 frames lit, 600 m up, 30 degrees down)"
    ));
    println!("| measure | MultiPatch | extruded | MultiPatch / extruded |\n|---|---|---|---|");
    let row = |name: &str, a: f64, b: f64, digits: usize| {
        println!("| {name} | {a:.digits$} | {b:.digits$} | {:.2}x |", a / b);
    };
    let (m, e) = (&multipatch, &extruded);
    row("scene load: spawn to the first GetState, ms", m.load_ms, e.load_ms, 0);
    row(&format!("GetTile, {} mesh tiles, first (generated), ms summed", m.tiles), m.tiles_cold_ms, e.tiles_cold_ms, 1);
    row("GetTile, the same tiles again (cached), ms summed", m.tiles_cached_ms, e.tiles_cached_ms, 1);
    row("triangles in those tiles", m.triangles as f64, e.triangles as f64, 0);
    row("mesh parts (features) in those tiles", m.parts as f64, e.parts as f64, 0);
    row("first frame, ms", m.first_frame_ms, e.first_frame_ms, 0);
    row("steady frame (median of 5), ms", m.steady_ms, e.steady_ms, 0);
    row("buildings drawn in the frame", f64::from(m.buildings_drawn), f64::from(e.buildings_drawn), 0);
    Ok(())
}

async fn run() -> anyhow::Result<()> {
    if !arcgis::available("the ArcGIS benchmark") {
        return Ok(());
    }
    let gpu = Path::new("/dev/nvidia0").exists() || Path::new("/dev/dri").exists();
    println!(
        "machine: {}; renderer: {}",
        relief_tests::machine(),
        if gpu { "a GPU (wgpu's first adapter)" } else { "Mesa lavapipe (no GPU here)" }
    );
    let edits = env_u64("RELIEF_BENCH_EDITS", 25) as usize;
    if wanted("RELIEF_BENCH_ONLY", "edit") || wanted("RELIEF_BENCH_ONLY", "bulk") {
        geodatabase_tables(edits).await?;
    }
    if wanted("RELIEF_BENCH_ONLY", "multipatch") {
        multipatch_table().await?;
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?.block_on(run())
}
