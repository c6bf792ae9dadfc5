//! Vector sources against a real reliefd: feature counts as GDAL/OGR reads
//! them, feature tiles, and the shapefile states a save can leave behind.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use gdal::vector::LayerAccess;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::{Reliefd, check};
use relief_tests::fixtures;
use relief_tests::tiles;

/// Three parcels (one with a hole, one split at the antimeridian) and a
/// null geometry, written as a shapefile by ogr2ogr; and two trees, one on
/// a corner of four tiles.
const PARCELS: &str = r#"{"type": "FeatureCollection", "features": [
  {"type": "Feature", "properties": {"name": "Été", "height": 12.5}, "geometry": {"type": "Polygon", "coordinates": [[[10.0, 45.0], [10.2, 45.0], [10.2, 45.2], [10.0, 45.2], [10.0, 45.0]], [[10.05, 45.05], [10.1, 45.05], [10.1, 45.1], [10.05, 45.1], [10.05, 45.05]]]}},
  {"type": "Feature", "properties": {"name": "B", "height": 30}, "geometry": {"type": "Polygon", "coordinates": [[[11.0, 45.0], [11.3, 45.0], [11.3, 45.3], [11.0, 45.0]]]}},
  {"type": "Feature", "properties": {"name": "C", "height": 8}, "geometry": {"type": "MultiPolygon", "coordinates": [[[[179.5, -17.0], [180.0, -17.0], [180.0, -16.5], [179.5, -17.0]]], [[[-180.0, -17.0], [-179.5, -17.0], [-180.0, -16.5], [-180.0, -17.0]]]]}},
  {"type": "Feature", "properties": {"name": "none", "height": 0}, "geometry": null}
]}"#;

const TREES: &str = r#"{"type": "FeatureCollection", "features": [
  {"type": "Feature", "properties": {"name": "tree"}, "geometry": {"type": "Point", "coordinates": [22.5, 45.0]}},
  {"type": "Feature", "properties": {"name": "tree"}, "geometry": {"type": "Point", "coordinates": [10.1, 45.1]}}
]}"#;

fn shapefile(dir: &Path, name: &str, geojson: &str) -> PathBuf {
    relief_tests::vectors::shapefile(dir, name, geojson).unwrap()
}

fn ogr_count(path: &Path) -> u64 {
    let ds = gdal::Dataset::open(path).unwrap();
    (0..ds.layer_count()).map(|i| ds.layer(i).unwrap().feature_count()).sum()
}

fn manifest(dir: &Path, sources: &[(&str, &Path)]) -> PathBuf {
    let mut text = String::from("[scene]\nname = \"vectors\"\n");
    for (id, path) in sources {
        let _ = write!(text, "\n[[source]]\nid = \"{id}\"\nkind = \"shapefile\"\npath = \"{}\"\n", path.display());
    }
    fixtures::write_manifest(dir, &text).unwrap()
}

async fn details(daemon: &Reliefd, id: &str) -> std::collections::HashMap<String, String> {
    let state = SceneServiceClient::new(daemon.channel().await.unwrap())
        .get_state(pb::GetStateRequest {})
        .await
        .unwrap()
        .into_inner();
    state.sources.into_iter().find(|s| s.id == id).unwrap().details
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shared_shapefiles_load_with_the_counts_ogr_reports() {
    let Some(data) = relief_tests::shared_data("shared_shapefiles_load_with_the_counts_ogr_reports") else { return };
    let dir = tempfile::tempdir().unwrap();
    let countries = data.join("shp/naturalearth_lowres.shp");
    let cities = data.join("shp/naturalearth_cities.shp");
    let daemon = Reliefd::start(&manifest(dir.path(), &[("countries", &countries), ("cities", &cities)]), &[]).unwrap();
    for (id, path) in [("countries", &countries), ("cities", &cities)] {
        let d = details(&daemon, id).await;
        let read: u64 = d["features"].parse::<u64>().unwrap() + d["null_shapes"].parse::<u64>().unwrap();
        assert_eq!(read, ogr_count(path), "{id}: {d:?}");
    }
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn feature_tiles_hold_what_reaches_them_and_points_once() {
    let dir = tempfile::tempdir().unwrap();
    let shp = shapefile(dir.path(), "parcels", PARCELS);
    let trees = shapefile(dir.path(), "trees", TREES);
    let daemon = Reliefd::start(&manifest(dir.path(), &[("parcels", &shp), ("trees", &trees)]), &[]).unwrap();
    let d = details(&daemon, "parcels").await;
    assert_eq!((d["features"].as_str(), d["null_shapes"].as_str()), ("3", "1"), "{d:?}");
    assert_eq!(d["features"].parse::<u64>().unwrap() + 1, ogr_count(&shp));
    let channel = daemon.channel().await.unwrap();
    let get = async |source: &str, level: u32, x: u32, y: u32| {
        tiles::geojson(&tiles::get(channel.clone(), source, (level, x, y)).await.unwrap())
    };
    let names = |fc: &serde_json::Value| -> Vec<String> {
        fc["features"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f["properties"]["name"].as_str().unwrap().to_owned())
            .collect()
    };
    // Level 3 tiles are 22.5 degrees: (22.5, 45.0) is a corner of four of
    // them, and the grid's half-open rule gives it to one.
    let mut owners = 0;
    for (x, y) in [(8, 1), (9, 1), (8, 2), (9, 2)] {
        let fc = get("trees", 3, x, y).await;
        owners += fc["features"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["geometry"]["coordinates"] == serde_json::json!([22.5, 45.0]))
            .count();
    }
    assert_eq!(owners, 1, "a point belongs to exactly one tile");
    // The first parcel's attributes came through, accents decoded per the .cpg.
    let fc = get("parcels", 3, 8, 1).await;
    let ete = fc["features"].as_array().unwrap().iter().find(|f| f["properties"]["name"] == "Été").unwrap();
    assert_eq!(ete["geometry"]["type"], "MultiPolygon");
    assert_eq!(ete["geometry"]["coordinates"][0].as_array().unwrap().len(), 2, "outer ring and its hole");
    // The parcel split at the antimeridian is in the tiles at both ends,
    // not in every tile between them.
    let (west, east, middle) =
        (get("parcels", 3, 0, 4).await, get("parcels", 3, 15, 4).await, get("parcels", 3, 8, 4).await);
    assert!(names(&west).contains(&"C".to_owned()) && names(&east).contains(&"C".to_owned()));
    assert!(!names(&middle).contains(&"C".to_owned()));
    daemon.stop(&[]).unwrap();
}

fn assert_rejected(manifest: &Path, expected: &[&str]) {
    let (code, stderr) = check(manifest).unwrap();
    assert_eq!(code, 2, "{stderr}");
    for text in expected {
        assert!(stderr.contains(text), "error should mention {text:?}:\n{stderr}");
    }
}

#[test]
fn torn_shapefiles_are_rejected_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let shp = shapefile(dir.path(), "parcels", PARCELS);
    let m = manifest(dir.path(), &[("parcels", &shp)]);
    let (shx, dbf) = (shp.with_extension("shx"), shp.with_extension("dbf"));
    let (shp_bytes, shx_bytes, dbf_bytes) =
        (std::fs::read(&shp).unwrap(), std::fs::read(&shx).unwrap(), std::fs::read(&dbf).unwrap());

    std::fs::write(&shp, &shp_bytes[..shp_bytes.len() - 40]).unwrap();
    assert_rejected(&m, &["source 'parcels'", "truncated or torn .shp", shp.to_str().unwrap()]);
    std::fs::write(&shp, &shp_bytes).unwrap();

    // Without its .shx the index is rebuilt from the records (as GDAL's
    // SHAPE_RESTORE_SHX does): read, with a warning in the state. While a
    // QGIS repack is under way (`_packed` beside it) the same file is torn.
    std::fs::remove_file(&shx).unwrap();
    let (code, stderr) = check(&m).unwrap();
    assert_eq!(code, 0, "a shapefile without its .shx: {stderr}");
    let packed = shp.with_file_name("parcels_packed.shp");
    std::fs::write(&packed, &shp_bytes).unwrap();
    let (code, _) = check(&m).unwrap();
    assert_ne!(code, 0, "a .shx missing during a repack is a writer at work");
    std::fs::remove_file(&packed).unwrap();
    std::fs::write(&shx, &shx_bytes).unwrap();

    let mut wrong = dbf_bytes.clone();
    wrong[4..8].copy_from_slice(&12u32.to_le_bytes());
    std::fs::write(&dbf, &wrong).unwrap();
    assert_rejected(
        &m,
        &["source 'parcels'", "invalid record count 12 in the .dbf (the .shx indexes 4)", dbf.to_str().unwrap()],
    );
    std::fs::write(&dbf, &dbf_bytes).unwrap();

    let (code, stderr) = check(&m).unwrap();
    assert_eq!(code, 0, "restored: {stderr}");
}

fn kml_manifest(dir: &Path, sources: &[(&str, &Path)]) -> PathBuf {
    let mut text = String::from("[scene]\nname = \"kml\"\n");
    for (id, path) in sources {
        let _ = write!(text, "\n[[source]]\nid = \"{id}\"\nkind = \"kml\"\npath = \"{}\"\n", path.display());
    }
    fixtures::write_manifest(dir, &text).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shared_kml_files_load_with_the_counts_ogr_reports() {
    let Some(data) = relief_tests::shared_data("shared_kml_files_load_with_the_counts_ogr_reports") else { return };
    let dir = tempfile::tempdir().unwrap();
    let files = [
        ("samples", data.join("kml/kmlsamples.kml")),
        ("modes", data.join("kml/all-altitudemodes.kml")),
        ("gnis", data.join("kml/gnis-ak-first-101.kml")),
    ];
    let sources: Vec<(&str, &Path)> = files.iter().map(|(id, p)| (*id, p.as_path())).collect();
    let daemon = Reliefd::start(&kml_manifest(dir.path(), &sources), &[]).unwrap();
    for (id, path) in &files {
        let d = details(&daemon, id).await;
        assert_eq!(d["features"].parse::<u64>().unwrap(), ogr_count(path), "{id}: {d:?}");
    }
    let modes = details(&daemon, "modes").await;
    assert!(modes.contains_key("network_links_not_followed"), "{modes:?}");
    // Altitude modes and extrude come through as properties.
    let fc = tiles::geojson(&tiles::get(daemon.channel().await.unwrap(), "samples", (0, 0, 0)).await.unwrap());
    let modes: Vec<&str> =
        fc["features"].as_array().unwrap().iter().filter_map(|f| f["properties"]["altitude_mode"].as_str()).collect();
    for m in ["clampToGround", "relativeToGround", "absolute"] {
        assert!(modes.contains(&m), "{m} missing from {modes:?}");
    }
    let holed = fc["features"].as_array().unwrap().iter().find(|f| f["properties"]["name"] == "The Pentagon").unwrap();
    assert_eq!(holed["geometry"]["coordinates"][0].as_array().unwrap().len(), 2, "outer ring and one hole");
    assert_eq!(holed["properties"]["extrude"], "true");
    daemon.stop(&[]).unwrap();
}

fn kmz(path: &Path, entries: &[(&str, &[u8])]) {
    let mut zip = zip::ZipWriter::new(std::fs::File::create(path).unwrap());
    for (name, bytes) in entries {
        zip.start_file(
            *name,
            zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated),
        )
        .unwrap();
        std::io::Write::write_all(&mut zip, bytes).unwrap();
    }
    zip.finish().unwrap();
}

const ONE_PLACEMARK: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<kml xmlns="http://www.opengis.net/kml/2.2"><Document><Placemark><name>here</name><Point><coordinates>10.5,45.5,0</coordinates></Point></Placemark></Document></kml>"#;

#[test]
fn kmz_archives_are_read_and_hostile_kml_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.kmz");
    kmz(&good, &[("doc.kml", ONE_PLACEMARK.as_bytes()), ("files/icon.png", b"png")]);
    let (code, stderr) = check(&kml_manifest(dir.path(), &[("kmz", &good)])).unwrap();
    assert_eq!(code, 0, "{stderr}");

    type Case<'a> = (&'a str, Box<dyn Fn(&Path)>, &'a str);
    let cases: Vec<Case> = vec![
        (
            "broken.kml",
            Box::new(|p: &Path| std::fs::write(p, "<kml><Document><Placemark><name>x</Placemark></kml>").unwrap()),
            "malformed KML",
        ),
        (
            "empty.kmz",
            Box::new(|p: &Path| kmz(p, &[("files/readme.txt", b"no kml here")])),
            "KMZ holds no .kml document",
        ),
        ("bomb.kmz", Box::new(|p: &Path| kmz(p, &[("doc.kml", &vec![b' '; 20 << 20])])), "refused as a zip bomb"),
        (
            "laughs.kml",
            Box::new(|p: &Path| {
                let mut lol = String::from("<?xml version=\"1.0\"?>\n<!DOCTYPE kml [\n<!ENTITY lol \"lol\">\n");
                for i in 1..10 {
                    let _ = writeln!(
                        lol,
                        "<!ENTITY lol{i} \"{}\">",
                        format!("&lol{};", if i == 1 { String::new() } else { (i - 1).to_string() }).repeat(10)
                    );
                }
                lol += "]>\n<kml><Document><name>&lol9;</name></Document></kml>\n";
                std::fs::write(p, lol).unwrap();
            }),
            "refused, they are how entity-expansion attacks work",
        ),
        ("notzip.kmz", Box::new(|p: &Path| std::fs::write(p, "plain text").unwrap()), "not a KMZ (zip) archive"),
    ];
    for (name, make, expected) in cases {
        let path = dir.path().join(name);
        make(&path);
        let (code, stderr) = check(&kml_manifest(dir.path(), &[("bad", &path)])).unwrap();
        assert_eq!(code, 2, "{name}: {stderr}");
        for text in ["source 'bad'", "field 'path'", expected, path.to_str().unwrap()] {
            assert!(stderr.contains(text), "{name}: {text:?} missing from {stderr}");
        }
    }
}

/// WGS84 area of the cell between latitudes `lat0` and `lat1` and `dlon`
/// degrees wide (the authalic zone formula).
fn cell_area_m2(lat0: f64, lat1: f64, dlon: f64) -> f64 {
    let (a, f): (f64, f64) = (6_378_137.0, 1.0 / 298.257_223_563);
    let e2 = f * (2.0 - f);
    let (e, b2) = (e2.sqrt(), a * a * (1.0 - e2));
    let zone = |lat: f64| {
        let s = lat.to_radians().sin();
        s / (1.0 - e2 * s * s) + (e * s).atanh() / e
    };
    b2 * dlon.to_radians() / 2.0 * (zone(lat1) - zone(lat0)).abs()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rasterized_area_matches_the_geodesic_area_within_one_percent() {
    use geo::{GeodesicArea, Orient};
    // An irregular parcel with a hole, at 45 N.
    let outer = [(10.02, 45.01), (10.41, 45.03), (10.47, 45.38), (10.2, 45.46), (10.05, 45.3), (10.02, 45.01)];
    let hole = [(10.2, 45.15), (10.3, 45.15), (10.3, 45.25), (10.2, 45.25), (10.2, 45.15)];
    let ring = |r: &[(f64, f64)]| r.iter().map(|(x, y)| format!("[{x}, {y}]")).collect::<Vec<_>>().join(", ");
    let geojson = format!(
        r#"{{"type": "FeatureCollection", "features": [{{"type": "Feature", "properties": {{"name": "p"}}, "geometry": {{"type": "Polygon", "coordinates": [[{}], [{}]]}}}}]}}"#,
        ring(&outer),
        ring(&hole)
    );
    let dir = tempfile::tempdir().unwrap();
    let shp = shapefile(dir.path(), "parcel", &geojson);
    let manifest = fixtures::write_manifest(
        dir.path(),
        &format!(
            "[scene]\nname = \"area\"\n\n[[source]]\nid = \"parcel\"\nkind = \"shapefile\"\npath = \"{}\"\n\n[[source]]\nid = \"drawn\"\nkind = \"rasterize\"\ninputs = [\"parcel\"]\nfill = \"#ff0000ff\"\nstroke = \"none\"\n\n[layers]\ncolor = \"drawn\"\n",
            shp.display()
        ),
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let level = 10u32;
    let span = 180.0 / f64::from(1u32 << level);
    let texel = span / 256.0;
    let mut area = 0.0;
    for y in ((90.0 - 45.5) / span) as u32..=((90.0 - 45.0) / span) as u32 {
        for x in ((10.0 + 180.0) / span) as u32..=((10.5 + 180.0) / span) as u32 {
            let img = tiles::image(&tiles::get(channel.clone(), "drawn", (level, x, y)).await.unwrap());
            let north = 90.0 - f64::from(y) * span;
            for j in 1..257u32 {
                let lat1 = north - f64::from(j - 1) * texel;
                let cell = cell_area_m2(lat1 - texel, lat1, texel);
                for i in 1..257u32 {
                    area += f64::from(img.get_pixel(i, j)[3]) / 255.0 * cell;
                }
            }
        }
    }
    // Exterior anticlockwise, hole clockwise, as geodesic areas expect.
    let polygon = geo::Polygon::new(geo::LineString::from(outer.to_vec()), vec![geo::LineString::from(hole.to_vec())])
        .orient(geo::orient::Direction::Default);
    let truth = polygon.geodesic_area_unsigned();
    assert!(truth > 1e8 && truth < 1e10, "{truth}");
    let error = (area - truth).abs() / truth;
    eprintln!("rasterized {area:.0} m2, geodesic {truth:.0} m2, error {:.4}%", error * 100.0);
    assert!(error < 0.01, "rasterized {area:.0} m2 vs geodesic {truth:.0} m2: {:.3}%", error * 100.0);
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn natural_earth_countries_reach_the_pole_and_do_not_smear() {
    let Some(data) = relief_tests::shared_data("natural_earth_countries_reach_the_pole_and_do_not_smear") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let manifest = fixtures::write_manifest(
        dir.path(),
        &format!(
            "[scene]\nname = \"world\"\n\n[[source]]\nid = \"countries\"\nkind = \"shapefile\"\npath = \"{}\"\n\n[[source]]\nid = \"drawn\"\nkind = \"rasterize\"\ninputs = [\"countries\"]\nfill = \"#ff0000ff\"\nstroke = \"none\"\n",
            data.join("shp/naturalearth_lowres.shp").display()
        ),
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let alpha = async |level: u32, x: u32, y: u32| {
        tiles::image(&tiles::get(channel.clone(), "drawn", (level, x, y)).await.unwrap())
    };
    // Antarctica covers the last texel row above -90 at every longitude.
    for x in 0..8 {
        let img = alpha(2, x, 3).await;
        assert!((1..257).all(|i| img.get_pixel(i, 256)[3] > 0), "tile {x}: a gap at the south pole");
    }
    // Fiji and Russia cross the antimeridian: open Pacific tiles stay empty.
    for (x, y) in [(1u32, 2u32), (1, 4)] {
        let img = alpha(3, x, y).await;
        let covered = img.pixels().filter(|p| p[3] > 0).count() as f64 / f64::from(img.width() * img.height());
        assert!(covered < 0.005, "tile 3/{x}/{y} is {:.1}% covered: a smear", covered * 100.0);
    }
    // While Fiji itself shows at both ends.
    let (west, east) = (alpha(3, 0, 4).await, alpha(3, 15, 4).await);
    assert!(west.pixels().any(|p| p[3] > 0) && east.pixels().any(|p| p[3] > 0));
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_moved_parcel_dirties_only_where_it_was_and_is() {
    use relief_tests::edit::{self, Events};
    let dir = tempfile::tempdir().unwrap();
    let shp = shapefile(dir.path(), "parcels", PARCELS);
    let manifest = fixtures::write_manifest(
        dir.path(),
        &format!(
            "[scene]\nname = \"edits\"\n\n[[source]]\nid = \"parcels\"\nkind = \"shapefile\"\npath = \"{}\"\n\n[[source]]\nid = \"drawn\"\nkind = \"rasterize\"\ninputs = [\"parcels\"]\n\n[layers]\ncolor = \"drawn\"\n",
            shp.display()
        ),
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let events = Events::follow(channel.clone()).await.unwrap();
    // Tiles over parcel B (11..11.3 E) and far away, over parcel C (Fiji).
    let near = [(8u32, 271u32, 63u32), (8, 272, 63)];
    let far = (8u32, 509u32, 152u32);
    let mut before = Vec::new();
    for k in near.iter().chain([&far]) {
        before.push(edit::tile_hash(channel.clone(), "drawn", *k).await.unwrap());
    }
    // Parcel B moves 0.1 degrees north; the rest is rewritten unchanged, by
    // ogr2ogr replacing the files (delete, create, stream, close).
    let moved = PARCELS.replace(
        "[[[11.0, 45.0], [11.3, 45.0], [11.3, 45.3], [11.0, 45.0]]]",
        "[[[11.0, 45.1], [11.3, 45.1], [11.3, 45.4], [11.0, 45.1]]]",
    );
    assert_ne!(moved, PARCELS);
    let src = dir.path().join("moved.geojson");
    std::fs::write(&src, moved).unwrap();
    let out = Command::new("ogr2ogr")
        .args(["-q", "-overwrite", "-f", "ESRI Shapefile", "-lco", "ENCODING=UTF-8"])
        .arg(&shp)
        .arg(&src)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let g = events.generation(2).await.unwrap();
    let parcels = g.dirty.iter().find(|d| d.source_id == "parcels").unwrap();
    let boxes: Vec<[f64; 4]> = parcels.extents.iter().map(|e| [e.min_x, e.min_y, e.max_x, e.max_y]).collect();
    assert_eq!(
        boxes,
        vec![[11.0, 45.0, 11.3, 45.3], [11.0, 45.1, 11.3, 45.4]],
        "the moved parcel's old and new boxes, nothing else"
    );
    assert!(g.tiles_carried_over >= 1, "{g:?}");
    let mut after = Vec::new();
    for k in near.iter().chain([&far]) {
        after.push(edit::tile_hash(channel.clone(), "drawn", *k).await.unwrap());
    }
    assert_eq!(after[2], before[2], "the far tile is untouched");
    assert!(after[..2] != before[..2], "the parcel moved on the near tiles");
    assert!(events.errors().is_empty(), "{:?}", events.errors());
    daemon.stop(&[]).unwrap();
}
