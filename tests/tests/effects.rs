//! Effects a scene declares, on lavapipe: each drawn where it must be when
//! declared, and when not declared, none of its work done (its pass never
//! built or run, the state without it).

#![allow(clippy::unwrap_used, reason = "a test")]

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::scenes;

const SIZE: (u32, u32) = (200, 120);
/// The fog of these tests: thick enough to see over the hill's 40 km.
const FOG: &str = "fog = { density = 0.0002, falloff_m = 3000, color = \"#c0c8d0\" }\n";
const FOG_RGB: [f64; 3] = [192.0, 200.0, 208.0];

/// From south of the hill, low, looking north over it to the horizon.
fn across_the_hill() -> pb::Camera {
    scenes::camera(10.25, 44.93, 2500.0, 0.0, -8.0)
}

async fn frame(effects: &str, camera: pb::Camera) -> (pb::RenderResponse, pb::SceneState) {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), effects).unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let frame = scenes::render_rgba(&channel, camera, SIZE).await.unwrap();
    let state = SceneServiceClient::new(channel).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    daemon.stop(&[]).unwrap();
    (frame, state)
}

fn pixel(f: &pb::RenderResponse, x: usize, y: usize) -> [f64; 3] {
    let i = (y * f.width as usize + x) * 4;
    [f64::from(f.image[i]), f64::from(f.image[i + 1]), f64::from(f.image[i + 2])]
}

fn pass<'a>(f: &'a pb::RenderResponse, name: &str) -> &'a pb::PassState {
    f.pass_counters.iter().find(|p| p.name == name).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fog_hazes_distant_terrain_and_costs_nothing_undeclared() {
    let (off, off_state) = frame("[effects]\nlighting = {}\n", across_the_hill()).await;
    let (on, on_state) = frame(&format!("[effects]\nlighting = {{}}\n{FOG}"), across_the_hill()).await;

    // Undeclared: the pass was never built nor run, the state has no fog.
    let idle = pass(&off, "fog");
    assert!(!idle.built && idle.runs == 0, "{idle:?}");
    assert!(off.passes.iter().all(|p| p.pass != "fog"));
    assert!(off_state.effects.iter().all(|e| e.name != "fog"), "{:?}", off_state.effects);
    // Declared: built, ran in this frame, in the state with its cost.
    let ran = pass(&on, "fog");
    assert!(ran.built && ran.runs >= 1 && ran.total_ms > 0.0, "{ran:?}");
    let effect = on_state.effects.iter().find(|e| e.name == "fog").unwrap();
    assert!(effect.ran && effect.last_cost_ms > 0.0, "{effect:?}");

    // How far each pixel went from its clear colour towards the fog's:
    // 0 clear, 1 all fog. Rows near the bottom see the hill's near slope,
    // rows higher up see farther terrain: the farther, the hazier.
    let haze = |x: usize, y: usize| {
        let (a, b) = (pixel(&off, x, y), pixel(&on, x, y));
        let (moved, room): (f64, f64) = (0..3)
            .map(|k| ((b[k] - a[k]).abs(), (FOG_RGB[k] - a[k]).abs()))
            .fold((0.0, 0.0), |s, v| (s.0 + v.0, s.1 + v.1));
        (room > 30.0).then_some(moved / room)
    };
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    let band = |rows: std::ops::Range<usize>| {
        let v: Vec<f64> = rows.flat_map(|y| (0..w).filter_map(move |x| haze(x, y))).collect();
        assert!(!v.is_empty());
        v.iter().sum::<f64>() / v.len() as f64
    };
    let near = band(h - 15..h);
    let far = band(h / 2..h / 2 + 10);
    assert!(near < far, "near {near:.3}, far {far:.3}");
    assert!(far > 0.15 && far <= 1.0 && near >= 0.0, "near {near:.3}, far {far:.3}");
    let changed =
        (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).filter(|&(x, y)| pixel(&on, x, y) != pixel(&off, x, y));
    assert!(changed.count() > w * h / 2, "fog left most of the frame as it was");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_camera_inside_fog_sees_fog_not_nan() {
    // 30 m above the hill's foot in fog of 100 m visibility.
    let thick = "[effects]\nlighting = {}\nfog = { density = 0.04, falloff_m = 2000, color = \"#c0c8d0\" }\n";
    let (inside, _) = frame(thick, scenes::camera(10.25, 45.0, 60.0, 0.0, 0.0)).await;
    let (w, h) = (inside.width as usize, inside.height as usize);
    let fogged = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| pixel(&inside, x, y).iter().zip(FOG_RGB).all(|(p, f)| (p - f).abs() <= 3.0))
        .count();
    assert!(fogged > w * h * 9 / 10, "{fogged} of {} pixels are the fog", w * h);
    assert!(inside.image.chunks(4).all(|p| p[3] == 255), "every pixel drawn");
}

#[test]
fn effects_relief_cannot_draw_are_refused_with_the_known_ones() {
    for (effects, message) in [
        ("[effects]\natmosphere = {}\n", "effects.atmosphere': not drawn yet (drawn: lighting, fog)"),
        ("[effects]\nsmog = {}\n", "effects.smog': unknown effect (drawn: lighting, fog)"),
        ("[effects]\nfog = { visibility_m = 100 }\n", "effects.fog.visibility_m"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let (code, text) = relief_tests::daemon::check(&scenes::hill(dir.path(), effects).unwrap()).unwrap();
        assert_ne!(code, 0, "{effects}: accepted");
        assert!(text.contains(message) && text.contains("scene.toml"), "{effects}: {text}");
    }
}
