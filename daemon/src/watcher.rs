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
//! Every read re-stats the files afterwards and is discarded if they
//! changed meanwhile, so a slow writer is never half read. Events that do
//! not fit the bounded queue are dropped for a full rescan.

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use notify::event::{AccessKind, AccessMode, EventKind, ModifyKind, RenameMode};
use notify::{RecommendedWatcher, RecursiveMode, Watcher};
use relief_source::files::{dataset_key, is_lock_or_temp, is_repack_marker};
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

use crate::manifest::WatchSettings;
use crate::scene::Scene;

/// What a group of files belongs to.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Target {
    Source(String),
    Manifest,
}

/// Where a dataset's save stands.
#[derive(Debug, Clone, Copy)]
struct Pending {
    last_event: Instant,
    /// Written to since its last close: a writer is at work.
    writing: bool,
    /// A fast read was tried and failed: wait for the quiet period.
    fast_failed: bool,
    /// Earliest next attempt after a discarded read (backoff).
    not_before: Option<Instant>,
    backoff: Duration,
}

impl Pending {
    fn new(now: Instant) -> Self {
        Self {
            last_event: now,
            writing: false,
            fast_failed: false,
            not_before: None,
            backoff: Duration::from_millis(250),
        }
    }
}

/// The read a pending dataset is ready for, if any.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ready {
    Fast,
    Quiet,
}

fn readiness(p: &Pending, now: Instant, s: &WatchSettings, repacking: bool) -> Option<Ready> {
    if p.not_before.is_some_and(|t| now < t) {
        return None;
    }
    let quiet = now.duration_since(p.last_event);
    if p.writing {
        return (quiet >= Duration::from_millis(s.write_timeout_ms.max(s.debounce_ms))).then_some(Ready::Quiet);
    }
    if quiet >= Duration::from_millis(s.debounce_ms) && !repacking {
        return Some(Ready::Quiet);
    }
    (s.fast_path && !p.fast_failed && !repacking && quiet >= Duration::from_millis(s.settle_ms)).then_some(Ready::Fast)
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
        for file in files {
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

fn is_repacking(dir: &Path, stem: &str) -> bool {
    std::fs::read_dir(dir).is_ok_and(|entries| {
        entries.flatten().any(|e| {
            let p = e.path();
            is_repack_marker(&p) && dataset_key(&p).is_some_and(|(_, s)| s == stem)
        })
    })
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
    let mut tick = tokio::time::interval(Duration::from_millis(settings.settle_ms.clamp(1, 50)));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);

    loop {
        tokio::select! {
            () = shutdown.cancelled() => return Ok(()),
            Some(event) = rx.recv() => note(&event, &groups, &mut pending),
            _ = tick.tick() => {}
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
            let repacking = match target {
                Target::Source(id) => {
                    groups.iter().any(|((dir, stem), t)| t.contains(target) && is_repacking(dir, stem))
                        && !id.is_empty()
                }
                Target::Manifest => false,
            };
            match (target, readiness(p, now, &settings, repacking)) {
                (Target::Manifest, Some(_)) => manifest = true,
                (Target::Source(id), Some(Ready::Fast)) => fast.push(id.clone()),
                (Target::Source(id), Some(Ready::Quiet)) => quiet.push(id.clone()),
                (_, None) => {}
            }
        }
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
        if manifest || !pending.is_empty() {
            let now_groups = interests(&scene);
            if now_groups != groups {
                groups = now_groups;
                update_watches(&mut watcher, &mut watched, &groups);
            }
        }
    }
}

/// Records one notify event against the datasets it touches.
fn note(
    event: &notify::Event,
    groups: &HashMap<(PathBuf, String), BTreeSet<Target>>,
    pending: &mut HashMap<Target, Pending>,
) {
    let now = Instant::now();
    // Reads (ours included) change nothing.
    let (writing, closing) = match event.kind {
        EventKind::Access(AccessKind::Close(AccessMode::Write))
        | EventKind::Modify(ModifyKind::Name(RenameMode::To | RenameMode::Both)) => (false, true),
        EventKind::Access(_) => return,
        EventKind::Modify(ModifyKind::Data(_) | ModifyKind::Any) | EventKind::Create(_) => (true, false),
        EventKind::Remove(_) | EventKind::Modify(_) | EventKind::Any | EventKind::Other => (false, false),
    };
    for path in &event.paths {
        if is_lock_or_temp(path) {
            continue;
        }
        let Some(key) = dataset_key(path) else {
            continue;
        };
        let Some(targets) = groups.get(&key) else {
            continue;
        };
        for target in targets {
            let p = pending.entry(target.clone()).or_insert_with(|| Pending::new(now));
            p.last_event = now;
            p.fast_failed = false;
            p.not_before = None;
            p.backoff = Duration::from_millis(250);
            if writing {
                p.writing = true;
            } else if closing {
                p.writing = false;
            }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn saves_are_read_fast_only_when_closed() {
        let s = WatchSettings::default();
        let t0 = Instant::now();
        let closed = Pending::new(t0);
        assert_eq!(readiness(&closed, t0, &s, false), None, "settle first");
        assert_eq!(readiness(&closed, t0 + Duration::from_millis(6), &s, false), Some(Ready::Fast));
        assert_eq!(readiness(&closed, t0 + Duration::from_millis(6), &s, true), None, "repack under way");
        assert_eq!(readiness(&closed, t0 + Duration::from_millis(600), &s, false), Some(Ready::Quiet));
        let writing = Pending { writing: true, ..closed };
        assert_eq!(readiness(&writing, t0 + Duration::from_millis(600), &s, false), None, "still open for writing");
        assert_eq!(readiness(&writing, t0 + Duration::from_millis(2100), &s, false), Some(Ready::Quiet));
        let failed = Pending { fast_failed: true, ..closed };
        assert_eq!(readiness(&failed, t0 + Duration::from_millis(100), &s, false), None);
        let slow = WatchSettings { fast_path: false, ..s };
        assert_eq!(readiness(&closed, t0 + Duration::from_millis(100), &slow, false), None);
        let backing_off = Pending { not_before: Some(t0 + Duration::from_secs(1)), ..closed };
        assert_eq!(readiness(&backing_off, t0 + Duration::from_millis(600), &s, false), None);
    }
}
