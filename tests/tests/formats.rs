//! Every raster GDAL opens is a source: the same terrain as GeoTIFF, ESRI
//! ASCII grid, VRT and in feet gives the same heights in metres.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::fmt::Write as _;
use std::process::Command;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::fixtures::{self, Lcg};

fn gdal_translate(args: &[&str]) {
    let out = Command::new("gdal_translate").arg("-q").args(args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn formats_and_units_give_the_same_heights() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    fixtures::write_dem(&dir.path().join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    gdal_translate(&["-of", "AAIGrid", &d("hill.tif"), &d("hill.asc")]);
    gdal_translate(&["-of", "VRT", &d("hill.tif"), &d("hill.vrt")]);
    // The same hill in feet, saying so in the band's unit type.
    let feet = fixtures::hill_spec();
    fixtures::write_dem(&dir.path().join("feet.tif"), &feet, |lon, lat| fixtures::hill(lon, lat) / 0.3048).unwrap();
    gdal_translate(&["-of", "VRT", "-a_srs", "EPSG:4326", &d("feet.tif"), &d("feet.vrt")]);
    let vrt = std::fs::read_to_string(d("feet.vrt")).unwrap();
    std::fs::write(d("feet.vrt"), vrt.replacen("</ColorInterp>", "</ColorInterp>\n    <UnitType>ft</UnitType>", 1))
        .unwrap();

    let mut manifest = String::from("[scene]\nname = \"formats\"\n");
    for (id, file) in [("tif", "hill.tif"), ("asc", "hill.asc"), ("vrt", "hill.vrt"), ("feet", "feet.vrt")] {
        let _ =
            write!(manifest, "\n[[source]]\nid = \"{id}\"\nkind = \"gdal\"\npath = \"{file}\"\ncrs = \"EPSG:4326\"\n");
    }
    let daemon = Reliefd::start(&fixtures::write_manifest(dir.path(), &manifest).unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let driver = |id: &str| state.sources.iter().find(|s| s.id == id).unwrap().details["driver"].clone();
    assert_eq!((driver("tif"), driver("asc"), driver("vrt")), ("GTiff".into(), "AAIGrid".into(), "VRT".into()));
    let feet_state = state.sources.iter().find(|s| s.id == "feet").unwrap();
    assert!(feet_state.vertical_units.contains("ft"), "{}", feet_state.vertical_units);

    let mut rng = Lcg(99);
    let points: Vec<pb::GeodeticPoint> = (0..20)
        .map(|_| pb::GeodeticPoint { lon_deg: rng.range(10.01, 10.49), lat_deg: rng.range(45.01, 45.49) })
        .collect();
    let mut tiles = TileServiceClient::new(channel);
    let mut answers = Vec::new();
    for id in ["tif", "asc", "vrt", "feet"] {
        let a = tiles
            .sample_elevation(pb::SampleElevationRequest { points: points.clone(), source_id: id.into() })
            .await
            .unwrap()
            .into_inner();
        answers.push(a.samples.into_iter().map(|s| s.height_m.unwrap()).collect::<Vec<f64>>());
    }
    for (n, p) in points.iter().enumerate() {
        let want = fixtures::hill(p.lon_deg, p.lat_deg);
        // ASCII grids print 6 significant digits or so; feet go through f32.
        for (id, answer, tolerance) in [
            ("tif", &answers[0], 0.1),
            ("asc", &answers[1], 0.15),
            ("vrt", &answers[2], 0.1),
            ("feet", &answers[3], 0.15),
        ] {
            assert!((answer[n] - want).abs() < tolerance, "{id} at {p:?}: {} vs analytic {want}", answer[n]);
        }
        assert_eq!(answers[0][n], answers[2][n], "a VRT of the GeoTIFF reads the same bytes");
    }
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn watch_streams_a_snapshot_then_generations_and_errors() {
    use tokio_stream::StreamExt;
    let dir = tempfile::tempdir().unwrap();
    let file = fixtures::write_dem(&dir.path().join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"watched\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"",
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let mut scene = SceneServiceClient::new(daemon.channel().await.unwrap());
    let mut events = scene.watch(pb::WatchRequest { from_generation: 0 }).await.unwrap().into_inner();
    let first = events.next().await.unwrap().unwrap();
    assert!(matches!(first.event, Some(pb::scene_event::Event::Snapshot(ref s)) if s.generation == 1), "{first:?}");

    std::fs::write(&file, b"broken").unwrap();
    let error =
        tokio::time::timeout(std::time::Duration::from_secs(20), events.next()).await.unwrap().unwrap().unwrap();
    match error.event {
        Some(pb::scene_event::Event::SourceError(e)) => {
            assert_eq!(e.source_id, "dem");
            assert!(e.kept_last_good && e.error.contains("hill.tif"), "{e:?}");
        }
        other => panic!("expected a source error, got {other:?}"),
    }
    fixtures::write_dem(&file, &fixtures::hill_spec(), |lon, lat| fixtures::hill(lon, lat) + 1.0).unwrap();
    // The error event came with its own generation; the recovery is the next data change.
    loop {
        let e =
            tokio::time::timeout(std::time::Duration::from_secs(20), events.next()).await.unwrap().unwrap().unwrap();
        if let Some(pb::scene_event::Event::GenerationChanged(g)) = e.event
            && g.changed_sources == ["dem"]
        {
            assert!(e.generation >= 3, "{g:?}");
            assert_eq!(g.dirty.len(), 1);
            let x = &g.dirty[0].extents[0];
            assert!((x.min_x - 10.0).abs() < 1e-9 && (x.max_y - 45.5).abs() < 1e-9, "{x:?}");
            break;
        }
    }
    daemon.stop(&["keeping the last good version"]).unwrap();
}
