//! The HTTP transport on reliefd's gRPC port: the page, state and events,
//! a rendered PNG for curl, frames as Server-Sent Events, and bad input
//! answered with an HTTP status and a message that names the field, while
//! the daemon keeps serving.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::process::Command;
use std::time::Duration;

use base64::Engine as _;
use relief_tests::daemon::Reliefd;
use relief_tests::http::{Events, get, request};
use relief_tests::scenes;

async fn blocking<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
    tokio::task::spawn_blocking(f).await.unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn curl_reads_the_state_and_fetches_a_rendered_png() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let url = daemon.url();
    let out = dir.path().join("view.png");
    let state = Command::new("curl").args(["-sf", &format!("{url}/api/state")]).output().unwrap();
    assert!(state.status.success(), "{state:?}");
    let state: serde_json::Value = serde_json::from_slice(&state.stdout).unwrap();
    assert_eq!((state["name"].as_str(), state["generation"].as_str()), (Some("hill"), Some("1")));
    assert_eq!(state["sources"][0]["status"], "SOURCE_STATUS_READY");
    let render = format!("{url}/api/render?camera=10.25,45.1,9000,0,-45,0&fov=50&width=320&height=200");
    let status = Command::new("curl").args(["-sf", "-o"]).arg(&out).arg(&render).status().unwrap();
    assert!(status.success());
    let png = image::open(&out).unwrap().to_rgba8();
    assert_eq!(png.dimensions(), (320, 200));
    // The same frame over gRPC-free JSON, with its generation in a header.
    let reply = blocking(move || get(&render)).await.unwrap();
    assert_eq!(
        (reply.status, reply.content_type.as_str(), reply.header("x-relief-generation")),
        (200, "image/png", Some("1"))
    );
    // The page and its script, embedded in reliefd.
    let page = blocking({
        let url = url.clone();
        move || get(&format!("{url}/"))
    })
    .await
    .unwrap();
    assert!(page.content_type.starts_with("text/html") && String::from_utf8_lossy(&page.body).contains("viewer.js"));
    let routes = blocking(move || get(&format!("{url}/api"))).await.unwrap().json().unwrap();
    assert!(routes.as_array().unwrap().iter().any(|r| r["path"].as_str().unwrap().starts_with("/api/frames")));
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_and_events_stream_as_server_sent_events() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let url = daemon.url();
    let frames_url = format!("{url}/api/frames?camera=10.25,45.1,9000,0,-45,0&width=160&height=90&max_fps=20");
    let (frame, events) = blocking(move || {
        let mut events = Events::open(&frames_url).unwrap();
        assert_eq!(events.status, 200);
        let (name, data) = events.next_event().unwrap().unwrap();
        assert_eq!(name, "frame");
        (serde_json::from_str::<serde_json::Value>(&data).unwrap(), events)
    })
    .await;
    assert_eq!((frame["width"].as_u64(), frame["generation"].as_str()), (Some(160), Some("1")));
    let png = base64::engine::general_purpose::STANDARD.decode(frame["image"].as_str().unwrap()).unwrap();
    assert_eq!(image::load_from_memory(&png).unwrap().width(), 160);
    // The scene's events: a snapshot first.
    let events_url = format!("{url}/api/events");
    let snapshot = blocking(move || {
        let mut e = Events::open(&events_url).unwrap();
        e.next_event().unwrap().unwrap()
    })
    .await;
    assert_eq!(snapshot.0, "scene");
    assert!(snapshot.1.contains("\"snapshot\""), "{}", snapshot.1);
    // A client that disconnects mid-stream: its stream ends, the daemon
    // serves on.
    blocking(move || drop(events)).await;
    let state_url = format!("{url}/api/state");
    let mut streams = u64::MAX;
    for _ in 0..200 {
        let state = blocking({
            let u = state_url.clone();
            move || get(&u)
        })
        .await
        .unwrap()
        .json()
        .unwrap();
        streams = state["counters"]["frameStreams"].as_str().map_or(0, |s| s.parse().unwrap());
        if streams == 0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(streams, 0, "the disconnected stream still runs");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_http_requests_get_a_status_and_a_message_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let url = daemon.url();
    let good = "10.25,45.1,9000,0,-45,0";
    let cases: Vec<(&str, String, Option<&str>, u16, &str)> = vec![
        ("GET", "/no/such/route".into(), None, 404, "/no/such/route"),
        ("GET", "/api/render?camera=10.25,95,9000,0,-45,0".into(), None, 400, "lat_deg"),
        ("GET", "/api/render?camera=10.25,NaN,9000,0,-45,0".into(), None, 400, "lat_deg"),
        ("GET", "/api/render?camera=10.25,45".into(), None, 400, "camera"),
        ("GET", format!("/api/render?camera={good}&width=5000"), None, 400, "width"),
        ("GET", format!("/api/render?camera={good}&height=tall"), None, 400, "height"),
        ("GET", format!("/api/frames?camera={good}&width=5000"), None, 400, "width"),
        ("GET", format!("/api/frames?camera={good}&max_fps=1000"), None, 400, "max_fps"),
        ("GET", "/api/frames?view=nope".into(), None, 404, "nope"),
        ("PUT", "/api/camera".into(), Some(r#"{"latDeg": "north"}"#), 400, "invalid JSON body"),
        (
            "PUT",
            "/api/camera".into(),
            Some(r#"{"lonDeg": 10, "latDeg": 45, "altitudeM": 1000, "pitchDeg": -100, "verticalFovDeg": 50}"#),
            400,
            "pitch_deg",
        ),
        ("POST", "/api/views".into(), Some("not json"), 400, "invalid JSON body"),
        ("PATCH", "/api/views/nope".into(), Some("{}"), 404, "nope"),
        ("GET", "/api/views/nope/pick?x=0.5&y=0.5".into(), None, 404, "nope"),
        ("GET", "/api/elevation?points=10.25".into(), None, 400, "points"),
        ("GET", "/api/tiles/nope/0/0/0".into(), None, 404, "nope"),
        ("GET", "/api/wait?generation=9&timeout_ms=10".into(), None, 504, "generation 9"),
    ];
    for (method, path, body, status, field) in cases {
        let target = format!("{url}{path}");
        let reply = blocking(move || request(method, &target, body)).await.unwrap();
        let json = reply.json().unwrap();
        assert_eq!(reply.status, status, "{method} {path}: {json}");
        let message = json["message"].as_str().unwrap();
        assert!(message.contains(field), "{method} {path}: {message}");
        assert!(!message.contains("{ ") && !message.contains("Some("), "Debug output: {message}");
    }
    // Still serving, the camera as it was.
    let camera = blocking(move || get(&format!("{url}/api/camera"))).await.unwrap().json().unwrap();
    assert_eq!(camera["latDeg"].as_f64(), Some(45.1));
    daemon.stop(&["a view could not be rendered"]).unwrap();
}

/// The header and image of a binary frame message: the u32 (little-endian)
/// length of the JSON header, the header, the image.
fn ws_frame(bytes: &[u8]) -> (serde_json::Value, Vec<u8>) {
    let n = u32::from_le_bytes(bytes[..4].try_into().unwrap()) as usize;
    let header: serde_json::Value = serde_json::from_slice(&bytes[4..4 + n]).unwrap();
    (header, bytes[4 + n..].to_vec())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_travel_as_binary_websocket_messages_and_a_bad_request_is_refused_before_the_upgrade() {
    use futures_util::StreamExt as _;
    use tokio_tungstenite::tungstenite::Message;

    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let ws = daemon.url().replace("http://", "ws://");
    let camera = "camera=10.25,45.1,9000,0,-45,0&width=160&height=90&max_fps=20";
    // At rest (no view dragging), a live stream's frames are lossless PNG.
    let (mut socket, _) = tokio_tungstenite::connect_async(format!("{ws}/api/frames/ws?{camera}")).await.unwrap();
    let message = tokio::time::timeout(Duration::from_secs(60), socket.next()).await.unwrap().unwrap().unwrap();
    let Message::Binary(bytes) = message else { panic!("not a binary frame: {message:?}") };
    let (header, image) = ws_frame(&bytes);
    let frame = &header["frame"];
    assert_eq!((frame["width"].as_u64(), frame["height"].as_u64()), (Some(160), Some(90)));
    assert_eq!(frame["format"], "IMAGE_FORMAT_PNG");
    assert!(frame.get("image").is_none(), "the image travels beside the header, not in it");
    assert!(frame["passes"].as_array().unwrap().iter().any(|p| p["pass"] == "encode png"));
    assert_eq!(image::load_from_memory(&image).unwrap().to_rgba8().dimensions(), (160, 90));
    socket.close(None).await.unwrap();
    // JPEG when asked, at its quality.
    let url = format!("{ws}/api/frames/ws?{camera}&format=jpeg&jpeg_quality=50");
    let (mut socket, _) = tokio_tungstenite::connect_async(url).await.unwrap();
    let message = tokio::time::timeout(Duration::from_secs(60), socket.next()).await.unwrap().unwrap().unwrap();
    let Message::Binary(bytes) = message else { panic!("not a binary frame: {message:?}") };
    let (header, image) = ws_frame(&bytes);
    assert_eq!(header["frame"]["format"], "IMAGE_FORMAT_JPEG");
    assert!(image.starts_with(&[0xff, 0xd8, 0xff]));
    assert_eq!(image::load_from_memory(&image).unwrap().to_rgba8().dimensions(), (160, 90));
    drop(socket);
    // A bad request: an HTTP error naming the field, no socket.
    for (query, field) in [("width=99999", "width"), ("format=gif", "format"), ("jpeg_quality=0", "frame_jpeg_quality")]
    {
        let url = format!("{ws}/api/frames/ws?{camera}&{query}");
        let e = tokio_tungstenite::connect_async(url).await.unwrap_err();
        let tokio_tungstenite::tungstenite::Error::Http(response) = e else { panic!("{query}: {e}") };
        assert_eq!(response.status(), 400, "{query}");
        let body = String::from_utf8_lossy(response.body().as_deref().unwrap_or_default()).into_owned();
        assert!(body.contains(field), "{query}: {body}");
    }
    daemon.stop(&[]).unwrap();
}
