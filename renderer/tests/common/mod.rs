//! What the renderer's tests share: one device, analytic terrains sampled
//! exactly at every lattice point, the scenes over them, and poses.

#![allow(dead_code, reason = "each test binary uses its own part")]

pub mod raycast;

use std::ops::Range;
use std::sync::Arc;

use relief_renderer::{ClipmapConfig, Gpu, Pose, Renderer, Surface, TerrainSamples};
use relief_source::{GridKind, ProjectedGrid, TileGrid};

/// An analytic surface sampled exactly at every lattice point.
pub struct Analytic {
    pub surface: Surface,
    pub height: fn(f64, f64) -> f64,
    pub max_level: u8,
    /// Levels above this one answer "not ready", as tiles still building.
    pub ready_up_to: u8,
}

impl Analytic {
    /// The formula at every sample of the block (reflected past a pole).
    pub fn values<T>(&self, level: u8, xs: Range<i64>, ys: Range<i64>, f: impl Fn(f64) -> T) -> Option<Vec<T>> {
        if level > self.ready_up_to {
            return None;
        }
        let mut out = Vec::new();
        for gy in ys {
            for gx in xs.clone() {
                let (mut x, mut y) = self.surface.sample_point(level, gx, gy);
                if self.surface.is_planet() && !(-90.0..=90.0).contains(&y) {
                    y = y.signum() * 180.0 - y;
                    x += 180.0;
                }
                out.push(f((self.height)(x, y)));
            }
        }
        Some(out)
    }
}

impl TerrainSamples for Analytic {
    fn heights(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<f32>> {
        self.values(level, xs, ys, |h| h as f32)
    }

    fn colors(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<[u8; 4]>> {
        self.values(level, xs, ys, |h| {
            let c = relief_examples::demo_color(h);
            [c[0], c[1], c[2], 255]
        })
    }

    fn max_level(&self) -> u8 {
        self.max_level
    }
}

/// One device for the whole test binary, as reliefd shares one.
pub fn gpu() -> Arc<Gpu> {
    static GPU: std::sync::OnceLock<Arc<Gpu>> = std::sync::OnceLock::new();
    Arc::clone(GPU.get_or_init(|| Arc::new(Gpu::headless().unwrap())))
}

pub fn hill_scene(gpu: &Arc<Gpu>, config: ClipmapConfig) -> (Renderer, Analytic) {
    let surface = Surface::new(TileGrid::geodetic(256).unwrap());
    let source =
        Analytic { surface: surface.clone(), height: relief_examples::hill, max_level: 14, ready_up_to: u8::MAX };
    (Renderer::new(Arc::clone(gpu), surface, config).unwrap(), source)
}

/// A local scene: 20 km of UTM 12N round the analytic `utm_surface`.
pub fn utm_scene(config: ClipmapConfig) -> (Renderer, Analytic) {
    utm_scene_of(config, relief_examples::utm_surface)
}

/// The same 20 km of UTM 12N round the analytic surface `height`.
pub fn utm_scene_of(config: ClipmapConfig, height: fn(f64, f64) -> f64) -> (Renderer, Analytic) {
    let (crs, min_x, min_y, size) = relief_examples::UTM_SQUARE;
    let grid = TileGrid::new(GridKind::Projected(ProjectedGrid { crs: crs.into(), min_x, min_y, size }), 256).unwrap();
    let surface = Surface::new(grid);
    let source = Analytic { surface: surface.clone(), height, max_level: 8, ready_up_to: u8::MAX };
    (Renderer::new(gpu(), surface, config).unwrap(), source)
}

/// The terrain rebuilt over `area`, and nothing else.
pub fn terrain_dirt(area: relief_source::Extent) -> relief_renderer::Dirt {
    relief_renderer::Dirt { terrain: vec![area], ..relief_renderer::Dirt::default() }
}

pub fn pose(lon: f64, lat: f64, alt: f64, heading: f64, pitch: f64) -> Pose {
    Pose { position: [lon, lat, alt], heading_deg: heading, pitch_deg: pitch, roll_deg: 0.0, vertical_fov_deg: 50.0 }
}

pub fn save(frame: &relief_renderer::Frame, name: &str) {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    image::save_buffer(dir.join(name), &frame.rgba, frame.width, frame.height, image::ExtendedColorType::Rgba8)
        .unwrap();
}

/// The pixel a world point falls in, if in the image and in front.
pub fn project(frame: &relief_renderer::Frame, p: glam::DVec3) -> Option<(u32, u32)> {
    let v = &frame.view;
    let d = p - v.eye;
    let z = d.dot(v.forward);
    let tan = (v.vertical_fov_deg.to_radians() / 2.0).tan();
    let aspect = f64::from(frame.width) / f64::from(frame.height);
    let (sx, sy) = (d.dot(v.right) / z / (tan * aspect), d.dot(v.up) / z / tan);
    let px = f64::midpoint(sx, 1.0) * f64::from(frame.width) - 0.5;
    let py = (1.0 - sy) / 2.0 * f64::from(frame.height) - 0.5;
    let inside = z > 0.0 && px >= 0.0 && py >= 0.0 && px < f64::from(frame.width) && py < f64::from(frame.height);
    inside.then(|| (px.round() as u32, py.round() as u32))
}
