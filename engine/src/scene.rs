//! The live scene: the current snapshot, refreshes that turn file changes
//! (and manifest edits) into new generations, the rebuild of the cached
//! tiles a change touched, and the events that tell viewers about it.

use std::collections::{HashMap, HashSet, VecDeque};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, RwLock};
use std::time::Instant;

use relief_source::{DirtySet, Extent, Quality, Refresh, TileKey};
use tokio::sync::{broadcast, watch};

use crate::addressing::ContentKeys;
use crate::backing::disk::DiskTiles;
use crate::backing::redis::RedisTiles;
use crate::backing::{Backing, Backings};
use crate::graph::{self, LoadError, SceneSnapshot};
use crate::manifest::Manifest;
use crate::parameters::{self, InForce, Overrides, Target};
use crate::registry::Registry;
use crate::tiles::{QualityKey, TileStore};

#[derive(Debug, Clone)]
pub struct DirtyRegion {
    pub source_id: String,
    pub extents: Vec<Extent>,
}

/// What a new generation cost.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RebuildStats {
    /// Cached tiles the change touched, generated again before the
    /// generation was published.
    pub rebuilt: u64,
    /// Cached tiles whose old version was dropped.
    pub invalidated: u64,
    /// Cached tiles the change did not touch, kept as they were.
    pub carried: u64,
    /// Tiles of derived sources kept because every input tile they read
    /// was rebuilt to the same bytes (early cutoff).
    pub cut_off: u64,
}

#[derive(Debug, Clone)]
pub enum EventKind {
    Generation {
        changed_sources: Vec<String>,
        dirty: Vec<DirtyRegion>,
        stats: RebuildStats,
        elapsed_ms: f64,
        reason: String,
    },
    SourceError {
        source_id: String,
        error: String,
        kept_last_good: bool,
    },
    ManifestError {
        error: String,
    },
}

#[derive(Debug, Clone)]
pub struct SceneEvent {
    pub generation: u64,
    pub kind: EventKind,
}

/// What a refresh did.
#[derive(Debug, Clone, Default)]
pub struct RefreshOutcome {
    pub generation: u64,
    /// Sources to read again later: a writer was at work, or (when errors
    /// are not to be reported yet) the read failed.
    pub retry: Vec<String>,
}

pub struct Scene {
    current: RwLock<Arc<SceneSnapshot>>,
    manifest_path: PathBuf,
    manifest_error: RwLock<Option<String>>,
    /// The manifest's text the last edit was built from: a save that left
    /// it as it was (an editor's, or a file beside it sharing its name's
    /// stem) makes no generation.
    built_from: Mutex<Option<String>>,
    /// The values calls have set (laid over the manifest), and them as the
    /// state shows them.
    parameters: RwLock<(Overrides, Vec<InForce>)>,
    /// What else a manifest must pass, read at load and read again.
    check: ManifestCheck,
    registry: Registry,
    pub store: Arc<TileStore>,
    generation: watch::Sender<u64>,
    events: broadcast::Sender<SceneEvent>,
    refresh_lock: Mutex<()>,
    reads_retried: AtomicU64,
    /// Sources read again because their files changed.
    source_reads: AtomicU64,
    /// Works out each new version's content address in the background.
    content: ContentKeys,
    /// The last [`DIRT_LOG`] generations' dirty extents by source, oldest
    /// first, logged before each is served: what a cache that fell behind
    /// refreshes.
    dirt_log: Mutex<VecDeque<(u64, Vec<DirtyRegion>)>>,
}

/// Generations of dirt remembered for caches that fall behind.
const DIRT_LOG: usize = 64;

/// How many events a slow Watch subscriber may fall behind before it is
/// told it lagged (it then gets a fresh snapshot).
const EVENT_BACKLOG: usize = 256;

/// A check of a manifest beyond its own (the picture it asks for, which
/// what draws it knows): a manifest that fails it is refused at load and
/// when read again, as any other error in it.
pub type ManifestCheck = fn(&Manifest) -> Result<(), crate::manifest::ManifestError>;

impl Scene {
    /// Loads the manifest and opens every source. With `keep_going`, sources
    /// that fail to open are served as failed (their errors are returned
    /// for logging); without it any error fails the load.
    pub fn load(
        manifest_path: &std::path::Path,
        keep_going: bool,
        threads: usize,
    ) -> Result<(Self, Vec<LoadError>), Vec<LoadError>> {
        Self::load_checked(manifest_path, keep_going, threads, |_| Ok(()))
    }

    /// `load`, the manifest also held to `check`, then and whenever it is
    /// read again.
    pub fn load_checked(
        manifest_path: &std::path::Path,
        keep_going: bool,
        threads: usize,
        check: ManifestCheck,
    ) -> Result<(Self, Vec<LoadError>), Vec<LoadError>> {
        let text = Manifest::read(manifest_path).map_err(|e| vec![LoadError::from(e)])?;
        let manifest = Manifest::parse(&text, manifest_path)
            .and_then(|m| check(&m).map(|()| m))
            .map_err(|e| vec![LoadError::from(e)])?;
        let budget = manifest.cache_budget_bytes;
        relief_source_gdal::set_block_budget(manifest.raster_budget_bytes);
        let registry = Registry::builtin();
        let (snapshot, open_errors) = graph::build(manifest, &registry, None)?;
        if !keep_going && !open_errors.is_empty() {
            return Err(open_errors);
        }
        let (generation, _) = watch::channel(snapshot.generation);
        let (events, _) = broadcast::channel(EVENT_BACKLOG);
        let store = Arc::new(TileStore::new(budget, threads).with_backings(outer_stores(&snapshot.manifest)));
        if store.has_backings() {
            crate::addressing::fill_objects(&snapshot);
        }
        let snapshot = Arc::new(snapshot);
        let content = ContentKeys::start(Arc::downgrade(&store));
        if store.has_backings() {
            content.fill(Arc::clone(&snapshot));
        }
        Ok((
            Self {
                manifest_path: snapshot.manifest.path.clone(),
                check,
                current: RwLock::new(snapshot),
                manifest_error: RwLock::new(None),
                built_from: Mutex::new(Some(text)),
                parameters: RwLock::new((Overrides::default(), Vec::new())),
                registry,
                store,
                generation,
                events,
                refresh_lock: Mutex::new(()),
                reads_retried: AtomicU64::new(0),
                source_reads: AtomicU64::new(0),
                content,
                dirt_log: Mutex::new(VecDeque::new()),
            },
            open_errors,
        ))
    }

    pub fn snapshot(&self) -> Arc<SceneSnapshot> {
        Arc::clone(&self.current.read().expect("scene lock is never poisoned"))
    }

    pub fn manifest_path(&self) -> &std::path::Path {
        &self.manifest_path
    }

    /// Why the last manifest edit was not taken, if it was not.
    pub fn manifest_error(&self) -> Option<String> {
        self.manifest_error.read().expect("scene lock is never poisoned").clone()
    }

    /// Reads discarded so far because a writer was still at work.
    pub fn reads_retried(&self) -> u64 {
        self.reads_retried.load(Ordering::Relaxed)
    }

    /// Sources read again because their files changed (successful or not).
    pub fn source_reads(&self) -> u64 {
        self.source_reads.load(Ordering::Relaxed)
    }

    /// The dirty extents of every generation after `since` up to `upto`,
    /// by source; None when the log no longer holds them all.
    pub fn dirt_between(&self, since: u64, upto: u64) -> Option<Vec<DirtyRegion>> {
        let log = self.dirt_log.lock().expect("the dirt log's lock is never held across a panic");
        if since >= upto {
            return Some(Vec::new());
        }
        if log.front().is_none_or(|(g, _)| *g > since + 1) || log.back().is_none_or(|(g, _)| *g < upto) {
            return None;
        }
        Some(log.iter().filter(|(g, _)| *g > since && *g <= upto).flat_map(|(_, d)| d.iter().cloned()).collect())
    }

    pub fn generations(&self) -> watch::Receiver<u64> {
        self.generation.subscribe()
    }

    pub fn events(&self) -> broadcast::Receiver<SceneEvent> {
        self.events.subscribe()
    }

    /// Serves `new` from now on (its content addresses worked out behind).
    fn swap(&self, new: SceneSnapshot) {
        if self.store.has_backings() {
            crate::addressing::fill_objects(&new);
        }
        let new = Arc::new(new);
        *self.current.write().expect("scene lock is never poisoned") = Arc::clone(&new);
        if self.store.has_backings() {
            self.content.fill(new);
        }
    }

    fn send(&self, generation: u64, kind: EventKind) {
        if let EventKind::SourceError { source_id, .. } = &kind {
            metrics::counter!("relief_source_errors_total", "source" => source_id.clone()).increment(1);
        }
        let _no_subscribers = self.events.send(SceneEvent { generation, kind });
    }

    /// Re-reads the file sources (all, or those in `only`). A source that
    /// fails keeps its last good version; with `report_errors` the error is
    /// shown on it, otherwise it is only handed back for a retry (the
    /// watcher does that while a writer may still be at work). Blocking.
    pub fn refresh(&self, only: Option<&[String]>, reason: &str, report_errors: bool) -> RefreshOutcome {
        let _one_at_a_time = self.refresh_lock.lock().expect("refresh lock is never poisoned");
        let started = Instant::now();
        let old = self.snapshot();
        let mut new = (*old).clone();
        let generation = old.generation + 1;
        let mut dirt: HashMap<String, DirtySet> = HashMap::new();
        let mut changed_sources = Vec::new();
        let mut status_changed = false;
        let mut retry = Vec::new();
        let mut error_events = Vec::new();

        for slot in &mut new.slots {
            // Ops change with their inputs; only those that read files of
            // their own (the glTF models of `scatter`) are refreshed too.
            let reads_files = slot.inputs.is_empty() || !slot.spec.paths.is_empty();
            if only.is_some_and(|ids| !ids.contains(&slot.spec.id)) || !reads_files {
                continue;
            }
            // A failure says (transient, worth retrying, error).
            let result = match &slot.source {
                Some(source) => source.refresh(&new.grid).map_err(|e| {
                    let (transient, again) = (e.is_transient(), e.retry_later());
                    (transient, again, graph::source_error(&slot.spec, e))
                }),
                None => graph::open_source(&slot.spec, &new.grid, &self.registry)
                    .map(|source| Refresh::Changed { source, dirty: DirtySet::everything() })
                    .map_err(|e| match &e {
                        LoadError::Source { error, .. } => (error.is_transient(), error.retry_later(), e),
                        _ => (false, false, e),
                    }),
            };
            if !matches!(result, Ok(Refresh::Unchanged)) {
                self.source_reads.fetch_add(1, Ordering::Relaxed);
            }
            match result {
                Ok(Refresh::Unchanged) => {
                    if slot.error.take().is_some() {
                        status_changed = true;
                    }
                }
                // Same data under new file fingerprints (a no-op save): swap
                // it in quietly, nothing to rebuild.
                Ok(Refresh::Changed { source, dirty }) if dirty.is_none() => {
                    slot.source = Some(source);
                    if slot.error.take().is_some() {
                        status_changed = true;
                    }
                }
                Ok(Refresh::Changed { source, dirty }) => {
                    slot.source = Some(source);
                    slot.version = generation;
                    slot.error = None;
                    dirt.insert(slot.spec.id.clone(), dirty);
                    changed_sources.push(slot.spec.id.clone());
                }
                Err((transient, again, e)) => {
                    if transient || !report_errors {
                        tracing::debug!(source.id = %slot.spec.id, "not read yet: {e}");
                        retry.push(slot.spec.id.clone());
                        self.reads_retried.fetch_add(1, Ordering::Relaxed);
                        continue;
                    }
                    if again {
                        // Shown, and read again once the lock may be gone.
                        retry.push(slot.spec.id.clone());
                    }
                    let message = e.to_string();
                    if slot.error.as_deref() != Some(message.as_str()) {
                        tracing::warn!(source.id = %slot.spec.id, "{message}; keeping the last good version");
                        error_events.push(EventKind::SourceError {
                            source_id: slot.spec.id.clone(),
                            error: message.clone(),
                            kept_last_good: slot.source.is_some(),
                        });
                        slot.error = Some(message);
                        status_changed = true;
                    }
                }
            }
        }
        tracing::debug!(read_ms = started.elapsed().as_secs_f64() * 1e3, "sources read");
        if changed_sources.is_empty() && !status_changed {
            // Quiet swaps (new fingerprints, same data) still take effect.
            self.swap(new);
            return RefreshOutcome { generation: old.generation, retry };
        }
        let generation = self.publish(&old, new, dirt, changed_sources, error_events, reason, started);
        RefreshOutcome { generation, retry }
    }

    /// Reads the manifest again and applies it source by source: unchanged
    /// sources keep their tiles; added, removed and changed ones are
    /// (re)built. A manifest that does not load keeps the scene as it was
    /// and shows why. Blocking.
    pub fn reload_manifest(&self) -> u64 {
        let _one_at_a_time = self.refresh_lock.lock().expect("refresh lock is never poisoned");
        let started = Instant::now();
        let old = self.snapshot();
        // A call's values stay in force over the edit, less those whose
        // source or effect the edit removed.
        let held = self.parameters.read().expect("scene lock is never poisoned").0.clone();
        let read = self.read_manifest();
        let unchanged = read.as_ref().is_ok_and(|(text, _)| {
            self.built_from.lock().expect("scene lock is never poisoned").as_deref() == Some(text.as_str())
        });
        if unchanged && self.manifest_error.read().expect("scene lock is never poisoned").is_none() {
            return old.generation;
        }
        let built = read.and_then(|(text, table)| {
            let overrides = held.still_applicable(&table);
            let built = self.build(&text, &table, &overrides, &old)?;
            *self.built_from.lock().expect("scene lock is never poisoned") = Some(text);
            Ok((built, overrides, table))
        });
        let ((new, open_errors), overrides, table) = match built {
            Ok(b) => b,
            Err(error) => {
                tracing::warn!("{error}; keeping the scene as it was");
                *self.manifest_error.write().expect("scene lock is never poisoned") = Some(error.clone());
                self.send(old.generation, EventKind::ManifestError { error });
                return old.generation;
            }
        };
        *self.manifest_error.write().expect("scene lock is never poisoned") = None;
        self.keep_parameters(overrides, &table);
        let reason =
            if old.manifest.grid == new.manifest.grid { "manifest edited" } else { "manifest edited (new grid)" };
        self.publish_manifest(&old, new, &open_errors, reason, started)
    }

    /// Sets `name` of `target` to `value` (TOML, or else a string; None:
    /// back to the manifest's), as if the manifest said so: checked as the
    /// manifest is, by building the scene from it, and published as a
    /// manifest edit is (what changed is dirty, nothing else). Err says
    /// why it was refused; the scene stays as it was. Blocking.
    pub fn set_parameter(&self, target: &str, name: &str, value: Option<&str>) -> Result<u64, String> {
        let _one_at_a_time = self.refresh_lock.lock().expect("refresh lock is never poisoned");
        let started = Instant::now();
        let old = self.snapshot();
        let target = Target::parse(target)?;
        let held = self.parameters.read().expect("scene lock is never poisoned").0.clone();
        let next = held.with(target.clone(), name, value.map(parameters::parse_value))?;
        let (text, table) = self.read_manifest()?;
        let (new, open_errors) = self.build(&text, &table, &next, &old)?;
        if let Target::Source(id) = &target
            && let Some(e) =
                open_errors.iter().find(|e| matches!(e, LoadError::Source { source_id, .. } if source_id == id))
        {
            return Err(e.to_string());
        }
        self.keep_parameters(next, &table);
        let reason = match value {
            Some(v) => format!("parameter set: {} {name} = {}", target.name(), relief_source::echo::echoed(v)),
            None => format!("parameter reset to the manifest's: {} {name}", target.name()),
        };
        Ok(self.publish_manifest(&old, new, &open_errors, &reason, started))
    }

    /// The values calls have set that are in force, with the manifest's.
    pub fn parameters(&self) -> Vec<InForce> {
        self.parameters.read().expect("scene lock is never poisoned").1.clone()
    }

    /// Keeps `overrides`, shown beside the manifest's values (`table`).
    fn keep_parameters(&self, overrides: Overrides, table: &toml::Table) {
        let shown = overrides.in_force(table);
        *self.parameters.write().expect("scene lock is never poisoned") = (overrides, shown);
    }

    /// The manifest's text and its TOML, read once for a rebuild.
    fn read_manifest(&self) -> Result<(String, toml::Table), String> {
        let path = &self.manifest_path;
        let text = Manifest::read(path).map_err(|e| e.to_string())?;
        let table = Manifest::table(&text, path).map_err(|e| e.to_string())?;
        Ok((text, table))
    }

    /// The scene the manifest describes with `overrides` laid over it, held
    /// to the server's check, built over `old` (unchanged sources kept).
    fn build(
        &self,
        text: &str,
        table: &toml::Table,
        overrides: &Overrides,
        old: &SceneSnapshot,
    ) -> Result<(SceneSnapshot, Vec<LoadError>), String> {
        let path = &self.manifest_path;
        let manifest = if overrides.is_empty() {
            Manifest::parse(text, path).map_err(|e| e.to_string())?
        } else {
            let mut table = table.clone();
            overrides.apply(&mut table)?;
            let laid =
                toml::to_string(&table).map_err(|e| format!("cannot lay the parameters over the manifest: {e}"))?;
            Manifest::parse(&laid, path).map_err(|e| e.to_string())?
        };
        (self.check)(&manifest).map_err(|e| e.to_string())?;
        graph::build(manifest, &self.registry, Some(old))
            .map_err(|errors| errors.iter().map(ToString::to_string).collect::<Vec<_>>().join("; "))
    }

    /// Publishes a scene built from the manifest (an edit, or a call's
    /// parameter): the sources whose spec changed are dirty everywhere,
    /// those gone are forgotten, the rest keep their tiles.
    fn publish_manifest(
        &self,
        old: &SceneSnapshot,
        new: SceneSnapshot,
        open_errors: &[LoadError],
        reason: &str,
        started: Instant,
    ) -> u64 {
        let (was, now) = (&old.manifest, &new.manifest);
        if (was.cache_budget_bytes, &was.disk, &was.redis) != (now.cache_budget_bytes, &now.disk, &now.redis) {
            // The stores are the process's: opened once, when reliefd starts.
            tracing::warn!(
                "the manifest's [cache] changed: the new sizes and stores take effect when reliefd restarts"
            );
        }
        let mut dirt = HashMap::new();
        let mut changed = Vec::new();
        for slot in &new.slots {
            let before = old.slots.iter().find(|s| s.spec.id == slot.spec.id);
            if before.is_none_or(|b| b.spec != slot.spec) {
                dirt.insert(slot.spec.id.clone(), DirtySet::everything());
                changed.push(slot.spec.id.clone());
            }
        }
        for gone in old.slots.iter().filter(|s| new.index_of(&s.spec.id).is_none()) {
            self.store.forget(&gone.spec.id, gone.effective_version);
            changed.push(gone.spec.id.clone());
        }
        let errors = open_errors
            .iter()
            .map(|e| match e {
                LoadError::Source { source_id, .. } => {
                    EventKind::SourceError { source_id: source_id.clone(), error: e.to_string(), kept_last_good: false }
                }
                other => EventKind::ManifestError { error: other.to_string() },
            })
            .collect();
        self.publish(old, new, dirt, changed, errors, reason, started)
    }

    /// Carries dirt downstream, rebuilds the cached tiles it touches (coarse
    /// first, inputs before dependents, stopping where rebuilt tiles come
    /// out the same), then makes `new` the current generation and tells
    /// the watchers. Returns the new generation.
    #[expect(clippy::too_many_arguments, reason = "one call site per kind of change; a struct would only rename them")]
    fn publish(
        &self,
        old: &SceneSnapshot,
        mut new: SceneSnapshot,
        mut dirt: HashMap<String, DirtySet>,
        changed_sources: Vec<String>,
        error_events: Vec<EventKind>,
        reason: &str,
        started: Instant,
    ) -> u64 {
        for i in 0..new.slots.len() {
            let slot = &new.slots[i];
            let Some(source) = &slot.source else { continue };
            let mut d = dirt.remove(&slot.spec.id).unwrap_or_default();
            for (n, &input) in slot.inputs.iter().enumerate() {
                if let Some(input_dirt) = dirt.get(&new.slots[input].spec.id).filter(|d| !d.is_none()) {
                    d = d.union(&source.dirty_from_input(n, input_dirt));
                }
            }
            dirt.insert(slot.spec.id.clone(), d);
        }
        new.generation = old.generation + 1;
        new.recompute_versions();
        let rebuild_started = Instant::now();
        let stats = self.rebuild(old, &new, &dirt);
        tracing::debug!(
            rebuild_ms = rebuild_started.elapsed().as_secs_f64() * 1e3,
            rebuilt = stats.rebuilt,
            "cached tiles rebuilt"
        );

        let dirty: Vec<DirtyRegion> = new
            .slots
            .iter()
            .filter_map(|s| {
                dirt.get(&s.spec.id)
                    .filter(|d| !d.is_none())
                    .map(|d| DirtyRegion { source_id: s.spec.id.clone(), extents: d.extents(&new.grid) })
            })
            .collect();
        let generation = new.generation;
        {
            let mut log = self.dirt_log.lock().expect("the dirt log's lock is never held across a panic");
            log.push_back((generation, dirty.clone()));
            while log.len() > DIRT_LOG {
                log.pop_front();
            }
        }
        self.swap(new);
        let elapsed_ms = started.elapsed().as_secs_f64() * 1e3;
        record(&self.snapshot(), &changed_sources, &stats, elapsed_ms);
        tracing::info!(generation, changed = ?changed_sources, rebuilt = stats.rebuilt, carried = stats.carried, cut_off = stats.cut_off, elapsed_ms, "{reason}: new generation");
        for kind in error_events {
            self.send(generation, kind);
        }
        self.send(
            generation,
            EventKind::Generation { changed_sources, dirty, stats, elapsed_ms, reason: reason.to_owned() },
        );
        self.generation.send_replace(generation);
        generation
    }

    /// Moves the cache from `old` to `new`: tiles the dirt does not touch
    /// are carried over; touched ones are generated again, and a derived
    /// tile whose input tiles all came out the same is carried (early
    /// cutoff).
    fn rebuild(&self, old: &SceneSnapshot, new: &SceneSnapshot, dirt: &HashMap<String, DirtySet>) -> RebuildStats {
        let mut stats = RebuildStats::default();
        // Per source, the touched tiles that were rebuilt: changed or not.
        let mut outcome: Vec<HashMap<(QualityKey, TileKey), bool>> = vec![HashMap::new(); new.slots.len()];
        let none = DirtySet::none();
        for (i, slot) in new.slots.iter().enumerate() {
            let Some(before) = old.slots.iter().find(|s| s.spec.id == slot.spec.id) else {
                continue;
            };
            if before.effective_version == slot.effective_version {
                continue;
            }
            let d = dirt.get(&slot.spec.id).unwrap_or(&none);
            let mut to_build: Vec<(QualityKey, TileKey, u64)> = Vec::new();
            for (quality, key, tile) in self.store.cached(&slot.spec.id, before.effective_version) {
                let touched = d.touches_tile(&new.grid, key);
                // Early cutoff applies to a derived source that itself did not
                // change: only its inputs did.
                let inputs_same = !slot.inputs.is_empty()
                    && slot.version == before.version
                    && slot.inputs.iter().all(|&input| Self::input_unchanged(new, dirt, &outcome, input, quality, key));
                if touched && !inputs_same {
                    to_build.push((quality, key, tile.content_hash));
                } else {
                    if touched {
                        stats.cut_off += 1;
                    } else {
                        stats.carried += 1;
                    }
                    self.store.carry(&slot.spec.id, slot.effective_version, quality, key, tile);
                }
            }
            self.store.forget(&slot.spec.id, before.effective_version);
            stats.invalidated += to_build.len() as u64;
            let mut by_quality: HashMap<QualityKey, Vec<(usize, TileKey)>> = HashMap::new();
            for (q, key, _) in &to_build {
                by_quality.entry(*q).or_default().push((i, *key));
            }
            if self.store.shares_tiles() {
                // Replicas share the tiles: every replica sees the change,
                // and each building the tiles it held would build each of
                // them N times. They are built when next asked for, by the
                // first replica asked, and the others read them from the
                // shared store under the new content address.
                for (q, key, _) in &to_build {
                    outcome[i].insert((*q, *key), true);
                }
                continue;
            }
            let hashes: HashMap<(QualityKey, TileKey), u64> = to_build.iter().map(|(q, k, h)| ((*q, *k), *h)).collect();
            for (q, keys) in by_quality {
                for ((_, key), built) in keys.iter().zip(self.store.build(new, &keys, &Quality::from(q))) {
                    stats.rebuilt += 1;
                    let changed = built.map_or(true, |t| Some(&t.content_hash) != hashes.get(&(q, *key)));
                    outcome[i].insert((q, *key), changed);
                }
            }
        }
        stats
    }

    /// True when every tile of source `input` that a derived tile at `key`
    /// reads (the tile and its neighbours) is known to be unchanged.
    fn input_unchanged(
        new: &SceneSnapshot,
        dirt: &HashMap<String, DirtySet>,
        outcome: &[HashMap<(QualityKey, TileKey), bool>],
        input: usize,
        quality: QualityKey,
        key: TileKey,
    ) -> bool {
        let id = &new.slots[input].spec.id;
        let Some(d) = dirt.get(id).filter(|d| !d.is_none()) else {
            return true;
        };
        let lattice = new.grid.lattice(key, relief_source::SampleKind::Corner);
        let reach = new.grid.tile_extent(key).dilate(lattice.step_x, lattice.step_y);
        let read: HashSet<TileKey> = new.grid.keys_overlapping(key.level, &reach).into_iter().collect();
        read.iter().all(|k| !d.touches_tile(&new.grid, *k) || outcome[input].get(&(quality, *k)) == Some(&false))
    }
}

/// The tile stores behind memory the manifest asks for: the disk cache,
/// then Redis. One that cannot be opened is left out, with a warning: the
/// scene is served, only colder.
fn outer_stores(manifest: &crate::manifest::Manifest) -> Backings {
    let mut stores: Vec<Arc<dyn Backing>> = Vec::new();
    if let Some(disk) = &manifest.disk {
        match DiskTiles::open(disk.dir.clone(), disk.budget_bytes) {
            Ok(d) => stores.push(Arc::new(d)),
            Err(e) => tracing::warn!(
                "cannot use the disk tile cache ({e}): {}; tiles are kept in memory only",
                disk.dir.display()
            ),
        }
    }
    if let Some(url) = &manifest.redis {
        match RedisTiles::open(url) {
            Ok(r) => stores.push(Arc::new(r)),
            Err(e) => tracing::warn!("{e}; this replica generates its own tiles"),
        }
    }
    Backings::new(stores)
}

/// A generation in the metrics: its latency under each changed source's
/// kind, and what happened to the cached tiles.
fn record(snap: &SceneSnapshot, changed_sources: &[String], stats: &RebuildStats, elapsed_ms: f64) {
    metrics::counter!("relief_generations_total").increment(1);
    let mut kinds: Vec<&str> = changed_sources
        .iter()
        .filter_map(|id| snap.slots.iter().find(|s| &s.spec.id == id).map(|s| s.spec.kind.as_str()))
        .collect();
    kinds.sort_unstable();
    kinds.dedup();
    for kind in kinds {
        metrics::histogram!("relief_reload_seconds", "kind" => kind.to_owned()).record(elapsed_ms / 1e3);
    }
    metrics::counter!("relief_tiles_rebuilt_total").increment(stats.rebuilt);
    metrics::counter!("relief_tiles_carried_total").increment(stats.carried);
    metrics::counter!("relief_tiles_cut_off_total").increment(stats.cut_off);
}
