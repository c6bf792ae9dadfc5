//! A shapefile's files, read into memory: from a folder (the .shp and the
//! sidecars beside it) or, through `zipped`, from inside a zip.

use std::path::{Path, PathBuf};

use relief_source::SourceError;
use relief_source::files::{dataset_key, is_repack_marker};

/// One of a shapefile's files and the path that names it in messages (for
/// a zip member, the zip's path followed by the member's name:
/// `data/roads.zip/roads/roads.shp`, as GDAL's /vsizip/ writes it).
#[derive(Debug)]
pub(crate) struct Part {
    pub path: PathBuf,
    pub bytes: Vec<u8>,
}

/// The files that make one shapefile. Only the .shp is required: a missing
/// .shx is rebuilt and a missing .dbf read as no attributes, with warnings.
#[derive(Debug)]
pub(crate) struct Dataset {
    pub shp: Part,
    pub shx: Option<Part>,
    pub dbf: Option<Part>,
    pub prj: Option<Part>,
    pub cpg: Option<Part>,
}

impl Dataset {
    /// The shapefile `shp` and the sidecars beside it.
    ///
    /// A sidecar missing while a QGIS repack is under way (a
    /// `<stem>_packed.*` file beside it, EDITORS.md) is a writer at work,
    /// not a shapefile without one: that read is `Changing`, to be tried again.
    pub(crate) fn beside(shp: &Path) -> Result<Self, SourceError> {
        let bytes = relief_source::regular::read_regular(shp).map_err(|source| SourceError::Io {
            what: "shapefile",
            path: shp.to_path_buf(),
            source,
        })?;
        let dataset = Self {
            shp: Part { path: shp.to_path_buf(), bytes },
            shx: sidecar(shp, "shx", "shapefile index")?,
            dbf: sidecar(shp, "dbf", "shapefile attributes")?,
            prj: sidecar(shp, "prj", "shapefile projection")?,
            cpg: sidecar(shp, "cpg", "shapefile code page")?,
        };
        if (dataset.shx.is_none() || dataset.dbf.is_none()) && repacking(shp) {
            return Err(SourceError::Changing { path: shp.to_path_buf() });
        }
        Ok(dataset)
    }
}

/// The sidecar of `shp` with extension `ext`, in the case of the .shp's
/// extension first, then in the other; None when there is none.
fn sidecar(shp: &Path, ext: &str, what: &'static str) -> Result<Option<Part>, SourceError> {
    let candidates = [sibling(shp, ext), shp.with_extension(ext), shp.with_extension(ext.to_ascii_uppercase())];
    let mut tried = Vec::new();
    for path in candidates {
        if tried.contains(&path) {
            continue;
        }
        match relief_source::regular::read_regular(&path) {
            Ok(bytes) => return Ok(Some(Part { path, bytes })),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => tried.push(path),
            Err(source) => return Err(SourceError::Io { what, path, source }),
        }
    }
    Ok(None)
}

/// The sibling path with `ext`, matching the case of the .shp's extension.
pub(crate) fn sibling(shp: &Path, ext: &str) -> PathBuf {
    let upper = shp.extension().and_then(|e| e.to_str()).is_some_and(|e| e.chars().all(|c| c.is_ascii_uppercase()));
    shp.with_extension(if upper { ext.to_ascii_uppercase() } else { ext.to_owned() })
}

/// True when a `<stem>_packed.*` file lies beside `shp`: QGIS is swapping
/// the dataset's files.
fn repacking(shp: &Path) -> bool {
    let Some((dir, stem)) = dataset_key(shp) else { return false };
    let dir = if dir.as_os_str().is_empty() { PathBuf::from(".") } else { dir };
    let Ok(entries) = std::fs::read_dir(dir) else { return false };
    entries.flatten().map(|e| e.path()).any(|p| is_repack_marker(&p) && dataset_key(&p).is_some_and(|(_, s)| s == stem))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sidecars_are_found_in_either_case() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let shp = dir.path().join("roads.shp");
        std::fs::write(&shp, b"shp")?;
        std::fs::write(dir.path().join("roads.DBF"), b"dbf")?;
        // No .shx and no repack under way: the dataset is taken as it is.
        let dataset = Dataset::beside(&shp)?;
        assert!(dataset.shx.is_none());
        assert_eq!(dataset.dbf.map(|d| d.bytes), Some(b"dbf".to_vec()));
        Ok(())
    }

    #[test]
    fn a_sidecar_missing_during_a_repack_is_a_writer_at_work() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let shp = dir.path().join("roads.shp");
        std::fs::write(&shp, b"shp")?;
        std::fs::write(dir.path().join("roads.shx"), b"shx")?;
        std::fs::write(dir.path().join("roads_packed.dbf"), b"dbf")?;
        assert!(matches!(Dataset::beside(&shp), Err(SourceError::Changing { .. })));
        Ok(())
    }
}
