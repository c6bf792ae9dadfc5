//! The `detail` effect: synthesized samples below a DEM's resolution change
//! what is drawn and never what GetTile or SampleElevation answer; the
//! same every frame; its octaves a knob; the state says it is on.

#![allow(clippy::unwrap_used, reason = "a test")]

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::{fixtures, scenes};

const SIZE: (u32, u32) = (160, 100);

/// The hill with a metre or so of rough ground at every sample (a hash of
/// the place): a spectrum the detail's noise is fitted to.
fn rough_hill(lon: f64, lat: f64) -> f64 {
    let h = ((lon * 12.9898 + lat * 78.233).sin() * 43_758.545).fract();
    fixtures::hill(lon, lat) + 3.0 * h
}

/// Low over the hill's flank, looking across it.
fn close() -> pb::Camera {
    scenes::camera(10.25, 45.17, rough_hill(10.25, 45.17) + 60.0, 0.0, -20.0)
}

struct Seen {
    frames: Vec<pb::RenderResponse>,
    state: pb::SceneState,
    tile: pb::GetTileResponse,
    elevation: pb::SampleElevationResponse,
}

async fn seen(effects: &str, octaves: &[Option<u32>]) -> Seen {
    let dir = tempfile::tempdir().unwrap();
    let manifest = scenes::hill(dir.path(), effects).unwrap();
    fixtures::write_dem(&dir.path().join("hill.tif"), &fixtures::hill_spec(), rough_hill).unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let mut frames = Vec::new();
    for o in octaves {
        let request = pb::RenderRequest {
            camera: Some(close()),
            width: SIZE.0,
            height: SIZE.1,
            format: pb::ImageFormat::Rgba8 as i32,
            quality: o.map(|d| pb::QualityOverrides { detail_octaves: Some(d), ..Default::default() }),
            sun: None,
        };
        let mut views = ViewServiceClient::new(channel.clone()).max_decoding_message_size(64 << 20);
        frames.push(views.render(request).await.unwrap().into_inner());
    }
    // The finest tile under the camera.
    let key = relief_source::TileGrid::geodetic(256).unwrap().key_at(12, 10.25, 45.17).unwrap();
    let tile = relief_tests::tiles::get(channel.clone(), "dem", (12, key.x, key.y)).await.unwrap();
    let elevation = TileServiceClient::new(channel.clone())
        .sample_elevation(pb::SampleElevationRequest {
            points: vec![pb::GeodeticPoint { lon_deg: 10.2513, lat_deg: 45.1702 }],
            source_id: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    let state = SceneServiceClient::new(channel).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    daemon.stop(&[]).unwrap();
    Seen { frames, state, tile, elevation }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn detail_changes_what_is_drawn_and_never_the_data() {
    let off = seen("[effects]\nlighting = {}\n", &[None]).await;
    let on = seen("[effects]\nlighting = {}\ndetail = {}\n", &[None, None, Some(4)]).await;

    // Drawn: the frames differ; the same every frame; the octaves a knob.
    let (a, b) = (&off.frames[0], &on.frames[0]);
    let changed = a.image.chunks(4).zip(b.image.chunks(4)).filter(|(p, q)| p != q).count();
    assert!(changed > (SIZE.0 * SIZE.1 / 4) as usize, "detail changed {changed} pixels");
    assert_eq!(on.frames[0].image, on.frames[1].image, "detail is not deterministic");
    assert_ne!(on.frames[2].image, on.frames[0].image, "4 octaves drew what 2 did");

    // Never the data: the same tile bytes and the same elevation.
    assert_eq!(on.tile.content_hash, off.tile.content_hash);
    let bits =
        |t: &pb::GetTileResponse| relief_tests::tiles::heights(t).iter().map(|h| h.to_bits()).collect::<Vec<_>>();
    assert!(relief_tests::tiles::heights(&on.tile).iter().all(|h| h.is_finite()));
    assert_eq!(bits(&on.tile), bits(&off.tile));
    assert_eq!(on.elevation.samples[0].height_m, off.elevation.samples[0].height_m);

    // The state says synthesized detail is on, and ran.
    let effect = on.state.effects.iter().find(|e| e.name == "detail").unwrap();
    assert!(effect.ran, "{effect:?}");
    assert_eq!(on.state.quality.get("detail_octaves").map(String::as_str), Some("2"));
    assert!(off.state.effects.iter().all(|e| e.name != "detail"));
    assert!(!off.state.quality.contains_key("detail_octaves"));
}

#[test]
fn bad_detail_declarations_are_refused() {
    for (effects, message) in [
        ("[effects]\ndetail = { octaves = 3 }\n", "effects.detail.octaves"),
        ("[quality]\ndetail_octaves = 2\n", "declares no detail"),
        ("[effects]\ndetail = {}\n[quality]\ndetail_octaves = 0\n", "quality.detail_octaves"),
        ("[effects]\ndetail = {}\n[quality]\ndetail_octaves = 7\n", "quality.detail_octaves"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let (code, text) = relief_tests::daemon::check(&scenes::hill(dir.path(), effects).unwrap()).unwrap();
        assert_ne!(code, 0, "{effects}: accepted");
        assert!(text.contains(message) && text.contains("scene.toml"), "{effects}: {text}");
    }
}
