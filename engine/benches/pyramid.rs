//! Tile pyramid benchmark. Prints tables; never asserts a time.
//!
//! 1. Throughput: every tile of levels 0..=N over the two SRTM tiles in
//!    `../shared/data/dem`, built through reliefd's own tile store, against
//!    `gdal2tiles.py --processes=2` building the same levels (geodetic,
//!    tmscompatible: the same 2 x 1 level-0 grid) in the same run.
//! 2. Accuracy knobs: for each resampling kernel, and for each
//!    reprojection error threshold, time per tile against error.
//!
//! Every scene here has no disk tile cache (`disk_mb = 0`): a run after
//! the first would otherwise read the first one's tiles back from it.
//! On the 3.2 GB raster a last row times GDAL decoding the same blocks
//! and nothing else: the floor under a build that read them through GDAL
//! (relief decodes that file's blocks itself).
//!
//! `cargo bench -p relief-engine --bench pyramid` (RELIEF_BENCH_MAX_LEVEL, default 10;
//! RELIEF_PYRAMID_ONLY=srtm,big,kernels,reprojection picks tables).

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use common::median;
use relief_engine::scene::Scene;
use relief_examples as fixtures;
use relief_source::{Payload, Quality, Resampling, TileKey};

const THREADS: usize = 2;
const RUNS: usize = 3;

fn machine() -> String {
    format!("{}, tile pool of {THREADS} threads", relief_tests::machine())
}

fn load(manifest: &Path) -> Scene {
    common::load(manifest, THREADS).expect("the bench scene loads")
}

/// Every tile of levels 0..=max that overlaps the source's data.
fn pyramid_keys(scene: &Scene, source: usize, max_level: u8) -> Vec<(usize, TileKey)> {
    let snap = scene.snapshot();
    let extent = snap.slots[source].source.as_ref().and_then(|s| s.info().extent).expect("the DEM has an extent");
    (0..=max_level).flat_map(|l| snap.grid.keys_overlapping(l, &extent)).map(|k| (source, k)).collect()
}

/// The inputs of a throughput table: the DEM files, what they are, and
/// the height range scaled to bytes for gdal2tiles (None: GDAL finds it,
/// reading every pixel).
struct Inputs {
    files: Vec<PathBuf>,
    label: String,
    byte_range: Option<(f64, f64)>,
    runs: usize,
    /// Also time decoding alone (an Int16 file with overviews).
    decode_floor: bool,
}

fn throughput(inputs: &Inputs, max_level: u8) {
    let dir = tempfile::tempdir().expect("temp dir");
    let hgts = &inputs.files;
    let paths: Vec<String> = hgts.iter().map(|p| format!("\"{}\"", p.display())).collect();
    let manifest = fixtures::write_manifest(
        dir.path(),
        &format!(
            "[scene]\nname = \"bench\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npaths = [{}]\n\n[quality]\nresampling = \"bilinear\"\n\n[cache]\ndisk_mb = 0\n",
            paths.join(", ")
        ),
    )
    .expect("manifest");
    let runs = inputs.runs;

    // relief: open the sources and build every tile, cold, through the tile store.
    let mut relief_s = Vec::new();
    let mut relief_write_s = Vec::new();
    let mut tiles = 0;
    let mut load_s = Vec::new();
    let mut cpu_s = Vec::new();
    for run in 0..runs {
        let started = Instant::now();
        let scene = load(&manifest);
        load_s.push(started.elapsed().as_secs_f64());
        let keys = pyramid_keys(&scene, 0, max_level);
        let snap = scene.snapshot();
        let cpu = common::cpu_seconds();
        let built = scene.store.build(&snap, &keys, &snap.manifest.quality);
        relief_s.push(started.elapsed().as_secs_f64());
        cpu_s.push(common::cpu_seconds() - cpu);
        tiles = built.len();
        assert!(built.iter().all(Result::is_ok), "every tile builds");
        // Same again, writing each tile to disk as gdal2tiles does.
        let out = dir.path().join(format!("relief-{run}"));
        let started = Instant::now();
        let scene = load(&manifest);
        let snap = scene.snapshot();
        for ((_, key), tile) in keys.iter().zip(scene.store.build(&snap, &keys, &snap.manifest.quality)) {
            let tile = tile.expect("tile builds");
            let Payload::Height(h) = tile.payload.as_ref() else { unreachable!("a DEM gives heights") };
            let path = out.join(format!("{}/{}/{}.f32", key.level, key.x, key.y));
            std::fs::create_dir_all(path.parent().expect("has a parent")).expect("mkdir");
            std::fs::write(&path, h.heights.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>())
                .expect("write tile");
        }
        relief_write_s.push(started.elapsed().as_secs_f64());
    }

    // gdal2tiles: needs one Byte input, so a VRT mosaic scaled to Byte first
    // (what gdal2tiles itself tells you to do), then the same levels.
    let vrt = dir.path().join("in.vrt");
    let byte_vrt = dir.path().join("byte.vrt");
    let status = Command::new("gdalbuildvrt").arg("-q").arg(&vrt).args(hgts).status().expect("gdalbuildvrt (gdal-bin)");
    assert!(status.success());
    let mut scale = vec!["-scale".to_owned()];
    if let Some((lo, hi)) = inputs.byte_range {
        scale.extend([lo.to_string(), hi.to_string(), "0".into(), "255".into()]);
    }
    let status = Command::new("gdal_translate")
        .args(["-q", "-of", "VRT", "-ot", "Byte"])
        .args(&scale)
        .arg(&vrt)
        .arg(&byte_vrt)
        .output()
        .expect("gdal_translate");
    assert!(status.status.success());
    let mut peer_s = Vec::new();
    let mut peer_tiles = 0;
    for run in 0..runs {
        let out = dir.path().join(format!("g2t-{run}"));
        let started = Instant::now();
        let result = Command::new("gdal2tiles.py")
            .args(["--profile=geodetic", "--tmscompatible", "-r", "bilinear", "-w", "none", "-q", "--processes=2"])
            .arg(format!("-z0-{max_level}"))
            .arg(&byte_vrt)
            .arg(&out)
            .output()
            .expect("gdal2tiles.py (Debian python3-gdal / gdal-bin)");
        peer_s.push(started.elapsed().as_secs_f64());
        assert!(result.status.success(), "gdal2tiles failed: {}", String::from_utf8_lossy(&result.stderr));
        peer_tiles = count_files(&out, "png");
    }

    // GDAL decoding alone, the floor under a build that reads this file's
    // blocks through GDAL: every block of the levels the finest tiles read
    // (and coarser), each once.
    let floor = inputs.decode_floor.then(|| {
        let scene = load(&manifest);
        let snap = scene.snapshot();
        let keys = pyramid_keys(&scene, 0, max_level);
        let finest = keys.iter().map(|(_, k)| *k).max_by_key(|k| k.level).expect("keys");
        let step = snap.grid.lattice(finest, relief_source::SampleKind::Corner).step_x;
        scene.store.build(&snap, &keys, &snap.manifest.quality);
        let info = snap.slots[0].source.as_ref().expect("the DEM").info();
        let read = info.details.get("bytes_read").and_then(|b| b.parse::<u64>().ok()).unwrap_or(0);
        (decode_floor(&hgts[0], step), read)
    });
    let (r, rw, p, l) = (median(relief_s), median(relief_write_s), median(peer_s), median(load_s));
    println!("\n## Pyramid build: levels 0..={max_level} of {}, median of {runs} cold runs", inputs.label);
    println!("machine: {}", machine());
    println!("relief's seconds include opening the scene: {l:.3} s (median)");
    println!(
        "relief's build used {:.2} CPU seconds, all threads (median; a steadier figure than its wall time)",
        median(cpu_s)
    );
    println!("| builder | tiles | seconds | tiles/s | relief / gdal2tiles |");
    println!("|---|---|---|---|---|");
    println!(
        "| relief, f32 257x257 tiles into the cache | {tiles} | {r:.3} | {:.0} | {:.1}x |",
        tiles as f64 / r,
        (tiles as f64 / r) / (peer_tiles as f64 / p)
    );
    println!(
        "| relief, and each tile written to disk | {tiles} | {rw:.3} | {:.0} | {:.1}x |",
        tiles as f64 / rw,
        (tiles as f64 / rw) / (peer_tiles as f64 / p)
    );
    println!(
        "| gdal2tiles.py --processes=2, 8-bit PNG | {peer_tiles} | {p:.3} | {:.0} | 1.0x |",
        peer_tiles as f64 / p
    );
    if let Some((floor, read)) = floor {
        println!(
            "| GDAL decoding alone: {} blocks of the file's levels from 1/{} ({:.0} MB of pixels; relief's build read {:.0} MB), GDALReadBlock on {THREADS} threads | - | {:.3} | - | a build through GDAL: at most {:.1}x |",
            floor.blocks,
            floor.factor,
            floor.bytes as f64 / 1e6,
            read as f64 / 1e6,
            floor.seconds,
            (tiles as f64 / floor.seconds) / (peer_tiles as f64 / p)
        );
    }
}

/// What decoding alone took.
struct Floor {
    /// The finest level decoded: 1/factor of the base.
    factor: usize,
    blocks: usize,
    bytes: u64,
    seconds: f64,
}

/// Decodes every block of the Int16 file's overviews at least as coarse as
/// the level relief reads for samples `step` apart (its CRS units), each
/// once, through `GDALReadBlock` (no cache: the decode alone), on THREADS
/// threads with a handle each.
fn decode_floor(path: &Path, step: f64) -> Floor {
    let ds = gdal::Dataset::open(path).expect("the big raster opens");
    let band = ds.rasterband(1).expect("band 1");
    assert_eq!(band.band_type(), gdal::raster::GdalDataType::Int16, "the floor reads Int16");
    let pixel = ds.geo_transform().expect("georeferenced")[1].abs();
    // As the gdal source picks its mip: pixels at most the samples' spacing.
    let factor = 1usize << ((step / pixel).log2().floor().max(0.0) as u32);
    let width = band.size().0;
    let mut jobs: Vec<(usize, usize, usize)> = Vec::new();
    let mut bytes = 0u64;
    for o in 0..band.overview_count().expect("overview count").max(0) as usize {
        let over = band.overview(o).expect("overview");
        let ((w, h), (bw, bh)) = (over.size(), over.block_size());
        if w > width.div_ceil(factor) {
            continue;
        }
        for by in 0..h.div_ceil(bh) {
            for bx in 0..w.div_ceil(bw) {
                jobs.push((o, bx, by));
                bytes += (bw * bh * 2) as u64;
            }
        }
    }
    let started = Instant::now();
    std::thread::scope(|scope| {
        for t in 0..THREADS {
            let jobs = &jobs;
            scope.spawn(move || {
                let ds = gdal::Dataset::open(path).expect("opens");
                let band = ds.rasterband(1).expect("band 1");
                for &(o, bx, by) in jobs.iter().skip(t).step_by(THREADS) {
                    band.overview(o).expect("overview").read_block::<i16>((bx, by)).expect("block decodes");
                }
            });
        }
    });
    Floor { factor, blocks: jobs.len(), bytes, seconds: started.elapsed().as_secs_f64() }
}

fn count_files(dir: &Path, ext: &str) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    entries
        .flatten()
        .map(|e| {
            let p = e.path();
            if p.is_dir() { count_files(&p, ext) } else { usize::from(p.extension().is_some_and(|x| x == ext)) }
        })
        .sum()
}

/// Time per tile and error against the analytic hill, for each kernel.
fn kernels() {
    let dir = tempfile::tempdir().expect("temp dir");
    fixtures::write_dem(&dir.path().join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).expect("fixture");
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"hill\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n[cache]\ndisk_mb = 0\n",
    )
    .expect("manifest");
    println!(
        "\n## Accuracy knob `quality.resampling`: Gaussian hill (0.00125 deg pixels), error against the analytic surface"
    );
    println!("| kernel | level | sample spacing / source pixel | ms per tile | RMS error m | max error m |");
    println!("|---|---|---|---|---|---|");
    for level in [9u8, 11] {
        for kernel in Resampling::ALL {
            let scene = load(&manifest);
            let snap = scene.snapshot();
            let extent = relief_source::Extent::new(10.05, 45.05, 10.45, 45.45);
            let keys: Vec<(usize, TileKey)> =
                snap.grid.keys_overlapping(level, &extent).into_iter().map(|k| (0, k)).collect();
            let quality = Quality { resampling: kernel, ..Quality::default() };
            let started = Instant::now();
            let built = scene.store.build(&snap, &keys, &quality);
            let ms = started.elapsed().as_secs_f64() * 1e3 / keys.len() as f64;
            let (mut sum2, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
            for ((_, key), tile) in keys.iter().zip(built) {
                let tile = tile.expect("tile builds");
                let Payload::Height(h) = tile.payload.as_ref() else { unreachable!() };
                let lattice = snap.grid.lattice(*key, relief_source::SampleKind::Corner);
                for j in 0..lattice.rows {
                    for i in 0..lattice.cols {
                        let (lon, lat) = (lattice.x(i), lattice.y(j));
                        if !extent.contains(lon, lat) {
                            continue;
                        }
                        let err = f64::from(h.get(i, j)) - fixtures::hill(lon, lat);
                        sum2 += err * err;
                        max = max.max(err.abs());
                        n += 1;
                    }
                }
            }
            let step = snap.grid.lattice(keys[0].1, relief_source::SampleKind::Corner).step_x;
            println!(
                "| {kernel} | {level} | {:.2} | {ms:.2} | {:.4} | {max:.4} |",
                step / 0.00125,
                (sum2 / n as f64).sqrt()
            );
        }
    }
}

/// Time per tile against the error the approximate reprojection adds.
fn reprojection() {
    let dir = tempfile::tempdir().expect("temp dir");
    fixtures::write_dem(&dir.path().join("utm.tif"), &fixtures::utm_spec(), fixtures::utm_surface).expect("fixture");
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"utm-on-the-planet\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"utm.tif\"\n\n[cache]\ndisk_mb = 0\n",
    )
    .expect("manifest");
    println!(
        "\n## Accuracy knob `quality.reprojection_error_px`: a UTM 12N DEM warped into the geodetic grid, error against exact PROJ for every sample"
    );
    println!("| threshold px | ms per tile | max height error m | max error / local relief |");
    println!("|---|---|---|---|");
    let mut exact: Option<Vec<Vec<f32>>> = None;
    for threshold in [0.0, 0.05, 0.125, 0.5, 2.0, 8.0] {
        let scene = load(&manifest);
        let snap = scene.snapshot();
        let extent = snap.slots[0].source.as_ref().and_then(|s| s.info().extent).expect("extent");
        let keys: Vec<(usize, TileKey)> = snap.grid.keys_overlapping(13, &extent).into_iter().map(|k| (0, k)).collect();
        let quality = Quality { reprojection_error_px: threshold, ..Quality::default() };
        let started = Instant::now();
        let built: Vec<Vec<f32>> = scene
            .store
            .build(&snap, &keys, &quality)
            .into_iter()
            .map(|t| match t.expect("tile builds").payload.as_ref() {
                Payload::Height(h) => h.heights.clone(),
                _ => unreachable!(),
            })
            .collect();
        let ms = started.elapsed().as_secs_f64() * 1e3 / keys.len() as f64;
        let reference = exact.get_or_insert_with(|| built.clone());
        let max = built
            .iter()
            .flatten()
            .zip(reference.iter().flatten())
            .filter(|(a, b)| !a.is_nan() && !b.is_nan())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        let relief = reference
            .iter()
            .flatten()
            .filter(|v| !v.is_nan())
            .fold((f32::MAX, f32::MIN), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
        println!("| {threshold} | {ms:.2} | {max:.4} | {:.2e} |", max / (relief.1 - relief.0));
    }
}

/// True when RELIEF_PYRAMID_ONLY is unset or names `table`.
fn wanted(table: &str) -> bool {
    common::wanted("RELIEF_PYRAMID_ONLY", table)
}

fn main() {
    // `cargo bench` passes --bench; `cargo test --benches` passes nothing useful either.
    let max_level: u8 = std::env::var("RELIEF_BENCH_MAX_LEVEL").ok().and_then(|v| v.parse().ok()).unwrap_or(10);
    let data: PathBuf = std::env::var_os("RELIEF_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
    if wanted("srtm") && data.join("dem/N43E006.hgt").exists() {
        let inputs = Inputs {
            files: vec![data.join("dem/N43E006.hgt"), data.join("dem/N43E007.hgt")],
            label: "N43E006 + N43E007 (2 x 1201 x 1201 Int16)".into(),
            byte_range: None,
            runs: RUNS,
            decode_floor: false,
        };
        throughput(&inputs, max_level);
    } else if wanted("srtm") {
        println!("skipping the pyramid throughput table: no SRTM tiles at {}", data.display());
    }
    // The bigdem bench's 40,000 x 40,000 raster, when it has been made:
    // levels down to where its overviews stop (RELIEF_BENCH_BIG_MAX_LEVEL).
    let big = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/bench-data/bigdem/side-40000/big.tif");
    if wanted("big") && big.exists() {
        let level: u8 = std::env::var("RELIEF_BENCH_BIG_MAX_LEVEL").ok().and_then(|v| v.parse().ok()).unwrap_or(9);
        let inputs = Inputs {
            files: vec![big],
            label: "the bigdem bench's 40,000 x 40,000 Int16 tiled GeoTIFF (3.2 GB of samples, with overviews)".into(),
            byte_range: Some((0.0, 3000.0)),
            runs: RUNS,
            decode_floor: true,
        };
        throughput(&inputs, level);
    } else if wanted("big") {
        println!(
            "skipping the pyramid table on the 3.2 GB raster: run the bigdem bench first to make {}",
            big.display()
        );
    }
    if wanted("kernels") {
        kernels();
    }
    if wanted("reprojection") {
        reprojection();
    }
}
