//! SetSourceParameter against a real reliefd: a source's option, a
//! `[quality]` knob and an effect's option, through gRPC, HTTP and the CLI;
//! each checked as the manifest checks it (refused with the manifest's
//! words, the scene kept), each a new generation that dirties exactly what
//! it touches, and the value in force shown in the state beside the
//! manifest's.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::Path;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::{Reliefd, relief};
use relief_tests::edit::{Events, tile_hash, version};
use relief_tests::{fixtures, http, scenes};
use tonic::transport::Channel;

/// A level-9 tile over the hill.
const TILE: (u32, u32, u32) = (9, 541, 127);

fn scene(dir: &Path) -> std::path::PathBuf {
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    let parcels = relief_tests::vectors::squares(&[(r#"{"name": "a"}"#, 10.2, 45.2, 0.05)]);
    relief_tests::vectors::shapefile(dir, "parcels", &parcels).unwrap();
    fixtures::write_manifest(
        dir,
        "[scene]\nname = \"what-if\"\n\n\
         [[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n\
         [[source]]\nid = \"shade\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\nazimuth_deg = 315\n\n\
         [[source]]\nid = \"parcels\"\nkind = \"shapefile\"\npath = \"parcels.shp\"\n\n\
         [[source]]\nid = \"drawn\"\nkind = \"rasterize\"\ninputs = [\"parcels\"]\nfill = \"#ff000080\"\n\n\
         [[source]]\nid = \"map\"\nkind = \"overlay\"\ninputs = [\"shade\", \"drawn\"]\n\n\
         [layers]\nheight = \"dem\"\ncolor = \"map\"\n\n\
         [effects]\nlighting = {}\nfog = { density = 0.0003 }\n\n\
         [camera]\nlon_deg = 10.25\nlat_deg = 45.1\naltitude_m = 9000\npitch_deg = -45\n",
    )
    .unwrap()
}

async fn set(channel: &Channel, target: &str, name: &str, value: &str) -> Result<pb::SceneState, tonic::Status> {
    let request = pb::SetSourceParameterRequest {
        source_id: target.into(),
        name: name.into(),
        value: value.into(),
        reset: false,
    };
    SceneServiceClient::new(channel.clone()).set_source_parameter(request).await.map(tonic::Response::into_inner)
}

async fn hashes(channel: &Channel) -> Vec<u64> {
    let mut out = Vec::new();
    for id in ["dem", "shade", "parcels", "drawn", "map"] {
        out.push(tile_hash(channel.clone(), id, TILE).await.unwrap());
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_source_option_is_checked_as_the_manifest_checks_it_and_dirties_only_what_it_touches() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path()), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let before = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let [dem, shade, parcels, drawn, map] = hashes(&channel).await[..] else { unreachable!() };

    // The hillshade's sun from the east: shade is new, and map over it;
    // the DEM and the parcels are untouched.
    let after = set(&channel, "shade", "azimuth_deg", "90").await.unwrap();
    assert_eq!(after.generation, before.generation + 1);
    let event = events.generation(after.generation).await.unwrap();
    assert_eq!(event.changed_sources, ["shade"], "{event:?}");
    let dirty: Vec<&str> = event.dirty.iter().filter(|d| !d.extents.is_empty()).map(|d| d.source_id.as_str()).collect();
    assert!(dirty.contains(&"shade") && dirty.contains(&"map") && !dirty.contains(&"dem"), "{dirty:?}");
    assert!(!dirty.contains(&"drawn") && !dirty.contains(&"parcels"), "{dirty:?}");
    for id in ["dem", "parcels", "drawn"] {
        assert_eq!(version(&after, id), version(&before, id), "{id}");
    }
    let now = hashes(&channel).await;
    assert_eq!((now[0], now[2], now[3]), (dem, parcels, drawn), "untouched tiles are the same");
    assert_ne!(now[1], shade, "the shade is lit from the east now");
    assert_ne!(now[4], map);
    let shown = after.parameters.iter().find(|p| p.target == "shade").unwrap();
    assert_eq!(
        (shown.name.as_str(), shown.value.as_str(), shown.manifest_value.as_deref()),
        ("azimuth_deg", "90", Some("315"))
    );
    assert_eq!(shown.origin, "call");

    // Refused as the manifest refuses it, and the scene stays.
    let refused = set(&channel, "shade", "azimuth_deg", "\"east\"").await.unwrap_err();
    assert_eq!(refused.code(), tonic::Code::InvalidArgument);
    assert!(refused.message().contains("source 'shade'") && refused.message().contains("azimuth_deg"), "{refused:?}");
    let refused = set(&channel, "shade", "colour", "1").await.unwrap_err();
    assert!(refused.message().contains("unknown option"), "{refused:?}");
    let refused = set(&channel, "dem", "path", "\"other.tif\"").await.unwrap_err();
    assert!(refused.message().contains("chooses what the source reads"), "{refused:?}");
    assert_eq!(set(&channel, "nope", "x", "1").await.unwrap_err().code(), tonic::Code::NotFound);
    let kept = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    assert_eq!(kept.generation, after.generation, "a refused value makes no generation");

    // Through HTTP: the rasterize fill; only drawn (and map over it) change.
    let body = r##"{"sourceId": "drawn", "name": "fill", "value": "#0000ffff"}"##;
    let reply = http::request("POST", &format!("{}/api/parameters", daemon.url()), Some(body)).unwrap();
    let state = reply.json().unwrap();
    assert_eq!(state["generation"].as_str().unwrap().parse::<u64>().unwrap(), kept.generation + 1, "{state}");
    let event = events.generation(kept.generation + 1).await.unwrap();
    assert_eq!(event.changed_sources, ["drawn"], "{event:?}");
    let later = hashes(&channel).await;
    assert_eq!((later[0], later[1], later[2]), (now[0], now[1], now[2]));
    assert_ne!(later[3], now[3]);

    // Reset: the manifest's value back.
    let reset = pb::SetSourceParameterRequest {
        source_id: "shade".into(),
        name: "azimuth_deg".into(),
        reset: true,
        ..Default::default()
    };
    let back = SceneServiceClient::new(channel.clone()).set_source_parameter(reset).await.unwrap().into_inner();
    assert!(back.parameters.iter().all(|p| p.target != "shade"));
    assert_eq!(hashes(&channel).await[1], shade, "the manifest's shade again");
    daemon.stop(&[]).unwrap();
}

async fn frame(channel: &Channel, camera: pb::Camera) -> Vec<u8> {
    scenes::render_rgba(channel, camera, (160, 90)).await.unwrap().image.to_vec()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn quality_knobs_and_effect_options_set_from_the_cli_change_only_what_they_draw() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path()), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let camera = scenes::camera(10.25, 45.1, 9000.0, 0.0, -45.0);
    let before_frame = frame(&channel, camera).await;
    let before = hashes(&channel).await;

    // An effect's option: a new generation that dirties no tile, and a
    // frame that shows it.
    let (code, out, err) = relief(&daemon, &["set", "[effects.fog]", "density", "0.004"]).unwrap();
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("[effects.fog] density = 0.004 (set by a call; the manifest: 0.0003)"), "{out}");
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let event = events.generation(state.generation).await.unwrap();
    assert!(event.changed_sources.is_empty() && event.dirty.iter().all(|d| d.extents.is_empty()), "{event:?}");
    assert_eq!(hashes(&channel).await, before, "no tile changes for fog");
    assert_ne!(frame(&channel, camera).await, before_frame, "the fog is thicker");

    // A quality knob: the tiles it makes are made again with it.
    let (code, _, err) = relief(&daemon, &["set", "[quality]", "resampling", "nearest"]).unwrap();
    assert_eq!(code, 0, "{err}");
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    assert_eq!(state.quality["resampling"], "nearest");
    assert_ne!(hashes(&channel).await[1], before[1], "the shade resampled");

    // Refused with the manifest's words, naming the knob; exit code 1.
    let (code, _, err) = relief(&daemon, &["set", "[quality]", "resampling", "blurry"]).unwrap();
    assert_ne!(code, 0);
    assert!(err.contains("resampling") && err.contains("blurry"), "{err}");
    let (code, _, err) = relief(&daemon, &["set", "[effects.water]", "level_m", "3"]).unwrap();
    assert_ne!(code, 0);
    assert!(err.contains("effect 'water' is not in this scene's [effects]"), "{err}");
    let (code, _, err) = relief(&daemon, &["set", "[cache]", "memory_mb", "3"]).unwrap();
    assert_ne!(code, 0);
    assert!(err.contains("not a section a call may set"), "{err}");

    // A manifest edit keeps the call's value in force over it.
    let manifest = dir.path().join("scene.toml");
    let text = std::fs::read_to_string(&manifest).unwrap().replace("azimuth_deg = 315", "azimuth_deg = 300");
    std::fs::write(&manifest, text).unwrap();
    let edited = relief_tests::edit::wait_for(channel.clone(), state.generation + 1).await.unwrap();
    assert_eq!(edited.quality["resampling"], "nearest");
    assert!(edited.parameters.iter().any(|p| p.target == "[effects.fog]" && p.value == "0.004"));
    daemon.stop(&["parameter refused"]).unwrap();
}
