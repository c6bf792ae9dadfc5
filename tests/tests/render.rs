//! Rendered views from a real reliefd: Render, cameras, StreamFrames, the
//! limits, and frames following the scene's generations.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::{Path, PathBuf};
use std::time::Duration;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::{Reliefd, relief};
use relief_tests::edit;
use relief_tests::scenes::camera;
use tokio_stream::StreamExt;
use tonic::transport::Channel;

/// The hill DEM and an "orthophoto" tinted by height, lit or not.
fn scene(dir: &Path, effects: &str) -> PathBuf {
    relief_tests::scenes::hill(dir, effects).unwrap()
}

async fn render(
    channel: &Channel,
    camera: Option<pb::Camera>,
    size: (u32, u32),
) -> Result<pb::RenderResponse, tonic::Status> {
    ViewServiceClient::new(channel.clone())
        .max_decoding_message_size(64 << 20)
        .render(pb::RenderRequest {
            camera,
            width: size.0,
            height: size.1,
            format: pb::ImageFormat::Rgba8 as i32,
            ..Default::default()
        })
        .await
        .map(tonic::Response::into_inner)
}

/// Sky is the clear colour (5, 8, 18); anything else is terrain.
fn sky_pixels(frame: &pb::RenderResponse) -> usize {
    frame.image.chunks(4).filter(|p| p[0] < 12 && p[1] < 14 && p[2] < 25).count()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn render_returns_the_frame_the_generation_and_its_passes() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), "[effects]\nlighting = {}\n"), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    // Straight down on the hill: every pixel is terrain.
    let frame = render(&channel, Some(camera(10.25, 45.25, 20_000.0, 0.0, -90.0)), (320, 240)).await.unwrap();
    assert_eq!((frame.width, frame.height, frame.image.len()), (320, 240, 320 * 240 * 4));
    assert_eq!(frame.generation, 1);
    assert_eq!(sky_pixels(&frame), 0);
    // The passes the scene calls for ran, each timed; then the read-back.
    let passes: Vec<&str> = frame.passes.iter().map(|p| p.pass.as_str()).collect();
    assert_eq!(passes, ["terrain", "read back"]);
    assert!(frame.passes.iter().all(|p| p.elapsed_ms > 0.0), "{:?}", frame.passes);
    // Every pass the renderer knows is counted in the answer: built, runs, time.
    let terrain = frame.pass_counters.iter().find(|p| p.name == "terrain").unwrap();
    assert!(terrain.built && terrain.runs >= 1 && terrain.total_ms >= frame.passes[0].elapsed_ms, "{terrain:?}");
    // The hill's top is tinted (demo colours: rock and snow above 1500 m),
    // its foot green: the colour layer is draped.
    let centre = &frame.image[(120 * 320 + 160) * 4..][..4];
    let corner = &frame.image[(5 * 320 + 5) * 4..][..4];
    assert!(centre[1] < corner[1] || centre[0] > corner[0], "top {centre:?} vs foot {corner:?}");
    // The lighting effect was declared, and ran; the state says so.
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let lighting = state.effects.iter().find(|e| e.name == "lighting").unwrap();
    assert!(lighting.ran && lighting.last_cost_ms > 0.0, "{lighting:?}");
    assert_eq!(state.effects.len(), 1, "no other effect was computed");
    // GetState counts the passes as the render answer did.
    let counted = state.passes.iter().find(|p| p.name == "terrain").unwrap();
    assert!(counted.built && counted.runs >= terrain.runs, "{counted:?}");

    // The CLI: camera set / get, and a PNG of the current camera.
    let (code, out, err) = relief(&daemon, &["camera", "set", "10.3,45.2,7000,270,-30,0", "--fov", "40"]).unwrap();
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("10.3,45.2,7000,270,-30,0"), "{out}");
    let (_, out, _) = relief(&daemon, &["--json", "camera", "get"]).unwrap();
    let got: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!((got["headingDeg"].as_f64(), got["verticalFovDeg"].as_f64()), (Some(270.0), Some(40.0)));
    let png = dir.path().join("view.png");
    let (code, out, err) = relief(&daemon, &["render", "--size", "200x100", "-o", png.to_str().unwrap()]).unwrap();
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("200x100"), "{out}");
    let image = image::open(&png).unwrap();
    assert_eq!((image.width(), image.height()), (200, 100));
    let (code, _, err) = relief(
        &daemon,
        &[
            "render",
            "--camera",
            "10.25,45.25,20000,0,-90,0",
            "--fov",
            "30",
            "--size",
            "64x64",
            "--grid-size",
            "63",
            "--levels",
            "4",
            "-o",
            png.to_str().unwrap(),
        ],
    )
    .unwrap();
    assert_eq!(code, 0, "{err}");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frame_says_which_terrain_blocks_it_left_out_and_why() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    // The scene's camera, 9 km up looking north at 45 degrees down: the
    // levels reach past its horizon (339 km away), so some blocks inside
    // the view's frustum are hidden by the planet, and left out.
    let frame = render(&channel, None, (320, 180)).await.unwrap();
    let d = frame.drawn.unwrap();
    assert!(d.terrain_blocks_beyond_horizon > 0, "{d:?}");
    assert!(d.terrain_blocks_drawn + d.terrain_blocks_beyond_horizon < d.terrain_blocks, "{d:?}");
    // Straight down from 20 km the horizon lies outside the view.
    let frame = render(&channel, Some(camera(10.25, 45.25, 20_000.0, 0.0, -90.0)), (320, 180)).await.unwrap();
    let d = frame.drawn.unwrap();
    assert_eq!(d.terrain_blocks_beyond_horizon, 0, "{d:?}");
    assert!(0 < d.terrain_blocks_drawn && d.terrain_blocks_drawn < d.terrain_blocks, "{d:?}");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_requests_get_invalid_argument_and_the_daemon_keeps_serving() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let good = camera(10.25, 45.1, 9000.0, 0.0, -45.0);
    let cases: [(Option<pb::Camera>, (u32, u32), &str); 6] = [
        (Some(good), (5000, 100), "width"),
        (Some(good), (100, 100_000), "height"),
        (Some(pb::Camera { pitch_deg: f64::NAN, ..good }), (64, 64), "pitch_deg"),
        (Some(pb::Camera { lat_deg: 95.0, ..good }), (64, 64), "lat_deg"),
        (Some(pb::Camera { altitude_m: 1e12, ..good }), (64, 64), "altitude_m"),
        (Some(pb::Camera { vertical_fov_deg: 0.0, ..good }), (64, 64), "vertical_fov_deg"),
    ];
    for (camera, size, field) in cases {
        let status = render(&channel, camera, size).await.unwrap_err();
        assert_eq!(status.code(), tonic::Code::InvalidArgument, "{field}: {status:?}");
        assert!(status.message().contains(field), "{field}: {}", status.message());
    }
    let mut views = ViewServiceClient::new(channel.clone());
    let status = views
        .set_camera(pb::SetCameraRequest { camera: Some(pb::Camera { lon_deg: f64::INFINITY, ..good }) })
        .await
        .unwrap_err();
    assert_eq!(status.code(), tonic::Code::InvalidArgument);
    assert!(status.message().contains("lon_deg"), "{}", status.message());
    let status = views
        .render(pb::RenderRequest {
            camera: None,
            width: 64,
            height: 64,
            format: 0,
            quality: Some(pb::QualityOverrides { clipmap_grid_size: Some(100), ..Default::default() }),
            ..Default::default()
        })
        .await
        .unwrap_err();
    assert_eq!(status.code(), tonic::Code::InvalidArgument);
    assert!(status.message().contains("clipmap_grid_size"), "{}", status.message());
    // A sun that cannot be placed is refused by field, never guessed.
    for (sun, field) in [
        (pb::Sun { time: "2026-06-21T15:00:00".into(), ..Default::default() }, "sun.time"),
        (pb::Sun { time: "21 June".into(), ..Default::default() }, "sun.time"),
        (pb::Sun { time: "2026-06-21T15:00:00Z".into(), azimuth_deg: Some(10.0), ..Default::default() }, "sun.time"),
        (pb::Sun { azimuth_deg: Some(10.0), elevation_deg: Some(95.0), ..Default::default() }, "sun.elevation_deg"),
        (pb::Sun { azimuth_deg: Some(10.0), ..Default::default() }, "sun.elevation_deg"),
        (pb::Sun::default(), "give a time or an azimuth and an elevation"),
        // This scene declares no effect: a sun would light nothing.
        (pb::Sun { azimuth_deg: Some(10.0), elevation_deg: Some(20.0), ..Default::default() }, "follows the sun"),
    ] {
        let request = pb::RenderRequest { width: 64, height: 64, sun: Some(sun.clone()), ..Default::default() };
        let status = views.render(request).await.unwrap_err();
        assert_eq!(status.code(), tonic::Code::InvalidArgument, "{sun:?}");
        assert!(status.message().contains(field), "{sun:?}: {}", status.message());
    }
    // Twelve large frames at once: four run or wait for the device, the
    // rest are told the daemon is busy, by name.
    let burst: Vec<_> = (0..12)
        .map(|_| {
            let channel = channel.clone();
            tokio::spawn(async move { render(&channel, Some(good), (1600, 1200)).await })
        })
        .collect();
    let (mut done, mut busy) = (0, 0);
    for r in burst {
        match r.await.unwrap() {
            Ok(_) => done += 1,
            Err(s) => {
                assert_eq!(s.code(), tonic::Code::ResourceExhausted, "{s:?}");
                assert!(s.message().contains("renders are already running"), "{}", s.message());
                busy += 1;
            }
        }
    }
    assert!(done >= 4 && busy >= 1, "{done} rendered, {busy} refused");
    // Still serving: the camera was not changed, and a good frame renders.
    let current = views.get_camera(pb::GetCameraRequest {}).await.unwrap().into_inner();
    assert_eq!(current.lat_deg, 45.1);
    render(&channel, None, (64, 64)).await.unwrap();
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn streamed_frames_follow_the_camera_and_the_generation_without_a_backlog() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = scene(dir.path(), "");
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    // A viewer that wants the freshest frame keeps its HTTP/2 window small,
    // and frames (640 x 480 RGBA, 1.2 MB) are larger than the server's
    // HTTP/2 send buffer (400 kB): the transport holds at most one.
    let channel =
        Channel::from_shared(daemon.url()).unwrap().initial_stream_window_size(32 * 1024).connect().await.unwrap();
    let mut views = ViewServiceClient::new(channel.clone()).max_decoding_message_size(64 << 20);
    let mut stream = views
        .stream_frames(pb::StreamFramesRequest {
            width: 640,
            height: 480,
            format: pb::ImageFormat::Rgba8 as i32,
            max_fps: 20.0,
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    let next = async |stream: &mut tonic::Streaming<pb::RenderResponse>| {
        tokio::time::timeout(Duration::from_secs(30), stream.next()).await.unwrap().unwrap().unwrap()
    };
    let first = next(&mut stream).await;
    assert_eq!((first.generation, first.camera.unwrap().lat_deg), (1, 45.1));
    // A new camera gives a new frame from it.
    let moved = camera(10.2, 45.3, 5000.0, 90.0, -30.0);
    views.set_camera(pb::SetCameraRequest { camera: Some(moved) }).await.unwrap();
    let mut frame = next(&mut stream).await;
    while frame.camera.unwrap().lat_deg != 45.3 {
        frame = next(&mut stream).await;
    }
    // A slow viewer: thirty camera changes over 1.2 s, time for a dozen
    // frames, while it reads nothing. Then it gets the latest camera after
    // at most three frames already in the pipe (the server's one-frame
    // channel, tonic's encoder, hyper's send buffer) and at most one of the
    // view that was being drawn when the camera came to rest (a stream keeps
    // that view so a moving camera still gets frames): the queue does not
    // grow with the changes it missed.
    for k in 0..30 {
        let c = camera(10.2 + f64::from(k) * 0.005, 45.3, 5000.0, 90.0, -30.0);
        views.set_camera(pb::SetCameraRequest { camera: Some(c) }).await.unwrap();
        tokio::time::sleep(Duration::from_millis(40)).await;
    }
    tokio::time::sleep(Duration::from_millis(500)).await;
    let latest = 10.2 + 29.0 * 0.005;
    let mut stale = 0;
    loop {
        let f = next(&mut stream).await;
        if (f.camera.unwrap().lon_deg - latest).abs() < 1e-9 {
            break;
        }
        stale += 1;
        assert!(stale <= 4, "frame {stale} still shows lon {}", f.camera.unwrap().lon_deg);
    }
    // An edit to the DEM: the next generation is streamed.
    edit::rewrite_window(&dir.path().join("hill.tif"), 100, 100, 32, 32, |_, _, h| h + 200.0).unwrap();
    let mut frame = next(&mut stream).await;
    while frame.generation < 2 {
        frame = next(&mut stream).await;
    }
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edit_shows_in_the_next_frame() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), "[effects]\nlighting = {}\n"), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let view = camera(10.25, 45.25, 20_000.0, 0.0, -90.0);
    let before = render(&channel, Some(view), (128, 128)).await.unwrap();
    // Raise a 40 x 40 pixel block (0.05 degrees) at the hill's centre by 800 m:
    // its walls catch the light differently.
    edit::rewrite_window(&dir.path().join("hill.tif"), 180, 180, 40, 40, |_, _, h| h + 800.0).unwrap();
    edit::wait_for(channel.clone(), 2).await.unwrap();
    let after = render(&channel, Some(view), (128, 128)).await.unwrap();
    assert_eq!(after.generation, 2);
    let changed: Vec<usize> = before
        .image
        .chunks(4)
        .zip(after.image.chunks(4))
        .enumerate()
        .filter(|(_, (a, b))| a.iter().zip(*b).any(|(x, y)| x.abs_diff(*y) > 8))
        .map(|(k, _)| k)
        .collect();
    assert!(!changed.is_empty(), "the raised block does not show");
    // Only round the block: the image's corners are as they were.
    for k in [0, 127, 128 * 127, 128 * 128 - 1] {
        assert!(!changed.contains(&k), "pixel {k} changed");
    }
    daemon.stop(&[]).unwrap();
}
