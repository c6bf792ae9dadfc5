//! The renderer on a real wgpu device (lavapipe in CI) over analytic
//! terrains with known heights.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use glam::DVec3;
use relief_renderer::{ClipLevel, ClipmapConfig, Frame, RenderSettings, Renderer, Surface};
use relief_source::{TileGrid, geodesy};

mod common;

use common::{Analytic, gpu, hill_scene, pose, save, utm_scene};

/// The base grid beyond the clipmap sits up to ~940 m low on the planet
/// (0.3% of its 313 km cells), so the horizon test allows for it.
const BASE_SINK_M: f64 = 1000.0;

const SETTINGS: RenderSettings = RenderSettings::new(320, 180, true);

/// Whether the ray from `eye` along `dir` meets the ellipsoid raised by `h`.
fn meets_ellipsoid(eye: DVec3, dir: DVec3, h: f64) -> bool {
    let scale = DVec3::new(1.0 / (geodesy::WGS84_A + h), 1.0 / (geodesy::WGS84_A + h), 1.0 / (geodesy::WGS84_B + h));
    let (o, d) = (eye * scale, dir * scale);
    let (a, b, c) = (d.dot(d), 2.0 * o.dot(d), o.dot(o) - 1.0);
    let disc = b * b - 4.0 * a * c;
    disc >= 0.0 && (-b - disc.sqrt()) / (2.0 * a) > 0.0
}

/// Pixels whose ray meets the lowest terrain but that show no terrain
/// (holes, cracks), and any depth that is not a finite number.
fn holes(frame: &Frame, lowest_m: f64) -> usize {
    let (w, h) = (frame.width, frame.height);
    let mut bad = 0;
    for py in 0..h {
        for px in 0..w {
            let depth = frame.depth[(py * w + px) as usize];
            assert!(depth.is_finite() && depth >= 0.0, "depth {depth} at ({px}, {py})");
            let (dir, _) = frame.view.unproject(f64::from(px), f64::from(py), w, h, 1.0);
            if depth == 0.0 && meets_ellipsoid(frame.view.eye, dir, lowest_m) {
                bad += 1;
            }
        }
    }
    bad
}

/// The largest height error over a grid of pixels, per (1 m + 1 mm per
/// metre of distance), against `truth` at the reconstructed point.
fn surface_error(
    frame: &Frame,
    to_surface: impl Fn(DVec3) -> (f64, f64, f64),
    truth: impl Fn(f64, f64) -> f64,
) -> (f64, usize) {
    let (w, h) = (frame.width, frame.height);
    let (mut worst, mut checked) = (0.0f64, 0);
    for py in (0..h).step_by(5) {
        for px in (0..w).step_by(5) {
            let depth = frame.depth[(py * w + px) as usize];
            if depth <= 0.0 {
                continue;
            }
            let (dir, distance) = frame.view.unproject(f64::from(px), f64::from(py), w, h, depth);
            let (x, y, z) = to_surface(frame.view.eye + dir * distance);
            let e = (z - truth(x, y)).abs() / (1.0 + 1e-3 * distance);
            if e > worst && std::env::var_os("RELIEF_DEBUG").is_some() {
                eprintln!("pixel ({px}, {py}) at ({x}, {y}) distance {distance}: {z} vs {}", truth(x, y));
            }
            worst = worst.max(e);
            checked += 1;
        }
    }
    (worst, checked)
}

#[test]
fn depth_reconstructs_the_analytic_hill_and_leaves_no_holes() {
    let (mut renderer, source) = hill_scene(&gpu(), ClipmapConfig::default());
    let frame = renderer.render(&source, &pose(10.1, 45.1, 4000.0, 45.0, -25.0), &SETTINGS).unwrap();
    save(&frame, "hill.png");
    let (worst, checked) = surface_error(&frame, |p| geodesy::geodetic_from_ecef(p.to_array()), relief_examples::hill);
    eprintln!("checked {checked} pixels, worst error {worst:.3} (m per 1 m + 1 mm/m)");
    // Tolerance: 1 m + 1 mm per metre of distance. Near the camera the
    // triangles of the finest level (4.8 m apart) on the hill's curvature
    // leave centimetres; far away coarser levels leave more.
    assert!(checked > 1000 && worst < 1.0, "{worst}");
    assert_eq!(holes(&frame, 500.0 - BASE_SINK_M), 0, "every pixel below the horizon is terrain");
}

#[test]
fn a_flat_projected_scene_reconstructs_its_surface() {
    let (mut renderer, source) = utm_scene(ClipmapConfig::default());
    let frame = renderer.render(&source, &pose(300_000.0, 5_095_000.0, 4000.0, 20.0, -30.0), &SETTINGS).unwrap();
    save(&frame, "utm.png");
    let (worst, checked) = surface_error(&frame, |p| (p.x, p.y, p.z), relief_examples::utm_surface);
    eprintln!("checked {checked} pixels, worst error {worst:.3}");
    assert!(checked > 1000 && worst < 1.0, "{worst}");
}

/// Every kept level equals a level filled from scratch at the same window:
/// the same world positions (f32 offsets from different anchors agree to
/// millimetres), the same normals and the same colours.
fn assert_matches_scratch(renderer: &Renderer, source: &Analytic) {
    for &t in renderer.clipmap().active() {
        let level = renderer.clipmap().level(t).unwrap();
        let scratch =
            ClipLevel::filled(renderer.surface(), source, t, level.n, level.color_detail, level.origin).unwrap();
        for k in 0..level.positions.len() {
            let (a, b) = (level.positions[k], scratch.positions[k]);
            let pa = level.anchor + DVec3::new(f64::from(a[0]), f64::from(a[1]), f64::from(a[2]));
            let pb = scratch.anchor + DVec3::new(f64::from(b[0]), f64::from(b[1]), f64::from(b[2]));
            assert!(
                (pa - pb).length() < 0.01 * (1.0 + f64::from(level.n as u32) * renderer.surface().step(t) * 1e-3),
                "level {t} sample {k}: {pa} vs {pb}"
            );
            assert_eq!(a[3], b[3]);
            // Normals worked out where samples changed and along a moved
            // edge: the same as all worked out at once, to a milliradian.
            let (na, nb) = (level.normals[k], scratch.normals[k]);
            let dot: f32 = (0..3).map(|c| na[c] * nb[c]).sum();
            let both_none = na == [0.0; 4] && nb == [0.0; 4];
            assert!(both_none || dot > 1.0 - 5e-7, "level {t} normal {k}: {na:?} vs {nb:?}");
        }
        let window = level.color_window();
        assert_eq!(window, scratch.color_window());
        for cy in window.y.clone() {
            for cx in window.x.clone() {
                assert_eq!(level.color_at(cx, cy), scratch.color_at(cx, cy), "level {t} colour sample ({cx}, {cy})");
            }
        }
        assert_eq!(window.x.end - window.x.start, (level.color_detail * (level.n - 1) + 1) as i64);
    }
}

#[test]
fn incremental_updates_equal_a_fill_from_scratch_across_the_antimeridian() {
    let (mut renderer, source) = hill_scene(&gpu(), ClipmapConfig::new(63, 5));
    // East across the antimeridian in small steps, then a jump back.
    let mut lon = 179.990;
    let mut written_moving = 0;
    for step in 0..12 {
        let frame = renderer.render(&source, &pose(lon, -16.8, 3000.0, 90.0, -40.0), &SETTINGS).unwrap();
        if step > 0 {
            written_moving += frame.update.samples_written;
        }
        lon += 0.0021;
        if lon > 180.0 {
            lon -= 360.0;
        }
        assert_matches_scratch(&renderer, &source);
        assert_nested(&renderer);
    }
    // Small moves rewrite strips, not windows: far less than a refill of
    // every level each step.
    let refill = (63 * 63 * 5 * 11) as u64;
    assert!(written_moving < refill / 3, "{written_moving} samples written moving, a refill per step is {refill}");
    let frame = renderer.render(&source, &pose(10.2, 45.2, 3000.0, 0.0, -40.0), &SETTINGS).unwrap();
    assert!(frame.update.samples_written > 0);
    assert_matches_scratch(&renderer, &source);
}

/// The colour detail knob: levels read their colour 0 or 2 tile levels
/// finer than their mesh, move incrementally as at the default, and a
/// frame's colours stay those of the default within a few levels of grey
/// (the tint is smooth, so finer imagery changes it little).
#[test]
fn every_colour_detail_moves_like_a_fill_from_scratch_and_agrees_with_the_default() {
    let at = pose(10.2, 45.2, 3000.0, 0.0, -40.0);
    let (mut reference, source) = hill_scene(&gpu(), ClipmapConfig::new(63, 5));
    let default = reference.render(&source, &at, &SETTINGS).unwrap();
    for color_detail in [1, 4] {
        let config = ClipmapConfig { color_detail, ..ClipmapConfig::new(63, 5) };
        let (mut renderer, source) = hill_scene(&gpu(), config);
        for step in 0..4 {
            let moved = pose(10.2 + f64::from(step) * 0.002, 45.2, 3000.0, 0.0, -40.0);
            renderer.render(&source, &moved, &SETTINGS).unwrap();
            assert_matches_scratch(&renderer, &source);
        }
        let frame = renderer.render(&source, &at, &SETTINGS).unwrap();
        let (mut sum, mut n) = (0.0, 0usize);
        for (a, b) in frame.rgba.chunks(4).zip(default.rgba.chunks(4)) {
            for k in 0..3 {
                sum += (f64::from(a[k]) - f64::from(b[k])).powi(2);
                n += 1;
            }
        }
        let rms = (sum / n as f64).sqrt();
        assert!(rms < 6.0, "colour detail {color_detail}: RMS {rms:.2} from the default's colours");
    }
}

#[test]
fn incremental_updates_cover_negative_indices_off_a_flat_grid() {
    let (mut renderer, source) = utm_scene(ClipmapConfig::new(63, 4));
    // Along the grid's north-west corner, so windows start at negative indices.
    let (mut negative_x, mut negative_y) = (false, false);
    for k in 0..10 {
        let x = 290_000.0 + f64::from(k) * 37.0 - 150.0;
        let y = 5_110_000.0 - f64::from(k) * 23.0 + 100.0;
        renderer.render(&source, &pose(x, y, 800.0, 135.0, -30.0), &SETTINGS).unwrap();
        assert_matches_scratch(&renderer, &source);
        for &t in renderer.clipmap().active() {
            let o = renderer.clipmap().level(t).unwrap().origin;
            negative_x |= o.0 < 0;
            negative_y |= o.1 < 0;
        }
    }
    assert!(negative_x && negative_y, "the path never took a window past the grid's corner");
}

#[test]
fn hard_cameras_give_whole_images() {
    let (mut renderer, source) = hill_scene(&gpu(), ClipmapConfig::default());
    let cases = [
        ("north pole", pose(0.0, 90.0, 20_000.0, 0.0, -90.0)),
        ("south pole", pose(0.0, -90.0, 20_000.0, 0.0, -90.0)),
        ("antimeridian", pose(180.0, -16.8, 5000.0, 270.0, -30.0)),
        ("40,000 km", pose(10.0, 45.0, 40_000_000.0, 0.0, -90.0)),
        ("1 m above the hill", pose(10.2, 45.2, relief_examples::hill(10.2, 45.2) + 1.0, 60.0, -10.0)),
    ];
    for (name, p) in cases {
        let frame = renderer.render(&source, &p, &SETTINGS).unwrap();
        save(&frame, &format!("hard-{}.png", name.replace([' ', ','], "-")));
        let lowest = if name.starts_with("1 m") { relief_examples::hill(10.2, 45.2) } else { 500.0 } - BASE_SINK_M;
        assert_eq!(holes(&frame, lowest), 0, "{name}: pixels below the horizon without terrain");
        let terrain = frame.depth.iter().filter(|d| **d > 0.0).count();
        assert!(terrain > 1000, "{name}: only {terrain} terrain pixels");
        if name.ends_with("pole") {
            // Flat ground seen from straight above: one shade, no seams
            // where windows fold over the pole.
            let greens: Vec<u8> = frame.rgba.chunks(4).map(|p| p[1]).collect();
            let (lo, hi) = (greens.iter().min().unwrap(), greens.iter().max().unwrap());
            assert!(hi - lo <= 6, "{name}: green from {lo} to {hi}");
        }
    }
}

/// Distances per pixel from reversed-Z depth (0 where there is sky).
fn distances(frame: &Frame) -> Vec<f64> {
    let (w, h) = (frame.width, frame.height);
    (0..w * h)
        .map(|k| {
            let d = frame.depth[k as usize];
            if d > 0.0 { frame.view.unproject(f64::from(k % w), f64::from(k / w), w, h, d).1 } else { 0.0 }
        })
        .collect()
}

#[test]
fn a_tenth_of_a_millimetre_moves_nothing_on_screen_one_metre_above_the_ground() {
    let (mut renderer, source) = hill_scene(&gpu(), ClipmapConfig::default());
    let ground = relief_examples::hill(10.3, 45.3);
    let a = pose(10.3, 45.3, ground + 1.0, 200.0, -15.0);
    // 0.1 mm east.
    let mut b = a;
    b.position[0] += 0.0001 / (geodesy::WGS84_A * 45.3f64.to_radians().cos()).to_radians();
    let (fa, fb) = (renderer.render(&source, &a, &SETTINGS).unwrap(), renderer.render(&source, &b, &SETTINGS).unwrap());
    let moved = (fa.view.eye - fb.view.eye).length();
    assert!((moved - 1e-4).abs() < 2e-5, "the eye moved {moved} m");
    // A point d metres away shifts by 0.1 mm / d radians: at 1 m that is
    // 0.02 pixels here. Distances may change by about the step, not by the
    // f32 quantum of ECEF (0.5 m), which absolute positions would show.
    // Pixels on a silhouette may flip to what is behind; all others keep
    // their distance to 0.1%.
    let (da, db) = (distances(&fa), distances(&fb));
    let mut changes: Vec<f64> =
        da.iter().zip(&db).filter(|(x, y)| **x > 0.0 && **y > 0.0).map(|(x, y)| (x - y).abs() / x.max(1.0)).collect();
    changes.sort_by(f64::total_cmp);
    let p999 = changes[changes.len() * 999 / 1000];
    eprintln!("relative distance change: 99.9th percentile {p999:.2e}, max {:.2e}", changes[changes.len() - 1]);
    assert!(changes.len() > 10_000 && p999 < 1e-3, "{p999}");
    let differing = fa
        .rgba
        .chunks(4)
        .zip(fb.rgba.chunks(4))
        .filter(|(p, q)| p.iter().zip(*q).any(|(u, v)| u.abs_diff(*v) > 3))
        .count();
    assert!(differing * 1000 < (SETTINGS.width * SETTINGS.height) as usize, "{differing} pixels changed colour");
}

fn psnr(a: &[u8], b: &[u8]) -> f64 {
    let mse = a.iter().zip(b).map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2)).sum::<f64>() / a.len() as f64;
    if mse == 0.0 { f64::INFINITY } else { 10.0 * (255.0f64 * 255.0 / mse).log10() }
}

/// Fixed views against stored images (renderer/tests/golden). Stated
/// tolerance: PSNR of at least 30 dB, so lavapipe and GPUs may differ in
/// rasterization rules and rounding, not in what is drawn.
/// `RELIEF_BLESS=1` writes the images anew.
#[test]
fn golden_views_match_within_30_db() {
    let (mut renderer, source) = hill_scene(&gpu(), ClipmapConfig::default());
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    let views = [
        ("hill-oblique", pose(10.05, 45.05, 6000.0, 45.0, -30.0)),
        ("hill-above", pose(10.25, 45.25, 30_000.0, 0.0, -90.0)),
        ("planet", pose(10.0, 30.0, 15_000_000.0, 0.0, -90.0)),
    ];
    for (name, p) in views {
        let frame = renderer.render(&source, &p, &SETTINGS).unwrap();
        let path = dir.join(format!("{name}.png"));
        if std::env::var_os("RELIEF_BLESS").is_some() {
            std::fs::create_dir_all(&dir).unwrap();
            image::save_buffer(&path, &frame.rgba, frame.width, frame.height, image::ExtendedColorType::Rgba8).unwrap();
            continue;
        }
        let golden =
            image::open(&path).unwrap_or_else(|e| panic!("{}: {e} (RELIEF_BLESS=1 writes it)", path.display()));
        let golden = golden.to_rgba8();
        assert_eq!((golden.width(), golden.height()), (frame.width, frame.height));
        let db = psnr(golden.as_raw(), &frame.rgba);
        eprintln!("{name}: {db:.1} dB");
        assert!(db >= 30.0, "{name}: {db:.1} dB against {}", path.display());
    }
}

#[test]
fn bad_cameras_and_sizes_are_refused_by_name() {
    let (mut renderer, source) = hill_scene(&gpu(), ClipmapConfig::default());
    let mut p = pose(10.0, 45.0, 1000.0, 0.0, -30.0);
    p.pitch_deg = f64::NAN;
    let e = renderer.render(&source, &p, &SETTINGS).unwrap_err().to_string();
    assert!(e.contains("pitch_deg"), "{e}");
    let e = renderer.render(&source, &pose(10.0, 91.0, 1000.0, 0.0, 0.0), &SETTINGS).unwrap_err().to_string();
    assert!(e.contains("lat_deg"), "{e}");
    let huge = RenderSettings { width: 1_000_000, ..SETTINGS };
    let e = renderer.render(&source, &pose(10.0, 45.0, 1000.0, 0.0, -30.0), &huge).unwrap_err().to_string();
    assert!(e.contains("width"), "{e}");
    // And it still renders.
    renderer.render(&source, &pose(10.0, 45.0, 1000.0, 0.0, -30.0), &SETTINGS).unwrap();
}

/// The hill with a 300 m block raised over 10.20..10.21 E, 45.20..45.21 N.
fn hill_with_block(lon: f64, lat: f64) -> f64 {
    let block = (10.20..=10.21).contains(&lon) && (45.20..=45.21).contains(&lat);
    relief_examples::hill(lon, lat) + if block { 300.0 } else { 0.0 }
}

#[test]
fn a_rebuilt_area_refreshes_only_its_samples() {
    let (mut renderer, before) = hill_scene(&gpu(), ClipmapConfig::new(63, 6));
    let view = pose(10.2, 45.2, 3000.0, 0.0, -60.0);
    renderer.render(&before, &view, &SETTINGS).unwrap();
    let after =
        Analytic { surface: before.surface.clone(), height: hill_with_block, max_level: 14, ready_up_to: u8::MAX };
    let written = |r: &Renderer| -> u64 {
        r.clipmap().active().iter().map(|&t| r.clipmap().level(t).unwrap().samples_written).sum()
    };
    let start = written(&renderer);
    renderer.invalidate(&after, &common::terrain_dirt(relief_source::Extent::new(10.20, 45.20, 10.21, 45.21)));
    let refreshed = written(&renderer) - start;
    // Only the samples over the block (plus one on each side) were read
    // again, not whole windows.
    assert!(refreshed > 0 && refreshed < (63 * 63 * 6 / 2) as u64, "{refreshed} samples refreshed");
    let frame = renderer.render(&after, &view, &SETTINGS).unwrap();
    assert_eq!(frame.update.samples_written, refreshed, "the camera did not move: only the refreshed samples");
    assert_matches_scratch(&renderer, &after);
}

#[test]
fn levels_whose_data_is_not_ready_are_not_drawn_and_the_view_stays_whole() {
    let (mut renderer, mut source) = hill_scene(&gpu(), ClipmapConfig::default());
    // Tile level 10 is ready, 11 is not: level 10's colour comes from 11.
    source.ready_up_to = 10;
    let view = pose(10.1, 45.1, 4000.0, 45.0, -25.0);
    let frame = renderer.render(&source, &view, &SETTINGS).unwrap();
    assert!(frame.update.active.iter().all(|&t| t <= 9), "{:?}", frame.update);
    assert_eq!(frame.update.not_ready, [10], "the first level not ready stops the finer ones");
    assert_eq!(holes(&frame, 500.0 - BASE_SINK_M), 0, "coarser levels cover the view");
    // Once the data is there, the finer levels come in.
    source.ready_up_to = u8::MAX;
    let frame = renderer.render(&source, &view, &SETTINGS).unwrap();
    assert!(frame.update.active.iter().any(|&t| t > 9) && frame.update.not_ready.is_empty(), "{:?}", frame.update);
}

/// Flies in small steps over `height` and returns, per frame, the 99.9th
/// percentile of the largest colour change of a pixel, and how many times
/// level windows moved.
fn flight(height: fn(f64, f64) -> f64) -> (Vec<u8>, usize) {
    let gpu = gpu();
    let surface = Surface::new(TileGrid::geodetic(256).unwrap());
    let source = Analytic { surface: surface.clone(), height, max_level: 16, ready_up_to: u8::MAX };
    let mut renderer = Renderer::new(gpu, surface, ClipmapConfig::new(63, 6)).unwrap();
    let (mut previous, mut changes, mut shifts): (Option<Frame>, Vec<u8>, usize) = (None, Vec::new(), 0);
    let mut origins: Vec<(u8, (i64, i64))> = Vec::new();
    for k in 0..24 {
        // 6 m a frame north-east at 2500 m: windows move by a sample every
        // few frames.
        let p = pose(10.15 + f64::from(k) * 0.00005, 45.15 + f64::from(k) * 0.00005, 2500.0, 45.0, -35.0);
        let frame = renderer.render(&source, &p, &SETTINGS).unwrap();
        let now: Vec<(u8, (i64, i64))> =
            frame.update.active.iter().map(|&t| (t, renderer.clipmap().level(t).unwrap().origin)).collect();
        shifts += now.iter().filter(|o| !origins.contains(o)).count();
        origins = now;
        if let Some(prev) = previous {
            let mut diffs: Vec<u8> = prev
                .rgba
                .chunks(4)
                .zip(frame.rgba.chunks(4))
                .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0))
                .collect();
            diffs.sort_unstable();
            changes.push(diffs[diffs.len() * 999 / 1000]);
        }
        previous = Some(frame);
    }
    (changes, shifts)
}

#[test]
fn a_slow_flight_across_window_shifts_does_not_pop() {
    // Smooth terrain moving by a fraction of a pixel: colours change by a
    // few levels; a level popping in would change whole areas.
    let (changes, shifts) = flight(relief_examples::hill);
    assert!(shifts > 6, "the flight moved windows only {shifts} times");
    assert!(changes.iter().all(|&c| c <= 6), "99.9th percentile colour changes {changes:?}");
    // Over bumps that coarse levels alias, the transition morphs them
    // from frame to frame instead of switching: 16-18 levels here, where
    // the same flight without the transition (alpha 0) measured 23-29.
    let (changes, _) = flight(bumps);
    assert!(changes.iter().all(|&c| c <= 21), "99.9th percentile colour changes over bumps {changes:?}");
}

/// 40 m bumps every 0.002 degrees (about 200 m): coarse levels alias them,
/// so neighbouring levels differ by tens of metres where they meet.
fn bumps(lon: f64, lat: f64) -> f64 {
    let k = std::f64::consts::TAU / 0.002;
    500.0 + 40.0 * (lon * k).sin() * (lat * k).sin()
}

#[test]
fn levels_meet_without_cracks_where_they_differ() {
    let gpu = gpu();
    let surface = Surface::new(TileGrid::geodetic(256).unwrap());
    let source = Analytic { surface: surface.clone(), height: bumps, max_level: 16, ready_up_to: u8::MAX };
    let mut renderer = Renderer::new(gpu, surface, ClipmapConfig::new(63, 6)).unwrap();
    // Views the clipmap covers whole (no horizon: beyond the coarsest level
    // a coarse base takes over, which may sit hundreds of metres low).
    for (k, p) in [
        pose(7.3, 46.1, 1500.0, 30.0, -50.0),
        pose(7.3, 46.1, 3000.0, 200.0, -60.0),
        pose(7.31, 46.12, 800.0, 90.0, -45.0),
        pose(7.3, 46.1, 20_000.0, 0.0, -90.0),
    ]
    .iter()
    .enumerate()
    {
        let frame = renderer.render(&source, p, &SETTINGS).unwrap();
        save(&frame, &format!("bumps-{k}.png"));
        // Every level approximates the bumps within their 40 m amplitude
        // (plus aliasing); a crack would show the base ~1000 m below, or sky.
        let (w, h) = (frame.width, frame.height);
        for py in 0..h {
            for px in 0..w {
                let depth = frame.depth[(py * w + px) as usize];
                let (dir, distance) = frame.view.unproject(f64::from(px), f64::from(py), w, h, depth.max(1e-30));
                if depth <= 0.0 {
                    assert!(
                        !meets_ellipsoid(frame.view.eye, dir, 460.0 - BASE_SINK_M),
                        "view {k}: sky at ({px}, {py})"
                    );
                    continue;
                }
                let (lon, lat, z) = geodesy::geodetic_from_ecef((frame.view.eye + dir * distance).to_array());
                let error = (z - bumps(lon, lat)).abs();
                assert!(error < 200.0, "view {k}: pixel ({px}, {py}) {error:.0} m off the surface: a crack");
            }
        }
    }
}

/// Each finer window lies inside the coarser one, in the same revolution.
fn assert_nested(renderer: &Renderer) {
    let active = renderer.clipmap().active();
    for pair in active.windows(2) {
        let (c, f) = (renderer.clipmap().level(pair[0]).unwrap(), renderer.clipmap().level(pair[1]).unwrap());
        let side = (f.n as i64 - 1) / 2;
        for (fo, co) in [(f.origin.0, c.origin.0), (f.origin.1, c.origin.1)] {
            assert!(
                fo / 2 >= co && fo / 2 + side < co + c.n as i64,
                "level {} at {:?} not inside level {} at {:?}",
                pair[1],
                f.origin,
                pair[0],
                c.origin
            );
        }
    }
}

#[test]
fn after_a_jump_across_the_antimeridian_levels_still_nest() {
    // A camera over lon 0 (the south pole), then on the antimeridian: the
    // kept coarse levels came from the other side of the planet; windows
    // that chose different revolutions left a band of sky.
    let (mut renderer, source) = hill_scene(&gpu(), ClipmapConfig::default());
    for p in [
        pose(0.0, -90.0, 20_000.0, 0.0, -90.0),
        pose(180.0, -16.8, 5000.0, 270.0, -30.0),
        pose(-179.9, -16.8, 5000.0, 90.0, -30.0),
    ] {
        let frame = renderer.render(&source, &p, &SETTINGS).unwrap();
        assert_nested(&renderer);
        assert_eq!(holes(&frame, 500.0 - BASE_SINK_M), 0, "{p:?}");
    }
}
