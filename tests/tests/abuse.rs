//! What an abuse probe found (issue 36), each held by a test that failed
//! on the code before its fix, through both transports where the finding
//! touches both: a read token steering the scene camera, views steered
//! by whoever knows their id, camera changes past the frame limits, a
//! named pipe in a file's place, connections with no deadline or cap, a
//! frame rate no duration holds, cross-site calls in open loopback mode,
//! an id echoed whole, and health streams without a cap.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

use anyhow::Context;
use relief_proto::v1 as pb;
use relief_proto::v1::navigate_request::Gesture;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::http::{Reply, request_with};
use relief_tests::probe::{CONTROL, OTHER_READ, READ, seconds_until_closed, token_file, with_token};
use relief_tests::scenes;
use tokio_stream::StreamExt;
use tonic::Code;
use tonic::transport::Channel;

fn orbit(view_id: &str) -> pb::NavigateRequest {
    pb::NavigateRequest {
        view_id: view_id.to_owned(),
        gesture: Some(Gesture::Orbit(pb::Orbit { heading_deg: 30.0, pitch_deg: 0.0 })),
    }
}

fn fly_to(view_id: &str) -> pb::NavigateRequest {
    pb::NavigateRequest { view_id: view_id.to_owned(), gesture: Some(Gesture::FlyToSource("dem".into())) }
}

/// An HTTP call with a bearer token, from a blocking thread.
async fn http(method: &str, url: String, body: Option<String>, token: &str) -> anyhow::Result<Reply> {
    let (method, bearer) = (method.to_owned(), format!("Bearer {token}"));
    tokio::task::spawn_blocking(move || request_with(&method, &url, body.as_deref(), &[("authorization", &bearer)]))
        .await?
}

async fn scene_heading(channel: &Channel) -> anyhow::Result<f64> {
    let camera =
        ViewServiceClient::new(channel.clone()).get_camera(with_token(pb::GetCameraRequest {}, Some(READ))?).await?;
    Ok(camera.into_inner().heading_deg)
}

/// Finding 1: a view that follows the scene camera moves it only for a
/// control token, a view answers only the token that opened it (or a
/// control token), over gRPC and HTTP alike.
#[tokio::test]
async fn a_read_token_steers_only_views_of_its_own() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let tokens = token_file(dir.path())?;
    let daemon = Reliefd::start(&manifest, &["--token-file", &tokens])?;
    let channel = daemon.channel().await?;
    let mut views = ViewServiceClient::new(channel.clone());
    let heading = scene_heading(&channel).await?;

    // gRPC: a read token's view that follows the scene camera.
    let follow = pb::OpenViewRequest { camera: None, follow_scene_camera: true };
    let view = views.open_view(with_token(follow, Some(READ))?).await?.into_inner().view_id;
    for gesture in [orbit(&view), fly_to(&view)] {
        let denied =
            views.navigate(with_token(gesture, Some(READ))?).await.err().context("a read token moved the scene")?;
        assert_eq!(denied.code(), Code::PermissionDenied, "{}", denied.message());
        assert!(denied.message().contains("control token"), "{}", denied.message());
    }
    assert_eq!(scene_heading(&channel).await?, heading, "the scene camera moved");
    // Its own view, let go of the scene camera, it may steer.
    let own = pb::UpdateViewRequest { view_id: view.clone(), follow_scene_camera: Some(false), ..Default::default() };
    views.update_view(with_token(own, Some(READ))?).await?;
    let moved = views.navigate(with_token(orbit(&view), Some(READ))?).await?.into_inner();
    assert!((moved.heading_deg - heading).abs() > 1.0, "{moved:?}");
    assert_eq!(scene_heading(&channel).await?, heading, "steering a view moved the scene camera");
    // Another read token may not, by gesture or update; a control token may.
    let denied =
        views.navigate(with_token(orbit(&view), Some(OTHER_READ))?).await.err().context("another token steered")?;
    assert_eq!(denied.code(), Code::PermissionDenied);
    let theirs = pb::UpdateViewRequest { view_id: view.clone(), follow_scene_camera: Some(true), ..Default::default() };
    let denied =
        views.update_view(with_token(theirs, Some(OTHER_READ))?).await.err().context("another token updated")?;
    assert_eq!(denied.code(), Code::PermissionDenied);
    views.navigate(with_token(orbit(&view), Some(CONTROL))?).await?;

    // HTTP: the same calls, the same answers.
    let url = daemon.url();
    let opened = http("POST", format!("{url}/api/views"), Some(r#"{"followSceneCamera":true}"#.into()), READ).await?;
    let view = opened.json()?["viewId"].as_str().context("no view id")?.to_owned();
    let navigate = format!("{url}/api/views/{view}/navigate");
    for body in [r#"{"orbit":{"headingDeg":30}}"#, r#"{"flyToSource":"dem"}"#] {
        let answer = http("POST", navigate.clone(), Some(body.into()), READ).await?;
        assert_eq!(answer.status, 403, "{body}: {}", String::from_utf8_lossy(&answer.body));
    }
    assert_eq!(scene_heading(&channel).await?, heading, "the scene camera moved");
    let patch = format!("{url}/api/views/{view}");
    let other = http("PATCH", patch.clone(), Some(r#"{"followSceneCamera":false}"#.into()), OTHER_READ).await?;
    assert_eq!(other.status, 403, "{}", String::from_utf8_lossy(&other.body));
    let own = http("PATCH", patch, Some(r#"{"followSceneCamera":false}"#.into()), READ).await?;
    assert_eq!(own.status, 200, "{}", String::from_utf8_lossy(&own.body));
    let steered = http("POST", navigate.clone(), Some(r#"{"orbit":{"headingDeg":30}}"#.into()), READ).await?;
    assert_eq!(steered.status, 200, "{}", String::from_utf8_lossy(&steered.body));
    let other = http("POST", navigate, Some(r#"{"orbit":{"headingDeg":30}}"#.into()), OTHER_READ).await?;
    assert_eq!(other.status, 403, "{}", String::from_utf8_lossy(&other.body));
    assert_eq!(scene_heading(&channel).await?, heading, "the scene camera moved");
    daemon.stop(&[])?;
    Ok(())
}

async fn frame_views(channel: &Channel) -> anyhow::Result<u64> {
    let state = relief_proto::v1::scene_service_client::SceneServiceClient::new(channel.clone())
        .get_state(pb::GetStateRequest {})
        .await?
        .into_inner();
    Ok(state.counters.unwrap_or_default().frame_views)
}

/// Finding 3: views opened on one camera share one render and are all let
/// in; turned each to a camera of its own (by PATCH or UpdateView), no
/// more than 64 distinct renders are made, and the streams past the limit
/// end with RESOURCE_EXHAUSTED.
#[tokio::test]
async fn camera_changes_keep_the_distinct_view_limit() -> anyhow::Result<()> {
    const VIEWS: usize = 70;
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let channel = daemon.channel().await?;
    let mut views = ViewServiceClient::new(channel.clone());
    let camera = scenes::camera(10.25, 45.1, 9000.0, 0.0, -45.0);
    let mut ids = Vec::new();
    let mut streams = Vec::new();
    for _ in 0..VIEWS {
        let open = pb::OpenViewRequest { camera: Some(camera), follow_scene_camera: false };
        let id = views.open_view(open).await?.into_inner().view_id;
        let request = pb::StreamFramesRequest {
            width: 16,
            height: 16,
            format: pb::ImageFormat::Rgba8 as i32,
            max_fps: 1.0,
            view_id: id.clone(),
            ..Default::default()
        };
        let mut stream = views.stream_frames(request).await?.into_inner();
        stream.next().await.context("no first frame")??;
        ids.push(id);
        streams.push(stream);
    }
    assert_eq!(frame_views(&channel).await?, 1, "one camera, one render");

    let url = daemon.url();
    for (n, id) in ids.iter().enumerate() {
        let own = scenes::camera(10.25, 45.1, 9000.0, (n + 1) as f64 * 5.0, -45.0);
        if n % 2 == 0 {
            let update = pb::UpdateViewRequest { view_id: id.clone(), camera: Some(own), ..Default::default() };
            views.update_view(update).await?;
        } else {
            let body = format!(
                r#"{{"camera":{{"lonDeg":10.25,"latDeg":45.1,"altitudeM":9000,"headingDeg":{},"pitchDeg":-45,"verticalFovDeg":50}}}}"#,
                own.heading_deg
            );
            let answer = tokio::task::spawn_blocking({
                let url = format!("{url}/api/views/{id}");
                move || request_with("PATCH", &url, Some(&body), &[])
            })
            .await??;
            assert_eq!(answer.status, 200, "{}", String::from_utf8_lossy(&answer.body));
        }
    }
    let (mut refused, mut streaming) = (0, 0);
    for mut stream in streams {
        // A stream either shows its new camera or ends, refused.
        match tokio::time::timeout(Duration::from_secs(60), async {
            loop {
                match stream.next().await {
                    Some(Ok(frame)) if frame.camera.is_some_and(|c| c.heading_deg != 0.0) => return Ok(()),
                    Some(Ok(_)) => {}
                    Some(Err(status)) => return Err(status),
                    None => return Err(tonic::Status::unknown("the stream ended without a word")),
                }
            }
        })
        .await
        .context("a stream neither moved nor ended")?
        {
            Ok(()) => streaming += 1,
            Err(status) => {
                assert_eq!(status.code(), Code::ResourceExhausted, "{}", status.message());
                assert!(status.message().contains("distinct views"), "{}", status.message());
                refused += 1;
            }
        }
    }
    assert!(streaming <= 64 && refused >= VIEWS - 64, "{streaming} streams moved, {refused} refused");
    assert!(frame_views(&channel).await? <= 64, "past the limit");
    daemon.stop(&[])?;
    Ok(())
}

/// `path` replaced by a named pipe.
fn make_fifo(path: &Path) -> anyhow::Result<()> {
    let _ = std::fs::remove_file(path);
    let status = Command::new("mkfifo").arg(path).status()?;
    anyhow::ensure!(status.success(), "mkfifo {} failed", path.display());
    Ok(())
}

/// Finding 4: a named pipe in place of a source file, its side file or
/// the manifest is refused as not a regular file, not opened and waited
/// on; many reloads at once all answer; SIGTERM ends the daemon.
#[tokio::test]
async fn a_named_pipe_in_a_files_place_is_refused_not_waited_on() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let url = daemon.url();
    let reload = |url: String| async move {
        tokio::task::spawn_blocking(move || request_with("POST", &format!("{url}/api/reload"), Some("{}"), &[])).await?
    };
    let cases = [dir.path().join("tint.tif.aux.xml"), dir.path().join("hill.tif"), manifest.clone()];
    for pipe in &cases {
        let saved = std::fs::read(pipe).ok();
        make_fifo(pipe)?;
        // Twenty reloads at once: each answers, naming the pipe.
        let answers = tokio::time::timeout(
            Duration::from_secs(60),
            futures_util::future::join_all((0..20).map(|_| reload(url.clone()))),
        )
        .await
        .with_context(|| format!("a reload waited on the pipe {}", pipe.display()))?;
        let name = pipe.file_name().context("no name")?.to_string_lossy().into_owned();
        let mut named = false;
        for answer in answers {
            let answer = answer?;
            let text = String::from_utf8_lossy(&answer.body).into_owned();
            named |= text.contains(&name) && text.contains("not a regular file");
            assert!(!text.contains("panicked"), "{text}");
        }
        // The manifest is read again by its watcher: its error shows in the state.
        let mut state_text = String::new();
        for _ in 0..100 {
            let state = tokio::task::spawn_blocking({
                let url = url.clone();
                move || relief_tests::http::get(&format!("{url}/api/state"))
            })
            .await??;
            assert_eq!(state.status, 200, "the daemon stopped serving");
            state_text = String::from_utf8_lossy(&state.body).into_owned();
            named |= state_text.contains(&name) && state_text.contains("not a regular file");
            if named {
                break;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        assert!(named, "{} is not named as not a regular file: {state_text}", pipe.display());
        std::fs::remove_file(pipe)?;
        if let Some(bytes) = saved {
            std::fs::write(pipe, bytes)?;
        }
    }
    // A pipe left in place at the end: SIGTERM still ends it (stop waits 5 s).
    make_fifo(&dir.path().join("hill.tif"))?;
    let _ = reload(url.clone()).await?;
    daemon.stop(&["not a regular file", "keeping the last good", "cannot"])?;
    Ok(())
}

const DRIP: &[u8] = b"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa";

/// Finding 5, plain TCP: a connection sending its headers a byte a second
/// and one sending nothing are closed within the 10 s deadline; ordinary
/// calls go on meanwhile.
#[test]
fn a_slowloris_connection_is_closed_within_the_header_timeout() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let addr = daemon.addr.clone();
    let silent = std::thread::Builder::new().name("silent".into()).spawn({
        let addr = addr.clone();
        move || -> anyhow::Result<Option<f64>> {
            let mut stream = TcpStream::connect(&addr)?;
            stream.set_read_timeout(Some(Duration::from_secs(1)))?;
            Ok(seconds_until_closed(&mut stream, b"", Duration::from_secs(20)))
        }
    })?;
    let mut stream = TcpStream::connect(&addr)?;
    stream.set_read_timeout(Some(Duration::from_secs(1)))?;
    let dripping = seconds_until_closed(&mut stream, DRIP, Duration::from_secs(20));
    let silent = silent.join().map_err(|_| anyhow::anyhow!("the silent client panicked"))??;
    assert!(dripping.is_some_and(|s| s < 13.0), "a byte a second kept it open: {dripping:?}");
    assert!(silent.is_some_and(|s| s < 13.0), "silence kept it open: {silent:?}");
    assert_eq!(relief_tests::http::get(&format!("{}/api/state", daemon.url()))?.status, 200);
    daemon.stop(&[])?;
    Ok(())
}

/// Finding 5, caps: past --max-connections a connection is closed at once
/// and ordinary calls work again when some close; off loopback, past
/// --max-connections-per-address from one address.
#[test]
fn connections_past_the_caps_are_closed_at_once() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &["--max-connections", "8"])?;
    let open: Vec<TcpStream> = (0..8).map(|_| TcpStream::connect(&daemon.addr)).collect::<Result<_, _>>()?;
    std::thread::sleep(Duration::from_millis(300));
    let mut ninth = TcpStream::connect(&daemon.addr)?;
    ninth.set_read_timeout(Some(Duration::from_secs(1)))?;
    let closed = seconds_until_closed(&mut ninth, b"", Duration::from_secs(5));
    assert!(closed.is_some_and(|s| s < 2.0), "the ninth connection was kept: {closed:?}");
    drop(open);
    let mut answered = false;
    for _ in 0..50 {
        if relief_tests::http::get(&format!("{}/api/state", daemon.url())).is_ok_and(|r| r.status == 200) {
            answered = true;
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(answered, "no answer once the idle connections closed");
    daemon.stop(&["connection"])?;

    // Off loopback: this machine's own network address, if it has one.
    let Some(own) = std::net::UdpSocket::bind("0.0.0.0:0")
        .and_then(|s| s.connect("192.0.2.1:9").and(s.local_addr()))
        .ok()
        .map(|a| a.ip())
        .filter(|ip| !ip.is_loopback() && !ip.is_unspecified())
    else {
        eprintln!("skipping the per-address cap: this machine has no network address");
        return Ok(());
    };
    let tokens = token_file(dir.path())?;
    let daemon = Reliefd::start(
        &manifest,
        &["--listen", &format!("{own}:0"), "--token-file", &tokens, "--insecure", "--max-connections-per-address", "4"],
    )?;
    let open: Vec<TcpStream> = (0..4).map(|_| TcpStream::connect(&daemon.addr)).collect::<Result<_, _>>()?;
    std::thread::sleep(Duration::from_millis(300));
    let mut fifth = TcpStream::connect(&daemon.addr)?;
    fifth.set_read_timeout(Some(Duration::from_secs(1)))?;
    let closed = seconds_until_closed(&mut fifth, b"", Duration::from_secs(5));
    assert!(closed.is_some_and(|s| s < 2.0), "the fifth connection from {own} was kept: {closed:?}");
    // Loopback is not counted against an address.
    drop(open);
    daemon.stop(&["connection", "--insecure"])?;
    Ok(())
}

/// Finding 6: frame rates no duration holds are refused with a clear
/// error by both transports, and the daemon goes on serving.
#[tokio::test]
async fn a_frame_rate_out_of_range_is_refused_not_panicked_on() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let channel = daemon.channel().await?;
    let url = daemon.url();
    for fps in ["1e-30", "-1", "1e30", "NaN", "inf"] {
        let frames = format!("{url}/api/frames?width=16&height=16&max_fps={fps}");
        let answer = tokio::task::spawn_blocking(move || request_with("GET", &frames, None, &[])).await??;
        let text = String::from_utf8_lossy(&answer.body).into_owned();
        assert_eq!(answer.status, 400, "{fps}: {text}");
        assert!(text.contains("max_fps"), "{fps}: {text}");
        let max_fps: f64 = fps.parse()?;
        let request = pb::StreamFramesRequest { width: 16, height: 16, max_fps, ..Default::default() };
        let refused = ViewServiceClient::new(channel.clone()).stream_frames(request).await.err();
        let status = refused.with_context(|| format!("max_fps {fps} was taken"))?;
        assert_eq!(status.code(), Code::InvalidArgument, "{fps}: {}", status.message());
        assert!(status.message().contains("max_fps"), "{}", status.message());
    }
    let request = pb::StreamFramesRequest { width: 16, height: 16, max_fps: 1.0 / 60.0, ..Default::default() };
    let mut slow = ViewServiceClient::new(channel.clone()).stream_frames(request).await?.into_inner();
    slow.next().await.context("no frame at a frame a minute")??;
    daemon.stop(&[])?;
    Ok(())
}

/// One HTTP/1.1 request, written out whole: (status, body).
fn raw(addr: &str, request: &str) -> anyhow::Result<(u16, String)> {
    let mut stream = TcpStream::connect(addr)?;
    stream.set_read_timeout(Some(Duration::from_secs(30)))?;
    stream.write_all(request.as_bytes())?;
    let mut answer = Vec::new();
    stream.read_to_end(&mut answer)?;
    let text = String::from_utf8_lossy(&answer).into_owned();
    let status = text.split_whitespace().nth(1).and_then(|s| s.parse().ok()).context("no status")?;
    Ok((status, text))
}

fn post(host: &str, path: &str, headers: &str, body: &str) -> String {
    format!(
        "POST {path} HTTP/1.1\r\nHost: {host}\r\n{headers}Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
}

/// Finding 7: with no token asked (loopback), a cross-site POST (text/plain
/// or from a foreign Origin) and a rebound Host are refused, while the
/// page, its own origin, curl's plain calls and an --allow-origin site work.
#[test]
fn cross_site_calls_and_rebound_hosts_are_refused_on_open_loopback() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &["--allow-origin", "https://maps.example.org"])?;
    let addr = daemon.addr.clone();
    let json = "Content-Type: application/json\r\n";
    let orbit = r#"{"orbit":{"headingDeg":30}}"#;
    let heading = || -> anyhow::Result<f64> {
        let camera = relief_tests::http::get(&format!("{}/api/camera", daemon.url()))?.json()?;
        Ok(camera["headingDeg"].as_f64().unwrap_or(0.0))
    };
    let before = heading()?;
    let refused = [
        (post(&addr, "/api/navigate", "Content-Type: text/plain\r\n", orbit), 415),
        (post(&addr, "/api/reload", "Content-Type: text/plain\r\n", "{}"), 415),
        (post(&addr, "/api/navigate", "", orbit), 415),
        (post(&addr, "/api/navigate", &format!("{json}Origin: https://evil.example\r\n"), orbit), 403),
        (post(&addr, "/api/reload", &format!("{json}Origin: http://127.0.0.1:1\r\n"), "{}"), 403),
        (post("rebind.example:80", "/api/navigate", json, orbit), 403),
        (format!("GET /api/state HTTP/1.1\r\nHost: rebind.example:{}\r\nConnection: close\r\n\r\n", port(&addr)), 403),
        ("GET / HTTP/1.1\r\nHost: rebind.example\r\nConnection: close\r\n\r\n".to_owned(), 403),
    ];
    for (request, status) in &refused {
        let (got, text) = raw(&addr, request)?;
        assert_eq!(got, *status, "{request}\n{text}");
        assert!(!text.contains(&dir.path().display().to_string()), "a refusal gave paths away: {text}");
    }
    assert_eq!(heading()?, before, "a refused call moved the camera");
    let served = [
        format!("GET / HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"),
        format!("GET /api/state HTTP/1.1\r\nHost: localhost:{}\r\nConnection: close\r\n\r\n", port(&addr)),
        post(&addr, "/api/reload", json, "{}"),
        post(&addr, "/api/reload", &format!("{json}Origin: http://{addr}\r\n"), "{}"),
        post(&addr, "/api/reload", &format!("{json}Origin: https://maps.example.org\r\n"), "{}"),
        post(&addr, "/api/navigate", "Content-Type: application/json; charset=utf-8\r\n", orbit),
    ];
    for request in &served {
        let (got, text) = raw(&addr, request)?;
        assert_eq!(got, 200, "{request}\n{text}");
    }
    assert_ne!(heading()?, before, "the JSON navigate was not served");
    daemon.stop(&[])?;
    Ok(())
}

fn port(addr: &str) -> &str {
    addr.rsplit(':').next().unwrap_or_default()
}

/// Smaller items: an id of a megabyte comes back as at most 200
/// characters of it, over both transports.
#[tokio::test]
async fn errors_repeat_at_most_200_characters_of_what_was_sent() -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let daemon = Reliefd::start(&manifest, &[])?;
    let channel = daemon.channel().await?;
    let huge = "x".repeat(1 << 20);
    let update = pb::UpdateViewRequest { view_id: huge.clone(), ..Default::default() };
    let status = ViewServiceClient::new(channel.clone())
        .max_decoding_message_size(8 << 20)
        .update_view(update)
        .await
        .err()
        .context("a megabyte id was found")?;
    assert_eq!(status.code(), Code::NotFound);
    assert!(status.message().len() < 600, "{} characters came back", status.message().len());
    let sample = pb::SampleElevationRequest {
        points: vec![pb::GeodeticPoint { lon_deg: 10.25, lat_deg: 45.1 }],
        source_id: huge.clone(),
    };
    let status = relief_proto::v1::tile_service_client::TileServiceClient::new(channel.clone())
        .sample_elevation(sample)
        .await
        .err()
        .context("a megabyte source was found")?;
    assert!(status.message().len() < 600, "{} characters came back", status.message().len());
    let url = daemon.url();
    let body = format!(r#"{{"points":[{{"lonDeg":10.25,"latDeg":45.1}}],"sourceId":"{huge}"}}"#);
    let answer =
        tokio::task::spawn_blocking(move || request_with("POST", &format!("{url}/api/elevation"), Some(&body), &[]))
            .await??;
    assert_eq!(answer.status, 404, "{}", String::from_utf8_lossy(&answer.body[..answer.body.len().min(400)]));
    assert!(answer.body.len() < 600, "{} bytes came back", answer.body.len());
    daemon.stop(&[])?;
    Ok(())
}

/// Smaller items: health Watch streams need no token, so they count
/// against a cap of 64; Check still answers past it.
#[tokio::test]
async fn health_watch_streams_are_capped() -> anyhow::Result<()> {
    use tonic_health::pb::HealthCheckRequest;
    use tonic_health::pb::health_client::HealthClient;
    let dir = tempfile::tempdir()?;
    let manifest = scenes::hill(dir.path(), "")?;
    let tokens = token_file(dir.path())?;
    let daemon = Reliefd::start(&manifest, &["--token-file", &tokens])?;
    let channel = daemon.channel().await?;
    let mut health = HealthClient::new(channel.clone());
    let mut watches = Vec::new();
    for _ in 0..64 {
        let mut stream = health.watch(HealthCheckRequest { service: String::new() }).await?.into_inner();
        stream.next().await.context("no first health answer")??;
        watches.push(stream);
    }
    let refused = match health.watch(HealthCheckRequest { service: String::new() }).await {
        Err(status) => status,
        Ok(answer) => {
            answer.into_inner().next().await.context("the 65th ended at once")?.err().context("a 65th watch ran")?
        }
    };
    assert_eq!(refused.code(), Code::ResourceExhausted, "{}", refused.message());
    health.check(HealthCheckRequest { service: String::new() }).await?;
    watches.truncate(10);
    let mut served = false;
    for _ in 0..50 {
        if let Ok(answer) = health.watch(HealthCheckRequest { service: String::new() }).await
            && answer.into_inner().next().await.is_some_and(|a| a.is_ok())
        {
            served = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(served, "no watch served once some closed");
    daemon.stop(&[])?;
    Ok(())
}
