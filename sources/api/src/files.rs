//! How files group into datasets on disk: one convention for the sources
//! (what to fingerprint) and the daemon's watcher (what to wait for).
//!
//! A dataset is its primary file and every sidecar that shares its stem in
//! the same folder, compared without case: `dem.tif`, `dem.tif.aux.xml`,
//! `dem.tfw`, `dem.ovr`; `roads.shp`, `roads.dbf`, `roads.shx`, `roads.prj`.
//! Editors' temporary and lock files are recognised so they never trigger a
//! read (EDITORS.md, in the shared notes, records what QGIS, ogr2ogr and
//! GDAL write).

use std::path::{Path, PathBuf};

/// The folder and lower-case stem that name a dataset, for any of its files.
/// `dem.tif.aux.xml` and `DEM.TIF` both give (folder, "dem"); a QGIS repack
/// file `roads_packed.dbf` gives (folder, "roads").
pub fn dataset_key(path: &Path) -> Option<(PathBuf, String)> {
    let name = path.file_name()?.to_str()?;
    let stem = name.split('.').next().filter(|s| !s.is_empty())?.to_lowercase();
    let stem = stem.strip_suffix("_packed").map(str::to_owned).unwrap_or(stem);
    Some((path.parent().map(Path::to_path_buf).unwrap_or_default(), stem))
}

/// True for a QGIS repack in progress (`<stem>_packed.*`): the dataset is
/// being swapped and must not be read yet.
pub fn is_repack_marker(path: &Path) -> bool {
    path.file_name()
        .and_then(|n| n.to_str())
        .and_then(|n| n.split('.').next())
        .is_some_and(|stem| stem.to_lowercase().ends_with("_packed"))
}

/// Lock files, editor back-ups and SQLite journals: never data.
#[expect(clippy::case_sensitive_file_extension_comparisons, reason = "the name is lower-cased first")]
pub fn is_lock_or_temp(path: &Path) -> bool {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        return true;
    };
    let lower = name.to_lowercase();
    lower.starts_with(".~lock.")
        || lower.starts_with("~$")
        || lower.starts_with(".#")
        || lower.ends_with('~')
        || lower.ends_with(".lock")
        || lower.ends_with(".lck")
        || lower.ends_with(".tmp")
        || lower.ends_with(".swp")
        || lower.ends_with("-journal")
        || lower.ends_with("-shm")
}

/// Every file in the dataset of `primary` that exists now (the primary
/// first), lock and temporary files left out.
pub fn dataset_files(primary: &Path) -> Vec<PathBuf> {
    let mut files = vec![primary.to_path_buf()];
    let Some((dir, stem)) = dataset_key(primary) else {
        return files;
    };
    let Ok(entries) = std::fs::read_dir(if dir.as_os_str().is_empty() { Path::new(".") } else { &dir }) else {
        return files;
    };
    let mut sidecars: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| p != primary && !is_lock_or_temp(p) && !is_repack_marker(p))
        .filter(|p| dataset_key(p).is_some_and(|(_, s)| s == stem))
        .collect();
    sidecars.sort();
    files.extend(sidecars);
    files
}

/// What a dataset's files looked like: names, sizes, modification times
/// and inodes. A refresh compares it; a read that sees it change while
/// reading is discarded (a writer was at work).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fingerprint(Vec<(PathBuf, u64, Option<std::time::SystemTime>, u64)>);

impl Fingerprint {
    /// The fingerprint of `primary`'s dataset; `what` names the primary in
    /// the error when it is missing.
    pub fn of(primary: &Path, what: &'static str) -> Result<Self, crate::SourceError> {
        use std::os::unix::fs::MetadataExt;
        let mut files = Vec::new();
        for (n, file) in dataset_files(primary).into_iter().enumerate() {
            match std::fs::metadata(&file) {
                Ok(meta) => files.push((file, meta.len(), meta.modified().ok(), meta.ino())),
                // The primary must be there; a sidecar may vanish between listing and stat.
                Err(source) if n == 0 => return Err(crate::SourceError::Io { what, path: file, source }),
                Err(_) => {}
            }
        }
        Ok(Self(files))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sidecars_share_the_dataset_key() {
        let key = |p: &str| dataset_key(Path::new(p)).unwrap();
        assert_eq!(key("/d/dem.tif"), (PathBuf::from("/d"), "dem".into()));
        assert_eq!(key("/d/DEM.TIF.aux.xml"), key("/d/dem.tif"));
        assert_eq!(key("/d/dem.tfw"), key("/d/dem.tif"));
        assert_eq!(key("/d/roads_packed.dbf"), key("/d/roads.shp"));
        assert_ne!(key("/e/dem.tif"), key("/d/dem.tif"));
        assert!(is_repack_marker(Path::new("/d/roads_packed.shx")));
        assert!(!is_repack_marker(Path::new("/d/roads.shx")));
    }

    #[test]
    fn locks_and_temporaries_are_not_data() {
        for p in
            [".~lock.dem.tif#", "dem.tif~", "x.gpkg-journal", "x.gpkg-shm", "dem.tif.lock", "~$dem.tif", ".#dem.tif"]
        {
            assert!(is_lock_or_temp(Path::new(p)), "{p}");
        }
        for p in ["dem.tif", "dem.tif.aux.xml", "roads.dbf", "N43E007.hgt"] {
            assert!(!is_lock_or_temp(Path::new(p)), "{p}");
        }
    }
}
