use std::path::PathBuf;

use notify::event::{CreateKind, DataChange, MetadataKind, RemoveKind};

use super::*;

#[test]
fn saves_are_read_fast_only_when_closed() {
    let s = WatchSettings::default();
    let t0 = Instant::now();
    let idle = Busy::default();
    let repacking = Busy { repacking: true, ..idle };
    let closed = Pending::new(t0);
    assert_eq!(readiness(&closed, t0, &s, idle), None, "settle first");
    assert_eq!(readiness(&closed, t0 + Duration::from_millis(6), &s, idle), Some(Ready::Fast));
    assert_eq!(readiness(&closed, t0 + Duration::from_millis(6), &s, repacking), None, "repack under way");
    assert_eq!(readiness(&closed, t0 + Duration::from_millis(600), &s, idle), Some(Ready::Quiet));
    let writing = Pending { save: Save::Writing, ..closed };
    assert_eq!(readiness(&writing, t0 + Duration::from_millis(600), &s, idle), None, "still open for writing");
    assert_eq!(readiness(&writing, t0 + Duration::from_millis(2100), &s, idle), Some(Ready::Quiet));
    let failed = Pending { fast_failed: true, ..closed };
    assert_eq!(readiness(&failed, t0 + Duration::from_millis(100), &s, idle), None);
    let slow = WatchSettings { fast_path: false, ..s };
    assert_eq!(readiness(&closed, t0 + Duration::from_millis(100), &slow, idle), None);
    let backing_off = Pending { not_before: Some(t0 + Duration::from_secs(1)), ..closed };
    assert_eq!(readiness(&backing_off, t0 + Duration::from_millis(600), &s, idle), None);
}

#[test]
fn a_committed_transaction_waits_for_the_quiet_period_and_a_journal_blocks_fast_reads() {
    let s = WatchSettings::default();
    let t0 = Instant::now();
    let committing = Pending { save: Save::Committing, ..Pending::new(t0) };
    assert_eq!(readiness(&committing, t0 + Duration::from_millis(100), &s, Busy::default()), None);
    assert_eq!(readiness(&committing, t0 + Duration::from_millis(500), &s, Busy::default()), Some(Ready::Quiet));
    let closed = Pending::new(t0);
    let journal = Busy { journal: true, ..Busy::default() };
    assert_eq!(readiness(&closed, t0 + Duration::from_millis(100), &s, journal), None);
    // A journal left behind does not stop the quiet read: SQLite's locks decide.
    assert_eq!(readiness(&closed, t0 + Duration::from_millis(500), &s, journal), Some(Ready::Quiet));
}

/// An event as notify's inotify backend reports it.
fn event(what: &str) -> EventKind {
    match what {
        "MODIFY" => EventKind::Modify(ModifyKind::Data(DataChange::Any)),
        "CLOSE_WRITE" => EventKind::Access(AccessKind::Close(AccessMode::Write)),
        "CREATE" => EventKind::Create(CreateKind::File),
        "DELETE" => EventKind::Remove(RemoveKind::File),
        "ATTRIB" => EventKind::Modify(ModifyKind::Metadata(MetadataKind::Any)),
        other => panic!("no such event in the traces: {other}"),
    }
}

/// One QGIS 3.22 commit on a GeoPackage layer (a vertex moved, an
/// attribute changed, a feature added, one deleted), as inotify showed it:
/// microseconds from the first write of the log, event, file suffix. Four
/// transactions go into the log, with two closes of the log among them
/// (QGIS's second connection), then the checkpoint into the database, the
/// log deleted, a journal transaction back to rollback mode, and the close
/// of the database. Recorded with one layer loaded; with a second layer of
/// the file loaded, the same, then the log and index made again.
const QGIS_COMMIT: &[(u64, &str, &str)] = &[
    (0, "MODIFY", "-wal"),
    (404, "MODIFY", "-wal"),
    (420, "MODIFY", "-wal"),
    (716, "CLOSE_WRITE", "-wal"),
    (1280, "ATTRIB", "-wal"),
    (1836, "CLOSE_WRITE", "-wal"),
    (2080, "MODIFY", "-wal"),
    (2692, "MODIFY", "-wal"),
    (3098, "MODIFY", "-wal"),
    (3900, "MODIFY", "-wal"),
    (4269, "MODIFY", "-shm"),
    (4746, "MODIFY", "-wal"),
    (5568, "MODIFY", "-wal"),
    (9626, "MODIFY", "-wal"),
    (9978, "MODIFY", ""),
    (10024, "MODIFY", ""),
    (10217, "DELETE", "-shm"),
    (10249, "CLOSE_WRITE", "-shm"),
    (10288, "CLOSE_WRITE", "-wal"),
    (10298, "DELETE", "-wal"),
    (10594, "CREATE", "-journal"),
    (10613, "MODIFY", "-journal"),
    (11016, "MODIFY", ""),
    (11037, "CLOSE_WRITE", "-journal"),
    (11050, "DELETE", "-journal"),
    (11142, "CLOSE_WRITE", ""),
    (12546, "CREATE", "-wal"),
    (12554, "CREATE", "-shm"),
];

/// Replays `trace` with its gaps stretched `stretch` times, asking after
/// every event and every millisecond between events whether the dataset
/// may be read; the first time it may, and how.
fn first_read(trace: &[(u64, &str, &str)], stretch: u64, s: &WatchSettings) -> Option<(u64, Ready)> {
    let t0 = Instant::now();
    let dir = tempfile::tempdir().expect("a temporary folder");
    let db = dir.path().join("town.gpkg");
    std::fs::write(&db, b"SQLite format 3\0").expect("a database header");
    let mut pending = Pending::new(t0);
    pending.fast_failed = true; // nothing to read before the commit
    let mut journal = false;
    let end = trace.last().map_or(0, |e| e.0 * stretch) + 1_000_000;
    let mut next = 0;
    let mut at = 0;
    while at <= end {
        while let Some(&(us, what, suffix)) = trace.get(next).filter(|e| e.0 * stretch <= at) {
            let path = PathBuf::from(format!("{}{suffix}", db.display()));
            match (what, suffix) {
                ("CREATE", "-journal") => journal = true,
                ("DELETE", "-journal") => journal = false,
                _ => {}
            }
            pending.note(change(event(what), &path), t0 + Duration::from_micros(us * stretch));
            next += 1;
        }
        let now = t0 + Duration::from_micros(at);
        if let Some(ready) = readiness(&pending, now, s, Busy { journal, ..Busy::default() }) {
            return Some((at, ready));
        }
        at += 250;
    }
    None
}

#[test]
fn a_qgis_geopackage_commit_is_read_once_whole_after_its_last_transaction() {
    let s = WatchSettings::default();
    let closing = QGIS_COMMIT.iter().rposition(|e| e.1 == "CLOSE_WRITE" && e.2.is_empty()).expect("the close");
    for stretch in [1, 4, 20, 40] {
        // Gaps up to 4 ms x 40 = 160 ms between the transactions of the
        // commit: still nothing is read before the database is closed.
        let (at, how) = first_read(QGIS_COMMIT, stretch, &s).expect("the commit is read");
        let closed = QGIS_COMMIT[closing].0 * stretch;
        assert_eq!(how, Ready::Fast, "x{stretch}: the close is the commit's closing event");
        assert!(at >= closed + s.settle_ms * 1000, "x{stretch}: read at {at} us, before the close at {closed} us");
        assert!(at <= closed + s.settle_ms * 1000 + 250, "x{stretch}: read late, at {at} us");
    }
}

#[test]
fn a_commit_whose_database_is_never_closed_is_read_after_the_quiet_period() {
    // "Save Layer Edits" that stays in edit mode, or a script's connection
    // kept open: transactions into the log, nothing closed.
    let s = WatchSettings::default();
    let trace: Vec<_> = QGIS_COMMIT.iter().copied().filter(|e| e.0 < 9700).collect();
    let (at, how) = first_read(&trace, 20, &s).expect("read in the end");
    assert_eq!(how, Ready::Quiet);
    assert!(at >= 9626 * 20 + s.debounce_ms * 1000, "read at {at} us, before the quiet period ended");
}

#[test]
fn our_own_reads_of_a_database_are_not_changes() {
    // A reader's connection to a database in WAL mode: the log and index
    // made, opened for writing, closed and deleted; and (GDAL 3.6) the
    // database closed after a read-write open, with nothing written.
    let db = PathBuf::from("/d/town.gpkg");
    let wal = PathBuf::from("/d/town.gpkg-wal");
    let shm = PathBuf::from("/d/town.gpkg-shm");
    for (what, path) in [("CREATE", &wal), ("CREATE", &shm), ("MODIFY", &shm), ("CLOSE_WRITE", &wal), ("DELETE", &wal)]
    {
        assert_eq!(change(event(what), path), Change::None, "{what} {}", path.display());
    }
    assert_eq!(change(event("CLOSE_WRITE"), &db), Change::Closed, "no change to read: the fingerprint says so");
    assert_eq!(change(event("MODIFY"), &wal), Change::Committed);
}

#[test]
fn an_arcgis_lock_holds_a_read_back_until_it_goes_or_the_write_timeout() {
    let s = WatchSettings::default();
    let t0 = Instant::now();
    let closed = Pending::new(t0);
    let locked = Busy { locked: true, ..Busy::default() };
    assert_eq!(readiness(&closed, t0 + Duration::from_millis(6), &s, locked), None, "no fast read");
    assert_eq!(readiness(&closed, t0 + Duration::from_millis(600), &s, locked), None, "nor a quiet one");
    // A lock left by a crashed ArcGIS: read after the write timeout.
    assert_eq!(readiness(&closed, t0 + Duration::from_millis(2100), &s, locked), Some(Ready::Quiet));
    // Gone: read at once.
    assert_eq!(readiness(&closed, t0 + Duration::from_millis(600), &s, Busy::default()), Some(Ready::Quiet));
}

#[test]
fn edit_locks_on_a_table_or_the_whole_geodatabase_hold_it_back_and_schema_locks_do_not()
-> Result<(), Box<dyn std::error::Error>> {
    let dir = tempfile::tempdir()?;
    let gdb = dir.path();
    std::fs::write(gdb.join("a0000000b.gdbtable"), b"")?;
    let stems: std::collections::BTreeSet<&str> = ["a0000000b"].into();
    std::fs::write(gdb.join("a0000000b.HOST.12.3.sr.lock"), b"")?;
    std::fs::write(gdb.join("_gdb.HOST.12.3.sr.lock"), b"")?;
    std::fs::write(gdb.join("a0000000c.HOST.12.3.ed.lock"), b"")?;
    assert!(!busy(gdb, &stems).locked, "schema locks, and another table's edit lock");
    std::fs::write(gdb.join("a0000000b.HOST.12.3.ed.lock"), b"")?;
    assert!(busy(gdb, &stems).locked);
    std::fs::remove_file(gdb.join("a0000000b.HOST.12.3.ed.lock"))?;
    std::fs::write(gdb.join("_gdb.HOST.12.3.wr.lock"), b"")?;
    assert!(busy(gdb, &stems).locked, "a write lock on the whole geodatabase");
    Ok(())
}
