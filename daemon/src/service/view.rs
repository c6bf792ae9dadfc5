//! ViewService: camera and rendered frames. The renderer lands with its own
//! issue; until then every call answers UNIMPLEMENTED.

use relief_proto::v1::{
    Camera, GetCameraRequest, RenderRequest, RenderResponse, SetCameraRequest, StreamFramesRequest,
    view_service_server::ViewService,
};
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status};

pub struct ViewApi;

fn not_yet(call: &str) -> Status {
    Status::unimplemented(format!("{call}: this reliefd has no renderer yet"))
}

#[tonic::async_trait]
impl ViewService for ViewApi {
    async fn set_camera(&self, _request: Request<SetCameraRequest>) -> Result<Response<Camera>, Status> {
        Err(not_yet("SetCamera"))
    }

    async fn get_camera(&self, _request: Request<GetCameraRequest>) -> Result<Response<Camera>, Status> {
        Err(not_yet("GetCamera"))
    }

    async fn render(&self, _request: Request<RenderRequest>) -> Result<Response<RenderResponse>, Status> {
        Err(not_yet("Render"))
    }

    type StreamFramesStream = ReceiverStream<Result<RenderResponse, Status>>;

    async fn stream_frames(
        &self,
        _request: Request<StreamFramesRequest>,
    ) -> Result<Response<Self::StreamFramesStream>, Status> {
        Err(not_yet("StreamFrames"))
    }
}
