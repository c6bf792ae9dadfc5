//! Instances on a real device: stock models near and their billboards far,
//! where the trees stand; distance bands and the model/billboard switch
//! fade instead of popping; the antimeridian, near a pole and a camera one
//! metre above a tree; and no instances pass for a scene without them.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::collections::HashMap;
use std::sync::Arc;

use relief_models::Model;
use relief_renderer::{
    ClipmapConfig, Frame, InstanceBands, InstanceTiles, Pose, RenderSettings, Renderer, SceneLayers, Surface,
};
use relief_source::{Instance, InstanceKind, InstanceTile, Payload, TileGrid, TileKey};

mod common;

use common::{Analytic, gpu, pose, project, save};

const SETTINGS: RenderSettings = RenderSettings::new(480, 320, true);
/// Every instance drawn (no thinning), models to 400 m.
const ALL_DRAWN: InstanceBands =
    InstanceBands { edges_m: [700.0, 1400.0, 3000.0], densities: [1.0; 3], model_distance_m: 400.0 };
const LEVEL: u8 = 14;

fn flat(_lon: f64, _lat: f64) -> f64 {
    0.0
}

/// Trees at given points on the analytic ground, served as instance tiles
/// at LEVEL, with the stock models.
struct Forest {
    grid: TileGrid,
    trees: Vec<(f64, f64, &'static str)>,
    height: fn(f64, f64) -> f64,
    models: HashMap<&'static str, Arc<Model>>,
}

impl Forest {
    fn new(height: fn(f64, f64) -> f64, trees: Vec<(f64, f64, &'static str)>) -> Self {
        let models = relief_models::STOCK.iter().map(|&n| (n, Arc::new(relief_models::stock(n).unwrap()))).collect();
        Self { grid: TileGrid::geodetic(256).unwrap(), trees, height, models }
    }
}

impl InstanceTiles for Forest {
    fn level(&self) -> u8 {
        LEVEL
    }

    fn instances(&self, keys: &[TileKey]) -> Vec<Option<Arc<Payload>>> {
        keys.iter()
            .map(|&key| {
                let instances = self
                    .trees
                    .iter()
                    .enumerate()
                    .filter(|(_, (x, y, _))| self.grid.key_at(key.level, *x, *y) == Some(key))
                    .map(|(k, &(x, y, model))| Instance {
                        feature_id: k as u64,
                        position: [x, y, (self.height)(x, y)],
                        kind: InstanceKind::Model,
                        model: model.into(),
                        scale: 1.0,
                        rotation_deg: 0.0,
                    })
                    .collect();
                Some(Arc::new(Payload::Instances(InstanceTile { instances, skipped: Vec::new() })))
            })
            .collect()
    }

    fn model(&self, name: &str) -> Option<Arc<Model>> {
        self.models.get(name).cloned()
    }
}

fn scene(height: fn(f64, f64) -> f64) -> (Renderer, Analytic) {
    let surface = Surface::new(TileGrid::geodetic(256).unwrap());
    let source = Analytic { surface: surface.clone(), height, max_level: 16, ready_up_to: u8::MAX };
    (Renderer::new(gpu(), surface, ClipmapConfig::default()).unwrap(), source)
}

fn draw(renderer: &mut Renderer, source: &Analytic, forest: &Forest, view: &Pose, bands: InstanceBands) -> Frame {
    let settings = RenderSettings { bands, ..SETTINGS };
    let layers = SceneLayers { buildings: None, instances: Some(forest), water: None };
    renderer.render_scene(source, layers, view, &settings).unwrap()
}

/// Degrees of latitude for `m` metres north.
fn north(m: f64) -> f64 {
    m / 111_320.0
}

/// Distance along the ray to what pixel (px, py) shows; None for sky.
fn distance_at(frame: &Frame, (px, py): (u32, u32)) -> Option<f64> {
    let depth = frame.depth[(py * frame.width + px) as usize];
    (depth > 0.0).then(|| frame.view.unproject(f64::from(px), f64::from(py), frame.width, frame.height, depth).1)
}

/// Mean square difference of two frames' colours (additive over pixels:
/// a change made in two steps sums to the change made at once).
fn mse(a: &Frame, b: &Frame) -> f64 {
    let sum: f64 = a.rgba.iter().zip(&b.rgba).map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2)).sum();
    sum / a.rgba.len() as f64
}

#[test]
fn models_near_and_billboards_far_stand_where_the_trees_are() {
    let (mut renderer, source) = scene(flat);
    let distances = [40.0, 90.0, 160.0, 300.0, 800.0, 1300.0];
    // Each at its own bearing, so none hides another.
    let at = |k: usize, d: f64| {
        let a = (k as f64 * 6.0 - 15.0).to_radians();
        (10.0 + north(d * a.sin()) / 45f64.to_radians().cos(), 45.0 + north(d * a.cos()))
    };
    let trees = distances.iter().enumerate().map(|(k, d)| (at(k, *d).0, at(k, *d).1, "conifer")).collect();
    let forest = Forest::new(flat, trees);
    let view = pose(10.0, 45.0, 3.0, 0.0, 0.0);
    let frame = draw(&mut renderer, &source, &forest, &view, ALL_DRAWN);
    save(&frame, "instances-row.png");
    assert_eq!((frame.drawn.models, frame.drawn.billboards), (4, 2), "models to 400 m, billboards past it");
    let crown = relief_models::stock("conifer").unwrap().height() / 2.0;
    let surface = renderer.surface().clone();
    for (k, d) in distances.into_iter().enumerate() {
        let (lon, lat) = at(k, d);
        let centre = surface.world(lon, lat, f64::from(crown));
        let pixel = project(&frame, centre).unwrap();
        let seen = distance_at(&frame, pixel).unwrap_or(0.0);
        let truth = (centre - frame.view.eye).length();
        // The crown is about 2.5 m in radius: the pixel shows its near side.
        assert!(
            (seen - truth).abs() < 3.0,
            "tree at {d} m: the pixel shows something {seen:.1} m away, not {truth:.1}"
        );
    }
    // Nothing behind the camera is drawn.
    let behind = Forest::new(flat, vec![(10.0, 45.0 - north(50.0), "conifer")]);
    let frame = draw(&mut renderer, &source, &behind, &view, ALL_DRAWN);
    assert_eq!((frame.drawn.models, frame.drawn.billboards), (0, 0));
}

/// A frame per value of a knob, with trees all at one distance: a hard
/// switch would change the image in one step; a fade spreads the change
/// over many.
fn largest_step_share(forest: &Forest, view: &Pose, bands: impl Fn(f64) -> InstanceBands, knob: &[f64]) -> f64 {
    let (mut renderer, source) = scene(flat);
    let frames: Vec<Frame> = knob.iter().map(|&k| draw(&mut renderer, &source, forest, view, bands(k))).collect();
    let total = mse(&frames[0], &frames[frames.len() - 1]);
    assert!(total > 0.05, "the knob changes the image ({total})");
    let steps: Vec<f64> = frames.windows(2).map(|w| mse(&w[0], &w[1])).collect();
    steps.iter().copied().fold(0.0, f64::max) / total
}

/// Trees on an arc `d` metres from the camera point, across the view.
fn arc(d: f64, count: usize) -> Vec<(f64, f64, &'static str)> {
    (0..count)
        .map(|k| {
            let a = (k as f64 / (count - 1) as f64 - 0.5) * 40f64.to_radians();
            (10.0 + north(d * a.sin()) / 45f64.to_radians().cos(), 45.0 + north(d * a.cos()), "broadleaf")
        })
        .collect()
}

#[test]
fn models_cross_fade_into_billboards_without_popping() {
    let forest = Forest::new(flat, arc(400.0, 60));
    let view = pose(10.0, 45.0, 20.0, 0.0, -1.0);
    let knob: Vec<f64> = (0..=16).map(|k| 320.0 + 10.0 * f64::from(k)).collect();
    let bands = |m: f64| InstanceBands { model_distance_m: m, ..ALL_DRAWN };
    let share = largest_step_share(&forest, &view, bands, &knob);
    assert!(share < 0.5, "one 10 m step of the switch makes {:.0} % of its change", share * 100.0);
}

#[test]
fn a_band_edge_thins_instances_without_popping() {
    let forest = Forest::new(flat, arc(700.0, 120));
    let view = pose(10.0, 45.0, 30.0, 0.0, -1.5);
    let knob: Vec<f64> = (0..=16).map(|k| 620.0 + 10.0 * f64::from(k)).collect();
    let bands = |edge: f64| InstanceBands {
        edges_m: [edge, 1400.0, 3000.0],
        densities: [1.0, 0.5, 0.5],
        model_distance_m: 0.0,
    };
    let share = largest_step_share(&forest, &view, bands, &knob);
    assert!(share < 0.5, "one 10 m step of the band edge makes {:.0} % of its change", share * 100.0);
}

#[test]
fn bands_keep_their_share_of_instances() {
    // A square kilometre of trees 10 m apart straight ahead; the middle
    // band keeps 80 %, the far one 50 %.
    let mut trees = Vec::new();
    for i in -50..50 {
        for j in 0..300 {
            trees.push((
                10.0 + north(f64::from(i) * 10.0) / 45f64.to_radians().cos(),
                45.0 + north(f64::from(j) * 10.0),
                "shrub",
            ));
        }
    }
    let forest = Forest::new(flat, trees);
    let (mut renderer, source) = scene(flat);
    let view = pose(10.0, 45.0, 2000.0, 0.0, -89.0);
    let mut count = |densities: [f64; 3]| {
        let bands = InstanceBands { edges_m: [5000.0, 6000.0, 7000.0], densities, model_distance_m: 0.0 };
        draw(&mut renderer, &source, &forest, &view, bands).drawn.billboards as f64
    };
    let all = count([1.0; 3]);
    let most = count([0.8; 3]);
    let half = count([0.5; 3]);
    assert!(all > 1000.0, "{all}");
    assert!((most / all - 0.8).abs() < 0.05, "80 % band kept {:.3}", most / all);
    assert!((half / all - 0.5).abs() < 0.05, "50 % band kept {:.3}", half / all);
}

#[test]
fn a_scene_without_instances_builds_no_instances_pass() {
    let (mut renderer, source) = scene(flat);
    let view = pose(10.0, 45.0, 3.0, 0.0, 0.0);
    renderer.render(&source, &view, &SETTINGS).unwrap();
    let find = |r: &Renderer| r.counters().stats().iter().find(|s| s.name == "instances").copied().unwrap();
    assert_eq!((find(&renderer).built, find(&renderer).runs), (false, 0));
    let forest = Forest::new(flat, vec![(10.0, 45.0 + north(60.0), "conifer")]);
    draw(&mut renderer, &source, &forest, &view, ALL_DRAWN);
    assert_eq!((find(&renderer).built, find(&renderer).runs), (true, 1));
    renderer.render(&source, &view, &SETTINGS).unwrap();
    assert_eq!((find(&renderer).built, find(&renderer).runs), (false, 1));
}

#[test]
fn hard_cases_the_antimeridian_a_pole_and_a_camera_a_metre_above_a_tree() {
    // Two trees either side of the antimeridian, the camera on it.
    let (mut renderer, source) = scene(flat);
    let dx = north(30.0) / (-17f64).to_radians().cos();
    let forest = Forest::new(
        flat,
        vec![(180.0 - dx, -17.0 + north(120.0), "conifer"), (-180.0 + dx, -17.0 + north(120.0), "conifer")],
    );
    for lon in [180.0, -180.0 + 1e-9, 179.9999] {
        let frame = draw(&mut renderer, &source, &forest, &pose(lon, -17.0, 3.0, 0.0, 0.0), ALL_DRAWN);
        assert_eq!(frame.drawn.models, 2, "camera at {lon}");
    }

    // Near the north pole: a ring of trees round the camera's view.
    let trees = (0..12).map(|k| (f64::from(k) * 30.0 - 180.0, 89.998, "conifer")).collect();
    let forest = Forest::new(flat, trees);
    let frame = draw(&mut renderer, &source, &forest, &pose(0.0, 89.995, 40.0, 0.0, -5.0), ALL_DRAWN);
    save(&frame, "instances-pole.png");
    assert!(frame.drawn.models + frame.drawn.billboards >= 3, "{:?}", frame.drawn);
    assert!(frame.depth.iter().all(|d| d.is_finite()));

    // A camera one metre above a tree's top, looking down: the tree fills
    // the middle of the image, one metre away.
    let top = f64::from(relief_models::stock("broadleaf").unwrap().bounds.max[1]);
    let forest = Forest::new(flat, vec![(10.0, 45.0, "broadleaf")]);
    let frame = draw(&mut renderer, &source, &forest, &pose(10.0, 45.0, top + 1.0, 0.0, -90.0), ALL_DRAWN);
    save(&frame, "instances-above.png");
    let seen = distance_at(&frame, (SETTINGS.width / 2, SETTINGS.height / 2)).unwrap();
    assert!((seen - 1.0).abs() < 0.3, "the tree top is {seen} m away");
    assert!(frame.rgba.chunks_exact(4).all(|p| p[3] == 255));
}
