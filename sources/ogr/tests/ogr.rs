//! The `ogr` source against real files written through GDAL.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use gdal::spatial_ref::SpatialRef;
use gdal::vector::{Geometry as OgrGeometry, LayerAccess, LayerOptions, OGRFieldType, OGRwkbGeometryType};
use gdal::{Dataset, DatasetOptions, DriverManager, GdalOpenFlags};
use relief_source::{
    Feature, Geometry, OptionValue, Refresh, Source, SourceError, SourceSpec, TileGrid, VectorFormat, VectorRead,
};
use relief_source_ogr::{Ogr, OgrSource};

type Fields = &'static [(&'static str, OGRFieldType::Type)];

/// A layer to write: its fields, and per feature a WKT and field texts
/// (None: null).
struct LayerSpec {
    name: &'static str,
    ty: OGRwkbGeometryType::Type,
    fields: Fields,
    features: Vec<(&'static str, Vec<Option<&'static str>>)>,
}

const SITE_FIELDS: Fields = &[
    ("name", OGRFieldType::OFTString),
    ("visitors", OGRFieldType::OFTInteger64),
    ("height", OGRFieldType::OFTReal),
    ("opened", OGRFieldType::OFTDate),
];

fn sites() -> LayerSpec {
    LayerSpec {
        name: "sites",
        ty: OGRwkbGeometryType::wkbPoint25D,
        fields: SITE_FIELDS,
        features: vec![
            ("POINT Z (7.25 43.5 812.5)", vec![Some("col"), Some("1200"), Some("2.5"), Some("2024-05-01")]),
            ("POINT Z (-100 -40 3)", vec![Some("lake"), None, Some("0.1"), None]),
            ("POINT Z (120.125 10 0)", vec![Some("summit"), Some("-7"), Some("12"), Some("1999-12-31")]),
        ],
    }
}

fn roads() -> LayerSpec {
    LayerSpec {
        name: "roads",
        ty: OGRwkbGeometryType::wkbLineString,
        fields: &[("ref", OGRFieldType::OFTString), ("lanes", OGRFieldType::OFTInteger)],
        features: vec![
            ("LINESTRING (0 0, 1 1, 2 0.5)", vec![Some("A1"), Some("2")]),
            ("LINESTRING (10 10, 11 12)", vec![Some("B2"), None]),
        ],
    }
}

fn parcels() -> LayerSpec {
    LayerSpec {
        name: "parcels",
        ty: OGRwkbGeometryType::wkbPolygon,
        fields: &[("use", OGRFieldType::OFTString), ("area_m2", OGRFieldType::OFTReal)],
        features: vec![(
            "POLYGON ((0 0, 10 0, 10 10, 0 10, 0 0), (2 2, 2 4, 4 4, 4 2, 2 2))",
            vec![Some("farm"), Some("96.000001")],
        )],
    }
}

/// Writes `layers` into a new dataset with GDAL's `driver`.
fn write(driver: &str, path: &Path, layers: &[LayerSpec]) -> PathBuf {
    let driver = DriverManager::get_driver_by_name(driver).expect("driver built into GDAL");
    let mut ds = driver.create_vector_only(path).expect("dataset created");
    let srs = SpatialRef::from_epsg(4326).expect("EPSG:4326");
    // FlatGeobuf's spatial index would reorder the features.
    let options: &[&str] = if driver.short_name() == "FlatGeobuf" { &["SPATIAL_INDEX=NO"] } else { &[] };
    for spec in layers {
        let layer = ds
            .create_layer(LayerOptions { name: spec.name, srs: Some(&srs), ty: spec.ty, options: Some(options) })
            .expect("layer created");
        layer.create_defn_fields(spec.fields).expect("fields created");
        for (wkt, values) in &spec.features {
            let mut f = gdal::vector::Feature::new(layer.defn()).expect("feature");
            f.set_geometry(OgrGeometry::from_wkt(wkt).expect("valid WKT")).expect("geometry set");
            for (i, value) in values.iter().enumerate() {
                match value {
                    Some(v) => f.set_field_string(i, v).expect("field set"),
                    None => f.set_field_null(i).expect("field nulled"),
                }
            }
            f.create(&layer).expect("feature written");
        }
    }
    ds.close().expect("dataset closed");
    path.to_path_buf()
}

fn spec(path: &Path, options: &[(&str, &str)]) -> SourceSpec {
    SourceSpec {
        id: "test".into(),
        kind: "ogr".into(),
        paths: vec![path.to_path_buf()],
        inputs: Vec::new(),
        options: options.iter().map(|(k, v)| ((*k).to_owned(), OptionValue::Text((*v).to_owned()))).collect(),
    }
}

fn read(path: &Path, options: &[(&str, &str)]) -> Result<VectorRead, SourceError> {
    let spec = spec(path, options);
    Ogr::read(&spec, path, &Ogr::stamped(&spec, path)?)
}

/// A geometry with NaN (no z) made comparable.
fn comparable(g: &Geometry) -> String {
    format!("{g:?}")
}

fn props(pairs: &[(&str, &str)]) -> BTreeMap<String, String> {
    pairs.iter().map(|(k, v)| ((*k).to_owned(), (*v).to_owned())).collect()
}

fn assert_features(actual: &[Feature], expected: &[Feature]) {
    assert_eq!(actual.len(), expected.len(), "feature count");
    for (a, e) in actual.iter().zip(expected) {
        assert_eq!(a.id, e.id);
        assert_eq!(comparable(&a.geometry), comparable(&e.geometry), "feature {}", e.id);
        assert_eq!(a.properties, e.properties, "feature {}", e.id);
    }
}

const N: f64 = f64::NAN;

/// What `sites()` reads back as, with ids from `first_id`.
fn expected_sites(first_id: u64) -> Vec<Feature> {
    vec![
        Feature {
            id: first_id,
            geometry: Geometry::Points(vec![[7.25, 43.5, 812.5]]),
            properties: props(&[("name", "col"), ("visitors", "1200"), ("height", "2.5"), ("opened", "2024-05-01")]),
        },
        Feature {
            id: first_id + 1,
            geometry: Geometry::Points(vec![[-100.0, -40.0, 3.0]]),
            properties: props(&[("name", "lake"), ("height", "0.1")]),
        },
        Feature {
            id: first_id + 2,
            geometry: Geometry::Points(vec![[120.125, 10.0, 0.0]]),
            properties: props(&[("name", "summit"), ("visitors", "-7"), ("height", "12"), ("opened", "1999-12-31")]),
        },
    ]
}

fn three_layer_gpkg(dir: &Path) -> PathBuf {
    write("GPKG", &dir.join("scene.gpkg"), &[sites(), roads(), parcels()])
}

#[test]
fn geopackage_layers_read_back_as_written() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = three_layer_gpkg(dir.path());

    let sites = read(&path, &[("layer", "sites")]).expect("sites read");
    // GeoPackage FIDs start at 1.
    assert_features(&sites.features, &expected_sites(1));
    assert_eq!(sites.details["driver"], "GPKG");
    assert_eq!(sites.details["layer"], "sites");
    assert_eq!(sites.details["layers"], "sites, roads, parcels");
    assert_eq!(sites.details["features"], "3");
    assert_eq!(sites.details["null_geometries"], "0");
    assert_eq!(sites.details["fields"], "name:String, visitors:Integer64, height:Real, opened:Date");
    assert_eq!(sites.details["ids"], "OGR FIDs");
    assert!(sites.crs.contains("WGS 84"), "the layer's WKT: {}", sites.crs);
    assert_eq!(sites.crs_name, "EPSG:4326 (WGS 84)");
    assert_eq!(sites.files[0], path);

    let roads = read(&path, &[("layer", "roads")]).expect("roads read");
    assert_features(
        &roads.features,
        &[
            Feature {
                id: 1,
                geometry: Geometry::Lines(vec![vec![[0.0, 0.0, N], [1.0, 1.0, N], [2.0, 0.5, N]]]),
                properties: props(&[("ref", "A1"), ("lanes", "2")]),
            },
            Feature {
                id: 2,
                geometry: Geometry::Lines(vec![vec![[10.0, 10.0, N], [11.0, 12.0, N]]]),
                properties: props(&[("ref", "B2")]),
            },
        ],
    );

    let parcels = read(&path, &[("layer", "parcels")]).expect("parcels read");
    let ring = |c: &[(f64, f64)]| c.iter().map(|&(x, y)| [x, y, N]).collect::<Vec<_>>();
    assert_features(
        &parcels.features,
        &[Feature {
            id: 1,
            geometry: Geometry::Polygons(vec![vec![
                ring(&[(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0), (0.0, 0.0)]),
                ring(&[(2.0, 2.0), (2.0, 4.0), (4.0, 4.0), (4.0, 2.0), (2.0, 2.0)]),
            ]]),
            properties: props(&[("use", "farm"), ("area_m2", "96.000001")]),
        }],
    );
}

#[test]
fn one_layer_needs_no_layer_option_and_several_need_one() {
    let dir = tempfile::tempdir().expect("temp dir");
    let single = write("GPKG", &dir.path().join("single.gpkg"), &[roads()]);
    let read_single = read(&single, &[]).expect("a one-layer dataset needs no option");
    assert_eq!(read_single.details["layer"], "roads");

    let several = three_layer_gpkg(dir.path());
    let message = read(&several, &[]).expect_err("three layers and no choice").to_string();
    assert!(message.contains("3 layers (sites, roads, parcels)"), "{message}");
    assert!(message.contains("option 'layer'"), "{message}");
    assert!(message.ends_with(&several.display().to_string()), "{message}");

    let unknown = read(&several, &[("layers", "x")]).expect_err("unknown option").to_string();
    assert!(unknown.contains("unknown option"), "{unknown}");
}

#[test]
fn geojson_and_flatgeobuf_read_the_same_features() {
    let dir = tempfile::tempdir().expect("temp dir");
    let gpkg = read(&write("GPKG", &dir.path().join("sites.gpkg"), &[sites()]), &[]).expect("gpkg read");
    // Neither format keeps FIDs across edits: ids are the read order, from 0.
    let geojson = read(&write("GeoJSON", &dir.path().join("sites.geojson"), &[sites()]), &[]).expect("geojson read");
    assert_eq!(geojson.details["ids"], "read order");
    assert_features(&geojson.features, &expected_sites(0));
    for (a, b) in gpkg.features.iter().zip(&geojson.features) {
        assert_eq!(a.properties, b.properties);
    }
    let fgb = read(&write("FlatGeobuf", &dir.path().join("sites.fgb"), &[sites()]), &[]).expect("fgb read");
    assert_eq!(fgb.details["driver"], "FlatGeobuf");
    // FlatGeobuf has no date type: GDAL stores a date as a date-time at
    // midnight, and reads it back as one. Everything else must match.
    let mut fgb_features = fgb.features.clone();
    for f in &mut fgb_features {
        if let Some(opened) = f.properties.get_mut("opened") {
            *opened = opened.strip_suffix("T00:00:00").unwrap_or(opened).to_owned();
        }
    }
    assert_features(&fgb_features, &expected_sites(0));
}

#[test]
fn a_shapefile_reads_as_the_shapefile_source_reads_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut layer = parcels();
    layer.features.push(("POLYGON ((20 20, 30 20, 30 25, 20 20))", vec![Some("wood"), None]));
    let path = write("ESRI Shapefile", &dir.path().join("parcels.shp"), &[layer]);
    let via_ogr = read(&path, &[]).expect("read through OGR");
    let spec = SourceSpec { kind: "shapefile".into(), ..spec(&path, &[]) };
    let via_shapefile = relief_source_shapefile::Shapefile::read(&spec, &path, std::slice::from_ref(&path))
        .expect("read by the shapefile crate");
    assert_eq!(via_ogr.details["driver"], "ESRI Shapefile");
    assert_eq!(via_ogr.details["ids"], "read order");
    assert_features(&via_ogr.features, &via_shapefile.features);
}

#[test]
fn feature_counts_match_ogr_for_the_shared_data() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if !data.is_dir() {
        eprintln!("skipped: no shared data at {}", data.display());
        return;
    }
    let mut files = Vec::new();
    let mut folders = vec![data];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).expect("readable folder").flatten() {
            let path = entry.path();
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or_default().to_lowercase();
            if path.is_dir() {
                folders.push(path);
            } else if ["shp", "gpkg", "geojson", "json", "kml", "kmz", "fgb", "gml", "gpx", "sqlite"]
                .contains(&ext.as_str())
            {
                files.push(path);
            }
        }
    }
    files.sort();
    assert!(!files.is_empty(), "no vector files found under the shared data");
    for path in files {
        let options = DatasetOptions { open_flags: GdalOpenFlags::GDAL_OF_VECTOR, ..DatasetOptions::default() };
        let Ok(ds) = Dataset::open_ex(&path, options) else {
            eprintln!("{}: not a vector dataset, left out", path.display());
            continue;
        };
        for layer in ds.layers() {
            let name = layer.name();
            let ogr_count = layer.feature_count();
            let read = read(&path, &[("layer", &name)]).expect("every shared file reads");
            let skipped: u64 = read
                .details
                .iter()
                .filter(|(k, _)| k.starts_with("skipped."))
                .map(|(_, v)| v.parse::<u64>().unwrap_or(0))
                .sum();
            let ours =
                read.features.len() as u64 + read.details["null_geometries"].parse::<u64>().expect("a count") + skipped;
            eprintln!(
                "{} layer '{name}': OGR {ogr_count}, ogr source {ours} ({} features, {} null, {skipped} skipped)",
                path.display(),
                read.features.len(),
                read.details["null_geometries"]
            );
            assert_eq!(ours, ogr_count, "{} layer '{name}'", path.display());
        }
    }
}

fn assert_error(error: &SourceError, path: &Path, words: &str) {
    let message = error.to_string();
    assert!(message.contains(words), "'{message}' should say '{words}'");
    assert!(message.ends_with(&path.display().to_string()), "'{message}' should name {}", path.display());
    assert!(!message.contains("NullPointer") && !message.contains("{ "), "no Debug output: {message}");
}

#[test]
fn bad_input_errors_name_the_file_and_the_problem() {
    let dir = tempfile::tempdir().expect("temp dir");

    let truncated = three_layer_gpkg(dir.path());
    let bytes = std::fs::read(&truncated).expect("gpkg bytes");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).expect("gpkg cut in half");
    let e = read(&truncated, &[("layer", "parcels")]).expect_err("a truncated gpkg");
    // SQLite notices at open ("database disk image is malformed"); a cut
    // that spared what the open reads ends the layer early instead.
    let message = e.to_string();
    assert!(message.contains("malformed") || message.contains("truncated or corrupt"), "{message}");
    assert_error(&e, &truncated, "'parcels'");

    let not_json = dir.path().join("broken.geojson");
    std::fs::write(&not_json, "{\"type\": \"FeatureCollection\", \"features\": [ {\"type\": ").expect("written");
    let e = read(&not_json, &[]).expect_err("not JSON");
    assert_error(&e, &not_json, "not a vector dataset GDAL can read");

    let gpkg = write("GPKG", &dir.path().join("two.gpkg"), &[roads(), parcels()]);
    let e = read(&gpkg, &[("layer", "rivers")]).expect_err("no such layer");
    assert_error(&e, &gpkg, "no layer 'rivers' (layers: roads, parcels)");

    let raster = dir.path().join("dem.tif");
    let driver = DriverManager::get_driver_by_name("GTiff").expect("GTiff");
    driver.create(&raster, 4, 4, 1).expect("raster").close().expect("closed");
    let e = read(&raster, &[]).expect_err("a raster");
    assert_error(&e, &raster, "not a vector dataset GDAL can read");
}

#[test]
fn refresh_dirties_only_the_edited_feature() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write("GPKG", &dir.path().join("sites.gpkg"), &[sites()]);
    let grid = TileGrid::geodetic(256).expect("grid");
    let source = OgrSource::open(&spec(&path, &[]), &grid, Arc::new(relief_source_gdal::OsrTransform)).expect("opened");
    assert!(matches!(source.refresh(&grid).expect("refresh"), Refresh::Unchanged));

    {
        let options = DatasetOptions {
            open_flags: GdalOpenFlags::GDAL_OF_VECTOR | GdalOpenFlags::GDAL_OF_UPDATE,
            ..DatasetOptions::default()
        };
        let ds = Dataset::open_ex(&path, options).expect("opened for update");
        {
            let layer = ds.layer(0).expect("layer");
            let mut feature = layer.feature(2).expect("feature 2");
            let index = feature.field_index("name").expect("name field");
            feature.set_field_string(index, "marsh").expect("field set");
            layer.set_feature(feature).expect("feature saved");
        }
        ds.close().expect("closed");
    }

    let Refresh::Changed { source: new, dirty } = source.refresh(&grid).expect("refresh") else {
        panic!("the edit must be seen");
    };
    assert_eq!(new.info().details["features"], "3");
    let level = 6;
    let edited = grid.key_at(level, -100.0, -40.0).expect("in the grid");
    let untouched = [grid.key_at(level, 7.25, 43.5).expect("in"), grid.key_at(level, 120.125, 10.0).expect("in")];
    assert!(dirty.touches_tile(&grid, edited), "the edited feature's tile is dirty");
    for key in untouched {
        assert!(!dirty.touches_tile(&grid, key), "{key:?} holds no edited feature");
    }
}

/// Holds an exclusive SQLite lock on `path` (Python's sqlite3, as a script
/// in the middle of a write would) until the returned child is ended.
fn hold_exclusive_lock(path: &Path) -> std::process::Child {
    use std::io::BufRead;
    let script = "import sqlite3, sys\nc = sqlite3.connect(sys.argv[1], isolation_level=None)\n\
                  c.execute('BEGIN EXCLUSIVE')\nprint('locked', flush=True)\nsys.stdin.read()\n";
    let mut child = std::process::Command::new("python3")
        .args(["-c", script])
        .arg(path)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("python3 runs");
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.as_mut().expect("stdout")).read_line(&mut line).expect("a line");
    assert_eq!(line.trim(), "locked");
    child
}

#[test]
fn a_locked_database_is_named_and_read_again_later() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = three_layer_gpkg(dir.path());
    let mut lock = hold_exclusive_lock(&path);
    let e = read(&path, &[("layer", "parcels")]).expect_err("locked");
    drop(lock.stdin.take());
    lock.wait().expect("the lock is let go");
    assert_error(&e, &path, "the database is locked by another program (a write under way) (layer 'parcels')");
    assert!(e.retry_later() && !e.is_transient(), "shown, and tried again");
    assert_eq!(read(&path, &[("layer", "parcels")]).expect("free again").features.len(), parcels().features.len());
}
