//! The scene calls: state, events, generations and reloads. Transports
//! (gRPC, HTTP) are thin adapters over these.

use std::sync::Arc;
use std::time::Duration;

use relief_proto::v1::{
    ReloadRequest, SceneEvent, SceneState, SetSourceParameterRequest, WaitForGenerationRequest, WatchRequest,
    scene_event,
};
use tokio::sync::broadcast::error::RecvError;
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use tokio_util::sync::CancellationToken;
use tonic::Status;

use crate::frames::FrameHub;
use crate::scene::Scene;
use crate::service::auth::Scope;
use crate::service::convert;
use crate::service::metrics::StreamGauge;
use crate::standard::StandardTiles;

/// The longest a WaitForGeneration call may wait.
const MAX_WAIT: Duration = Duration::from_secs(600);

pub struct SceneCalls {
    scene: Arc<Scene>,
    hub: Arc<FrameHub>,
    standard: Arc<StandardTiles>,
    shutdown: CancellationToken,
    reloads: Reloads,
}

/// Reloads one at a time, and coalesced: a call that waited while another
/// reload of the same sources started and finished takes that one's
/// outcome, so a flood of calls costs a few reads, never a thread each.
#[derive(Default)]
struct Reloads {
    /// Held while a reload runs (waiting holds no thread).
    running: tokio::sync::Mutex<()>,
    /// Reloads started, and the sources of the last one (none: all).
    started: std::sync::atomic::AtomicU64,
    last: std::sync::Mutex<Vec<String>>,
}

impl SceneCalls {
    pub fn new(
        scene: Arc<Scene>,
        hub: Arc<FrameHub>,
        standard: Arc<StandardTiles>,
        shutdown: CancellationToken,
    ) -> Self {
        Self { scene, hub, standard, shutdown, reloads: Reloads::default() }
    }

    pub fn state(&self) -> SceneState {
        convert::scene_state(&self.scene, &self.hub, &self.standard)
    }

    /// The current state, then one event per change after `from_generation`.
    pub fn watch(&self, request: WatchRequest) -> ReceiverStream<Result<SceneEvent, Status>> {
        let from = request.from_generation;
        // Subscribe before taking the snapshot, so no event falls between.
        let mut events = self.scene.events();
        let (tx, rx) = mpsc::channel(16);
        let (scene, hub, standard) = (Arc::clone(&self.scene), Arc::clone(&self.hub), Arc::clone(&self.standard));
        let shutdown = self.shutdown.clone();
        tokio::spawn(async move {
            let _open = StreamGauge::open("events");
            let snapshot = |scene: &Scene| {
                let state = convert::scene_state(scene, &hub, &standard);
                SceneEvent { generation: state.generation, event: Some(scene_event::Event::Snapshot(state)) }
            };
            let first = snapshot(&scene);
            // A generation ahead of this scene's came from another replica
            // (behind a load balancer, each counts its own): the snapshot
            // is where the viewer stands now, and every later event follows.
            let from = from.min(first.generation);
            if tx.send(Ok(first)).await.is_err() {
                return;
            }
            loop {
                let event = tokio::select! {
                    () = shutdown.cancelled() => return,
                    e = events.recv() => e,
                };
                let message = match event {
                    Ok(e) if e.generation > from => convert::scene_event(e),
                    Ok(_) => continue,
                    // Too slow to keep up: start again from a fresh snapshot.
                    Err(RecvError::Lagged(_)) => snapshot(&scene),
                    Err(RecvError::Closed) => return,
                };
                if tx.send(Ok(message)).await.is_err() {
                    return;
                }
            }
        });
        ReceiverStream::new(rx)
    }

    pub async fn wait_for_generation(&self, r: WaitForGenerationRequest) -> Result<SceneState, Status> {
        let timeout = Duration::from_millis(u64::from(r.timeout_ms)).min(MAX_WAIT);
        let mut generations = self.scene.generations();
        let reached = tokio::time::timeout(timeout, generations.wait_for(|g| *g >= r.min_generation))
            .await
            .map(|r| r.map(|_| ()));
        match reached {
            Ok(Ok(())) => Ok(self.state()),
            Ok(Err(_)) => Err(Status::unavailable("the scene is shutting down")),
            Err(_) => Err(Status::deadline_exceeded(format!(
                "generation {} not reached within {} ms (current: {})",
                r.min_generation,
                timeout.as_millis(),
                *generations.borrow()
            ))),
        }
    }

    /// Sets a parameter as the manifest would (engine's `set_parameter`);
    /// the state after the new generation.
    pub async fn set_source_parameter(&self, scope: Scope, r: SetSourceParameterRequest) -> Result<SceneState, Status> {
        scope.require_control("set a source parameter")?;
        let target = r.source_id.trim().to_owned();
        if !target.starts_with('[') && self.scene.snapshot().index_of(&target).is_none() {
            return Err(Status::not_found(format!("no source has id '{}'", relief_source::echo::echoed(&target))));
        }
        let scene = Arc::clone(&self.scene);
        let value = (!r.reset).then_some(r.value);
        let set = tokio::task::spawn_blocking(move || scene.set_parameter(&target, &r.name, value.as_deref()))
            .await
            .map_err(|_| Status::internal("the parameter task failed"))?;
        set.map_err(|e| Status::invalid_argument(format!("parameter refused: {e}")))?;
        Ok(self.state())
    }

    /// Reads again, at once, the sources of the objects an S3 event notice
    /// names (objects the scene does not read are ignored): the webhook
    /// S3, MinIO and others call when an object is written or removed.
    pub async fn notify_objects(&self, scope: Scope, objects: Vec<std::path::PathBuf>) -> Result<SceneState, Status> {
        scope.require_control("reload objects")?;
        let scene = Arc::clone(&self.scene);
        tokio::task::spawn_blocking(move || {
            let ids: Vec<String> = relief_engine::watcher::noticed(&scene, &objects).into_iter().collect();
            if !ids.is_empty() {
                scene.refresh(Some(&ids), "objects changed (notice)", true);
            }
        })
        .await
        .map_err(|_| Status::internal("reload task failed"))?;
        Ok(self.state())
    }

    pub async fn reload(&self, scope: Scope, r: ReloadRequest) -> Result<SceneState, Status> {
        scope.require_control("reload sources")?;
        let ids = r.source_ids;
        let snap = self.scene.snapshot();
        if let Some(unknown) = ids.iter().find(|id| snap.index_of(id).is_none()) {
            return Err(Status::not_found(format!("no source has id '{}'", relief_source::echo::echoed(unknown))));
        }
        let arrived = self.reloads.started.load(std::sync::atomic::Ordering::Acquire);
        let _turn = self.reloads.running.lock().await;
        // One of the same sources started after this call came and is done.
        let covered = self.reloads.started.load(std::sync::atomic::Ordering::Acquire) > arrived
            && *self.reloads.last.lock().unwrap_or_else(std::sync::PoisonError::into_inner) == ids;
        if !covered {
            self.reloads.started.fetch_add(1, std::sync::atomic::Ordering::AcqRel);
            ids.clone_into(&mut self.reloads.last.lock().unwrap_or_else(std::sync::PoisonError::into_inner));
            let only = (!ids.is_empty()).then_some(ids);
            let scene = Arc::clone(&self.scene);
            tokio::task::spawn_blocking(move || scene.refresh(only.as_deref(), "reload requested", true))
                .await
                .map_err(|_| Status::internal("reload task failed"))?;
        }
        Ok(self.state())
    }
}
