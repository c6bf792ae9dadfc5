//! Buildings on the analytic hill, on a real device: the terrain the CPU
//! lifts buildings onto is the terrain the GPU draws, and every building
//! stands on it (touches it, its roof its height above it) at two clipmap
//! configurations.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::sync::Arc;

use relief_renderer::{ClipmapConfig, Frame, MeshTiles, Pose, RenderSettings, Renderer, SceneLayers, Surface};
use relief_source::{MeshPart, MeshTile, Payload, TileGrid, TileKey, geodesy};

mod common;

use common::{Analytic, gpu, hill_scene, pose, project, save};

const SETTINGS: RenderSettings = RenderSettings::new(480, 320, true);
/// Two clipmap configurations: coarse levels (the drawn terrain far from
/// the data) and the default.
const CONFIGS: [ClipmapConfig; 2] = [ClipmapConfig::new(31, 10), ClipmapConfig::new(127, 8)];
/// Buildings 40 m square and 25 m high.
const SIDE_M: f64 = 40.0;
const HEIGHT_M: f64 = 25.0;

/// Heights and the GPU's depth agree to float precision at these
/// distances (f32 eye-relative positions, reversed-Z depth): 5 cm.
const GROUND_TOL_M: f64 = 0.05;

/// Half a building's side in degrees of longitude and latitude at `lat`.
fn half_side_deg(lat: f64) -> (f64, f64) {
    let hy = SIDE_M / 2.0 / 111_320.0;
    (hy / lat.to_radians().cos(), hy)
}

/// The geodetic point a pixel shows, or None for sky.
fn shown(frame: &Frame, px: u32, py: u32) -> Option<(f64, f64, f64)> {
    let depth = frame.depth[(py * frame.width + px) as usize];
    let p = frame.view.world_at(f64::from(px), f64::from(py), frame.width, frame.height, depth)?;
    Some(geodesy::geodetic_from_ecef(p.to_array()))
}

#[test]
fn the_terrain_buildings_are_lifted_onto_is_the_terrain_the_device_draws() {
    let gpu = gpu();
    for config in CONFIGS {
        let (mut renderer, source) = hill_scene(&gpu, config);
        for view in [pose(10.25, 45.2, 6000.0, 0.0, -90.0), pose(10.2, 45.1, 3000.0, 20.0, -25.0)] {
            let frame = renderer.render(&source, &view, &SETTINGS).unwrap();
            let (mut worst, mut checked) = (0.0f64, 0);
            for py in (0..frame.height).step_by(7) {
                for px in (0..frame.width).step_by(7) {
                    let Some((lon, lat, h)) = shown(&frame, px, py) else { continue };
                    let Some(drawn) = renderer.drawn_height(&view, &frame.update.active, lon, lat) else { continue };
                    if (drawn - h).abs() > 0.1 && std::env::var_os("RELIEF_DEBUG").is_some() {
                        for &t in frame.update.active.iter().rev() {
                            let l = renderer.clipmap().level(t).unwrap();
                            let (sx, sy) = renderer.surface().sample_coords(t, lon, lat);
                            eprintln!(
                                "  level {t} fi {:.2} fj {:.2} n {}",
                                sx - l.origin.0 as f64,
                                sy - l.origin.1 as f64,
                                l.n
                            );
                        }
                        let d = frame.depth[(py * frame.width + px) as usize];
                        eprintln!("({px},{py}) {lon} {lat} h {h} drawn {drawn} depth {d}");
                    }
                    worst = worst.max((drawn - h).abs());
                    checked += 1;
                }
            }
            assert!(checked > 500, "{config:?} {view:?}: only {checked} pixels on the levels");
            assert!(worst < GROUND_TOL_M, "{config:?} {view:?}: drawn heights differ by {worst} m");
        }
    }
}

/// Buildings on a grid of points on the hill's slope, given in whichever
/// tile owns each one's centre at every level from `min_level` on (tiles
/// coarser are empty), built the way `extrude` builds them: the base at
/// the lowest data height under the footprint, walls and a flat roof.
struct Town<'a> {
    source: &'a Analytic,
    centres: Vec<(f64, f64)>,
    min_level: u8,
}

impl<'a> Town<'a> {
    fn new(source: &'a Analytic, min_level: u8) -> Self {
        let centres = (0..6)
            .flat_map(|i| (0..4).map(move |j| (10.1925 + 0.003 * f64::from(i), 45.121 + 0.003 * f64::from(j))))
            .collect();
        Self { source, centres, min_level }
    }

    /// A square SIDE_M a side round `(cx, cy)` (degrees; east of 180 kept
    /// unwrapped, as `extrude` keeps a footprint on the antimeridian whole).
    fn corners((cx, cy): (f64, f64)) -> [(f64, f64); 4] {
        let (hx, hy) = half_side_deg(cy);
        [(cx - hx, cy - hy), (cx + hx, cy - hy), (cx + hx, cy + hy), (cx - hx, cy + hy)]
    }

    /// The building whose footprint is nearest (lon, lat), if within its
    /// footprint's reach.
    fn at(&self, lon: f64, lat: f64) -> Option<(usize, (f64, f64))> {
        let metres = |c: &(f64, f64)| {
            let dx = ((lon - c.0 + 540.0) % 360.0 - 180.0) * 111_320.0 * c.1.to_radians().cos();
            dx.hypot((lat - c.1) * 111_320.0)
        };
        let (b, c) = self.centres.iter().enumerate().min_by(|a, b| metres(a.1).total_cmp(&metres(b.1)))?;
        (metres(c) < SIDE_M).then_some((b, *c))
    }

    fn tile(&self, key: TileKey) -> MeshTile {
        let mut mesh = MeshTile::default();
        if key.level < self.min_level {
            return mesh;
        }
        let grid = self.source.surface.grid();
        for (b, &centre) in self.centres.iter().enumerate() {
            if grid.key_at(key.level, centre.0, centre.1) != Some(key) {
                continue;
            }
            let ring = Self::corners(centre);
            let base = ring.iter().map(|&(x, y)| (self.source.height)(x, y)).fold(f64::INFINITY, f64::min);
            let first = mesh.indices.len() as u32;
            let roof = mesh.positions.len() as u32;
            mesh.positions.extend(ring.iter().map(|&(x, y)| [x, y, base + HEIGHT_M]));
            mesh.indices.extend([roof, roof + 1, roof + 2, roof, roof + 2, roof + 3]);
            for k in 0..4 {
                let (a, c) = (ring[k], ring[(k + 1) % 4]);
                let v = mesh.positions.len() as u32;
                let top = base + HEIGHT_M;
                mesh.positions.extend([[a.0, a.1, base], [c.0, c.1, base], [c.0, c.1, top], [a.0, a.1, top]]);
                mesh.indices.extend([v, v + 1, v + 2, v, v + 2, v + 3]);
            }
            let index_count = mesh.indices.len() as u32 - first;
            mesh.parts.push(MeshPart {
                feature_id: b as u64,
                first_index: first,
                index_count,
                color: [40, 60, 230, 255],
                on_ground: true,
            });
        }
        mesh
    }
}

impl MeshTiles for Town<'_> {
    fn min_level(&self) -> u8 {
        self.min_level
    }

    fn meshes(&self, keys: &[TileKey]) -> Vec<Option<Arc<Payload>>> {
        keys.iter().map(|&k| Some(Arc::new(Payload::Mesh(self.tile(k))))).collect()
    }
}

/// How the town stands in the frame from `view`: per building drawn (more
/// than 15 pixels) the roof is its height above the drawn ground's lowest
/// corner, not raised and not sunk (the highest pixel within its footprint
/// of the roof); and at each lowest corner facing the camera, the pixel of
/// a point two pixels inside the corner, a little above the drawn ground
/// (two pixels' footprint, at least 30 cm), shows the wall or something in
/// front of it, never the ground behind (which a floating building would
/// show there). Returns the buildings drawn and the corners probed.
fn check_standing(
    renderer: &mut Renderer,
    town: &Town<'_>,
    view: &Pose,
    settings: &RenderSettings,
    label: &str,
) -> (usize, usize) {
    let source = town.source;
    let bare = renderer.render(source, view, settings).unwrap();
    let frame = renderer
        .render_scene(source, SceneLayers { buildings: Some(town), instances: None, water: None }, view, settings)
        .unwrap();
    save(&frame, &format!("{label}.png"));
    assert_eq!(frame.passes.iter().map(|p| p.0).collect::<Vec<_>>(), ["terrain", "buildings", "read back"]);
    assert!(frame.depth.iter().all(|d| d.is_finite()), "{label}: a depth is not finite");
    let drawn = |(x, y): (f64, f64)| renderer.drawn_height(view, &frame.update.active, x, y);
    let pixel_angle = view.vertical_fov_deg.to_radians() / f64::from(frame.height);
    let mut seen = vec![(f64::NEG_INFINITY, f64::NEG_INFINITY, 0usize); town.centres.len()];
    for py in 0..frame.height {
        for px in 0..frame.width {
            let i = (py * frame.width + px) as usize;
            if frame.depth[i] <= bare.depth[i] * 1.000_01 {
                continue; // Terrain: no building in front here.
            }
            let Some((lon, lat, h)) = shown(&frame, px, py) else { continue };
            let Some((b, c)) = town.at(lon, lat) else { continue };
            let base = Town::corners(c).into_iter().filter_map(drawn).fold(f64::INFINITY, f64::min);
            let point = frame.view.world_at(f64::from(px), f64::from(py), frame.width, frame.height, frame.depth[i]);
            let footprint = (point.unwrap() - frame.view.eye).length() * pixel_angle;
            let s = &mut seen[b];
            s.0 = s.0.max(h - base);
            s.1 = s.1.max(h - base + footprint);
            s.2 += 1;
        }
    }
    let standing: Vec<_> = seen.iter().filter(|s| s.2 > 15).collect();
    for (highest, reach, _) in &standing {
        assert!(*highest < HEIGHT_M + 0.1, "{label}: a roof at {highest} m, not {HEIGHT_M}");
        assert!(*reach > HEIGHT_M - 0.1, "{label}: a roof at {highest} m ({reach} with a pixel), not {HEIGHT_M}");
    }
    let surface = renderer.surface();
    let (mut probed, mut worst) = (0, 0.0f64);
    for &centre in &town.centres {
        // The lowest corner (any within a centimetre of it) facing the camera.
        let corners: Vec<_> = Town::corners(centre).into_iter().filter_map(|c| Some((c, drawn(c)?))).collect();
        let lowest = corners.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
        let facing = corners.into_iter().filter(|c| c.1 < lowest + 0.01).find_map(|(corner, ground)| {
            let foot = surface.world(corner.0, corner.1, ground);
            let inward = (surface.world(centre.0, centre.1, ground) - foot).normalize();
            (inward.dot(frame.view.eye - foot) < 0.0).then_some((corner, foot, inward))
        });
        let Some((corner, foot, inward)) = facing else { continue };
        let footprint = (foot - frame.view.eye).length() * pixel_angle;
        let lift = (2.0 * footprint).max(0.3);
        let probe = foot + surface.enu(corner.0, corner.1)[2] * lift + inward * (2.0 * footprint).max(0.5);
        let Some((px, py)) = project(&frame, probe) else { continue };
        let i = (py * frame.width + px) as usize;
        let Some(shown) = frame.view.world_at(f64::from(px), f64::from(py), frame.width, frame.height, frame.depth[i])
        else {
            continue;
        };
        // Something in front (another building) hides the corner: fine.
        // The ground behind showing through would be farther.
        let behind = (shown - frame.view.eye).length() - (probe - frame.view.eye).length();
        worst = worst.max(behind / (3.0 * footprint + 0.5));
        probed += 1;
    }
    assert!(worst < 1.0, "{label}: a building's foot shows {worst} times the allowance away from the wall");
    (standing.len(), probed)
}

#[test]
fn buildings_touch_the_drawn_terrain_and_stand_their_height_above_it() {
    let gpu = gpu();
    // Fine pixels: 40 cm at 300 m, so a building floating more than that
    // shows.
    let settings = RenderSettings { width: 1200, height: 800, ..SETTINGS };
    for config in CONFIGS {
        let (mut renderer, source) = hill_scene(&gpu, config);
        // Buildings from level 9 on: where the terrain is drawn that fine
        // or finer (within a few kilometres here).
        let town = Town::new(&source, 9);
        let view = pose(10.2, 45.118, 880.0, 0.0, -12.0);
        let (standing, probed) = check_standing(&mut renderer, &town, &view, &settings, &format!("town-{}", config.n));
        assert!(standing >= 8, "{config:?}: only {standing} buildings in view");
        assert!(probed >= 4, "{config:?}: only {probed} lowest corners in view");
    }
}

fn cliff(lon: f64, _lat: f64) -> f64 {
    // 1,000 m straight up at 10.2 E.
    if lon < 10.2 { 500.0 } else { 1500.0 }
}

fn plain(_lon: f64, _lat: f64) -> f64 {
    300.0
}

#[test]
fn hard_cases_a_cliff_under_a_building_the_antimeridian_and_near_a_pole() {
    let gpu = gpu();
    let settings = RenderSettings { width: 960, height: 640, ..SETTINGS };
    let surface = Surface::new(TileGrid::geodetic(256).unwrap());
    let scene = |height: fn(f64, f64) -> f64| {
        let source = Analytic { surface: surface.clone(), height, max_level: 16, ready_up_to: u8::MAX };
        let renderer = Renderer::new(Arc::clone(&gpu), surface.clone(), ClipmapConfig::default()).unwrap();
        (renderer, source)
    };
    // A building across a 1,000 m cliff stands at the cliff's foot (its
    // base is its lowest ground, as `extrude` makes it), its uphill walls in
    // the rock; seen from below, it stands and its numbers stay finite.
    let (mut renderer, source) = scene(cliff);
    let (hx, _) = half_side_deg(45.0);
    let town = Town { source: &source, centres: vec![(10.2 - hx / 2.0, 45.0), (10.199, 45.0005)], min_level: 12 };
    let (standing, _) =
        check_standing(&mut renderer, &town, &pose(10.199, 44.9965, 560.0, 0.0, -5.0), &settings, "cliff");
    assert!(standing >= 2, "cliff: {standing} buildings drawn");
    // Across the antimeridian: buildings both sides of 180, one on it.
    let (mut renderer, source) = scene(plain);
    let (hx, _) = half_side_deg(-17.0);
    let centres = vec![(179.9985, -17.0), (180.0 - hx / 3.0, -16.9995), (-179.9985, -17.0)];
    let town = Town { source: &source, centres, min_level: 12 };
    let (standing, probed) =
        check_standing(&mut renderer, &town, &pose(180.0, -17.004, 420.0, 0.0, -15.0), &settings, "antimeridian");
    assert!(standing == 3 && probed >= 2, "antimeridian: {standing} drawn, {probed} corners probed");
    // Near the north pole, where degrees of longitude are short (a
    // building 40 m wide spans 0.05 degrees at 89.6 N; the clipmap's
    // windows, square in samples, reach only some 70 m east and west
    // there, so the town stands within that).
    let (mut renderer, source) = scene(plain);
    let centres = vec![(20.0, 89.6), (20.0, 89.6012), (20.06, 89.6006)];
    let town = Town { source: &source, centres, min_level: 12 };
    let (standing, probed) =
        check_standing(&mut renderer, &town, &pose(20.0, 89.5965, 420.0, 0.0, -15.0), &settings, "pole");
    assert!(standing == 3 && probed >= 2, "pole: {standing} drawn, {probed} corners probed");
}

#[test]
fn a_frame_without_buildings_builds_no_buildings_pass() {
    let (mut renderer, source) = hill_scene(&gpu(), ClipmapConfig::default());
    renderer.render(&source, &pose(10.25, 45.2, 6000.0, 0.0, -60.0), &SETTINGS).unwrap();
    let stats = renderer.counters().stats();
    let find = |n: &str| stats.iter().find(|s| s.name == n).copied().unwrap();
    assert!(find("terrain").built && find("terrain").runs == 1);
    assert_eq!((find("buildings").built, find("buildings").runs), (false, 0));
    // Built when a frame has buildings, dropped when the scene has none again.
    let town = Town::new(&source, 9);
    let view = pose(10.2, 45.118, 880.0, 0.0, -12.0);
    renderer
        .render_scene(&source, SceneLayers { buildings: Some(&town), instances: None, water: None }, &view, &SETTINGS)
        .unwrap();
    assert!(renderer.counters().stats().iter().any(|s| s.name == "buildings" && s.built && s.runs == 1));
    renderer.render(&source, &view, &SETTINGS).unwrap();
    assert!(renderer.counters().stats().iter().any(|s| s.name == "buildings" && !s.built && s.runs == 1));
}

#[test]
fn buildings_stay_after_the_camera_flies_round_the_planet() {
    let surface = Surface::new(TileGrid::geodetic(256).unwrap());
    let source = Analytic { surface: surface.clone(), height: plain, max_level: 16, ready_up_to: u8::MAX };
    let mut renderer = Renderer::new(gpu(), surface, ClipmapConfig::default()).unwrap();
    let (hx, _) = half_side_deg(-17.0);
    let centres = vec![(179.9985, -17.0), (180.0 - hx / 3.0, -16.9995), (-179.9985, -17.0)];
    let town = Town { source: &source, centres, min_level: 12 };
    let view = |lon: f64| pose(lon, -17.004, 420.0, 0.0, -15.0);
    let drawn = |r: &mut Renderer, lon: f64| {
        r.render_scene(
            &source,
            SceneLayers { buildings: Some(&town), instances: None, water: None },
            &view(lon),
            &SETTINGS,
        )
        .unwrap()
        .drawn
        .buildings
    };
    assert_eq!(drawn(&mut renderer, 180.0), 3);
    // Twice round eastwards, 45 degrees a frame: the clipmap's windows
    // follow without bound; the buildings must still be found.
    for step in 1..=16 {
        drawn(&mut renderer, (180.0 + 45.0 * f64::from(step) + 180.0) % 360.0 - 180.0);
    }
    assert_eq!(drawn(&mut renderer, 180.0), 3);
}
