//! SceneService: state, events, generations and reloads.

use std::sync::Arc;
use std::time::Duration;

use relief_proto::v1::{
    GetStateRequest, ReloadRequest, SceneEvent, SceneState, SetSourceParameterRequest, WaitForGenerationRequest,
    WatchRequest, scene_event, scene_service_server::SceneService,
};
use tokio::sync::broadcast::error::RecvError;
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use tokio_util::sync::CancellationToken;
use tonic::{Request, Response, Status};

use crate::scene::Scene;
use crate::service::convert;

/// The longest a WaitForGeneration call may wait.
const MAX_WAIT: Duration = Duration::from_secs(600);

pub struct SceneApi {
    scene: Arc<Scene>,
    shutdown: CancellationToken,
}

impl SceneApi {
    pub fn new(scene: Arc<Scene>, shutdown: CancellationToken) -> Self {
        Self { scene, shutdown }
    }

    fn state(&self) -> SceneState {
        convert::scene_state(&self.scene)
    }
}

#[tonic::async_trait]
impl SceneService for SceneApi {
    async fn get_state(&self, _request: Request<GetStateRequest>) -> Result<Response<SceneState>, Status> {
        Ok(Response::new(self.state()))
    }

    type WatchStream = ReceiverStream<Result<SceneEvent, Status>>;

    async fn watch(&self, request: Request<WatchRequest>) -> Result<Response<Self::WatchStream>, Status> {
        let from = request.into_inner().from_generation;
        // Subscribe before taking the snapshot, so no event falls between.
        let mut events = self.scene.events();
        let (tx, rx) = mpsc::channel(16);
        let scene = Arc::clone(&self.scene);
        let shutdown = self.shutdown.clone();
        tokio::spawn(async move {
            let snapshot = |scene: &Scene| {
                let state = convert::scene_state(scene);
                SceneEvent { generation: state.generation, event: Some(scene_event::Event::Snapshot(state)) }
            };
            if tx.send(Ok(snapshot(&scene))).await.is_err() {
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
        Ok(Response::new(ReceiverStream::new(rx)))
    }

    async fn wait_for_generation(
        &self,
        request: Request<WaitForGenerationRequest>,
    ) -> Result<Response<SceneState>, Status> {
        let r = request.into_inner();
        let timeout = Duration::from_millis(u64::from(r.timeout_ms)).min(MAX_WAIT);
        let mut generations = self.scene.generations();
        let reached = tokio::time::timeout(timeout, generations.wait_for(|g| *g >= r.min_generation))
            .await
            .map(|r| r.map(|_| ()));
        match reached {
            Ok(Ok(())) => Ok(Response::new(self.state())),
            Ok(Err(_)) => Err(Status::unavailable("the scene is shutting down")),
            Err(_) => Err(Status::deadline_exceeded(format!(
                "generation {} not reached within {} ms (current: {})",
                r.min_generation,
                timeout.as_millis(),
                *generations.borrow()
            ))),
        }
    }

    async fn set_source_parameter(
        &self,
        request: Request<SetSourceParameterRequest>,
    ) -> Result<Response<SceneState>, Status> {
        let r = request.into_inner();
        Err(Status::unimplemented(format!(
            "SetSourceParameter: source '{}' has no runtime parameters in this reliefd",
            r.source_id
        )))
    }

    async fn reload(&self, request: Request<ReloadRequest>) -> Result<Response<SceneState>, Status> {
        let ids = request.into_inner().source_ids;
        let snap = self.scene.snapshot();
        if let Some(unknown) = ids.iter().find(|id| snap.index_of(id).is_none()) {
            return Err(Status::not_found(format!("no source has id '{unknown}'")));
        }
        let scene = Arc::clone(&self.scene);
        tokio::task::spawn_blocking(move || {
            let only = (!ids.is_empty()).then_some(ids);
            scene.refresh(only.as_deref(), "reload requested", true)
        })
        .await
        .map_err(|_| Status::internal("reload task failed"))?;
        Ok(Response::new(self.state()))
    }
}
