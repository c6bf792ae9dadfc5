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

/// The stem of an ArcGIS lock on a whole file geodatabase
/// (`_gdb.HOST.PID.N.ed.lock`): it is on every table in its folder.
pub const WHOLE_FOLDER_LOCK: &str = "_gdb";

/// True for an editor's lock that holds a read back: ArcGIS's `*.lock`
/// files beside a dataset (`<stem>.<host>.<pid>.<n>.ed.lock` while it
/// edits, `.wr.lock` while it writes), but not the schema lock every
/// ArcGIS session keeps while it merely shows the data (`.sr.lock`), nor
/// another reader's (`.rd.lock`). A lock is never data (`Member::Ignored`).
#[expect(clippy::case_sensitive_file_extension_comparisons, reason = "the name is lower-cased first")]
pub fn is_write_lock(path: &Path) -> bool {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else { return false };
    let lower = name.to_lowercase();
    lower.ends_with(".lock") && !lower.ends_with(".sr.lock") && !lower.ends_with(".rd.lock")
}

/// True when `path` is an editor's write lock (`is_write_lock`) on a
/// dataset `held` says is of interest (by its lower-case stem), or on every
/// dataset of its folder (`WHOLE_FOLDER_LOCK`): the one rule the watcher
/// waits by and a source reports by.
pub fn write_lock_holds(path: &Path, held: impl Fn(&str) -> bool) -> bool {
    is_write_lock(path) && dataset_key(path).is_some_and(|(_, stem)| stem == WHOLE_FOLDER_LOCK || held(&stem))
}

/// The part a file plays in its dataset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Member {
    /// The primary file or a sidecar: data.
    Data,
    /// A SQLite write-ahead log (`x.gpkg-wal`): committed transactions not
    /// yet copied into the database. Written only by commits; SQLite opens,
    /// closes, creates and deletes it for every connection, readers too.
    SqliteWal,
    /// A SQLite rollback journal (`x.gpkg-journal`): a write transaction is
    /// under way while it exists.
    SqliteJournal,
    /// Lock files, editor back-ups, temporaries, SQLite's shared-memory
    /// index (`-shm`, touched by every reader) and ArcGIS's side files
    /// (spatial indexes `.sbn`/`.sbx`, metadata `.shp.xml`, which it
    /// rewrites when it merely opens a layer): never data.
    Ignored,
}

/// What `path` is to its dataset, from its name alone.
#[expect(clippy::case_sensitive_file_extension_comparisons, reason = "the name is lower-cased first")]
pub fn member(path: &Path) -> Member {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        return Member::Ignored;
    };
    let lower = name.to_lowercase();
    if lower.ends_with("-wal") {
        Member::SqliteWal
    } else if lower.ends_with("-journal") {
        Member::SqliteJournal
    } else if lower.starts_with(".~lock.")
        || lower.starts_with("~$")
        || lower.starts_with(".#")
        || lower.ends_with('~')
        || lower.ends_with(".lock")
        || lower.ends_with(".lck")
        || lower.ends_with(".tmp")
        || lower.ends_with(".swp")
        || lower.ends_with("-shm")
        || lower.ends_with(".sbn")
        || lower.ends_with(".sbx")
        || lower.ends_with(".shp.xml")
    {
        Member::Ignored
    } else {
        Member::Data
    }
}

/// True for a SQLite database (a GeoPackage, a SpatiaLite file...), by its
/// header, whatever its name. Its writes are transactions: a reader through
/// SQLite never sees one half done.
pub fn is_sqlite(path: &Path) -> bool {
    use std::io::Read;
    let mut header = [0u8; 16];
    crate::regular::open_regular(path).and_then(|mut f| f.read_exact(&mut header)).is_ok()
        && &header == b"SQLite format 3\0"
}

/// Every file in the dataset of `primary` that exists now (the primary
/// first): data and a SQLite write-ahead log; locks, temporaries and
/// journals left out.
pub fn dataset_files(primary: &Path) -> Vec<PathBuf> {
    let mut files = vec![primary.to_path_buf()];
    // An object stands alone: GDAL is told not to look for side objects.
    if crate::objects::is_object(primary) {
        return files;
    }
    let Some((dir, stem)) = dataset_key(primary) else {
        return files;
    };
    let Ok(entries) = std::fs::read_dir(if dir.as_os_str().is_empty() { Path::new(".") } else { &dir }) else {
        return files;
    };
    let mut sidecars: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| p != primary && matches!(member(p), Member::Data | Member::SqliteWal) && !is_repack_marker(p))
        .filter(|p| dataset_key(p).is_some_and(|(_, s)| s == stem))
        .collect();
    sidecars.sort();
    files.extend(sidecars);
    files
}

/// One file as a write leaves it: size, modification and change times
/// (a user can set the first back, never the second), device and inode.
/// Compared around reads (a writer at work) and before trusting what was
/// worked out from the file earlier.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FileStamp {
    len: u64,
    modified: Option<std::time::SystemTime>,
    changed: (i64, i64),
    dev: u64,
    ino: u64,
}

impl FileStamp {
    /// No file seen (a store not yet reading one).
    pub const NONE: Self = Self { len: 0, modified: None, changed: (0, 0), dev: 0, ino: 0 };

    /// The file's stamp now; None when it cannot be read. An object's is
    /// its version as last asked of the store (`objects::version`): its
    /// size, Last-Modified and ETag.
    pub fn of(path: &Path) -> Option<Self> {
        use std::os::unix::fs::MetadataExt;
        if crate::objects::is_object(path) {
            return crate::objects::version(path, false).ok().map(|v| Self::object(&v));
        }
        let meta = std::fs::metadata(path).ok()?;
        Some(Self {
            len: meta.len(),
            modified: meta.modified().ok(),
            changed: (meta.ctime(), meta.ctime_nsec()),
            dev: meta.dev(),
            ino: meta.ino(),
        })
    }

    /// An object's version as a stamp: its ETag's hash stands for the inode
    /// (a new ETag is a new file), on a device no file has.
    pub fn object(version: &crate::objects::ObjectVersion) -> Self {
        Self {
            len: version.len,
            modified: version.modified.map(|s| std::time::UNIX_EPOCH + std::time::Duration::from_secs(s)),
            changed: (0, 0),
            dev: u64::MAX,
            ino: xxhash_rust::xxh3::xxh3_64(version.etag.as_bytes()),
        }
    }

    /// When the file was last modified, if the system says.
    pub fn modified(&self) -> Option<std::time::SystemTime> {
        self.modified
    }
}

/// What a dataset's files looked like: names, sizes, modification times
/// and inodes. A refresh compares it; a read that sees it change while
/// reading is discarded (a writer was at work). An empty SQLite
/// write-ahead log is left out: every connection, a reader's too, creates
/// one and deletes it again, and it holds nothing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fingerprint(Vec<(PathBuf, u64, Option<std::time::SystemTime>, u64)>);

impl Fingerprint {
    /// The fingerprint of `primary`'s dataset; `what` names the primary in
    /// the error when it is missing.
    pub fn of(primary: &Path, what: &'static str) -> Result<Self, crate::SourceError> {
        use std::os::unix::fs::MetadataExt;
        let mut files = Vec::new();
        if crate::objects::is_object(primary) {
            let version = crate::objects::version(primary, false).map_err(|why| crate::SourceError::Io {
                what,
                path: primary.to_path_buf(),
                source: std::io::Error::other(why),
            })?;
            let stamp = FileStamp::object(&version);
            files.push((primary.to_path_buf(), stamp.len, stamp.modified, stamp.ino));
            return Ok(Self(files));
        }
        for (n, file) in dataset_files(primary).into_iter().enumerate() {
            match std::fs::metadata(&file) {
                Ok(meta) if meta.len() == 0 && member(&file) == Member::SqliteWal => {}
                Ok(meta) => files.push((file, meta.len(), meta.modified().ok(), meta.ino())),
                // The primary must be there; a sidecar may vanish between listing and stat.
                Err(source) if n == 0 => return Err(crate::SourceError::Io { what, path: file, source }),
                Err(_) => {}
            }
        }
        Ok(Self(files))
    }

    /// The fingerprints of several datasets, by their primaries, as one.
    pub fn of_each(primaries: &[PathBuf], what: &'static str) -> Result<Self, crate::SourceError> {
        let mut all = Vec::new();
        for primary in primaries {
            all.extend(Self::of(primary, what)?.0);
        }
        Ok(Self(all))
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
        for p in [
            ".~lock.dem.tif#",
            "dem.tif~",
            "x.gpkg-shm",
            "dem.tif.lock",
            "~$dem.tif",
            ".#dem.tif",
            "roads.sbn",
            "roads.SBX",
            "roads.shp.xml",
            "roads.shp.HOST.1234.5678.sr.lock",
        ] {
            assert_eq!(member(Path::new(p)), Member::Ignored, "{p}");
        }
        assert!(is_write_lock(Path::new("/g.gdb/a0000000b.HOST.1.2.ed.lock")));
        assert!(is_write_lock(Path::new("_gdb.HOST.1.2.wr.lock")));
        assert!(!is_write_lock(Path::new("a0000000b.HOST.1.2.sr.lock")));
        assert!(!is_write_lock(Path::new("_gdb.HOST.1.2.RD.LOCK")));
        assert!(!is_write_lock(Path::new("a0000000b.gdbtable")));
        for p in ["dem.tif", "dem.tif.aux.xml", "roads.dbf", "N43E007.hgt", "town.gpkg"] {
            assert_eq!(member(Path::new(p)), Member::Data, "{p}");
        }
        assert_eq!(member(Path::new("/d/Town.GPKG-wal")), Member::SqliteWal);
        assert_eq!(member(Path::new("/d/town.gpkg-journal")), Member::SqliteJournal);
        assert_eq!(dataset_key(Path::new("/d/town.gpkg-wal")), dataset_key(Path::new("/d/town.gpkg")));
    }

    #[test]
    fn an_empty_write_ahead_log_is_not_part_of_the_fingerprint() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let db = dir.path().join("town.gpkg");
        std::fs::write(&db, b"SQLite format 3\0 and the rest")?;
        assert!(is_sqlite(&db));
        assert!(!is_sqlite(&dir.path().join("absent.gpkg")));
        let before = Fingerprint::of(&db, "test")?;
        // A reader's connection makes an empty log and shared-memory index.
        std::fs::write(dir.path().join("town.gpkg-wal"), b"")?;
        std::fs::write(dir.path().join("town.gpkg-shm"), b"0123")?;
        assert_eq!(Fingerprint::of(&db, "test")?, before);
        // A commit writes frames into it.
        std::fs::write(dir.path().join("town.gpkg-wal"), b"frames")?;
        assert_ne!(Fingerprint::of(&db, "test")?, before);
        Ok(())
    }
}
