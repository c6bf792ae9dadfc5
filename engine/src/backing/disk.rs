//! Tiles in a folder, so a restarted reliefd starts warm: one file per
//! tile under its content address (`ab/abcdef....tile`), written to a
//! temporary name and renamed into place (a reader never sees half a
//! tile), the least recently used dropped past the size budget. Writes and
//! the bookkeeping run on one background thread; a read is a plain file
//! read. Deleting the folder at any time only costs the tiles in it.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::time::SystemTime;

use super::Backing;

/// Writes waiting for the thread; past this, new writes are dropped.
const QUEUE: usize = 512;
/// Eviction takes the folder down to this fraction of the budget.
const EVICT_TO: f64 = 0.9;

enum Job {
    Write(u128, Vec<u8>),
    /// A read hit: the file is fresh again for eviction.
    Touch(u128),
}

pub struct DiskTiles {
    root: PathBuf,
    jobs: SyncSender<Job>,
    dropped: AtomicU64,
}

impl std::fmt::Debug for DiskTiles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DiskTiles({})", self.root.display())
    }
}

fn path_of(root: &Path, address: u128) -> PathBuf {
    let hex = format!("{address:032x}");
    root.join(&hex[..2]).join(format!("{hex}.tile"))
}

impl DiskTiles {
    /// The cache in `root` (created when missing) under `budget_bytes`.
    pub fn open(root: PathBuf, budget_bytes: u64) -> std::io::Result<Self> {
        fs::create_dir_all(&root)?;
        let (jobs, rx) = sync_channel(QUEUE);
        let thread_root = root.clone();
        std::thread::Builder::new().name("relief-disk-cache".into()).spawn(move || {
            // Writing tiles yields to serving.
            crate::priority::lowest("disk-cache");
            Writer::new(thread_root, budget_bytes).run(&rx);
        })?;
        Ok(Self { root, jobs, dropped: AtomicU64::new(0) })
    }

    fn send(&self, job: Job) {
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = self.jobs.try_send(job) {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl Backing for DiskTiles {
    fn name(&self) -> &'static str {
        "disk"
    }

    fn get(&self, address: u128) -> Option<Vec<u8>> {
        let bytes = fs::read(path_of(&self.root, address)).ok()?;
        self.send(Job::Touch(address));
        Some(bytes)
    }

    fn put(&self, address: u128, bytes: Vec<u8>) {
        self.send(Job::Write(address, bytes));
    }
}

/// The thread's view of the folder: every tile's size and last use.
struct Writer {
    root: PathBuf,
    budget_bytes: u64,
    files: BTreeMap<u128, (u64, SystemTime)>,
    total: u64,
    scanned: bool,
}

impl Writer {
    fn new(root: PathBuf, budget_bytes: u64) -> Self {
        Self { root, budget_bytes, files: BTreeMap::new(), total: 0, scanned: false }
    }

    fn run(mut self, rx: &Receiver<Job>) {
        while let Ok(job) = rx.recv() {
            if !self.scanned {
                self.scan();
            }
            match job {
                Job::Write(address, bytes) => {
                    if let Err(e) = self.write(address, &bytes) {
                        tracing::debug!(dir = %self.root.display(), "cannot write a tile to the disk cache: {e}");
                    }
                }
                Job::Touch(address) => {
                    let path = path_of(&self.root, address);
                    if let Ok(file) = fs::File::options().write(true).open(&path) {
                        let now = SystemTime::now();
                        let _ = file.set_modified(now);
                        if let Some(entry) = self.files.get_mut(&address) {
                            entry.1 = now;
                        }
                    }
                }
            }
        }
    }

    /// What is in the folder already, from an earlier run.
    fn scan(&mut self) {
        self.scanned = true;
        let Ok(dirs) = fs::read_dir(&self.root) else { return };
        for dir in dirs.flatten() {
            let Ok(entries) = fs::read_dir(dir.path()) else { continue };
            for entry in entries.flatten() {
                let name = entry.file_name();
                let Some(address) =
                    name.to_str().and_then(|n| n.strip_suffix(".tile")).and_then(|h| u128::from_str_radix(h, 16).ok())
                else {
                    continue;
                };
                if let Ok(meta) = entry.metadata() {
                    let used = meta.modified().unwrap_or(SystemTime::UNIX_EPOCH);
                    self.total += meta.len();
                    self.files.insert(address, (meta.len(), used));
                }
            }
        }
        self.evict();
    }

    fn write(&mut self, address: u128, bytes: &[u8]) -> std::io::Result<()> {
        let path = path_of(&self.root, address);
        // An address names its bytes: a tile already there (handed out
        // when it was made, then again with its source's others) stays.
        if let Some(entry) = self.files.get_mut(&address)
            && path.exists()
        {
            entry.1 = SystemTime::now();
            return Ok(());
        }
        let dir = path.parent().unwrap_or(&self.root);
        // The folder may have been deleted under us: make it again.
        fs::create_dir_all(dir)?;
        let temporary = dir.join(format!(".{address:032x}.{}.part", std::process::id()));
        fs::write(&temporary, bytes)?;
        fs::rename(&temporary, &path).inspect_err(|_| {
            let _ = fs::remove_file(&temporary);
        })?;
        let size = bytes.len() as u64;
        if let Some((old, _)) = self.files.insert(address, (size, SystemTime::now())) {
            self.total -= old.min(self.total);
        }
        self.total += size;
        self.evict();
        Ok(())
    }

    /// Drops the least recently used tiles while over the budget.
    fn evict(&mut self) {
        if self.total <= self.budget_bytes {
            return;
        }
        let target = (self.budget_bytes as f64 * EVICT_TO) as u64;
        let mut by_age: Vec<(SystemTime, u128, u64)> = self.files.iter().map(|(a, (s, t))| (*t, *a, *s)).collect();
        by_age.sort_unstable();
        for (_, address, size) in by_age {
            if self.total <= target {
                break;
            }
            let _ = fs::remove_file(path_of(&self.root, address));
            self.files.remove(&address);
            self.total -= size.min(self.total);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wait_for(path: &Path, present: bool) -> bool {
        for _ in 0..200 {
            if path.exists() == present {
                return true;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        false
    }

    #[test]
    fn tiles_are_written_read_and_evicted_past_the_budget() -> std::io::Result<()> {
        let dir = tempfile::tempdir()?;
        let disk = DiskTiles::open(dir.path().join("tiles"), 3000)?;
        for address in 1..=5u128 {
            disk.put(address, vec![address as u8; 1000]);
            assert!(wait_for(&path_of(&disk.root, address), true));
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        // 5 kB written under a 3 kB budget: the oldest went first.
        assert!(wait_for(&path_of(&disk.root, 1), false));
        assert_eq!(disk.get(5), Some(vec![5; 1000]));
        assert_eq!(disk.get(1), None);
        // The folder deleted under it: reads miss, writes make it again.
        fs::remove_dir_all(&disk.root)?;
        assert_eq!(disk.get(5), None);
        disk.put(6, vec![6; 10]);
        assert!(wait_for(&path_of(&disk.root, 6), true));
        assert_eq!(disk.get(6), Some(vec![6; 10]));
        Ok(())
    }
}
