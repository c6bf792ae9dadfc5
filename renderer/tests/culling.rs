//! Culling the terrain's level blocks outside the view is exact: each
//! frame is the same, pixel for pixel and depth for depth, with and
//! without it, from every kind of camera, while oblique views draw far
//! fewer blocks.

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
    let cases = [
        ("oblique over the hill", pose(10.25, 45.1, 9000.0, 0.0, -45.0), 0.45),
        ("low, looking at the horizon", pose(10.2, 45.2, h + 30.0, 60.0, -2.0), 0.45),
        ("1 m above the hill", pose(10.2, 45.2, h + 1.0, 200.0, -10.0), 0.5),
        ("straight down", pose(10.25, 45.25, 3000.0, 0.0, -90.0), 0.3),
        ("north pole", pose(0.0, 90.0, 20_000.0, 0.0, -90.0), 0.4),
        ("antimeridian", pose(180.0, -16.8, 5000.0, 270.0, -30.0), 0.4),
        ("looking up", pose(10.2, 45.2, h + 50.0, 90.0, 30.0), 0.2),
    ];
    for (name, p, most) in cases {
        let whole = planet.render(&hill, &p, &WHOLE).unwrap();
        let culled = planet.render(&hill, &p, &CULLED).unwrap();
        assert_eq!(whole.drawn.terrain_blocks_drawn, whole.drawn.terrain_blocks, "{name}: nothing culled when off");
        assert!(culled.rgba == whole.rgba, "{name}: the culled image differs");
        assert!(culled.depth == whole.depth, "{name}: the culled depth differs");
        let share = culled.drawn.terrain_blocks_drawn as f64 / culled.drawn.terrain_blocks as f64;
        eprintln!("{name}: {} of {} blocks drawn", culled.drawn.terrain_blocks_drawn, culled.drawn.terrain_blocks);
        assert!(share <= most, "{name}: {share:.2} of the blocks drawn");
    }
    let p = relief_renderer::Pose { position: [298_000.0, 5_098_000.0, 2500.0], ..pose(0.0, 0.0, 0.0, 30.0, -30.0) };
    let whole = flat.render(&utm, &p, &WHOLE).unwrap();
    let culled = flat.render(&utm, &p, &CULLED).unwrap();
    assert!(culled.rgba == whole.rgba && culled.depth == whole.depth, "flat grid: the culled frame differs");
    assert!(culled.drawn.terrain_blocks_drawn < culled.drawn.terrain_blocks / 2, "flat grid: {:?}", culled.drawn);
}
