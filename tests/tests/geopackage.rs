//! GeoPackage against a real reliefd: two sources on two layers of one
//! `.gpkg` (an edit to one layer's features changes only its source), and a
//! raster GeoPackage (tiled gridded coverage) served by the `gdal` kind
//! with the heights it was written with.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::Path;

use gdal::vector::{FieldDefn, Geometry, LayerAccess, LayerOptions, OGRFieldType, OGRwkbGeometryType};
use gdal::{Dataset, DatasetOptions, DriverManager, GdalOpenFlags};
use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_client::SceneServiceClient;
use relief_tests::daemon::Reliefd;
use relief_tests::edit::{height_at, wait_for};
use relief_tests::fixtures;

/// Writes `town.gpkg` with layers `parcels` (two squares) and `wells` (two
/// points), each feature with a `name`.
fn write_town(path: &Path) {
    let driver = DriverManager::get_driver_by_name("GPKG").unwrap();
    let mut ds = driver.create_vector_only(path).unwrap();
    let srs = gdal::spatial_ref::SpatialRef::from_epsg(4326).unwrap();
    for (layer_name, ty, wkts) in [
        (
            "parcels",
            OGRwkbGeometryType::wkbPolygon,
            [
                "POLYGON((10.2 45.2,10.21 45.2,10.21 45.21,10.2 45.21,10.2 45.2))",
                "POLYGON((10.3 45.3,10.31 45.3,10.31 45.31,10.3 45.31,10.3 45.3))",
            ],
        ),
        ("wells", OGRwkbGeometryType::wkbPoint, ["POINT(10.25 45.25)", "POINT(10.35 45.15)"]),
    ] {
        let layer = ds.create_layer(LayerOptions { name: layer_name, srs: Some(&srs), ty, options: None }).unwrap();
        FieldDefn::new("name", OGRFieldType::OFTString).unwrap().add_to_layer(&layer).unwrap();
        for (k, wkt) in wkts.iter().enumerate() {
            let mut feature = gdal::vector::Feature::new(layer.defn()).unwrap();
            feature.set_geometry(Geometry::from_wkt(wkt).unwrap()).unwrap();
            feature.set_field_string(0, &format!("{layer_name}-{k}")).unwrap();
            feature.create(&layer).unwrap();
        }
    }
}

fn source_version(state: &pb::SceneState, id: &str) -> u64 {
    state.sources.iter().find(|s| s.id == id).unwrap().version
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_edit_to_one_layer_changes_only_the_sources_of_that_layer() {
    let dir = tempfile::tempdir().unwrap();
    fixtures::write_dem(&dir.path().join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    let gpkg = dir.path().join("town.gpkg");
    write_town(&gpkg);
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"town\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n[[source]]\nid = \"parcels\"\nkind = \"ogr\"\npath = \"town.gpkg\"\nlayer = \"parcels\"\n\n[[source]]\nid = \"wells\"\nkind = \"ogr\"\npath = \"town.gpkg\"\nlayer = \"wells\"\n\n[layers]\nheight = \"dem\"\n",
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    let before = SceneServiceClient::new(channel.clone()).get_state(pb::GetStateRequest {}).await.unwrap().into_inner();
    let details = &before.sources.iter().find(|s| s.id == "wells").unwrap().details;
    assert_eq!(details["features"], "2", "{details:?}");
    assert_eq!(details["driver"], "GPKG");

    // A well renamed through GDAL in update mode, as a script would.
    {
        let options = DatasetOptions {
            open_flags: GdalOpenFlags::GDAL_OF_UPDATE | GdalOpenFlags::GDAL_OF_VECTOR,
            ..DatasetOptions::default()
        };
        let ds = Dataset::open_ex(&gpkg, options).unwrap();
        let layer = ds.layer_by_name("wells").unwrap();
        let mut feature = layer.feature(1).unwrap();
        feature.set_field_string(0, "renamed").unwrap();
        layer.set_feature(feature).unwrap();
        ds.close().unwrap();
    }
    let after = wait_for(channel.clone(), before.generation + 1).await.unwrap();
    assert!(source_version(&after, "wells") > source_version(&before, "wells"), "the edited layer's source is new");
    assert_eq!(source_version(&after, "parcels"), source_version(&before, "parcels"), "the other layer's is not");
    daemon.stop(&[]).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_raster_geopackage_is_served_by_the_gdal_kind() {
    let dir = tempfile::tempdir().unwrap();
    let tif = fixtures::write_dem(&dir.path().join("hill.tif"), &fixtures::hill_spec(), fixtures::hill).unwrap();
    let gpkg = dir.path().join("hill.gpkg");
    {
        // Float32 heights as a tiled gridded coverage (TIFF tiles), as
        // `gdal_translate -of GPKG` writes them.
        let source = Dataset::open(&tif).unwrap();
        let driver = DriverManager::get_driver_by_name("GPKG").unwrap();
        let mut options = gdal::cpl::CslStringList::new();
        options.set_name_value("TILE_FORMAT", "TIFF").unwrap();
        source.create_copy(&driver, &gpkg, &options).unwrap();
    }
    let manifest = fixtures::write_manifest(
        dir.path(),
        "[scene]\nname = \"hill\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.gpkg\"\n\n[layers]\nheight = \"dem\"\n",
    )
    .unwrap();
    let daemon = Reliefd::start(&manifest, &[]).unwrap();
    let channel = daemon.channel().await.unwrap();
    for (lon, lat) in [(10.25, 45.25), (10.1, 45.4), (10.37, 45.12)] {
        let h = height_at(channel.clone(), lon, lat).await.unwrap().unwrap();
        // The hill's samples are 0.00125 degrees apart: bilinear between
        // them is within a metre of the formula here.
        assert!((h - fixtures::hill(lon, lat)).abs() < 1.0, "({lon}, {lat}): {h} vs {}", fixtures::hill(lon, lat));
    }
    daemon.stop(&[]).unwrap();
}
