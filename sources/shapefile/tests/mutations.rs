//! Spoiled shapefiles (real ones, written by the `shapefile` crate, then
//! with bytes flipped, cut off or inserted in their .shp, .shx and .dbf, a
//! sidecar left out or not, or the zip holding them spoiled) give an error
//! or features, never a panic; and no message shows Rust `Debug` output.
//!
//! The last property takes spoiled files through the source as the daemon
//! opens it (reader, then feature index), for what garbage coordinates
//! could do there.
//!
//! Each property runs 256 cases (`CASES`): 1,280 in all, in a few seconds,
//! in every `cargo test`.

mod fixtures;

use std::path::Path;
use std::sync::OnceLock;

use std::sync::Arc;

use fixtures::{DEBUG_TELLS, Files, Identity, Layer, read, spec, zip};
use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::TestCaseError;
use relief_source::{SourceError, TileGrid, VectorRead};
use relief_source_shapefile::ShapefileSource;

const CASES: u32 = 256;

/// The three layers' files, written once.
fn originals() -> &'static [Files; 3] {
    static ORIGINALS: OnceLock<[Files; 3]> = OnceLock::new();
    ORIGINALS.get_or_init(|| Layer::ALL.map(|layer| layer.bytes().expect("the fixtures can be written")))
}

#[derive(Debug, Clone, Copy)]
enum Target {
    Shp,
    Shx,
    Dbf,
}

#[derive(Debug, Clone)]
enum Spoil {
    /// Bytes xor-ed with a non-zero mask.
    Flip(Vec<(Index, u8)>),
    /// The file cut off.
    Truncate(Index),
    /// Garbage put in.
    Insert(Index, Vec<u8>),
}

impl Spoil {
    fn apply(&self, bytes: &mut Vec<u8>) {
        match self {
            Self::Flip(flips) if !bytes.is_empty() => {
                for (at, mask) in flips {
                    let at = at.index(bytes.len());
                    bytes[at] ^= mask;
                }
            }
            Self::Flip(_) => {}
            Self::Truncate(at) => bytes.truncate(at.index(bytes.len() + 1)),
            Self::Insert(at, garbage) => {
                let at = at.index(bytes.len() + 1);
                bytes.splice(at..at, garbage.iter().copied());
            }
        }
    }
}

fn flips() -> impl Strategy<Value = Spoil> {
    prop::collection::vec((any::<Index>(), 1..=255u8), 1..8).prop_map(Spoil::Flip)
}

fn truncations() -> impl Strategy<Value = Spoil> {
    any::<Index>().prop_map(Spoil::Truncate)
}

fn insertions() -> impl Strategy<Value = Spoil> {
    (any::<Index>(), prop::collection::vec(any::<u8>(), 1..64)).prop_map(|(at, garbage)| Spoil::Insert(at, garbage))
}

fn layers() -> impl Strategy<Value = Layer> {
    prop::sample::select(Layer::ALL.to_vec())
}

fn targets() -> impl Strategy<Value = Target> {
    prop::sample::select(vec![Target::Shp, Target::Shx, Target::Dbf])
}

/// The outcome is an error or a read, and its words show no `Debug` output.
fn plain(outcome: Result<VectorRead, SourceError>, dir: &Path) -> Result<(), TestCaseError> {
    let texts = match outcome {
        Ok(read) => read.warnings,
        Err(e) => {
            let message = e.to_string();
            prop_assert!(!message.starts_with(char::is_uppercase), "not lower case: {message}");
            vec![message]
        }
    };
    for text in texts {
        // The temporary folder's random name is not the reader's words.
        let text = text.replace(&dir.display().to_string(), "<dir>");
        let debug = DEBUG_TELLS.find(&text);
        prop_assert!(debug.is_none(), "Debug output ({:?}) in: {text}", debug);
    }
    Ok(())
}

/// `layer`'s files with `spoil` done to `target`, the .shx and .dbf kept or
/// left out, written in `dir`; the .shp's path.
fn write_spoiled(
    dir: &Path,
    layer: Layer,
    target: Target,
    spoil: &Spoil,
    keep_shx: bool,
    keep_dbf: bool,
) -> Result<std::path::PathBuf, TestCaseError> {
    let mut files = originals()[layer as usize].clone();
    let bytes = match target {
        Target::Shp => Some(&mut files.shp),
        Target::Shx => files.shx.as_mut(),
        Target::Dbf => files.dbf.as_mut(),
    };
    if let Some(bytes) = bytes {
        spoil.apply(bytes);
    }
    files.shx = files.shx.filter(|_| keep_shx);
    files.dbf = files.dbf.filter(|_| keep_dbf);
    files.write(dir, layer.name()).map_err(|e| TestCaseError::fail(e.to_string()))
}

/// The same, read from a folder.
fn spoiled(layer: Layer, target: Target, spoil: &Spoil, keep_shx: bool, keep_dbf: bool) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().map_err(|e| TestCaseError::fail(e.to_string()))?;
    let shp = write_spoiled(dir.path(), layer, target, spoil, keep_shx, keep_dbf)?;
    plain(read(&shp, &[]), dir.path())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn flipped_bytes_give_an_error_or_features(
        layer in layers(), target in targets(), spoil in flips(), keep_shx in any::<bool>(), keep_dbf in any::<bool>()
    ) {
        spoiled(layer, target, &spoil, keep_shx, keep_dbf)?;
    }

    #[test]
    fn truncated_files_give_an_error_or_features(
        layer in layers(), target in targets(), spoil in truncations(), keep_shx in any::<bool>(), keep_dbf in any::<bool>()
    ) {
        spoiled(layer, target, &spoil, keep_shx, keep_dbf)?;
    }

    #[test]
    fn inserted_garbage_gives_an_error_or_features(
        layer in layers(), target in targets(), spoil in insertions(), keep_shx in any::<bool>(), keep_dbf in any::<bool>()
    ) {
        spoiled(layer, target, &spoil, keep_shx, keep_dbf)?;
    }

    #[test]
    fn spoiled_zips_give_an_error_or_features(
        layer in layers(), spoil in prop_oneof![flips(), truncations(), insertions()]
    ) {
        let files = &originals()[layer as usize];
        let dir = tempfile::tempdir().map_err(|e| TestCaseError::fail(e.to_string()))?;
        let mut members = vec![(format!("{}.shp", layer.name()), files.shp.clone())];
        members.extend(files.shx.clone().map(|b| (format!("{}.shx", layer.name()), b)));
        members.extend(files.dbf.clone().map(|b| (format!("{}.dbf", layer.name()), b)));
        let path = zip(&dir.path().join("spoiled.zip"), &members).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let mut bytes = std::fs::read(&path).map_err(|e| TestCaseError::fail(e.to_string()))?;
        spoil.apply(&mut bytes);
        std::fs::write(&path, &bytes).map_err(|e| TestCaseError::fail(e.to_string()))?;
        plain(read(&path, &[]), dir.path())?;
    }

    #[test]
    fn spoiled_shapefiles_open_as_a_source_or_fail(
        layer in layers(), target in targets(), spoil in prop_oneof![flips(), truncations(), insertions()]
    ) {
        let dir = tempfile::tempdir().map_err(|e| TestCaseError::fail(e.to_string()))?;
        let shp = write_spoiled(dir.path(), layer, target, &spoil, true, true)?;
        let grid = TileGrid::geodetic(256).map_err(TestCaseError::fail)?;
        let opened = ShapefileSource::open(&spec(&shp, &[("crs", "EPSG:4326")]), &grid, Arc::new(Identity));
        if let Err(e) = opened {
            let message = e.to_string().replace(&dir.path().display().to_string(), "<dir>");
            prop_assert!(DEBUG_TELLS.find(&message).is_none(), "Debug output in: {message}");
        }
    }
}
