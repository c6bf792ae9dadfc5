//! The spine end to end: a real reliefd on loopback serves heights that
//! agree with GDAL's own reading of the same file and with the analytic
//! terrain the fixture was made from.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_tests::daemon::{Reliefd, relief};
use relief_tests::fixtures::{self, Lcg};
use relief_tests::reference;
use relief_tests::tiles;

fn hill_scene(dir: &std::path::Path, extra: &str) -> std::path::PathBuf {
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    fixtures::write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"hill\"\ngrid = \"geodetic\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n\
             [[source]]\nid = \"shade\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\n\n[layers]\nheight = \"dem\"\ncolor = \"shade\"\n{extra}"
        ),
    )
    .unwrap()
}

async fn tile(
    client: &mut TileServiceClient<tonic::transport::Channel>,
    source: &str,
    level: u32,
    x: u32,
    y: u32,
) -> pb::GetTileResponse {
    client
        .get_tile(pb::GetTileRequest {
            source_id: source.into(),
            key: Some(pb::TileKey { level, x, y }),
            quality: None,
        })
        .await
        .unwrap()
        .into_inner()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tile_heights_match_gdal_and_the_analytic_hill() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = hill_scene(dir.path(), "");
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let mut tiles = TileServiceClient::new(daemon.channel().await.unwrap());

    // Level 10 tile 1082/254 holds the peak; its samples are 0.55 source
    // pixels apart. (At coarser levels gdalwarp widens its kernel while
    // relief reads a mip level, so the two smooth differently there.)
    let t = tile(&mut tiles, "dem", 10, 1082, 254).await;
    assert_eq!((t.width, t.height), (257, 257));
    assert_eq!(t.crs, "EPSG:4326");
    let e = t.extent.unwrap();
    let got = tiles::heights(&t);
    let want = reference::gdal_lattice(
        &dir.path().join("hill.tif"),
        [e.min_x, e.min_y, e.max_x, e.max_y],
        257,
        "EPSG:4326",
        "bilinear",
        dir.path(),
    )
    .unwrap();
    let step = (e.max_x - e.min_x) / 256.0;
    let mut compared = 0;
    for j in 0..257 {
        for i in 0..257 {
            let (g, w) = (got[j * 257 + i], want[j * 257 + i]);
            assert_eq!(g.is_nan(), w.is_nan(), "nodata differs from GDAL at sample ({i}, {j}): {g} vs {w}");
            if g.is_nan() {
                continue;
            }
            // Against GDAL: 1 cm. Against the analytic hill: bilinear error is
            // at most |h''| d^2 / 8 ~ 5 cm here; 10 cm stated.
            assert!((f64::from(g) - w).abs() < 0.01, "({i}, {j}): relief {g} vs GDAL {w}");
            let (lon, lat) = (e.min_x + i as f64 * step, e.max_y - j as f64 * step);
            assert!(
                (f64::from(g) - fixtures::hill(lon, lat)).abs() < 0.1,
                "({i}, {j}): relief {g} vs analytic {}",
                fixtures::hill(lon, lat)
            );
            compared += 1;
        }
    }
    assert!(compared > 40_000, "only {compared} samples had data");

    // Coarse levels cover the data with no holes and stay within the terrain's range.
    for (level, x, y) in [(4u32, 16u32, 3u32), (6, 65, 15)] {
        let t = tile(&mut tiles, "dem", level, x, y).await;
        let e = t.extent.unwrap();
        let step = (e.max_x - e.min_x) / 256.0;
        for (n, h) in tiles::heights(&t).iter().enumerate() {
            let (lon, lat) = (e.min_x + (n % 257) as f64 * step, e.max_y - (n / 257) as f64 * step);
            let inside = (10.0 + step..10.5 - step).contains(&lon) && (45.0 + step..45.5 - step).contains(&lat);
            if inside {
                assert!((499.0..=2001.0).contains(h), "level {level} sample at {lon},{lat}: {h}");
            }
        }
    }
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn elevations_match_gdal_bilinear_within_a_centimetre() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = hill_scene(dir.path(), "");
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let mut tiles = TileServiceClient::new(daemon.channel().await.unwrap());
    let mut rng = Lcg(7);
    let points: Vec<pb::GeodeticPoint> = (0..20)
        .map(|_| pb::GeodeticPoint { lon_deg: rng.range(10.01, 10.49), lat_deg: rng.range(45.01, 45.49) })
        .chain([pb::GeodeticPoint { lon_deg: 12.0, lat_deg: 45.2 }])
        .collect();
    let answer = tiles
        .sample_elevation(pb::SampleElevationRequest { points: points.clone(), source_id: String::new() })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(answer.source_id, "dem");
    assert_eq!(answer.samples.len(), points.len());
    for (p, s) in points.iter().zip(&answer.samples).take(20) {
        let got = s.height_m.expect("the point is inside the DEM");
        let gdal = reference::gdal_value_at(&dir.path().join("hill.tif"), p.lon_deg, p.lat_deg, "bilinear", dir.path())
            .unwrap()
            .unwrap();
        assert!((got - gdal).abs() < 0.01, "{p:?}: relief {got} vs GDAL {gdal}");
        assert!((got - fixtures::hill(p.lon_deg, p.lat_deg)).abs() < 0.1, "{p:?}: relief {got} vs analytic");
    }
    assert_eq!(answer.samples[20].height_m, None, "a point off the DEM has no height");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn projected_scene_serves_utm_heights() {
    let dir = tempfile::tempdir().unwrap();
    let spec = fixtures::utm_spec();
    let dem = fixtures::write_dem(&dir.path().join("utm.tif"), &spec, fixtures::utm_surface).unwrap();
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"utm\"\ngrid = { crs = \"EPSG:32612\" }\ntile_size = 64\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"utm.tif\"\n\n[layers]\nheight = \"dem\"\n",
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let state = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let grid = state.grid.unwrap();
    assert_eq!((grid.kind.as_str(), grid.crs.as_str(), grid.level0_columns), ("projected", "EPSG:32612", 1));
    let g = grid.extent.unwrap();
    // Derived from the data: 9000 m wide, so the level-0 square is 9000 m.
    assert_eq!((g.min_x, g.max_x - g.min_x), (300_000.0, 9000.0));

    let mut tiles = TileServiceClient::new(channel);
    // Level 3: samples 17.6 m apart over 30 m pixels.
    let t = tile(&mut tiles, "dem", 3, 3, 4).await;
    assert_eq!((t.width, t.crs.as_str()), (65, "EPSG:32612"));
    let e = t.extent.unwrap();
    let want =
        reference::gdal_lattice(&dem, [e.min_x, e.min_y, e.max_x, e.max_y], 65, "EPSG:32612", "bilinear", dir.path())
            .unwrap();
    for (n, (g, w)) in tiles::heights(&t).iter().zip(&want).enumerate() {
        assert_eq!(g.is_nan(), w.is_nan(), "sample {n}: {g} vs {w}");
        if !g.is_nan() {
            assert!((f64::from(*g) - w).abs() < 0.01, "sample {n}: relief {g} vs GDAL {w}");
        }
    }

    // Elevations at lon/lat go through PROJ to UTM and agree with gdalwarp.
    // Random points inside the DEM, taken to lon/lat by PROJ (through GDAL).
    let mut rng = Lcg(3);
    let xs: Vec<f64> = (0..20).map(|_| rng.range(300_100.0, 308_900.0)).collect();
    let ys: Vec<f64> = (0..20).map(|_| rng.range(5_100_100.0, 5_105_900.0)).collect();
    let points = reference::lon_lat_points("EPSG:32612", &xs, &ys).unwrap();
    let answer = tiles
        .sample_elevation(pb::SampleElevationRequest { points: points.clone(), source_id: "dem".into() })
        .await
        .unwrap()
        .into_inner();
    for (p, s) in points.iter().zip(&answer.samples) {
        let gdal = reference::gdal_value_at(&dem, p.lon_deg, p.lat_deg, "bilinear", dir.path()).unwrap();
        match (s.height_m, gdal) {
            (Some(got), Some(want)) => assert!((got - want).abs() < 0.01, "{p:?}: relief {got} vs GDAL {want}"),
            (got, want) => panic!("{p:?}: relief {got:?} vs GDAL {want:?}"),
        }
    }
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn nodata_is_never_interpolated_into_heights() {
    let dir = tempfile::tempdir().unwrap();
    let mut spec = fixtures::hill_spec();
    spec.nodata = Some(-9999.0);
    // A square void of 40 x 40 pixels on the hill's flank, and a one-pixel void.
    fixtures::write_dem(&dir.path().join("hill.tif"), &spec, |lon, lat| {
        let in_void = (10.30..10.35).contains(&lon) && (45.20..45.25).contains(&lat);
        let pinhole = (lon - 10.1006).abs() < 0.0006 && (lat - 45.1006).abs() < 0.0006;
        if in_void || pinhole { -9999.0 } else { fixtures::hill(lon, lat) }
    })
    .unwrap();
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"holes\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n[layers]\nheight = \"dem\"\n",
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let mut tiles = TileServiceClient::new(daemon.channel().await.unwrap());
    // Every level from coarse to finer than the source.
    let mut voids = 0;
    for level in [5u32, 8, 9, 10, 11] {
        let n = 1u32 << level;
        let span = 180.0 / f64::from(n);
        let (x, y) = (((10.325 + 180.0) / span) as u32, ((90.0 - 45.225) / span) as u32);
        for h in tiles::heights(&tile(&mut tiles, "dem", level, x, y).await) {
            if h.is_nan() {
                voids += 1;
            } else {
                assert!((499.0..=2001.0).contains(&h), "level {level}: a height of {h} m leaked from the -9999 nodata");
            }
        }
    }
    assert!(voids > 0, "the void shows as nodata at fine levels");
    let answer = tiles
        .sample_elevation(pb::SampleElevationRequest {
            points: vec![
                pb::GeodeticPoint { lon_deg: 10.325, lat_deg: 45.225 },
                pb::GeodeticPoint { lon_deg: 10.1006, lat_deg: 45.1006 },
                pb::GeodeticPoint { lon_deg: 10.2, lat_deg: 45.4 },
            ],
            source_id: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(answer.samples[0].height_m, None, "inside the void");
    assert_eq!(answer.samples[1].height_m, None, "on the one-pixel void");
    assert!(answer.samples[2].height_m.is_some());
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hillshade_tiles_share_their_border_texels() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = hill_scene(dir.path(), "[effects]\nlighting = {}\n");
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let mut tiles = TileServiceClient::new(daemon.channel().await.unwrap());
    let (a, b) = (tile(&mut tiles, "shade", 9, 541, 127).await, tile(&mut tiles, "shade", 9, 542, 127).await);
    let (a, b) = (tiles::image(&a), tiles::image(&b));
    assert_eq!(a.width(), 258);
    // a's east border texel is b's first core texel, and the other way round.
    for j in 0..258 {
        assert_eq!(a.get_pixel(257, j), b.get_pixel(1, j), "row {j}");
        assert_eq!(a.get_pixel(256, j), b.get_pixel(0, j), "row {j}");
    }
    // The shaded hill is not flat: the peak's sunny and shaded flanks differ.
    let lum: Vec<u8> = a.pixels().map(|p| p[0]).collect();
    assert!(lum.iter().max().unwrap() - lum.iter().min().unwrap() > 60);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_and_reflection_list_the_services() {
    use tokio_stream::StreamExt;
    use tonic_health::pb::health_client::HealthClient;
    use tonic_reflection::pb::v1::server_reflection_client::ServerReflectionClient;
    use tonic_reflection::pb::v1::{
        ServerReflectionRequest, server_reflection_request::MessageRequest, server_reflection_response::MessageResponse,
    };

    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&hill_scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let health = HealthClient::new(channel.clone())
        .check(tonic_health::pb::HealthCheckRequest { service: "relief.v1.SceneService".into() })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(health.status, tonic_health::pb::health_check_response::ServingStatus::Serving as i32);

    let request = ServerReflectionRequest {
        host: String::new(),
        message_request: Some(MessageRequest::ListServices(String::new())),
    };
    let mut responses = ServerReflectionClient::new(channel)
        .server_reflection_info(tokio_stream::iter([request]))
        .await
        .unwrap()
        .into_inner();
    let Some(Ok(response)) = responses.next().await else { panic!("no reflection answer") };
    let Some(MessageResponse::ListServicesResponse(list)) = response.message_response else {
        panic!("not a service list")
    };
    let names: Vec<String> = list.service.into_iter().map(|s| s.name).collect();
    for expected in
        ["relief.v1.SceneService", "relief.v1.TileService", "relief.v1.ViewService", "grpc.health.v1.Health"]
    {
        assert!(names.iter().any(|n| n == expected), "{expected} missing from {names:?}");
    }
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_requests_get_clear_statuses_and_the_daemon_keeps_serving() {
    let dir = tempfile::tempdir().unwrap();
    let mut daemon = Reliefd::start(&hill_scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let mut tiles = TileServiceClient::new(channel.clone());
    let get = |source: &str, level, x, y, resampling: Option<&str>| pb::GetTileRequest {
        source_id: source.into(),
        key: Some(pb::TileKey { level, x, y }),
        quality: Some(pb::QualityOverrides { resampling: resampling.map(Into::into), ..Default::default() }),
    };
    let cases = [
        (get("nope", 3, 0, 0, None), tonic::Code::NotFound, "no source has id 'nope'"),
        (get("dem", 3, 16, 0, None), tonic::Code::InvalidArgument, "outside the grid"),
        (get("dem", 99, 0, 0, None), tonic::Code::InvalidArgument, "key.level"),
        (get("dem", 3, 0, 0, Some("bicubic")), tonic::Code::InvalidArgument, "quality.resampling"),
        (
            pb::GetTileRequest { source_id: "dem".into(), key: None, quality: None },
            tonic::Code::InvalidArgument,
            "'key'",
        ),
    ];
    for (request, code, text) in cases {
        let status = tiles.get_tile(request).await.unwrap_err();
        assert_eq!(status.code(), code, "{status:?}");
        assert!(status.message().contains(text), "{:?} should mention {text:?}", status.message());
    }
    let bad_point = pb::SampleElevationRequest {
        points: vec![pb::GeodeticPoint { lon_deg: f64::NAN, lat_deg: 0.0 }],
        source_id: String::new(),
    };
    let status = tiles.sample_elevation(bad_point).await.unwrap_err();
    assert_eq!(status.code(), tonic::Code::InvalidArgument);
    assert!(status.message().contains("points[0]"), "{}", status.message());
    let colour = pb::SampleElevationRequest {
        points: vec![pb::GeodeticPoint { lon_deg: 10.2, lat_deg: 45.2 }],
        source_id: "shade".into(),
    };
    assert_eq!(tiles.sample_elevation(colour).await.unwrap_err().code(), tonic::Code::FailedPrecondition);
    let mut scene = SceneServiceClient::new(channel);
    let wait = scene
        .wait_for_generation(pb::WaitForGenerationRequest { min_generation: 99, timeout_ms: 100 })
        .await
        .unwrap_err();
    assert_eq!(wait.code(), tonic::Code::DeadlineExceeded);
    let reload = scene.reload(pb::ReloadRequest { source_ids: vec!["ghost".into()] }).await.unwrap_err();
    assert_eq!(reload.code(), tonic::Code::NotFound);

    // Still serving.
    assert!(daemon.is_running());
    assert_eq!(tile(&mut tiles, "dem", 9, 541, 127).await.width, 257);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cli_prints_elevations_and_writes_geotiff_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&hill_scene(dir.path(), "[effects]\nlighting = {}\n"), &[]).unwrap();

    let (code, out, err) = relief(&daemon, &["elevation", "10.25,45.25", "11,45"]).unwrap();
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines[0].starts_with("10.250000,45.250000\t"), "{out}");
    let peak: f64 = lines[0].split('\t').nth(1).unwrap().parse().unwrap();
    assert!((peak - 2000.0).abs() < 0.1, "{peak}");
    assert!(lines[1].ends_with("null"), "{out}");

    let (code, out, err) = relief(&daemon, &["--json", "elevation", "10.25,45.25", "11,45"]).unwrap();
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    // The proto3 JSON mapping: a sample without a height has no heightM.
    assert!(v["samples"][1].get("heightM").is_none(), "{v}");
    assert!((v["samples"][0]["heightM"].as_f64().unwrap() - peak).abs() < 1e-3);

    let tif = dir.path().join("tile.tif");
    let (code, _, err) = relief(&daemon, &["tile", "dem", "9", "541", "127", "-o", tif.to_str().unwrap()]).unwrap();
    assert_eq!(code, 0, "{err}");
    // The GeoTIFF's pixel centres are the tile's samples: GDAL reads the
    // analytic hill back at their positions.
    let ds = gdal::Dataset::open(&tif).unwrap();
    let gt = ds.geo_transform().unwrap();
    let data =
        ds.rasterband(1).unwrap().read_as::<f32>((0, 0), (257, 257), (257, 257), None).unwrap().into_shape_and_vec().1;
    for (i, j) in [(0usize, 0usize), (128, 128), (200, 250), (37, 201)] {
        let (lon, lat) = (gt[0] + (i as f64 + 0.5) * gt[1], gt[3] + (j as f64 + 0.5) * gt[5]);
        let h = f64::from(data[j * 257 + i]);
        assert!((h - fixtures::hill(lon, lat)).abs() < 0.1, "({i},{j}) at {lon},{lat}: {h}");
    }
    let png = dir.path().join("shade.png");
    let (code, _, err) = relief(&daemon, &["tile", "shade", "9", "541", "127", "-o", png.to_str().unwrap()]).unwrap();
    assert_eq!(code, 0, "{err}");
    assert_eq!(image::open(&png).unwrap().width(), 258);

    let (code, out, err) = relief(&daemon, &["--json", "state"]).unwrap();
    assert_eq!(code, 0, "{err}");
    let state: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(state["sources"][0]["id"], "dem");
    assert_eq!(state["sources"][0]["status"], "SOURCE_STATUS_READY");
    assert_eq!(state["sources"][0]["active"], true);
    assert_eq!(state["effects"][0]["name"], "lighting");
    // uint64 is a string in the proto3 JSON mapping.
    assert!(state["counters"]["tilesGenerated"].as_str().unwrap().parse::<u64>().unwrap() >= 2);
    // Field for field what the HTTP transport answers (the scene is idle).
    let http = relief_tests::http::get(&format!("{}/api/state", daemon.url())).unwrap().json().unwrap();
    assert_eq!(state, http, "relief --json state and GET /api/state differ");

    let (code, _, err) = relief(&daemon, &["tile", "nope", "0", "0", "0", "-o", "/dev/null"]).unwrap();
    assert_eq!(code, 1);
    assert!(err.contains("no source has id 'nope'"), "{err}");
    daemon.stop(&[]).unwrap();
}
