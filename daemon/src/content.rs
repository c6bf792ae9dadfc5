//! Content addresses: what a source's tiles are made of, as one number a
//! tile store outside this process (a folder on disk, Redis) can key them
//! by. A source's address hashes its kind, options, the scene's grid, the
//! bytes of every file it reads and its inputs' addresses, with reliefd's
//! own build: a file edited while reliefd was down, or a new reliefd, gives
//! a new address, so a stale tile is never read back.
//!
//! Addresses are worked out off the serving path, by one background thread
//! at the lowest priority after each load and generation (`ContentKeys`);
//! until a source's is ready its tiles simply skip the outer stores.

use std::collections::HashSet;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, OnceLock, Weak};

use relief_source::files::FileStamp;
use xxhash_rust::xxh3::Xxh3;

use crate::graph::SceneSnapshot;
use crate::tiles::TileStore;

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

    /// Whether every file is as it was when the version was taken in.
    fn unchanged(&self) -> bool {
        self.1.iter().all(|(file, then)| FileStamp::of(file) == *then)
    }
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

/// Works out every slot's address of `snap` that is not known yet, inputs
/// first; the indices of the slots that got one now.
pub fn fill(snap: &SceneSnapshot) -> Vec<usize> {
    let mut found = Vec::new();
    for (index, slot) in snap.slots.iter().enumerate() {
        if slot.content.0.get().is_some() {
            continue;
        }
        let inputs: Option<Vec<u128>> = slot.inputs.iter().map(|&i| snap.slots[i].content.get()).collect();
        let address = slot.source.as_ref().zip(inputs).and_then(|(source, inputs)| {
            let mut h = Xxh3::new();
            h.update(FORMAT);
            h.update(&build_id().to_le_bytes());
            h.update(format!("{:?}", snap.grid).as_bytes());
            h.update(slot.spec.kind.as_bytes());
            h.update(format!("{:?}", slot.spec.options).as_bytes());
            for input in inputs {
                h.update(&input.to_le_bytes());
            }
            let mut files = source.info().files;
            files.sort();
            if !slot.content.unchanged() {
                return None;
            }
            for file in files {
                let name = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
                h.update(name.as_bytes());
                h.update(&file_digest(&file).ok()?.to_le_bytes());
            }
            slot.content.unchanged().then(|| h.digest128())
        });
        if address.is_some() {
            found.push(index);
        }
        let _ = slot.content.0.set(address);
    }
    found
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

/// The background thread that fills in addresses: snapshots are handed to
/// it as they are published, and it takes the latest (an older one's new
/// slots are the latest's too, or gone). Tiles made before their source's
/// address was known are handed to the outer stores once it is and the
/// scene has been still for `STILL`. The thread ends when this handle is
/// dropped.
pub struct ContentKeys {
    shared: Arc<Shared>,
}

#[derive(Default)]
struct Shared {
    /// The latest snapshot not yet filled, and whether the handle is gone.
    state: Mutex<(Option<Arc<SceneSnapshot>>, bool)>,
    ready: Condvar,
}

impl ContentKeys {
    pub fn start(store: Weak<TileStore>) -> Self {
        let shared = Arc::new(Shared::default());
        let theirs = Arc::clone(&shared);
        let spawned = std::thread::Builder::new().name("relief-content".into()).spawn(move || run(&theirs, &store));
        if let Err(e) = spawned {
            tracing::warn!("cannot start the content-address thread ({e}); tiles skip the outer stores");
        }
        Self { shared }
    }

    /// Asks for `snap`'s addresses; never blocks on the hashing.
    pub fn fill(&self, snap: Arc<SceneSnapshot>) {
        self.shared.state.lock().expect("content lock is never poisoned").0 = Some(snap);
        self.shared.ready.notify_one();
    }
}

impl Drop for ContentKeys {
    fn drop(&mut self) {
        self.shared.state.lock().expect("content lock is never poisoned").1 = true;
        self.shared.ready.notify_one();
    }
}

/// How long the scene must go without a new generation before the tiles
/// made before their source's address was known go to the outer stores:
/// every save gives the edited source a new address, under which all its
/// cached tiles (carried and rebuilt) would otherwise be written again, at
/// every save of a burst.
const STILL: std::time::Duration = std::time::Duration::from_secs(2);

fn run(shared: &Shared, store: &Weak<TileStore>) {
    // Hashing yields to serving: on a busy machine (a first frame, a
    // reload) the tiles come first.
    crate::priority::lowest("content-address");
    // Sources addressed and not yet persisted, by id and address: they go
    // out once the scene has been still for `STILL`, if the latest
    // snapshot still has them.
    let mut pending: HashSet<(String, u128)> = HashSet::new();
    let mut latest: Option<Arc<SceneSnapshot>> = None;
    loop {
        let next = {
            let mut state = shared.state.lock().expect("content lock is never poisoned");
            loop {
                if state.1 {
                    return;
                }
                if let Some(snap) = state.0.take() {
                    break Some(snap);
                }
                if pending.is_empty() {
                    state = shared.ready.wait(state).expect("content lock is never poisoned");
                    continue;
                }
                let (woken, waited) = shared.ready.wait_timeout(state, STILL).expect("content lock is never poisoned");
                state = woken;
                if waited.timed_out() && state.0.is_none() && !state.1 {
                    break None;
                }
            }
        };
        match next {
            Some(snap) => {
                for index in fill(&snap) {
                    let slot = &snap.slots[index];
                    if let Some(address) = slot.content.get() {
                        pending.insert((slot.spec.id.clone(), address));
                    }
                }
                latest = Some(snap);
            }
            None => {
                let Some(store) = store.upgrade() else { return };
                let slots = latest.as_ref().map(|snap| snap.slots.as_slice()).unwrap_or_default();
                for slot in slots {
                    if slot.content.get().is_some_and(|a| pending.contains(&(slot.spec.id.clone(), a))) {
                        store.persist(slot);
                    }
                }
                pending.clear();
            }
        }
    }
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

    /// Snapshots coming faster than `STILL` (a burst of saves, each a new
    /// version to address): the tiles made before go to the disk store
    /// once, when the snapshots stop, not once for each.
    #[test]
    fn tiles_go_to_the_outer_stores_once_the_scene_is_still() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let disk = crate::backing::disk::DiskTiles::open(dir.path().to_path_buf(), 64 << 20)?;
        let backings = crate::backing::Backings::new(vec![Arc::new(disk)]);
        let store = Arc::new(TileStore::new(64 << 20, 2).with_backings(backings));
        let first = Arc::new(crate::testing::flat_snapshot(1));
        let keys: Vec<(usize, relief_source::TileKey)> =
            (0..4).map(|x| (0, relief_source::TileKey { level: 3, x, y: 2 })).collect();
        let built = store.build(&first, &keys, &first.manifest.quality);
        assert!(built.iter().all(Result::is_ok));
        let writes = || store.backing_counters().iter().map(|c| c.writes).sum::<u64>();
        let keys_thread = ContentKeys::start(Arc::downgrade(&store));
        keys_thread.fill(first);
        for generation in 2..=5 {
            std::thread::sleep(Duration::from_millis(200));
            assert_eq!(writes(), 0, "written while snapshots still came (generation {generation})");
            keys_thread.fill(Arc::new(crate::testing::flat_snapshot(generation)));
        }
        let started = std::time::Instant::now();
        while writes() == 0 && started.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(started.elapsed() >= STILL / 2, "written {:?} after the last snapshot", started.elapsed());
        std::thread::sleep(STILL + Duration::from_millis(500));
        assert_eq!(writes(), keys.len() as u64, "each tile once");
        Ok(())
    }
}
