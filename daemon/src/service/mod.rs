//! The serving edge: each relief.v1 call implemented once (`scene`,
//! `tiles`, `view`) over the scene, and two thin transports on one port:
//! gRPC (`grpc`) and HTTP/JSON with Server-Sent Events and the browser
//! viewer's page (`http`). prost types stop here; `convert` turns them into
//! relief's own types and back, `status` turns errors into statuses.

pub mod auth;
mod convert;
mod grpc;
mod http;
pub mod metrics;
mod scene;
mod status;
mod tiles;
pub mod tls;
mod view;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use hyper_util::rt::{TokioExecutor, TokioIo};
use hyper_util::server::conn::auto;
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use relief_proto::v1::scene_service_server::SceneServiceServer;
use relief_proto::v1::tile_service_server::TileServiceServer;
use relief_proto::v1::view_service_server::ViewServiceServer;
use tokio::net::{TcpListener, TcpStream};
use tokio_rustls::TlsAcceptor;
use tokio_util::sync::CancellationToken;

use self::auth::Access;

use crate::frames::FrameHub;
use crate::scene::Scene;
use crate::view::Viewer;

/// HTTP/2 flow-control window per stream.
pub const WINDOW_BYTES: u32 = 8 * 1024 * 1024;
/// How long open connections get to finish once reliefd stops.
const DRAIN: Duration = Duration::from_secs(3);
/// How long a client gets to finish its TLS handshake.
const HANDSHAKE: Duration = Duration::from_secs(10);

/// How the port is guarded: who may call (tokens and their scopes), and
/// TLS when the daemon has a certificate.
#[derive(Clone)]
pub struct Guard {
    pub access: Access,
    pub tls: Option<TlsAcceptor>,
}

/// How the command line asks the port to be guarded.
#[derive(Debug, Default, Clone)]
pub struct GuardOptions {
    pub token_file: Option<PathBuf>,
    pub tls_cert: Option<PathBuf>,
    pub tls_key: Option<PathBuf>,
    /// Serve a non-loopback address without a token or TLS anyway.
    pub insecure: bool,
}

impl Guard {
    /// No tokens and no TLS: for loopback, where only this machine's users reach.
    pub fn open() -> Self {
        Self { access: Access::Open, tls: None }
    }

    /// The guard for serving `listen`: tokens and TLS as asked. An address
    /// other machines can reach needs both, unless `insecure` says to serve
    /// it open (with a warning).
    pub fn for_listen(listen: SocketAddr, options: &GuardOptions) -> anyhow::Result<Self> {
        let tls = match (&options.tls_cert, &options.tls_key) {
            (Some(cert), Some(key)) => Some(tls::acceptor(cert, key)?),
            (None, None) => None,
            _ => anyhow::bail!("--tls-cert and --tls-key go together: give both, or neither"),
        };
        let access = match &options.token_file {
            Some(path) => Access::from_file(path)?,
            None => Access::Open,
        };
        if !listen.ip().is_loopback() {
            let mut missing = Vec::new();
            if matches!(access, Access::Open) {
                missing.push("a token file (--token-file)");
            }
            if tls.is_none() {
                missing.push("TLS (--tls-cert, --tls-key)");
            }
            if !missing.is_empty() {
                let missing = missing.join(" and ");
                anyhow::ensure!(
                    options.insecure,
                    "refusing to serve {listen} without {missing}: anyone who reaches it could read the scene, \
                     move its camera and reload it; give them, or --insecure to serve it open anyway"
                );
                tracing::warn!(%listen, "serving to the network without {missing} (--insecure): anyone who reaches it may read the scene, move its camera and reload it");
            }
        }
        Ok(Self { access, tls })
    }
}

/// Every call, once, for both transports.
pub struct Calls {
    pub scene: scene::SceneCalls,
    pub tiles: tiles::TileCalls,
    pub view: view::ViewCalls,
    /// The scene and frame hub the calls serve, for the metrics page.
    origin: Arc<Scene>,
    hub: Arc<FrameHub>,
}

impl Calls {
    pub fn new(scene: &Arc<Scene>, shutdown: &CancellationToken) -> Arc<Self> {
        let viewer = Viewer::new(scene);
        let hub = FrameHub::start(scene, &viewer, shutdown.clone());
        Arc::new(Self {
            scene: scene::SceneCalls::new(Arc::clone(scene), Arc::clone(&hub), shutdown.clone()),
            tiles: tiles::TileCalls::new(Arc::clone(scene)),
            view: view::ViewCalls::new(Arc::clone(scene), Arc::clone(&hub), shutdown.clone()),
            origin: Arc::clone(scene),
            hub,
        })
    }
}

/// gRPC (relief.v1, health, reflection) and HTTP on one router, every
/// call through the token check.
async fn router(calls: &Arc<Calls>, access: Access) -> anyhow::Result<axum::Router> {
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
    Ok(http::router(Arc::clone(calls), routes.into_axum_router())
        .layer(axum::middleware::from_fn_with_state(access, auth::check)))
}

/// Serves gRPC and HTTP on `listener` until `shutdown` is cancelled: each
/// connection speaks HTTP/1.1 (browsers, curl) or HTTP/2 (gRPC, browsers),
/// inside TLS when `guard` has it.
/// With `metrics`, Prometheus text is served at `/metrics` there too.
pub async fn serve(
    scene: Arc<Scene>,
    listener: TcpListener,
    guard: Guard,
    metrics: Option<TcpListener>,
    shutdown: CancellationToken,
) -> anyhow::Result<()> {
    let calls = Calls::new(&scene, &shutdown);
    if let Some(metrics) = metrics {
        let (calls, shutdown) = (Arc::clone(&calls), shutdown.clone());
        tokio::spawn(async move {
            if let Err(e) = metrics::serve(metrics, calls, shutdown).await {
                tracing::error!("{e:#}");
            }
        });
    }
    let service = TowerToHyperService::new(router(&calls, guard.access).await?);
    let mut builder = auto::Builder::new(TokioExecutor::new());
    // Wide HTTP/2 windows: a height tile (264 kB) goes out in one flight.
    builder.http2().initial_stream_window_size(WINDOW_BYTES).initial_connection_window_size(2 * WINDOW_BYTES);
    let graceful = GracefulShutdown::new();
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
        let (builder, service, watcher, tls) =
            (builder.clone(), service.clone(), graceful.watcher(), guard.tls.clone());
        tokio::spawn(async move {
            let ended = match tls {
                None => {
                    watcher
                        .watch(builder.serve_connection_with_upgrades(TokioIo::new(stream), service).into_owned())
                        .await
                }
                Some(tls) => {
                    let Some(stream) = handshake(&tls, stream, peer).await else { return };
                    watcher
                        .watch(builder.serve_connection_with_upgrades(TokioIo::new(stream), service).into_owned())
                        .await
                }
            };
            if let Err(e) = ended {
                tracing::debug!(%peer, "connection ended: {e}");
            }
        });
    }
    if tokio::time::timeout(DRAIN, graceful.shutdown()).await.is_err() {
        tracing::debug!("connections still open after {DRAIN:?}; closing them");
    }
    Ok(())
}

/// The TLS handshake of a new connection; `None` (logged) when the client
/// speaks plaintext, offers nothing this server accepts, or stalls.
async fn handshake(
    tls: &TlsAcceptor,
    stream: TcpStream,
    peer: std::net::SocketAddr,
) -> Option<tokio_rustls::server::TlsStream<TcpStream>> {
    match tokio::time::timeout(HANDSHAKE, tls.accept(stream)).await {
        Ok(Ok(stream)) => Some(stream),
        Ok(Err(e)) => {
            tracing::info!(%peer, "refused a connection: TLS handshake failed ({e}); plaintext to a TLS port?");
            None
        }
        Err(_) => {
            tracing::info!(%peer, "refused a connection: no TLS handshake within {HANDSHAKE:?}");
            None
        }
    }
}
