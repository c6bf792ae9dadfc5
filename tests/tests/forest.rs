//! The forest against a real reliefd: `scatter` grows trees from a
//! land-cover raster written through GDAL, frames draw them, the state
//! counts them per class (and names classes without a rule), an edit of
//! the class raster rebuilds only the instance tiles it touches, and every
//! bad input is named (file and source) while the rest of the scene is
//! served.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::Path;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_source::TileGrid;
use relief_tests::daemon::Reliefd;
use relief_tests::edit::{Events, rewrite_window, tile_hash, wait_for};
use relief_tests::fixtures::{self, RasterSpec};
use relief_tests::scenes::{camera, hill, render_rgba};
use tonic::transport::Channel;

/// The land cover: 0.0002-degree pixels over the hill's south flank.
const COVER: RasterSpec<'static> = RasterSpec {
    width: 400,
    height: 300,
    origin_x: 10.18,
    origin_y: 45.12,
    pixel: 0.0002,
    crs: "EPSG:4326",
    nodata: None,
};
/// Rule densities per km² of classes 1 (west) and 2 (east).
const CONIFERS: f64 = 4000.0;
const BROADLEAVES: f64 = 1500.0;
/// The level scatter builds at on the geodetic grid (tiles 1.2 km tall).
const LEVEL: u8 = 14;

/// Conifers west of 10.22, broadleaves east of it, a northern strip of
/// class 7 (no rule), and a nodata pocket.
fn cover(lon: f64, lat: f64) -> u8 {
    if (lon - 10.24).powi(2) + (lat - 45.08).powi(2) < 0.003f64.powi(2) {
        0
    } else if lat > 45.1 {
        7
    } else if lon < 10.22 {
        1
    } else {
        2
    }
}

fn forest(extra: &str) -> String {
    format!(
        "instances = \"forest\"\n\n[[source]]\nid = \"landcover\"\nkind = \"gdal\"\npath = \"cover.tif\"\nresampling = \"nearest\"\n\n[[source]]\nid = \"forest\"\nkind = \"scatter\"\ninputs = [\"landcover\", \"dem\"]\nseed = 3\n{extra}\n[[source.rule]]\nclass = 1\nmodels = {{ conifer = 1 }}\ndensity = {CONIFERS}\n\n[[source.rule]]\nclass = 2\nmodels = {{ broadleaf = 0.7, shrub = 0.3 }}\ndensity = {BROADLEAVES}\nscale = [0.8, 1.2]\n"
    )
}

/// The hill scene with the forest as its instances layer (`hill` puts the
/// fragment under [layers]).
fn scene(dir: &Path, extra: &str) -> std::path::PathBuf {
    fixtures::write_classes(&dir.join("cover.tif"), &COVER, cover).unwrap();
    hill(dir, &forest(extra)).unwrap()
}

/// Low over the forest from the south, looking north across both classes.
fn low_camera() -> pb::Camera {
    let ground = fixtures::hill(10.22, 45.075);
    camera(10.22, 45.075, ground + 120.0, 0.0, -8.0)
}

async fn render(channel: &Channel, camera: pb::Camera) -> pb::RenderResponse {
    render_rgba(channel, camera, (480, 320)).await.unwrap()
}

async fn state(channel: &Channel) -> pb::SceneState {
    SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner()
}

fn source<'a>(state: &'a pb::SceneState, id: &str) -> &'a pb::SourceState {
    state.sources.iter().find(|s| s.id == id).unwrap()
}

/// A class sample's area at LEVEL near the forest, km².
fn sample_km2() -> f64 {
    let step = TileGrid::geodetic(256).unwrap().sample_step(LEVEL);
    let (dy, dx) = (step * 111_320.0, step * 111_320.0 * 45.09f64.to_radians().cos());
    dx * dy / 1e6
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_forest_is_drawn_and_counted_per_class() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let frame = render(&channel, low_camera()).await;
    let drawn = frame.drawn.unwrap();
    assert!(drawn.models > 100 && drawn.billboards > 100, "{drawn:?}");
    let instances = frame.pass_counters.iter().find(|p| p.name == "instances").unwrap();
    assert!(instances.built && instances.runs == 1, "{instances:?}");
    let passes: Vec<&str> = frame.passes.iter().map(|p| p.pass.as_str()).collect();
    assert_eq!(passes, ["terrain", "instances", "read back"]);

    let state = state(&channel).await;
    let forest = source(&state, "forest");
    assert_eq!(forest.status, pb::SourceStatus::Ready as i32, "{}", forest.error);
    let class = |c: i64| forest.instance_classes.iter().find(|k| k.class == c).unwrap_or_else(|| panic!("class {c}"));
    // Each class's density within 5 % of its rule over the tiles built
    // (square kilometres of them), class 7 listed without a rule.
    for (c, rule) in [(1, CONIFERS), (2, BROADLEAVES)] {
        let k = class(c);
        assert!(k.has_rule && k.samples > 10_000, "{k:?}");
        let density = k.instances as f64 / (k.samples as f64 * sample_km2());
        assert!((density / rule - 1.0).abs() < 0.05, "class {c}: {density:.0} per km², rule {rule}");
    }
    let unruled = class(7);
    assert!(!unruled.has_rule && unruled.instances == 0 && unruled.samples > 0, "{unruled:?}");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edit_of_the_class_raster_rebuilds_only_the_instance_tiles_it_touches() {
    let dir = tempfile::tempdir().unwrap();
    let daemon = Reliefd::start(&scene(dir.path(), ""), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    render(&channel, low_camera()).await;
    let before = state(&channel).await;
    let generated = source(&before, "forest").tiles_generated;
    let grid = TileGrid::geodetic(256).unwrap();
    let edited = grid.key_at(LEVEL, 10.202, 45.092).unwrap();
    let far = grid.key_at(LEVEL, 10.245, 45.1).unwrap();
    assert_ne!(edited, far);
    let hash = |k: relief_source::TileKey| tile_hash(channel.clone(), "forest", (u32::from(k.level), k.x, k.y));
    let (edited_before, far_before) = (hash(edited).await.unwrap(), hash(far).await.unwrap());

    // 20 x 20 pixels (about 300 m) of conifers become broadleaves, written
    // in place through GDAL as a GIS would.
    rewrite_window(&dir.path().join("cover.tif"), 100, 130, 20, 20, |_, _, _| 2.0).unwrap();
    let after = wait_for(channel.clone(), before.generation + 1).await.unwrap();
    let event = events.generation(after.generation).await.unwrap();
    assert_eq!(event.changed_sources, ["landcover"], "{event:?}");
    render(&channel, low_camera()).await;
    let after = state(&channel).await;
    let remade = source(&after, "forest").tiles_generated - generated;
    assert!(remade >= 1 && remade * 4 <= generated, "{remade} instance tiles made again, of {generated}");
    assert_ne!(hash(edited).await.unwrap(), edited_before, "the edited tile changed");
    assert_eq!(hash(far).await.unwrap(), far_before, "a tile away from the edit is the same");
    daemon.stop(&[]).unwrap();
}

/// A scene whose forest is broken in one way: the terrain is still drawn,
/// and the source's error names what is wrong.
async fn broken(dir: &Path, extra: &str) -> (String, pb::RenderResponse) {
    let daemon = Reliefd::start(&scene(dir, extra), &["--keep-going"]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let frame = render(&channel, low_camera()).await;
    let state = state(&channel).await;
    let error = source(&state, "forest").error.clone();
    daemon.stop(&["source 'forest'"]).unwrap();
    (error, frame)
}

fn terrain_drawn(frame: &pb::RenderResponse) -> bool {
    let sky = frame.image.chunks(4).filter(|p| p[2] > p[0] + 20 && p[2] > p[1]).count();
    frame.passes.iter().any(|p| p.pass == "terrain") && sky < frame.image.len() / 8
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_models_and_rules_are_named_and_the_rest_of_the_scene_is_served() {
    // A missing glTF.
    let dir = tempfile::tempdir().unwrap();
    let (error, frame) = broken(dir.path(), "paths = [\"oak.glb\"]\n").await;
    assert!(error.contains("forest") && error.contains("oak.glb") && error.contains("No such file"), "{error}");
    assert!(terrain_drawn(&frame) && frame.drawn.unwrap().models == 0);

    // A corrupt glTF.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("oak.glb"), b"glTF\x02\0\0\0 this is not a model").unwrap();
    let (error, frame) = broken(dir.path(), "paths = [\"oak.glb\"]\n").await;
    assert!(error.contains("forest") && error.contains("oak.glb") && error.contains("glTF"), "{error}");
    assert!(!error.contains("{ ") && !error.contains("Os {"), "no Debug output: {error}");
    assert!(terrain_drawn(&frame));

    // A rule with a negative density.
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path()).unwrap();
    fixtures::write_classes(&dir.path().join("cover.tif"), &COVER, cover).unwrap();
    let text = forest("").replace(&format!("density = {BROADLEAVES}"), "density = -5");
    let manifest = hill(dir.path(), &text).unwrap();
    let daemon = Reliefd::start(&manifest, &["--keep-going"]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let state = state(&channel).await;
    let error = &source(&state, "forest").error;
    assert!(error.contains("forest") && error.contains("rule[1].density") && error.contains("0 or more"), "{error}");
    assert!(terrain_drawn(&render(&channel, low_camera()).await));
    daemon.stop(&["source 'forest'"]).unwrap();

    // A class raster that is not integer: a Float32 band of fractions.
    let dir = tempfile::tempdir().unwrap();
    let manifest = scene(dir.path(), "");
    fixtures::write_dem(&dir.path().join("cover.tif"), &COVER, |lon, _| 1.0 + (lon - 10.18) * 10.0).unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let frame = render(&channel, low_camera()).await;
    assert!(terrain_drawn(&frame) && frame.drawn.unwrap().models == 0);
    let key = TileGrid::geodetic(256).unwrap().key_at(LEVEL, 10.2, 45.09).unwrap();
    let status = relief_tests::tiles::get(channel.clone(), "forest", (u32::from(key.level), key.x, key.y))
        .await
        .unwrap_err()
        .to_string();
    assert!(
        status.contains("forest")
            && status.contains("class raster 'landcover' (reading ")
            && status.contains("cover.tif")
            && status.contains("integers"),
        "{status}"
    );
    daemon.stop(&["class raster 'landcover'"]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_model_file_broken_after_a_good_start_keeps_the_last_good_forest() {
    let dir = tempfile::tempdir().unwrap();
    let oak = dir.path().join("oak.glb");
    std::fs::write(&oak, relief_models::stock_glb("broadleaf").unwrap()).unwrap();
    let text = forest("paths = [\"oak.glb\"]\n").replace("models = { broadleaf = 0.7", "models = { oak = 0.7");
    fixtures::write_classes(&dir.path().join("cover.tif"), &COVER, cover).unwrap();
    let daemon = Reliefd::start(&hill(dir.path(), &text).unwrap(), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    let good = render(&channel, low_camera()).await.drawn.unwrap();
    assert!(good.models > 0, "{good:?}");
    // Saved over with garbage: an error naming the file and the source; the
    // last good forest is still drawn.
    std::fs::write(&oak, b"not a model at all").unwrap();
    for _ in 0..100 {
        if !events.errors().is_empty() {
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
    let errors = events.errors();
    let error = errors.first().unwrap_or_else(|| panic!("no source error: {:#?}", daemon.log()));
    assert_eq!(error.source_id, "forest");
    assert!(error.kept_last_good && error.error.contains("oak.glb") && error.error.contains("glTF"), "{error:?}");
    let still = render(&channel, low_camera()).await.drawn.unwrap();
    assert_eq!((still.models, still.billboards), (good.models, good.billboards));
    daemon.stop(&["keeping the last good version"]).unwrap();
}
