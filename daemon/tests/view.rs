//! The renderer fed by the scene's own tiles (GDAL reading the analytic
//! hill): `SceneTerrain` samples across tile borders, and the heights
//! reconstructed from a rendered depth buffer, against the formula.

use std::sync::Arc;

use anyhow::Context;
use glam::DVec3;
use relief_daemon::scene::Scene;
use relief_daemon::view::SceneTerrain;
use relief_renderer::{ClipmapConfig, Gpu, Pose, RenderSettings, Renderer, Surface, TerrainSamples};
use relief_source::geodesy;

fn hill_scene(dir: &std::path::Path) -> anyhow::Result<Scene> {
    relief_examples::write_dem(&dir.join("hill.tif"), &relief_examples::hill_spec(), relief_examples::hill)?;
    let manifest = relief_examples::write_manifest(
        dir,
        "[scene]\nname = \"hill\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n[layers]\nheight = \"dem\"\n",
    )?;
    Scene::load_checked(&manifest, false, 2, relief_daemon::picture::check)
        .map(|(scene, _)| scene)
        .map_err(|e| anyhow::anyhow!("the hill scene does not load: {e:?}"))
}

#[test]
fn samples_across_tile_borders_follow_the_hill() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let scene = hill_scene(dir.path())?;
    let snap = scene.snapshot();
    let terrain = SceneTerrain::new(&scene.store, &snap, snap.manifest.quality);
    // The DEM has 0.00125-degree pixels: refine to one level past them.
    assert_eq!(terrain.max_level(), 11);
    // Level 10: 256-sample tiles of 0.176 degrees; this block straddles the
    // corner of four tiles (samples 277248 and 65024 are tile edges).
    let (level, xs, ys) = (10u8, 277_240..277_260, 65_016..65_036);
    let heights = terrain.heights(level, xs.clone(), ys.clone()).context("the hill's tiles build")?;
    let step = 180.0 / 1024.0 / 256.0;
    let mut worst: f64 = 0.0;
    for (j, gy) in ys.enumerate() {
        for (i, gx) in xs.clone().enumerate() {
            let (lon, lat) = (-180.0 + gx as f64 * step, 90.0 - gy as f64 * step);
            let h = f64::from(heights[j * 20 + i]);
            worst = worst.max((h - relief_examples::hill(lon, lat)).abs());
        }
    }
    // Bilinear from 0.00125-degree pixels on the hill's curvature: <= 0.045 m.
    assert!(worst < 0.05, "worst {worst} m");
    Ok(())
}

#[test]
fn the_rendered_surface_is_the_hill() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let scene = hill_scene(dir.path())?;
    let snap = scene.snapshot();
    let terrain = SceneTerrain::new(&scene.store, &snap, snap.manifest.quality);
    let gpu = Arc::new(Gpu::headless()?);
    let mut renderer = Renderer::new(gpu, Surface::new(snap.grid.clone()), ClipmapConfig::default())?;
    let settings = RenderSettings::new(320, 180, true);
    let pose = Pose {
        position: [10.1, 45.1, 4000.0],
        heading_deg: 45.0,
        pitch_deg: -30.0,
        roll_deg: 0.0,
        vertical_fov_deg: 50.0,
    };
    let frame = renderer.render(&terrain, &pose, &settings)?;
    let (mut worst, mut checked) = (0.0f64, 0);
    for py in (0..180).step_by(4) {
        for px in (0..320).step_by(4) {
            let depth = frame.depth[(py * 320 + px) as usize];
            if depth <= 0.0 {
                continue;
            }
            let (dir, distance) = frame.view.unproject(f64::from(px), f64::from(py), 320, 180, depth);
            let p: DVec3 = frame.view.eye + dir * distance;
            let (lon, lat, h) = geodesy::geodetic_from_ecef(p.to_array());
            // Only where the DEM is (off it the terrain is nodata, drawn at 0 m).
            if !(10.01..10.49).contains(&lon) || !(45.01..45.49).contains(&lat) {
                continue;
            }
            worst = worst.max((h - relief_examples::hill(lon, lat)).abs() / (1.0 + 1e-3 * distance));
            checked += 1;
        }
    }
    // The same budget as the renderer's own test: 1 m + 1 mm per metre.
    assert!(checked > 1000 && worst < 1.0, "{checked} pixels, worst {worst}");
    Ok(())
}
