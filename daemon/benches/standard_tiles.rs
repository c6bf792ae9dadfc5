//! Quantized-mesh terrain tiles against pydelatin + quantized-mesh-encoder.
//! Prints a table; never asserts a time.
//!
//! Real terrain: the committed SRTM crop (`examples/data`, 3 arc-second
//! samples, the Maritime Alps to Provence) as a geodetic scene, its height
//! tiles read through relief's own tile store at the terrain layer's finest
//! level and the one above (as `/tiles/terrain` reads them), with the
//! samples outside the data set to 0 m as the daemon does. Each error is
//! used at both levels (the daemon doubles it per level up; here the knob
//! is what is compared).
//!
//! relief: `Rtin::new` (nodata fill and the split errors), `mesh` and
//! `encode_quantized_mesh` with `octvertexnormals`, one thread, per tile.
//! The peer: the same filled heights (`Rtin::heights`, as f32) through
//! `pydelatin.Delatin` and `quantized_mesh_encoder.encode` with its
//! `VertexNormalsExtension`, in a venv the bench makes under
//! `target/standard-tiles-peer` (pip install pydelatin
//! quantized-mesh-encoder numpy); without PyPI the table has relief alone.
//! Times are the median of 3 passes over every tile; sizes and triangles
//! are means per tile, the max error the largest over the tiles (relief:
//! `mesh_stats`, measured over every sample; pydelatin: its own `error`).
//!
//! `cargo bench -p relief-daemon --bench standard_tiles`

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::Context;
use common::median;
use relief_daemon::picture::DEFAULT_TERRAIN_MESH_ERROR_M;
use relief_daemon::standard::TerrainLayer;
use relief_source::{HeightTile, Payload, SampleKind, TileGrid, TileKey};
use relief_standard_tiles::{EdgeVertices, EncodeOptions, Rtin, encode_quantized_mesh, mesh_stats};

/// Tiles timed, at most: the whole level above the finest, then the
/// finest level's first tiles.
const MAX_TILES: usize = 32;
/// Passes over every tile per error (the median is printed).
const PASSES: usize = 3;
const PEER_SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/standard_tiles_peer.py");
const PEER_PACKAGES: [&str; 3] = ["pydelatin", "quantized-mesh-encoder", "numpy"];

/// One error's results on one side, per tile.
#[derive(Debug, Clone, Copy)]
struct Side {
    tiles_per_s: f64,
    bytes: f64,
    gzip_bytes: f64,
    triangles: f64,
    max_error_m: f64,
}

/// The tiles of `level` that the data's extent overlaps (rows from the north).
fn covering(grid: &TileGrid, level: u8, data: &relief_source::Extent) -> Vec<TileKey> {
    let e = grid.extent();
    let (w, h) = grid.tile_span(level);
    let (cols, rows) = grid.tiles_at(level);
    let first = |v: f64, span: f64, count: u32| ((v / span).floor().max(0.0) as u32).min(count - 1);
    let last = |v: f64, span: f64, count: u32| (((v / span).ceil() - 1.0).max(0.0) as u32).min(count - 1);
    let (x0, x1) = (first(data.min_x - e.min_x, w, cols), last(data.max_x - e.min_x, w, cols));
    let (y0, y1) = (first(e.max_y - data.max_y, h, rows), last(e.max_y - data.min_y, h, rows));
    (y0..=y1).flat_map(|y| (x0..=x1).map(move |x| TileKey::new(level, x, y))).collect()
}

/// The height tile as the daemon meshes it: samples without data outside
/// the layer's data are 0 m (holes inside are filled by `Rtin::new`).
fn as_served(grid: &TileGrid, key: TileKey, tile: &HeightTile, data: &relief_source::Extent) -> HeightTile {
    let mut tile = tile.clone();
    let lattice = grid.lattice(key, SampleKind::Corner);
    for j in 0..tile.size {
        for i in 0..tile.size {
            let h = &mut tile.heights[j * tile.size + i];
            if h.is_nan() && !data.contains(lattice.x(i), lattice.y(j)) {
                *h = 0.0;
            }
        }
    }
    tile
}

fn relief_side(grid: &TileGrid, tiles: &[(TileKey, HeightTile)], error_m: f64) -> anyhow::Result<Side> {
    let options = EncodeOptions { octvertexnormals: true, watermask: None };
    let mut passes = Vec::new();
    for _ in 0..PASSES {
        let start = Instant::now();
        for (key, tile) in tiles {
            let mesh = Rtin::new(tile)?.mesh(error_m);
            std::hint::black_box(encode_quantized_mesh(&mesh, grid, *key, options)?);
        }
        passes.push(start.elapsed().as_secs_f64());
    }
    let n = tiles.len() as f64;
    let mut side =
        Side { tiles_per_s: n / median(passes), bytes: 0.0, gzip_bytes: 0.0, triangles: 0.0, max_error_m: 0.0 };
    for (key, tile) in tiles {
        let s = mesh_stats(tile, grid, *key, error_m, EdgeVertices::AsNeeded)?;
        side.bytes += s.bytes as f64 / n;
        side.gzip_bytes += s.gzip_bytes as f64 / n;
        side.triangles += s.triangles as f64 / n;
        side.max_error_m = side.max_error_m.max(s.max_error_m);
    }
    Ok(side)
}

/// The peer's venv's python, made (and pydelatin and quantized-mesh-encoder
/// installed) on first use.
fn peer_python(target: &Path) -> anyhow::Result<PathBuf> {
    let venv = target.join("standard-tiles-peer");
    let python = venv.join("bin/python");
    let ready = || {
        Command::new(&python)
            .args(["-c", "import pydelatin, quantized_mesh_encoder, numpy"])
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if ready() {
        return Ok(python);
    }
    let made =
        Command::new("python3").arg("-m").arg("venv").arg(&venv).output().context("cannot run python3 -m venv")?;
    anyhow::ensure!(made.status.success(), "python3 -m venv failed: {}", String::from_utf8_lossy(&made.stderr).trim());
    let pip = Command::new(&python)
        .args(["-m", "pip", "install", "--quiet", "--disable-pip-version-check"])
        .args(PEER_PACKAGES)
        .output()
        .context("cannot run pip")?;
    anyhow::ensure!(
        pip.status.success(),
        "pip install {} failed: {}",
        PEER_PACKAGES.join(" "),
        String::from_utf8_lossy(&pip.stderr).lines().last().unwrap_or("").trim()
    );
    anyhow::ensure!(ready(), "the venv {} cannot import pydelatin and quantized_mesh_encoder", venv.display());
    Ok(python)
}

/// Writes the tiles' filled heights and bounds under `dir` and runs the
/// peer over them: its results by error.
fn peer_side(
    python: &Path,
    dir: &Path,
    grid: &TileGrid,
    tiles: &[(TileKey, HeightTile)],
    errors_m: &[f64],
) -> anyhow::Result<Vec<Side>> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut listed = Vec::new();
    for (key, tile) in tiles {
        let rtin = Rtin::new(tile)?;
        let bytes: Vec<u8> = rtin.heights().iter().flat_map(|&h| (h as f32).to_le_bytes()).collect();
        let path = dir.join(format!("{}-{}-{}.f32", key.level, key.x, key.y));
        std::fs::write(&path, bytes).with_context(|| format!("cannot write {}", path.display()))?;
        let e = grid.tile_extent(*key);
        listed.push(serde_json::json!({"path": path, "bounds": [e.min_x, e.min_y, e.max_x, e.max_y]}));
    }
    let size = tiles.first().map_or(0, |(_, t)| t.size);
    let spec = serde_json::json!({"size": size, "errors_m": errors_m, "passes": PASSES, "tiles": listed});
    let spec_path = dir.join("tiles.json");
    std::fs::write(&spec_path, serde_json::to_vec(&spec)?)?;
    let out = Command::new(python).arg(PEER_SCRIPT).arg(&spec_path).output().context("cannot run the peer script")?;
    anyhow::ensure!(out.status.success(), "the peer script failed: {}", String::from_utf8_lossy(&out.stderr).trim());
    let mut sides = Vec::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let v: serde_json::Value = serde_json::from_str(line).with_context(|| format!("peer line: {line}"))?;
        let number = |name: &str| v[name].as_f64().with_context(|| format!("peer line without {name}: {line}"));
        let seconds: Vec<f64> = v["seconds"]
            .as_array()
            .map(|a| a.iter().filter_map(serde_json::Value::as_f64).collect())
            .unwrap_or_default();
        let n = number("tiles")?;
        sides.push(Side {
            tiles_per_s: n / median(seconds),
            bytes: number("bytes")? / n,
            gzip_bytes: number("gzip_bytes")? / n,
            triangles: number("triangles")? / n,
            max_error_m: number("max_error_m")?,
        });
    }
    anyhow::ensure!(sides.len() == errors_m.len(), "the peer answered {} of {} errors", sides.len(), errors_m.len());
    Ok(sides)
}

fn main() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = relief_examples::write_manifest(
        dir.path(),
        &format!(
            "[scene]\nname = \"standard-tiles-bench\"\ngrid = \"geodetic\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"{}\"\n\n[layers]\nheight = \"dem\"\n",
            relief_examples::ALPS_DEM
        ),
    )?;
    let scene = common::load(&manifest, 2)?;
    let snap = scene.snapshot();
    let grid = &snap.grid;
    let layer = TerrainLayer::of(&snap, 0).map_err(|e| anyhow::anyhow!("the bench scene has no terrain: {e}"))?;
    let quality = snap.manifest.quality;
    let levels = [layer.max_zoom.saturating_sub(1), layer.max_zoom];
    let keys: Vec<TileKey> = levels.iter().flat_map(|&z| covering(grid, z, &layer.data)).take(MAX_TILES).collect();
    let mut tiles = Vec::new();
    for key in keys {
        let stored = scene.store.tile(&snap, layer.height, key, &quality)?;
        let Payload::Height(tile) = &*stored.payload else { anyhow::bail!("the height layer gave a non-height tile") };
        tiles.push((key, as_served(grid, key, tile, &layer.data)));
    }
    let per_level = |z: u8| tiles.iter().filter(|(k, _)| k.level == z).count();

    let mut errors_m = vec![0.5, DEFAULT_TERRAIN_MESH_ERROR_M, 2.0, 4.0, 8.0];
    errors_m.sort_by(f64::total_cmp);
    errors_m.dedup();
    let target = relief_tests::workspace_root().join("target");
    let peer = peer_python(&target)
        .and_then(|python| peer_side(&python, &target.join("standard-tiles-bench"), grid, &tiles, &errors_m));

    println!("\n## Quantized-mesh terrain: relief (RTIN) against pydelatin + quantized-mesh-encoder");
    println!("machine: {}", relief_tests::machine());
    println!(
        "data: examples/data/maritime-alps-srtm3.tif (SRTM 3\"), geodetic; {} tiles of {} x {} samples: {} of level {}, {} of level {} (the finest); one thread, median of {PASSES} passes; octvertexnormals on both sides",
        tiles.len(),
        tiles.first().map_or(0, |(_, t)| t.size),
        tiles.first().map_or(0, |(_, t)| t.size),
        per_level(levels[0]),
        levels[0],
        per_level(levels[1]),
        levels[1],
    );
    if let Err(e) = &peer {
        println!("peer: not run ({e:#}); relief alone");
    }
    println!(
        "| error m | relief tiles/s | peer tiles/s | relief / peer | relief bytes/tile (gzip) | peer bytes/tile (gzip) | relief / peer bytes | relief triangles/tile | peer triangles/tile | relief max error m | peer max error m |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for (k, &error_m) in errors_m.iter().enumerate() {
        let r = relief_side(grid, &tiles, error_m)?;
        let default = if error_m == DEFAULT_TERRAIN_MESH_ERROR_M { " (default)" } else { "" };
        let p = peer.as_ref().ok().map(|sides| sides[k]);
        let or_dash = |f: &dyn Fn(Side) -> String| p.map_or("-".to_owned(), f);
        println!(
            "| {error_m}{default} | {:.0} | {} | {} | {:.0} ({:.0}) | {} | {} | {:.0} | {} | {:.3} | {} |",
            r.tiles_per_s,
            or_dash(&|p| format!("{:.0}", p.tiles_per_s)),
            or_dash(&|p| format!("{:.2}x", r.tiles_per_s / p.tiles_per_s)),
            r.bytes,
            r.gzip_bytes,
            or_dash(&|p| format!("{:.0} ({:.0})", p.bytes, p.gzip_bytes)),
            or_dash(&|p| format!("{:.2}x ({:.2}x)", r.bytes / p.bytes, r.gzip_bytes / p.gzip_bytes)),
            r.triangles,
            or_dash(&|p| format!("{:.0}", p.triangles)),
            r.max_error_m,
            or_dash(&|p| format!("{:.3}", p.max_error_m)),
        );
    }
    Ok(())
}
