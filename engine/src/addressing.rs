//! Content addresses worked out off the serving path: one background
//! thread at the lowest priority takes each snapshot as it is published,
//! works out the addresses its sources lack (`content.rs` says what they
//! hash), and hands the tiles made before an address was known to the
//! outer stores once the scene is still.

use std::collections::HashSet;
use std::sync::{Arc, Condvar, Mutex, Weak};

use crate::content::MadeOf;
use crate::graph::SceneSnapshot;
use crate::tiles::TileStore;

/// Works out every slot's address of `snap` that is not known yet, inputs
/// first; the indices of the slots that got one now.
pub fn fill(snap: &SceneSnapshot) -> Vec<usize> {
    fill_where(snap, |_| true)
}

/// Works out, before `snap` is served, the addresses of the slots that
/// read only objects: an object's part of an address is its version (no
/// bytes hashed), so it costs nothing, and every tile made from the first
/// is known to the outer stores (replicas find each other's tiles at once).
pub fn fill_objects(snap: &SceneSnapshot) {
    fill_where(snap, |slot| {
        slot.source.as_ref().is_some_and(|s| {
            let files = s.info().files;
            !files.is_empty() && files.iter().all(|f| relief_source::objects::is_object(f))
        })
    });
}

/// `fill`, for the slots `wanted` takes.
fn fill_where(snap: &SceneSnapshot, wanted: impl Fn(&crate::graph::Slot) -> bool) -> Vec<usize> {
    let mut found = Vec::new();
    for (index, slot) in snap.slots.iter().enumerate() {
        if slot.content.is_worked_out() || !wanted(slot) {
            continue;
        }
        let inputs: Option<Vec<u128>> = slot.inputs.iter().map(|&i| snap.slots[i].content.get()).collect();
        let made_of = slot.source.as_ref().zip(inputs).map(|(source, inputs)| MadeOf {
            grid: format!("{:?}", snap.grid),
            kind: &slot.spec.kind,
            options: format!("{:?}", slot.spec.options),
            inputs,
            files: source.info().files,
        });
        if slot.content.work_out(made_of) {
            found.push(index);
        }
    }
    found
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
    // Sources whose tiles went out under their address (a source's
    // address may have been worked out before it was served:
    // `fill_objects`).
    let mut persisted: HashSet<(String, u128)> = HashSet::new();
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
                fill(&snap);
                for slot in &snap.slots {
                    if let Some(address) = slot.content.get() {
                        let key = (slot.spec.id.clone(), address);
                        if !persisted.contains(&key) {
                            pending.insert(key);
                        }
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
                persisted = slots
                    .iter()
                    .filter_map(|slot| slot.content.get().map(|a| (slot.spec.id.clone(), a)))
                    .filter(|key| pending.contains(key) || persisted.contains(key))
                    .collect();
                pending.clear();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

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
