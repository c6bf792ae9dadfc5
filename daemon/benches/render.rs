//! Renderer benchmark. Prints tables; never asserts a time.
//!
//! The demo scene (a synthetic range whose heights are a formula) rendered
//! at 1280 x 720 through reliefd's tile store, for the clipmap knobs n
//! (samples per level side) and L (levels): the time of a frame while the
//! camera flies (level updates included) and of a frame from a still camera,
//! against the surface error reconstructed from the depth buffer. In the
//! same run, the brute-force reference: every sample of the DEM's finest
//! level as one mesh.

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

mod common;

use std::sync::Arc;

use anyhow::Context;
use common::median;
use relief_daemon::view::{SceneBuildings, SceneTerrain};
use relief_renderer::{
    Atmosphere, ClipmapConfig, Frame, Gpu, Pose, RenderSettings, Renderer, SceneLayers, SunAngles, Surface,
    TerrainSamples, WaterSamples,
};
use relief_source::Extent;

const SETTINGS: RenderSettings = RenderSettings::new(1280, 720, true);

fn pose(step: usize) -> Pose {
    // The demo's camera, flying 25 m north per frame.
    Pose {
        position: [6.45, 44.95 + step as f64 * 25.0 / 111_320.0, 9000.0],
        heading_deg: 15.0,
        pitch_deg: -25.0,
        roll_deg: 0.0,
        vertical_fov_deg: 50.0,
    }
}

fn total_ms(frame: &Frame) -> f64 {
    frame.passes.iter().map(|(_, ms)| ms).sum()
}

/// The time of a frame's effect passes, milliseconds.
fn effect_ms(frame: &Frame) -> f64 {
    let effects = ["fog", "atmosphere", "shadows", "water"];
    // Folded from +0: an empty `sum` of floats is -0, printed "-0.0".
    frame.passes.iter().filter(|p| effects.contains(&p.0)).fold(0.0, |ms, p| ms + p.1)
}

/// RMS and max of (rendered - formula) over every 4th pixel that shows
/// the DEM (not its void), in metres (`relief_tests::surface`); 0 when
/// none does.
fn surface_error(frame: &Frame) -> (f64, f64) {
    let point_in_ecef = |px: u32, py: u32, depth: f32| {
        let (dir, distance) = frame.view.unproject(f64::from(px), f64::from(py), frame.width, frame.height, depth);
        (frame.view.eye + dir * distance).to_array()
    };
    relief_tests::surface::demo_surface_error(&frame.depth, frame.width, frame.height, point_in_ecef)
        .unwrap_or((0.0, 0.0))
}

fn main() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = relief_examples::write_demo_scene(dir.path())?;
    let scene = common::load(&manifest, 2)?;
    let snap = scene.snapshot();
    let terrain = SceneTerrain::new(&scene.store, &snap, snap.manifest.quality);
    let gpu = Arc::new(Gpu::headless()?);
    if let Some(frames) = std::env::var("RELIEF_BENCH_PROFILE_FRAMES").ok().and_then(|v| v.parse().ok()) {
        return profile(&gpu, &snap, &terrain, frames);
    }
    if std::env::var_os("RELIEF_BENCH_EFFECTS_ONLY").is_some() {
        return effects(&gpu, &snap, &terrain);
    }
    println!("\n## Frame time at 1280 x 720, demo scene, against surface error");
    println!("machine: {}; device: {}", relief_tests::machine(), gpu.description);
    println!(
        "camera: 9000 m, 25 degrees down, flying 25 m a frame; error from the depth buffer against the terrain formula"
    );
    println!(
        "| n | L | triangles drawn (about) | flying frame ms (median of 10) | still frame ms (median of 5) | RMS error m | max error m |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut default_still = 0.0;
    for n in [63usize, 127, 255] {
        for levels in [4usize, 6, 8] {
            let config = ClipmapConfig::new(n, levels);
            let mut renderer = Renderer::new(Arc::clone(&gpu), Surface::new(snap.grid.clone()), config)?;
            // The first frame fills every level and builds tiles: not timed.
            renderer.render(&terrain, &pose(0), &SETTINGS)?;
            let flying = (1..=10)
                .map(|k| Ok(total_ms(&renderer.render(&terrain, &pose(k), &SETTINGS)?)))
                .collect::<anyhow::Result<Vec<f64>>>()?;
            let mut still = Vec::new();
            let mut last = None;
            for _ in 0..5 {
                let frame = renderer.render(&terrain, &pose(10), &SETTINGS)?;
                still.push(total_ms(&frame));
                last = Some(frame);
            }
            let frame = last.context("no frame rendered")?;
            let (rms, max) = surface_error(&frame);
            // Every cell of every active level, less the finer levels' holes
            // and the blocks culled outside the view or beyond the horizon.
            let d = frame.drawn;
            let triangles =
                frame.update.active.len() * (n - 1) * (n - 1) * 2 * d.terrain_blocks_drawn / d.terrain_blocks.max(1);
            let still = median(still);
            if config == ClipmapConfig::default() {
                default_still = still;
            }
            println!("| {n} | {levels} | {triangles} | {:.1} | {still:.1} | {rms:.2} | {max:.1} |", median(flying));
        }
    }
    // The brute-force reference: the DEM's finest level, every sample.
    let renderer = Renderer::new(Arc::clone(&gpu), Surface::new(snap.grid.clone()), ClipmapConfig::default())?;
    let [w, s, e, n] = relief_examples::DEMO_EXTENT;
    let level = terrain.max_level() - 1;
    let area = Extent::new(w, s, e, n);
    let mut times = Vec::new();
    let mut mesh_ms = 0.0;
    let mut last = None;
    for _ in 0..3 {
        let frame = renderer
            .render_full_mesh(&terrain, level, &area, &pose(10), &SETTINGS)?
            .context("the DEM's tiles are not ready")?;
        mesh_ms = frame.passes[0].1;
        times.push(frame.passes[1].1);
        last = Some(frame);
    }
    let frame = last.context("no frame rendered")?;
    let (rms, max) = surface_error(&frame);
    let step = snap.grid.sample_step(level);
    let samples = ((e - w) / step).ceil() * ((n - s) / step).ceil();
    let brute = median(times);
    println!("\n### Brute force: the whole DEM at tile level {level} as one mesh ({:.0} triangles)", 2.0 * samples);
    println!(
        "| renderer | frame ms (draw and read back, median of 3) | mesh build ms (CPU, once) | RMS error m | max error m | clipmap default (n 127, L 8) still frame / brute force |"
    );
    println!("|---|---|---|---|---|---|");
    println!(
        "| full-resolution mesh | {brute:.1} | {mesh_ms:.0} | {rms:.2} | {max:.1} | {:.2}x |",
        default_still / brute
    );
    culling(&gpu, &snap, &terrain, brute)?;
    effects(&gpu, &snap, &terrain)?;
    passes(&gpu, &scene, &terrain)?;
    min_levels(&gpu, &manifest)?;
    Ok(())
}

/// Only the default still frame, `frames` times, for a profiler
/// (`RELIEF_BENCH_PROFILE_FRAMES=200 perf record ...`): each pass's median.
fn profile(
    gpu: &Arc<Gpu>,
    snap: &relief_daemon::graph::SceneSnapshot,
    terrain: &SceneTerrain<'_>,
    frames: usize,
) -> anyhow::Result<()> {
    // The demo's effects named in RELIEF_BENCH_PROFILE_EFFECTS (commas), on
    // top of lighting.
    let named = std::env::var("RELIEF_BENCH_PROFILE_EFFECTS").unwrap_or_default();
    let on = |name: &str| named.split(',').any(|n| n.trim() == name);
    let declared = relief_daemon::picture::Picture::of(&snap.manifest).effect_settings;
    let settings = RenderSettings {
        atmosphere: declared.atmosphere.filter(|_| on("atmosphere")),
        fog: declared.fog.filter(|_| on("fog")),
        shadows: declared.shadows.filter(|_| on("shadows")),
        water: declared.water.filter(|_| on("water")),
        ..SETTINGS
    };
    let layers = layers_of(terrain, &settings);
    let mut renderer = default_renderer(gpu, snap)?;
    renderer.render_scene(terrain, layers, &pose(10), &settings)?;
    // Each frame's pass times only: the images go, as a viewer's do.
    let runs = (0..frames.max(1))
        .map(|_| Ok(renderer.render_scene(terrain, layers, &pose(10), &settings)?.passes))
        .collect::<anyhow::Result<Vec<Vec<(&str, f64)>>>>()?;
    println!("\n## The default still frame, {} times (for a profiler), effects: {named}", runs.len());
    println!("| pass | median ms |");
    println!("|---|---|");
    for (i, (name, _)) in runs[0].iter().enumerate() {
        println!("| {name} | {:.1} |", median(runs.iter().map(|f| f[i].1).collect()));
    }
    println!("| frame | {:.1} |", median(runs.iter().map(|f| f.iter().map(|p| p.1).sum()).collect()));
    Ok(())
}

/// Seven still frames from `at` with the default clipmap, after one that
/// fills its levels and builds its tiles and passes (not kept).
fn still_frames(
    gpu: &Arc<Gpu>,
    snap: &relief_daemon::graph::SceneSnapshot,
    terrain: &SceneTerrain<'_>,
    settings: &RenderSettings,
    at: &Pose,
) -> anyhow::Result<Vec<Frame>> {
    let poses = vec![*at; 7];
    frames_along(gpu, snap, terrain, settings, at, &poses)
}

/// Frames of `settings` from each of `poses` in turn, after one (untimed)
/// from `first`, by one renderer.
fn frames_along(
    gpu: &Arc<Gpu>,
    snap: &relief_daemon::graph::SceneSnapshot,
    terrain: &SceneTerrain<'_>,
    settings: &RenderSettings,
    first: &Pose,
    poses: &[Pose],
) -> anyhow::Result<Vec<Frame>> {
    let mut renderer = default_renderer(gpu, snap)?;
    let layers = layers_of(terrain, settings);
    renderer.render_scene(terrain, layers, first, settings)?;
    poses.iter().map(|at| Ok(renderer.render_scene(terrain, layers, at, settings)?)).collect()
}

/// A renderer of the scene's grid with the default clipmap.
fn default_renderer(gpu: &Arc<Gpu>, snap: &relief_daemon::graph::SceneSnapshot) -> anyhow::Result<Renderer> {
    Ok(Renderer::new(Arc::clone(gpu), Surface::new(snap.grid.clone()), ClipmapConfig::default())?)
}

/// The layers a frame of `settings` draws: the water layer's coverage
/// where it declares water.
fn layers_of<'a>(terrain: &'a SceneTerrain<'_>, settings: &RenderSettings) -> SceneLayers<'a> {
    SceneLayers { water: settings.water.map(|_| terrain as &dyn WaterSamples), ..SceneLayers::default() }
}

/// Frames each `in_turns` takes turns over, for the effects table.
const ROUNDS: usize = 15;

/// One timed frame: all its passes, its effect passes, and the shadow
/// maps it drew.
struct Timed {
    total: f64,
    effects: f64,
    maps_drawn: usize,
}

/// One renderer for each of `settings`, each first drawing from `first`
/// (untimed), then taking turns over `poses`, one frame each: a change in
/// the machine's load falls on every setting alike, as it would not on
/// settings timed one after another.
fn in_turns(
    gpu: &Arc<Gpu>,
    snap: &relief_daemon::graph::SceneSnapshot,
    terrain: &SceneTerrain<'_>,
    settings: &[RenderSettings],
    first: &Pose,
    poses: &[Pose],
) -> anyhow::Result<Vec<Vec<Timed>>> {
    let mut renderers = settings
        .iter()
        .map(|s| {
            let mut renderer = default_renderer(gpu, snap)?;
            renderer.render_scene(terrain, layers_of(terrain, s), first, s)?;
            Ok(renderer)
        })
        .collect::<anyhow::Result<Vec<Renderer>>>()?;
    let mut timed: Vec<Vec<Timed>> = settings.iter().map(|_| Vec::new()).collect();
    for at in poses {
        for ((renderer, s), out) in renderers.iter_mut().zip(settings).zip(&mut timed) {
            let frame = renderer.render_scene(terrain, layers_of(terrain, s), at, s)?;
            out.push(Timed {
                total: total_ms(&frame),
                effects: effect_ms(&frame),
                maps_drawn: frame.drawn.shadow_maps_drawn,
            });
        }
    }
    Ok(timed)
}

/// The default clipmap's still frame with the level blocks outside the
/// view culled (the default) and with every block drawn: the same image
/// (the renderer's tests check it), at what cost.
fn culling(
    gpu: &Arc<Gpu>,
    snap: &relief_daemon::graph::SceneSnapshot,
    terrain: &SceneTerrain<'_>,
    brute: f64,
) -> anyhow::Result<()> {
    println!(
        "\n### Culling the clipmap's level blocks (16 x 16 cells) outside the view and beyond the horizon, n 127, L 8, still camera"
    );
    println!(
        "| blocks | blocks drawn | of them beyond the horizon | frame ms (median of 7) | terrain pass ms | brute force / this |"
    );
    println!("|---|---|---|---|---|---|");
    let mut frames = Vec::new();
    for (label, cull) in [("all drawn", false), ("culled (default)", true)] {
        let runs = still_frames(gpu, snap, terrain, &RenderSettings { cull, ..SETTINGS }, &pose(10))?;
        let total = median(runs.iter().map(total_ms).collect());
        let pass =
            median(runs.iter().filter_map(|f| f.passes.iter().find(|p| p.0 == "terrain")).map(|p| p.1).collect());
        let d = runs[0].drawn;
        println!(
            "| {label} | {} of {} | {} | {total:.1} | {pass:.1} | {:.2}x |",
            d.terrain_blocks_drawn,
            d.terrain_blocks,
            d.terrain_blocks_beyond_horizon,
            brute / total
        );
        frames.push(total);
    }
    println!("culled / all drawn: {:.2}x the frame time", frames[1] / frames[0]);
    Ok(())
}

/// The default still frame with lighting alone, then with each effect
/// added alone, then all of them (the demo's own settings for each): the
/// goal is all of them at most twice lighting alone. Then the knob
/// `atmosphere_steps` against a 256-step frame, by day and at dawn.
fn effects(
    gpu: &Arc<Gpu>,
    snap: &relief_daemon::graph::SceneSnapshot,
    terrain: &SceneTerrain<'_>,
) -> anyhow::Result<()> {
    let fog =
        relief_daemon::picture::Picture::of(&snap.manifest).effect_settings.fog.context("the demo declares fog")?;
    let atmosphere = relief_daemon::picture::Picture::of(&snap.manifest)
        .effect_settings
        .atmosphere
        .context("the demo declares an atmosphere")?;
    let shadows = relief_daemon::picture::Picture::of(&snap.manifest)
        .effect_settings
        .shadows
        .context("the demo declares shadows")?;
    let water =
        relief_daemon::picture::Picture::of(&snap.manifest).effect_settings.water.context("the demo declares water")?;
    // Frame and effect passes' medians and the last frame.
    let still = |settings: RenderSettings, at: &Pose| -> anyhow::Result<(f64, f64, Frame)> {
        let runs = still_frames(gpu, snap, terrain, &settings, at)?;
        let total = median(runs.iter().map(total_ms).collect());
        let effects = median(runs.iter().map(effect_ms).collect());
        Ok((total, effects, runs.into_iter().last().context("frames")?))
    };
    let lit = SETTINGS;
    let cases = [
        ("lighting alone", lit),
        ("lighting + atmosphere", RenderSettings { atmosphere: Some(atmosphere), ..lit }),
        ("lighting + fog", RenderSettings { fog: Some(fog), ..lit }),
        ("lighting + shadows", RenderSettings { shadows: Some(shadows), ..lit }),
        ("lighting + water", RenderSettings { water: Some(water), ..lit }),
        (
            "all effects (lighting, atmosphere, fog, shadows, water)",
            RenderSettings {
                atmosphere: Some(atmosphere),
                fog: Some(fog),
                shadows: Some(shadows),
                water: Some(water),
                ..lit
            },
        ),
        (
            "all effects but shadows",
            RenderSettings { atmosphere: Some(atmosphere), fog: Some(fog), water: Some(water), ..lit },
        ),
    ];
    println!(
        "\n### Effects: the default frame (n 127, L 8), still (median of {ROUNDS}) and flying 25 m a frame (median of {ROUNDS})"
    );
    println!("machine: {}; device: {}", relief_tests::machine(), gpu.description);
    println!(
        "the cases take turns, one frame each, so a change in the machine's load falls on all of them alike; a camera under a still sun keeps its shadow maps while their boxes, fixed in the world, still hold its view (`shadow maps drawn` counts those drawn in the timed frames)"
    );
    println!(
        "| effects | effect passes ms | still frame ms | / lighting alone | flying frame ms | / lighting alone | shadow maps drawn, still / flying |"
    );
    println!("|---|---|---|---|---|---|---|");
    let settings: Vec<RenderSettings> = cases.iter().map(|c| c.1).collect();
    let at_rest = in_turns(gpu, snap, terrain, &settings, &pose(10), &vec![pose(10); ROUNDS])?;
    let flying = in_turns(gpu, snap, terrain, &settings, &pose(0), &(1..=ROUNDS).map(pose).collect::<Vec<_>>())?;
    let total = |timed: &[Timed]| median(timed.iter().map(|t| t.total).collect());
    let maps = |timed: &[Timed]| timed.iter().map(|t| t.maps_drawn).sum::<usize>();
    let (alone, alone_flying) = (total(&at_rest[0]), total(&flying[0]));
    for ((label, _), (rest, fly)) in cases.iter().zip(at_rest.iter().zip(&flying)) {
        let effect_ms = median(rest.iter().map(|t| t.effects).collect());
        let (total_still, total_flying) = (total(rest), total(fly));
        println!(
            "| {label} | {effect_ms:.1} | {total_still:.1} | {:.2}x | {total_flying:.1} | {:.2}x | {} / {} |",
            total_still / alone,
            total_flying / alone_flying,
            maps(rest),
            maps(fly)
        );
    }

    println!("\n### Knobs `atmosphere_steps` and `atmosphere_downsample`, frame 1280 x 720, median of 7");
    println!(
        "reference: the same frame with 256 steps, a ray for every pixel; error: RMS over every pixel's R, G and B (0-255)"
    );
    println!("| light | steps | downsample | atmosphere pass ms | frame ms | RMS error | max error |");
    println!("|---|---|---|---|---|---|---|");
    // Looking level-ish along the range so sky and distance both show.
    let view = Pose { pitch_deg: -6.0, ..pose(10) };
    for (light, sun) in [
        ("day (sun 45 deg up)", SunAngles::DEFAULT),
        ("dawn (sun 3 deg up, ahead)", SunAngles { azimuth_deg: 30.0, elevation_deg: 3.0 }),
    ] {
        let with = |steps, downsample| RenderSettings {
            sun,
            atmosphere: Some(Atmosphere { steps, downsample, ..atmosphere }),
            ..SETTINGS
        };
        let (_, _, reference) = still(with(Atmosphere::MAX_STEPS, 1), &view)?;
        let d = Atmosphere::DEFAULT_DOWNSAMPLE;
        let settings = [2u32, 4, 8, 12, 16, 24, 36, 64]
            .map(|s| (s, d))
            .into_iter()
            .chain([1, 2, 3, 8].map(|k| (Atmosphere::DEFAULT_STEPS, k)));
        for (steps, downsample) in settings {
            let (total, pass_ms, frame) = still(with(steps, downsample), &view)?;
            let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
            for (a, b) in frame.rgba.chunks(4).zip(reference.rgba.chunks(4)) {
                for k in 0..3 {
                    let d = f64::from(a[k]) - f64::from(b[k]);
                    sum += d * d;
                    max = max.max(d.abs());
                    n += 1;
                }
            }
            let rms = (sum / n as f64).sqrt();
            let default = if (steps, downsample) == (Atmosphere::DEFAULT_STEPS, d) { " (default)" } else { "" };
            println!("| {light} | {steps} | {downsample}{default} | {pass_ms:.1} | {total:.1} | {rms:.2} | {max:.0} |");
        }
    }
    Ok(())
}

/// The town view of `passes`, still, for the extrude knob `min_level`.
fn town_view() -> Pose {
    let (lon, lat) = relief_examples::DEMO_TOWN_CENTRE;
    Pose {
        position: [lon, lat - 0.025, 800.0],
        heading_deg: 5.0,
        pitch_deg: -18.0,
        roll_deg: 0.0,
        vertical_fov_deg: 50.0,
    }
}

/// The knob `min_level` of `extrude`: buildings come from tiles of that
/// level or finer, so a coarser one draws buildings farther from the
/// camera at more cost. Error: the share of the buildings the most
/// generous setting (8) draws in this view that are left out.
fn min_levels(gpu: &Arc<Gpu>, manifest: &std::path::Path) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(manifest)?;
    let mut rows = Vec::new();
    for level in [8u8, 9, 10, 11, 12, 13] {
        let variant = manifest.with_file_name(format!("scene-min-level-{level}.toml"));
        std::fs::write(&variant, text.replace("min_level = 10", &format!("min_level = {level}")))?;
        let scene = common::load(&variant, 2)?;
        let snap = scene.snapshot();
        let terrain = SceneTerrain::new(&scene.store, &snap, snap.manifest.quality);
        let buildings =
            SceneBuildings::new(&scene.store, &snap, snap.manifest.quality).context("the demo has a town")?;
        let mut renderer = default_renderer(gpu, &snap)?;
        renderer.render_scene(
            &terrain,
            SceneLayers { buildings: Some(&buildings), instances: None, water: None },
            &town_view(),
            &SETTINGS,
        )?;
        let frames = (0..5)
            .map(|_| {
                Ok(renderer.render_scene(
                    &terrain,
                    SceneLayers { buildings: Some(&buildings), instances: None, water: None },
                    &town_view(),
                    &SETTINGS,
                )?)
            })
            .collect::<anyhow::Result<Vec<Frame>>>()?;
        let pass =
            median(frames.iter().filter_map(|f| f.passes.iter().find(|p| p.0 == "buildings")).map(|p| p.1).collect());
        rows.push((level, frames[0].drawn.buildings, pass, median(frames.iter().map(total_ms).collect())));
    }
    println!("\n### Knob: extrude `min_level` (buildings from tiles of that level or finer), town view");
    println!("| min_level | buildings drawn | left out (of min_level 8's) | buildings pass ms | frame ms |");
    println!("|---|---|---|---|---|");
    let all = rows[0].1.max(1) as f64;
    for (level, drawn, pass, total) in rows {
        println!("| {level} | {drawn} | {:.1} % | {pass:.1} | {total:.1} |", 100.0 * (1.0 - drawn as f64 / all));
    }
    Ok(())
}

/// The scene's passes from a camera over the demo town (2,000 buildings):
/// terrain alone, then terrain and buildings, still frames at 1280 x 720.
fn passes(gpu: &Arc<Gpu>, scene: &relief_daemon::scene::Scene, terrain: &SceneTerrain<'_>) -> anyhow::Result<()> {
    let snap = scene.snapshot();
    let buildings = SceneBuildings::new(&scene.store, &snap, snap.manifest.quality).context("the demo has a town")?;
    let town = town_view();
    let mut renderer = default_renderer(gpu, &snap)?;
    // First frames fill the levels and build tiles and meshes: not timed.
    renderer.render_scene(
        terrain,
        SceneLayers { buildings: Some(&buildings), instances: None, water: None },
        &town,
        &SETTINGS,
    )?;
    let mut rows = Vec::new();
    for (name, with_buildings) in [("terrain alone", false), ("terrain + buildings", true)] {
        let meshes = with_buildings.then_some(&buildings as &dyn relief_renderer::MeshTiles);
        let mut frames = Vec::new();
        for _ in 0..5 {
            frames.push(renderer.render_scene(
                terrain,
                SceneLayers { buildings: meshes, instances: None, water: None },
                &town,
                &SETTINGS,
            )?);
        }
        let pass_ms = |pass: &str| {
            median(frames.iter().filter_map(|f| f.passes.iter().find(|p| p.0 == pass)).map(|p| p.1).collect())
        };
        let total = median(frames.iter().map(total_ms).collect());
        rows.push((name, pass_ms("terrain"), with_buildings.then(|| pass_ms("buildings")), total));
    }
    println!(
        "\n## The scene's passes at 1280 x 720 over the demo town ({} buildings)",
        relief_examples::DEMO_TOWN_BUILDINGS
    );
    println!("machine: {}; device: {}", relief_tests::machine(), gpu.description);
    println!("camera: 800 m, 18 degrees down, 2.8 km south of the town's centre; still frames, median of 5");
    println!("| scene | terrain pass ms | buildings pass ms | frame ms (passes and read back) | / terrain alone |");
    println!("|---|---|---|---|---|");
    let alone = rows[0].3;
    for (name, terrain_ms, buildings_ms, total) in rows {
        let b = buildings_ms.map_or("-".to_owned(), |ms| format!("{ms:.1}"));
        println!("| {name} | {terrain_ms:.1} | {b} | {total:.1} | {:.2}x |", total / alone);
    }
    Ok(())
}
