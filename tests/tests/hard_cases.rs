//! Hard cases of the planet grid: the antimeridian and the poles, with a
//! global DEM whose heights are known everywhere.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use relief_proto::v1 as pb;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::fixtures;
use relief_tests::tiles;

/// Smooth on the sphere: 1000 m at both poles, +-500 m round the equator.
fn globe(lon: f64, lat: f64) -> f64 {
    1000.0 + 500.0 * lat.to_radians().cos() * lon.to_radians().cos()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn poles_and_the_antimeridian_have_one_height_and_no_seam() {
    let dir = tempfile::tempdir().unwrap();
    fixtures::write_dem(&dir.path().join("globe.tif"), &fixtures::globe_spec(), globe).unwrap();
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"globe\"\ntile_size = 64\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"globe.tif\"\n\n[[source]]\nid = \"shade\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\n\n[layers]\nheight = \"dem\"\n",
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let mut tiles = TileServiceClient::new(daemon.channel().await.unwrap());
    let mut get = async |level: u32, x: u32, y: u32| {
        tiles
            .get_tile(pb::GetTileRequest {
                source_id: "dem".into(),
                key: Some(pb::TileKey { level, x, y }),
                quality: None,
            })
            .await
            .unwrap()
            .into_inner()
    };
    for level in [0u32, 2, 5] {
        let (cols, rows) = (2u32 << level, 1u32 << level);
        let n = 65usize;
        for y in [0, rows / 2, rows - 1] {
            // The west edge of the first column and the east edge of the last
            // are the same meridian: the same heights, bit for bit.
            let (west, east) =
                (tiles::heights(&get(level, 0, y).await), tiles::heights(&get(level, cols - 1, y).await));
            for j in 0..n {
                assert_eq!(west[j * n].to_bits(), east[j * n + n - 1].to_bits(), "level {level} row {y} sample {j}");
                let lat = 90.0 - f64::from(y) * 180.0 / f64::from(rows) - j as f64 * 180.0 / f64::from(rows) / 64.0;
                // Interpolated across the date line, not clamped to one side.
                assert!(
                    (f64::from(west[j * n]) - globe(180.0, lat)).abs() < 2.5,
                    "level {level} at 180,{lat}: {}",
                    west[j * n]
                );
            }
        }
        // Every sample on a pole, in every tile, is the one pole height.
        let mut pole = None;
        for x in 0..cols {
            let top = tiles::heights(&get(level, x, 0).await);
            let bottom = tiles::heights(&get(level, x, rows - 1).await);
            for (h, south) in top[..n].iter().map(|h| (h, false)).chain(bottom[n * (n - 1)..].iter().map(|h| (h, true)))
            {
                assert!(!h.is_nan());
                let p = *pole.get_or_insert(*h);
                assert_eq!(h.to_bits(), p.to_bits(), "level {level} tile {x} (south: {south})");
            }
        }
        assert!((f64::from(pole.unwrap()) - 1000.0).abs() < 5.0, "{pole:?}");
    }
    // Elevations either side of the antimeridian and at the poles.
    let points: Vec<pb::GeodeticPoint> =
        [(179.9, 10.0), (-179.9, 10.0), (180.0, -30.0), (0.0, 90.0), (123.0, 90.0), (-45.0, -90.0)]
            .into_iter()
            .map(|(lon_deg, lat_deg)| pb::GeodeticPoint { lon_deg, lat_deg })
            .collect();
    let answer = tiles
        .sample_elevation(pb::SampleElevationRequest { points: points.clone(), source_id: String::new() })
        .await
        .unwrap()
        .into_inner();
    for (p, s) in points.iter().zip(&answer.samples).take(3) {
        let h = s.height_m.unwrap();
        assert!((h - globe(p.lon_deg, p.lat_deg)).abs() < 1.0, "{p:?}: {h}");
    }
    let poles: Vec<f64> = answer.samples[3..].iter().map(|s| s.height_m.unwrap()).collect();
    assert_eq!(poles[0], poles[1], "one north pole");
    assert!((poles[2] - 1000.0).abs() < 5.0);
    // The hillshade over the pole and the date line has no holes.
    let shade = tiles
        .get_tile(pb::GetTileRequest {
            source_id: "shade".into(),
            key: Some(pb::TileKey { level: 2, x: 0, y: 0 }),
            quality: None,
        })
        .await
        .unwrap()
        .into_inner();
    let img = tiles::image(&shade);
    assert!(img.pixels().all(|p| p[3] == 255), "every texel shaded");
    daemon.stop(&[]).unwrap();
}
