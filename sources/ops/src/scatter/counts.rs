//! What the scene state reports per class: samples of the class raster
//! and instances placed, summed over the tiles built so far. Counts are
//! kept per tile of the scatter's own level, so a tile built again (or a
//! coarser tile covering it) replaces its counts instead of adding to them.

use std::collections::{BTreeMap, HashMap};
use std::sync::Mutex;

use relief_source::{ClassCount, TileKey};

/// Samples and instances of each class in one tile.
pub type TileCounts = BTreeMap<i64, Tally>;

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Tally {
    pub samples: u64,
    pub instances: u64,
}

#[derive(Debug, Default)]
pub struct Counts {
    tiles: Mutex<HashMap<TileKey, TileCounts>>,
}

/// A copy, for a new version of the source whose instances stay the same.
impl Clone for Counts {
    fn clone(&self) -> Self {
        Self { tiles: Mutex::new(self.lock().clone()) }
    }
}

impl Counts {
    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<TileKey, TileCounts>> {
        // Counts are plain numbers: a panic elsewhere leaves them usable.
        self.tiles.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Sets the counts of tiles of the scatter's level.
    pub fn replace(&self, tiles: impl IntoIterator<Item = (TileKey, TileCounts)>) {
        let mut map = self.lock();
        for (key, counts) in tiles {
            map.insert(key, counts);
        }
    }

    /// How many tiles the counts cover.
    pub fn tiles(&self) -> usize {
        self.lock().len()
    }

    /// One line per class: every class seen and every class with a rule,
    /// by class code.
    pub fn classes(&self, ruled: &[i64]) -> Vec<ClassCount> {
        let mut total: BTreeMap<i64, Tally> = ruled.iter().map(|c| (*c, Tally::default())).collect();
        for counts in self.lock().values() {
            for (class, tally) in counts {
                let t = total.entry(*class).or_default();
                t.samples += tally.samples;
                t.instances += tally.instances;
            }
        }
        total
            .into_iter()
            .map(|(class, t)| ClassCount {
                class,
                has_rule: ruled.contains(&class),
                instances: t.instances,
                samples: t.samples,
            })
            .collect()
    }
}
