//! The renderer on a real wgpu device (lavapipe in CI) over analytic
//! terrains with known heights.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::ops::Range;
use std::sync::Arc;

use glam::DVec3;
use relief_renderer::{ClipmapConfig, Gpu, Pose, RenderSettings, Renderer, SampleBlock, Surface, TerrainSamples};
use relief_source::{TileGrid, geodesy};

/// An analytic surface sampled exactly at every lattice point.
struct Analytic {
    surface: Surface,
    height: fn(f64, f64) -> f64,
    max_level: u8,
}

impl TerrainSamples for Analytic {
    fn samples(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<SampleBlock> {
        let mut block = SampleBlock::default();
        for gy in ys {
            for gx in xs.clone() {
                let (x, mut y) = self.surface.sample_point(level, gx, gy);
                let mut x = x;
                if y > 90.0 || y < -90.0 {
                    y = y.signum() * 180.0 - y;
                    x += 180.0;
                }
                let h = (self.height)(x, y);
                block.heights.push(h as f32);
                let c = relief_examples::demo_color(h);
                block.colors.push([c[0], c[1], c[2], 255]);
            }
        }
        Some(block)
    }

    fn max_level(&self) -> u8 {
        self.max_level
    }
}

fn gpu() -> Arc<Gpu> {
    Arc::new(Gpu::headless().unwrap())
}

fn hill_scene(gpu: &Arc<Gpu>, config: ClipmapConfig) -> (Renderer, Analytic) {
    let surface = Surface::new(TileGrid::geodetic(256).unwrap());
    let source = Analytic { surface: surface.clone(), height: relief_examples::hill, max_level: 14 };
    (Renderer::new(Arc::clone(gpu), surface, config).unwrap(), source)
}

fn pose(lon: f64, lat: f64, alt: f64, heading: f64, pitch: f64) -> Pose {
    Pose { position: [lon, lat, alt], heading_deg: heading, pitch_deg: pitch, roll_deg: 0.0, vertical_fov_deg: 50.0 }
}

fn save(frame: &relief_renderer::Frame, name: &str) {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    image::save_buffer(dir.join(name), &frame.rgba, frame.width, frame.height, image::ExtendedColorType::Rgba8)
        .unwrap();
}

#[test]
fn depth_reconstructs_the_analytic_hill() {
    let gpu = gpu();
    let (mut renderer, source) = hill_scene(&gpu, ClipmapConfig::default());
    let settings = RenderSettings { width: 320, height: 180, lighting: true };
    let frame = renderer.render(&source, &pose(10.1, 45.1, 4000.0, 45.0, -25.0), &settings).unwrap();
    save(&frame, "hill.png");
    let mut worst: f64 = 0.0;
    let mut checked = 0;
    for py in (0..180).step_by(7) {
        for px in (0..320).step_by(7) {
            let depth = frame.depth[(py * 320 + px) as usize];
            if depth <= 0.0 {
                continue;
            }
            let (dir, distance) = frame.view.unproject(f64::from(px), f64::from(py), 320, 180, depth);
            let p: DVec3 = frame.view.eye + dir * distance;
            let (lon, lat, h) = geodesy::geodetic_from_ecef(p.to_array());
            let truth = relief_examples::hill(lon, lat);
            let error = (h - truth).abs();
            worst = worst.max(error / (1.0 + 1e-3 * distance));
            checked += 1;
        }
    }
    eprintln!("checked {checked} pixels, worst error {worst:.3} m (per 1 m + 1 mm/m)");
    assert!(checked > 500);
    assert!(worst < 1.0);
}
