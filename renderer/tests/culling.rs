//! Culling the terrain's level blocks outside the view, and beyond the
//! planet's horizon, is exact: each frame is the same, pixel for pixel and
//! depth for depth, with and without it, from every kind of camera, while
//! oblique views draw far fewer blocks.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use relief_renderer::{ClipmapConfig, RenderSettings};

mod common;

use common::{gpu, hill_scene, pose, utm_scene};

const CULLED: RenderSettings = RenderSettings::new(320, 180, true);
const WHOLE: RenderSettings = RenderSettings { cull: false, ..CULLED };

#[test]
fn culled_frames_equal_whole_ones_and_draw_fewer_blocks() {
    let (mut planet, hill) = hill_scene(&gpu(), ClipmapConfig::default());
    let (mut flat, utm) = utm_scene(ClipmapConfig::default());
    let h = relief_examples::hill(10.2, 45.2);
    // Each view, the most of its blocks it may draw, and whether the
    // horizon leaves some out (from 5-9 km up it is 250-340 km away, and
    // the coarsest level reaches past it).
    let cases = [
        ("oblique over the hill", pose(10.25, 45.1, 9000.0, 0.0, -45.0), 0.45, true),
        ("low, looking at the horizon", pose(10.2, 45.2, h + 30.0, 60.0, -2.0), 0.45, false),
        ("1 m above the hill", pose(10.2, 45.2, h + 1.0, 200.0, -10.0), 0.5, false),
        ("straight down", pose(10.25, 45.25, 3000.0, 0.0, -90.0), 0.3, false),
        ("north pole", pose(0.0, 90.0, 20_000.0, 0.0, -90.0), 0.4, false),
        ("antimeridian", pose(180.0, -16.8, 5000.0, 270.0, -30.0), 0.4, true),
        ("looking up", pose(10.2, 45.2, h + 50.0, 90.0, 30.0), 0.2, false),
        // Low over the 500 m plain the horizon is 5-6 km away, inside the
        // coarsest level: blocks beyond it are left out too.
        ("1.7 m over the plain, at the horizon", pose(10.0, 44.5, 501.7, 180.0, -1.0), 0.36, true),
        ("1 m over the plain, towards the hill", pose(10.25, 44.9, 501.0, 0.0, 0.0), 0.34, true),
        ("2 m over the plain, across the antimeridian", pose(179.99, 0.0, 502.0, 90.0, -0.5), 0.28, true),
        // No horizon here: the coarsest level reaches past the pole, and
        // from inside the hill the eye is under the drawn ground.
        ("2 m over the plain by the pole", pose(0.0, 89.9, 502.0, 0.0, -1.0), 0.6, false),
        ("inside the hill", pose(10.25, 45.25, 1500.0, 0.0, 0.0), 0.3, false),
    ];
    for (name, p, most, horizon) in cases {
        let whole = planet.render(&hill, &p, &WHOLE).unwrap();
        let culled = planet.render(&hill, &p, &CULLED).unwrap();
        assert_eq!(whole.drawn.terrain_blocks_drawn, whole.drawn.terrain_blocks, "{name}: nothing culled when off");
        assert!(culled.rgba == whole.rgba, "{name}: the culled image differs");
        assert!(culled.depth == whole.depth, "{name}: the culled depth differs");
        let d = culled.drawn;
        let share = d.terrain_blocks_drawn as f64 / d.terrain_blocks as f64;
        eprintln!(
            "{name}: {} of {} blocks drawn, {} beyond the horizon",
            d.terrain_blocks_drawn, d.terrain_blocks, d.terrain_blocks_beyond_horizon
        );
        assert!(share <= most, "{name}: {share:.2} of the blocks drawn");
        assert_eq!(d.terrain_blocks_beyond_horizon > 0, horizon, "{name}: {d:?}");
    }
    let p = relief_renderer::Pose { position: [298_000.0, 5_098_000.0, 2500.0], ..pose(0.0, 0.0, 0.0, 30.0, -30.0) };
    let whole = flat.render(&utm, &p, &WHOLE).unwrap();
    let culled = flat.render(&utm, &p, &CULLED).unwrap();
    assert!(culled.rgba == whole.rgba && culled.depth == whole.depth, "flat grid: the culled frame differs");
    assert!(culled.drawn.terrain_blocks_drawn < culled.drawn.terrain_blocks / 2, "flat grid: {:?}", culled.drawn);
}

/// Sea level, and east of 10 E a plateau 3000 m high.
fn plateau(lon: f64, _lat: f64) -> f64 {
    if lon >= 10.0 { 3000.0 } else { 0.0 }
}

/// The same 4000 m under the sea: a seabed, and a seamount's flat top.
fn sunken_plateau(lon: f64, lat: f64) -> f64 {
    plateau(lon, lat) - SUNK_M
}

const SUNK_M: f64 = 4000.0;

#[test]
fn a_plateau_past_the_eyes_horizon_but_over_its_own_is_drawn() {
    // From 2 m over the sea at 9 E the horizon is 5 km away; the plateau
    // begins 79 km east, far past the levels, where the coarse base draws
    // it. Its ground 2900 m up, 157 km away, stands over that horizon (it
    // is in sight from 197 km): it must show, not sky. The same holds 4 km
    // under the sea, with no water drawn: the seabed hides what the
    // ground over it would, not what sea level would.
    for (height, sunk) in [(plateau as fn(f64, f64) -> f64, 0.0), (sunken_plateau, SUNK_M)] {
        let surface = relief_renderer::Surface::new(relief_source::TileGrid::geodetic(256).unwrap());
        let source = common::Analytic { surface: surface.clone(), height, max_level: 14, ready_up_to: u8::MAX };
        let mut renderer = relief_renderer::Renderer::new(gpu(), surface, ClipmapConfig::default()).unwrap();
        let frame = renderer.render(&source, &pose(9.0, 45.2, 2.0 - sunk, 90.0, 0.5), &CULLED).unwrap();
        let ground = relief_source::geodesy::ecef_from_geodetic(11.0, 45.2, 2_900.0 - sunk);
        let (px, py) = common::project(&frame, glam::DVec3::from(ground)).expect("the plateau is in the frame");
        assert!(
            frame.depth[(py * frame.width + px) as usize] > 0.0,
            "{sunk} m down: sky over the plateau at ({px}, {py})"
        );
    }
}
