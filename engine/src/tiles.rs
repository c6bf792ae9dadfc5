//! The tile store: a memory-bounded cache in front of the source graph, and
//! the worker pool that fills it (coarse levels first, inputs before
//! dependents, one generation per tile even when many ask at once).

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use moka::sync::Cache;
use rayon::prelude::*;
use relief_source::{GenerateContext, InputTiles, Payload, Quality, SourceError, TileKey};

use crate::backing::Backings;
use crate::graph::SceneSnapshot;
pub use crate::tile::Tile;

/// Why a tile cannot be had. Not `non_exhaustive`: the server maps each
/// kind to its answer, and a new kind should make it choose one.
#[derive(Debug, Clone, thiserror::Error)]
pub enum TileError {
    #[error("no source has id '{0}'")]
    UnknownSource(String),
    #[error("tile {key} is outside the grid (level {level} has {cols} x {rows} tiles)", level = key.level)]
    OutsideGrid { key: TileKey, cols: u32, rows: u32 },
    #[error("source '{id}' has no data to serve: {reason}")]
    Unavailable { id: String, reason: String },
    #[error("source '{id}' could not generate tile {key}: {message}")]
    Generate { id: String, key: TileKey, message: String },
    #[error("the tile worker pool shut down")]
    Cancelled,
}

/// The quality knobs a tile was made with, as a cache key part that can be
/// turned back into the knobs (to rebuild the tile the same way).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct QualityKey {
    resampling: relief_source::Resampling,
    reprojection_error_bits: u64,
}

impl From<&Quality> for QualityKey {
    fn from(q: &Quality) -> Self {
        Self { resampling: q.resampling, reprojection_error_bits: q.reprojection_error_px.to_bits() }
    }
}

impl From<QualityKey> for Quality {
    fn from(k: QualityKey) -> Self {
        Self { resampling: k.resampling, reprojection_error_px: f64::from_bits(k.reprojection_error_bits) }
    }
}

#[derive(Clone, PartialEq, Eq, Hash)]
struct CacheKey {
    source: Arc<str>,
    version: u64,
    quality: QualityKey,
    key: TileKey,
}

/// Counters for the scene state.
#[derive(Debug, Clone, Copy, Default)]
pub struct StoreCounters {
    pub tiles_generated: u64,
    pub hits: u64,
    pub misses: u64,
    pub entries: u64,
    pub bytes: u64,
    pub budget_bytes: u64,
}

pub struct TileStore {
    cache: Cache<CacheKey, Arc<Tile>>,
    budget_bytes: u64,
    pool: rayon::ThreadPool,
    generated: Mutex<HashMap<String, u64>>,
    hits: AtomicU64,
    misses: AtomicU64,
    /// Stores outside the process (disk, Redis), asked on a miss before
    /// generating; each generated tile is handed to them.
    backings: Backings,
}

impl TileStore {
    pub fn new(budget_bytes: u64, threads: usize) -> Self {
        let cache = Cache::builder()
            .max_capacity(budget_bytes)
            .weigher(|_k: &CacheKey, t: &Arc<Tile>| u32::try_from(t.payload.size_bytes() + 96).unwrap_or(u32::MAX))
            .build();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .thread_name(|i| format!("relief-tiles-{i}"))
            .build()
            .expect("a thread pool of a few named threads can be built");
        Self {
            cache,
            budget_bytes,
            pool,
            generated: Mutex::new(HashMap::new()),
            hits: AtomicU64::new(0),
            misses: AtomicU64::new(0),
            backings: Backings::default(),
        }
    }

    /// The store with `backings` behind its memory cache.
    #[must_use]
    pub fn with_backings(mut self, backings: Backings) -> Self {
        self.backings = backings;
        self
    }

    /// Hands `slot`'s cached tiles to the outer stores, once its content
    /// address is known (tiles made before it were kept in memory only).
    pub fn persist(&self, slot: &crate::graph::Slot) {
        let Some(content) = slot.content.get() else { return };
        for (quality, key, tile) in self.cached(&slot.spec.id, slot.effective_version) {
            self.backings.put(crate::content::tile_address(content, &quality, key), &tile);
        }
    }

    pub fn has_backings(&self) -> bool {
        !self.backings.is_empty()
    }

    /// What each outer store did.
    /// True when tiles are shared with other processes (Redis): replicas
    /// of the scene then build a tile an edit touched once between them,
    /// when it is next asked for, rather than each at once.
    pub fn shares_tiles(&self) -> bool {
        self.backings.counters().iter().any(|c| c.name == "redis")
    }

    pub fn backing_counters(&self) -> Vec<crate::backing::BackingCounters> {
        self.backings.counters()
    }

    /// The tile `key` of source number `index` in `snap`, from the cache or
    /// generated now (its inputs first). Blocking: call it from the pool.
    pub fn tile(
        &self,
        snap: &SceneSnapshot,
        index: usize,
        key: TileKey,
        quality: &Quality,
    ) -> Result<Arc<Tile>, TileError> {
        let slot = &snap.slots[index];
        let id = slot.spec.id.as_str();
        if !snap.grid.contains_key(key) {
            let (cols, rows) = snap.grid.tiles_at(key.level);
            return Err(TileError::OutsideGrid { key, cols, rows });
        }
        let Some(source) = &slot.source else {
            return Err(TileError::Unavailable {
                id: id.into(),
                reason: slot.error.clone().unwrap_or_else(|| "never loaded".into()),
            });
        };
        let cache_key = CacheKey {
            source: Arc::from(id),
            version: slot.effective_version,
            quality: QualityKey::from(quality),
            key,
        };
        let quality_key = cache_key.quality;
        if let Some(t) = self.cache.get(&cache_key) {
            self.hits.fetch_add(1, Ordering::Relaxed);
            return Ok(t);
        }
        self.cache
            .try_get_with(cache_key, || {
                self.misses.fetch_add(1, Ordering::Relaxed);
                // Known once the content thread has hashed this version's files.
                let address = slot.content.get().map(|c| crate::content::tile_address(c, &quality_key, key));
                if let Some(tile) = address.and_then(|a| self.backings.get(a)) {
                    return Ok(Arc::new(tile));
                }
                let started = std::time::Instant::now();
                let inputs = Inputs { store: self, snap, index, quality };
                let ctx = GenerateContext { grid: &snap.grid, quality, inputs: &inputs };
                let payload = source.generate(key, &ctx).map_err(|e| TileError::Generate {
                    id: id.into(),
                    key,
                    message: e.to_string(),
                })?;
                *self.generated.lock().expect("counter lock is never poisoned").entry(id.to_owned()).or_default() += 1;
                tracing::trace!(
                    source.id = id,
                    tile.level = key.level,
                    tile.x = key.x,
                    tile.y = key.y,
                    elapsed_ms = started.elapsed().as_secs_f64() * 1e3,
                    "tile generated"
                );
                let content_hash = payload.content_hash();
                let tile = Tile { payload: Arc::new(payload), content_hash };
                if let Some(a) = address {
                    self.backings.put(a, &tile);
                }
                Ok(Arc::new(tile))
            })
            .map_err(|e: Arc<TileError>| (*e).clone())
    }

    /// Generates many tiles: coarse levels first, then in graph order, in
    /// parallel on the pool. Results come back in the order asked.
    pub fn build(
        &self,
        snap: &SceneSnapshot,
        requests: &[(usize, TileKey)],
        quality: &Quality,
    ) -> Vec<Result<Arc<Tile>, TileError>> {
        let mut order: Vec<usize> = (0..requests.len()).collect();
        order.sort_by_key(|&i| (requests[i].1.level, requests[i].0, requests[i].1.y, requests[i].1.x));
        let mut results: Vec<Option<Result<Arc<Tile>, TileError>>> = vec![None; requests.len()];
        self.pool.install(|| {
            // One level at a time, so no fine tile starts before every coarse one is done.
            let mut start = 0;
            while start < order.len() {
                let level = requests[order[start]].1.level;
                let end = start + order[start..].iter().take_while(|&&i| requests[i].1.level == level).count();
                let done: Vec<(usize, Result<Arc<Tile>, TileError>)> = order[start..end]
                    .par_iter()
                    .map(|&i| (i, self.tile(snap, requests[i].0, requests[i].1, quality)))
                    .collect();
                for (i, r) in done {
                    results[i] = Some(r);
                }
                start = end;
            }
        });
        results.into_iter().map(|r| r.unwrap_or(Err(TileError::Cancelled))).collect()
    }

    /// Runs blocking work on the tile pool and awaits its answer.
    pub async fn run<R: Send + 'static>(&self, job: impl FnOnce() -> R + Send + 'static) -> Result<R, TileError> {
        let (tx, rx) = tokio::sync::oneshot::channel();
        self.pool.spawn(move || {
            let _receiver_gone = tx.send(job());
        });
        rx.await.map_err(|_| TileError::Cancelled)
    }

    pub fn generated_for(&self, id: &str) -> u64 {
        self.generated.lock().expect("counter lock is never poisoned").get(id).copied().unwrap_or(0)
    }

    /// Tiles generated per source since start.
    pub fn generated(&self) -> Vec<(String, u64)> {
        self.generated.lock().expect("counter lock is never poisoned").iter().map(|(k, n)| (k.clone(), *n)).collect()
    }

    /// Every cached tile of `source` at `version`, coarse levels first.
    pub fn cached(&self, source: &str, version: u64) -> Vec<(QualityKey, TileKey, Arc<Tile>)> {
        let mut tiles: Vec<(QualityKey, TileKey, Arc<Tile>)> = self
            .cache
            .iter()
            .filter(|(k, _)| &*k.source == source && k.version == version)
            .map(|(k, t)| (k.quality, k.key, t))
            .collect();
        tiles.sort_by_key(|(_, k, _)| (k.level, k.y, k.x));
        tiles
    }

    /// Files a tile that is still right under a new version of its source.
    pub fn carry(&self, source: &str, version: u64, quality: QualityKey, key: TileKey, tile: Arc<Tile>) {
        self.cache.insert(CacheKey { source: Arc::from(source), version, quality, key }, tile);
    }

    /// Drops every cached tile of `source` at `version`.
    pub fn forget(&self, source: &str, version: u64) {
        let stale: Vec<Arc<CacheKey>> =
            self.cache.iter().filter(|(k, _)| &*k.source == source && k.version == version).map(|(k, _)| k).collect();
        for k in stale {
            self.cache.invalidate(&*k);
        }
    }

    pub fn counters(&self) -> StoreCounters {
        self.cache.run_pending_tasks();
        StoreCounters {
            tiles_generated: self.generated.lock().expect("counter lock is never poisoned").values().sum(),
            hits: self.hits.load(Ordering::Relaxed),
            misses: self.misses.load(Ordering::Relaxed),
            entries: self.cache.entry_count(),
            bytes: self.cache.weighted_size(),
            budget_bytes: self.budget_bytes,
        }
    }
}

/// Gives a generating source its inputs' tiles, through the same store.
struct Inputs<'a> {
    store: &'a TileStore,
    snap: &'a SceneSnapshot,
    index: usize,
    quality: &'a Quality,
}

impl InputTiles for Inputs<'_> {
    fn tile(&self, input: usize, key: TileKey) -> Result<Arc<Payload>, SourceError> {
        let slot = &self.snap.slots[self.index];
        let Some(&input_index) = slot.inputs.get(input) else {
            return Err(SourceError::Input { input: input.to_string(), message: "no such input".into() });
        };
        self.store.tile(self.snap, input_index, key, self.quality).map(|t| Arc::clone(&t.payload)).map_err(|e| {
            SourceError::Input { input: self.snap.slots[input_index].spec.id.clone(), message: e.to_string() }
        })
    }

    fn files(&self, input: usize) -> Vec<std::path::PathBuf> {
        let slot = &self.snap.slots[self.index];
        let Some(&input_index) = slot.inputs.get(input) else { return Vec::new() };
        let input = &self.snap.slots[input_index];
        input.source.as_ref().map(|s| s.info().files).unwrap_or_else(|| input.spec.paths.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn snapshot() -> SceneSnapshot {
        crate::testing::flat_snapshot(1)
    }

    #[test]
    fn the_cache_stays_within_its_memory_budget() {
        // 65 x 65 f32 = 16.9 kB a tile; a 200 kB budget holds about a dozen.
        let store = TileStore::new(200 * 1024, 2);
        let snap = snapshot();
        let keys: Vec<(usize, TileKey)> = (0..64).map(|x| (0, TileKey::new(6, x, 3))).collect();
        let built = store.build(&snap, &keys, &Quality::default());
        assert!(built.iter().all(Result::is_ok));
        let c = store.counters();
        assert!(c.bytes <= 200 * 1024, "{c:?}");
        assert!(c.entries < 64 && c.entries >= 5, "{c:?}");
        assert_eq!(c.tiles_generated, 64);
    }

    #[test]
    fn concurrent_requests_for_one_tile_generate_it_once() {
        let store = TileStore::new(64 << 20, 2);
        let snap = snapshot();
        let keys = vec![(0, TileKey::new(3, 1, 1)); 16];
        let built = store.build(&snap, &keys, &Quality::default());
        assert!(
            built
                .iter()
                .all(|t| { t.as_ref().is_ok_and(|t| t.content_hash == built[0].as_ref().unwrap().content_hash) })
        );
        assert_eq!(store.counters().tiles_generated, 1);
    }

    #[test]
    fn keys_outside_the_grid_are_refused() {
        let store = TileStore::new(1 << 20, 1);
        let err = store.tile(&snapshot(), 0, TileKey::new(2, 8, 0), &Quality::default()).unwrap_err();
        assert!(matches!(err, TileError::OutsideGrid { cols: 8, rows: 4, .. }), "{err}");
    }
}
