//! What several knobs share: the drawn surface's error against the demo's
//! formula, error statistics, PROJ through GDAL's OSR, and one tile
//! generated now and timed.

use std::sync::Arc;
use std::time::Instant;

use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
use relief_daemon::graph::SceneSnapshot;
use relief_daemon::scene::Scene;
use relief_renderer::Frame;
use relief_source::{Payload, Quality, TileKey};

/// RMS and max of (drawn - formula) over every 4th pixel that shows the
/// demo DEM (not its void), in metres (`relief_tests::surface`); NaN when
/// none does.
pub fn surface_error(frame: &Frame) -> (f64, f64) {
    let point_in_ecef = |px: u32, py: u32, depth: f32| {
        let (dir, distance) = frame.view.unproject(f64::from(px), f64::from(py), frame.width, frame.height, depth);
        (frame.view.eye + dir * distance).to_array()
    };
    relief_tests::surface::demo_surface_error(&frame.depth, frame.width, frame.height, point_in_ecef)
        .unwrap_or((f64::NAN, f64::NAN))
}

/// RMS and largest magnitude of a set of differences.
#[derive(Debug, Clone, Copy, Default)]
pub struct ErrorStats {
    sum_squares: f64,
    max: f64,
    count: usize,
}

impl ErrorStats {
    pub fn add(&mut self, difference: f64) {
        self.sum_squares += difference * difference;
        self.max = self.max.max(difference.abs());
        self.count += 1;
    }

    /// NaN when nothing was added.
    pub fn rms(&self) -> f64 {
        if self.count == 0 { f64::NAN } else { (self.sum_squares / self.count as f64).sqrt() }
    }

    pub fn max(&self) -> f64 {
        if self.count == 0 { f64::NAN } else { self.max }
    }

    pub fn count(&self) -> usize {
        self.count
    }
}

/// A PROJ transformation through GDAL's OSR, x = longitude or easting
/// whatever the authority's axis order (as the gdal source reads CRSs).
pub struct Proj(CoordTransform);

impl Proj {
    pub fn new(from: &str, to: &str) -> anyhow::Result<Self> {
        let srs = |definition: &str| -> anyhow::Result<SpatialRef> {
            let mut srs = SpatialRef::from_definition(definition)?;
            srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
            Ok(srs)
        };
        Ok(Self(CoordTransform::new(&srs(from)?, &srs(to)?)?))
    }

    /// Transforms the points in place; one PROJ cannot transform is an error.
    pub fn apply(&self, xs: &mut [f64], ys: &mut [f64]) -> anyhow::Result<()> {
        for (xs, ys) in xs.chunks_mut(65_536).zip(ys.chunks_mut(65_536)) {
            self.0.transform_coords(xs, ys, &mut [])?;
        }
        Ok(())
    }
}

/// The index of source `id` in `snap`.
pub fn source_index(snap: &SceneSnapshot, id: &str) -> anyhow::Result<usize> {
    snap.index_of(id).ok_or_else(|| anyhow::anyhow!("the scene has no source '{id}'"))
}

/// Tile `key` of source `index` generated now, and how long that took,
/// ms. The caller makes sure no cache can answer: the manifest turns the
/// disk cache off (`[cache] disk_mb = 0`; it is on by default, in the
/// user's cache folder) and the memory cache has not seen this quality
/// since `forget`. An answer from a cache is an error.
pub fn timed_tile(
    scene: &Scene,
    snap: &SceneSnapshot,
    index: usize,
    key: TileKey,
    quality: &Quality,
) -> anyhow::Result<(f64, Arc<Payload>)> {
    let id = &snap.slots[index].spec.id;
    let before = scene.store.generated_for(id);
    let started = Instant::now();
    let tile = scene.store.tile(snap, index, key, quality)?;
    let ms = started.elapsed().as_secs_f64() * 1e3;
    anyhow::ensure!(
        scene.store.generated_for(id) > before,
        "a cache answered for tile {key} of source '{id}' (the manifest must say [cache] disk_mb = 0)"
    );
    Ok((ms, Arc::clone(&tile.payload)))
}

/// Drops every cached tile of source `index`, so the next ask generates it.
pub fn forget(scene: &Scene, snap: &SceneSnapshot, index: usize) {
    let slot = &snap.slots[index];
    scene.store.forget(&slot.spec.id, slot.effective_version);
}

/// A manifest section that keeps tiles in memory only: a knob that times
/// tile generation must not find last run's tiles in the disk cache.
pub const NO_DISK_CACHE: &str = "\n[cache]\ndisk_mb = 0\n";
