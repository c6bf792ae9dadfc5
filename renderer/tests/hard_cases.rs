//! The renderer's hard cases (docs/hard-cases.md), on a real wgpu device
//! (lavapipe in CI) over analytic terrains with known answers: a DEM of
//! one constant value, NaN samples and voids, a 1,000 m cliff, and a flat
//! scene whose coordinates are ten thousand kilometres from its CRS's
//! origin.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::ops::Range;

use relief_renderer::{ClipmapConfig, Frame, RenderSettings, Renderer, SunAngles, Surface, TerrainSamples};
use relief_source::{GridKind, ProjectedGrid, TileGrid};

mod common;

use common::{gpu, pose, save};

const SETTINGS: RenderSettings = RenderSettings::new(320, 180, true);

/// A terrain given by a formula sampled exactly at every lattice point,
/// without colour (drawn light grey, as a scene without a colour layer, so
/// that the shading alone shows the normals), or with one colour where it
/// has data and none (alpha 0) where it has not, as a colour layer over a
/// DEM with voids gives.
struct Formula {
    surface: Surface,
    height: fn(f64, f64) -> f64,
    max_level: u8,
    color: Option<[u8; 3]>,
}

impl Formula {
    fn points(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        for gy in ys {
            for gx in xs.clone() {
                let (mut x, mut y) = self.surface.sample_point(level, gx, gy);
                if self.surface.is_planet() && !(-90.0..=90.0).contains(&y) {
                    y = y.signum() * 180.0 - y;
                    x += 180.0;
                }
                out.push((x, y));
            }
        }
        out
    }
}

impl TerrainSamples for Formula {
    fn heights(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<f32>> {
        Some(self.points(level, xs, ys).into_iter().map(|(x, y)| (self.height)(x, y) as f32).collect())
    }

    fn colors(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<[u8; 4]>> {
        let paint = |(x, y)| match self.color {
            Some([r, g, b]) if (self.height)(x, y).is_finite() => [r, g, b, 255],
            _ => [0; 4],
        };
        Some(self.points(level, xs, ys).into_iter().map(paint).collect())
    }

    fn max_level(&self) -> u8 {
        self.max_level
    }
}

/// A flat scene: `size` metres of UTM 12N from (min_x, min_y).
fn flat_scene(min_x: f64, min_y: f64, size: f64, height: fn(f64, f64) -> f64) -> (Renderer, Formula) {
    let grid = TileGrid::new(GridKind::Projected(ProjectedGrid { crs: "EPSG:32612".into(), min_x, min_y, size }), 256)
        .unwrap();
    let surface = Surface::new(grid);
    let source = Formula { surface: surface.clone(), height, max_level: 10, color: None };
    (Renderer::new(gpu(), surface, ClipmapConfig::default()).unwrap(), source)
}

fn planet_scene(height: fn(f64, f64) -> f64) -> (Renderer, Formula) {
    let surface = Surface::new(TileGrid::geodetic(256).unwrap());
    let source = Formula { surface: surface.clone(), height, max_level: 14, color: None };
    (Renderer::new(gpu(), surface, ClipmapConfig::default()).unwrap(), source)
}

/// The terrain pixels' colours (depth > 0), and a check that every depth
/// is a finite number and no terrain pixel is black: a NaN normal or
/// position shades to black (sunlight is never below its ambient part).
fn terrain_pixels(frame: &Frame, name: &str) -> Vec<[u8; 3]> {
    let mut out = Vec::new();
    for (k, (d, p)) in frame.depth.iter().zip(frame.rgba.chunks_exact(4)).enumerate() {
        assert!(d.is_finite() && *d >= 0.0, "{name}: depth {d} at pixel {k}");
        if *d > 0.0 {
            assert!(p[..3].iter().any(|c| *c > 20), "{name}: pixel {k} is black {p:?} (a NaN shade)");
            out.push([p[0], p[1], p[2]]);
        }
    }
    out
}

/// The spread of each channel over `pixels`.
fn spread(pixels: &[[u8; 3]]) -> u8 {
    (0..3)
        .map(|c| {
            let (lo, hi) = pixels.iter().fold((255, 0), |(lo, hi), p| (p[c].min(lo), p[c].max(hi)));
            hi - lo
        })
        .max()
        .unwrap()
}

fn lit(sun: SunAngles) -> RenderSettings {
    RenderSettings { sun, ..SETTINGS }
}

const FLAT_M: f64 = 1234.5;

fn constant(_x: f64, _y: f64) -> f64 {
    FLAT_M
}

/// A DEM of one value is flat ground: every normal straight up, so every
/// pixel has the one shade of a level surface, and that shade does not
/// change as the sun goes round at the same elevation. Tolerance: 1 level
/// in 255 on a flat scene; 2 on the planet, whose up turns across the
/// view while the sun stands over the camera.
#[test]
fn a_constant_dem_is_lit_as_level_ground_whatever_the_suns_azimuth() {
    let cases = [
        ("flat, from above", false, pose(300_000.0, 5_100_000.0, FLAT_M + 3000.0, 0.0, -90.0), 1),
        ("flat, 1 m up", false, pose(300_000.0, 5_100_000.0, FLAT_M + 1.0, 30.0, -10.0), 1),
        ("planet, from above", true, pose(10.0, 45.0, FLAT_M + 3000.0, 0.0, -90.0), 2),
        ("planet, 1 m up", true, pose(10.0, 45.0, FLAT_M + 1.0, 30.0, -10.0), 2),
    ];
    for (name, planet, at, tolerance) in cases {
        let (mut renderer, source) =
            if planet { planet_scene(constant) } else { flat_scene(290_000.0, 5_090_000.0, 20_000.0, constant) };
        let mut shades = Vec::new();
        for azimuth_deg in [0.0, 90.0, 200.0, 315.0] {
            let frame = renderer.render(&source, &at, &lit(SunAngles { azimuth_deg, elevation_deg: 40.0 })).unwrap();
            save(&frame, &format!("hard-constant-{}-{azimuth_deg}.png", name.replace([' ', ','], "-")));
            let pixels = terrain_pixels(&frame, name);
            assert!(pixels.len() > 10_000, "{name}: only {} terrain pixels", pixels.len());
            assert!(spread(&pixels) <= tolerance, "{name}, sun at {azimuth_deg}: shades spread {}", spread(&pixels));
            shades.push(pixels[pixels.len() / 2]);
        }
        // Straight up: the sun's dot product is the sine of its elevation.
        // The terrain shader's grey (0.78) under its ambient (0.35) and
        // diffuse (0.75) sunlight.
        let expected = 255.0 * 0.78 * (0.35 + 0.75 * 40f64.to_radians().sin());
        assert!(
            (f64::from(shades[0][0]) - expected).abs() <= 1.0,
            "{name}: shade {:?}, level ground {expected:.1}",
            shades[0]
        );
        assert!(spread(&shades) <= tolerance, "{name}: the shade turns with the sun: {shades:?}");
    }
}

/// A hill (500 to 2000 m) with a square void of NaN samples 600 m wide on
/// its flank and single NaN samples scattered over it, one in 97.
fn holed(x: f64, y: f64) -> f64 {
    let (dx, dy) = (x - 300_000.0, y - 5_100_000.0);
    if (1_000.0..1_600.0).contains(&dx) && (-300.0..300.0).contains(&dy) {
        return f64::NAN;
    }
    let k = ((x * 0.37).floor() as i64).wrapping_mul(73_856_093) ^ ((y * 0.37).floor() as i64).wrapping_mul(19_349_663);
    if k.rem_euclid(97) == 0 {
        return f64::NAN;
    }
    500.0 + 1500.0 * (-(dx * dx + dy * dy) / (2.0 * 2500.0 * 2500.0)).exp()
}

/// `holed` laid on the planet round 10 E, 45 N.
fn holed_planet(lon: f64, lat: f64) -> f64 {
    holed(300_000.0 + (lon - 10.0) * 78_710.0, 5_100_000.0 + (lat - 45.0) * 111_132.0)
}

/// NaN samples never reach the mesh or its shading: every depth finite,
/// no black (NaN-shaded) pixel, from above, from the side, from a camera
/// one metre over the void (whose ground the clipmap cannot probe), on a
/// flat scene and on the planet, and from 40,000 km; with a colour layer
/// that has no colour over the voids, whose edges are drawn part grey,
/// never darkened to black. Nodata is drawn at 0 m (the datum), as
/// documented in docs/hard-cases.md: the void is a pit down to 0 m, not a
/// hole through the ground.
#[test]
fn nan_samples_and_voids_leave_no_nan_in_the_mesh_or_its_shading() {
    let (mut flat, mut flat_source) = flat_scene(290_000.0, 5_090_000.0, 20_000.0, holed);
    let (mut planet, mut planet_source) = planet_scene(holed_planet);
    flat_source.color = Some([90, 140, 60]);
    planet_source.color = Some([90, 140, 60]);
    let void_lon = 10.0 + 1_300.0 / 78_710.0;
    for (name, on_planet, at) in [
        ("flat, above", false, pose(301_300.0, 5_100_000.0, 5000.0, 0.0, -90.0)),
        ("flat, side", false, pose(301_300.0, 5_097_000.0, 2500.0, 0.0, -30.0)),
        ("flat, 1 m over the void", false, pose(301_300.0, 5_100_000.0, 1.0, 90.0, -20.0)),
        ("planet, side", true, pose(void_lon, 44.97, 2500.0, 0.0, -30.0)),
        ("planet, 1 m over the void", true, pose(void_lon, 45.0, 1.0, 90.0, -20.0)),
        ("planet, 40,000 km", true, pose(void_lon, 45.0, 40_000_000.0, 0.0, -90.0)),
    ] {
        let frame = if on_planet {
            planet.render(&planet_source, &at, &SETTINGS)
        } else {
            flat.render(&flat_source, &at, &SETTINGS)
        }
        .unwrap();
        save(&frame, &format!("hard-voids-{}.png", name.replace([' ', ','], "-")));
        let pixels = terrain_pixels(&frame, name);
        // From 40,000 km the planet is some 57 pixels across.
        let least = if name.ends_with("km") { 2_000 } else { 10_000 };
        assert!(pixels.len() > least, "{name}: only {} terrain pixels", pixels.len());
    }
    // The void is drawn at the datum: straight down from 5 km over its
    // middle the ground is 5 km away.
    let frame = flat.render(&flat_source, &pose(301_300.0, 5_100_000.0, 5000.0, 0.0, -90.0), &SETTINGS).unwrap();
    let (w, h) = (frame.width, frame.height);
    let depth = frame.depth[(h / 2 * w + w / 2) as usize];
    let (_, distance) = frame.view.unproject(f64::from(w / 2), f64::from(h / 2), w, h, depth);
    assert!((distance - 5000.0).abs() < 1.0, "the void's floor is {distance} m below a camera 5 km up");
}

/// Where the cliff stands: 500 m west of this easting, 1,500 m from it on.
const CLIFF_X: f64 = 300_000.0;

fn cliff(x: f64, _y: f64) -> f64 {
    if x < CLIFF_X { 500.0 } else { 1500.0 }
}

/// Each terrain pixel's world point and colour.
fn ground_points(frame: &Frame) -> Vec<(glam::DVec3, [u8; 3])> {
    let (w, h) = (frame.width, frame.height);
    (0..w * h)
        .filter_map(|k| {
            let d = frame.depth[k as usize];
            (d > 0.0).then(|| {
                let (dir, distance) = frame.view.unproject(f64::from(k % w), f64::from(k / w), w, h, d);
                let p = &frame.rgba[k as usize * 4..k as usize * 4 + 3];
                (frame.view.eye + dir * distance, [p[0], p[1], p[2]])
            })
        })
        .collect()
}

/// The cells of the level drawn at grid point (x, y) in the last frame:
/// the finest active level whose window holds it, and its spacing, or the
/// coarser level's where the two blend (near a window's edge).
fn cell_at(renderer: &Renderer, x: f64, y: f64) -> f64 {
    let clipmap = renderer.clipmap();
    let active = clipmap.active();
    let finest = active.iter().rev().position(|&t| {
        let window = clipmap.level(t).unwrap().window();
        let (sx, sy) = renderer.surface().sample_coords(t, x, y);
        (window.x.start as f64..=(window.x.end - 1) as f64).contains(&sx)
            && (window.y.start as f64..=(window.y.end - 1) as f64).contains(&sy)
    });
    let k = finest.map_or(0, |from_end| (active.len() - 1 - from_end).saturating_sub(1));
    renderer.surface().step(active[k])
}

/// A 1,000 m cliff (a step between two samples at every level): no NaN
/// normal (no black pixel, every depth finite) from above, from its foot,
/// from its top and from far off. The slope's shading stays on the cliff:
/// ground more than two cells (of the level drawn there, or of the coarser
/// one it blends onto) from the cliff keeps the shade of level ground to
/// 1 in 255, and the face itself, whose normals all face west, is shaded
/// evenly: at least 90% of its pixels within 3 in 255 of its median
/// (the rest are its foot and brow, where normals turn from the plain's).
#[test]
fn a_thousand_metre_cliff_has_finite_normals_and_its_shading_stays_on_it() {
    let (mut renderer, source) = flat_scene(290_000.0, 5_090_000.0, 20_000.0, cliff);
    let level = renderer.render(&source, &pose(295_000.0, 5_100_000.0, 3000.0, 0.0, -90.0), &SETTINGS).unwrap();
    let level_shade = terrain_pixels(&level, "level ground")[0];
    for (name, at) in [
        ("above", pose(CLIFF_X, 5_100_000.0, 1800.0, 0.0, -90.0)),
        ("high above", pose(CLIFF_X, 5_100_000.0, 6000.0, 0.0, -90.0)),
        ("from its foot", pose(CLIFF_X - 800.0, 5_100_000.0, 520.0, 90.0, 10.0)),
        ("from its top", pose(CLIFF_X + 30.0, 5_100_000.0, 1501.0, 270.0, -30.0)),
        ("far off", pose(CLIFF_X - 8000.0, 5_094_000.0, 2500.0, 45.0, -10.0)),
    ] {
        let frame = renderer.render(&source, &at, &SETTINGS).unwrap();
        save(&frame, &format!("hard-cliff-{}.png", name.replace(' ', "-")));
        terrain_pixels(&frame, name);
        let (mut plain, mut smeared, mut face) = (0, Vec::new(), Vec::new());
        for (p, c) in ground_points(&frame) {
            let off = (p.x - CLIFF_X).abs();
            let cell = cell_at(&renderer, p.x, p.y);
            if (p.z - 500.0).abs() < 0.5 || (p.z - 1500.0).abs() < 0.5 {
                if off > 2.0 * cell {
                    plain += 1;
                    if (0..3).any(|k| c[k].abs_diff(level_shade[k]) > 1) {
                        smeared.push((off, cell, c));
                    }
                }
            } else if (600.0..1400.0).contains(&p.z) {
                face.push(c);
            }
        }
        // The face's shade: its median pixel's; how many pixels are within
        // 3 in 255 of it.
        face.sort_unstable();
        let even = face.get(face.len() / 2).map_or(1.0, |m| {
            face.iter().filter(|c| (0..3).all(|k| c[k].abs_diff(m[k]) <= 3)).count() as f64 / face.len() as f64
        });
        eprintln!(
            "{name}: {plain} pixels of plain, {} of face, {:.1}% of them evenly shaded",
            face.len(),
            even * 100.0
        );
        assert!(
            smeared.is_empty(),
            "{name}: slope shading smeared over the plain: {:?}",
            &smeared[..smeared.len().min(5)]
        );
        assert!(plain > 5_000, "{name}: only {plain} pixels of plain");
        assert!(even >= 0.9, "{name}: only {:.1}% of the face's pixels have its shade", even * 100.0);
    }
}

/// A false easting and northing of 10,000 km, as southern UTM zones and
/// many national grids have: the same scene, moved there exactly.
const FAR_X: f64 = 10_000_000.0;
const FAR_Y: f64 = 10_000_000.0;

fn far_surface(x: f64, y: f64) -> f64 {
    relief_examples::utm_surface(x - FAR_X, y - FAR_Y)
}

/// Huge coordinates: a flat scene 10,000 km from its CRS's origin draws
/// the very image it draws near it (positions reach the GPU relative to
/// the eye, never absolute), from above, 1 m over the ground and from
/// 40,000 km; and 1 m over the ground a 0.1 mm step moves nothing on
/// screen. Tolerance: 2 in 255 per channel on 99.9% of the pixels, depth
/// to 1e-4 of the distance.
#[test]
fn a_scene_ten_thousand_kilometres_from_its_origin_draws_as_it_does_near_it() {
    let (mut near, near_source) = flat_scene(290_000.0, 5_090_000.0, 20_000.0, relief_examples::utm_surface);
    let (mut far, far_source) = flat_scene(290_000.0 + FAR_X, 5_090_000.0 + FAR_Y, 20_000.0, far_surface);
    let ground = relief_examples::utm_surface(300_000.0, 5_100_000.0);
    for (name, at) in [
        ("above", pose(300_000.0, 5_100_000.0, 4000.0, 20.0, -60.0)),
        ("1 m up", pose(300_000.0, 5_100_000.0, ground + 1.0, 200.0, -15.0)),
        ("40,000 km", pose(300_000.0, 5_100_000.0, 40_000_000.0, 0.0, -90.0)),
    ] {
        let mut moved = at;
        moved.position[0] += FAR_X;
        moved.position[1] += FAR_Y;
        let a = near.render(&near_source, &at, &SETTINGS).unwrap();
        let b = far.render(&far_source, &moved, &SETTINGS).unwrap();
        save(&b, &format!("hard-far-{}.png", name.replace([' ', ','], "-")));
        terrain_pixels(&b, name);
        let differing = a
            .rgba
            .chunks(4)
            .zip(b.rgba.chunks(4))
            .filter(|(p, q)| p.iter().zip(*q).any(|(u, v)| u.abs_diff(*v) > 2))
            .count();
        let depth_off =
            a.depth.iter().zip(&b.depth).filter(|(x, y)| (**x - **y).abs() > 1e-4 * x.abs().max(y.abs())).count();
        eprintln!("{name}: {differing} pixels differ in colour, {depth_off} in depth");
        let allowed = (a.width * a.height) as usize / 1000;
        assert!(differing <= allowed && depth_off <= allowed, "{name}: {differing} colours, {depth_off} depths differ");
    }
    // 1 m over the ground, 0.1 mm east: distances change by about the step
    // (not by a float's quantum at 10,000 km, 2 mm in f32).
    let a = pose(300_000.0 + FAR_X, 5_100_000.0 + FAR_Y, ground + 1.0, 200.0, -15.0);
    let mut b = a;
    b.position[0] += 1e-4;
    let (fa, fb) = (far.render(&far_source, &a, &SETTINGS).unwrap(), far.render(&far_source, &b, &SETTINGS).unwrap());
    let moved = (fa.view.eye - fb.view.eye).length();
    assert!((moved - 1e-4).abs() < 1e-6, "the eye moved {moved} m");
    let differing = fa
        .rgba
        .chunks(4)
        .zip(fb.rgba.chunks(4))
        .filter(|(p, q)| p.iter().zip(*q).any(|(u, v)| u.abs_diff(*v) > 3))
        .count();
    assert!(differing * 1000 < (SETTINGS.width * SETTINGS.height) as usize, "{differing} pixels changed colour");
}
