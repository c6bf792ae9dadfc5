//! Files GDAL and OGR read that relief used to refuse: read, with a
//! warning in the source's state, while the daemon keeps serving; and
//! files torn for real still refused, naming the file and what is wrong.
//!
//! - a JPEG Cloud-Optimized GeoTIFF whose lossy overviews differ from its
//!   base beyond what JPEG explains: the overviews left out, the coarse
//!   levels halved from the base (the same tiles as GDAL's read of the
//!   base, saved lossless, gives);
//! - a shapefile whose .shx header length is off by less than an entry,
//!   and one whose .shp has a stray byte after its last record: the same
//!   features as OGR reads;
//! - a KML with one placemark whose inner tags do not match (which OGR
//!   refuses whole): the whole placemarks read, as OGR reads them without
//!   the torn one, with a warning naming its lines;
//! - ArcGIS's side files beside a shapefile (.sbn, .sbx, .shp.xml, locks):
//!   never data, and writing them reads nothing.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use gdal::vector::LayerAccess;
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::{Reliefd, check};
use relief_tests::fixtures::{self, Texture};
use relief_tests::tiles;

fn gdal_translate(args: &[&str]) {
    let out = Command::new("gdal_translate").arg("-q").args(args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// The state of source `id`.
async fn state(daemon: &Reliefd, id: &str) -> pb::SourceState {
    let channel = daemon.channel().await.unwrap();
    let state = SceneServiceClient::new(channel).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    state.sources.into_iter().find(|s| s.id == id).unwrap_or_else(|| panic!("no source '{id}' in the state"))
}

/// The geodetic grid's tile (x, y) at `level` holding (lon, lat): tiles of
/// 180 / 2^level degrees from (-180, 90).
fn tile_at(level: u32, lon: f64, lat: f64) -> (u32, u32, u32) {
    let side = 180.0 / f64::from(1u32 << level);
    (level, ((lon + 180.0) / side) as u32, ((90.0 - lat) / side) as u32)
}

/// A scene of `gdal` sources, (id, file) each.
fn rasters(dir: &Path, sources: &[(&str, &str)]) -> PathBuf {
    let mut text = String::from("[scene]\nname = \"tolerant\"\n");
    for (id, file) in sources {
        let _ = write!(text, "\n[[source]]\nid = \"{id}\"\nkind = \"gdal\"\npath = \"{file}\"\n");
    }
    fixtures::write_manifest(dir, &text).unwrap()
}

/// Serves `cog` (a JPEG COG) beside GDAL's read of its base saved
/// lossless; checks the warning (required when `must_warn`), and that the
/// levels read from the base (every level, when the overviews were left
/// out) serve the same colours from both: the base as GDAL reads it,
/// halved alike. The real orthophoto's overviews lie within the tolerance.
async fn jpeg_cog_is_served_as_its_base(dir: &Path, cog: &Path, probe: (f64, f64), must_warn: bool) {
    let base = dir.join("base.tif");
    // GDAL reading the base (no overviews copied), saved without loss.
    gdal_translate(&["-co", "COMPRESS=NONE", "-co", "TILED=YES", cog.to_str().unwrap(), base.to_str().unwrap()]);
    let manifest = rasters(dir, &[("photo", cog.to_str().unwrap()), ("base", "base.tif")]);
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let photo = state(&daemon, "photo").await;
    assert!(must_warn <= !photo.warnings.is_empty(), "a warning expected: {:?}", photo.details);
    // Within the tolerance the file's overviews serve the coarse levels:
    // only the levels read from the base are GDAL's base then.
    let levels = if let [warning] = photo.warnings.as_slice() {
        assert!(warning.starts_with(&format!("{}: its first overview (level 1, ", cog.display())), "{warning}");
        assert!(warning.contains("differs from its base beyond what its compression (JPEG, quality 75)"), "{warning}");
        assert!(warning.contains("sampled pixels (") && warning.contains("%) lie more than 8 outside"), "{warning}");
        8..=14
    } else {
        assert!(photo.warnings.is_empty(), "{:?}", photo.warnings);
        13..=14
    };
    // Checked, where the file's first overview is one relief uses.
    if must_warn || photo.details.contains_key("overview_check") {
        assert!(photo.details["overview_check"].contains("tolerance of 8"), "{:?}", photo.details);
    }
    assert!(state(&daemon, "base").await.warnings.is_empty());
    let channel = daemon.channel().await.unwrap();
    for level in levels {
        let key = tile_at(level, probe.0, probe.1);
        let photo = tiles::image(&tiles::get(channel.clone(), "photo", key).await.unwrap());
        let base = tiles::image(&tiles::get(channel.clone(), "base", key).await.unwrap());
        assert!(photo.pixels().any(|p| p[3] > 0), "tile {key:?} covers the image");
        assert!(photo == base, "tile {key:?}: the JPEG COG's colours differ from GDAL's read of its base");
    }
    daemon.stop(&["its first overview"]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_jpeg_cog_with_lossy_overviews_is_served_from_its_base_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let cog =
        fixtures::write_textured_cog(&dir.path().join("photo.tif"), Texture::Fine, &["COMPRESS=JPEG", "QUALITY=75"])
            .unwrap();
    jpeg_cog_is_served_as_its_base(dir.path(), &cog, (7.02, 45.98), true).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_shared_orthophoto_as_a_jpeg_cog_is_served_from_its_base() {
    let Some(data) = relief_tests::shared_data("the_shared_orthophoto_as_a_jpeg_cog_is_served_from_its_base") else {
        return;
    };
    let source = data.join("imagery/RGB.byte.tif");
    if !source.exists() {
        eprintln!("{} is absent: test skipped", source.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cog = dir.path().join("photo.tif");
    gdal_translate(&[
        "-of",
        "COG",
        "-co",
        "COMPRESS=JPEG",
        "-co",
        "QUALITY=75",
        "-co",
        "BLOCKSIZE=256",
        source.to_str().unwrap(),
        cog.to_str().unwrap(),
    ]);
    // Where the image is, from GDAL: its centre in longitude and latitude.
    let info = Command::new("gdalinfo").args(["-json", cog.to_str().unwrap()]).output().unwrap();
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    let centre = &info["wgs84Extent"]["coordinates"][0];
    let corners: Vec<(f64, f64)> =
        centre.as_array().unwrap().iter().map(|c| (c[0].as_f64().unwrap(), c[1].as_f64().unwrap())).collect();
    let n = corners.len() as f64;
    let probe = (corners.iter().map(|c| c.0).sum::<f64>() / n, corners.iter().map(|c| c.1).sum::<f64>() / n);
    jpeg_cog_is_served_as_its_base(dir.path(), &cog, probe, false).await;
}

const POINTS: &str = r#"{"type":"FeatureCollection","features":[
{"type":"Feature","properties":{"name":"p0"},"geometry":{"type":"Point","coordinates":[7.1,46.1]}},
{"type":"Feature","properties":{"name":"p1"},"geometry":{"type":"Point","coordinates":[7.2,46.15]}},
{"type":"Feature","properties":{"name":"p2"},"geometry":{"type":"Point","coordinates":[7.3,46.2]}},
{"type":"Feature","properties":{"name":"p3"},"geometry":{"type":"Point","coordinates":[7.4,46.25]}},
{"type":"Feature","properties":{"name":"p4"},"geometry":{"type":"Point","coordinates":[7.5,46.3]}},
{"type":"Feature","properties":{"name":"p5"},"geometry":{"type":"Point","coordinates":[7.6,46.35]}},
{"type":"Feature","properties":{"name":"p6"},"geometry":{"type":"Point","coordinates":[7.7,46.4]}},
{"type":"Feature","properties":{"name":"p7"},"geometry":{"type":"Point","coordinates":[7.8,46.45]}},
{"type":"Feature","properties":{"name":"p8"},"geometry":{"type":"Point","coordinates":[7.9,46.5]}},
{"type":"Feature","properties":{"name":"p9"},"geometry":{"type":"Point","coordinates":[8.0,46.55]}}]}"#;

/// The first `n` of `POINTS` as the shapefile `dir/name.shp`, through ogr2ogr.
fn points(dir: &Path, name: &str, n: usize) -> PathBuf {
    let all: serde_json::Value = serde_json::from_str(POINTS).unwrap();
    let mut some = all.clone();
    some["features"] = serde_json::Value::Array(all["features"].as_array().unwrap()[..n].to_vec());
    relief_tests::vectors::shapefile(dir, name, &some.to_string()).unwrap()
}

/// (name, lon, lat) of every feature, as OGR reads the shapefile.
fn ogr_features(shp: &Path) -> Vec<(String, f64, f64)> {
    let ds = gdal::Dataset::open(shp).unwrap();
    let mut layer = ds.layer(0).unwrap();
    layer
        .features()
        .map(|f| {
            let name = f.field_as_string(f.field_index("name").unwrap()).unwrap().unwrap_or_default();
            let (x, y, _) = f.geometry().unwrap().get_point(0);
            (name, x, y)
        })
        .collect()
}

/// (name, lon, lat) of every feature of the level-0 tiles of `source`.
async fn relief_features(daemon: &Reliefd, source: &str) -> Vec<(String, f64, f64)> {
    let channel = daemon.channel().await.unwrap();
    let mut out = Vec::new();
    for x in 0..2 {
        let fc = tiles::geojson(&tiles::get(channel.clone(), source, (0, x, 0)).await.unwrap());
        for f in fc["features"].as_array().unwrap() {
            let c = &f["geometry"]["coordinates"];
            out.push((
                f["properties"]["name"].as_str().unwrap().to_owned(),
                c[0].as_f64().unwrap(),
                c[1].as_f64().unwrap(),
            ));
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

fn shapefiles(dir: &Path, sources: &[(&str, &Path)]) -> PathBuf {
    let mut text = String::from("[scene]\nname = \"tolerant\"\n");
    for (id, shp) in sources {
        let _ = write!(text, "\n[[source]]\nid = \"{id}\"\nkind = \"shapefile\"\npath = \"{}\"\n", shp.display());
    }
    fixtures::write_manifest(dir, &text).unwrap()
}

/// Sets the big-endian file length (in 16-bit words) of a .shp or .shx header.
fn set_header_bytes(path: &Path, len: usize) {
    let mut bytes = std::fs::read(path).unwrap();
    bytes[24..28].copy_from_slice(&u32::try_from(len / 2).unwrap().to_be_bytes());
    std::fs::write(path, bytes).unwrap();
}

async fn same_as_ogr(daemon: &Reliefd, id: &str, shp: &Path, count: usize) -> pb::SourceState {
    let want = ogr_features(shp);
    assert_eq!(want.len(), count, "OGR reads every feature");
    let got = relief_features(daemon, id).await;
    assert_eq!(got.len(), want.len(), "{got:?} vs OGR's {want:?}");
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g.0, w.0);
        assert!((g.1 - w.1).abs() < 1e-9 && (g.2 - w.2).abs() < 1e-9, "{g:?} vs OGR's {w:?}");
    }
    let s = state(daemon, id).await;
    assert_eq!(s.details["features"], count.to_string());
    s
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_shx_header_length_off_and_a_stray_byte_after_the_last_record_are_read_as_ogr_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let wells = points(dir.path(), "wells", 8);
    let shx = wells.with_extension("shx");
    let len = std::fs::read(&shx).unwrap().len();
    set_header_bytes(&shx, len + 2);
    let springs = points(dir.path(), "springs", 10);
    let mut bytes = std::fs::read(&springs).unwrap();
    let shp_len = bytes.len();
    bytes.push(0);
    std::fs::write(&springs, &bytes).unwrap();

    let daemon = Reliefd::start(&shapefiles(dir.path(), &[("wells", &wells), ("springs", &springs)]), &[]).unwrap();
    let s = same_as_ogr(&daemon, "wells", &wells, 8).await;
    assert_eq!(
        s.warnings,
        [format!(
            "the .shx header says {} bytes, the file has {len}: its 8 entries read, as GDAL does ({})",
            len + 2,
            shx.display()
        )]
    );
    let s = same_as_ogr(&daemon, "springs", &springs, 10).await;
    assert_eq!(
        s.warnings,
        [format!(
            "the .shp has 1 byte past the {shp_len} its header says, not a record: ignored, as GDAL does ({})",
            springs.display()
        )]
    );
    daemon.stop(&[]).unwrap();
}

/// `reliefd check` refuses the manifest, saying every one of `expected`.
fn assert_refused(manifest: &Path, expected: &[&str]) {
    let (code, stderr) = check(manifest).unwrap();
    assert_eq!(code, 2, "reliefd check should fail: {stderr}");
    for text in expected {
        assert!(stderr.contains(text), "error should mention {text:?}:\n{stderr}");
    }
}

#[test]
fn shapefiles_torn_for_real_are_still_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let wells = points(dir.path(), "wells", 8);
    let m = shapefiles(dir.path(), &[("wells", &wells)]);
    let shx = wells.with_extension("shx");
    let (shp_bytes, shx_bytes) = (std::fs::read(&wells).unwrap(), std::fs::read(&shx).unwrap());

    // A .shx whose last entry points outside the .shp.
    let mut bad = shx_bytes.clone();
    let last = bad.len() - 8;
    bad[last..last + 4].copy_from_slice(&u32::try_from(shp_bytes.len()).unwrap().to_be_bytes());
    std::fs::write(&shx, &bad).unwrap();
    assert_refused(
        &m,
        &["source 'wells'", "the last .shx entry points past the end of the .shp", shx.to_str().unwrap()],
    );
    std::fs::write(&shx, &shx_bytes).unwrap();

    // A .shx header promising one entry more than it holds: being extended.
    set_header_bytes(&shx, shx_bytes.len() + 8);
    assert_refused(&m, &["source 'wells'", "torn .shx: its header says", shx.to_str().unwrap()]);
    std::fs::write(&shx, &shx_bytes).unwrap();

    // A record appended before the header counts it (QGIS mid-save).
    set_header_bytes(&wells, shp_bytes.len() - 28);
    assert_refused(&m, &["source 'wells'", "torn .shp: whole records lie past", wells.to_str().unwrap()]);

    // Every record torn: the .shp cut inside its first record.
    std::fs::write(&wells, &shp_bytes[..110]).unwrap();
    assert_refused(&m, &["source 'wells'", "truncated or torn .shp", wells.to_str().unwrap()]);
}

/// Three whole placemarks and, between them, one whose inner tags do not
/// match (`<Data>` closed by `</Dta>`): OGR refuses the whole file; relief
/// reads the whole placemarks, as OGR reads them once the torn one is gone.
const KML_TORN: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<kml xmlns="http://www.opengis.net/kml/2.2">
<Document>
<Placemark><name>a</name><description>one <b>bold</i> line</description><Point><coordinates>10.20,45.2</coordinates></Point></Placemark>
<Placemark><name>torn</name><ExtendedData><Data name="x"><value>1</value></Dta>
</ExtendedData><Point><coordinates>10.25,45.2</coordinates></Point></Placemark>
<Placemark><name>b</name><Point><coordinates>10.30,45.2</coordinates></Point></Placemark>
<Placemark><name>c</name><Point><coordinates>10.35,45.2</coordinates></Point></Placemark>
</Document>
</kml>
"#;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_kml_placemark_with_mismatched_tags_is_left_out_and_the_whole_ones_read_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let kml = dir.path().join("sites.kml");
    std::fs::write(&kml, KML_TORN).unwrap();
    // OGR's reference: the same file without the torn placemark (and with
    // its description's stray HTML escaped, which relief reads as CDATA).
    let whole: String = KML_TORN
        .lines()
        .filter(|l| !l.contains("<name>torn</name>") && !l.starts_with("</ExtendedData>"))
        .map(|l| l.replace("<b>bold</i>", "&lt;b&gt;bold&lt;/i&gt;") + "\n")
        .collect();
    let reference = dir.path().join("whole.kml");
    std::fs::write(&reference, whole).unwrap();
    assert!(gdal::Dataset::open(&kml).is_err(), "OGR refuses the torn file here");
    let ds = gdal::Dataset::open(&reference).unwrap();
    let mut layer = ds.layer(0).unwrap();
    let mut want: Vec<(String, f64, f64)> = layer
        .features()
        .map(|f| {
            let name = f.field_as_string(f.field_index("Name").unwrap()).unwrap().unwrap_or_default();
            let (x, y, _) = f.geometry().unwrap().get_point(0);
            (name, x, y)
        })
        .collect();
    want.sort_by(|a, b| a.0.cmp(&b.0));

    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"kml\"\n\n[[source]]\nid = \"sites\"\nkind = \"kml\"\npath = \"sites.kml\"\n",
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let got = relief_features(&daemon, "sites").await;
    assert_eq!(got.len(), 3, "{got:?}");
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g.0, w.0);
        assert!((g.1 - w.1).abs() < 1e-9 && (g.2 - w.2).abs() < 1e-9, "{g:?} vs OGR's {w:?}");
    }
    let s = state(&daemon, "sites").await;
    assert!(s.error.is_empty(), "{s:#?}");
    assert_eq!(
        s.warnings,
        ["the placemark at lines 5-6 (<Data> opened at line 5 is closed by </Dta> at line 5) was left out: its tags \
          do not match; the other placemarks are read"]
    );
    daemon.stop(&[]).unwrap();

    // Every placemark torn: refused, naming the file and the lines.
    let all_torn = KML_TORN.replace("</Point></Placemark>", "</Pont></Placemark>");
    std::fs::write(&kml, all_torn).unwrap();
    assert_refused(&manifest, &["source 'sites'", "every placemark is torn", "line 4", kml.to_str().unwrap()]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn arcgis_side_files_beside_a_shapefile_are_not_data_and_their_writes_read_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let wells = points(dir.path(), "wells", 8);
    let daemon = Reliefd::start(&shapefiles(dir.path(), &[("wells", &wells)]), &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let counters = |s: &pb::SceneState| s.counters.clone().unwrap_or_default();
    let get = || async {
        SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner()
    };
    let before = get().await;

    // What ArcGIS writes beside a shapefile it shows and indexes: spatial
    // indexes, metadata, its schema and edit locks; each written twice.
    let side = [
        "wells.sbn",
        "wells.sbx",
        "wells.shp.xml",
        "wells.shp.DESKTOP-7.4242.9000.sr.lock",
        "wells.shp.DESKTOP-7.4242.9000.ed.lock",
    ];
    for round in 0..2 {
        for name in side {
            std::fs::write(dir.path().join(name), format!("ArcGIS {round}")).unwrap();
        }
        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
    }
    for name in &side[4..] {
        std::fs::remove_file(dir.path().join(name)).unwrap();
    }
    tokio::time::sleep(std::time::Duration::from_millis(1500)).await;
    let after = get().await;
    assert_eq!(after.generation, before.generation);
    assert_eq!(counters(&after).source_reads, counters(&before).source_reads, "a side file caused a read");
    let s = after.sources.iter().find(|s| s.id == "wells").unwrap();
    assert!(s.files.iter().all(|f| !side.iter().any(|n| f.ends_with(n))), "{:?}", s.files);
    assert!(s.error.is_empty() && s.warnings.is_empty(), "{s:#?}");

    // A write to the data itself is read (the counter counts).
    let mut bytes = std::fs::read(&wells).unwrap();
    bytes.push(0);
    std::fs::write(&wells, bytes).unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(20);
    while counters(&get().await).source_reads == counters(&before).source_reads {
        assert!(std::time::Instant::now() < deadline, "the .shp write was never read");
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
    daemon.stop(&[]).unwrap();
}
