//! Frames for many viewers, from a real reliefd over gRPC: fifty streams
//! on one camera share one render and none is refused; streams with their
//! own cameras each get theirs; views of the viewers' own follow gestures,
//! the scene camera when asked, and smaller frames while dragging; a pick
//! finds the hill under a pixel.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::time::Duration;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::scenes::camera;
use relief_tests::{edit, fixtures, scenes};
use tokio_stream::StreamExt;
use tonic::transport::Channel;

/// How long a test waits for a frame (lavapipe, two cores, debug build).
const FRAME_TIMEOUT: Duration = Duration::from_secs(60);

fn views(channel: &Channel) -> ViewServiceClient<Channel> {
    ViewServiceClient::new(channel.clone()).max_decoding_message_size(64 << 20)
}

async fn counters(channel: &Channel) -> pb::Counters {
    SceneServiceClient::new(channel.clone())
        .get_state(pb::GetStateRequest {})
        .await
        .unwrap()
        .into_inner()
        .counters
        .unwrap()
}

async fn next(stream: &mut tonic::Streaming<pb::RenderResponse>) -> pb::RenderResponse {
    tokio::time::timeout(FRAME_TIMEOUT, stream.next()).await.expect("a frame in time").unwrap().unwrap()
}

/// Waits until `check` holds for the counters, or fails after 30 s.
async fn until(channel: &Channel, what: &str, check: impl Fn(&pb::Counters) -> bool) -> pb::Counters {
    for _ in 0..600 {
        let c = counters(channel).await;
        if check(&c) {
            return c;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    panic!("{what}: not within 30 s: {:?}", counters(channel).await);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fifty_streams_on_one_camera_all_get_frames_from_one_render() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "[effects]\nlighting = {}\n").unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let (first_tx, mut first_rx) = tokio::sync::mpsc::channel(50);
    let mut streams = Vec::new();
    for _ in 0..50 {
        let (channel, first_tx) = (channel.clone(), first_tx.clone());
        streams.push(tokio::spawn(async move {
            let request = pb::StreamFramesRequest { width: 320, height: 180, max_fps: 30.0, ..Default::default() };
            // No stream is refused because others exist.
            let mut stream = views(&channel).stream_frames(request).await.unwrap().into_inner();
            let first = next(&mut stream).await;
            first_tx.send(first.generation).await.unwrap();
            let mut frame = next(&mut stream).await;
            while frame.generation < 2 {
                frame = next(&mut stream).await;
            }
            (first, frame)
        }));
    }
    for _ in 0..50 {
        assert_eq!(tokio::time::timeout(FRAME_TIMEOUT, first_rx.recv()).await.unwrap(), Some(1));
    }
    let before = counters(&channel).await;
    assert_eq!((before.frame_streams, before.frame_views), (50, 1), "{before:?}");
    // An edit: every stream gets the new generation, rendered once more.
    edit::rewrite_window(&dir.path().join("hill.tif"), 150, 150, 64, 64, |_, _, h| h + 900.0).unwrap();
    for s in streams {
        let (first, second) = tokio::time::timeout(FRAME_TIMEOUT, s).await.unwrap().unwrap();
        assert_eq!((first.width, first.height, second.generation), (320, 180, 2));
        assert!(first.image != second.image, "the edit does not show");
    }
    let after = counters(&channel).await;
    // One frame per change, whatever the number of streams (a frame of the
    // old generation may have been under way when the edit landed).
    assert!(before.stream_frames_rendered <= 2, "{before:?}");
    assert!(after.stream_frames_rendered - before.stream_frames_rendered <= 2, "{before:?} then {after:?}");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn eight_streams_with_their_own_cameras_each_get_their_own_frames() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let mut streams = Vec::new();
    for k in 0..8 {
        let wanted = camera(10.1 + 0.04 * f64::from(k), 45.1, 8000.0, 45.0 * f64::from(k), -40.0);
        let channel = channel.clone();
        streams.push(tokio::spawn(async move {
            let request =
                pb::StreamFramesRequest { width: 160, height: 90, camera: Some(wanted), ..Default::default() };
            let mut stream = views(&channel).stream_frames(request).await.unwrap().into_inner();
            let frames = [next(&mut stream).await, next(&mut stream).await];
            (wanted, frames)
        }));
    }
    // Each stream's second frame is its first after the edit below.
    until(&channel, "eight views shown", |c| c.frame_views == 8 && c.stream_frames_rendered >= 8).await;
    edit::rewrite_window(&dir.path().join("hill.tif"), 150, 150, 64, 64, |_, _, h| h + 900.0).unwrap();
    for s in streams {
        let (wanted, frames) = tokio::time::timeout(FRAME_TIMEOUT, s).await.unwrap().unwrap();
        for f in &frames {
            assert_eq!(f.camera.unwrap(), wanted, "a stream shows its own camera");
        }
        assert_eq!((frames[0].generation, frames[1].generation), (1, 2));
    }
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_view_follows_its_gestures_and_the_scene_camera_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let mut client = views(&channel);
    let scene_camera = client.get_camera(pb::GetCameraRequest {}).await.unwrap().into_inner();
    let view = client.open_view(pb::OpenViewRequest::default()).await.unwrap().into_inner();
    assert_eq!(view.camera, Some(scene_camera));
    let request =
        pb::StreamFramesRequest { width: 320, height: 200, view_id: view.view_id.clone(), ..Default::default() };
    let mut stream = client.stream_frames(request).await.unwrap().into_inner();
    let first = next(&mut stream).await;
    assert_eq!(first.camera, Some(scene_camera));

    // The ground under the centre pixel is the hill: the pick's drawn
    // height is within the clipmap's error of the formula (4 m), and the
    // data's height there within the bilinear sampling's (1 m).
    let picked =
        client.pick(pb::PickRequest { view_id: view.view_id.clone(), x: 0.5, y: 0.5 }).await.unwrap().into_inner();
    assert!(picked.hit, "{picked:?}");
    let truth = fixtures::hill(picked.lon_deg, picked.lat_deg);
    assert!((picked.surface_height_m - truth).abs() < 4.0, "{picked:?} against {truth}");
    assert!((picked.ground_height_m.unwrap() - truth).abs() < 1.0, "{picked:?} against {truth}");
    // The centre ray at 45 degrees down from 9 km meets ground some 12 km away.
    assert!((5_000.0..20_000.0).contains(&picked.distance_m), "{picked:?}");

    // A gesture moves this view only; its stream shows it.
    let orbit = pb::navigate_request::Gesture::Orbit(pb::Orbit { heading_deg: 30.0, pitch_deg: 0.0 });
    let moved = client
        .navigate(pb::NavigateRequest { view_id: view.view_id.clone(), gesture: Some(orbit) })
        .await
        .unwrap()
        .into_inner();
    assert!((moved.heading_deg - 30.0).abs() < 0.5, "{moved:?}");
    let mut frame = next(&mut stream).await;
    while frame.camera != Some(moved) {
        frame = next(&mut stream).await;
    }
    assert_eq!(client.get_camera(pb::GetCameraRequest {}).await.unwrap().into_inner(), scene_camera);

    // While the user drags, frames come at the interactive scale (0.5).
    let update = |interactive: bool| pb::UpdateViewRequest {
        view_id: view.view_id.clone(),
        interactive: Some(interactive),
        ..Default::default()
    };
    client.update_view(update(true)).await.unwrap();
    let mut frame = next(&mut stream).await;
    while frame.width != 160 {
        frame = next(&mut stream).await;
    }
    assert_eq!(frame.height, 100);
    client.update_view(update(false)).await.unwrap();
    let mut frame = next(&mut stream).await;
    while frame.width != 320 {
        frame = next(&mut stream).await;
    }

    // Following the scene camera: SetCamera shows, and a gesture moves the
    // scene camera for everyone.
    let follow =
        pb::UpdateViewRequest { view_id: view.view_id.clone(), follow_scene_camera: Some(true), ..Default::default() };
    assert!(client.update_view(follow).await.unwrap().into_inner().follow_scene_camera);
    let set = camera(10.3, 45.2, 6000.0, 200.0, -30.0);
    client.set_camera(pb::SetCameraRequest { camera: Some(set) }).await.unwrap();
    let mut frame = next(&mut stream).await;
    while frame.camera != Some(set) {
        frame = next(&mut stream).await;
    }
    let zoom = pb::navigate_request::Gesture::Zoom(pb::Zoom { factor: 0.5, x: 0.5, y: 0.5 });
    let zoomed = client
        .navigate(pb::NavigateRequest { view_id: view.view_id.clone(), gesture: Some(zoom) })
        .await
        .unwrap()
        .into_inner();
    assert!(zoomed.altitude_m < set.altitude_m, "{zoomed:?}");
    assert_eq!(client.get_camera(pb::GetCameraRequest {}).await.unwrap().into_inner(), zoomed);
    // Fly to a source: the camera frames it from the south.
    let fly = pb::navigate_request::Gesture::FlyToSource("tint".into());
    let flown = client.navigate(pb::NavigateRequest { view_id: String::new(), gesture: Some(fly) }).await.unwrap();
    let flown = flown.into_inner();
    assert!((10.0..10.5).contains(&flown.lon_deg) && flown.lat_deg < 45.25, "{flown:?}");

    // A viewer that goes away mid-stream: its stream ends, the daemon serves on.
    drop(stream);
    until(&channel, "the stream ended", |c| c.frame_streams == 0).await;
    let state = counters(&channel).await;
    assert_eq!(state.open_views, 1);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_views_and_gestures_are_refused_by_field() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let mut client = views(&channel);
    let good = camera(10.25, 45.1, 9000.0, 0.0, -45.0);
    let stream = |camera: Option<pb::Camera>, width: u32, view_id: &str| pb::StreamFramesRequest {
        width,
        height: 90,
        camera,
        view_id: view_id.into(),
        ..Default::default()
    };
    let cases = [
        (stream(Some(pb::Camera { pitch_deg: f64::NAN, ..good }), 160, ""), tonic::Code::InvalidArgument, "pitch_deg"),
        (stream(Some(pb::Camera { lat_deg: 91.0, ..good }), 160, ""), tonic::Code::InvalidArgument, "lat_deg"),
        (stream(Some(good), 5000, ""), tonic::Code::InvalidArgument, "width"),
        (stream(None, 160, "no-such-view"), tonic::Code::NotFound, "no-such-view"),
    ];
    for (request, code, field) in cases {
        let status = client.stream_frames(request).await.unwrap_err();
        assert_eq!(status.code(), code, "{field}: {status:?}");
        assert!(status.message().contains(field), "{field}: {}", status.message());
    }
    let status = client
        .open_view(pb::OpenViewRequest {
            camera: Some(pb::Camera { altitude_m: f64::INFINITY, ..good }),
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert!(status.message().contains("altitude_m"), "{}", status.message());
    let view = client.open_view(pb::OpenViewRequest::default()).await.unwrap().into_inner();
    let gesture = |g| pb::NavigateRequest { view_id: view.view_id.clone(), gesture: Some(g) };
    let bad_gestures = [
        (gesture(pb::navigate_request::Gesture::Zoom(pb::Zoom { factor: 0.0, x: 0.5, y: 0.5 })), "zoom.factor"),
        (gesture(pb::navigate_request::Gesture::Pan(pb::Pan { from_x: f64::NAN, ..Default::default() })), "pan.from_x"),
        (
            gesture(pb::navigate_request::Gesture::Orbit(pb::Orbit { heading_deg: f64::INFINITY, pitch_deg: 0.0 })),
            "orbit.heading_deg",
        ),
        (gesture(pb::navigate_request::Gesture::FlyToSource("nope".into())), "nope"),
        (pb::NavigateRequest { view_id: view.view_id.clone(), gesture: None }, "gesture"),
    ];
    for (request, field) in bad_gestures {
        let status = client.navigate(request).await.unwrap_err();
        assert!(matches!(status.code(), tonic::Code::InvalidArgument | tonic::Code::NotFound), "{field}: {status:?}");
        assert!(status.message().contains(field), "{field}: {}", status.message());
    }
    // No frame shown yet: a pick says so.
    let status = client.pick(pb::PickRequest { view_id: view.view_id.clone(), x: 0.5, y: 0.5 }).await.unwrap_err();
    assert_eq!(status.code(), tonic::Code::FailedPrecondition, "{status:?}");
    // The camera is as it was, and frames still come.
    assert_eq!(client.get_camera(pb::GetCameraRequest {}).await.unwrap().into_inner(), good);
    let mut s = client.stream_frames(stream(None, 160, "")).await.unwrap().into_inner();
    assert_eq!(next(&mut s).await.width, 160);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_camera_moving_faster_than_frames_render_still_gets_frames() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let request = pb::StreamFramesRequest { width: 320, height: 180, max_fps: 60.0, ..Default::default() };
    let mut stream = views(&channel).stream_frames(request).await.unwrap().into_inner();
    let first = next(&mut stream).await;
    // A new scene camera every 10 ms for 4 s: every view the stream passes
    // through is left before its frame could be drawn.
    let mover = tokio::spawn({
        let channel = channel.clone();
        async move {
            let mut client = views(&channel);
            for k in 0..400 {
                let c = camera(10.2 + f64::from(k) * 1e-4, 45.1, 9000.0, 0.0, -45.0);
                client.set_camera(pb::SetCameraRequest { camera: Some(c) }).await.unwrap();
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
        }
    });
    let mut during = Vec::new();
    while !mover.is_finished() {
        if let Ok(Some(Ok(f))) = tokio::time::timeout(Duration::from_millis(200), stream.next()).await {
            during.push(f.camera.unwrap().lon_deg);
        }
    }
    // Frames kept coming, each of a newer camera than the last.
    assert!(during.len() >= 3, "{} frames while the camera moved", during.len());
    let rest = 10.2 + 399.0 * 1e-4;
    assert_eq!(first.camera.unwrap().lon_deg, 10.25);
    assert!(during.windows(2).all(|w| w[1] > w[0]) && (10.2..=rest).contains(&during[0]), "{during:?}");
    // And the stream ends on the camera where it came to rest (its frame
    // may have come while the mover slept after its last move: then no
    // other comes, as the camera does not change).
    let mut last = *during.last().unwrap();
    while (last - rest).abs() > 1e-12 {
        last = next(&mut stream).await.camera.unwrap().lon_deg;
    }
    daemon.stop(&[]).unwrap();
}
