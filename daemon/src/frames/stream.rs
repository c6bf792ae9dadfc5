//! One viewer's stream of frames: it follows its camera (the scene's, a
//! fixed one, or an open view's) through the hub's distinct views, and
//! sends the newest frame when the viewer has taken the last one, at most
//! `max_fps`.

use std::sync::{Arc, Weak};
use std::time::{Duration, Instant};

use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use super::frame::{FrameFormat, HubFrame, Published, ViewKey};
use super::hub::{FrameHub, Subscription};
use super::views::{OpenView, ViewSettings};
use crate::view::{Camera, Overrides, ViewError};

/// Whose camera a stream shows.
#[derive(Clone)]
pub enum CameraSource {
    /// The scene camera, as SetCamera moves it.
    Scene,
    Fixed(Camera),
    View(Arc<OpenView>),
}

#[derive(Clone)]
pub struct StreamSpec {
    pub source: CameraSource,
    pub width: u32,
    pub height: u32,
    pub overrides: Overrides,
    pub max_fps: f64,
    /// How frames travel (each encoded before sending, off the async
    /// threads).
    pub format: FrameFormat,
    /// The fraction of each side while a view is interactive.
    pub interactive_scale: f64,
}

/// What a stream yields: a frame, or why the view cannot be rendered.
pub type FrameStream = mpsc::Receiver<Result<Arc<HubFrame>, Arc<ViewError>>>;

/// The cameras a stream listens to.
struct Cameras {
    scene: watch::Receiver<Camera>,
    view: Option<(Arc<OpenView>, watch::Receiver<ViewSettings>)>,
    fixed: Option<Camera>,
}

impl Cameras {
    fn new(hub: &FrameHub, source: &CameraSource) -> Self {
        let scene = hub.viewer().cameras();
        match source {
            CameraSource::Scene => Self { scene, view: None, fixed: None },
            CameraSource::Fixed(c) => Self { scene, view: None, fixed: Some(*c) },
            CameraSource::View(v) => Self { scene, view: Some((Arc::clone(v), v.watch())), fixed: None },
        }
    }

    /// The camera to show now, and whether the user is dragging.
    fn current(&mut self) -> (Camera, bool) {
        let scene = *self.scene.borrow_and_update();
        if let Some(c) = self.fixed {
            return (c, false);
        }
        match &mut self.view {
            Some((_, settings)) => {
                let s = *settings.borrow_and_update();
                (if s.follow_scene_camera { scene } else { s.camera }, s.interactive)
            }
            None => (scene, false),
        }
    }

    /// Waits for a change of either camera; false when one is gone.
    async fn changed(&mut self) -> bool {
        match &mut self.view {
            Some((_, settings)) => tokio::select! {
                r = self.scene.changed() => r.is_ok(),
                r = settings.changed() => r.is_ok(),
            },
            None if self.fixed.is_some() => std::future::pending().await,
            None => self.scene.changed().await.is_ok(),
        }
    }
}

impl StreamSpec {
    fn key(&self, (camera, interactive): (Camera, bool)) -> ViewKey {
        let scale = if interactive { self.interactive_scale } else { 1.0 };
        let side = |v: u32| ((f64::from(v) * scale).round() as u32).max(1);
        ViewKey { camera, width: side(self.width), height: side(self.height), overrides: self.overrides, interactive }
    }
}

/// Starts a stream. A stream that would add a distinct view past the hub's
/// limits is refused here; once running it follows its camera wherever it
/// goes, and ends when the receiver is dropped or at `shutdown`.
pub fn start(hub: &Arc<FrameHub>, spec: StreamSpec, shutdown: CancellationToken) -> Result<FrameStream, ViewError> {
    let mut cameras = Cameras::new(hub, &spec.source);
    let subscription = hub.subscribe(spec.key(cameras.current()), None)?;
    let (tx, rx) = mpsc::channel(1);
    tokio::spawn(run(Arc::clone(hub), spec, cameras, subscription, tx, shutdown));
    Ok(rx)
}

/// The newest thing a subscription holds: its view's frame, or why it failed.
fn newest(sub: &mut Subscription) -> Published {
    sub.frames.borrow_and_update().clone()
}

/// Waits for a new frame of `previous`, forever when there is none.
async fn previous_changed(previous: &mut Option<Subscription>) -> bool {
    match previous {
        Some(p) => p.frames.changed().await.is_ok(),
        None => std::future::pending().await,
    }
}

/// Moves the stream to the view of its camera now, within the hub's limits
/// (a camera change that would add a distinct view past them ends the
/// stream with the reason). The view left is kept while it waits for its
/// first frame: the one being drawn, else the oldest waiting (it is next
/// in turn).
fn follow(
    hub: &FrameHub,
    spec: &StreamSpec,
    cameras: &mut Cameras,
    sub: &mut Subscription,
    previous: &mut Option<Subscription>,
) -> Result<(), ViewError> {
    let key = spec.key(cameras.current());
    if key == *sub.key() {
        return Ok(());
    }
    let keep =
        sub.is_waiting() && (sub.is_drawing() || previous.as_ref().is_none_or(|p| !p.is_drawing() && !p.is_waiting()));
    // The view left counts against the limits only while it is kept.
    let joined = hub.subscribe(key, (!keep).then_some(&*sub))?;
    let left = std::mem::replace(sub, joined);
    if keep {
        *previous = Some(left);
    }
    Ok(())
}

/// Sends the newest frame whenever the viewer has room, following the
/// camera. A camera that moves faster than frames render would leave every
/// view it passes through before its frame is ready: the stream keeps the
/// oldest view still waiting for its frame (`previous`) until the current
/// one has one, so frames keep coming (each of a recent camera) however fast
/// the camera moves.
async fn run(
    hub: Arc<FrameHub>,
    spec: StreamSpec,
    mut cameras: Cameras,
    mut sub: Subscription,
    tx: mpsc::Sender<Result<Arc<HubFrame>, Arc<ViewError>>>,
    shutdown: CancellationToken,
) {
    // The calls check max_fps; a rate no Duration holds still never panics.
    let interval = Duration::try_from_secs_f64(1.0 / spec.max_fps).unwrap_or(Duration::from_secs(60));
    let mut last_sent: Option<(Weak<HubFrame>, Instant)> = None;
    let mut previous: Option<Subscription> = None;
    let is_new = |frame: &Arc<HubFrame>, last: &Option<(Weak<HubFrame>, Instant)>| {
        last.as_ref().is_none_or(|(w, _)| !std::ptr::eq(w.as_ptr(), Arc::as_ptr(frame)))
    };
    loop {
        let candidate = match newest(&mut sub) {
            Some(current) => Some(current),
            None => previous.as_mut().and_then(newest),
        };
        let unsent = match candidate {
            Some(Ok(frame)) => is_new(&frame, &last_sent),
            Some(Err(e)) => {
                let _ = tx.send(Err(e)).await;
                return;
            }
            None => false,
        };
        if unsent {
            // Room first (following the camera while the viewer is slow),
            // then the rate limit, then the newest frame.
            let permit = tokio::select! {
                p = tx.reserve() => match p { Ok(p) => p, Err(_) => return },
                alive = cameras.changed() => {
                    if !alive {
                        return;
                    }
                    if let Err(e) = follow(&hub, &spec, &mut cameras, &mut sub, &mut previous) {
                        let _ = tx.send(Err(Arc::new(e))).await;
                        return;
                    }
                    continue;
                }
                () = shutdown.cancelled() => return,
            };
            if let Some((_, at)) = &last_sent {
                let wait = interval.saturating_sub(at.elapsed());
                tokio::select! {
                    () = tokio::time::sleep(wait) => {}
                    () = shutdown.cancelled() => return,
                }
            }
            // Either way the view left has done its part.
            let left = previous.take().as_mut().and_then(newest);
            let ((Some(Ok(frame)), _) | (_, Some(Ok(frame)))) = (newest(&mut sub), left) else { continue };
            if let Some(codec) = spec.format.codec(frame.interactive)
                && !frame.is_encoded(codec)
            {
                let job = Arc::clone(&frame);
                // An encoding error shows when the transport asks for it.
                let _ = tokio::task::spawn_blocking(move || job.encoded(codec)).await;
            }
            if let CameraSource::View(view) = &spec.source {
                view.shown(&frame);
            }
            last_sent = Some((Arc::downgrade(&frame), Instant::now()));
            permit.send(Ok(frame));
            continue;
        }
        tokio::select! {
            r = sub.frames.changed() => if r.is_err() { return },
            alive = previous_changed(&mut previous) => if !alive { previous = None },
            alive = cameras.changed() => {
                if !alive {
                    return;
                }
                if let Err(e) = follow(&hub, &spec, &mut cameras, &mut sub, &mut previous) {
                    let _ = tx.send(Err(Arc::new(e))).await;
                    return;
                }
            }
            () = tx.closed() => return,
            () = shutdown.cancelled() => return,
        }
    }
}
