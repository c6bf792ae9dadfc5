//! Vector rasterizer benchmark. Prints tables; never asserts a time.
//!
//! Natural Earth's countries (`../shared/data/shp`) drawn into every tile
//! of levels 0..=N (RELIEF_BENCH_MAX_LEVEL, default 6) through reliefd's
//! tile store, and the same tiles burnt by GDAL's rasterizer (the library
//! call behind `gdal_rasterize`, in-process, one MEM raster per tile) in the
//! same run, each on 1 thread and on 2:
//! - GDAL at equal quality: 4 x 4 sub-samples per texel, as relief's default
//!   `antialias = 4` takes, is a raster 4 times finer burnt at its pixel
//!   centres (the same sub-sample places) and summed 4 x 4 into coverage;
//! - GDAL aliased (one sample at each texel's centre), for scale.
//!
//! Then the `antialias` knob: time against coverage error, taking 8 x 8
//! sub-samples as the reference.

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

/// Alpha planes of tiles, to compare coverage.
type Alphas = Vec<Vec<u8>>;

/// A GDAL thread's tiles: each one's place in the key list and its alpha.
type Share = Vec<(usize, Vec<u8>)>;

fn relief(
    dir: &Path,
    countries: &Path,
    antialias: u32,
    keys: &[TileKey],
    threads: usize,
) -> anyhow::Result<(f64, Alphas)> {
    let manifest = relief_examples::write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"countries\"\n\n[[source]]\nid = \"countries\"\nkind = \"shapefile\"\npath = \"{}\"\n\n[[source]]\nid = \"drawn\"\nkind = \"rasterize\"\ninputs = [\"countries\"]\nstroke = \"none\"\nfill = \"#ff0000ff\"\nantialias = {antialias}\n\n[layers]\ncolor = \"drawn\"\n\n[cache]\nmemory_mb = 4096\ndisk_mb = 0\n",
            countries.display()
        ),
    )?;
    let scene = common::load(&manifest, threads)?;
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

/// GDAL's rasterize over `keys` on `threads` threads (each opens the file
/// and burns its share of the tiles), `ss` x `ss` samples per texel: the
/// seconds and each tile's alpha (coverage of 255 burnt samples).
fn gdal(
    grid: &TileGrid,
    countries: &Path,
    keys: &[TileKey],
    ss: usize,
    threads: usize,
) -> anyhow::Result<(f64, Alphas)> {
    let started = Instant::now();
    let shares: Vec<anyhow::Result<Share>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                scope.spawn(move || -> anyhow::Result<Share> {
                    let source = gdal::Dataset::open(countries)?;
                    let mut layer = source.layer(0)?;
                    let geometries: Vec<gdal::vector::Geometry> =
                        layer.features().filter_map(|f| f.geometry().cloned()).collect();
                    let burn = vec![255.0; geometries.len()];
                    let driver = gdal::DriverManager::get_driver_by_name("MEM")?;
                    let mut out = Vec::new();
                    for (i, key) in keys.iter().enumerate().skip(t).step_by(threads) {
                        let l = grid.lattice(*key, SampleKind::TexelWithBorder);
                        let (w, h) = (l.cols * ss, l.rows * ss);
                        let mut ds = driver.create_with_band_type::<u8, _>("", w, h, 1)?;
                        let (sx, sy) = (l.step_x / ss as f64, l.step_y / ss as f64);
                        ds.set_geo_transform(&[l.x(0) - l.step_x / 2.0, sx, 0.0, l.y(0) + l.step_y / 2.0, 0.0, -sy])?;
                        gdal::raster::rasterize(&mut ds, &[1], &geometries, &burn, None)?;
                        let samples = ds.rasterband(1)?.read_as::<u8>((0, 0), (w, h), (w, h), None)?;
                        let samples = samples.data();
                        let mut alpha = vec![0u8; l.cols * l.rows];
                        if ss == 1 {
                            alpha.copy_from_slice(samples);
                        } else {
                            let full = (ss * ss * 255) as u32;
                            for (k, a) in alpha.iter_mut().enumerate() {
                                let (i0, j0) = ((k % l.cols) * ss, (k / l.cols) * ss);
                                let sum: u32 = (j0..j0 + ss)
                                    .map(|j| {
                                        samples[j * w + i0..j * w + i0 + ss].iter().map(|&v| u32::from(v)).sum::<u32>()
                                    })
                                    .sum();
                                *a = ((sum * 255 + full / 2) / full) as u8;
                            }
                        }
                        out.push((i, alpha));
                    }
                    Ok(out)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|_| Err(anyhow::anyhow!("a GDAL thread panicked"))))
            .collect()
    });
    let seconds = started.elapsed().as_secs_f64();
    let mut alphas = vec![Vec::new(); keys.len()];
    for share in shares {
        for (i, alpha) in share? {
            alphas[i] = alpha;
        }
    }
    Ok((seconds, alphas))
}

/// Mean absolute difference of two sets of alpha planes, in alpha levels.
fn coverage_error(a: &Alphas, b: &Alphas) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (a, b) in a.iter().zip(b) {
        for (x, y) in a.iter().zip(b) {
            sum += (f64::from(*x) - f64::from(*y)).abs();
            n += 1;
        }
    }
    sum / n as f64
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
    // A discarded first run: the first ~3 GB of tiles pay the kernel's page
    // faults, which would be charged to whichever setting ran first.
    relief(dir.path(), &countries, 1, &keys, 2)?;
    let mut runs = Vec::new();
    for antialias in [1u32, 2, 4, 8] {
        runs.push((antialias, 2, relief(dir.path(), &countries, antialias, &keys, 2)?));
    }
    runs.push((4, 1, relief(dir.path(), &countries, 4, &keys, 1)?));
    let reference = runs.iter().find(|r| r.0 == 8).map(|r| r.2.1.clone()).unwrap_or_default();
    let mut peers = Vec::new();
    for (ss, threads) in [(4usize, 1usize), (4, 2), (1, 1), (1, 2)] {
        peers.push((ss, threads, gdal(&grid, &countries, &keys, ss, threads)?));
    }
    println!(
        "\n## Natural Earth countries rasterized, levels 0..={max_level} ({} tiles of 258 x 258 texels)",
        keys.len()
    );
    println!(
        "machine: {}; relief through its tile store (its shapefile source's tiles included), GDAL in-process \
         (each thread reading the shapefile's geometries once, timed with it)",
        relief_tests::machine()
    );
    println!(
        "| rasterizer | samples per texel | threads | seconds | tiles/s | mean coverage error vs relief 8x8 (alpha levels) |"
    );
    println!("|---|---|---|---|---|---|");
    for (ss, threads, (seconds, alphas)) in &peers {
        let how = if *ss == 1 { "aliased, texel centre" } else { "burnt 4x finer, summed" };
        println!(
            "| GDAL rasterize ({how}) | {ss}x{ss} | {threads} | {seconds:.2} | {:.0} | {:.3} |",
            keys.len() as f64 / seconds,
            coverage_error(alphas, &reference)
        );
    }
    for (antialias, threads, (seconds, alphas)) in &runs {
        println!(
            "| relief rasterize | {antialias}x{antialias} | {threads} | {seconds:.2} | {:.0} | {:.3} |",
            keys.len() as f64 / seconds,
            coverage_error(alphas, &reference)
        );
    }
    println!("\n### relief at its default antialias = 4 against GDAL, in this run (ratio of tiles/s)");
    println!("| GDAL | GDAL threads | relief threads | ratio |");
    println!("|---|---|---|---|");
    for (ss, gdal_threads, (g, _)) in &peers {
        for (_, threads, (seconds, _)) in runs.iter().filter(|r| r.0 == 4) {
            let what = if *ss == 1 { "aliased (lower quality)" } else { "4x4 (equal quality)" };
            println!("| {what} | {gdal_threads} | {threads} | {:.2} |", g / seconds);
        }
    }
    Ok(())
}
