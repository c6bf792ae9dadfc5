//! What the scene holds is drawn, against a real reliefd: a building layer
//! shows in frames and follows its shapefile, and a scene without one (or
//! without instances) builds no buildings (or instances) pass.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::Path;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::scenes::{camera, hill, render_rgba};
use relief_tests::vectors::{shapefile, squares};
use tonic::transport::Channel;

/// One 0.004-degree square building, 60 m high, drawn blue.
const SIDE: f64 = 0.004;
const WEST: f64 = 10.3;
const SOUTH: f64 = 45.3;
const TOWN: &str = "buildings = \"town\"\n\n[[source]]\nid = \"footprints\"\nkind = \"shapefile\"\npath = \"town.shp\"\n\n[[source]]\nid = \"town\"\nkind = \"extrude\"\ninputs = [\"footprints\", \"dem\"]\nheight = 60\ncolor = \"#2040ff\"\n";
const SIZE: (u32, u32) = (320, 240);

async fn frame(channel: &Channel) -> pb::RenderResponse {
    // Straight down over the building, 4 km up.
    let camera = camera(WEST + SIDE / 2.0, SOUTH + SIDE / 2.0, 5500.0, 0.0, -90.0);
    render_rgba(channel, camera, SIZE).await.unwrap()
}

/// The blue pixels: their count, centre (column, row) and width in columns.
fn building_pixels(frame: &pb::RenderResponse) -> (usize, f64, f64, f64) {
    let (mut n, mut sx, mut sy) = (0, 0.0, 0.0);
    let (mut left, mut right) = (f64::MAX, f64::MIN);
    for (k, p) in frame.image.chunks(4).enumerate() {
        if i32::from(p[2]) > i32::from(p[0]) + 80 && i32::from(p[2]) > i32::from(p[1]) + 60 {
            let (x, y) = ((k % SIZE.0 as usize) as f64, (k / SIZE.0 as usize) as f64);
            n += 1;
            sx += x;
            sy += y;
            (left, right) = (left.min(x), right.max(x));
        }
    }
    (n, sx / n.max(1) as f64, sy / n.max(1) as f64, right - left + 1.0)
}

fn footprint(dir: &Path, west: f64) {
    let tmp = dir.join(format!("edit-{west}"));
    std::fs::create_dir_all(&tmp).unwrap();
    shapefile(&tmp, "town", &squares(&[(r#"{"name": "hall"}"#, west, SOUTH, SIDE)])).unwrap();
    // Saved over the scene's files part by part, as an editor saves.
    for ext in ["shp", "shx", "dbf", "prj", "cpg"] {
        let from = tmp.join(format!("town.{ext}"));
        if from.exists() {
            std::fs::copy(&from, dir.join(format!("town.{ext}"))).unwrap();
        }
    }
}

fn pass<'a>(passes: &'a [pb::PassState], name: &str) -> &'a pb::PassState {
    passes.iter().find(|p| p.name == name).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_moved_footprint_moves_in_the_next_frame_and_only_its_tiles_are_rebuilt() {
    let dir = tempfile::tempdir().unwrap();
    footprint(dir.path(), WEST);
    let daemon = Reliefd::start(&hill(dir.path(), TOWN).unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let before = frame(&channel).await;
    let (n, x0, y0, width) = building_pixels(&before);
    // 0.004 degrees (310 x 445 m) from about 3.9 km above the roof, 14 m a
    // pixel: some 22 x 31 pixels.
    assert!(n > 400 && width > 15.0, "only {n} building pixels, {width} wide");
    assert!((x0 - 160.0).abs() < 8.0 && (y0 - 120.0).abs() < 8.0, "building centred at ({x0}, {y0})");
    let mut scene = SceneServiceClient::new(channel.clone());
    let state = scene.get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let buildings = pass(&state.passes, "buildings");
    assert!(buildings.built && buildings.runs >= 1, "{buildings:?}");
    let town = |s: &pb::SceneState| s.sources.iter().find(|s| s.id == "town").unwrap().tiles_generated;
    let generated = town(&state);

    // A quarter of its width east.
    footprint(dir.path(), WEST + SIDE / 4.0);
    let request = pb::WaitForGenerationRequest { min_generation: state.generation + 1, timeout_ms: 20_000 };
    scene.wait_for_generation(request).await.unwrap();
    let after = frame(&channel).await;
    let (m, x1, y1, _) = building_pixels(&after);
    assert!((m as f64 - n as f64).abs() < 0.1 * n as f64, "{n} then {m} pixels");
    // East is right in a north-up view: a quarter of its width, within a
    // pixel and a half.
    let shift = x1 - x0;
    assert!((shift - width / 4.0).abs() < 1.5 && (y1 - y0).abs() < 1.5, "moved from ({x0}, {y0}) to ({x1}, {y1})");
    // Only the tiles holding the building (one per clipmap level, where it
    // was and where it is: 8 here) were made again, not every mesh tile
    // the frames asked for (18 here).
    let state = scene.get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let remade = town(&state) - generated;
    assert!(remade >= 1 && remade < generated, "{remade} building tiles made again, of {generated}");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_without_buildings_or_instances_builds_neither_pass() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&hill(dir.path(), "").unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let answer = frame(&channel).await;
    assert_eq!(answer.passes.iter().map(|p| p.pass.as_str()).collect::<Vec<_>>(), ["terrain", "read back"]);
    for passes in [
        answer.pass_counters,
        SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner().passes,
    ] {
        let (terrain, buildings) = (pass(&passes, "terrain"), pass(&passes, "buildings"));
        assert!(terrain.built && terrain.runs >= 1, "{terrain:?}");
        assert!(!buildings.built && buildings.runs == 0 && buildings.total_ms == 0.0, "{buildings:?}");
        let instances = pass(&passes, "instances");
        assert!(!instances.built && instances.runs == 0 && instances.total_ms == 0.0, "{instances:?}");
    }
    daemon.stop(&[]).unwrap();
}
