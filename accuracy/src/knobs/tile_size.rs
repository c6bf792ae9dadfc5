//! `[scene] tile_size`: N samples a tile side. Every level's lattice is
//! the same global one whatever N (a level of 512 is one of 256 a level
//! finer), so N changes what a tile costs, not the heights: large tiles
//! pay less overhead per sample when a view is built, small ones rebuild
//! less around an edit. Both are timed on the demo range; the error is
//! the drawn surface's against the demo's formula.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use relief_daemon::scene::EventKind;
use relief_daemon::view::SceneTerrain;
use relief_renderer::{ClipmapConfig, Renderer, SceneLayers, Surface, TerrainSamples};
use relief_source::TileGrid;

use super::data::surface_error;
use super::{Context, HD, demo_pose, median};
use crate::sweep::{Row, Sweep};

const SIZES: [u32; 4] = [128, 256, 512, 1024];
const EDITS: usize = 9;
/// The edit: a window of the demo DEM (1000 x 600 pixels) rewritten.
const EDIT_SIDE: usize = 64;

/// The scene's terrain, timing the renderer's asks (which build the tiles).
struct Timed<'a> {
    inner: &'a SceneTerrain<'a>,
    nanos: AtomicU64,
}

impl Timed<'_> {
    fn time<T>(&self, f: impl FnOnce() -> T) -> T {
        let started = Instant::now();
        let out = f();
        self.nanos.fetch_add(started.elapsed().as_nanos() as u64, Ordering::Relaxed);
        out
    }

    fn ms(&self) -> f64 {
        self.nanos.load(Ordering::Relaxed) as f64 / 1e6
    }
}

impl TerrainSamples for Timed<'_> {
    fn heights(&self, level: u8, xs: std::ops::Range<i64>, ys: std::ops::Range<i64>) -> Option<Vec<f32>> {
        self.time(|| self.inner.heights(level, xs, ys))
    }

    fn colors(&self, level: u8, xs: std::ops::Range<i64>, ys: std::ops::Range<i64>) -> Option<Vec<[u8; 4]>> {
        self.time(|| self.inner.colors(level, xs, ys))
    }

    fn max_level(&self) -> u8 {
        self.inner.max_level()
    }
}

/// A first view, cold: what building its tiles cost and what it drew.
struct Cold {
    build_ms: f64,
    first_frame_ms: f64,
    tiles: u64,
    samples: u64,
    rms: f64,
    max: f64,
}

/// One tile size measured, with the demo's orthophoto as the colour layer
/// and with a hillshade of the DEM instead (an op reading the DEM tile and
/// its neighbours).
struct Measured {
    size: u32,
    ortho: Cold,
    shade_build_ms: f64,
    edit_ms: f64,
    shade_edit_ms: f64,
    rebuilt: f64,
    shade_rebuilt: f64,
}

/// Cold first views, each in a fresh scene.
const COLD_RUNS: usize = 3;

pub fn run(cx: &Context) -> anyhow::Result<Vec<Sweep>> {
    // A copy of the demo: the edits must not reach the other knobs' scene.
    let pristine = cx.demo.parent().ok_or_else(|| anyhow::anyhow!("the demo manifest has no folder"))?;
    let dir = cx.dir.path().join("tile-size");
    std::fs::create_dir_all(&dir)?;
    for entry in std::fs::read_dir(pristine)? {
        let entry = entry?;
        if entry.file_type()?.is_file() {
            std::fs::copy(entry.path(), dir.join(entry.file_name()))?;
        }
    }
    // The context's demo has the disk cache off already (`[cache] disk_mb = 0`).
    let demo_text = std::fs::read_to_string(&cx.demo)?;
    anyhow::ensure!(demo_text.contains("disk_mb = 0"), "the demo manifest keeps its disk cache");
    let mut measured = Vec::new();
    for size in SIZES {
        let ortho = demo_text.replacen("[scene]\n", &format!("[scene]\ntile_size = {size}\n"), 1);
        let shade = ortho.replacen("color = \"ortho\"", "color = \"shade\"", 1);
        anyhow::ensure!(
            ortho.contains("tile_size") && shade != ortho,
            "the demo manifest has no [scene] section or no ortho colour layer to change"
        );
        let mut runs = Vec::new();
        for (name, text) in [("ortho", &ortho), ("shade", &shade)] {
            let manifest = dir.join(format!("scene-{size}-{name}.toml"));
            std::fs::write(&manifest, text)?;
            let mut colds = Vec::new();
            let mut last = None;
            for _ in 0..COLD_RUNS {
                // One scene at a time: the last one goes before the next loads.
                drop(last.take());
                std::fs::copy(pristine.join("dem.tif"), dir.join("dem.tif"))?;
                let scene = cx.load(&manifest)?;
                colds.push(cold(cx, &scene, size)?);
                last = Some(scene);
            }
            let scene = last.ok_or_else(|| anyhow::anyhow!("no cold run"))?;
            let (edit_ms, rebuilt) = edits(&scene, &dir.join("dem.tif"))?;
            runs.push((colds, edit_ms, rebuilt));
        }
        let [(ortho_colds, edit_ms, rebuilt), (shade_colds, shade_edit_ms, shade_rebuilt)]: [_; 2] =
            runs.try_into().map_err(|_| anyhow::anyhow!("two colour layers measured"))?;
        let median_of = |colds: &[Cold], f: fn(&Cold) -> f64| median(colds.iter().map(f).collect());
        let shade_build_ms = median_of(&shade_colds, |c| c.build_ms);
        let (build_ms, first_frame_ms) =
            (median_of(&ortho_colds, |c| c.build_ms), median_of(&ortho_colds, |c| c.first_frame_ms));
        let last = ortho_colds.into_iter().last().ok_or_else(|| anyhow::anyhow!("no cold run"))?;
        measured.push(Measured {
            size,
            ortho: Cold { build_ms, first_frame_ms, ..last },
            shade_build_ms,
            edit_ms,
            shade_edit_ms,
            rebuilt,
            shade_rebuilt,
        });
    }
    let default = TileGrid::DEFAULT_TILE_SIZE;
    let rows = |time: fn(&Measured) -> f64, extra: fn(Row, &Measured) -> Row| -> Vec<Row> {
        measured
            .iter()
            .map(|m| {
                let row = Row::new(m.size.to_string(), time(m), m.ortho.rms)
                    .default_if(m.size == default)
                    .with("max error m", format!("{:.1}", m.ortho.max));
                extra(row, m)
            })
            .collect()
    };
    let first_rows = rows(
        |m| m.ortho.build_ms,
        |r, m| {
            r.with("tiles built", m.ortho.tiles.to_string())
                .with("samples built (M)", format!("{:.1}", m.ortho.samples as f64 / 1e6))
                .with("first frame ms", format!("{:.0}", m.ortho.first_frame_ms))
                .with("hillshade colour: tile ms", format!("{:.0}", m.shade_build_ms))
        },
    );
    let edit_rows = rows(
        |m| m.edit_ms,
        |r, m| {
            r.with("tiles rebuilt per edit", format!("{:.1}", m.rebuilt))
                .with("hillshade colour: edit ms", format!("{:.1}", m.shade_edit_ms))
                .with("hillshade colour: tiles rebuilt", format!("{:.1}", m.shade_rebuilt))
        },
    );
    let spread = measured.iter().map(|m| m.ortho.rms).fold(f64::NEG_INFINITY, f64::max)
        - measured.iter().map(|m| m.ortho.rms).fold(f64::INFINITY, f64::min);
    let list = |f: fn(&Measured) -> f64| -> String {
        measured.iter().map(|m| format!("{:.0} ms at {}", f(m), m.size)).collect::<Vec<_>>().join(", ")
    };
    let fastest =
        |f: fn(&Measured) -> f64| -> u32 { measured.iter().min_by(|a, b| f(a).total_cmp(&f(b))).map_or(0, |m| m.size) };
    let measures: [fn(&Measured) -> f64; 4] =
        [|m| m.ortho.build_ms, |m| m.shade_build_ms, |m| m.edit_ms, |m| m.shade_edit_ms];
    let wins = measures.iter().filter(|&&f| fastest(f) == default).count();
    let worst = measures
        .iter()
        .map(|&f| {
            let best = measured.iter().map(f).fold(f64::INFINITY, f64::min);
            measured.iter().find(|m| m.size == default).map_or(f64::NAN, |m| f(m) / best)
        })
        .fold(0.0f64, f64::max);
    let why = format!(
        "Every tile size samples the same global lattices (a level of 512 is one of 256 a level finer), so the \
         surface drawn is the same (the RMS errors within {spread:.3} m of each other): the knob is time only. The \
         first view's tiles cost {} (fastest: {}); with a hillshade as the colour layer, an op that reads each DEM \
         tile's neighbours, {} (fastest: {}). A 64 x 64 edit to its new generation costs {} (fastest: {}); with \
         the hillshade, {} (fastest: {}): every cached tile it touches is built again whole, so large tiles make \
         every edit dearer. The default of {default} is the fastest in {wins} of these 4 measures and within \
         {worst:.1} times the fastest in each; what is not timed here favours fewer, larger tiles (a GetTile \
         request and a cache entry per tile, the renderer's and clients' per-tile work). 512 and up cost more on \
         every count measured.",
        list(|m| m.ortho.build_ms),
        fastest(|m| m.ortho.build_ms),
        list(|m| m.shade_build_ms),
        fastest(|m| m.shade_build_ms),
        list(|m| m.edit_ms),
        fastest(|m| m.edit_ms),
        list(|m| m.shade_edit_ms),
        fastest(|m| m.shade_edit_ms),
    );
    let case = format!(
        "The demo range (heights from a formula) at 1280 x 720 from its camera with the default clipmap (n 127, \
         L 8); a fresh scene for each first view ({COLD_RUNS} for each tile size, median), so it builds every tile it \
         needs; the same again with the hillshade of the DEM as the colour layer."
    );
    let reference = "the terrain's formula, at the ground point each pixel's depth gives (f64)";
    let error = "RMS height error of the drawn surface, m";
    Ok(vec![
        Sweep {
            knob: "tile_size (first view)".into(),
            case: case.clone(),
            reference: reference.into(),
            error: error.into(),
            time: "ms the first frame spent building and reading tiles (cold cache), orthophoto colour".into(),
            rows: first_rows,
            why_default: why.clone(),
        },
        Sweep {
            knob: "tile_size (64 x 64 edit)".into(),
            case: format!(
                "{case} Then {EDITS} edits, each a {EDIT_SIDE} x {EDIT_SIDE} window of the DEM rewritten through \
                 GDAL in place, each followed by the refresh that rebuilds the cached tiles it touched."
            ),
            reference: reference.into(),
            error: error.into(),
            time: format!("ms from the start of an edit to its new generation, median of {EDITS}, orthophoto colour"),
            rows: edit_rows,
            why_default: why,
        },
    ])
}

/// The first frame of `scene` (fresh), timing the tiles it builds; the
/// second frame's surface against the formula.
fn cold(cx: &Context, scene: &relief_daemon::scene::Scene, size: u32) -> anyhow::Result<Cold> {
    let snap = scene.snapshot();
    let terrain = SceneTerrain::new(&scene.store, &snap, snap.manifest.quality);
    let timed = Timed { inner: &terrain, nanos: AtomicU64::new(0) };
    let mut renderer =
        Renderer::new(std::sync::Arc::clone(&cx.gpu), Surface::new(snap.grid.clone()), ClipmapConfig::default())?;
    let pose = demo_pose();
    let started = Instant::now();
    renderer.render_scene(&timed, SceneLayers::default(), &pose, &HD)?;
    let first_frame_ms = started.elapsed().as_secs_f64() * 1e3;
    let build_ms = timed.ms();
    let frame = renderer.render_scene(&terrain, SceneLayers::default(), &pose, &HD)?;
    let (rms, max) = surface_error(&frame);
    let (mut tiles, mut samples) = (0, 0);
    for (id, n) in scene.store.generated() {
        tiles += n;
        let output = snap.index_of(&id).and_then(|i| snap.slots[i].source.as_ref()).map(|s| s.output());
        let per_tile = if output == Some(relief_source::PayloadKind::Height) {
            (u64::from(size) + 1).pow(2)
        } else {
            (u64::from(size) + 2).pow(2)
        };
        samples += n * per_tile;
    }
    Ok(Cold { build_ms, first_frame_ms, tiles, samples, rms, max })
}

/// `EDITS` edits of the DEM, each to its new generation: the median ms
/// and the mean tiles rebuilt.
fn edits(scene: &relief_daemon::scene::Scene, dem: &std::path::Path) -> anyhow::Result<(f64, f64)> {
    let mut events = scene.events();
    let mut rng = relief_examples::Lcg(17);
    let (mut edit_ms, mut rebuilt) = (Vec::new(), Vec::new());
    let only = ["dem".to_owned()];
    for n in 0..EDITS {
        let before = scene.snapshot().generation;
        let (x, y) =
            (rng.range(0.0, (1000 - EDIT_SIDE) as f64) as usize, rng.range(0.0, (600 - EDIT_SIDE) as f64) as usize);
        let started = Instant::now();
        relief_tests::edit::rewrite_window(dem, x, y, EDIT_SIDE, EDIT_SIDE, |_, _, h| h + 10.0 + n as f32)?;
        let mut tries = 0;
        while scene.refresh(Some(&only), "accuracy edit", true).generation == before {
            tries += 1;
            anyhow::ensure!(tries < 50, "an edit of the demo DEM made no new generation");
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        edit_ms.push(started.elapsed().as_secs_f64() * 1e3);
        while let Ok(event) = events.try_recv() {
            if let EventKind::Generation { stats, .. } = event.kind {
                rebuilt.push(stats.rebuilt as f64);
            }
        }
    }
    Ok((median(edit_ms), rebuilt.iter().sum::<f64>() / rebuilt.len().max(1) as f64))
}
