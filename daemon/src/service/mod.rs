//! The serving edge: each relief.v1 call implemented once (`scene`,
//! `tiles`, `view`) over the scene, and two thin transports on one port:
//! gRPC (`grpc`) and HTTP/JSON with Server-Sent Events and the browser
//! viewer's page (`http`). prost types stop here; `convert` turns them into
//! relief's own types and back, `status` turns errors into statuses.

mod convert;
mod grpc;
mod http;
mod scene;
mod status;
mod tiles;
mod view;

use std::sync::Arc;
use std::time::Duration;

use hyper_util::rt::{TokioExecutor, TokioIo};
use hyper_util::server::conn::auto;
use hyper_util::service::TowerToHyperService;
use relief_proto::v1::scene_service_server::SceneServiceServer;
use relief_proto::v1::tile_service_server::TileServiceServer;
use relief_proto::v1::view_service_server::ViewServiceServer;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

use crate::frames::FrameHub;
use crate::scene::Scene;
use crate::view::Viewer;

/// HTTP/2 flow-control window per stream.
pub const WINDOW_BYTES: u32 = 8 * 1024 * 1024;
/// How long open connections get to finish once reliefd stops.
const DRAIN: Duration = Duration::from_secs(3);

/// Every call, once, for both transports.
pub struct Calls {
    pub scene: scene::SceneCalls,
    pub tiles: tiles::TileCalls,
    pub view: view::ViewCalls,
}

impl Calls {
    pub fn new(scene: &Arc<Scene>, shutdown: &CancellationToken) -> Arc<Self> {
        let viewer = Viewer::new(scene);
        let hub = FrameHub::start(scene, &viewer, shutdown.clone());
        Arc::new(Self {
            scene: scene::SceneCalls::new(Arc::clone(scene), Arc::clone(&hub), shutdown.clone()),
            tiles: tiles::TileCalls::new(Arc::clone(scene)),
            view: view::ViewCalls::new(Arc::clone(scene), hub, shutdown.clone()),
        })
    }
}

/// gRPC (relief.v1, health, reflection) and HTTP on one router.
async fn router(calls: &Arc<Calls>) -> anyhow::Result<axum::Router> {
    let (health, health_service) = tonic_health::server::health_reporter();
    let grpc = grpc::Grpc(Arc::clone(calls));
    health.set_serving::<SceneServiceServer<grpc::Grpc>>().await;
    health.set_serving::<TileServiceServer<grpc::Grpc>>().await;
    health.set_serving::<ViewServiceServer<grpc::Grpc>>().await;
    let reflection = tonic_reflection::server::Builder::configure()
        .register_encoded_file_descriptor_set(relief_proto::FILE_DESCRIPTOR_SET)
        .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
        .build_v1()?;
    let routes = tonic::service::Routes::new(health_service)
        .add_service(reflection)
        .add_service(SceneServiceServer::new(grpc.clone()))
        .add_service(TileServiceServer::new(grpc.clone()))
        .add_service(ViewServiceServer::new(grpc))
        .prepare();
    Ok(http::router(Arc::clone(calls), routes.into_axum_router()))
}

/// Serves gRPC and HTTP on `listener` until `shutdown` is cancelled: each
/// connection speaks HTTP/1.1 (browsers, curl) or HTTP/2 (gRPC, browsers).
pub async fn serve(scene: Arc<Scene>, listener: TcpListener, shutdown: CancellationToken) -> anyhow::Result<()> {
    let calls = Calls::new(&scene, &shutdown);
    let service = TowerToHyperService::new(router(&calls).await?);
    let mut builder = auto::Builder::new(TokioExecutor::new());
    // Wide HTTP/2 windows: a height tile (264 kB) goes out in one flight.
    builder.http2().initial_stream_window_size(WINDOW_BYTES).initial_connection_window_size(2 * WINDOW_BYTES);
    let graceful = hyper_util::server::graceful::GracefulShutdown::new();
    loop {
        let (stream, peer) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(a) => a,
                Err(e) => {
                    // Out of file descriptors, say: wait and go on serving.
                    tracing::warn!("cannot accept a connection: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            () = shutdown.cancelled() => break,
        };
        // No Nagle: a reply's frames must not wait for the peer's delayed ACK.
        let _ = stream.set_nodelay(true);
        let connection = builder.serve_connection_with_upgrades(TokioIo::new(stream), service.clone());
        let connection = graceful.watch(connection.into_owned());
        tokio::spawn(async move {
            if let Err(e) = connection.await {
                tracing::debug!(%peer, "connection ended: {e}");
            }
        });
    }
    if tokio::time::timeout(DRAIN, graceful.shutdown()).await.is_err() {
        tracing::debug!("connections still open after {DRAIN:?}; closing them");
    }
    Ok(())
}
