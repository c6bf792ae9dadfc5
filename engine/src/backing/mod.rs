//! Tile stores outside the process, behind the in-memory cache: a folder
//! on disk (warm restarts) and Redis (replicas sharing their work). Both
//! key tiles by content address (`content.rs`), so neither can hand back
//! a tile of another version of the data; both are optional, and a store
//! that fails only costs the tiles it would have given.

pub mod codec;
pub mod disk;
pub mod redis;

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::tile::Tile;

/// Bytes by content address.
pub trait Backing: Send + Sync + std::fmt::Debug {
    /// "disk", "redis": the name in the state and the metrics.
    fn name(&self) -> &'static str;
    fn get(&self, address: u128) -> Option<Vec<u8>>;
    /// Stores in the background; never blocks a request for long.
    fn put(&self, address: u128, bytes: Vec<u8>);
}

/// One store and what it did.
#[derive(Debug)]
struct Counted {
    backing: Arc<dyn Backing>,
    hits: AtomicU64,
    misses: AtomicU64,
    writes: AtomicU64,
}

/// A store's counters, for the state and the metrics.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BackingCounters {
    pub name: &'static str,
    pub hits: u64,
    pub misses: u64,
    pub writes: u64,
}

/// The stores, nearest first: a tile is looked for in each in turn, and a
/// tile found further out is copied into the nearer ones.
#[derive(Debug, Default)]
pub struct Backings(Vec<Counted>);

impl Backings {
    pub fn new(stores: Vec<Arc<dyn Backing>>) -> Self {
        Self(
            stores
                .into_iter()
                .map(|backing| Counted {
                    backing,
                    hits: AtomicU64::new(0),
                    misses: AtomicU64::new(0),
                    writes: AtomicU64::new(0),
                })
                .collect(),
        )
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The tile at `address` from the first store that has a whole record of it.
    pub fn get(&self, address: u128) -> Option<Tile> {
        for (i, store) in self.0.iter().enumerate() {
            let found = store.backing.get(address).and_then(|bytes| Some((codec::decode(address, &bytes)?, bytes)));
            match found {
                Some((tile, bytes)) => {
                    store.hits.fetch_add(1, Ordering::Relaxed);
                    for nearer in &self.0[..i] {
                        nearer.backing.put(address, bytes.clone());
                        nearer.writes.fetch_add(1, Ordering::Relaxed);
                    }
                    return Some(tile);
                }
                None => {
                    store.misses.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        None
    }

    /// Hands a tile generated here to every store.
    pub fn put(&self, address: u128, tile: &Tile) {
        if self.0.is_empty() {
            return;
        }
        let Some(bytes) = codec::encode(address, tile) else { return };
        for store in &self.0 {
            store.backing.put(address, bytes.clone());
            store.writes.fetch_add(1, Ordering::Relaxed);
        }
    }

    pub fn counters(&self) -> Vec<BackingCounters> {
        self.0
            .iter()
            .map(|s| BackingCounters {
                name: s.backing.name(),
                hits: s.hits.load(Ordering::Relaxed),
                misses: s.misses.load(Ordering::Relaxed),
                writes: s.writes.load(Ordering::Relaxed),
            })
            .collect()
    }
}
