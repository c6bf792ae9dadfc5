//! Shapefiles read from a folder: whole, missing a sidecar that other
//! readers do without (the .shx rebuilt from the .shp; no .dbf, geometry
//! only), and with records deleted in the .dbf.

mod fixtures;

use fixtures::{Layer, TestResult, read};

#[test]
fn a_complete_shapefile_reads_with_its_attributes_and_no_warnings() -> TestResult {
    let dir = tempfile::tempdir()?;
    for layer in Layer::ALL {
        let read = read(&layer.write(dir.path())?, &[])?;
        assert_eq!(read.features.len(), layer.count(), "{layer:?}");
        assert!(read.warnings.is_empty(), "{layer:?}: {:?}", read.warnings);
        let first = &read.features[0].properties;
        assert_eq!(first.get("name").map(String::as_str), Some(format!("{} 0", layer.name()).as_str()));
        assert_eq!(first.get("height").map(String::as_str), Some("10.5"));
    }
    Ok(())
}

#[test]
fn a_shapefile_without_its_shx_is_read_with_the_index_rebuilt() -> TestResult {
    let dir = tempfile::tempdir()?;
    for layer in Layer::ALL {
        let shp = layer.write(dir.path())?;
        let whole = read(&shp, &[])?;
        std::fs::remove_file(shp.with_extension("shx"))?;
        let rebuilt = read(&shp, &[])?;
        // Debug text, as z is NaN (no z) and NaN is never equal to itself.
        assert_eq!(format!("{:?}", rebuilt.features), format!("{:?}", whole.features), "{layer:?}");
        assert_eq!(
            rebuilt.warnings,
            [format!("no .shx beside the .shp: the index was rebuilt by walking its {} records", layer.count())]
        );
        assert!(rebuilt.features.iter().all(|f| f.properties.contains_key("name")), "{layer:?}");
    }
    Ok(())
}

#[test]
fn a_shapefile_without_its_dbf_is_read_as_geometry_without_attributes() -> TestResult {
    let dir = tempfile::tempdir()?;
    for layer in Layer::ALL {
        let shp = layer.write(dir.path())?;
        let whole = read(&shp, &[])?;
        std::fs::remove_file(shp.with_extension("dbf"))?;
        let bare = read(&shp, &[])?;
        assert_eq!(bare.features.len(), layer.count(), "{layer:?}");
        assert!(bare.features.iter().all(|f| f.properties.is_empty()), "{layer:?}");
        // Debug text, as z is NaN (no z) and NaN is never equal to itself.
        let geometries =
            |r: &relief_source::VectorRead| format!("{:?}", r.features.iter().map(|f| &f.geometry).collect::<Vec<_>>());
        assert_eq!(geometries(&bare), geometries(&whole), "{layer:?}");
        assert_eq!(bare.warnings, ["no .dbf: geometry read without attributes"]);
    }
    Ok(())
}

#[test]
fn a_shapefile_with_only_its_shp_gets_both_warnings() -> TestResult {
    let dir = tempfile::tempdir()?;
    let shp = Layer::Lines.write(dir.path())?;
    std::fs::remove_file(shp.with_extension("shx"))?;
    std::fs::remove_file(shp.with_extension("dbf"))?;
    let read = read(&shp, &[])?;
    assert_eq!(read.features.len(), Layer::Lines.count());
    assert_eq!(read.warnings.len(), 2, "{:?}", read.warnings);
    Ok(())
}

#[test]
fn a_truncated_shp_without_its_shx_is_an_error_naming_the_shp() -> TestResult {
    let dir = tempfile::tempdir()?;
    let shp = Layer::Polygons.write(dir.path())?;
    std::fs::remove_file(shp.with_extension("shx"))?;
    let bytes = std::fs::read(&shp)?;

    // Cut inside the last record, and the header's length fixed to match:
    // only the walk can tell.
    let mut cut = bytes[..bytes.len() - 20].to_vec();
    let words = (cut.len() / 2) as i32;
    cut[24..28].copy_from_slice(&words.to_be_bytes());
    std::fs::write(&shp, &cut)?;
    let message = read(&shp, &[]).err().ok_or("a cut record was read")?.to_string();
    assert!(
        message.starts_with("no .shx beside the .shp, and its records do not walk cleanly: record 2 at byte"),
        "{message}"
    );
    assert!(message.contains("past the end of the file"), "{message}");
    assert!(message.ends_with(&format!(": {}", shp.display())), "{message}");

    // Cut without fixing the header: the torn-file check says so first.
    std::fs::write(&shp, &bytes[..bytes.len() - 20])?;
    let message = read(&shp, &[]).err().ok_or("a torn .shp was read")?.to_string();
    assert!(message.starts_with("truncated or torn .shp"), "{message}");
    assert!(message.ends_with(&format!(": {}", shp.display())), "{message}");
    Ok(())
}

#[test]
fn the_dbf_must_still_agree_with_a_rebuilt_index() -> TestResult {
    let dir = tempfile::tempdir()?;
    let shp = Layer::Points.write(dir.path())?;
    std::fs::remove_file(shp.with_extension("shx"))?;
    let dbf = shp.with_extension("dbf");
    let mut bytes = std::fs::read(&dbf)?;
    bytes[4..8].copy_from_slice(&12u32.to_le_bytes());
    std::fs::write(&dbf, &bytes)?;
    let message = read(&shp, &[]).err().ok_or("a disagreeing .dbf was read")?.to_string();
    assert_eq!(message, format!("invalid record count 12 in the .dbf (the .shp holds 5): {}", dbf.display()));
    Ok(())
}

#[test]
fn a_sidecar_missing_during_a_qgis_repack_is_a_writer_at_work() -> TestResult {
    let dir = tempfile::tempdir()?;
    let shp = Layer::Points.write(dir.path())?;
    std::fs::rename(shp.with_extension("dbf"), dir.path().join("wells_packed.dbf"))?;
    let error = read(&shp, &[]).err().ok_or("a dataset under repack was read")?;
    assert!(error.retry_later(), "{error}");
    Ok(())
}

#[test]
fn the_layer_option_is_for_zips_only() -> TestResult {
    let dir = tempfile::tempdir()?;
    let shp = Layer::Points.write(dir.path())?;
    let message = read(&shp, &[("layer", "wells")]).err().ok_or("layer accepted for a .shp")?.to_string();
    assert!(message.starts_with("invalid option 'layer': chooses a shapefile inside a .zip"), "{message}");
    Ok(())
}

#[test]
fn a_record_deleted_in_the_dbf_takes_its_shape_with_it() -> TestResult {
    let dir = tempfile::tempdir()?;
    let shp = Layer::Points.write(dir.path())?;
    let dbf = shp.with_extension("dbf");
    let mut bytes = std::fs::read(&dbf)?;
    // Record 1's deletion flag: the first record starts at the header's
    // offset, each is 1 + 24 + 10 bytes long.
    let first = usize::from(u16::from_le_bytes([bytes[8], bytes[9]]));
    bytes[first + 35] = b'*';
    std::fs::write(&dbf, &bytes)?;
    let read = read(&shp, &[])?;
    let ids: Vec<u64> = read.features.iter().map(|f| f.id).collect();
    assert_eq!(ids, [0, 2, 3, 4]);
    for feature in &read.features {
        assert_eq!(
            feature.properties.get("name"),
            Some(&format!("wells {}", feature.id)),
            "records stay with their shapes"
        );
    }
    assert_eq!(read.details.get("deleted_records").map(String::as_str), Some("1"));
    Ok(())
}

/// The big-endian header length of a .shp or .shx, in bytes.
fn header_bytes(bytes: &[u8]) -> usize {
    2 * u32::from_be_bytes([bytes[24], bytes[25], bytes[26], bytes[27]]) as usize
}

fn set_header_bytes(bytes: &mut [u8], len: usize) {
    bytes[24..28].copy_from_slice(&u32::try_from(len / 2).expect("a test file is small").to_be_bytes());
}

#[test]
fn a_stray_byte_after_the_last_record_is_ignored_with_a_warning() -> TestResult {
    let dir = tempfile::tempdir()?;
    for layer in Layer::ALL {
        let shp = layer.write(dir.path())?;
        let whole = read(&shp, &[])?;
        let mut bytes = std::fs::read(&shp)?;
        let len = bytes.len();
        bytes.push(0);
        std::fs::write(&shp, &bytes)?;
        let odd = read(&shp, &[])?;
        // Debug text, as z is NaN (no z) and NaN is never equal to itself.
        assert_eq!(format!("{:?}", odd.features), format!("{:?}", whole.features), "{layer:?}");
        assert_eq!(
            odd.warnings,
            [format!(
                "the .shp has 1 byte past the {len} its header says, not a record: ignored, as GDAL does ({})",
                shp.display()
            )]
        );
        // Without its .shx, the walk stops at the header's length too.
        std::fs::remove_file(shp.with_extension("shx"))?;
        let walked = read(&shp, &[])?;
        assert_eq!(walked.features.len(), layer.count(), "{layer:?}");
        assert_eq!(walked.warnings.len(), 2, "{:?}", walked.warnings);
    }
    Ok(())
}

#[test]
fn a_record_appended_before_the_header_counts_it_is_torn() -> TestResult {
    let dir = tempfile::tempdir()?;
    let shp = Layer::Polygons.write(dir.path())?;
    let mut bytes = std::fs::read(&shp)?;
    // QGIS appends a record, then rewrites the header: in between, the
    // header is one record short.
    let last = header_bytes(&std::fs::read(shp.with_extension("shx"))?) - 8;
    let shx = std::fs::read(shp.with_extension("shx"))?;
    let offset = 2 * u32::from_be_bytes([shx[last], shx[last + 1], shx[last + 2], shx[last + 3]]) as usize;
    set_header_bytes(&mut bytes, offset);
    std::fs::write(&shp, &bytes)?;
    let message = read(&shp, &[]).err().ok_or("a record being appended was read")?.to_string();
    assert!(message.starts_with("torn .shp: whole records lie past the"), "{message}");
    assert!(message.ends_with(&format!(": {}", shp.display())), "{message}");
    Ok(())
}

#[test]
fn a_shx_header_length_off_by_less_than_an_entry_is_read_with_a_warning() -> TestResult {
    let dir = tempfile::tempdir()?;
    let shp = Layer::Points.write(dir.path())?;
    let whole = read(&shp, &[])?;
    let shx = shp.with_extension("shx");
    let original = std::fs::read(&shx)?;
    let len = original.len();

    // Over by 2 or 6 bytes: GDAL reads every entry, and so does relief.
    for over in [2, 6] {
        let mut bytes = original.clone();
        set_header_bytes(&mut bytes, len + over);
        std::fs::write(&shx, &bytes)?;
        let odd = read(&shp, &[])?;
        assert_eq!(format!("{:?}", odd.features), format!("{:?}", whole.features));
        assert_eq!(
            odd.warnings,
            [format!(
                "the .shx header says {} bytes, the file has {len}: its 5 entries read, as GDAL does ({})",
                len + over,
                shx.display()
            )]
        );
    }
    // A whole entry more (a .shx being extended), or fewer than the file
    // holds (being rewritten): torn.
    for declared in [len + 8, len - 8, len - 2] {
        let mut bytes = original.clone();
        set_header_bytes(&mut bytes, declared);
        std::fs::write(&shx, &bytes)?;
        let message = read(&shp, &[]).err().ok_or("a torn .shx was read")?.to_string();
        assert_eq!(
            message,
            format!("torn .shx: its header says {declared} bytes, the file has {len}: {}", shx.display())
        );
    }
    Ok(())
}
