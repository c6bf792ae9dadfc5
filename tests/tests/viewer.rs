//! The browser viewer in a real headless Chromium (Debian's `chromium`),
//! driven over the DevTools protocol: the page served by reliefd shows a
//! frame equal to a Render of the same camera, follows an edit on disk,
//! shows a broken file's error while the image stays, and a drag moves the
//! tab's own camera, or the scene camera in follow mode.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::time::Duration;

use base64::Engine as _;
use relief_proto::v1 as pb;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::browser::{self, Browser};
use relief_tests::daemon::Reliefd;
use relief_tests::{edit, scenes};
use tonic::transport::Channel;

/// How long the page may take to show what the daemon serves (first frame
/// on lavapipe in a debug build, a reload, an error).
const PAGE_TIMEOUT: Duration = Duration::from_secs(60);
/// The displayed image against a Render of the same camera and size.
const MIN_PSNR_DB: f64 = 40.0;

fn psnr(a: &[u8], b: &[u8]) -> f64 {
    assert_eq!(a.len(), b.len());
    let mse = a.iter().zip(b).map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2)).sum::<f64>() / a.len() as f64;
    if mse == 0.0 { f64::INFINITY } else { 10.0 * (255.0f64.powi(2) / mse).log10() }
}

/// The pixels the page's `<img id="view">` shows, through a canvas.
async fn displayed(page: &Browser) -> (u32, u32, Vec<u8>) {
    let v = page
        .eval(
            "(() => { const img = document.getElementById('view'); const c = document.createElement('canvas');
               c.width = img.naturalWidth; c.height = img.naturalHeight;
               const g = c.getContext('2d'); g.drawImage(img, 0, 0);
               const d = g.getImageData(0, 0, c.width, c.height).data;
               let s = ''; for (let i = 0; i < d.length; i += 8192) s += String.fromCharCode.apply(null, d.subarray(i, i + 8192));
               return { w: c.width, h: c.height, rgba: btoa(s) }; })()",
        )
        .await
        .unwrap();
    let rgba = base64::engine::general_purpose::STANDARD.decode(v["rgba"].as_str().unwrap()).unwrap();
    (v["w"].as_u64().unwrap() as u32, v["h"].as_u64().unwrap() as u32, rgba)
}

fn camera_of(v: &serde_json::Value) -> pb::Camera {
    let f = |k: &str| v[k].as_f64().unwrap_or(0.0);
    pb::Camera {
        lon_deg: f("lonDeg"),
        lat_deg: f("latDeg"),
        altitude_m: f("altitudeM"),
        heading_deg: f("headingDeg"),
        pitch_deg: f("pitchDeg"),
        roll_deg: f("rollDeg"),
        vertical_fov_deg: f("verticalFovDeg"),
    }
}

async fn scene_camera(channel: &Channel) -> pb::Camera {
    ViewServiceClient::new(channel.clone()).get_camera(pb::GetCameraRequest {}).await.unwrap().into_inner()
}

async fn open(daemon: &Reliefd) -> Browser {
    let page = Browser::start(1000, 640).await.unwrap();
    page.navigate(&format!("{}/", daemon.url())).await.unwrap();
    page.wait_for("document.body.dataset.ready === '1'", PAGE_TIMEOUT).await.unwrap();
    page
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_page_shows_frames_edits_and_errors_as_the_daemon_serves_them() {
    if !browser::available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "[effects]\nlighting = {}\n").unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let page = open(&daemon).await;
    assert_eq!(page.eval("document.getElementById('scene-name').textContent").await.unwrap(), "hill");
    assert_eq!(page.eval("document.getElementById('generation').textContent").await.unwrap(), "1");

    // What the page shows is a Render of the same camera and size.
    let frame = page.eval("window.relief.lastFrame").await.unwrap();
    let (w, h, shown) = displayed(&page).await;
    assert_eq!((u64::from(w), u64::from(h)), (frame["width"].as_u64().unwrap(), frame["height"].as_u64().unwrap()));
    let reference = ViewServiceClient::new(channel.clone())
        .max_decoding_message_size(64 << 20)
        .render(pb::RenderRequest {
            camera: Some(camera_of(&frame["camera"])),
            width: w,
            height: h,
            format: pb::ImageFormat::Rgba8 as i32,
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    let db = psnr(&shown, &reference.image);
    assert!(db >= MIN_PSNR_DB, "the page shows {db:.1} dB from a Render of its camera");

    // Frames come as binary WebSocket messages, lossless at rest.
    assert_eq!(page.eval("window.relief.lastFrame.format").await.unwrap(), "IMAGE_FORMAT_PNG");
    assert!(page.eval("window.relief.frameBytes").await.unwrap().as_u64().unwrap() > 1000);
    assert!(page.eval("window.relief.lastFrame.image === undefined").await.unwrap().as_bool().unwrap());

    // A DEM edited on disk: the page's generation advances and its image
    // changes, pushed by the daemon.
    let (_, _, before) = displayed(&page).await;
    edit::rewrite_window(&dir.path().join("hill.tif"), 150, 150, 64, 64, |_, _, h| h + 900.0).unwrap();
    page.wait_for(
        "window.relief.generation >= 2 && window.relief.frameLog.some(f => f.generation >= 2 && f.shown)",
        PAGE_TIMEOUT,
    )
    .await
    .unwrap();
    assert_eq!(page.eval("document.getElementById('generation').textContent").await.unwrap(), "2");
    let (_, _, after) = displayed(&page).await;
    assert_ne!(after, before, "the edit shows");
    let change = page.eval("document.getElementById('last-change').textContent").await.unwrap();
    assert!(change.as_str().unwrap().contains("dem"), "{change}");
    // The change is outlined on the picture (the edit is in front of the camera).
    page.wait_for("window.relief.dirtyShown >= 1", PAGE_TIMEOUT).await.unwrap();
    assert!(page.eval("window.relief.dirtyLines").await.unwrap().as_u64().unwrap() >= 1);
    if let Ok(out) = std::env::var("RELIEF_TEST_SCREENSHOTS") {
        std::fs::write(std::path::Path::new(&out).join("viewer-dirty-outline.png"), page.screenshot().await.unwrap())
            .unwrap();
    }
    // The effects say what the frame shown ran: lighting inside the terrain pass.
    let lighting = page.eval("document.querySelector('tr[data-effect=\"lighting\"]').textContent").await.unwrap();
    assert!(lighting.as_str().unwrap().contains("in terrain"), "{lighting}");

    // A corrupted file: its error in the panel, the image stays (the
    // error is a new generation of the scene's state, drawn from the same
    // last good data).
    let (_, _, shown_before) = displayed(&page).await;
    std::fs::write(dir.path().join("hill.tif"), b"II*\0 this is not a TIFF any more").unwrap();
    let error_cell = "document.querySelector('tr[data-source-id=\"dem\"] td.error').textContent";
    page.wait_for(&format!("{error_cell}.includes('hill.tif')"), PAGE_TIMEOUT).await.unwrap();
    // A banner names the file, and the status is not a green "live".
    page.wait_for("document.getElementById('source-errors').textContent.includes('hill.tif')", PAGE_TIMEOUT)
        .await
        .unwrap();
    let status = page.eval("document.querySelector('#status .conn').className").await.unwrap();
    assert!(!status.as_str().unwrap().split(' ').any(|c| c == "live"), "{status}");
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (_, _, shown_after) = displayed(&page).await;
    let db = psnr(&shown_before, &shown_after);
    assert!(db >= MIN_PSNR_DB, "the image changed with the broken file: {db:.1} dB");

    // The controls help opens from its button and closes with Escape.
    page.eval("document.getElementById('help-button').click()").await.unwrap();
    page.wait_for("!document.getElementById('help').hidden", PAGE_TIMEOUT).await.unwrap();
    page.eval("document.dispatchEvent(new KeyboardEvent('keydown', { key: 'Escape' }))").await.unwrap();
    page.wait_for("document.getElementById('help').hidden", PAGE_TIMEOUT).await.unwrap();

    // The cursor readout: longitude, latitude and height under the mouse.
    page.mouse("mouseMoved", 500.0, 400.0, "none").await.unwrap();
    page.wait_for("/\\d+\\.\\d{6}/.test(document.getElementById('cursor').textContent)", PAGE_TIMEOUT).await.unwrap();
    // RELIEF_TEST_SCREENSHOTS=DIR keeps a picture of the page for a person to look at.
    if let Ok(out) = std::env::var("RELIEF_TEST_SCREENSHOTS") {
        std::fs::write(std::path::Path::new(&out).join("viewer-broken-file.png"), page.screenshot().await.unwrap())
            .unwrap();
    }

    let errors: Vec<String> = page.errors().into_iter().filter(|e| e.starts_with("exception")).collect();
    assert!(errors.is_empty(), "the page threw: {errors:?}");
    drop(page);
    daemon.stop(&["hill.tif"]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_drag_moves_the_tabs_own_camera_and_the_scene_camera_in_follow_mode() {
    if !browser::available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let start = scene_camera(&channel).await;
    let (tab, other) = (open(&daemon).await, open(&daemon).await);
    let heading = "window.relief.lastFrame.camera.headingDeg ?? 0";
    let other_heading = other.eval(heading).await.unwrap();

    // Its own camera: the tab turns, the other tab and the scene do not.
    // While it drags, its frames are JPEG; at rest PNG again.
    tab.eval("window.relief.formats = new Set(); const show = window.relief; setInterval(() => { if (show.lastFrame) show.formats.add(show.lastFrame.format); }, 5)").await.unwrap();
    tab.drag((400.0, 300.0), (520.0, 300.0), 6).await.unwrap();
    tab.wait_for(&format!("Math.abs(({heading}) - {}) > 5", start.heading_deg), PAGE_TIMEOUT).await.unwrap();
    assert_eq!(scene_camera(&channel).await, start);
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(other.eval(heading).await.unwrap(), other_heading);
    tab.wait_for("window.relief.formats.has('IMAGE_FORMAT_JPEG')", PAGE_TIMEOUT).await.unwrap();
    tab.wait_for("window.relief.lastFrame.format === 'IMAGE_FORMAT_PNG'", PAGE_TIMEOUT).await.unwrap();

    // Follow mode: the tab shows the scene camera, and a drag moves it for
    // every follower; GetCamera over gRPC says so.
    tab.eval("document.getElementById('follow').click()").await.unwrap();
    tab.wait_for(&format!("Math.abs(({heading}) - {}) < 1e-9", start.heading_deg), PAGE_TIMEOUT).await.unwrap();
    tab.drag((400.0, 300.0), (400.0, 380.0), 6).await.unwrap();
    let mut moved = start;
    for _ in 0..400 {
        moved = scene_camera(&channel).await;
        if moved != start {
            break;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    assert_ne!(moved, start, "the drag did not move the scene camera");
    // The drag tilts: vertical mouse motion changes the pitch.
    tab.wait_for("window.relief.lastFrame && !!window.relief.lastFrame.camera", PAGE_TIMEOUT).await.unwrap();
    let settled = async {
        loop {
            let now = scene_camera(&channel).await;
            let shown = camera_of(&tab.eval("window.relief.lastFrame.camera").await.unwrap());
            if (shown.pitch_deg - now.pitch_deg).abs() < 1e-9 && (shown.lon_deg - now.lon_deg).abs() < 1e-12 {
                return now;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    };
    let now = tokio::time::timeout(PAGE_TIMEOUT, settled).await.expect("the page shows the scene camera");
    assert!((now.pitch_deg - start.pitch_deg).abs() > 1.0, "{start:?} -> {now:?}");

    // Unticking Follow keeps the pose shown (it used to jump back to the
    // tab's own pose from before it followed).
    tab.eval("document.getElementById('follow').click()").await.unwrap();
    tab.wait_for("document.getElementById('follow').checked === false", PAGE_TIMEOUT).await.unwrap();
    tab.drag((400.0, 300.0), (410.0, 300.0), 2).await.unwrap();
    let turned = format!("Math.abs(((({heading}) - {} + 540) % 360) - 180) > 1", now.heading_deg);
    tab.wait_for(&turned, PAGE_TIMEOUT).await.unwrap();
    tab.wait_for("window.relief.lastFrame.format === 'IMAGE_FORMAT_PNG'", PAGE_TIMEOUT).await.unwrap();
    let own = camera_of(&tab.eval("window.relief.lastFrame.camera").await.unwrap());
    assert!((own.pitch_deg - now.pitch_deg).abs() < 0.5, "the view jumped from {now:?} to {own:?}");
    let turned = ((own.heading_deg - now.heading_deg + 540.0).rem_euclid(360.0) - 180.0).abs();
    assert!(turned < 10.0, "the view jumped from {now:?} to {own:?}");
    assert_eq!(scene_camera(&channel).await, now, "the drag after unticking moved the scene camera");

    // The screenshot button saves a PNG of the view at full resolution.
    let downloads = tempfile::tempdir().unwrap();
    tab.allow_downloads(downloads.path()).await.unwrap();
    tab.eval("document.getElementById('screenshot').click()").await.unwrap();
    let (w, h) = {
        let size = tab.eval("[window.relief.lastFrame.width, window.relief.lastFrame.height]").await.unwrap();
        (size[0].as_u64().unwrap() as u32, size[1].as_u64().unwrap() as u32)
    };
    let mut saved = None;
    for _ in 0..600 {
        saved = std::fs::read_dir(downloads.path())
            .unwrap()
            .filter_map(Result::ok)
            .map(|e| e.path())
            .find(|p| p.extension().is_some_and(|x| x == "png"));
        if saved.is_some() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let saved = image::open(saved.expect("a screenshot saved within 60 s")).unwrap();
    assert!(saved.width() >= w && saved.height() >= h, "{}x{} against a {w}x{h} view", saved.width(), saved.height());

    // Fly to a source: its whole extent (10..10.5 E, 45..45.5 N, the
    // ground at 500 m at its edges) is in the picture.
    tab.eval("document.querySelector('button[data-fly-to=\"tint\"]').click()").await.unwrap();
    tab.wait_for("Math.abs(window.relief.lastFrame.camera.pitchDeg + 35) < 1e-9", PAGE_TIMEOUT).await.unwrap();
    let corners = tab
        .eval(
            "import('/js/dirty.js').then(m => { const f = window.relief.lastFrame;
               const p = m.projector(f.camera, f.width, f.height);
               return [[10, 45], [10.5, 45], [10, 45.5], [10.5, 45.5]].map(([lon, lat]) => p([lon, lat, 500]))
                 .map(q => q && q[0] >= 0 && q[0] <= f.width && q[1] >= 0 && q[1] <= f.height); })",
        )
        .await
        .unwrap();
    assert_eq!(corners, serde_json::json!([true, true, true, true]), "a corner of the extent is off the picture");

    // Home: back to the manifest's camera.
    tab.eval("document.getElementById('home').click()").await.unwrap();
    tab.wait_for("Math.abs(window.relief.lastFrame.camera.pitchDeg + 45) < 1e-9", PAGE_TIMEOUT).await.unwrap();
    let home = camera_of(&tab.eval("window.relief.lastFrame.camera").await.unwrap());
    assert!((home.lat_deg - 45.1).abs() < 1e-9 && (home.altitude_m - 9000.0).abs() < 1e-6, "{home:?}");
    for page in [&tab, &other] {
        let errors: Vec<String> = page.errors().into_iter().filter(|e| e.starts_with("exception")).collect();
        assert!(errors.is_empty(), "the page threw: {errors:?}");
    }
    drop((tab, other));
    daemon.stop(&[]).unwrap();
}

/// The ground under a camera, through `/api/elevation`.
fn ground_at(url: &str, camera: &serde_json::Value) -> f64 {
    let (lon, lat) = (camera["lonDeg"].as_f64().unwrap_or(0.0), camera["latDeg"].as_f64().unwrap_or(0.0));
    let reply = relief_tests::http::get(&format!("{url}/api/elevation?points={lon},{lat}")).unwrap();
    reply.json().unwrap()["samples"][0]["heightM"].as_f64().unwrap_or(0.0)
}

/// Sets the scene camera over HTTP.
fn put_camera(url: &str, lon: f64, lat: f64, alt: f64, heading: f64, pitch: f64) {
    let body = serde_json::json!({
        "lonDeg": lon, "latDeg": lat, "altitudeM": alt, "headingDeg": heading, "pitchDeg": pitch, "verticalFovDeg": 50.0
    });
    let reply = relief_tests::http::request("PUT", &format!("{url}/api/camera"), Some(&body.to_string())).unwrap();
    assert_eq!(reply.status, 200, "{}", String::from_utf8_lossy(&reply.body));
}

/// A gesture on the scene camera over HTTP; the camera it leaves.
fn navigate(url: &str, gesture: &serde_json::Value) -> serde_json::Value {
    let reply =
        relief_tests::http::request("POST", &format!("{url}/api/navigate"), Some(&gesture.to_string())).unwrap();
    assert_eq!(reply.status, 200, "{gesture}: {}", String::from_utf8_lossy(&reply.body));
    reply.json().unwrap()
}

/// Above the ground under it and within the hill's extent (10..10.5 E,
/// 45..45.5 N) plus the margin (half its larger side, about 0.25 degrees).
fn assert_in_scene(url: &str, camera: &serde_json::Value, what: &str) {
    let ground = ground_at(url, camera);
    let f = |k: &str| camera[k].as_f64().unwrap_or(0.0);
    assert!(
        f("altitudeM") > ground,
        "{what}: the eye at {} m is under the ground at {ground} m: {camera}",
        f("altitudeM")
    );
    assert!(
        (9.7..=10.8).contains(&f("lonDeg")) && (44.7..=45.8).contains(&f("latDeg")),
        "{what}: left the scene: {camera}"
    );
}

#[test]
fn gestures_keep_the_camera_above_the_ground_and_inside_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let url = daemon.url();
    let zoom = serde_json::json!({ "zoom": { "factor": 0.85, "x": 0.5, "y": 0.5 } });

    // Issue 39: low over a slope, nearly level, three wheel notches at the
    // centre sent the camera 100 km off and under the ground.
    put_camera(&url, 10.25, 45.19, 1700.0, 0.0, -2.2);
    for notch in 1..=3 {
        let camera = navigate(&url, &zoom);
        assert_in_scene(&url, &camera, &format!("zoom notch {notch}"));
        let moved_m = (camera["latDeg"].as_f64().unwrap() - 45.19).abs() * 111_320.0;
        assert!(moved_m < 10_000.0, "zoom notch {notch} went {moved_m:.0} m: {camera}");
    }
    // A camera already under the ground comes out with its next gesture.
    put_camera(&url, 10.25, 45.19, 1000.0, 0.0, -2.2);
    assert_in_scene(&url, &navigate(&url, &zoom), "zoom from under the ground");
    // Over the sky, a bounded step.
    put_camera(&url, 10.25, 45.19, 1700.0, 0.0, 30.0);
    let camera = navigate(&url, &zoom);
    assert_in_scene(&url, &camera, "zoom into the sky");

    // An orbit about a point on the hill's southern flank swings the eye
    // round to the north, where the hill is higher than the eye was.
    put_camera(&url, 10.25, 45.12, 1500.0, 0.0, -10.0);
    for (heading, pitch) in [(180.0, 0.0), (90.0, 30.0), (-90.0, -40.0)] {
        let orbit = serde_json::json!({ "orbit": { "headingDeg": heading, "pitchDeg": pitch } });
        assert_in_scene(&url, &navigate(&url, &orbit), &format!("orbit {heading} {pitch}"));
    }

    // Moves keep a minimum step: one press (a tenth of the height above
    // the ground) moves at least 10 m however near the ground the eye is.
    let ground = ground_at(&url, &serde_json::json!({ "lonDeg": 10.25, "latDeg": 45.19 }));
    put_camera(&url, 10.25, 45.19, ground + 11.0, 0.0, -10.0);
    let camera = navigate(&url, &serde_json::json!({ "move": { "forward": 0.1 } }));
    let moved_m = (camera["latDeg"].as_f64().unwrap() - 45.19) * 111_320.0;
    assert!(moved_m >= 9.9, "a press moved {moved_m:.2} m");
    assert_in_scene(&url, &camera, "move");
    // Far moves stop at the scene's margin.
    for _ in 0..20 {
        navigate(&url, &serde_json::json!({ "move": { "forward": 100.0, "up": 100.0 } }));
    }
    assert_in_scene(&url, &navigate(&url, &serde_json::json!({ "move": { "forward": 100.0 } })), "far moves");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn wheel_notches_in_the_page_keep_the_camera_above_the_ground() {
    if !browser::available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let url = daemon.url();
    let page = open(&daemon).await;
    // The tab's own camera low over the slope, nearly level (issue 39).
    let set = "import('/js/hooks.js').then(() => fetch('api/views/' + window.relief.viewId, { method: 'PATCH',
                 headers: { 'content-type': 'application/json' },
                 body: JSON.stringify({ camera: { lonDeg: 10.25, latDeg: 45.19, altitudeM: 1700, pitchDeg: -2.2, verticalFovDeg: 50 } }) }))
               .then(r => r.status)";
    assert_eq!(page.eval(set).await.unwrap(), 200);
    page.wait_for("Math.abs(window.relief.lastFrame.camera.pitchDeg + 2.2) < 1e-9", PAGE_TIMEOUT).await.unwrap();
    let frames = page.eval("window.relief.frames").await.unwrap().as_u64().unwrap();
    for _ in 0..3 {
        page.wheel(380.0, 320.0, -100.0).await.unwrap();
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    page.wait_for(
        &format!("window.relief.frames > {frames} && window.relief.lastFrame.format === 'IMAGE_FORMAT_PNG'"),
        PAGE_TIMEOUT,
    )
    .await
    .unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let camera = page.eval("window.relief.lastFrame.camera").await.unwrap();
    assert_in_scene(&url, &camera, "three wheel notches in the page");
    drop(page);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn six_tabs_show_frames_and_steer_their_own_cameras_and_back_recovers() {
    if !browser::available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let start = scene_camera(&channel).await;
    let first = Browser::start(1000, 640).await.unwrap();
    let mut tabs = vec![];
    // Each in a window of its own: six pages shown at once.
    for _ in 1..6 {
        tabs.push(first.window().await.unwrap());
    }
    tabs.insert(0, first);
    for tab in &tabs {
        tab.navigate(&format!("{}/", daemon.url())).await.unwrap();
    }
    // Every page shows frames at once, and each turns its own camera.
    let heading = "window.relief.lastFrame.camera.headingDeg ?? 0";
    for (i, tab) in tabs.iter().enumerate() {
        tab.wait_for(
            "window.relief && window.relief.framesSinceShow > 0 && document.body.dataset.ready === '1'",
            PAGE_TIMEOUT,
        )
        .await
        .unwrap_or_else(|e| panic!("tab {i}: {e}"));
        let before = tab.eval(heading).await.unwrap().as_f64().unwrap();
        tab.drag((400.0, 300.0), (460.0, 300.0), 4).await.unwrap();
        tab.wait_for(&format!("Math.abs(({heading}) - {before}) > 5"), PAGE_TIMEOUT)
            .await
            .unwrap_or_else(|e| panic!("tab {i} did not turn: {e}"));
    }
    for (i, tab) in tabs.iter().enumerate() {
        let shown =
            tab.eval("document.visibilityState === 'visible' && window.relief.framesSinceShow > 0").await.unwrap();
        assert_eq!(shown, serde_json::json!(true), "tab {i} is hidden or shows no frame");
    }
    assert_eq!(scene_camera(&channel).await, start, "a tab moved the scene camera");
    let views: std::collections::HashSet<String> = {
        let mut ids = std::collections::HashSet::new();
        for tab in &tabs {
            ids.insert(tab.eval("window.relief.viewId").await.unwrap().as_str().unwrap().to_owned());
        }
        ids
    };
    assert_eq!(views.len(), 6, "each tab has a view of its own");

    // Leaving the page and coming back (back, then forward and back again)
    // shows frames again within 2 s.
    let tab = &tabs[5];
    tab.bring_to_front().await.unwrap();
    tab.wait_for("window.relief && window.relief.framesSinceShow > 0", PAGE_TIMEOUT).await.unwrap();
    for round in 0..2 {
        tab.navigate(&format!("{}/api", daemon.url())).await.unwrap();
        tab.wait_for("location.pathname === '/api' && document.readyState === 'complete'", PAGE_TIMEOUT).await.unwrap();
        let left = std::time::Instant::now();
        tab.back().await.unwrap();
        tab.wait_for("!!window.relief && window.relief.framesSinceShow > 0", Duration::from_secs(10))
            .await
            .unwrap_or_else(|e| panic!("round {round}: no frame after coming back: {e}"));
        let took = left.elapsed();
        assert!(took <= Duration::from_secs(2), "round {round}: frames came back after {took:?}");
    }
    for tab in &tabs {
        let errors: Vec<String> = tab.errors().into_iter().filter(|e| e.starts_with("exception")).collect();
        assert!(errors.is_empty(), "a page threw: {errors:?}");
    }
    drop(tabs);
    daemon.stop(&[]).unwrap();
}

#[test]
fn the_page_its_modules_and_its_icon_are_served_with_their_types() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scenes::hill(dir.path(), "").unwrap(), &[]).unwrap();
    let url = daemon.url();
    let page = relief_tests::http::get(&format!("{url}/")).unwrap();
    let html = String::from_utf8(page.body).unwrap();
    assert!(html.contains(r#"<script type="module" src="viewer.js">"#) && html.contains("favicon.svg"), "{html}");
    for (path, kind) in [
        ("/viewer.js", "text/javascript"),
        ("/js/stream.js", "text/javascript"),
        ("/js/camera.js", "text/javascript"),
        ("/js/panel.js", "text/javascript"),
        ("/favicon.svg", "image/svg+xml"),
    ] {
        let reply = relief_tests::http::get(&format!("{url}{path}")).unwrap();
        assert_eq!(reply.status, 200, "{path}");
        assert!(reply.content_type.starts_with(kind), "{path} is served as {}", reply.content_type);
    }
    daemon.stop(&[]).unwrap();
}
