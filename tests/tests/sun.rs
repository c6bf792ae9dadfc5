//! The sun lights the scene where `[sun]`, a render request or a stream
//! puts it: the slope facing it is the bright one, night is dark (and a
//! number, not NaN), and every frame says which sun lit it.

#![allow(clippy::unwrap_used, reason = "a test")]

use relief_proto::v1 as pb;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::scenes;
use tokio_stream::StreamExt;

const SIZE: (u32, u32) = (160, 160);

/// Straight down over the hill's top, north up.
fn above_the_hill() -> pb::Camera {
    scenes::camera(10.25, 45.25, 40_000.0, 0.0, -90.0)
}

async fn render(channel: &tonic::transport::Channel, sun: Option<pb::Sun>) -> pb::RenderResponse {
    let request = pb::RenderRequest {
        camera: Some(above_the_hill()),
        width: SIZE.0,
        height: SIZE.1,
        format: pb::ImageFormat::Rgba8 as i32,
        quality: None,
        sun,
    };
    ViewServiceClient::new(channel.clone())
        .max_decoding_message_size(64 << 20)
        .render(request)
        .await
        .unwrap()
        .into_inner()
}

/// Mean brightness (0..255) of the image's east and west halves.
fn halves(frame: &pb::RenderResponse) -> (f64, f64) {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let (mut east, mut west) = (0.0, 0.0);
    for y in 0..h {
        for x in 0..w {
            let p = &frame.image[(y * w + x) * 4..(y * w + x) * 4 + 3];
            let v = p.iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0;
            if x < w / 2 { west += v } else { east += v }
        }
    }
    let n = (w * h / 2) as f64;
    (east / n, west / n)
}

fn fixed(azimuth_deg: f64, elevation_deg: f64) -> pb::Sun {
    pb::Sun { azimuth_deg: Some(azimuth_deg), elevation_deg: Some(elevation_deg), ..Default::default() }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_slope_facing_the_sun_is_the_bright_one_and_night_is_dark() {
    let dir = tempfile::tempdir().unwrap();
    // The scene's sun: 21 June, 07:00 in Italy (the morning sun, east-north-east).
    let manifest =
        scenes::hill(dir.path(), "[effects]\nlighting = {}\n[sun]\ntime = \"2026-06-21T07:00:00+02:00\"\n").unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();

    let morning = render(&channel, None).await;
    let sun = morning.sun.clone().unwrap();
    assert!(sun.source.contains("2026-06-21T07:00:00+02:00"), "{sun:?}");
    assert!((50.0..90.0).contains(&sun.azimuth_deg) && (10.0..30.0).contains(&sun.elevation_deg), "{sun:?}");
    let (east, west) = halves(&morning);
    assert!(east > west + 5.0, "morning: east {east:.1}, west {west:.1}");

    // A request's own sun, low in the west: the other slope.
    let evening = render(&channel, Some(fixed(270.0, 20.0))).await;
    assert_eq!(evening.sun.as_ref().unwrap().azimuth_deg, 270.0);
    let (east_pm, west_pm) = halves(&evening);
    assert!(west_pm > east_pm + 5.0, "evening: east {east_pm:.1}, west {west_pm:.1}");

    // Night (01:00): the sun under the horizon, a dark scene, not black
    // NaNs; and just under the horizon the light fades, it does not jump.
    let night =
        render(&channel, Some(pb::Sun { time: "2026-06-21T01:00:00+02:00".into(), ..Default::default() })).await;
    assert!(night.sun.as_ref().unwrap().elevation_deg < -10.0, "{:?}", night.sun);
    let (e_night, w_night) = halves(&night);
    let day = f64::midpoint(east, west);
    assert!(f64::midpoint(e_night, w_night) < day / 3.0, "night {e_night:.1}/{w_night:.1} against day {day:.1}");
    assert!(e_night > 1.0 && w_night > 1.0, "night terrain is dim, still drawn: {e_night:.1}/{w_night:.1}");
    assert!((e_night - w_night).abs() < 1.0, "no side lit at night: {e_night:.1}/{w_night:.1}");
    let dusk = render(&channel, Some(fixed(300.0, -0.1))).await;
    let (e_dusk, w_dusk) = halves(&dusk);
    assert!(e_dusk > e_night && e_dusk < day, "dusk {e_dusk:.1} between night {e_night:.1} and day {day:.1}");
    assert!(w_dusk > e_night && w_dusk < day, "dusk {w_dusk:.1}");
    // The sun at the zenith: both slopes alike.
    let (e_zen, w_zen) = halves(&render(&channel, Some(fixed(0.0, 90.0))).await);
    assert!((e_zen - w_zen).abs() < 3.0, "zenith: east {e_zen:.1}, west {w_zen:.1}");

    // A stream with its own sun: every frame lit by it.
    let request = pb::StreamFramesRequest {
        width: SIZE.0,
        height: SIZE.1,
        camera: Some(above_the_hill()),
        sun: Some(fixed(180.0, 30.0)),
        ..Default::default()
    };
    let mut stream = ViewServiceClient::new(channel.clone())
        .max_decoding_message_size(64 << 20)
        .stream_frames(request)
        .await
        .unwrap()
        .into_inner();
    let frame =
        tokio::time::timeout(std::time::Duration::from_secs(60), stream.next()).await.unwrap().unwrap().unwrap();
    let sun = frame.sun.unwrap();
    assert_eq!((sun.azimuth_deg, sun.elevation_deg), (180.0, 30.0));
    assert!(sun.source.starts_with("fixed"), "{}", sun.source);
    daemon.stop(&[]).unwrap();
}

#[test]
fn a_sun_the_manifest_cannot_place_is_refused_by_field() {
    for (sun, field) in [
        ("time = \"2026-06-21T15:00:00\"\n", "sun.time"),
        ("time = \"tomorrow\"\n", "sun.time"),
        ("time = \"2026-06-21T15:00:00Z\"\nazimuth_deg = 10\n", "sun.time"),
        ("azimuth_deg = 10\n", "sun.elevation_deg"),
        ("azimuth_deg = 10\nelevation_deg = 100\n", "sun.elevation_deg"),
        ("colour = \"red\"\n", "colour"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let manifest = scenes::hill(dir.path(), &format!("[sun]\n{sun}")).unwrap();
        let (code, text) = relief_tests::daemon::check(&manifest).unwrap();
        assert_ne!(code, 0, "{sun}: accepted");
        assert!(text.contains(field), "{sun}: {text}");
        assert!(text.contains("scene.toml"), "{sun}: names the file: {text}");
    }
}
