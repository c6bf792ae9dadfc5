//! ViewService: the camera and rendered frames.

use std::sync::Arc;
use std::time::{Duration, Instant};

use relief_proto::v1::{
    Camera, GetCameraRequest, ImageFormat, PassTiming, QualityOverrides, RenderRequest, RenderResponse,
    SetCameraRequest, StreamFramesRequest, view_service_server::ViewService,
};
use relief_renderer::ClipmapConfig;
use tokio_stream::wrappers::ReceiverStream;
use tokio_util::sync::CancellationToken;
use tonic::{Request, Response, Status};

use crate::scene::Scene;
use crate::service::convert;
use crate::service::status::invalid_field;
use crate::view::{Rendered, ViewError, Viewer};

/// Fastest StreamFrames rate a viewer may ask for.
const MAX_FPS: f64 = 60.0;

pub struct ViewApi {
    scene: Arc<Scene>,
    viewer: Arc<Viewer>,
    /// Ends frame streams when reliefd stops.
    shutdown: CancellationToken,
}

impl ViewApi {
    pub fn new(scene: Arc<Scene>, viewer: Arc<Viewer>, shutdown: CancellationToken) -> Self {
        Self { scene, viewer, shutdown }
    }
}

fn status(e: &ViewError) -> Status {
    match e {
        ViewError::Invalid(e) => Status::invalid_argument(e.to_string()),
        ViewError::Busy => Status::resource_exhausted(e.to_string()),
        ViewError::NoDevice(_) => Status::unavailable(e.to_string()),
    }
}

/// A frame request checked and in relief's own types.
#[derive(Clone, Copy)]
struct FrameRequest {
    camera: Option<crate::view::Camera>,
    width: u32,
    height: u32,
    png: bool,
    clipmap: Option<ClipmapConfig>,
    quality: Option<relief_source::Quality>,
}

fn frame_request(
    scene: &Scene,
    camera: Option<&Camera>,
    (width, height): (u32, u32),
    format: i32,
    overrides: Option<&QualityOverrides>,
) -> Result<FrameRequest, Status> {
    let snap = scene.snapshot();
    let png = match ImageFormat::try_from(format) {
        Ok(ImageFormat::Unspecified | ImageFormat::Png) => true,
        Ok(ImageFormat::Rgba8) => false,
        Err(_) => return Err(invalid_field("format", format!("{format} is not an image format"))),
    };
    let clipmap = overrides.and_then(|o| {
        (o.clipmap_grid_size.is_some() || o.clipmap_levels.is_some()).then(|| ClipmapConfig {
            n: o.clipmap_grid_size.map_or(snap.manifest.clipmap.n, |n| n as usize),
            levels: o.clipmap_levels.map_or(snap.manifest.clipmap.levels, |l| l as usize),
        })
    });
    if let Some(c) = clipmap {
        c.validate().map_err(|e| invalid_field("quality.clipmap_grid_size", e))?;
    }
    let quality = overrides.map(|o| convert::quality(snap.manifest.quality, Some(o))).transpose()?;
    Ok(FrameRequest {
        camera: camera.map(convert::camera_from),
        width: if width == 0 { 1280 } else { width },
        height: if height == 0 { 720 } else { height },
        png,
        clipmap,
        quality,
    })
}

async fn render(viewer: &Arc<Viewer>, r: FrameRequest) -> Result<RenderResponse, Status> {
    let job = Arc::clone(viewer);
    let rendered = tokio::task::spawn_blocking(move || job.render(r.camera, r.width, r.height, r.clipmap, r.quality))
        .await
        .map_err(|e| Status::internal(format!("the render task failed: {e}")))?
        .map_err(|e| status(&e))?;
    response(rendered, r.png)
}

fn response(rendered: Rendered, png: bool) -> Result<RenderResponse, Status> {
    let Rendered { frame, generation, camera } = rendered;
    let started = Instant::now();
    let (format, image) = if png {
        (ImageFormat::Png, convert::png(&frame.rgba, frame.width, frame.height)?)
    } else {
        (ImageFormat::Rgba8, frame.rgba)
    };
    let mut passes: Vec<PassTiming> =
        frame.passes.iter().map(|(pass, ms)| PassTiming { pass: (*pass).into(), elapsed_ms: *ms }).collect();
    if png {
        passes.push(PassTiming { pass: "encode png".into(), elapsed_ms: started.elapsed().as_secs_f64() * 1e3 });
    }
    Ok(RenderResponse {
        generation,
        width: frame.width,
        height: frame.height,
        format: format as i32,
        image,
        passes,
        camera: Some(convert::camera_to(&camera)),
    })
}

#[tonic::async_trait]
impl ViewService for ViewApi {
    async fn set_camera(&self, request: Request<SetCameraRequest>) -> Result<Response<Camera>, Status> {
        let camera = request.into_inner().camera.ok_or_else(|| invalid_field("camera", "missing"))?;
        let set = self.viewer.set_camera(convert::camera_from(&camera)).map_err(|e| status(&e))?;
        Ok(Response::new(convert::camera_to(&set)))
    }

    async fn get_camera(&self, _request: Request<GetCameraRequest>) -> Result<Response<Camera>, Status> {
        Ok(Response::new(convert::camera_to(&self.viewer.camera())))
    }

    async fn render(&self, request: Request<RenderRequest>) -> Result<Response<RenderResponse>, Status> {
        let r = request.into_inner();
        let req = frame_request(&self.scene, r.camera.as_ref(), (r.width, r.height), r.format, r.quality.as_ref())?;
        Ok(Response::new(render(&self.viewer, req).await?))
    }

    type StreamFramesStream = ReceiverStream<Result<RenderResponse, Status>>;

    /// A frame now, then one whenever the generation or the camera changes,
    /// at most `max_fps`. A frame is rendered only once the channel has room
    /// for it, from the state of that moment: a slow viewer gets the latest
    /// state, never a queue of old frames. (What a viewer's own HTTP/2
    /// window holds on top is its choice: a viewer that wants the freshest
    /// frame keeps that window near one frame.)
    async fn stream_frames(
        &self,
        request: Request<StreamFramesRequest>,
    ) -> Result<Response<Self::StreamFramesStream>, Status> {
        let r = request.into_inner();
        let req = frame_request(&self.scene, None, (r.width, r.height), r.format, r.quality.as_ref())?;
        let fps = if r.max_fps == 0.0 { 10.0 } else { r.max_fps };
        if !(fps.is_finite() && fps > 0.0 && fps <= MAX_FPS) {
            return Err(invalid_field("max_fps", format!("{fps} is not more than 0 and at most {MAX_FPS}")));
        }
        let (tx, rx) = tokio::sync::mpsc::channel(1);
        let (viewer, scene, shutdown) = (Arc::clone(&self.viewer), Arc::clone(&self.scene), self.shutdown.clone());
        tokio::spawn(async move {
            let mut generations = scene.generations();
            let mut cameras = viewer.cameras();
            let interval = Duration::from_secs_f64(1.0 / fps);
            loop {
                let permit = tokio::select! {
                    p = tx.reserve() => p,
                    () = shutdown.cancelled() => break,
                };
                let Ok(permit) = permit else { break };
                let started = Instant::now();
                generations.mark_unchanged();
                cameras.mark_unchanged();
                let frame = render(&viewer, req).await;
                let failed = frame.is_err();
                permit.send(frame);
                if failed {
                    break;
                }
                tokio::time::sleep(interval.saturating_sub(started.elapsed())).await;
                let changed = tokio::select! {
                    r = generations.changed() => r.is_ok(),
                    r = cameras.changed() => r.is_ok(),
                    () = tx.closed() => false,
                    () = shutdown.cancelled() => false,
                };
                if !changed {
                    break;
                }
            }
        });
        Ok(Response::new(ReceiverStream::new(rx)))
    }
}
