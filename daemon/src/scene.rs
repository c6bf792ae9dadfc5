//! The live scene: the current snapshot, refreshes that turn file changes
//! into new generations, and the events that tell viewers about them.

use std::sync::{Arc, Mutex, RwLock};
use std::time::Instant;

use relief_source::{DirtySet, Extent, Refresh};
use tokio::sync::{broadcast, watch};

use crate::graph::{self, LoadError, SceneSnapshot};
use crate::manifest::Manifest;
use crate::registry::Registry;
use crate::tiles::TileStore;

#[derive(Debug, Clone)]
pub struct DirtyRegion {
    pub source_id: String,
    pub extents: Vec<Extent>,
}

#[derive(Debug, Clone)]
pub enum EventKind {
    Generation {
        changed_sources: Vec<String>,
        dirty: Vec<DirtyRegion>,
        tiles_invalidated: u64,
        tiles_rebuilt: u64,
        elapsed_ms: f64,
        reason: String,
    },
    SourceError {
        source_id: String,
        error: String,
        kept_last_good: bool,
    },
}

#[derive(Debug, Clone)]
pub struct SceneEvent {
    pub generation: u64,
    pub kind: EventKind,
}

pub struct Scene {
    current: RwLock<Arc<SceneSnapshot>>,
    registry: Registry,
    pub store: Arc<TileStore>,
    generation: watch::Sender<u64>,
    events: broadcast::Sender<SceneEvent>,
    refresh_lock: Mutex<()>,
}

/// How many events a slow Watch subscriber may fall behind before it is
/// told it lagged (it then gets a fresh snapshot).
const EVENT_BACKLOG: usize = 256;

impl Scene {
    /// Loads the manifest and opens every source. With `keep_going`, sources
    /// that fail to open are served as failed (their errors are returned
    /// for logging); without it any error fails the load.
    pub fn load(
        manifest_path: &std::path::Path,
        keep_going: bool,
        threads: usize,
    ) -> Result<(Self, Vec<LoadError>), Vec<LoadError>> {
        let manifest = Manifest::load(manifest_path).map_err(|e| vec![LoadError::from(e)])?;
        let budget = manifest.cache_budget_bytes;
        let registry = Registry::builtin();
        let (snapshot, open_errors) = graph::build(manifest, &registry)?;
        if !keep_going && !open_errors.is_empty() {
            return Err(open_errors);
        }
        let (generation, _) = watch::channel(snapshot.generation);
        let (events, _) = broadcast::channel(EVENT_BACKLOG);
        Ok((
            Self {
                current: RwLock::new(Arc::new(snapshot)),
                registry,
                store: Arc::new(TileStore::new(budget, threads)),
                generation,
                events,
                refresh_lock: Mutex::new(()),
            },
            open_errors,
        ))
    }

    pub fn snapshot(&self) -> Arc<SceneSnapshot> {
        Arc::clone(&self.current.read().expect("scene lock is never poisoned"))
    }

    pub fn generations(&self) -> watch::Receiver<u64> {
        self.generation.subscribe()
    }

    pub fn events(&self) -> broadcast::Receiver<SceneEvent> {
        self.events.subscribe()
    }

    /// Re-reads the sources (all, or those in `only`) and publishes a new
    /// generation if anything changed. A source that fails keeps its last
    /// good version and shows the error. Blocking: run it off the runtime.
    pub fn refresh(&self, only: Option<&[String]>, reason: &str) -> u64 {
        let _one_at_a_time = self
            .refresh_lock
            .lock()
            .expect("refresh lock is never poisoned");
        let started = Instant::now();
        let old = self.snapshot();
        let mut new = (*old).clone();
        let count = new.slots.len();
        let mut dirt = vec![DirtySet::none(); count];
        let mut changed_sources = Vec::new();
        let mut status_changed = false;
        let mut error_events = Vec::new();

        for (slot, slot_dirt) in new.slots.iter_mut().zip(dirt.iter_mut()) {
            if only.is_some_and(|ids| !ids.contains(&slot.spec.id)) || !slot.inputs.is_empty() {
                continue;
            }
            let result = match &slot.source {
                Some(source) => source
                    .refresh(&new.grid)
                    .map_err(|e| graph::source_error(&slot.spec, e)),
                None => graph::open_source(&slot.spec, &new.grid, &self.registry).map(|source| {
                    Refresh::Changed {
                        source,
                        dirty: DirtySet::everything(),
                    }
                }),
            };
            match result {
                Ok(Refresh::Unchanged) => {
                    if slot.error.take().is_some() {
                        status_changed = true;
                    }
                }
                Ok(Refresh::Changed { source, dirty }) => {
                    slot.source = Some(source);
                    slot.version += 1;
                    slot.error = None;
                    *slot_dirt = dirty;
                    changed_sources.push(slot.spec.id.clone());
                }
                Err(e) => {
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
        if changed_sources.is_empty() && !status_changed {
            return old.generation;
        }

        // Carry dirt downstream: each op maps its inputs' dirt to its own.
        for i in 0..count {
            let slot = &new.slots[i];
            let Some(source) = &slot.source else { continue };
            for (n, &input) in slot.inputs.iter().enumerate() {
                if !dirt[input].is_none() {
                    dirt[i] = dirt[i].union(&source.dirty_from_input(n, &dirt[input]));
                }
            }
        }
        new.recompute_versions();
        new.generation = old.generation + 1;

        // Cached tiles the dirt does not touch are still right: carry them
        // over to the new versions; the others are invalidated.
        let mut tiles_invalidated = 0;
        for (i, d) in dirt.iter().enumerate() {
            let (old_slot, new_slot) = (&old.slots[i], &new.slots[i]);
            if old_slot.effective_version == new_slot.effective_version {
                continue;
            }
            let (carried, invalidated) = self.store.carry_over(
                &new_slot.spec.id,
                old_slot.effective_version,
                new_slot.effective_version,
                |k| !d.touches_tile(&new.grid, k),
            );
            tracing::debug!(source.id = %new_slot.spec.id, carried, invalidated, "tiles carried over");
            tiles_invalidated += invalidated;
        }
        let dirty = dirt
            .iter()
            .zip(&new.slots)
            .filter(|(d, _)| !d.is_none())
            .map(|(d, s)| DirtyRegion {
                source_id: s.spec.id.clone(),
                extents: d.extents(&new.grid),
            })
            .collect();
        let generation = new.generation;
        *self.current.write().expect("scene lock is never poisoned") = Arc::new(new);
        let elapsed_ms = started.elapsed().as_secs_f64() * 1e3;
        tracing::info!(generation, changed = ?changed_sources, tiles_invalidated, elapsed_ms, "{reason}: new generation");
        for kind in error_events {
            let _no_subscribers = self.events.send(SceneEvent { generation, kind });
        }
        let _no_subscribers = self.events.send(SceneEvent {
            generation,
            kind: EventKind::Generation {
                changed_sources,
                dirty,
                tiles_invalidated,
                tiles_rebuilt: 0,
                elapsed_ms,
                reason: reason.to_owned(),
            },
        });
        self.generation.send_replace(generation);
        generation
    }
}
