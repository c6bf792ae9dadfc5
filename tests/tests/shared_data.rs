//! Real public DEMs from `../shared/data` (CI always has them; a clone
//! without them skips these tests and says so).

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::Path;

use relief_proto::v1 as pb;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::fixtures::{self, Lcg};
use relief_tests::reference;

async fn elevations(daemon: &Reliefd, points: &[pb::GeodeticPoint]) -> Vec<Option<f64>> {
    TileServiceClient::new(daemon.channel().await.unwrap())
        .sample_elevation(pb::SampleElevationRequest { points: points.to_vec(), source_id: String::new() })
        .await
        .unwrap()
        .into_inner()
        .samples
        .into_iter()
        .map(|s| s.height_m)
        .collect()
}

fn assert_matches_gdal(raster: &Path, points: &[pb::GeodeticPoint], got: &[Option<f64>], scratch: &Path) {
    let mut compared = 0;
    for (p, g) in points.iter().zip(got) {
        let want = reference::gdal_value_at(raster, p.lon_deg, p.lat_deg, "bilinear", scratch).unwrap();
        match (g, want) {
            (Some(g), Some(w)) => {
                assert!((g - w).abs() < 0.01, "{p:?}: relief {g} vs GDAL {w}");
                compared += 1;
            }
            // Beside a void relief's policy (valid taps must carry half the
            // weight) may say nodata where GDAL still renormalises.
            (None, _) => {}
            (Some(g), None) => panic!("{p:?}: relief {g} where GDAL has no data"),
        }
    }
    assert!(compared >= points.len() - 1, "only {compared} of {} points compared", points.len());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn srtm_elevations_match_gdal_bilinear_within_a_centimetre() {
    let Some(data) = relief_tests::shared_data("srtm_elevations_match_gdal_bilinear_within_a_centimetre") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let hgt = data.join("dem/N43E007.hgt");
    let manifest = fixtures::write_manifest(
        dir.path(),
        &format!(
            "[scene]\nname = \"alps\"\ngrid = \"geodetic\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"{}\"\n\n[layers]\nheight = \"dem\"\n\n[quality]\nresampling = \"bilinear\"\n",
            hgt.display()
        ),
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    // Over land: the north-west of the tile (Maritime Alps).
    let mut rng = Lcg(2026);
    let points: Vec<pb::GeodeticPoint> =
        (0..20).map(|_| pb::GeodeticPoint { lon_deg: rng.range(7.0, 7.6), lat_deg: rng.range(43.7, 44.0) }).collect();
    let got = elevations(&daemon, &points).await;
    assert!(got.iter().flatten().any(|h| *h > 500.0), "mountains expected: {got:?}");
    assert_matches_gdal(&hgt, &points, &got, dir.path());
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn storm_lake_utm_elevations_match_gdal_within_a_centimetre() {
    let Some(data) = relief_tests::shared_data("storm_lake_utm_elevations_match_gdal_within_a_centimetre") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let tif = data.join("dem/storml_elev.tif");
    let manifest = fixtures::write_manifest(
        dir.path(),
        &format!(
            "[scene]\nname = \"storm-lake\"\ngrid = {{ crs = \"EPSG:26912\" }}\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"{}\"\n\n[layers]\nheight = \"dem\"\n",
            tif.display()
        ),
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    // Random points inside the raster, in UTM, taken to lon/lat by PROJ.
    let ds = gdal::Dataset::open(&tif).unwrap();
    let gt = ds.geo_transform().unwrap();
    let (w, h) = ds.raster_size();
    let mut rng = Lcg(12);
    let xs: Vec<f64> = (0..20).map(|_| gt[0] + rng.range(1.0, w as f64 - 1.0) * gt[1]).collect();
    let ys: Vec<f64> = (0..20).map(|_| gt[3] + rng.range(1.0, h as f64 - 1.0) * gt[5]).collect();
    let points = reference::lon_lat_points("EPSG:26912", &xs, &ys).unwrap();
    let got = elevations(&daemon, &points).await;
    assert!(got.iter().flatten().all(|h| (2400.0..3100.0).contains(h)), "{got:?}");
    assert_matches_gdal(&tif, &points, &got, dir.path());
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_srtm_tiles_mosaic_without_a_seam() {
    let Some(data) = relief_tests::shared_data("two_srtm_tiles_mosaic_without_a_seam") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let manifest = fixtures::write_manifest(
        dir.path(),
        &format!(
            "[scene]\nname = \"provence\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npaths = [\"{}\", \"{}\"]\n\n[layers]\nheight = \"dem\"\n",
            data.join("dem/N43E006.hgt").display(),
            data.join("dem/N43E007.hgt").display()
        ),
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    // Along the shared meridian, and a hair either side, the mosaic answers everywhere.
    let points: Vec<pb::GeodeticPoint> = (0..50)
        .flat_map(|i| {
            let lat = 43.9 - f64::from(i) * 0.01;
            [6.9999, 7.0, 7.0001].map(|lon_deg| pb::GeodeticPoint { lon_deg, lat_deg: lat })
        })
        .collect();
    let got = elevations(&daemon, &points).await;
    for (chunk, p) in got.chunks(3).zip(points.chunks(3)) {
        let [a, b, c] = [chunk[0].unwrap(), chunk[1].unwrap(), chunk[2].unwrap()];
        // 0.0001 degrees is 0.12 pixels: neighbours differ by a fraction of the local relief.
        assert!((a - b).abs() < 50.0 && (b - c).abs() < 50.0, "{p:?}: {a} {b} {c}");
    }
    // A tile across the seam has no column of nodata.
    let t = TileServiceClient::new(daemon.channel().await.unwrap())
        .get_tile(pb::GetTileRequest {
            source_id: "dem".into(),
            key: Some(pb::TileKey { level: 8, x: 265, y: 65 }),
            quality: None,
        })
        .await
        .unwrap()
        .into_inner();
    let Some(pb::get_tile_response::Payload::HeightsF32Le(bytes)) = t.payload else { panic!("heights expected") };
    let e = t.extent.unwrap();
    assert!(e.min_x < 7.0 && e.max_x > 7.0, "{e:?}");
    let heights: Vec<f32> = bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    let step = (e.max_x - e.min_x) / 256.0;
    for j in 0..257 {
        let lat = e.max_y - j as f64 * step;
        if !(43.01..43.99).contains(&lat) {
            continue;
        }
        for i in 0..257 {
            let lon = e.min_x + i as f64 * step;
            if (6.01..7.99).contains(&lon) {
                assert!(!heights[j * 257 + i].is_nan(), "hole at {lon},{lat}");
            }
        }
    }
    daemon.stop(&[]).unwrap();
}
