//! `[quality] resampling`: the kernel that warps a raster into the grid.
//! A DEM written from a sum of plane waves, read at a level finer than its
//! pixels (the kernels interpolate) and at one coarser (they read a mip
//! level and interpolate that); every tile sample compared with the waves
//! at the sample's own position, in f64.

use relief_examples::{RasterSpec, write_dem, write_manifest};
use relief_source::{Payload, Quality, Resampling, TileKey};

use super::data::{ErrorStats, NO_DISK_CACHE, forget, source_index, timed_tile};
use super::{Context, median};
use crate::sweep::{Row, Sweep};

/// A plane wave over (lon, lat) degrees: amplitude m, wavelength degrees,
/// direction degrees (counter-clockwise from east), phase radians.
type Wave = (f64, f64, f64, f64);

/// Wavelengths 5 to 30 pixels of the coarse DEM (0.01 degrees).
const COARSE_WAVES: [Wave; 4] =
    [(300.0, 0.3, 20.0, 0.3), (200.0, 0.13, 75.0, 1.1), (120.0, 0.08, 130.0, 2.0), (60.0, 0.05, 200.0, 0.7)];

/// Broad waves, one of 24 pixels of the fine DEM (0.0005 degrees), and two
/// of about 3 pixels: finer than the coarse level's samples can hold.
const FINE_WAVES: [Wave; 6] = [
    (300.0, 0.11, 20.0, 0.3),
    (200.0, 0.05, 75.0, 1.1),
    (100.0, 0.03, 130.0, 2.0),
    (50.0, 0.012, 200.0, 0.7),
    (30.0, 0.0016, 160.0, 0.4),
    (20.0, 0.0011, 45.0, 1.9),
];

/// The surface: 1000 m plus the waves at least `shortest` degrees long.
fn surface(waves: &[Wave], shortest: f64, lon: f64, lat: f64) -> f64 {
    let mut h = 1000.0;
    for &(amplitude, wavelength, direction, phase) in waves {
        if wavelength < shortest {
            continue;
        }
        let (s, c) = direction.to_radians().sin_cos();
        h += amplitude * (std::f64::consts::TAU * (lon * c + lat * s) / wavelength + phase).sin();
    }
    h
}

/// One case: a DEM, the tiles read from it, and which waves a tile should hold.
struct Case {
    name: &'static str,
    sentence: &'static str,
    waves: &'static [Wave],
    spec: RasterSpec<'static>,
    level: u8,
    /// Tile columns and rows at `level`, all well inside the DEM.
    columns: std::ops::Range<u32>,
    rows: std::ops::Range<u32>,
}

const ROUNDS: usize = 5;

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    let up = Case {
        name: "resampling (upsampling 3.6x)",
        sentence: "A 300 x 300 DEM of 0.01-degree pixels (EPSG:4326) written from four plane waves 5 to 30 pixels \
                   long (60 to 300 m high), read at level 8 of the geodetic grid (samples of 0.0027 degrees, 3.6 \
                   to a pixel): 9 tiles of 257 x 257 samples, every one at least 29 pixels inside the DEM.",
        waves: &COARSE_WAVES,
        spec: RasterSpec {
            width: 300,
            height: 300,
            origin_x: 10.0,
            origin_y: 47.0,
            pixel: 0.01,
            crs: "EPSG:4326",
            nodata: None,
        },
        level: 8,
        columns: 271..274,
        rows: 62..65,
    };
    let down = Case {
        name: "resampling (downsampling 2.7x)",
        sentence: "A 2500 x 2500 DEM of 0.0005-degree pixels (EPSG:4326) written from four broad plane waves (12 to \
                   220 pixels long) and two of about 3 pixels, read at level 9 of the geodetic grid (samples of \
                   0.00137 degrees, 2.7 pixels each: the source reads its mip level 1, of 2 x 2 pixels): 9 tiles well inside \
                   the DEM.",
        waves: &FINE_WAVES,
        spec: RasterSpec {
            width: 2500,
            height: 2500,
            origin_x: 10.1,
            origin_y: 45.8,
            pixel: 0.0005,
            crs: "EPSG:4326",
            nodata: None,
        },
        level: 9,
        columns: 541..544,
        rows: 126..129,
    };
    let mut sweeps = Vec::new();
    for (n, case) in [up, down].into_iter().enumerate() {
        sweeps.push(sweep(cx, &case, n)?);
    }
    Ok(sweeps)
}

fn sweep(cx: &Context, case: &Case, n: usize) -> anyhow::Result<Sweep> {
    let dir = cx.dir.path().join(format!("resampling-{n}"));
    std::fs::create_dir_all(&dir)?;
    let waves = case.waves;
    write_dem(&dir.join("dem.tif"), &case.spec, |lon, lat| surface(waves, 0.0, lon, lat))?;
    let manifest = write_manifest(
        &dir,
        &format!(
            "[scene]\nname = \"resampling\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"dem.tif\"\n\n\
             [layers]\nheight = \"dem\"\n{NO_DISK_CACHE}"
        ),
    )?;
    let scene = cx.load(&manifest)?;
    let snap = scene.snapshot();
    let dem = source_index(&snap, "dem")?;
    let keys: Vec<TileKey> =
        case.rows.clone().flat_map(|y| case.columns.clone().map(move |x| TileKey::new(case.level, x, y))).collect();
    // What a tile's samples can hold: waves at least 4 samples long (none
    // of the waves lies between 2 and 4).
    let step = snap.grid.sample_step(case.level);
    let shortest = 4.0 * step;
    let dropped = waves.iter().filter(|w| w.1 < shortest).count();
    // The raster's mip levels are made on first use: made here, not timed.
    for &key in &keys {
        timed_tile(&scene, &snap, dem, key, &Quality::default())?;
    }
    // Rounds outside, kernels inside: a busy spell on the machine falls on
    // every kernel alike.
    let mut times = vec![Vec::new(); Resampling::ALL.len()];
    let mut stats = vec![ErrorStats::default(); Resampling::ALL.len()];
    for round in 0..ROUNDS {
        forget(&scene, &snap, dem);
        for (k, kernel) in Resampling::ALL.into_iter().enumerate() {
            let quality = Quality { resampling: kernel, ..Quality::default() };
            for &key in &keys {
                let (ms, payload) = timed_tile(&scene, &snap, dem, key, &quality)?;
                times[k].push(ms);
                if round > 0 {
                    continue;
                }
                let Payload::Height(tile) = payload.as_ref() else {
                    anyhow::bail!("source 'dem' gave no height tile for {key}");
                };
                let lattice = snap.grid.lattice(key, relief_source::SampleKind::Corner);
                for j in 0..lattice.rows {
                    for i in 0..lattice.cols {
                        let h = f64::from(tile.get(i, j));
                        anyhow::ensure!(h.is_finite(), "tile {key} has no height at sample ({i}, {j})");
                        stats[k].add(h - surface(waves, shortest, lattice.x(i), lattice.y(j)));
                    }
                }
            }
        }
    }
    let rows: Vec<Row> = Resampling::ALL
        .into_iter()
        .zip(times)
        .zip(&stats)
        .map(|((kernel, times), stats)| {
            Row::new(kernel.name(), median(times), stats.rms())
                .default_if(kernel == Quality::default().resampling)
                .with("max error m", format!("{:.2}", stats.max()))
                .with("samples", stats.count().to_string())
        })
        .collect();
    let rms = |name: &str| rows.iter().find(|r| r.setting == name).map_or((f64::NAN, f64::NAN), |r| (r.error, r.time));
    let (bilinear, cubic, lanczos, nearest) = (rms("bilinear"), rms("cubic"), rms("lanczos"), rms("nearest"));
    let best = rows.iter().min_by(|a, b| a.error.total_cmp(&b.error)).map_or("?", |r| r.setting.as_str());
    let why = if n == 0 {
        format!(
            "Finer than the data the kernels differ most: nearest leaves steps ({:.1} m RMS), bilinear cuts the \
             waves' crests ({:.2} m), cubic ({:.2} m) and lanczos ({:.2} m) follow them. Bilinear stays the default: \
             it costs {:.2} ms a tile against cubic's {:.2} and lanczos' {:.2}, it is the better kernel below the \
             data's resolution (the downsampling case), and it cannot overshoot, where cubic and lanczos weigh \
             some pixels negatively and ring past a cliff or a nodata edge (which these smooth waves do not \
             test). A scene of smooth terrain seen mostly closer than its pixels gains from \
             `resampling = \"cubic\"` ({:.1} times less error here).",
            nearest.0,
            bilinear.0,
            cubic.0,
            lanczos.0,
            bilinear.1,
            cubic.1,
            lanczos.1,
            bilinear.0 / cubic.0
        )
    } else {
        format!(
            "Coarser than the data a tile reads a mip level (2 x 2 means) and interpolates that. The means leave \
             part of the 3-pixel waves in, and the sharper a kernel the more of that remainder it passes on: \
             against the {} waves the samples can hold, bilinear is off by {:.2} m RMS, cubic by {:.2} m, lanczos \
             by {:.2} m, nearest by {:.2} m; the most accurate here is {best}. Bilinear costs {:.2} ms a tile \
             against cubic's {:.2} and lanczos' {:.2}.",
            waves.len() - dropped,
            bilinear.0,
            cubic.0,
            lanczos.0,
            nearest.0,
            bilinear.1,
            cubic.1,
            lanczos.1
        )
    };
    Ok(Sweep {
        knob: case.name.into(),
        case: case.sentence.into(),
        reference: if dropped == 0 {
            "the waves the DEM was written from, at each sample's position (f64)".into()
        } else {
            format!(
                "the waves the DEM was written from that are at least 4 samples long ({} of {}; the {dropped} finer \
                 ones no tile of this level can hold), at each sample's position (f64)",
                waves.len() - dropped,
                waves.len()
            )
        },
        error: "RMS height error over every sample of the tiles, m".into(),
        time: format!("ms per tile generated (257 x 257 samples), median of {} ({ROUNDS} rounds)", keys.len() * ROUNDS),
        rows,
        why_default: why,
    })
}
