//! Mutated manifests (bytes flipped, cut short, TOML put in, spans dropped
//! or repeated, values replaced) parse to a manifest or an error in words:
//! never a panic, never `Debug` output, the manifest's path last.
//!
//! 256 cases per property (two properties), set in `CASES`.

use std::path::Path;

use proptest::prelude::*;
use proptest::sample::Index;
use relief_daemon::manifest::Manifest;
use relief_testkit::{DebugMarks, apply, in_words, mutation};

/// Cases per property.
const CASES: u32 = 256;

/// A manifest with every section: sources of each kind with options,
/// nested tables and arrays of tables, layers, effects with parameters,
/// sun, quality, cache, watch and camera.
const MANIFEST: &str = r#"# A scene with a bit of everything.
[scene]
name = "fuzz-range"
grid = "geodetic"
tile_size = 256

[[source]]
id = "dem"
kind = "gdal"
path = "dem.tif"
vertical_datum = "WGS84 ellipsoid"

[[source]]
id = "ortho"
kind = "gdal"
paths = ["ortho.tif"]

[[source]]
id = "shade"
kind = "hillshade"
inputs = ["dem"]
azimuth_deg = 315
altitude_deg = 40.5

[[source]]
id = "roads"
kind = "kml"
path = "roads.kmz"

[[source]]
id = "town"
kind = "extrude"
inputs = ["roads", "dem"]
height_attribute = "height"
min_level = 10

[[source]]
id = "forest"
kind = "scatter"
inputs = ["ortho", "dem"]
seed = 1

[[source.rule]]
class = 1
models = { conifer = 0.85, broadleaf = 0.15 }
density = 21000
scale = [0.7, 1.3]

[layers]
height = "dem"
color = "ortho"
buildings = "town"
instances = "forest"

[effects]
lighting = {}
atmosphere = {}
fog = { density = 0.00006, falloff_m = 2000, color = '#c4ccd6' }
shadows = {}
detail = {}

[sun]
time = "2026-06-21T17:00:00+02:00"

[quality]
resampling = "bilinear"
reprojection_error_px = 0.125
clipmap_grid_size = 127
clipmap_levels = 8
interactive_scale = 0.5
instance_bands_m = [500.0, 2000.0, 8000.0]
instance_band_densities = [1.0, 0.5, 0.1]
atmosphere_steps = 16
shadow_cascades = 3
shadow_map_size = 2048
detail_octaves = 4

[cache]
memory_mb = 256
raster_mb = 64

[watch]
settle_ms = 200
debounce_ms = 500
fast_path = true
poll_ms = 0

[camera]
lon_deg = 6.45
lat_deg = 44.95
altitude_m = 9000
heading_deg = 15
pitch_deg = -25
"#;

/// What the byte mutations put in: TOML's punctuation and pieces of lines.
const INSERTS: &[&str] = &[
    "[",
    "]",
    "[[",
    "]]",
    "{",
    "}",
    "=",
    "\"",
    "'",
    "'''",
    "\"\"\"",
    ",",
    ".",
    "#",
    "\n",
    "\\",
    "\\u",
    "*",
    "[[source]]\n",
    "[effects]\n",
    "[layers]\nheight = \"nowhere\"\n",
    "water = { level_m = 'x' }\n",
    "x = 1\n",
    "id = \"dem\"\n",
    "kind = \"shapefile\"\n",
    "time = 1979-05-27T07:32:00Z\n",
    "nan",
    "-inf",
    "1e309",
    "-9223372036854775809",
    "é",
];

/// Values that replace a value: out of range, of the wrong type, odd.
const VALUES: &[&str] = &[
    "0",
    "-1",
    "1e309",
    "nan",
    "-inf",
    "18446744073709551616",
    "-9223372036854775808",
    "4294967296",
    "0.0",
    "true",
    "\"\"",
    "\" \"",
    "'*'",
    "'/'",
    "'../'",
    "'[a-'",
    "[]",
    "[1, 2]",
    "[\"a\", 1]",
    "{}",
    "{ a = { b = 1 } }",
    "1979-05-27",
    "07:32:00",
    "1979-05-27T07:32:00Z",
    "\"2026-13-45T99:00:00\"",
    "\"not a time\"",
    "\"EPSG:999999\"",
    "{ crs = \"EPSG:32612\", extent = [1, 2, 0, 1] }",
    "{ crs = \"EPSG:32612\", extent = [nan, 0, 1, 1] }",
];

/// Each value (what follows `key = ` on a line) replaced by one of
/// `VALUES`, for a list of (line, value) picks.
fn replace_values(text: &str, picks: &[(Index, Index)]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let assignments: Vec<usize> = (0..lines.len()).filter(|&i| lines[i].contains(" = ")).collect();
    for (line, value) in picks {
        let i = assignments[line.index(assignments.len())];
        let key = lines[i].split(" = ").next().unwrap_or_default().to_owned();
        lines[i] = format!("{key} = {}", VALUES[value.index(VALUES.len())]);
    }
    lines.join("\n") + "\n"
}

/// Marks of Rust `Debug` output, which no message may show, and a
/// struct's ` { field: `. (A TOML inline table, ` { crs = `, which the
/// messages may suggest, is not one.)
const DEBUG_MARKS: DebugMarks =
    DebugMarks::new(&["BytesStart", "Borrowed(", "Some(", "None", "Err(", "Ok("]).and_struct_fields();

/// Parses `text` as a manifest in a folder of its own: a manifest, or an
/// error in words that ends with the manifest's path.
fn parses_or_fails_in_words(text: &str) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let path = dir.path().join("scene.toml");
    // The manifest's own checks, then the picture's (as reliefd loads it).
    let parsed = Manifest::parse(text, &path).and_then(|m| relief_daemon::picture::Picture::parse(&m).map(drop));
    if let Err(e) = parsed {
        let message = e.to_string();
        check_message(&message, text, &path)?;
    }
    Ok(())
}

fn check_message(message: &str, text: &str, path: &Path) -> Result<(), TestCaseError> {
    // TOML's messages quote the manifest's line, which may hold a mark
    // itself: only marks the manifest lacks count.
    in_words(message, DEBUG_MARKS.find(message).filter(|mark| !text.contains(mark)), path)
}

#[test]
fn debug_output_is_told_from_toml() {
    assert_eq!(DEBUG_MARKS.find("bad: Start(BytesStart { buf: Borrowed(\"b\") })"), Some("BytesStart"));
    assert_eq!(DEBUG_MARKS.find("bad: Point { x: 1 }"), Some(" { x:"));
    assert_eq!(DEBUG_MARKS.find("use \"geodetic\" or { crs = \"EPSG:...\" }"), None);
}

#[test]
fn the_unmutated_manifest_parses() {
    let dir = tempfile::tempdir().unwrap();
    let m = Manifest::parse(MANIFEST, &dir.path().join("scene.toml")).unwrap();
    assert_eq!(m.sources.len(), 6);
    assert_eq!(m.effects.len(), 5);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn mutated_manifest_bytes_parse_or_fail_in_words(mutations in prop::collection::vec(mutation(INSERTS), 1..5)) {
        let mut bytes = MANIFEST.as_bytes().to_vec();
        apply(&mut bytes, &mutations);
        // A manifest is read as UTF-8 text; bytes that are not are refused
        // before parsing (`Manifest::load`).
        let text = String::from_utf8_lossy(&bytes);
        parses_or_fails_in_words(&text)?;
    }

    #[test]
    fn manifests_with_odd_values_parse_or_fail_in_words(
        picks in prop::collection::vec((any::<Index>(), any::<Index>()), 1..4),
    ) {
        parses_or_fails_in_words(&replace_values(MANIFEST, &picks))?;
    }
}
