//! The gRPC transport: each relief.v1 method hands its message to the one
//! implementation of the call and wraps the answer. No logic lives here.

use std::sync::Arc;

use relief_proto::v1 as pb;
use relief_proto::v1::scene_service_server::SceneService;
use relief_proto::v1::tile_service_server::TileService;
use relief_proto::v1::view_service_server::ViewService;
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status};

use super::auth::{Holder, Scope};
use super::calls::Calls;
use super::view::Frames;

/// The calls behind the three relief.v1 services.
#[derive(Clone)]
pub struct Grpc(pub Arc<Calls>);

type Answer<T> = Result<Response<T>, Status>;

/// The scope the token check gave the call (read, when none is there).
fn scope<T>(r: &Request<T>) -> Scope {
    r.extensions().get::<Scope>().copied().unwrap_or(Scope::Read)
}

/// Whose token the call showed (anyone, when none is there).
fn holder<T>(r: &Request<T>) -> Holder {
    r.extensions().get::<Holder>().copied().unwrap_or(Holder::ANYONE)
}

#[tonic::async_trait]
impl SceneService for Grpc {
    async fn get_state(&self, _r: Request<pb::GetStateRequest>) -> Answer<pb::SceneState> {
        Ok(Response::new(self.0.scene.state()))
    }

    type WatchStream = ReceiverStream<Result<pb::SceneEvent, Status>>;

    async fn watch(&self, r: Request<pb::WatchRequest>) -> Answer<Self::WatchStream> {
        Ok(Response::new(self.0.scene.watch(r.into_inner())))
    }

    async fn wait_for_generation(&self, r: Request<pb::WaitForGenerationRequest>) -> Answer<pb::SceneState> {
        self.0.scene.wait_for_generation(r.into_inner()).await.map(Response::new)
    }

    async fn set_source_parameter(&self, r: Request<pb::SetSourceParameterRequest>) -> Answer<pb::SceneState> {
        self.0.scene.set_source_parameter(scope(&r), r.into_inner()).await.map(Response::new)
    }

    async fn reload(&self, r: Request<pb::ReloadRequest>) -> Answer<pb::SceneState> {
        self.0.scene.reload(scope(&r), r.into_inner()).await.map(Response::new)
    }
}

#[tonic::async_trait]
impl TileService for Grpc {
    async fn get_tile(&self, r: Request<pb::GetTileRequest>) -> Answer<pb::GetTileResponse> {
        self.0.tiles.tile(r.into_inner()).await.map(Response::new)
    }

    async fn sample_elevation(&self, r: Request<pb::SampleElevationRequest>) -> Answer<pb::SampleElevationResponse> {
        self.0.tiles.elevation(r.into_inner()).await.map(Response::new)
    }
}

#[tonic::async_trait]
impl ViewService for Grpc {
    async fn set_camera(&self, r: Request<pb::SetCameraRequest>) -> Answer<pb::Camera> {
        self.0.view.set_camera(scope(&r), r.get_ref()).map(Response::new)
    }

    async fn get_camera(&self, _r: Request<pb::GetCameraRequest>) -> Answer<pb::Camera> {
        Ok(Response::new(self.0.view.camera()))
    }

    async fn render(&self, r: Request<pb::RenderRequest>) -> Answer<pb::RenderResponse> {
        self.0.view.render(r.get_ref()).await.map(Response::new)
    }

    type StreamFramesStream = Frames;

    async fn stream_frames(&self, r: Request<pb::StreamFramesRequest>) -> Answer<Self::StreamFramesStream> {
        self.0.view.stream_frames(r.get_ref()).map(Response::new)
    }

    async fn open_view(&self, r: Request<pb::OpenViewRequest>) -> Answer<pb::ViewState> {
        self.0.view.open_view(holder(&r), r.get_ref()).map(Response::new)
    }

    async fn update_view(&self, r: Request<pb::UpdateViewRequest>) -> Answer<pb::ViewState> {
        self.0.view.update_view(scope(&r), holder(&r), r.get_ref()).map(Response::new)
    }

    async fn navigate(&self, r: Request<pb::NavigateRequest>) -> Answer<pb::Camera> {
        let (scope, holder) = (scope(&r), holder(&r));
        self.0.view.navigate(scope, holder, r.into_inner()).await.map(Response::new)
    }

    async fn pick(&self, r: Request<pb::PickRequest>) -> Answer<pb::PickResponse> {
        self.0.view.pick(r.get_ref()).await.map(Response::new)
    }
}
