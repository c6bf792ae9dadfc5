//! Turns file changes into refreshes, never reading a file mid-save.
//!
//! The folders holding the sources' files and the manifest are watched
//! (folders, not files: saves replace inodes). Events are grouped by
//! dataset (`relief_source::files`). A dataset is read:
//! - at once (after `settle_ms`) when its last event closes a save:
//!   close-after-write or a rename into place, and no QGIS repack is under
//!   way; such a read reports no error, it only retries later;
//! - after `debounce_ms` without events otherwise, or when the fast read
//!   failed; errors from this read are shown on the source;
//! - after `write_timeout_ms` when a file was written but never closed.
//!
//! An ArcGIS edit or write lock on a dataset (`*.lock` beside it, not the
//! schema lock `*.sr.lock` every session holds) holds its read back until
//! the lock goes, or for `write_timeout_ms` without events (a crashed
//! ArcGIS leaves its locks; the source's read then says so in the state).
//! A file geodatabase is watched per table: a source's files are its
//! table's (`a0000000b.*` in the `.gdb` folder) and the catalog's, so an
//! edit to one table refreshes only the sources that read it.
//!
//! A SQLite database (a GeoPackage) is watched with its write-ahead log and
//! rollback journal. Its writes are transactions, so a reader through SQLite
//! never sees one torn; but one QGIS commit is several transactions
//! (geometries, attributes, deletes, adds) and must be read whole. The
//! boundary: QGIS leaves edit mode after the last one, copying the log into
//! the database (a checkpoint) and closing the database after writing it.
//! So a close-after-write of the database file itself is the closing
//! event; a write to the log or journal (a transaction committed) waits for
//! the quiet period instead, as does any database write without that close
//! (a script's connection kept open, "Save Layer Edits" that stays in edit
//! mode). No fast read while a journal exists (a transaction under way).
//! Opening, closing, creating or deleting the log, and the `-shm` index,
//! are every connection's doing, relief's own reads included: not changes.
//!
//! Every read re-stats the files afterwards and is discarded if they
//! changed meanwhile, so a slow writer is never half read. Events that do
//! not fit the bounded queue are dropped for a full rescan.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use notify::{RecommendedWatcher, RecursiveMode, Watcher};
use relief_source::files::dataset_key;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

use crate::manifest::WatchSettings;
use crate::scene::Scene;

mod objects;
mod saves;

pub use objects::{event_objects, noticed};
use saves::{Busy, Change, Pending, Ready, busy, change, readiness};

/// What a group of files belongs to.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Target {
    Source(String),
    Manifest,
}

/// Which datasets (and the manifest) the scene reads, by folder and stem.
fn interests(scene: &Scene) -> HashMap<(PathBuf, String), BTreeSet<Target>> {
    let snap = scene.snapshot();
    let mut map: HashMap<(PathBuf, String), BTreeSet<Target>> = HashMap::new();
    for slot in &snap.slots {
        let files = slot
            .source
            .as_ref()
            .map(|s| s.info().files)
            .filter(|f| !f.is_empty())
            .unwrap_or_else(|| slot.spec.paths.clone());
        // Objects are polled (`objects`), not watched.
        for file in files.into_iter().filter(|f| !relief_source::objects::is_object(f)) {
            if let Some(key) = dataset_key(&file) {
                map.entry(key).or_default().insert(Target::Source(slot.spec.id.clone()));
            }
        }
    }
    if let Some(key) = dataset_key(scene.manifest_path()) {
        map.entry(key).or_default().insert(Target::Manifest);
    }
    map
}

/// Folders under watch, and the events from them. Made before reliefd says
/// it is listening, so no save after that line can be missed.
pub struct FileWatch {
    scene: Arc<Scene>,
    settings: WatchSettings,
    watcher: RecommendedWatcher,
    events: mpsc::Receiver<notify::Event>,
    overflow: Arc<AtomicBool>,
    watched: BTreeSet<PathBuf>,
    groups: HashMap<(PathBuf, String), BTreeSet<Target>>,
}

impl FileWatch {
    /// Watches the folders of every file the scene reads. Fails only if no
    /// watcher can be made at all.
    pub fn start(scene: Arc<Scene>, settings: WatchSettings) -> anyhow::Result<Self> {
        let (tx, events) = mpsc::channel::<notify::Event>(4096);
        let overflow = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&overflow);
        let watcher: RecommendedWatcher =
            notify::recommended_watcher(move |event: notify::Result<notify::Event>| match event {
                Ok(e) => {
                    if tx.try_send(e).is_err() {
                        flag.store(true, Ordering::Relaxed);
                    }
                }
                Err(_) => flag.store(true, Ordering::Relaxed),
            })?;
        let groups = interests(&scene);
        let mut watch = Self { scene, settings, watcher, events, overflow, watched: BTreeSet::new(), groups };
        update_watches(&mut watch.watcher, &mut watch.watched, &watch.groups);
        Ok(watch)
    }

    /// Turns events into refreshes until `shutdown`.
    pub async fn run(self, shutdown: CancellationToken) -> anyhow::Result<()> {
        run(self, shutdown).await
    }
}

async fn run(watch: FileWatch, shutdown: CancellationToken) -> anyhow::Result<()> {
    let FileWatch { scene, settings, mut watcher, events: mut rx, overflow, mut watched, mut groups } = watch;
    // Anything saved between loading the scene and watching its folders is
    // caught by one look at every source (a fingerprint check when nothing
    // changed).
    let mut pending: HashMap<Target, Pending> = scene
        .snapshot()
        .slots
        .iter()
        .map(|s| (Target::Source(s.spec.id.clone()), Pending::new(Instant::now())))
        .collect();
    let mut poll = (settings.poll_ms > 0).then(|| tokio::time::interval(Duration::from_millis(settings.poll_ms)));
    let mut seen_generation = scene.snapshot().generation;
    let mut object_poll =
        (settings.object_poll_ms > 0).then(|| tokio::time::interval(Duration::from_millis(settings.object_poll_ms)));
    if let Some(p) = object_poll.as_mut() {
        p.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    }
    let mut polled = Some(objects::Polled::default());
    let mut tick = tokio::time::interval(Duration::from_millis(settings.settle_ms.clamp(1, 50)));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);

    loop {
        tokio::select! {
            () = shutdown.cancelled() => return Ok(()),
            Some(event) = rx.recv() => note(&event, &groups, &mut pending),
            _ = tick.tick() => {}
            _ = async { object_poll.as_mut().expect("guarded").tick().await }, if object_poll.is_some() => {
                // One HEAD per object the scene reads, off the runtime; the
                // sources whose objects changed are read at once (a store
                // replaces an object whole: there is no save to wait out).
                let s = Arc::clone(&scene);
                let mut p = polled.take().unwrap_or_default();
                let (p, changed) = tokio::task::spawn_blocking(move || {
                    let changed = p.changed(&s);
                    (p, changed)
                })
                .await?;
                polled = Some(p);
                if !changed.is_empty() {
                    let s = Arc::clone(&scene);
                    let ids: Vec<String> = changed.into_iter().collect();
                    tokio::task::spawn_blocking(move || s.refresh(Some(&ids), "objects changed (polled)", true)).await?;
                }
            }
            _ = async { poll.as_mut().expect("guarded").tick().await }, if poll.is_some() => {
                // Polling finds changes notify missed; it reads only quietly.
                let now = Instant::now();
                for slot in &scene.snapshot().slots {
                    pending.entry(Target::Source(slot.spec.id.clone())).or_insert_with(|| Pending { fast_failed: true, ..Pending::new(now) });
                }
            }
        }
        while let Ok(event) = rx.try_recv() {
            note(&event, &groups, &mut pending);
        }
        let now = Instant::now();
        if overflow.swap(false, Ordering::Relaxed) {
            tracing::warn!("too many file events at once; rescanning every source after the quiet period");
            for slot in &scene.snapshot().slots {
                pending
                    .insert(Target::Source(slot.spec.id.clone()), Pending { fast_failed: true, ..Pending::new(now) });
            }
        }

        // Everything ready now, in one refresh per kind of read.
        let mut fast = Vec::new();
        let mut quiet = Vec::new();
        let mut manifest = false;
        for (target, p) in &pending {
            // What is on disk only ever holds a read back: the folders are
            // looked at only once a dataset would be read without it.
            let unhindered = readiness(p, now, &settings, Busy::default());
            let ready = match target {
                Target::Source(_) if unhindered.is_some() => readiness(p, now, &settings, on_disk(&groups, target)),
                _ => unhindered,
            };
            match (target, ready) {
                (Target::Manifest, Some(_)) => manifest = true,
                (Target::Source(id), Some(Ready::Fast)) => fast.push(id.clone()),
                (Target::Source(id), Some(Ready::Quiet)) => quiet.push(id.clone()),
                (_, None) => {}
            }
        }
        let read = manifest || !fast.is_empty() || !quiet.is_empty();
        if manifest {
            pending.remove(&Target::Manifest);
            let s = Arc::clone(&scene);
            tokio::task::spawn_blocking(move || s.reload_manifest()).await?;
        }
        for (ids, report) in [(fast, false), (quiet, true)] {
            if ids.is_empty() {
                continue;
            }
            let s = Arc::clone(&scene);
            let asked = ids.clone();
            let reason = if report { "files changed (quiet)" } else { "files changed" };
            let outcome = tokio::task::spawn_blocking(move || s.refresh(Some(&asked), reason, report)).await?;
            let now = Instant::now();
            for id in ids {
                let target = Target::Source(id.clone());
                if outcome.retry.contains(&id) {
                    if let Some(p) = pending.get_mut(&target) {
                        p.fast_failed = true;
                        if report {
                            // A writer was still at work: back off and read again.
                            p.not_before = Some(now + p.backoff);
                            p.backoff = (p.backoff * 2).min(Duration::from_secs(4));
                        }
                    }
                } else {
                    pending.remove(&target);
                }
            }
        }
        // The files the scene reads change with what it read (a VRT that
        // names new files) or by a request: looked at again when a read
        // ran here or the scene moved on, not at every tick.
        let generation = scene.snapshot().generation;
        if read || generation != seen_generation {
            seen_generation = generation;
            let now_groups = interests(&scene);
            if now_groups != groups {
                groups = now_groups;
                update_watches(&mut watcher, &mut watched, &groups);
            }
        }
    }
}

/// What on disk holds back a read of the source `target`: one look at each
/// folder, for all of its datasets there (a mosaic has hundreds in one).
fn on_disk(groups: &HashMap<(PathBuf, String), BTreeSet<Target>>, target: &Target) -> Busy {
    let mut folders: BTreeMap<&Path, BTreeSet<&str>> = BTreeMap::new();
    for ((dir, stem), _) in groups.iter().filter(|(_, t)| t.contains(target)) {
        folders.entry(dir.as_path()).or_default().insert(stem.as_str());
    }
    folders.iter().map(|(dir, stems)| busy(dir, stems)).fold(Busy::default(), Busy::or)
}

/// Records one notify event against the datasets it touches.
fn note(
    event: &notify::Event,
    groups: &HashMap<(PathBuf, String), BTreeSet<Target>>,
    pending: &mut HashMap<Target, Pending>,
) {
    let now = Instant::now();
    for path in &event.paths {
        let Some(key) = dataset_key(path) else {
            continue;
        };
        let Some(targets) = groups.get(&key) else {
            continue;
        };
        let change = change(event.kind, path);
        if change == Change::None {
            continue;
        }
        for target in targets {
            pending.entry(target.clone()).or_insert_with(|| Pending::new(now)).note(change, now);
        }
    }
}

fn update_watches(
    watcher: &mut RecommendedWatcher,
    watched: &mut BTreeSet<PathBuf>,
    groups: &HashMap<(PathBuf, String), BTreeSet<Target>>,
) {
    let wanted: BTreeSet<PathBuf> = groups
        .keys()
        .map(|(dir, _)| if dir.as_os_str().is_empty() { PathBuf::from(".") } else { dir.clone() })
        .collect();
    for gone in watched.difference(&wanted) {
        let _already_gone = watcher.unwatch(gone);
    }
    for dir in wanted.difference(watched) {
        if let Err(e) = watcher.watch(dir, RecursiveMode::NonRecursive) {
            tracing::warn!(folder = %dir.display(), "cannot watch folder: {e}; changes there are seen only through reloads");
        }
    }
    *watched = wanted;
}
