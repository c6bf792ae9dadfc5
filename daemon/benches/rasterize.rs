//! Vector rasterizer benchmark. Prints tables; never asserts a time.
//!
//! Natural Earth's countries (`../shared/data/shp`) drawn into every tile
//! of levels 0..=N (RELIEF_BENCH_MAX_LEVEL, default 6) through reliefd's
//! tile store, and the same tiles burnt by GDAL's rasterizer (the library
//! call behind `gdal_rasterize`, in-process, one MEM raster per tile of the
//! same texel lattice) in the same run. Then the `antialias` knob: time
//! against coverage error, taking 8 x 8 sub-samples as the reference.

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

mod common;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use gdal::vector::LayerAccess;
use relief_source::{Payload, Quality, SampleKind, TileGrid, TileKey};

fn keys(grid: &TileGrid, max_level: u8) -> Vec<TileKey> {
    (0..=max_level).flat_map(|l| grid.keys_overlapping(l, &grid.extent())).collect()
}

fn relief(dir: &Path, countries: &Path, antialias: u32, keys: &[TileKey]) -> anyhow::Result<(f64, Vec<Vec<u8>>)> {
    let manifest = relief_examples::write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"countries\"\n\n[[source]]\nid = \"countries\"\nkind = \"shapefile\"\npath = \"{}\"\n\n[[source]]\nid = \"drawn\"\nkind = \"rasterize\"\ninputs = [\"countries\"]\nstroke = \"none\"\nfill = \"#ff0000ff\"\nantialias = {antialias}\n\n[layers]\ncolor = \"drawn\"\n\n[cache]\nmemory_mb = 4096\n",
            countries.display()
        ),
    )?;
    let scene = common::load(&manifest, 2)?;
    let snap = scene.snapshot();
    let index = snap.index_of("drawn").context("the bench scene has its rasterizer")?;
    let requests: Vec<(usize, TileKey)> = keys.iter().map(|k| (index, *k)).collect();
    let started = Instant::now();
    let built = scene.store.build(&snap, &requests, &Quality::default());
    let seconds = started.elapsed().as_secs_f64();
    let mut alphas = Vec::with_capacity(built.len());
    for tile in built {
        match tile?.payload.as_ref() {
            Payload::Color(c) => alphas.push(c.rgba.chunks(4).map(|p| p[3]).collect()),
            other => anyhow::bail!("a rasterizer gave a {} tile", other.kind()),
        }
    }
    Ok((seconds, alphas))
}

fn gdal(grid: &TileGrid, countries: &Path, keys: &[TileKey]) -> anyhow::Result<f64> {
    let source = gdal::Dataset::open(countries)?;
    let mut layer = source.layer(0)?;
    let geometries: Vec<gdal::vector::Geometry> = layer.features().filter_map(|f| f.geometry().cloned()).collect();
    let burn = vec![255.0; geometries.len()];
    let driver = gdal::DriverManager::get_driver_by_name("MEM")?;
    let started = Instant::now();
    for key in keys {
        let l = grid.lattice(*key, SampleKind::TexelWithBorder);
        let mut ds = driver.create_with_band_type::<u8, _>("", l.cols, l.rows, 1)?;
        ds.set_geo_transform(&[l.x(0) - l.step_x / 2.0, l.step_x, 0.0, l.y(0) + l.step_y / 2.0, 0.0, -l.step_y])?;
        gdal::raster::rasterize(&mut ds, &[1], &geometries, &burn, None)?;
    }
    Ok(started.elapsed().as_secs_f64())
}

fn main() -> anyhow::Result<()> {
    let max_level: u8 = std::env::var("RELIEF_BENCH_MAX_LEVEL").ok().and_then(|v| v.parse().ok()).unwrap_or(6);
    let data: PathBuf = std::env::var_os("RELIEF_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
    let countries = data.join("shp/naturalearth_lowres.shp");
    if !countries.exists() {
        println!("skipping: no Natural Earth countries at {}", countries.display());
        return Ok(());
    }
    let dir = tempfile::tempdir()?;
    let grid = TileGrid::geodetic(256).map_err(anyhow::Error::msg)?;
    let keys = keys(&grid, max_level);
    let g = gdal(&grid, &countries, &keys)?;
    // A discarded first run: the first ~3 GB of tiles pay the kernel's page
    // faults, which would be charged to whichever setting ran first.
    relief(dir.path(), &countries, 1, &keys)?;
    let mut runs = Vec::new();
    for antialias in [1u32, 2, 4, 8] {
        runs.push((antialias, relief(dir.path(), &countries, antialias, &keys)?));
    }
    let reference = runs.last().map(|r| r.1.1.clone()).unwrap_or_default();
    println!(
        "\n## Natural Earth countries rasterized, levels 0..={max_level} ({} tiles of 258 x 258 texels)",
        keys.len()
    );
    println!(
        "machine: {}; relief through its tile store (2 threads), GDAL in-process, one thread",
        relief_tests::machine()
    );
    println!(
        "| rasterizer | antialias | seconds | tiles/s | ratio to GDAL | mean coverage error vs 8x8 (alpha levels) |"
    );
    println!("|---|---|---|---|---|---|");
    println!("| GDAL rasterize (aliased, centre of texel) | 1 | {g:.2} | {:.0} | 1.00 | - |", keys.len() as f64 / g);
    for (antialias, (seconds, alphas)) in &runs {
        let (mut sum, mut n) = (0.0, 0usize);
        for (a, b) in alphas.iter().zip(&reference) {
            for (x, y) in a.iter().zip(b) {
                sum += (f64::from(*x) - f64::from(*y)).abs();
                n += 1;
            }
        }
        println!(
            "| relief rasterize | {antialias}x{antialias} | {seconds:.2} | {:.0} | {:.2} | {:.3} |",
            keys.len() as f64 / seconds,
            g / seconds,
            sum / n as f64
        );
    }
    Ok(())
}
