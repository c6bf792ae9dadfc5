//! Instances benchmark. Prints tables; never asserts a time.
//!
//! The demo scene (a synthetic range, a town of 2,000 buildings, and the
//! forest `scatter` grows from its land cover) at 1280 x 720 through
//! reliefd's tile store, from a low camera south of the town looking over
//! it and the wooded valley:
//!
//! 1. frame time for terrain alone, plus the buildings, plus the trees (at
//!    default quality), and the same trees all drawn as models, as a ratio;
//! 2. the accuracy of the instances' knobs against time: the image error
//!    (RMSE of the colours) against a reference frame in which every
//!    instance within 6 km is a full model at full density, for the band
//!    distances and the model/billboard switch.

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

mod common;

use std::sync::Arc;

use anyhow::Context;
use common::median;
use relief_daemon::view::{ModelCache, SceneBuildings, SceneInstances, SceneTerrain};
use relief_renderer::{
    ClipmapConfig, Frame, Gpu, InstanceBands, MeshTiles, Pose, RenderSettings, Renderer, SceneLayers, Surface,
};

const SETTINGS: RenderSettings = RenderSettings::new(1280, 720, true);
/// Frames timed per row (the median is printed).
const FRAMES: usize = 5;

fn total_ms(frame: &Frame) -> f64 {
    frame.passes.iter().map(|(_, ms)| ms).sum()
}

fn pass_ms(frames: &[Frame], pass: &str) -> Option<f64> {
    let times: Vec<f64> = frames.iter().filter_map(|f| f.passes.iter().find(|p| p.0 == pass)).map(|p| p.1).collect();
    (!times.is_empty()).then(|| median(times))
}

/// Root mean square difference of two frames' colours, 0..255.
fn rmse(a: &Frame, b: &Frame) -> f64 {
    let sum: f64 = a.rgba.iter().zip(&b.rgba).map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2)).sum();
    (sum / a.rgba.len() as f64).sqrt()
}

/// Writes `frame` as `<RELIEF_BENCH_FRAMES>/instances-<name>.png` when
/// that variable names a folder (to look at what the table measures).
fn save(frame: &Frame, name: &str) -> anyhow::Result<()> {
    let Some(dir) = std::env::var_os("RELIEF_BENCH_FRAMES") else { return Ok(()) };
    let png = relief_daemon::codec::png(&frame.rgba, frame.width, frame.height).map_err(anyhow::Error::msg)?;
    std::fs::write(std::path::Path::new(&dir).join(format!("instances-{name}.png")), png)?;
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = relief_examples::write_demo_scene(dir.path())?;
    let scene = common::load(&manifest, 2)?;
    let snap = scene.snapshot();
    let quality = snap.manifest.quality;
    let terrain = SceneTerrain::new(&scene.store, &snap, quality);
    let buildings = SceneBuildings::new(&scene.store, &snap, quality).context("the demo has a town")?;
    let models = ModelCache::default();
    let trees = SceneInstances::new(&scene.store, &snap, quality, &models).context("the demo has a forest")?;
    let gpu = Arc::new(Gpu::headless()?);
    let mut renderer = Renderer::new(Arc::clone(&gpu), Surface::new(snap.grid.clone()), ClipmapConfig::default())?;
    // 60 m over the wood south of the town, looking north across it.
    let relief_examples::Viewpoint { position, heading_deg, pitch_deg, vertical_fov_deg } =
        relief_examples::demo_forest_view();
    let view = Pose { position, heading_deg, pitch_deg, roll_deg: 0.0, vertical_fov_deg };
    let mut run = |layers: SceneLayers<'_>, bands: InstanceBands| -> anyhow::Result<Vec<Frame>> {
        let settings = RenderSettings { bands, ..SETTINGS };
        // The first frame fills the levels and builds tiles: not timed.
        renderer.render_scene(&terrain, layers, &view, &settings)?;
        (0..FRAMES).map(|_| Ok(renderer.render_scene(&terrain, layers, &view, &settings)?)).collect()
    };
    let town = Some(&buildings as &dyn MeshTiles);
    let forest = Some(&trees as &dyn relief_renderer::InstanceTiles);
    let default = InstanceBands::default();
    let all_models = InstanceBands { model_distance_m: 1e9, ..default };

    println!("\n## Frame time at 1280 x 720: terrain, buildings and trees (the demo's valley)");
    println!("machine: {}; device: {}", relief_tests::machine(), gpu.description);
    println!(
        "camera: 60 m over the wood 3.9 km south of the town, 8 degrees down; still frames, median of {FRAMES}; trees from `scatter` over the demo's land cover"
    );
    println!(
        "| scene | trees in view (before bands) | models | billboards | buildings | terrain ms | buildings ms | instances ms | frame ms | / terrain alone |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let rows = [
        ("terrain alone", SceneLayers::default(), default),
        ("+ 2,000 buildings", SceneLayers { buildings: town, instances: None, water: None }, default),
        ("+ trees, default quality", SceneLayers { buildings: town, instances: forest, water: None }, default),
        ("+ the same trees all as models", SceneLayers { buildings: town, instances: forest, water: None }, all_models),
    ];
    let mut alone = 0.0;
    let mut by_name = Vec::new();
    for (k, (name, layers, bands)) in rows.into_iter().enumerate() {
        let frames = run(layers, bands)?;
        save(&frames[0], &format!("scene-{k}"))?;
        let d = frames[0].drawn;
        let total = median(frames.iter().map(total_ms).collect());
        if alone == 0.0 {
            alone = total;
        }
        let ms = |pass: &str| pass_ms(&frames, pass).map_or("-".to_owned(), |v| format!("{v:.1}"));
        println!(
            "| {name} | {} | {} | {} | {} | {} | {} | {} | {total:.1} | {:.2}x |",
            d.instances_in_view,
            d.models,
            d.billboards,
            d.buildings,
            ms("terrain"),
            ms("buildings"),
            ms("instances"),
            total / alone
        );
        by_name.push(total);
    }
    println!(
        "\nall trees as models / default quality (models to {} m, billboards beyond): {:.2}x the frame time",
        default.model_distance_m,
        by_name[3] / by_name[2]
    );

    // Accuracy against time: every knob row against the reference.
    let reference = InstanceBands::reference(6000.0);
    let layers = SceneLayers { buildings: town, instances: forest, water: None };
    let truth = run(layers, reference)?;
    save(&truth[0], "reference")?;
    let truth_ms = median(truth.iter().map(total_ms).collect());
    println!("\n### Knobs: distance bands and the model/billboard switch, against the reference");
    println!(
        "reference: every instance within 6 km a full model at full density: {} models, frame {truth_ms:.1} ms",
        truth[0].drawn.models
    );
    println!(
        "| knob | value | models | billboards | image RMSE (0-255) | instances ms | frame ms | / reference time |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut rows: Vec<(String, String, InstanceBands)> = Vec::new();
    for m in [0.0, 100.0, 200.0, 400.0, 700.0, 1400.0, 3000.0] {
        let mark = if m == default.model_distance_m { " (default)" } else { "" };
        rows.push(("model_distance_m".into(), format!("{m}{mark}"), InstanceBands { model_distance_m: m, ..default }));
    }
    for scale in [0.5, 0.75, 1.0, 1.5, 2.0] {
        let edges_m = default.edges_m.map(|e| e * scale);
        let mark = if scale == 1.0 { " (default)" } else { "" };
        let value = format!("{} / {} / {} m{mark}", edges_m[0], edges_m[1], edges_m[2]);
        rows.push(("instance_bands_m".into(), value, InstanceBands { edges_m, ..default }));
    }
    for densities in [[1.0, 1.0, 1.0], [1.0, 0.8, 0.5], [1.0, 0.5, 0.25]] {
        let mark = if densities == default.densities { " (default)" } else { "" };
        let value = format!("{} / {} / {}{mark}", densities[0], densities[1], densities[2]);
        rows.push(("instance_band_densities".into(), value, InstanceBands { densities, ..default }));
    }
    for (knob, value, bands) in rows {
        let frames = run(layers, bands)?;
        let d = frames[0].drawn;
        let error = rmse(&frames[0], &truth[0]);
        let total = median(frames.iter().map(total_ms).collect());
        let instances = pass_ms(&frames, "instances").unwrap_or(0.0);
        println!(
            "| {knob} | {value} | {} | {} | {error:.2} | {instances:.1} | {total:.1} | {:.2}x |",
            d.models,
            d.billboards,
            total / truth_ms
        );
    }
    Ok(())
}
