//! The demo people see (`make demo`): written from the SRTM crop committed
//! under `examples/data`, its default view keeps most of its contrast
//! through the atmosphere and the fog while still showing them, and the
//! DEM it serves is GDAL's read of the committed file.

#![allow(clippy::unwrap_used, reason = "a test")]

use std::path::{Path, PathBuf};

use relief_proto::v1 as pb;
use relief_proto::v1::tile_service_client::TileServiceClient;
use relief_proto::v1::view_service_client::ViewServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::{fixtures, reference};

/// The default view's size: enough pixels for the contrast to settle, few
/// enough for lavapipe in a debug build.
const SIZE: (u32, u32) = (480, 270);

/// The share of the clear view's RMS contrast the hazy one must keep.
const MIN_CONTRAST_KEPT: f64 = 0.6;

fn committed_dem() -> PathBuf {
    relief_tests::workspace_root().join("examples/data/maritime-alps-srtm3.tif")
}

/// The demo's manifest without the atmosphere and the fog, beside it.
fn without_haze(manifest: &Path) -> PathBuf {
    let text = std::fs::read_to_string(manifest).unwrap();
    let kept: Vec<&str> = text.lines().filter(|l| !l.starts_with("atmosphere =") && !l.starts_with("fog =")).collect();
    assert_eq!(kept.len() + 2, text.lines().count(), "the demo declares atmosphere and fog, one line each");
    let clear = manifest.with_file_name("scene-clear.toml");
    std::fs::write(&clear, kept.join("\n")).unwrap();
    clear
}

/// The scene's own camera (the request names none), as RGBA8.
async fn default_view(manifest: &Path) -> pb::RenderResponse {
    let daemon = Reliefd::start(manifest, &[]).unwrap();
    let (width, height) = SIZE;
    let request = pb::RenderRequest { width, height, format: pb::ImageFormat::Rgba8 as i32, ..Default::default() };
    let frame = ViewServiceClient::new(daemon.channel().await.unwrap())
        .max_decoding_message_size(64 << 20)
        .render(request)
        .await
        .unwrap()
        .into_inner();
    daemon.stop(&[]).unwrap();
    assert_eq!((frame.width, frame.height), SIZE);
    frame
}

/// Writes `frame` under target/demo-test/, for a person to look at.
fn save(frame: &pb::RenderResponse, name: &str) {
    let dir = relief_tests::workspace_root().join("target/demo-test");
    std::fs::create_dir_all(&dir).unwrap();
    image::RgbaImage::from_raw(frame.width, frame.height, frame.image.to_vec()).unwrap().save(dir.join(name)).unwrap();
}

/// Rec. 709 luminance of each pixel, 0 to 1 (of the encoded values).
fn luminance(frame: &pb::RenderResponse) -> Vec<f64> {
    frame
        .image
        .chunks_exact(4)
        .map(|p| (0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2])) / 255.0)
        .collect()
}

/// RMS contrast: the standard deviation of the luminance.
fn rms_contrast(luminance: &[f64]) -> f64 {
    let n = luminance.len() as f64;
    let mean = luminance.iter().sum::<f64>() / n;
    (luminance.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / n).sqrt()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn demo_default_view_keeps_its_contrast_through_atmosphere_and_fog() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = fixtures::write_alps_demo_scene(dir.path(), &committed_dem()).unwrap();
    let hazy = default_view(&manifest).await;
    let clear = default_view(&without_haze(&manifest)).await;
    for (frame, pass, ran) in [(&hazy, "atmosphere", true), (&hazy, "fog", true), (&clear, "atmosphere", false)] {
        let runs = frame.pass_counters.iter().find(|p| p.name == pass).map_or(0, |p| p.runs);
        assert_eq!(runs > 0, ran, "{pass}: {runs} runs");
    }

    save(&hazy, "default-view.png");
    save(&clear, "default-view-without-haze.png");

    let (l_hazy, l_clear) = (luminance(&hazy), luminance(&clear));
    let (c_hazy, c_clear) = (rms_contrast(&l_hazy), rms_contrast(&l_clear));
    let kept = c_hazy / c_clear;
    let moved = l_hazy.iter().zip(&l_clear).map(|(a, b)| (a - b).abs()).sum::<f64>() / l_hazy.len() as f64;
    let changed = l_hazy.iter().zip(&l_clear).filter(|(a, b)| (*a - *b).abs() > 4.0 / 255.0).count();
    let changed_share = changed as f64 / l_hazy.len() as f64;
    eprintln!(
        "demo default view {}x{}: RMS contrast {c_hazy:.4} with atmosphere and fog, {c_clear:.4} without: \
         {:.1}% kept; mean |luminance difference| {:.2}/255, {:.1}% of pixels changed by more than 4/255",
        SIZE.0,
        SIZE.1,
        100.0 * kept,
        255.0 * moved,
        100.0 * changed_share
    );
    assert!(c_clear > 0.05, "the clear view is flat: RMS contrast {c_clear:.4}");
    assert!(kept >= MIN_CONTRAST_KEPT, "the haze keeps {:.1}% of the contrast", 100.0 * kept);
    // The effects show: most of the frame moves, by a visible amount.
    assert!(moved > 3.0 / 255.0 && changed_share > 0.5, "atmosphere and fog barely show");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn demo_serves_the_committed_dem_as_gdal_reads_it() {
    let dem = committed_dem();
    let dir = tempfile::tempdir().unwrap();
    let manifest = fixtures::write_alps_demo_scene(&dir.path().join("scene"), &dem).unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    // The lake's surface, the gorges, the Préalpes de Castellane, the
    // Cheiron, the Vésubie's ridges, a sample's centre exactly, Nice's
    // coast, and the void at the Var's mouth.
    let points: Vec<pb::GeodeticPoint> = [
        (6.1713, 43.7706),
        (6.3704, 43.7597),
        (6.3311, 43.8693),
        (6.9702, 43.8104),
        (7.3319, 43.9508),
        (6.5, 43.9),
        (7.2706, 43.6903),
        (7.21, 43.6625),
    ]
    .into_iter()
    .map(|(lon_deg, lat_deg)| pb::GeodeticPoint { lon_deg, lat_deg })
    .collect();
    let samples = TileServiceClient::new(daemon.channel().await.unwrap())
        .sample_elevation(pb::SampleElevationRequest { points: points.clone(), source_id: "dem".into() })
        .await
        .unwrap()
        .into_inner()
        .samples;
    daemon.stop(&[]).unwrap();
    assert_eq!(samples.len(), points.len());

    let scratch = tempfile::tempdir().unwrap();
    let mut compared = 0;
    for (p, s) in points.iter().zip(&samples) {
        let want = reference::gdal_value_at(&dem, p.lon_deg, p.lat_deg, "bilinear", scratch.path()).unwrap();
        eprintln!("({}, {}): relief {:?}, GDAL {want:?}", p.lon_deg, p.lat_deg, s.height_m);
        match (s.height_m, want) {
            (Some(got), Some(want)) => {
                assert!((got - want).abs() < 0.01, "({}, {}): relief {got} vs GDAL {want}", p.lon_deg, p.lat_deg);
                compared += 1;
            }
            // Beside a void relief's policy (valid taps must carry half the
            // weight) may say nodata where GDAL still renormalises.
            (None, _) => {}
            (Some(got), None) => panic!("({}, {}): relief {got} where GDAL has no data", p.lon_deg, p.lat_deg),
        }
    }
    assert!(compared >= points.len() - 1, "only {compared} of {} points compared", points.len());
    // The void is served as one: nodata, not a height.
    assert_eq!(samples.last().unwrap().height_m, None, "the Var mouth's void");
}
