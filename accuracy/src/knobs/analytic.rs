//! Analytic terrains for the knobs whose reference needs a surface the
//! renderer's tests use (the shadows' peaks, the detail's fractal): a
//! formula sampled exactly at every lattice point of 20 km of UTM 12N, as
//! `renderer/tests/common` builds it (that module is test-only: it writes
//! into a test's target folder).

use std::ops::Range;
use std::sync::Arc;

use relief_renderer::{ClipmapConfig, Gpu, Pose, Renderer, Surface, TerrainSamples};
use relief_source::{GridKind, ProjectedGrid, TileGrid};

/// A formula sampled exactly at every lattice point, coloured by the
/// demo's tint.
pub struct Analytic {
    pub surface: Surface,
    pub height: fn(f64, f64) -> f64,
    /// The finest tile level the source answers for.
    pub max_level: u8,
}

impl Analytic {
    fn values<T>(&self, level: u8, xs: Range<i64>, ys: Range<i64>, f: impl Fn(f64) -> T) -> Vec<T> {
        let mut out = Vec::with_capacity(xs.clone().count() * ys.clone().count());
        for gy in ys {
            for gx in xs.clone() {
                let (x, y) = self.surface.sample_point(level, gx, gy);
                out.push(f((self.height)(x, y)));
            }
        }
        out
    }

    /// The same formula answering down to `max_level`.
    pub fn to_level(&self, max_level: u8) -> Self {
        Self { surface: self.surface.clone(), height: self.height, max_level }
    }
}

impl TerrainSamples for Analytic {
    fn heights(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<f32>> {
        Some(self.values(level, xs, ys, |h| h as f32))
    }

    fn colors(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<[u8; 4]>> {
        Some(self.values(level, xs, ys, |h| {
            let c = relief_examples::demo_color(h);
            [c[0], c[1], c[2], 255]
        }))
    }

    fn max_level(&self) -> u8 {
        self.max_level
    }
}

/// 20 km of UTM 12N (290,000 to 310,000 m east, 5,090,000 to 5,110,000 m
/// north) round the formula `height`, answering down to tile level 8, and
/// a renderer over it.
pub fn utm_scene(
    gpu: &Arc<Gpu>,
    config: ClipmapConfig,
    height: fn(f64, f64) -> f64,
) -> anyhow::Result<(Renderer, Analytic)> {
    let (crs, min_x, min_y, size) = relief_examples::UTM_SQUARE;
    let grid = TileGrid::new(GridKind::Projected(ProjectedGrid { crs: crs.into(), min_x, min_y, size }), 256)
        .map_err(anyhow::Error::msg)?;
    let surface = Surface::new(grid);
    let source = Analytic { surface: surface.clone(), height, max_level: 8 };
    Ok((Renderer::new(Arc::clone(gpu), surface, config)?, source))
}

/// A camera at grid (x, y), `alt` metres up, with a 50 degree field of view.
pub fn pose(x: f64, y: f64, alt: f64, heading_deg: f64, pitch_deg: f64) -> Pose {
    Pose { position: [x, y, alt], heading_deg, pitch_deg, roll_deg: 0.0, vertical_fov_deg: 50.0 }
}
