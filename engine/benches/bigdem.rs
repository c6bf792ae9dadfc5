//! Rasters larger than memory. Prints a table; never asserts a time.
//!
//! Data, made once and cached under `target/bench-data/bigdem/side-SIDE/`
//! (made again only when missing; delete the folder to start afresh):
//! - `big.tif`: SIDE x SIDE Int16 heights of a fractal terrain (ridged
//!   gradient noise over a rolling base, 0..3000 m), EPSG:4326, 1e-4 degree
//!   pixels from lon 7, lat 47 (SIDE 40000 reaches lon 11, lat 43); a tiled
//!   DEFLATE BigTIFF written a band of rows at a time, with internal
//!   AVERAGE overviews (`gdaladdo`) down to under 256 pixels;
//! - `mosaic.vrt` (`gdalbuildvrt`) over `mosaic/`: the same area as 20 x 20
//!   GeoTIFFs of SIDE/20 pixels, each with its own overviews (at least one
//!   level), from the same terrain function, so the mosaic equals big.tif.
//!
//! For each dataset the real reliefd serves a scene of it as the height
//! layer, and the bench reports:
//! - start to first frame: from spawning reliefd to the first 1280 x 720
//!   frame (Render, retried until it answers) of a camera a few km above
//!   the centre looking at it obliquely;
//! - reliefd's VmRSS and VmHWM after a flight of FLIGHT_FRAMES frames
//!   crossing the whole dataset at low altitude, north-west to south-east;
//! - edit to generation: a 64 x 64 window (wholly inside one mosaic file,
//!   the same windows for both datasets) rewritten through GDAL in update
//!   mode, each overview's window updated with the 2 x 2 average of the
//!   level below, closed; the clock runs from just before the open to
//!   WaitForGeneration returning. Edits come in pairs, a 50 m bump and then
//!   its removal, so the cached data holds the same heights after every run
//!   (an odd count gets one more, untimed, removal; the files grow a little,
//!   as GDAL appends rewritten blocks). The tiles reliefd hands to its
//!   disk store during the edits and in the 3 s after are counted (it
//!   writes a source's cached tiles once the scene has been still for 2 s,
//!   not again under every save's new address). A dataset whose edit brings no
//!   generation within WaitForGeneration's 20 s is reported as such and its
//!   remaining edits are skipped.
//!
//! The bench itself holds at most BAND_ROWS rows of samples (or one mosaic
//! file's) and a 256 MB GDAL block cache; `gdaladdo` runs as its own process.
//!
//! `cargo bench -p relief-engine --bench bigdem`; RELIEF_BIGDEM_SIDE
//! (default 40000, a multiple of 20, at least 2560), RELIEF_BIGDEM_EDITS
//! (default 25), RELIEF_BIGDEM_MAKE_ONLY (make the data and stop),
//! RELIEF_BIGDEM_ONLY (the datasets to serve, commas: big, exact, mosaic), RELIEF_BIGDEM_RASTER_MB (`[cache] raster_mb`, default 512,
//! written only while RASTER_BUDGET_OPTION is on). reliefd is the one built
//! beside the bench (target/<profile>/reliefd).

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::Context;
use gdal::raster::{Buffer, RasterCreationOptions};
use gdal::spatial_ref::SpatialRef;
use gdal::{Dataset, DatasetOptions, DriverManager, GdalOpenFlags};
use rayon::prelude::*;
use relief_examples::Lcg;
use relief_proto::v1 as pb;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::edit::{self, Events};
use tonic::transport::Channel;

/// Whether the manifest gets `[cache] raster_mb` (the budget of decoded
/// raster blocks): reliefd takes it since the windowed rasters (7c4c05e);
/// an older reliefd rejects it as an unknown field, so turn this off to
/// measure one.
const RASTER_BUDGET_OPTION: bool = true;
/// `[cache] memory_mb`: the tile cache.
const MEMORY_MB: u64 = 512;

const PIXEL_DEG: f64 = 1e-4;
const WEST_DEG: f64 = 7.0;
const NORTH_DEG: f64 = 47.0;
const NODATA: i16 = -32768;
/// Mosaic files per side.
const MOSAIC_GRID: usize = 20;
/// Rows computed and written at a time (a multiple of the block height).
const BAND_ROWS: usize = 256;
const EDIT_SIDE: usize = 64;
const BUMP_M: i16 = 50;
const FLIGHT_FRAMES: usize = 40;
const FRAME: (u32, u32) = (1280, 720);
const CREATION_OPTIONS: [&str; 7] = [
    "TILED=YES",
    "BLOCKXSIZE=256",
    "BLOCKYSIZE=256",
    "COMPRESS=DEFLATE",
    "PREDICTOR=2",
    "BIGTIFF=YES",
    "NUM_THREADS=ALL_CPUS",
];

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

// ---------------------------------------------------------------- terrain

/// 16 unit gradients, 11.25 degrees off the axes: with a gradient along an
/// axis, a lattice edge between two such gradients is zero all along, a
/// straight crease once the noise is folded into ridges.
const GRADIENTS: [(f64, f64); 16] = {
    let mut g = [(0.0, 0.0); 16];
    // cos of 11.25, 33.75, 56.25 and 78.75 degrees.
    let c = [0.980_785_3, 0.831_469_6, 0.555_570_2, 0.195_090_3];
    let mut k = 0;
    while k < 16 {
        let q = k % 4;
        let (a, b) = (c[q], c[3 - q]);
        g[k] = match k / 4 {
            0 => (a, b),
            1 => (-b, a),
            2 => (-a, -b),
            _ => (b, -a),
        };
        k += 1;
    }
    g
};

fn hash(x: i64, y: i64, seed: u64) -> u64 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ seed.wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    h = h.wrapping_mul(0xC4CE_B9FE_1A85_EC53);
    h ^ (h >> 33)
}

/// Gradient noise on the unit lattice, about -1..1.
fn noise(x: f64, y: f64, seed: u64) -> f64 {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (ix, iy) = (x0 as i64, y0 as i64);
    let corner = |dx: i64, dy: i64| {
        let (gx, gy) = GRADIENTS[(hash(ix + dx, iy + dy, seed) & 15) as usize];
        gx * (fx - dx as f64) + gy * (fy - dy as f64)
    };
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (u, v) = (fade(fx), fade(fy));
    let bottom = corner(0, 0) + u * (corner(1, 0) - corner(0, 0));
    let top = corner(0, 1) + u * (corner(1, 1) - corner(0, 1));
    1.4 * (bottom + v * (top - bottom))
}

/// Rotates the lattice between octaves (by 0.6 rad) so their grids do
/// not line up.
fn rotate((x, y): (f64, f64)) -> (f64, f64) {
    const COS: f64 = 0.825_335_6;
    const SIN: f64 = 0.564_642_5;
    (COS * x - SIN * y + 17.3, SIN * x + COS * y - 5.1)
}

/// Height in metres at (lon, lat): massifs from a rolling base (3 octaves,
/// 2 cycles a degree), sharpened by a ridged multifractal (9 octaves from
/// 4 cycles a degree, about 28 km, to 1024, about 10 pixels).
fn height_m(lon: f64, lat: f64) -> f64 {
    let mut p = (lon * 2.0 + 0.37, lat * 2.0 + 0.71);
    let (mut base, mut amp, mut norm) = (0.0, 1.0, 0.0);
    for octave in 0..3 {
        base += amp * noise(p.0, p.1, octave);
        norm += amp;
        amp *= 0.5;
        p = rotate((p.0 * 2.0, p.1 * 2.0));
    }
    base /= norm;
    let (mut ridge, mut weight) = (0.0, 1.0);
    (amp, norm) = (1.0, 0.0);
    for octave in 0..9 {
        let mut s = 1.0 - noise(p.0, p.1, 100 + octave).abs();
        s = s * (s * weight);
        weight = (s * 2.0).clamp(0.0, 1.0);
        ridge += s * amp;
        norm += amp;
        amp *= 0.5;
        p = rotate((p.0 * 2.0, p.1 * 2.0));
    }
    ridge /= norm;
    let t = ((base + 0.35) / 0.8).clamp(0.0, 1.0);
    let massif = t * t * (3.0 - 2.0 * t);
    (150.0 + 500.0 * (base + 1.0) + 2600.0 * massif * ridge).clamp(0.0, 3000.0)
}

/// The sample of global pixel (i, j) (column, row from the north-west).
fn sample(i: usize, j: usize) -> i16 {
    let lon = WEST_DEG + (i as f64 + 0.5) * PIXEL_DEG;
    let lat = NORTH_DEG - (j as f64 + 0.5) * PIXEL_DEG;
    height_m(lon, lat).round() as i16
}

/// Samples of columns [x, x + w) of rows [y, y + h), computed in parallel.
fn samples(x: usize, y: usize, w: usize, h: usize) -> Vec<i16> {
    let mut data = vec![0i16; w * h];
    data.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        for (c, v) in row.iter_mut().enumerate() {
            *v = sample(x + c, y + r);
        }
    });
    data
}

// ---------------------------------------------------------------- data

struct Data {
    big: PathBuf,
    mosaic_dir: PathBuf,
    vrt: PathBuf,
}

/// target/ of this build (the bench runs from target/<profile>/deps/).
fn target_dir() -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe()?;
    exe.ancestors().nth(3).map(Path::to_path_buf).context("the bench runs from target/<profile>/deps")
}

fn run_tool(command: &mut Command) -> anyhow::Result<()> {
    let out = command.output().with_context(|| format!("cannot run {command:?}"))?;
    anyhow::ensure!(
        out.status.success(),
        "{command:?} failed: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    Ok(())
}

/// Overview factors 2, 4, 8, ... while the level above is 256 pixels or
/// more; at least one level.
fn overview_factors(side: usize) -> Vec<String> {
    let mut factors = vec![2usize];
    while side.div_ceil(*factors.last().expect("one factor at least")) >= 256 {
        factors.push(factors.last().expect("one factor at least") * 2);
    }
    factors.iter().map(ToString::to_string).collect()
}

fn add_overviews(path: &Path, side: usize) -> anyhow::Result<()> {
    run_tool(
        Command::new("/usr/bin/gdaladdo")
            .args(["-q", "-r", "average", "--config", "GDAL_NUM_THREADS", "ALL_CPUS"])
            .arg(path)
            .args(overview_factors(side)),
    )
}

/// A tiled Int16 GeoTIFF of `side` x `side` pixels whose north-west pixel
/// is global pixel (x, y), written BAND_ROWS rows at a time, with overviews.
fn write_square(path: &Path, x: usize, y: usize, side: usize) -> anyhow::Result<()> {
    let driver = DriverManager::get_driver_by_name("GTiff")?;
    let options = RasterCreationOptions::from_iter(CREATION_OPTIONS);
    let mut ds = driver
        .create_with_band_type_with_options::<i16, _>(path, side, side, 1, &options)
        .with_context(|| format!("cannot create {}", path.display()))?;
    ds.set_geo_transform(&[
        WEST_DEG + x as f64 * PIXEL_DEG,
        PIXEL_DEG,
        0.0,
        NORTH_DEG - y as f64 * PIXEL_DEG,
        0.0,
        -PIXEL_DEG,
    ])?;
    ds.set_spatial_ref(&SpatialRef::from_epsg(4326)?)?;
    let mut band = ds.rasterband(1)?;
    band.set_no_data_value(Some(f64::from(NODATA)))?;
    for row in (0..side).step_by(BAND_ROWS) {
        let rows = BAND_ROWS.min(side - row);
        let mut buffer = Buffer::new((side, rows), samples(x, y + row, side, rows));
        band.write((0, row as isize), (side, rows), &mut buffer)?;
    }
    ds.close()?;
    add_overviews(path, side)
}

fn dir_size(dir: &Path) -> anyhow::Result<u64> {
    let mut total = 0;
    for entry in std::fs::read_dir(dir)? {
        total += entry?.metadata()?.len();
    }
    Ok(total)
}

/// Makes what is missing; each piece is written under a temporary name and
/// renamed into place once whole, so an interrupted run leaves no half file.
fn make_data(side: usize) -> anyhow::Result<Data> {
    let dir = target_dir()?.join(format!("bench-data/bigdem/side-{side}"));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let data = Data { big: dir.join("big.tif"), mosaic_dir: dir.join("mosaic"), vrt: dir.join("mosaic.vrt") };
    if data.big.exists() {
        println!("big.tif: cached ({})", data.big.display());
    } else {
        let started = Instant::now();
        let partial = dir.join("big.partial.tif");
        write_square(&partial, 0, 0, side)?;
        std::fs::rename(&partial, &data.big)?;
        println!("big.tif: made in {:.1} s ({})", started.elapsed().as_secs_f64(), data.big.display());
    }
    if data.vrt.exists() {
        println!("mosaic.vrt: cached ({})", data.vrt.display());
    } else {
        let started = Instant::now();
        let piece = side / MOSAIC_GRID;
        if !data.mosaic_dir.exists() {
            let partial = dir.join("mosaic.partial");
            if partial.exists() {
                std::fs::remove_dir_all(&partial)?;
            }
            std::fs::create_dir_all(&partial)?;
            for row in 0..MOSAIC_GRID {
                for col in 0..MOSAIC_GRID {
                    write_square(&partial.join(mosaic_name(row, col)), col * piece, row * piece, piece)?;
                }
            }
            std::fs::rename(&partial, &data.mosaic_dir)?;
        }
        // Relative paths, so the VRT names its files relative to itself.
        let files: Vec<String> = (0..MOSAIC_GRID * MOSAIC_GRID)
            .map(|k| format!("mosaic/{}", mosaic_name(k / MOSAIC_GRID, k % MOSAIC_GRID)))
            .collect();
        run_tool(
            Command::new("/usr/bin/gdalbuildvrt").current_dir(&dir).args(["-q", "mosaic.partial.vrt"]).args(&files),
        )?;
        std::fs::rename(dir.join("mosaic.partial.vrt"), &data.vrt)?;
        println!("mosaic.vrt: made in {:.1} s ({})", started.elapsed().as_secs_f64(), data.vrt.display());
    }
    Ok(data)
}

fn mosaic_name(row: usize, col: usize) -> String {
    format!("dem_{row:02}_{col:02}.tif")
}

// ---------------------------------------------------------------- edits

/// Adds `bump_m` to pixels [x, x + EDIT_SIDE) x [y, y + EDIT_SIDE) of band 1
/// in update mode, then sets each overview's window to the 2 x 2 average of
/// the level below (nodata left out), and closes.
fn edit_window(path: &Path, x: usize, y: usize, bump_m: i16) -> anyhow::Result<()> {
    let options = DatasetOptions {
        open_flags: GdalOpenFlags::GDAL_OF_UPDATE | GdalOpenFlags::GDAL_OF_RASTER,
        ..DatasetOptions::default()
    };
    let ds = Dataset::open_ex(path, options).with_context(|| format!("cannot open {} for update", path.display()))?;
    let mut band = ds.rasterband(1)?;
    let window = (EDIT_SIDE, EDIT_SIDE);
    let origin = (x as isize, y as isize);
    let (_, old) = band.read_as::<i16>(origin, window, window, None)?.into_shape_and_vec();
    let new = old.iter().map(|&h| if h == NODATA { h } else { h.saturating_add(bump_m) }).collect();
    band.write(origin, window, &mut Buffer::new(window, new))?;
    // The window at the level below: [x0, x1) x [y0, y1).
    let (mut x0, mut y0, mut x1, mut y1) = (x, y, x + EDIT_SIDE, y + EDIT_SIDE);
    for level in 0..band.overview_count()? as usize {
        let below = if level == 0 { ds.rasterband(1)? } else { band.overview(level - 1)? };
        let mut over = band.overview(level)?;
        let ((bw, bh), (ow, oh)) = (below.size(), over.size());
        let (ox0, oy0, ox1, oy1) = (x0 / 2, y0 / 2, x1.div_ceil(2).min(ow), y1.div_ceil(2).min(oh));
        let (bx0, by0, bx1, by1) = (2 * ox0, 2 * oy0, (2 * ox1).min(bw), (2 * oy1).min(bh));
        let (rw, rh) = (bx1 - bx0, by1 - by0);
        let (_, src) =
            below.read_as::<i16>((bx0 as isize, by0 as isize), (rw, rh), (rw, rh), None)?.into_shape_and_vec();
        let (w, h) = (ox1 - ox0, oy1 - oy0);
        let mut averaged = Vec::with_capacity(w * h);
        for j in 0..h {
            for i in 0..w {
                let (mut sum, mut n) = (0i32, 0i32);
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (sx, sy) = (2 * i + dx, 2 * j + dy);
                    if sx < rw && sy < rh && src[sy * rw + sx] != NODATA {
                        sum += i32::from(src[sy * rw + sx]);
                        n += 1;
                    }
                }
                averaged.push(if n == 0 { NODATA } else { (f64::from(sum) / f64::from(n)).round() as i16 });
            }
        }
        over.write((ox0 as isize, oy0 as isize), (w, h), &mut Buffer::new((w, h), averaged))?;
        (x0, y0, x1, y1) = (ox0, oy0, ox1, oy1);
    }
    ds.close()?;
    Ok(())
}

/// Where an edit goes: its window in global pixels and in its mosaic file.
#[derive(Clone, Copy)]
struct Window {
    row: usize,
    col: usize,
    x: usize,
    y: usize,
}

/// `n` windows, each wholly inside one mosaic file.
fn windows(side: usize, n: usize) -> Vec<Window> {
    let piece = side / MOSAIC_GRID;
    let mut rng = Lcg(0x00B1_6DE3);
    (0..n)
        .map(|_| {
            let row = rng.range(0.0, MOSAIC_GRID as f64) as usize;
            let col = rng.range(0.0, MOSAIC_GRID as f64) as usize;
            let x = rng.range(0.0, (piece - EDIT_SIDE) as f64) as usize;
            let y = rng.range(0.0, (piece - EDIT_SIDE) as f64) as usize;
            Window { row, col, x, y }
        })
        .collect()
}

// ---------------------------------------------------------------- serving

/// Tiles reliefd has handed to its disk store so far (the state's counter).
async fn disk_writes(channel: &Channel) -> anyhow::Result<u64> {
    let counters = common::state(channel).await?.counters.unwrap_or_default();
    Ok(counters.outer_stores.iter().find(|o| o.name == "disk").map_or(0, |o| o.writes))
}

#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Big,
    /// big.tif with `change_detection = "exact"` (every block's compressed bytes hashed).
    BigExact,
    Mosaic,
}

struct Run {
    label: &'static str,
    size_bytes: u64,
    first_frame_ms: f64,
    first_frame_blocks: u32,
    flight_frame_ms: f64,
    rss_mb: f64,
    hwm_mb: f64,
    edits_ms: Vec<f64>,
    /// From the edited file's close (GDAL done writing) to the generation.
    saved_ms: Vec<f64>,
    rebuilt: Vec<u64>,
    /// Tiles handed to the disk store during the edits, and in the 3 s after.
    disk_writes: (u64, u64),
    /// Why the edits stopped early, if they did.
    edits_stopped: Option<String>,
    stop_note: Option<String>,
}

fn camera(lon: f64, lat: f64, altitude_m: f64, heading_deg: f64, pitch_deg: f64) -> pb::Camera {
    pb::Camera { lon_deg: lon, lat_deg: lat, altitude_m, heading_deg, pitch_deg, roll_deg: 0.0, vertical_fov_deg: 50.0 }
}

async fn render(channel: &Channel, camera: pb::Camera) -> Result<pb::RenderResponse, tonic::Status> {
    let request = pb::RenderRequest {
        camera: Some(camera),
        width: FRAME.0,
        height: FRAME.1,
        format: pb::ImageFormat::Png as i32,
        ..Default::default()
    };
    Ok(ViewServiceClient::new(channel.clone()).max_decoding_message_size(64 << 20).render(request).await?.into_inner())
}

/// VmRSS and VmHWM of `pid`, in MB.
fn memory_mb(pid: u32) -> (f64, f64) {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
            .map_or(f64::NAN, |kb| kb / 1024.0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

/// How far south of the centre the first frame's camera stands, degrees.
fn first_back_deg(side: usize) -> f64 {
    (side as f64 * PIXEL_DEG / 4.0).min(0.1)
}

fn raster_mb() -> Option<usize> {
    RASTER_BUDGET_OPTION.then(|| env_usize("RELIEF_BIGDEM_RASTER_MB", 512))
}

async fn serve(kind: Kind, data: &Data, side: usize, windows: &[Window], edits: usize) -> anyhow::Result<Run> {
    let (label, path) = match kind {
        Kind::Big => ("big.tif", &data.big),
        Kind::BigExact => ("big.tif, change_detection = exact", &data.big),
        Kind::Mosaic => ("mosaic.vrt (20 x 20 files)", &data.vrt),
    };
    let changes = if kind == Kind::BigExact { "change_detection = \"exact\"\n" } else { "" };
    let size_bytes = match kind {
        Kind::Big | Kind::BigExact => std::fs::metadata(&data.big)?.len(),
        Kind::Mosaic => std::fs::metadata(&data.vrt)?.len() + dir_size(&data.mosaic_dir)?,
    };
    let scene = tempfile::tempdir()?;
    let raster = raster_mb().map(|mb| format!("raster_mb = {mb}\n")).unwrap_or_default();
    let manifest = relief_examples::write_manifest(
        scene.path(),
        &format!(
            "[scene]\nname = \"bigdem\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"{}\"\n{changes}\n[layers]\nheight = \"dem\"\n\n[cache]\nmemory_mb = {MEMORY_MB}\n{raster}",
            path.display()
        ),
    )?;
    let extent_deg = side as f64 * PIXEL_DEG;
    let (centre_lon, centre_lat) = (WEST_DEG + extent_deg / 2.0, NORTH_DEG - extent_deg / 2.0);

    // Start to first frame: south of the centre, 8 km up, looking north.
    let started = Instant::now();
    let mut daemon = Reliefd::start(&manifest, &[])?;
    let channel = daemon.channel().await?;
    let back_deg = first_back_deg(side);
    let first = loop {
        match render(&channel, camera(centre_lon, centre_lat - back_deg, 8000.0, 0.0, -30.0)).await {
            Ok(frame) => break frame,
            Err(status) => {
                anyhow::ensure!(
                    daemon.is_running(),
                    "{label}: reliefd exited before its first frame: {}",
                    daemon.log().join("\n")
                );
                anyhow::ensure!(
                    started.elapsed() < Duration::from_secs(1800),
                    "{label}: no frame within 30 min: {status}"
                );
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        }
    };
    let first_frame_ms = started.elapsed().as_secs_f64() * 1e3;
    let first_frame_blocks = first.drawn.map_or(0, |d| d.terrain_blocks_drawn);

    // The flight: north-west to south-east at 4500 m, 15 degrees down.
    let margin = extent_deg * 0.05;
    let (lon0, lat0) = (WEST_DEG + margin, NORTH_DEG - margin);
    let (lon1, lat1) = (WEST_DEG + extent_deg - margin, NORTH_DEG - extent_deg + margin);
    let heading_deg = ((lon1 - lon0) * centre_lat.to_radians().cos()).atan2(lat1 - lat0).to_degrees().rem_euclid(360.0);
    let mut frame_ms = Vec::new();
    for k in 0..FLIGHT_FRAMES {
        let t = k as f64 / (FLIGHT_FRAMES - 1) as f64;
        let cam = camera(lon0 + t * (lon1 - lon0), lat0 + t * (lat1 - lat0), 4500.0, heading_deg, -15.0);
        let t0 = Instant::now();
        render(&channel, cam).await?;
        frame_ms.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    frame_ms.sort_by(f64::total_cmp);
    let (rss_mb, hwm_mb) = memory_mb(daemon.pid());

    // Edits: pairs of a bump and its removal on the same window.
    let disk_before = disk_writes(&channel).await?;
    let events = Events::follow(channel.clone()).await?;
    let mut generation = common::state(&channel).await?.generation;
    let (mut edits_ms, mut rebuilt, mut edits_stopped) = (Vec::new(), Vec::new(), None);
    let mut saved_ms = Vec::new();
    for k in 0..edits.next_multiple_of(2) {
        let w = windows[k / 2];
        let bump = if k % 2 == 0 { BUMP_M } else { -BUMP_M };
        let (file, x, y) = match kind {
            Kind::Big | Kind::BigExact => {
                (data.big.clone(), w.col * (side / MOSAIC_GRID) + w.x, w.row * (side / MOSAIC_GRID) + w.y)
            }
            Kind::Mosaic => (data.mosaic_dir.join(mosaic_name(w.row, w.col)), w.x, w.y),
        };
        let t0 = Instant::now();
        edit_window(&file, x, y, bump)?;
        let saved = Instant::now();
        if std::env::var_os("RELIEF_BIGDEM_LOG").is_some() {
            println!("bench: saved at {:?}", std::time::SystemTime::now());
        }
        if k >= edits {
            // The untimed removal of the last bump.
            break;
        }
        match edit::wait_for(channel.clone(), generation + 1).await {
            Ok(state) => {
                edits_ms.push(t0.elapsed().as_secs_f64() * 1e3);
                saved_ms.push(saved.elapsed().as_secs_f64() * 1e3);
                generation = state.generation;
                rebuilt.push(events.generation(generation).await.map_or(0, |g| g.tiles_rebuilt));
            }
            Err(e) => {
                edits_stopped = Some(format!("edit {} of {edits}: {e:#}", k + 1));
                if k % 2 == 0 {
                    edit_window(&file, x, y, -bump)?;
                }
                break;
            }
        }
    }
    if std::env::var_os("RELIEF_BIGDEM_LOG").is_some() {
        // RELIEF_TEST_LOG sets reliefd's RUST_LOG; this prints what it said.
        for line in daemon.log() {
            println!("reliefd: {line}");
        }
    }
    // What the edits handed to the disk store, then in the 3 s after
    // (reliefd writes a source's cached tiles once the scene is still).
    let disk_during = disk_writes(&channel).await? - disk_before;
    tokio::time::sleep(Duration::from_secs(3)).await;
    let disk_after = disk_writes(&channel).await? - disk_before - disk_during;
    let stop_note = daemon.stop(&[]).err().map(|e| format!("{e:#}"));
    Ok(Run {
        label,
        size_bytes,
        first_frame_ms,
        first_frame_blocks,
        flight_frame_ms: percentile(&frame_ms, 0.5),
        rss_mb,
        hwm_mb,
        edits_ms,
        saved_ms,
        rebuilt,
        edits_stopped,
        stop_note,
        disk_writes: (disk_during, disk_after),
    })
}

fn main() -> anyhow::Result<()> {
    let side = env_usize("RELIEF_BIGDEM_SIDE", 40_000);
    let edits = env_usize("RELIEF_BIGDEM_EDITS", 25).max(1);
    anyhow::ensure!(
        side.is_multiple_of(MOSAIC_GRID) && side / MOSAIC_GRID >= 2 * EDIT_SIDE,
        "RELIEF_BIGDEM_SIDE must be a multiple of {MOSAIC_GRID} and at least {} (got {side})",
        MOSAIC_GRID * 2 * EDIT_SIDE
    );
    // The bench's own GDAL block cache, while it writes and edits.
    gdal::config::set_config_option("GDAL_CACHEMAX", "256")?;
    println!("\n## Rasters larger than memory: a {side} x {side} Int16 DEM, one file and a 20 x 20 mosaic");
    let data = make_data(side)?;
    if std::env::var_os("RELIEF_BIGDEM_MAKE_ONLY").is_some() {
        return Ok(());
    }
    let windows = windows(side, edits.div_ceil(2));
    let runtime = tokio::runtime::Runtime::new()?;
    // RELIEF_BIGDEM_ONLY: the datasets to serve (commas: big, exact, mosaic).
    let runs = [(Kind::Big, "big"), (Kind::BigExact, "exact"), (Kind::Mosaic, "mosaic")]
        .into_iter()
        .filter(|(_, name)| common::wanted("RELIEF_BIGDEM_ONLY", name))
        .map(|(kind, _)| kind)
        .map(|kind| runtime.block_on(serve(kind, &data, side, &windows, edits)))
        .collect::<anyhow::Result<Vec<Run>>>()?;

    let budget = match raster_mb() {
        Some(mb) => format!("[cache] memory_mb = {MEMORY_MB}, raster_mb = {mb}"),
        None => format!("[cache] memory_mb = {MEMORY_MB} (raster_mb left out: RASTER_BUDGET_OPTION is off)"),
    };
    let budget_mb = MEMORY_MB as usize + raster_mb().unwrap_or(0);
    println!("machine: {}", relief_tests::machine());
    println!(
        "reliefd: {budget}; first frame {}x{} from 8000 m, {:.0} km south of the centre, 30 degrees down; flight {FLIGHT_FRAMES} frames NW to SE at 4500 m; {edits} edits of {EDIT_SIDE} x {EDIT_SIDE} (+/-{BUMP_M} m, overviews updated)",
        FRAME.0,
        FRAME.1,
        first_back_deg(side) * 111.3
    );
    println!(
        "goals: start to first frame under 2000 ms; VmRSS at most the cache budgets + 300 MB ({} MB); edit to generation p50 under 30 ms",
        budget_mb + 300
    );
    println!(
        "| dataset | size on disk MB | start to first frame ms | flight frame ms (median) | VmRSS after flight MB | VmHWM MB | edit to generation p50 ms | p95 ms | save to generation p50 ms | p95 ms | edits | tiles rebuilt per edit (mean) | tiles to disk during the edits / 3 s after |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for r in &runs {
        let mut sorted = r.edits_ms.clone();
        sorted.sort_by(f64::total_cmp);
        let mut saved = r.saved_ms.clone();
        saved.sort_by(f64::total_cmp);
        let (s50, s95) = if saved.is_empty() {
            ("-".to_owned(), "-".to_owned())
        } else {
            (format!("{:.1}", percentile(&saved, 0.5)), format!("{:.1}", percentile(&saved, 0.95)))
        };
        let (p50, p95, rebuilt) = if sorted.is_empty() {
            ("-".to_owned(), "-".to_owned(), "-".to_owned())
        } else {
            let mean_rebuilt = r.rebuilt.iter().sum::<u64>() as f64 / r.rebuilt.len() as f64;
            (
                format!("{:.1}", percentile(&sorted, 0.5)),
                format!("{:.1}", percentile(&sorted, 0.95)),
                format!("{mean_rebuilt:.1}"),
            )
        };
        println!(
            "| {} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {p50} | {p95} | {s50} | {s95} | {} | {rebuilt} | {} / {} |",
            r.label,
            r.size_bytes as f64 / 1e6,
            r.first_frame_ms,
            r.flight_frame_ms,
            r.rss_mb,
            r.hwm_mb,
            sorted.len(),
            r.disk_writes.0,
            r.disk_writes.1,
        );
    }
    for r in &runs {
        if r.first_frame_blocks == 0 {
            println!("note: {}: the first frame drew no terrain blocks", r.label);
        }
        if let Some(why) = &r.edits_stopped {
            println!("note: {}: edits stopped, no new generation: {why}", r.label);
        }
        if let Some(why) = &r.stop_note {
            println!("note: {}: {why}", r.label);
        }
    }
    Ok(())
}
