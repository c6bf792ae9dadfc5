//! The hub: distinct views in latest-wins slots, rendered in turn on the
//! one device, within the limits on distinct views and frame memory.

use std::sync::{Arc, Mutex};

use tokio::sync::{Notify, watch};
use tokio_util::sync::CancellationToken;

use super::frame::{HubFrame, Published, ViewKey};
use super::views::Views;
use crate::scene::Scene;
use crate::view::{Rendered, ViewError, Viewer};

/// Distinct views rendered at once.
pub const MAX_VIEWS: usize = 64;
/// Frames held for distinct views, in bytes.
pub const FRAME_MEMORY_BYTES: u64 = 512 * 1024 * 1024;
/// How often idle views and views no stream shows are let go.
const SWEEP: std::time::Duration = std::time::Duration::from_secs(10);

struct Slot {
    key: ViewKey,
    tx: watch::Sender<Published>,
    /// The generation the slot was last rendered (or failed) at.
    done_at: Mutex<Option<u64>>,
    /// The device is drawing it now.
    drawing: std::sync::atomic::AtomicBool,
}

/// Counters for the scene state and the benchmarks.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HubCounters {
    /// Distinct views some stream shows.
    pub views: usize,
    pub streams: usize,
    pub open_views: usize,
    pub frames_rendered: u64,
    /// Frames shown again for a later generation that changed nothing
    /// their view draws, instead of rendered.
    pub frames_carried_over: u64,
}

pub struct FrameHub {
    /// The views viewers opened for themselves.
    pub views: Views,
    scene: Arc<Scene>,
    viewer: Arc<Viewer>,
    /// Distinct views in round-robin order, and the turn's position.
    slots: Mutex<(Vec<Arc<Slot>>, usize)>,
    wake: Notify,
    rendered: std::sync::atomic::AtomicU64,
    carried: std::sync::atomic::AtomicU64,
}

/// A stream's hold on a distinct view: dropping it leaves the view.
pub struct Subscription {
    slot: Arc<Slot>,
    pub frames: watch::Receiver<Published>,
}

impl Subscription {
    pub fn key(&self) -> &ViewKey {
        &self.slot.key
    }

    /// The view has no frame yet.
    pub fn is_waiting(&self) -> bool {
        self.frames.borrow().is_none()
    }

    /// The device is drawing the view now.
    pub fn is_drawing(&self) -> bool {
        self.slot.drawing.load(std::sync::atomic::Ordering::Relaxed)
    }
}

impl FrameHub {
    /// The hub and its scheduler, which runs until `shutdown`.
    pub fn start(scene: &Arc<Scene>, viewer: &Arc<Viewer>, shutdown: CancellationToken) -> Arc<Self> {
        let hub = Arc::new(Self {
            views: Views::default(),
            scene: Arc::clone(scene),
            viewer: Arc::clone(viewer),
            slots: Mutex::new((Vec::new(), 0)),
            wake: Notify::new(),
            rendered: std::sync::atomic::AtomicU64::new(0),
            carried: std::sync::atomic::AtomicU64::new(0),
        });
        tokio::spawn(Arc::clone(&hub).schedule(shutdown.clone()));
        tokio::spawn(Arc::clone(&hub).sweep(shutdown));
        hub
    }

    pub fn viewer(&self) -> &Arc<Viewer> {
        &self.viewer
    }

    fn slots(&self) -> std::sync::MutexGuard<'_, (Vec<Arc<Slot>>, usize)> {
        self.slots.lock().expect("the hub's lock is never held across a panic")
    }

    /// Joins the distinct view `key`, making it when no stream shows it
    /// yet, within the limits: at most [`MAX_VIEWS`] distinct views and
    /// [`FRAME_MEMORY_BYTES`] of their frames. A stream that starts, and one
    /// whose camera moves (`leaving` the view it showed: not counted when it
    /// alone showed it), is refused past them.
    pub fn subscribe(&self, key: ViewKey, leaving: Option<&Subscription>) -> Result<Subscription, ViewError> {
        let mut guard = self.slots();
        let (slots, _) = &mut *guard;
        slots.retain(|s| s.tx.receiver_count() > 0);
        if let Some(slot) = slots.iter().find(|s| s.key == key) {
            return Ok(Subscription { slot: Arc::clone(slot), frames: slot.tx.subscribe() });
        }
        let freed = |s: &Arc<Slot>| leaving.is_some_and(|l| Arc::ptr_eq(&l.slot, s) && s.tx.receiver_count() == 1);
        let counted: Vec<&Arc<Slot>> = slots.iter().filter(|s| !freed(s)).collect();
        let held: u64 = counted.iter().map(|s| s.key.frame_bytes()).sum();
        if counted.len() >= MAX_VIEWS {
            return Err(ViewError::TooManyViews(format!("{MAX_VIEWS} distinct views are shown already")));
        }
        if held + key.frame_bytes() > FRAME_MEMORY_BYTES {
            return Err(ViewError::TooManyViews(format!(
                "their frames would hold more than {} MiB",
                FRAME_MEMORY_BYTES >> 20
            )));
        }
        let (tx, frames) = watch::channel(None);
        let slot = Arc::new(Slot { key, tx, done_at: Mutex::new(None), drawing: false.into() });
        slots.push(Arc::clone(&slot));
        drop(guard);
        self.wake.notify_one();
        Ok(Subscription { slot, frames })
    }

    /// What the frames the slots hold take, bytes (each frame once).
    pub fn held_bytes(&self) -> u64 {
        let guard = self.slots();
        let mut seen: Vec<*const Rendered> = Vec::new();
        let mut total = 0;
        for slot in &guard.0 {
            if let Some(Ok(frame)) = slot.tx.borrow().as_ref() {
                let at = Arc::as_ptr(&frame.rendered);
                if !seen.contains(&at) {
                    seen.push(at);
                    total += frame.held_bytes();
                }
            }
        }
        total
    }

    pub fn counters(&self) -> HubCounters {
        let guard = self.slots();
        HubCounters {
            views: guard.0.iter().filter(|s| s.tx.receiver_count() > 0).count(),
            streams: guard.0.iter().map(|s| s.tx.receiver_count()).sum(),
            open_views: self.views.len(),
            frames_rendered: self.rendered.load(std::sync::atomic::Ordering::Relaxed),
            frames_carried_over: self.carried.load(std::sync::atomic::Ordering::Relaxed),
        }
    }

    /// The next view, after the last one served, that some stream shows
    /// and that is not yet rendered at `generation`.
    fn next_stale(&self, generation: u64) -> Option<Arc<Slot>> {
        let mut guard = self.slots();
        let (slots, turn) = &mut *guard;
        slots.retain(|s| s.tx.receiver_count() > 0);
        let n = slots.len();
        let start = *turn + 1;
        let next = (0..n).map(|i| (start + i) % n).find(|&i| {
            let done = *slots[i].done_at.lock().expect("never held across a panic");
            done.is_none_or(|g| g < generation)
        })?;
        *turn = next;
        Some(Arc::clone(&slots[next]))
    }

    /// Every [`SWEEP`], closes idle views and lets go of views no stream
    /// shows (with the frames they hold), until `shutdown`.
    async fn sweep(self: Arc<Self>, shutdown: CancellationToken) {
        let mut tick = tokio::time::interval(SWEEP);
        loop {
            tokio::select! {
                _ = tick.tick() => {}
                () = shutdown.cancelled() => return,
            }
            self.views.close_idle();
            self.slots().0.retain(|s| s.tx.receiver_count() > 0);
        }
    }

    /// Renders stale views one at a time, in turn, until `shutdown`.
    async fn schedule(self: Arc<Self>, shutdown: CancellationToken) {
        let mut generations = self.scene.generations();
        loop {
            let generation = *generations.borrow_and_update();
            let Some(slot) = self.next_stale(generation) else {
                tokio::select! {
                    () = self.wake.notified() => {}
                    r = generations.changed() => if r.is_err() { return },
                    () = shutdown.cancelled() => return,
                }
                continue;
            };
            // A generation that changed nothing this view draws is shown
            // by its last frame again, not rendered.
            let last = slot.tx.borrow().as_ref().and_then(|p| p.as_ref().ok().cloned());
            let overrides = &slot.key.overrides;
            if let Some(last) =
                last.filter(|f| !self.viewer.draws_differently(f.rendered.generation, &f.rendered.manifest, overrides))
            {
                *slot.done_at.lock().expect("never held across a panic") = Some(generation);
                self.carried.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                slot.tx.send_replace(Some(Ok(Arc::new(last.carried(generation)))));
                continue;
            }
            let (viewer, key) = (Arc::clone(&self.viewer), slot.key);
            slot.drawing.store(true, std::sync::atomic::Ordering::Relaxed);
            let job = tokio::task::spawn_blocking(move || {
                let rendered = viewer.draw(Some(key.camera), key.width, key.height, key.overrides)?;
                Ok::<_, ViewError>(HubFrame::new(rendered, key.interactive))
            });
            let result = tokio::select! {
                r = job => r,
                () = shutdown.cancelled() => return,
            };
            let published = match result {
                Ok(Ok(frame)) => {
                    *slot.done_at.lock().expect("never held across a panic") = Some(frame.generation);
                    self.rendered.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    Ok(Arc::new(frame))
                }
                Ok(Err(e)) => {
                    tracing::warn!(error = %e, "a view could not be rendered");
                    *slot.done_at.lock().expect("never held across a panic") = Some(generation);
                    Err(Arc::new(e))
                }
                Err(e) => {
                    tracing::error!("the render task failed: {e}");
                    *slot.done_at.lock().expect("never held across a panic") = Some(generation);
                    Err(Arc::new(ViewError::NoDevice(format!("the render task failed: {e}"))))
                }
            };
            slot.drawing.store(false, std::sync::atomic::Ordering::Relaxed);
            slot.tx.send_replace(Some(published));
        }
    }
}
