//! What a dataset's file events say about its save, and when it may be
//! read: the rules of the module doc above, apart from the watching.

use std::path::Path;
use std::time::{Duration, Instant};

use notify::event::{AccessKind, AccessMode, EventKind, ModifyKind, RenameMode};
use relief_source::files::{Member, dataset_key, is_repack_marker, is_sqlite, member, write_lock_holds};

use crate::manifest::WatchSettings;

/// How far a dataset's save has got, by its last events.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Save {
    /// Its last write was closed (or nothing was written): a fast read may go.
    Closed,
    /// Written to since its last close: a writer is at work.
    Writing,
    /// A database transaction committed, the editor's connection still open:
    /// more transactions of the same commit may follow.
    Committing,
}

/// Where a dataset's save stands.
#[derive(Debug, Clone, Copy)]
pub(super) struct Pending {
    pub(super) last_event: Instant,
    pub(super) save: Save,
    /// A fast read was tried and failed: wait for the quiet period.
    pub(super) fast_failed: bool,
    /// Earliest next attempt after a discarded read (backoff).
    pub(super) not_before: Option<Instant>,
    pub(super) backoff: Duration,
}

impl Pending {
    pub(super) fn new(now: Instant) -> Self {
        Self {
            last_event: now,
            save: Save::Closed,
            fast_failed: false,
            not_before: None,
            backoff: Duration::from_millis(250),
        }
    }

    /// Takes one event's change into account, at `now`.
    pub(super) fn note(&mut self, change: Change, now: Instant) {
        if change == Change::None {
            return;
        }
        self.last_event = now;
        self.fast_failed = false;
        self.not_before = None;
        self.backoff = Duration::from_millis(250);
        self.save = match (change, self.save) {
            (Change::Closed, _) => Save::Closed,
            (Change::Written, _) | (Change::Committed, Save::Writing) => Save::Writing,
            (Change::Committed, _) => Save::Committing,
            (Change::Touched | Change::None, save) => save,
        };
    }
}

/// The read a pending dataset is ready for, if any.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Ready {
    Fast,
    Quiet,
}

/// What on disk holds a dataset back: a QGIS repack swaps files (no read
/// at all), a SQLite journal marks a transaction under way (no fast read),
/// an ArcGIS edit or write lock (no read until it goes, or until
/// `write_timeout_ms` without events: a crashed ArcGIS leaves its locks).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Busy {
    pub(super) repacking: bool,
    pub(super) journal: bool,
    pub(super) locked: bool,
}

impl Busy {
    pub(super) fn or(self, other: Self) -> Self {
        Self {
            repacking: self.repacking | other.repacking,
            journal: self.journal | other.journal,
            locked: self.locked | other.locked,
        }
    }
}

pub(super) fn readiness(p: &Pending, now: Instant, s: &WatchSettings, busy: Busy) -> Option<Ready> {
    if p.not_before.is_some_and(|t| now < t) {
        return None;
    }
    let quiet = now.duration_since(p.last_event);
    if p.save == Save::Writing || busy.locked {
        return (quiet >= Duration::from_millis(s.write_timeout_ms.max(s.debounce_ms))).then_some(Ready::Quiet);
    }
    if quiet >= Duration::from_millis(s.debounce_ms) && !busy.repacking {
        return Some(Ready::Quiet);
    }
    (s.fast_path
        && p.save == Save::Closed
        && !p.fast_failed
        && !busy.repacking
        && !busy.journal
        && quiet >= Duration::from_millis(s.settle_ms))
    .then_some(Ready::Fast)
}

/// What one event says about a dataset's save.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Change {
    /// Nothing (a read, a connection opening its log, our own reads).
    None,
    /// A write was closed, or a file renamed into place.
    Closed,
    /// A file was written to (or made) and is still open.
    Written,
    /// A database transaction was written.
    Committed,
    /// Anything else (a delete, new permissions): the save goes on.
    Touched,
}

/// Reads what `kind` on `path` means for its dataset's save.
pub(super) fn change(kind: EventKind, path: &Path) -> Change {
    let closed = matches!(
        kind,
        EventKind::Access(AccessKind::Close(AccessMode::Write))
            | EventKind::Modify(ModifyKind::Name(RenameMode::To | RenameMode::Both))
    );
    let written = matches!(kind, EventKind::Modify(ModifyKind::Data(_) | ModifyKind::Any) | EventKind::Create(_));
    match member(path) {
        Member::Ignored => Change::None,
        Member::SqliteWal => {
            if matches!(kind, EventKind::Modify(ModifyKind::Data(_) | ModifyKind::Any)) {
                Change::Committed
            } else {
                Change::None
            }
        }
        Member::SqliteJournal => {
            if written {
                Change::Committed
            } else {
                Change::None
            }
        }
        Member::Data if closed => Change::Closed,
        Member::Data if written => {
            if is_sqlite(path) {
                Change::Committed
            } else {
                Change::Written
            }
        }
        Member::Data => match kind {
            EventKind::Access(_) => Change::None,
            _ => Change::Touched,
        },
    }
}

pub(super) fn busy(dir: &Path, stems: &std::collections::BTreeSet<&str>) -> Busy {
    let mut busy = Busy::default();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return busy;
    };
    for p in entries.flatten().map(|e| e.path()) {
        let Some((_, stem)) = dataset_key(&p) else { continue };
        if stems.contains(stem.as_str()) {
            busy.repacking |= is_repack_marker(&p);
            busy.journal |= member(&p) == Member::SqliteJournal;
        }
        busy.locked |= write_lock_holds(&p, |s| stems.contains(s));
    }
    busy
}

#[cfg(test)]
mod tests;
