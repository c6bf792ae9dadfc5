//! Content addresses: what a source's tiles are made of, as one number a
//! tile store outside this process (a folder on disk, Redis) can key them
//! by. A source's address hashes its kind, options, the scene's grid, the
//! bytes of every file it reads and its inputs' addresses, with reliefd's
//! own build: a file edited while reliefd was down, or a new reliefd, gives
//! a new address, so a stale tile is never read back.
//!
//! Addresses are worked out off the serving path (`addressing.rs`); until a
//! source's is ready its tiles simply skip the outer stores.

use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};

use relief_source::files::FileStamp;
use xxhash_rust::xxh3::Xxh3;

/// Bumped when the encoding of keys or tiles changes.
const FORMAT: &[u8] = b"relief-content-1";
/// Files up to this size are hashed whole; larger ones by their size,
/// modification time and samples (a 3 GB DEM must not delay serving).
const WHOLE_FILE_LIMIT: u64 = 1 << 30;
const SAMPLE_BYTES: u64 = 1 << 20;
const SAMPLE_EVERY: u64 = 64 << 20;

/// A source version's content address, once worked out (`None` inside when
/// it cannot be: a file that cannot be read or that changed since the
/// version was taken in, an input without one).
#[derive(Debug, Clone, Default)]
pub struct ContentKey(Arc<OnceLock<Option<u128>>>, Arc<Vec<(PathBuf, Option<FileStamp>)>>);

impl ContentKey {
    /// The key of a version just taken in, with its files' stamps as they
    /// are now: the address is worked out later, and only if they still
    /// are (a write after the version read its files would otherwise give
    /// the old version's tiles the new bytes' address).
    pub fn taken_in(source: Option<&Arc<dyn relief_source::Source>>) -> Self {
        let files = source.map(|s| s.info().files).unwrap_or_default();
        let stamped = files.into_iter().map(|f| {
            let then = FileStamp::of(&f);
            (f, then)
        });
        Self(Arc::default(), Arc::new(stamped.collect()))
    }

    /// The address, if it is ready and there is one.
    pub fn get(&self) -> Option<u128> {
        self.0.get().copied().flatten()
    }

    /// Whether the address has been worked out (there may be none).
    pub fn is_worked_out(&self) -> bool {
        self.0.get().is_some()
    }

    /// Works the address out from what makes the version (`None` when a
    /// part is missing or a file changed since the version was taken in),
    /// once; whether there is one now.
    pub fn work_out(&self, made_of: Option<MadeOf<'_>>) -> bool {
        let address = made_of.and_then(|m| self.address(m));
        let _ = self.0.set(address);
        address.is_some()
    }

    fn address(&self, made_of: MadeOf<'_>) -> Option<u128> {
        let mut h = Xxh3::new();
        h.update(FORMAT);
        h.update(&build_id().to_le_bytes());
        h.update(made_of.grid.as_bytes());
        h.update(made_of.kind.as_bytes());
        h.update(made_of.options.as_bytes());
        for input in made_of.inputs {
            h.update(&input.to_le_bytes());
        }
        let mut files = made_of.files;
        files.sort();
        if !self.unchanged() {
            return None;
        }
        for file in files {
            let name = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            h.update(name.as_bytes());
            h.update(&file_digest(&file).ok()?.to_le_bytes());
        }
        self.unchanged().then(|| h.digest128())
    }

    /// Whether every file is as it was when the version was taken in.
    fn unchanged(&self) -> bool {
        self.1.iter().all(|(file, then)| FileStamp::of(file) == *then)
    }
}

/// What a source version is made of, for its address: the grid, its kind
/// and options (as text), its inputs' addresses and the files it reads.
pub struct MadeOf<'a> {
    pub grid: String,
    pub kind: &'a str,
    pub options: String,
    pub inputs: Vec<u128>,
    pub files: Vec<PathBuf>,
}

/// The address of one tile: its source's, the quality it was made with
/// and its key.
pub fn tile_address(source: u128, quality: &impl std::hash::Hash, key: relief_source::TileKey) -> u128 {
    let mut h = Xxh3::new();
    h.update(&source.to_le_bytes());
    quality.hash(&mut h);
    h.update(&[key.level]);
    h.update(&key.x.to_le_bytes());
    h.update(&key.y.to_le_bytes());
    h.digest128()
}

/// The bytes of `path`, hashed: whole up to `WHOLE_FILE_LIMIT`, else its
/// length and modification time with a 1 MiB sample every 64 MiB. A file
/// hashed before and not touched since (the same `FileStamp`) is not read
/// again: an edit to one file of a mosaic of hundreds re-reads that file
/// alone. As git does with its index, a file
/// modified less than `SETTLED` before it was hashed is hashed again next
/// time: a second write within the clock's tick could leave the same
/// modification time.
pub fn file_digest(path: &Path) -> std::io::Result<u128> {
    use std::collections::HashMap;
    if relief_source::objects::is_object(path) {
        return object_digest(path);
    }
    use std::time::{Duration, SystemTime};
    const SETTLED: Duration = Duration::from_secs(2);
    /// Files remembered at most (a scene's files; past it, forgotten).
    const REMEMBERED: usize = 100_000;
    static KNOWN: OnceLock<Mutex<HashMap<PathBuf, (FileStamp, u128)>>> = OnceLock::new();
    let known = KNOWN.get_or_init(Mutex::default);
    let before = FileStamp::of(path);
    let remembered = known.lock().expect("digest lock is never poisoned").get(path).copied();
    if let (Some(before), Some((then, digest))) = (before, remembered)
        && then == before
    {
        return Ok(digest);
    }
    let hashed_at = SystemTime::now();
    let digest = hash_file(path)?;
    // Remembered only if the file was settled when read, and did not
    // change while it was.
    let settled = before.filter(|s| s.modified().is_some_and(|m| m + SETTLED < hashed_at));
    if let Some(then) = settled
        && FileStamp::of(path) == Some(then)
    {
        let mut known = known.lock().expect("digest lock is never poisoned");
        if known.len() >= REMEMBERED {
            known.clear();
        }
        known.insert(path.to_path_buf(), (then, digest));
    }
    Ok(digest)
}

/// An object's digest: its URL and its version as the store gives it
/// (ETag, size, and Last-Modified where the server sends no ETag). An S3
/// ETag is the object's bytes' MD5 (or its parts'), so replicas reading the
/// same object version agree on its tiles' addresses without reading it.
fn object_digest(path: &Path) -> std::io::Result<u128> {
    let version = relief_source::objects::version(path, false).map_err(std::io::Error::other)?;
    let mut h = Xxh3::new();
    h.update(path.to_string_lossy().as_bytes());
    h.update(version.etag.as_bytes());
    h.update(&version.len.to_le_bytes());
    if version.etag.is_empty() {
        h.update(&version.modified.unwrap_or_default().to_le_bytes());
    }
    Ok(h.digest128())
}

fn hash_file(path: &Path) -> std::io::Result<u128> {
    let mut file = relief_source::regular::open_regular(path)?;
    let meta = file.metadata()?;
    let mut h = Xxh3::new();
    h.update(&meta.len().to_le_bytes());
    let mut buffer = vec![0; 1 << 20];
    if meta.len() <= WHOLE_FILE_LIMIT {
        loop {
            let n = file.read(&mut buffer)?;
            if n == 0 {
                break;
            }
            h.update(&buffer[..n]);
        }
    } else {
        let modified = meta.modified()?.duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
        h.update(&modified.as_nanos().to_le_bytes());
        let mut at = 0;
        while at < meta.len() {
            file.seek(SeekFrom::Start(at))?;
            let want = SAMPLE_BYTES.min(meta.len() - at) as usize;
            file.read_exact(&mut buffer[..want])?;
            h.update(&buffer[..want]);
            at += SAMPLE_EVERY;
        }
    }
    Ok(h.digest128())
}

/// This reliefd's build: its executable's bytes, so tiles made by another
/// build are never read back.
fn build_id() -> u128 {
    static ID: OnceLock<u128> = OnceLock::new();
    *ID.get_or_init(|| {
        let exe: Option<PathBuf> = std::env::current_exe().ok();
        exe.and_then(|p| file_digest(&p).ok()).unwrap_or(0)
    })
}

#[cfg(test)]
mod tests {
    use std::fs::File;
    use std::time::{Duration, SystemTime};

    use super::*;

    /// Every write gives a new digest: one within the clock's tick of the
    /// last (the same length, maybe the same modification time) because a
    /// fresh file is never remembered, and one to a settled file because
    /// its modification time moves.
    #[test]
    fn a_file_digest_follows_every_write() -> std::io::Result<()> {
        let dir = tempfile::tempdir()?;
        let path = dir.path().join("dem.bin");
        std::fs::write(&path, b"first version")?;
        let first = file_digest(&path)?;
        std::fs::write(&path, b"other version")?;
        let second = file_digest(&path)?;
        assert_ne!(first, second);
        // Settled: modified a minute ago, remembered, the same answer.
        File::options().write(true).open(&path)?.set_modified(SystemTime::now() - Duration::from_secs(60))?;
        assert_eq!(file_digest(&path)?, second);
        assert_eq!(file_digest(&path)?, second);
        std::fs::write(&path, b"third version")?;
        assert_ne!(file_digest(&path)?, second);
        Ok(())
    }

    /// A version's files written after it was taken in: it gets no
    /// address (its tiles would otherwise go under the new bytes' one).
    #[test]
    fn a_version_whose_files_changed_since_it_was_taken_in_has_no_address() -> std::io::Result<()> {
        let dir = tempfile::tempdir()?;
        let path = dir.path().join("dem.bin");
        std::fs::write(&path, b"as read")?;
        let key = ContentKey(Arc::default(), Arc::new(vec![(path.clone(), FileStamp::of(&path))]));
        assert!(key.unchanged());
        std::fs::write(&path, b"as saved")?;
        assert!(!key.unchanged());
        Ok(())
    }
}
