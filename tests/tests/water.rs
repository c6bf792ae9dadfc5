//! The `water` effect on lavapipe: the water layer drawn where its mask is
//! (on the terrain, or at a level with the bottom seen through it), nothing
//! of it evaluated when the effect is not declared, an eye under the
//! surface, and each bad declaration refused.

#![allow(clippy::unwrap_used, reason = "a test")]

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::{fixtures, scenes};

const SIZE: (u32, u32) = (160, 120);
/// A round lake on the hill scene's plain, 0.03 degrees across.
const LAKE: (f64, f64, f64) = (10.1, 45.1, 0.03);

fn lake(lon: f64, lat: f64) -> f64 {
    let (dx, dy) = ((lon - LAKE.0) * (LAKE.1.to_radians().cos()), lat - LAKE.1);
    if dx.hypot(dy) < LAKE.2 { 1.0 } else { 0.0 }
}

/// The hill scene with the lake as its water layer (a raster: 1 water, 0
/// dry), and `effects`.
fn scene(dir: &std::path::Path, effects: &str) -> std::path::PathBuf {
    fixtures::write_dem(&dir.join("lake.tif"), &fixtures::hill_spec(), lake).unwrap();
    let water = format!(
        "water = \"lake\"\n\n[[source]]\nid = \"lake\"\nkind = \"gdal\"\npath = \"lake.tif\"\n\n[effects]\nlighting = {{}}\n{effects}"
    );
    scenes::hill(dir, &water).unwrap()
}

async fn frames(effects: &str, cameras: &[pb::Camera]) -> (Vec<pb::RenderResponse>, pb::SceneState) {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), effects), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let mut out = Vec::new();
    for camera in cameras {
        out.push(scenes::render_rgba(&channel, *camera, SIZE).await.unwrap());
    }
    let state = SceneServiceClient::new(channel).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    daemon.stop(&[]).unwrap();
    (out, state)
}

fn pixel(f: &pb::RenderResponse, x: usize, y: usize) -> [f64; 3] {
    let i = (y * f.width as usize + x) * 4;
    [f64::from(f.image[i]), f64::from(f.image[i + 1]), f64::from(f.image[i + 2])]
}

fn pass<'a>(f: &'a pb::RenderResponse, name: &str) -> &'a pb::PassState {
    f.pass_counters.iter().find(|p| p.name == name).unwrap()
}

/// Straight down over the lake from 15 km: it is a disc about 28 pixels
/// in radius round the image's centre.
fn over_the_lake() -> pb::Camera {
    scenes::camera(LAKE.0, LAKE.1, 15_000.0, 0.0, -90.0)
}

fn from_centre(x: usize, y: usize) -> f64 {
    (x as f64 + 0.5 - f64::from(SIZE.0) / 2.0).hypot(y as f64 + 0.5 - f64::from(SIZE.1) / 2.0)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn water_is_drawn_where_the_mask_is_and_its_layer_is_read_only_when_declared() {
    let (off, off_state) = frames("", &[over_the_lake()]).await;
    let (on, on_state) = frames("water = {}\n", &[over_the_lake()]).await;

    // Undeclared: the pass never built, the layer's source never read.
    let idle = pass(&off[0], "water");
    assert!(!idle.built && idle.runs == 0, "{idle:?}");
    let lake_source = |s: &pb::SceneState| s.sources.iter().find(|s| s.id == "lake").unwrap().tiles_generated;
    assert_eq!(lake_source(&off_state), 0, "the water layer was read for a scene without water");
    assert!(off_state.effects.iter().all(|e| e.name != "water"));
    // Declared: built, ran, its layer read, in the state with its sources.
    let ran = pass(&on[0], "water");
    assert!(ran.built && ran.runs >= 1 && ran.total_ms > 0.0, "{ran:?}");
    assert!(lake_source(&on_state) > 0);
    let effect = on_state.effects.iter().find(|e| e.name == "water").unwrap();
    assert!(effect.ran && effect.sources.contains(&"lake".to_owned()), "{effect:?}");

    // Water where the mask is: inside the disc every pixel changed and is
    // blue-green; well outside it, nothing changed.
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    let mut inside = 0;
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (pixel(&off[0], x, y), pixel(&on[0], x, y));
            let r = from_centre(x, y);
            if r < 22.0 {
                inside += 1;
                assert!(b != a && b[2] > b[0] + 10.0, "({x}, {y}) inside: {a:?} became {b:?}");
            } else if r > 36.0 {
                assert_eq!(a, b, "({x}, {y}) outside the lake changed");
            }
        }
    }
    assert!(inside > 1000);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn at_a_level_the_bottom_shows_through_shallow_water_and_an_eye_under_it_sees_water() {
    // The plain under the lake lies about 503 m up: 2 m of water at 505.
    let ground = fixtures::hill(LAKE.0, LAKE.1);
    let cameras = [over_the_lake(), scenes::camera(LAKE.0, LAKE.1, ground + 1.0, 90.0, 5.0)];
    let (on_terrain, _) = frames("water = {}\n", &cameras[..1]).await;
    let (shallow, _) = frames(&format!("water = {{ level_m = {} }}\n", ground + 2.0), &cameras).await;
    let (deep, _) = frames(&format!("water = {{ level_m = {} }}\n", ground + 40.0), &cameras[..1]).await;
    let (bare, _) = frames("", &cameras[..1]).await;
    // Through 2 m of water the bottom's colour shows: nearer the bare
    // ground than the opaque water on the terrain, or 40 m of it, are.
    let distance = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).abs()).sum::<f64>();
    let (cx, cy) = (SIZE.0 as usize / 2, SIZE.1 as usize / 2);
    let ground_colour = pixel(&bare[0], cx, cy);
    let through = distance(pixel(&shallow[0], cx, cy), ground_colour);
    assert!(through < distance(pixel(&on_terrain[0], cx, cy), ground_colour), "2 m of water hid the bottom");
    assert!(through < distance(pixel(&deep[0], cx, cy), ground_colour), "2 m as opaque as 40 m");
    assert!(through > 3.0, "2 m of water left the bottom as it was");

    // An eye a metre above the lake bed, a metre under the surface: all
    // water, no NaN (black), no sky.
    let under = &shallow[1];
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    let watery = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let p = pixel(under, x, y);
            p[2] >= p[0] && p.iter().sum::<f64>() > 10.0
        })
        .count();
    assert!(watery > w * h * 9 / 10, "{watery} of {} pixels look like water", w * h);
}

#[test]
fn bad_water_declarations_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (effects, message) in [
        ("water = { depth = 3 }\n", "effects.water.depth"),
        ("water = { level_m = 1e9 }\n", "effects.water.level_m"),
        ("water = { clarity_m = 0 }\n", "effects.water.clarity_m"),
        ("water = { color = '#1f4e5f80' }\n", "effects.water.color"),
    ] {
        let (code, text) = relief_tests::daemon::check(&scene(dir.path(), effects)).unwrap();
        assert_ne!(code, 0, "{effects}: accepted");
        assert!(text.contains(message) && text.contains("scene.toml"), "{effects}: {text}");
    }
    // Water without a water layer.
    let bare = scenes::hill(dir.path(), "[effects]\nlighting = {}\nwater = {}\n").unwrap();
    let (code, text) = relief_tests::daemon::check(&bare).unwrap();
    assert!(code != 0 && text.contains("effects.water") && text.contains("needs a 'water' layer"), "{text}");
}
