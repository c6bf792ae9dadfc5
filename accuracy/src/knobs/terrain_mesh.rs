//! `terrain_mesh_error_m`: how far the quantized-mesh terrain under
//! `/tiles/terrain` (CesiumJS) may stray from the heights. The demo range's
//! height tiles at the terrain's finest level, meshed (RTIN) and encoded
//! (quantized-mesh-1.0 with normals) at each setting; the mesh's surface at
//! every sample against the demo's formula there, which the DEM holds.

use relief_daemon::picture::DEFAULT_TERRAIN_MESH_ERROR_M;
use relief_daemon::standard::TerrainLayer;
use relief_source::{Payload, SampleKind, TileKey};
use relief_standard_tiles::{EncodeOptions, Rtin, encode_quantized_mesh, gzip};

use super::{Context, median};
use crate::sweep::{Row, Sweep};

const SETTINGS: [f64; 9] = [0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0];
/// Meshings timed per tile and setting (the median kept).
const RUNS: usize = 3;

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    let scene = cx.load(&cx.demo)?;
    let snap = scene.snapshot();
    let layer = TerrainLayer::of(&snap, 0).map_err(|e| anyhow::anyhow!("{e}"))?;
    let grid = &snap.grid;
    let z = layer.max_zoom;
    // Eight tiles across the middle of the range.
    let (cx_lon, cx_lat) =
        (f64::midpoint(layer.data.min_x, layer.data.max_x), f64::midpoint(layer.data.min_y, layer.data.max_y));
    let centre = grid.key_at(z, cx_lon, cx_lat).ok_or_else(|| anyhow::anyhow!("no tile at the data's centre"))?;
    let keys: Vec<TileKey> = (0..8).map(|k| TileKey::new(z, centre.x + k % 4 - 2, centre.y + k / 4)).collect();
    let quality = snap.manifest.quality;
    let mut tiles = Vec::new();
    for &key in &keys {
        let tile = scene.store.tile(&snap, layer.height, key, &quality)?;
        let Payload::Height(h) = &*tile.payload else { anyhow::bail!("the height layer gave no heights") };
        let lattice = grid.lattice(key, SampleKind::Corner);
        let truth: Vec<f64> = (0..h.size * h.size)
            .map(|k| {
                let (i, j) = (k % h.size, k / h.size);
                // Voids in the DEM have no truth to meet.
                if h.heights[k].is_nan() { f64::NAN } else { relief_examples::demo_terrain(lattice.x(i), lattice.y(j)) }
            })
            .collect();
        tiles.push((key, h.clone(), truth));
    }
    let mut rows = Vec::new();
    for setting in SETTINGS {
        let (mut ms, mut bytes, mut zipped, mut triangles) = (Vec::new(), 0usize, 0usize, 0usize);
        let (mut sum_sq, mut count, mut worst) = (0.0f64, 0usize, 0.0f64);
        for (key, tile, truth) in &tiles {
            let mut encoded = Vec::new();
            let mut mesh = None;
            let mut times = Vec::new();
            for _ in 0..RUNS {
                let started = std::time::Instant::now();
                let m = Rtin::new(tile)?.mesh(setting);
                encoded =
                    encode_quantized_mesh(&m, grid, *key, EncodeOptions { octvertexnormals: true, watermask: None })?;
                times.push(started.elapsed().as_secs_f64() * 1e3);
                mesh = Some(m);
            }
            let mesh = mesh.ok_or_else(|| anyhow::anyhow!("no mesh"))?;
            ms.push(median(times));
            bytes += encoded.len();
            zipped += gzip(&encoded).len();
            triangles += mesh.triangles.len();
            for (m, t) in mesh.surface_heights().iter().zip(truth).filter(|(_, t)| t.is_finite()) {
                sum_sq += (m - t).powi(2);
                worst = worst.max((m - t).abs());
                count += 1;
            }
        }
        let n = tiles.len() as f64;
        let per_tile_ms = ms.iter().sum::<f64>() / n;
        rows.push(
            Row::new(format!("{setting} m"), per_tile_ms, (sum_sq / count.max(1) as f64).sqrt())
                .default_if(setting == DEFAULT_TERRAIN_MESH_ERROR_M)
                .with("max error m", format!("{worst:.2}"))
                .with("KiB per tile", format!("{:.1}", bytes as f64 / n / 1024.0))
                .with("gzip KiB per tile", format!("{:.1}", zipped as f64 / n / 1024.0))
                .with("triangles per tile", format!("{:.0}", triangles as f64 / n)),
        );
    }
    let why_default = why(&rows);
    Ok(vec![Sweep {
        knob: "terrain_mesh_error_m".into(),
        case: format!(
            "Eight {}-sample height tiles of the demo range at level {z}, the terrain's finest (its samples \
             are the DEM's own spacing), meshed by RTIN at each setting and encoded as quantized-mesh-1.0 with \
             oct-encoded normals, as /tiles/terrain serves them to CesiumJS; coarser levels allow twice the \
             error per level up.",
            grid.tile_size() + 1
        ),
        reference: "the demo's formula at every tile sample (the DEM holds it at its pixel centres; setting 0 \
                    shows what resampling alone costs)"
            .into(),
        error: "RMS height error over every sample of the tiles, m".into(),
        time: "ms per tile to mesh and encode (median of 3)".into(),
        rows,
        why_default,
    }])
}

fn why(rows: &[Row]) -> String {
    let get = |s: &str| rows.iter().find(|r| r.setting == s);
    let extra = |r: &Row, h: &str| r.extra.iter().find(|(k, _)| k == h).map_or_else(String::new, |(_, v)| v.clone());
    let (Some(zero), Some(one), Some(four)) = (get("0 m"), get("1 m"), get("4 m")) else {
        return "the sweep did not measure the settings it compares".into();
    };
    format!(
        "Keeping every bend (0 m) costs {} gzipped KiB a tile for an RMS error of {:.2} m (resampling alone); \
         1 m costs {} KiB ({:.2} m RMS, {} m at worst) and 4 m {} KiB ({:.2} m RMS). 1 m keeps the mesh's \
         own error below the vertical accuracy of the public DEMs relief is fed (SRTM and Copernicus, several \
         metres) while a tile stays a few times smaller than keeping every sample; raise it for lighter tiles \
         over rough terrain.",
        extra(zero, "gzip KiB per tile"),
        zero.error,
        extra(one, "gzip KiB per tile"),
        one.error,
        extra(one, "max error m"),
        extra(four, "gzip KiB per tile"),
        four.error
    )
}
