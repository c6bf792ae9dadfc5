//! Lossy overviews: a JPEG or LERC file's overviews are checked against
//! its base within what its compression may change; beyond it they are
//! left out (the coarse levels halved from the base), with a warning,
//! never refused. Files written by GDAL's COG driver from textures.
#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::path::Path;

use relief_examples::{self as examples, Texture};
use relief_source::{GenerateContext, NoInputs, OptionValue, Payload, Quality, Source, SourceSpec, TileGrid, TileKey};
use relief_source_gdal::GdalSource;

fn spec(path: &Path, options: &[(&str, OptionValue)]) -> SourceSpec {
    SourceSpec {
        id: "photo".into(),
        kind: "gdal".into(),
        paths: vec![path.to_path_buf()],
        options: options.iter().map(|(k, v)| ((*k).to_owned(), v.clone())).collect(),
        ..SourceSpec::default()
    }
}

fn grid() -> TileGrid {
    TileGrid::geodetic(256).unwrap()
}

fn open(path: &Path, options: &[(&str, OptionValue)]) -> GdalSource {
    GdalSource::open(&spec(path, options), &grid()).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The colour tiles over the source's extent from level 10 to 16.
fn tiles(source: &GdalSource) -> Vec<(TileKey, Vec<u8>)> {
    let (grid, quality) = (grid(), Quality::default());
    let ctx = GenerateContext { grid: &grid, quality: &quality, inputs: &NoInputs };
    let extent = source.info().extent.unwrap();
    (10..=16)
        .flat_map(|l| grid.keys_overlapping(l, &extent))
        .map(|k| match source.generate(k, &ctx).unwrap() {
            Payload::Color(c) => (k, c.rgba),
            other => panic!("colour expected, got {other:?}"),
        })
        .collect()
}

#[test]
fn jpeg_overviews_beyond_their_tolerance_are_halved_from_the_base_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let path =
        examples::write_textured_cog(&dir.path().join("fine.tif"), Texture::Fine, &["COMPRESS=JPEG", "QUALITY=75"])
            .unwrap();
    let source = open(&path, &[]);
    let info = source.info();
    let [warning] = info.warnings.as_slice() else { panic!("one warning expected: {:?}", info.warnings) };
    assert!(warning.starts_with(&format!("{}: its first overview (level 1, 256x256)", path.display())), "{warning}");
    assert!(warning.contains("(JPEG, quality 75)") && warning.contains("lie more than 8 outside"), "{warning}");
    assert!(warning.contains("% of") || warning.contains("%)"), "says what share was off: {warning}");
    let check = &info.details["overview_check"];
    assert!(check.contains("tolerance of 8"), "{check}");
    assert!(info.details["overviews"].contains("left out"), "{:?}", info.details);
    // What it serves is what overviews = false serves: halved from the base.
    let halved = open(&path, &[("overviews", OptionValue::Bool(false))]);
    assert!(halved.info().warnings.is_empty());
    assert_eq!(tiles(&source), tiles(&halved));
}

#[test]
fn jpeg_overviews_within_their_tolerance_are_used() {
    let dir = tempfile::tempdir().unwrap();
    let path =
        examples::write_textured_cog(&dir.path().join("smooth.tif"), Texture::Smooth, &["COMPRESS=JPEG", "QUALITY=75"])
            .unwrap();
    let info = open(&path, &[]).info();
    assert!(info.warnings.is_empty(), "{:?}", info.warnings);
    assert_eq!(info.details["overviews"], "1 of the file's used for coarse levels");
    assert_eq!(
        info.details["overview_check"],
        "lossy (JPEG, quality 75): the first overview checked against the base with a tolerance of 8 in stored \
         units (the step JPEG quantises an 8x8 block's mean by at that quality, 8)"
    );
}

#[test]
fn a_lerc_file_is_checked_within_twice_its_max_z_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = examples::write_textured_cog(
        &dir.path().join("lerc.tif"),
        Texture::Smooth,
        &["COMPRESS=LERC", "MAX_Z_ERROR=0.5"],
    )
    .unwrap();
    let info = open(&path, &[]).info();
    assert!(info.warnings.is_empty(), "{:?}", info.warnings);
    let check = &info.details["overview_check"];
    assert!(check.starts_with("lossy (LERC, max Z error 0.5)") && check.contains("tolerance of 1 "), "{check}");
    // Lossless compressions are checked as before, with no tolerance.
    let deflated =
        examples::write_textured_cog(&dir.path().join("deflate.tif"), Texture::Smooth, &["COMPRESS=DEFLATE"]).unwrap();
    assert!(!open(&deflated, &[]).info().details.contains_key("overview_check"));
}
