//! The gRPC edge: relief.v1 services over the scene. prost types stop
//! here; `convert` turns them into relief's own types and back.

mod convert;
mod scene;
mod status;
mod tiles;
mod view;

use std::sync::Arc;

use relief_proto::v1::scene_service_server::SceneServiceServer;
use relief_proto::v1::tile_service_server::TileServiceServer;
use relief_proto::v1::view_service_server::ViewServiceServer;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

use crate::scene::Scene;

/// HTTP/2 flow-control window per stream.
pub const WINDOW_BYTES: u32 = 8 * 1024 * 1024;

/// Serves every relief.v1 service, gRPC health and reflection on
/// `listener` until `shutdown` is cancelled.
pub async fn serve(scene: Arc<Scene>, listener: TcpListener, shutdown: CancellationToken) -> anyhow::Result<()> {
    let (health, health_service) = tonic_health::server::health_reporter();
    health.set_serving::<SceneServiceServer<scene::SceneApi>>().await;
    health.set_serving::<TileServiceServer<tiles::TileApi>>().await;
    health.set_serving::<ViewServiceServer<view::ViewApi>>().await;
    let reflection = tonic_reflection::server::Builder::configure()
        .register_encoded_file_descriptor_set(relief_proto::FILE_DESCRIPTOR_SET)
        .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
        .build_v1()?;
    // No Nagle: a reply's frames must not wait for the peer's delayed ACK.
    // Wide HTTP/2 windows: a height tile (264 kB) goes out in one flight.
    let incoming = tonic::transport::server::TcpIncoming::from(listener).with_nodelay(Some(true));
    tonic::transport::Server::builder()
        .initial_stream_window_size(WINDOW_BYTES)
        .initial_connection_window_size(2 * WINDOW_BYTES)
        .add_service(health_service)
        .add_service(reflection)
        .add_service(SceneServiceServer::new(scene::SceneApi::new(Arc::clone(&scene), shutdown.clone())))
        .add_service(TileServiceServer::new(tiles::TileApi::new(Arc::clone(&scene))))
        .add_service(ViewServiceServer::new(view::ViewApi::new(
            Arc::clone(&scene),
            crate::view::Viewer::new(&scene),
            shutdown.clone(),
        )))
        .serve_with_incoming_shutdown(incoming, shutdown.cancelled_owned())
        .await?;
    Ok(())
}
