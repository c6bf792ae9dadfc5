//! A bulk edit stays bounded (issue "live on a full scene"): one
//! GeoPackage commit moving every footprint of a town of 900 buildings
//! while a viewer's camera moves. Frames keep coming all through it (none
//! waits for the whole layer: the layer is rebuilt beside the frames, and
//! the first frame of the commit's generation brings only the changed mesh
//! tiles to the device, made ready in parallel), and that first frame shows
//! the moved town.

#![allow(clippy::unwrap_used, reason = "a test")]

use std::time::{Duration, Instant};

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::{edit, fixtures, scenes};
use tokio_stream::StreamExt;

/// The town's middle, on the hill's flank.
const TOWN: (f64, f64) = (10.3, 45.2);
const BUILDINGS: usize = 900;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_commit_moving_a_whole_town_keeps_frames_coming_and_its_first_frame_shows_it() {
    let dir = tempfile::tempdir().unwrap();
    let gpkg = dir.path().join("town.gpkg");
    relief_examples::write_town(&gpkg, TOWN, BUILDINGS).unwrap();
    fixtures::write_dem(&dir.path().join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"town\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n\
         [[source]]\nid = \"footprints\"\nkind = \"ogr\"\npath = \"town.gpkg\"\nlayer = \"town\"\n\n\
         [[source]]\nid = \"town\"\nkind = \"extrude\"\ninputs = [\"footprints\", \"dem\"]\nheight_attribute = \"height\"\nmin_level = 10\n\n\
         [layers]\nheight = \"dem\"\nbuildings = \"town\"\n\n[effects]\nlighting = {}\nshadows = {}\n",
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let mut views = ViewServiceClient::new(channel.clone()).max_decoding_message_size(64 << 20);
    // 2 km south of the town and 1 km over it (the hill stands 1,500 m
    // there), looking north down at it.
    let above = fixtures::hill(TOWN.0, TOWN.1) + 1000.0;
    let camera = |k: u32| scenes::camera(TOWN.0 + 1e-6 * f64::from(k), TOWN.1 - 0.02, above, 0.0, -30.0);
    let view = views.open_view(pb::OpenViewRequest { camera: Some(camera(0)), ..Default::default() }).await.unwrap();
    let view_id = view.into_inner().view_id;
    let request = pb::StreamFramesRequest {
        width: 320,
        height: 180,
        max_fps: 30.0,
        view_id: view_id.clone(),
        format: pb::ImageFormat::Rgba8 as i32,
        ..Default::default()
    };
    let mut stream = views.stream_frames(request).await.unwrap().into_inner();
    let before = tokio::time::timeout(Duration::from_secs(120), stream.next()).await.unwrap().unwrap().unwrap();
    assert!(before.drawn.unwrap().buildings > 100, "{:?}", before.drawn);

    // The commit, then the camera moving a little every 100 ms until the
    // commit's generation is shown.
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let built_before = state.counters.and_then(|c| c.renderer_caches).map_or(0, |c| c.building_tiles_built);
    let started = Instant::now();
    let moved = tokio::task::spawn_blocking(move || edit::move_every_polygon(&gpkg, "town", (0.0003, 0.0)));
    let mut arrivals = Vec::new();
    let mut k = 1;
    let shown = loop {
        assert!(started.elapsed() < Duration::from_secs(120), "the commit never showed: {arrivals:?}");
        let update = pb::UpdateViewRequest { view_id: view_id.clone(), camera: Some(camera(k)), ..Default::default() };
        views.update_view(update).await.unwrap();
        k += 1;
        if let Ok(Some(frame)) = tokio::time::timeout(Duration::from_millis(100), stream.next()).await {
            let frame = frame.unwrap();
            arrivals.push(started.elapsed().as_secs_f64());
            if frame.generation > before.generation && !frame.carried_over {
                break frame;
            }
        }
    };
    assert_eq!(moved.await.unwrap().unwrap(), BUILDINGS);
    // Frames all through: no gap of 3 s between the commit and its frame
    // (a debug build on lavapipe renders one in a few hundred ms).
    let mut last = 0.0;
    for t in &arrivals {
        assert!(t - last < 3.0, "no frame from {last:.1} to {t:.1} s: {arrivals:?}");
        last = *t;
    }
    // The mesh tiles were built for a frame of the new generation (the
    // stream may have passed that very frame over for a later camera).
    let d = shown.drawn.unwrap();
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let built = state.counters.and_then(|c| c.renderer_caches).map_or(0, |c| c.building_tiles_built);
    assert!(d.buildings > 100 && built > built_before, "{d:?}: {built_before} building tiles built, then {built}");
    let changed = shown.image.chunks(4).zip(before.image.chunks(4)).filter(|(a, b)| a != b).count();
    eprintln!("{} frames in {:.1} s; the commit's: {d:?}", arrivals.len(), started.elapsed().as_secs_f64());
    assert!(changed > 500, "the moved town does not show: {changed} pixels changed");
    drop(stream);
    daemon.stop(&[]).unwrap();
}
