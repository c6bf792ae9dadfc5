//! `[quality] reprojection_error_px`: how far the interpolated mapping from
//! grid samples to a raster's pixels may stray before the gdal source
//! transforms a finer lattice exactly (0: PROJ for every sample). Two
//! rasters where the mapping bends: a polar stereographic DEM read on the
//! geodetic grid round the pole, and a UTM zone 32 DEM reaching far east
//! of its zone. Beside each DEM two more rasters whose values are their own
//! pixel column and row: bilinear interpolation reproduces a linear ramp
//! exactly, so their tiles tell where each sample really read the raster.

use std::collections::HashMap;
use std::fmt::Write as _;

use relief_examples::{RasterSpec, write_dem, write_manifest};
use relief_source::{Payload, Quality, SampleKind, TileKey};

use super::data::{ErrorStats, NO_DISK_CACHE, Proj, forget, source_index, timed_tile};
use super::{Context, median};
use crate::sweep::{Row, Sweep};

const THRESHOLDS_PX: [f64; 8] = [0.0, 0.01, 0.05, 0.125, 0.5, 1.0, 2.0, 4.0];

/// Samples closer than this to the DEM's edge (in its pixels) are not
/// compared: the kernels clamp there, and the ramps stop being linear.
const MARGIN_PX: f64 = 24.0;

const ROUNDS: usize = 3;

struct Case {
    name: &'static str,
    sentence: &'static str,
    spec: RasterSpec<'static>,
    /// Heights as a function of (lon, lat), degrees.
    height: fn(f64, f64) -> f64,
    keys: Vec<TileKey>,
}

/// Smooth over the pole: a function of the unit vector's x and y, 28 and
/// 27 m/km at its steepest (56 m a pixel).
fn polar_height(lon: f64, lat: f64) -> f64 {
    let (x, y) = (lat.to_radians().cos() * lon.to_radians().cos(), lat.to_radians().cos() * lon.to_radians().sin());
    2000.0 + 1500.0 * (120.0 * x + 0.3).sin() * (90.0 * y - 0.2).cos() + 400.0 * (300.0 * (x + y) + 1.0).sin()
}

/// Waves 0.9 and 0.35 degrees long: up to 80 m/km (40 m a pixel).
fn utm_height(lon: f64, lat: f64) -> f64 {
    use std::f64::consts::TAU;
    1500.0
        + 800.0 * (TAU * lon / 0.9 + 0.4).sin() * (TAU * lat / 0.7 - 0.3).cos()
        + 300.0 * (TAU * (lon + lat) / 0.35 + 1.2).sin()
}

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    let polar = Case {
        name: "reprojection_error_px (polar stereographic)",
        sentence: "A 1500 x 1500 DEM of 2 km pixels in EPSG:3413 (NSIDC polar stereographic north), 3000 km across \
                   the pole, its heights a smooth function of geodetic position (up to 28 m/km, 56 m a pixel), read \
                   on the geodetic grid: the 16 tiles of level 3 round the pole (67.5 to 90 N, samples of 0.088 \
                   degrees; the source reads its mip level 2, of 4 x 4 pixels).",
        spec: RasterSpec {
            width: 1500,
            height: 1500,
            origin_x: -1_500_000.0,
            origin_y: 1_500_000.0,
            pixel: 2000.0,
            crs: "EPSG:3413",
            nodata: None,
        },
        height: polar_height,
        keys: (0..16).map(|x| TileKey::new(3, x, 0)).collect(),
    };
    let utm = Case {
        name: "reprojection_error_px (UTM far outside its zone)",
        sentence: "A 1960 x 1590 DEM of 500 m pixels in EPSG:32632 (UTM zone 32N, 6 to 12 E) spanning 5.6 to 18.5 E \
                   and 47.3 to 54 N, so most of it lies east of its zone; heights from waves of geodetic position \
                   (up to 80 m/km), read on the geodetic grid: the 10 tiles of level 6 over it (samples of 0.011 \
                   degrees; the source reads its mip level 1, of 2 x 2 pixels).",
        spec: RasterSpec {
            width: 1960,
            height: 1590,
            origin_x: 240_000.0,
            origin_y: 6_030_000.0,
            pixel: 500.0,
            crs: "EPSG:32632",
            nodata: None,
        },
        height: utm_height,
        keys: (13..15).flat_map(|y| (66..71).map(move |x| TileKey::new(6, x, y))).collect(),
    };
    let mut sweeps = Vec::new();
    for (n, case) in [polar, utm].into_iter().enumerate() {
        sweeps.push(sweep(cx, &case, n)?);
    }
    Ok(sweeps)
}

/// What one tile's samples are compared with: each sample's exact pixel
/// coordinates in the DEM and its formula height, None where the sample
/// is off the DEM or too near its edge.
type Truth = Vec<Option<(f64, f64, f64)>>;

fn write_case(dir: &std::path::Path, case: &Case) -> anyhow::Result<std::path::PathBuf> {
    std::fs::create_dir_all(dir)?;
    let spec = &case.spec;
    let (mut lons, mut lats): (Vec<f64>, Vec<f64>) = spec.pixels().unzip();
    Proj::new(spec.crs, "EPSG:4326")?.apply(&mut lons, &mut lats)?;
    let index = |x: f64, y: f64| {
        let i = ((x - spec.origin_x) / spec.pixel - 0.5).round() as usize;
        let j = ((spec.origin_y - y) / spec.pixel - 0.5).round() as usize;
        j * spec.width + i
    };
    write_dem(&dir.join("dem.tif"), spec, |x, y| {
        let k = index(x, y);
        (case.height)(lons[k], lats[k])
    })?;
    // Pixel-edge coordinates of each pixel's centre: i + 0.5, j + 0.5.
    write_dem(&dir.join("u.tif"), spec, |x, _| (x - spec.origin_x) / spec.pixel)?;
    write_dem(&dir.join("v.tif"), spec, |_, y| (spec.origin_y - y) / spec.pixel)?;
    let mut text = String::from("[scene]\nname = \"reprojection\"\n");
    for id in ["dem", "u", "v"] {
        let _ = write!(text, "\n[[source]]\nid = \"{id}\"\nkind = \"gdal\"\npath = \"{id}.tif\"\n");
    }
    text.push_str("\n[layers]\nheight = \"dem\"\n");
    text.push_str(NO_DISK_CACHE);
    write_manifest(dir, &text)
}

fn sweep(cx: &Context, case: &Case, n: usize) -> anyhow::Result<Sweep> {
    let manifest = write_case(&cx.dir.path().join(format!("reprojection-{n}")), case)?;
    let scene = cx.load(&manifest)?;
    let snap = scene.snapshot();
    let [dem, u, v] = ["dem", "u", "v"].map(|id| source_index(&snap, id));
    let (dem, u, v) = (dem?, u?, v?);
    let spec = &case.spec;
    let to_dem = Proj::new("EPSG:4326", spec.crs)?;
    let mut truth: HashMap<TileKey, Truth> = HashMap::new();
    for &key in &case.keys {
        let lattice = snap.grid.lattice(key, SampleKind::Corner);
        let (mut xs, mut ys): (Vec<f64>, Vec<f64>) =
            (0..lattice.rows).flat_map(|j| (0..lattice.cols).map(move |i| (lattice.x(i), lattice.y(j)))).unzip();
        let (lons, lats) = (xs.clone(), ys.clone());
        to_dem.apply(&mut xs, &mut ys)?;
        let inside = |c: f64, size: usize| (MARGIN_PX..=size as f64 - MARGIN_PX).contains(&c);
        let t = (0..xs.len())
            .map(|k| {
                let (pu, pv) = ((xs[k] - spec.origin_x) / spec.pixel, (spec.origin_y - ys[k]) / spec.pixel);
                (inside(pu, spec.width) && inside(pv, spec.height)).then(|| (pu, pv, (case.height)(lons[k], lats[k])))
            })
            .collect();
        truth.insert(key, t);
    }
    // Transforms and mip levels are made on first use: made here, not timed.
    let warm = Quality { reprojection_error_px: 3.0, ..Quality::default() };
    for &key in &case.keys {
        for source in [dem, u, v] {
            timed_tile(&scene, &snap, source, key, &warm)?;
        }
    }
    let heights = |payload: &Payload, key: TileKey| -> anyhow::Result<Vec<f32>> {
        match payload {
            Payload::Height(t) => Ok(t.heights.clone()),
            _ => anyhow::bail!("no height tile for {key}"),
        }
    };
    // Rounds outside, thresholds inside: a busy spell on the machine falls
    // on every threshold alike. The exact tiles (0 px) come first.
    let mut exact: HashMap<TileKey, Vec<f32>> = HashMap::new();
    let mut times = vec![Vec::new(); THRESHOLDS_PX.len()];
    let mut stats = vec![[ErrorStats::default(); 3]; THRESHOLDS_PX.len()];
    for round in 0..ROUNDS {
        forget(&scene, &snap, dem);
        for (t, threshold) in THRESHOLDS_PX.into_iter().enumerate() {
            let quality = Quality { reprojection_error_px: threshold, ..Quality::default() };
            for &key in &case.keys {
                let (ms, payload) = timed_tile(&scene, &snap, dem, key, &quality)?;
                times[t].push(ms);
                if round > 0 {
                    continue;
                }
                let h = heights(&payload, key)?;
                let us = heights(&timed_tile(&scene, &snap, u, key, &quality)?.1, key)?;
                let vs = heights(&timed_tile(&scene, &snap, v, key, &quality)?.1, key)?;
                let reference = exact.entry(key).or_insert_with(|| h.clone());
                let [against_exact, against_formula, position] = &mut stats[t];
                for (k, truth) in truth[&key].iter().enumerate() {
                    let Some((pu, pv, formula)) = *truth else { continue };
                    if h[k].is_nan() {
                        continue;
                    }
                    against_exact.add(f64::from(h[k]) - f64::from(reference[k]));
                    against_formula.add(f64::from(h[k]) - formula);
                    position.add((f64::from(us[k]) - pu).hypot(f64::from(vs[k]) - pv));
                }
            }
        }
    }
    let compared = stats[0][0].count();
    let rows: Vec<Row> = THRESHOLDS_PX
        .into_iter()
        .zip(times)
        .zip(&stats)
        .map(|((threshold, times), [against_exact, against_formula, position])| {
            Row::new(format_threshold(threshold), median(times), against_exact.max())
                .default_if(threshold == Quality::default().reprojection_error_px)
                .with("RMS vs exact m", format!("{:.3}", against_exact.rms()))
                .with("max position error px", format!("{:.4}", position.max()))
                .with("RMS position error px", format!("{:.4}", position.rms()))
                .with("RMS vs formula m", format!("{:.2}", against_formula.rms()))
        })
        .collect();
    let why = why_default(&rows, &THRESHOLDS_PX, n);
    Ok(Sweep {
        knob: case.name.into(),
        case: format!("{} {compared} samples compared.", case.sentence),
        reference: "the same tiles with reprojection_error_px = 0 (PROJ for every sample); the position error \
                    against PROJ run here on every sample (f64), read from two rasters holding their own pixel \
                    coordinates; the formula the DEM was written from"
            .into(),
        error: "largest height difference from the exact (0 px) tiles, m".into(),
        time: format!(
            "ms per height tile generated (257 x 257 samples), median of {} ({ROUNDS} rounds)",
            case.keys.len() * ROUNDS
        ),
        rows,
        why_default: why,
    })
}

fn format_threshold(px: f64) -> String {
    if px == 0.0 { "0 (exact)".into() } else { format!("{px} px") }
}

/// Why 0.125 px, from this sweep's numbers.
fn why_default(rows: &[Row], thresholds: &[f64], n: usize) -> String {
    let extra = |r: &Row, header: &str| {
        r.extra.iter().find(|(h, _)| h == header).map_or(f64::NAN, |(_, v)| v.parse().unwrap_or(f64::NAN))
    };
    let at = |px: f64| thresholds.iter().position(|&t| t == px).map(|i| &rows[i]);
    let (Some(exact), Some(default)) = (at(0.0), at(0.125)) else {
        return "a setting is missing from the sweep".into();
    };
    // Thresholds that gave the default's very tiles.
    let same: Vec<String> = thresholds
        .iter()
        .zip(rows)
        .filter(|(_, r)| r.error == default.error && extra(r, "RMS vs exact m") == extra(default, "RMS vs exact m"))
        .map(|(t, _)| format!("{t}"))
        .collect();
    let over: Vec<String> = thresholds
        .iter()
        .zip(rows)
        .filter(|&(&t, r)| t > 0.0 && extra(r, "max position error px") > t)
        .map(|(t, r)| format!("{} px at {t} px", extra(r, "max position error px")))
        .collect();
    let place = if n == 0 { "Round the pole" } else { "Far outside the zone" };
    let mut text = format!(
        "The source transforms every 32nd sample exactly and interpolates between, halving that step until the \
         interpolation error at the cells' centres is within the threshold, so the knob moves in steps: {} px \
         give the very same tiles here. {place} the default's samples read the DEM at most {} px from where PROJ \
         puts them: {} m of height at most and {} m RMS, against the {} m RMS the tiles are off the formula \
         anyway (the DEM's pixels and the mip level read). It costs {:.1} ms a tile against {:.1} ms for PROJ on \
         every sample.",
        same.join(", "),
        extra(default, "max position error px"),
        crate::report::number(default.error),
        extra(default, "RMS vs exact m"),
        extra(exact, "RMS vs formula m"),
        default.time,
        exact.time,
    );
    if !over.is_empty() {
        let _ = write!(
            text,
            " The threshold is checked at the cells' centres only, and the samples between can stray further: \
             measured {} (position errors in the DEM's pixels, the unit the source checks, not output samples).",
            over.join(", ")
        );
    }
    text
}
