//! Shapefiles read from inside a zip, as QGIS and GDAL's /vsizip/ read them.

mod fixtures;

use std::path::Path;
use std::sync::Arc;

use fixtures::{Identity, Layer, TestResult, read, spec, zip};
use relief_source::{Refresh, Source, TileGrid};
use relief_source_shapefile::ShapefileSource;

/// `layer`'s files as zip members under `folder` ("" for the root).
fn members(layer: Layer, folder: &str) -> TestResult<Vec<(String, Vec<u8>)>> {
    let files = layer.bytes()?;
    let name = |ext: &str| format!("{folder}{}.{ext}", layer.name());
    let mut members = vec![(name("shp"), files.shp)];
    members.extend(files.shx.map(|b| (name("shx"), b)));
    members.extend(files.dbf.map(|b| (name("dbf"), b)));
    Ok(members)
}

#[test]
fn a_zipped_shapefile_is_read_from_a_folder_inside_the_zip() -> TestResult {
    let dir = tempfile::tempdir()?;
    let mut inside = members(Layer::Lines, "roads/")?;
    inside.push(("roads/roads.prj".into(), b"GEOGCS[\"WGS 84\"]".to_vec()));
    inside.push(("roads/".into(), Vec::new()));
    let path = zip(&dir.path().join("roads.zip"), &inside)?;
    let read = read(&path, &[])?;
    assert_eq!(read.features.len(), Layer::Lines.count());
    assert!(read.features.iter().all(|f| f.properties.get("name").is_some_and(|n| n.starts_with("roads "))));
    assert!(read.warnings.is_empty(), "{:?}", read.warnings);
    assert_eq!(read.crs, "GEOGCS[\"WGS 84\"]");
    assert_eq!(read.details.get("zip_member").map(String::as_str), Some("roads/roads.shp"));
    assert_eq!(read.details.get("crs_source").map(String::as_str), Some("from the .prj"));
    assert_eq!(read.files, std::slice::from_ref(&path));
    assert_eq!(read.crs_file, Some(path.join("roads/roads.prj")));
    Ok(())
}

#[test]
fn a_zipped_shapefile_may_lack_its_shx_and_dbf() -> TestResult {
    let dir = tempfile::tempdir()?;
    let only_shp: Vec<_> = members(Layer::Polygons, "")?.into_iter().filter(|(n, _)| n == "parcels.shp").collect();
    let path = zip(&dir.path().join("parcels.zip"), &only_shp)?;
    let read = read(&path, &[])?;
    assert_eq!(read.features.len(), Layer::Polygons.count());
    assert!(read.features.iter().all(|f| f.properties.is_empty()));
    assert_eq!(
        read.warnings,
        [
            "no .shx beside the .shp: the index was rebuilt by walking its 3 records",
            "no .dbf: geometry read without attributes"
        ]
    );
    Ok(())
}

fn error(path: &Path, options: &[(&str, &str)]) -> TestResult<String> {
    Ok(read(path, options).err().ok_or("the zip was read")?.to_string())
}

#[test]
fn an_empty_zip_is_an_error_naming_the_zip() -> TestResult {
    let dir = tempfile::tempdir()?;
    let empty = zip(&dir.path().join("empty.zip"), &[])?;
    assert_eq!(
        error(&empty, &[])?,
        format!("the zip holds no shapefile (.shp) among its 0 entries: {}", empty.display())
    );
    let unrelated = zip(&dir.path().join("notes.zip"), &[("readme.txt".into(), b"hello".to_vec())])?;
    assert!(error(&unrelated, &[])?.starts_with("the zip holds no shapefile (.shp) among its 1 entries"));
    let not_a_zip = dir.path().join("plain.zip");
    std::fs::write(&not_a_zip, b"")?;
    let message = error(&not_a_zip, &[])?;
    assert!(message.starts_with("not a zip archive ("), "{message}");
    assert!(message.ends_with(&format!(": {}", not_a_zip.display())), "{message}");
    Ok(())
}

#[test]
fn a_zip_with_two_shapefiles_is_refused_with_their_names_unless_a_layer_is_named() -> TestResult {
    let dir = tempfile::tempdir()?;
    let mut inside = members(Layer::Lines, "")?;
    inside.extend(members(Layer::Points, "data/")?);
    let path = zip(&dir.path().join("town.zip"), &inside)?;
    assert_eq!(
        error(&path, &[])?,
        format!(
            "the zip holds 2 shapefiles (roads.shp, data/wells.shp): choose one with the layer option, such as layer = \"roads\": {}",
            path.display()
        )
    );
    let wells = read(&path, &[("layer", "wells")])?;
    assert_eq!(wells.features.len(), Layer::Points.count());
    assert_eq!(wells.details.get("zip_member").map(String::as_str), Some("data/wells.shp"));
    let roads = read(&path, &[("layer", "roads.shp")])?;
    assert_eq!(roads.features.len(), Layer::Lines.count());
    let message = error(&path, &[("layer", "rivers")])?;
    assert!(
        message.starts_with("the zip holds no shapefile 'rivers' (it holds roads.shp, data/wells.shp)"),
        "{message}"
    );
    Ok(())
}

#[test]
fn a_path_neither_shp_nor_zip_is_refused() -> TestResult {
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("roads.geojson");
    std::fs::write(&path, b"{}")?;
    assert!(error(&path, &[])?.contains("is neither a .shp file nor a .zip holding one"));
    Ok(())
}

#[test]
fn an_edit_of_the_zip_reloads_the_source() -> TestResult {
    let dir = tempfile::tempdir()?;
    let path = zip(&dir.path().join("town.zip"), &members(Layer::Points, "")?)?;
    let grid = TileGrid::geodetic(256)?;
    let source = ShapefileSource::open(&spec(&path, &[("crs", "EPSG:4326")]), &grid, Arc::new(Identity))?;
    assert!(matches!(source.refresh(&grid)?, Refresh::Unchanged));
    zip(&path, &members(Layer::Polygons, "")?)?;
    let Refresh::Changed { source, .. } = source.refresh(&grid)? else {
        return Err("an edited zip was not read again".into());
    };
    assert_eq!(source.info().details.get("features").map(String::as_str), Some("3"));
    Ok(())
}
