//! Views that viewers open for themselves (a browser tab each): a camera
//! of their own, or the scene camera followed, and whether the user is
//! dragging. A view no stream has shown for [`IDLE_CLOSE`] is closed.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio::sync::watch;

use super::frame::HubFrame;
use crate::view::{Camera, ViewError};

/// Views open at once.
pub const MAX_OPEN_VIEWS: usize = 256;
/// How long a view lives with no stream showing it and no call touching it.
pub const IDLE_CLOSE: Duration = Duration::from_secs(60);

/// Who opened a view, so only they may steer it: a digest of the token a
/// call showed (never the token itself), or anyone where no tokens are
/// asked for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Holder(u64);

impl Holder {
    /// Every caller of a daemon that asks for no token.
    pub const ANYONE: Self = Self(0);

    pub fn of(token: &str) -> Self {
        Self(xxhash_rust::xxh3::xxh3_64(token.as_bytes()) | 1)
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewSettings {
    /// The view's own camera (kept while it follows the scene camera).
    pub camera: Camera,
    pub follow_scene_camera: bool,
    /// The user is dragging: frames at the interactive scale.
    pub interactive: bool,
}

pub struct OpenView {
    pub id: String,
    /// Who opened it: only they (or a control token) may steer it.
    pub owner: Holder,
    settings: watch::Sender<ViewSettings>,
    /// The last frame a stream showed of this view: what gestures and
    /// picks refer to.
    last_frame: Mutex<Option<Arc<HubFrame>>>,
    touched: Mutex<Instant>,
}

impl OpenView {
    pub fn settings(&self) -> ViewSettings {
        *self.settings.borrow()
    }

    pub fn watch(&self) -> watch::Receiver<ViewSettings> {
        self.settings.subscribe()
    }

    pub fn update(&self, change: impl FnOnce(&mut ViewSettings)) -> ViewSettings {
        self.touch();
        self.settings.send_if_modified(|s| {
            let before = *s;
            change(s);
            *s != before
        });
        self.settings()
    }

    pub fn last_frame(&self) -> Option<Arc<HubFrame>> {
        self.last_frame.lock().expect("never held across a panic").clone()
    }

    pub fn shown(&self, frame: &Arc<HubFrame>) {
        *self.last_frame.lock().expect("never held across a panic") = Some(Arc::clone(frame));
        self.touch();
    }

    fn touch(&self) {
        *self.touched.lock().expect("never held across a panic") = Instant::now();
    }

    fn idle(self: &Arc<Self>) -> bool {
        // Streams hold the view: only the registry does when none runs.
        Arc::strong_count(self) == 1 && self.touched.lock().expect("never held across a panic").elapsed() > IDLE_CLOSE
    }
}

#[derive(Default)]
pub struct Views {
    open: Mutex<HashMap<String, Arc<OpenView>>>,
}

impl Views {
    fn open_views(&self) -> std::sync::MutexGuard<'_, HashMap<String, Arc<OpenView>>> {
        self.open.lock().expect("never held across a panic")
    }

    /// Opens a view for `owner`; closes idle ones first.
    pub fn open(&self, settings: ViewSettings, owner: Holder) -> Result<Arc<OpenView>, ViewError> {
        let mut open = self.open_views();
        open.retain(|_, v| !v.idle());
        if open.len() >= MAX_OPEN_VIEWS {
            return Err(ViewError::TooManyViews(format!("{MAX_OPEN_VIEWS} views are open already")));
        }
        let id = loop {
            let id = format!("{:016x}", rand_u64());
            if !open.contains_key(&id) {
                break id;
            }
        };
        let view = Arc::new(OpenView {
            id: id.clone(),
            owner,
            settings: watch::Sender::new(settings),
            last_frame: Mutex::new(None),
            touched: Mutex::new(Instant::now()),
        });
        open.insert(id, Arc::clone(&view));
        Ok(view)
    }

    /// Closes the views idle for [`IDLE_CLOSE`] (the sweep's, each ten
    /// seconds: not only when another view opens).
    pub fn close_idle(&self) {
        self.open_views().retain(|_, v| !v.idle());
    }

    pub fn get(&self, id: &str) -> Result<Arc<OpenView>, ViewError> {
        let mut open = self.open_views();
        // Idle views go here too, with the frame each holds.
        open.retain(|_, v| !v.idle());
        let view = open.get(id).cloned().ok_or_else(|| ViewError::UnknownView(relief_source::echo::echoed(id)))?;
        drop(open);
        view.touch();
        Ok(view)
    }

    pub fn len(&self) -> usize {
        self.open_views().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// An id no other viewer can guess from its own: the process's random
/// hasher keys, a clock and a counter.
fn rand_u64() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u64(COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed));
    h.write_u128(std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos()));
    h.finish()
}
