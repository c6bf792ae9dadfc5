//! Many file blocks at once. A window of a halved level rests on every
//! block under it of the nearest level read from the file (the base or an
//! overview): a coarse level over a whole mosaic is hundreds of them, read
//! one after another by the thread that asked. Before that thread starts,
//! the blocks missing from the cache are read here by reader threads of
//! their own (each with its own GDAL handles), while it waits.
//!
//! Why this cannot deadlock: the readers only decode file blocks, and
//! never wait on a coarser block; the asking thread holds no block under
//! construction while it waits (it has not started); and the readers are
//! plain threads, not a work-stealing pool, so a waiting tile thread never
//! takes up another tile's work (which could wait on a block this thread's
//! own stack is making).

use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex, OnceLock};

use super::Store;
use super::blocks::BLOCK;
use super::options::LevelInfo;

type Job = Box<dyn FnOnce() + Send>;

/// The reader threads' queue; None when none could be started.
fn queue() -> Option<&'static Mutex<Sender<Job>>> {
    static QUEUE: OnceLock<Option<Mutex<Sender<Job>>>> = OnceLock::new();
    QUEUE
        .get_or_init(|| {
            let (tx, rx) = channel::<Job>();
            let rx = Arc::new(Mutex::new(rx));
            let readers = std::thread::available_parallelism().map_or(2, usize::from).clamp(2, 16);
            let started = (0..readers)
                .filter(|i| {
                    let rx = Arc::clone(&rx);
                    std::thread::Builder::new().name(format!("relief-read-{i}")).spawn(move || serve(&rx)).is_ok()
                })
                .count();
            (started > 0).then(|| Mutex::new(tx))
        })
        .as_ref()
}

fn serve(jobs: &Mutex<Receiver<Job>>) {
    loop {
        let job = match jobs.lock() {
            Ok(rx) => rx.recv(),
            Err(_) => return,
        };
        match job {
            Ok(job) => job(),
            Err(_) => return,
        }
    }
}

/// The nearest level at or below `level` read from the file, and how many
/// of its pixels one pixel of `level` spans.
fn file_level(levels: &[LevelInfo], level: usize) -> (usize, usize) {
    let file = (0..=level).rev().find(|&l| l == 0 || levels[l].overview.is_some()).unwrap_or(0);
    (file, 1 << (level - file))
}

/// Reads the file blocks under `rect` of `level` that the cache lacks, on
/// the reader threads, and returns when they are in (or failed: the
/// window's own read then meets the error and reports it).
pub(super) fn file_blocks(store: &Arc<Store>, level: usize, rect: &super::PixelRect) {
    if rect.x0 >= rect.x1 || rect.y0 >= rect.y1 {
        return;
    }
    let (file, span) = file_level(&store.levels, level);
    let blocks = |l: usize, r: (usize, usize, usize, usize)| {
        (r.1 / BLOCK..=(r.3 - 1) / BLOCK)
            .flat_map(move |by| (r.0 / BLOCK..=(r.2 - 1) / BLOCK).map(move |bx| (l, bx, by)))
    };
    // Only under the blocks of `level` the cache lacks (file blocks under
    // cached ones would be read for nothing).
    let wanted: Vec<(usize, usize, usize)> = blocks(level, (rect.x0, rect.y0, rect.x1, rect.y1))
        .filter(|&(l, bx, by)| store.cached(l, bx, by).is_none())
        .collect();
    let base = &store.levels[file];
    let mut missing: Vec<(usize, usize)> = Vec::new();
    for &(_, bx, by) in &wanted {
        let (x0, y0) = (bx * BLOCK * span, by * BLOCK * span);
        let (x1, y1) = (((bx + 1) * BLOCK * span).min(base.width), ((by + 1) * BLOCK * span).min(base.height));
        if x0 < x1 && y0 < y1 {
            let under = blocks(file, (x0, y0, x1, y1));
            missing.extend(under.filter(|&(_, x, y)| store.cached(file, x, y).is_none()).map(|(_, x, y)| (x, y)));
        }
    }
    missing.sort_unstable();
    missing.dedup();
    // Read ahead at most a quarter of the block budget: more would be
    // pushed out again before the window reaches it.
    let block_bytes = (BLOCK * BLOCK * base.cache_pixel_bytes) as u64;
    if missing.len() < 2 || missing.len() as u64 * block_bytes > super::blocks::block_budget() / 4 {
        return;
    }
    let Some(queue) = queue() else { return };
    let (done, finished) = channel();
    let mut sent = 0;
    for (bx, by) in missing {
        let (store, done) = (Arc::clone(store), done.clone());
        let job: Job = Box::new(move || {
            let _read = store.block(file, bx, by);
            let _ = done.send(());
        });
        if queue.lock().is_ok_and(|q| q.send(job).is_ok()) {
            sent += 1;
        }
    }
    drop(done);
    for _ in 0..sent {
        if finished.recv().is_err() {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_halved_level_rests_on_the_nearest_file_level_below() {
        let level = |overview| LevelInfo::new((10, 10), 1.0, overview, (1.0, 1.0), (10, 10));
        let levels = [level(None), level(None), level(Some(0)), level(None), level(None)];
        assert_eq!(file_level(&levels, 0), (0, 1));
        assert_eq!(file_level(&levels, 1), (0, 2));
        assert_eq!(file_level(&levels, 2), (2, 1));
        assert_eq!(file_level(&levels, 4), (2, 4));
    }
}
