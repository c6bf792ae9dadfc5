//! The serving edge: each relief.v1 call implemented once (`scene`,
//! `tiles`, `view`) over the scene, and two thin transports on one port:
//! gRPC (`grpc`) and HTTP/JSON with Server-Sent Events and the browser
//! viewer's page (`http`). prost types stop here; `convert` turns them into
//! relief's own types and back, `status` turns errors into statuses.

pub mod auth;
mod calls;
pub mod connections;
mod convert;
mod grpc;
mod http;
pub mod metrics;
mod scene;
pub mod site;
mod status;
mod tiles;
pub mod tls;
mod view;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use hyper_util::server::conn::auto;
use hyper_util::service::TowerToHyperService;
use relief_proto::v1::scene_service_server::SceneServiceServer;
use relief_proto::v1::tile_service_server::TileServiceServer;
use relief_proto::v1::view_service_server::ViewServiceServer;
use tokio::net::{TcpListener, TcpStream};
use tokio_rustls::TlsAcceptor;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;

use self::auth::Access;
use self::calls::Calls;
pub use self::connections::Limits;
use self::connections::{Activity, Connections, Held, Hold, Secure};

use crate::scene::Scene;

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
    /// The hosts and origins browsers may reach it from.
    pub site: site::Site,
    /// How many connections, and for how long.
    pub limits: Limits,
}

/// How the command line asks the port to be guarded.
#[derive(Debug, Default, Clone)]
pub struct GuardOptions {
    pub token_file: Option<PathBuf>,
    pub tls_cert: Option<PathBuf>,
    pub tls_key: Option<PathBuf>,
    /// Serve a non-loopback address without a token or TLS anyway.
    pub insecure: bool,
    /// Host names served besides the daemon's own address (`--allow-host`).
    pub allow_hosts: Vec<String>,
    /// Origins whose pages may call (`--allow-origin`).
    pub allow_origins: Vec<String>,
    /// Connections at once, in all and from one address (`--max-connections`).
    pub limits: Limits,
}

impl Guard {
    /// No tokens and no TLS: for loopback, where only this machine's users reach.
    pub fn open() -> Self {
        Self { access: Access::Open, tls: None, site: site::Site::default(), limits: Limits::DEFAULT }
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
            let open = matches!(access, Access::Open);
            let mut missing = Vec::new();
            if open {
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
                let what = match (open, tls.is_some()) {
                    (true, true) => {
                        "anyone who reaches it may read the scene, move its camera and reload it; TLS \
                                     only keeps others on the path from reading what it sends"
                    }
                    (false, false) => {
                        "the token file still decides who may read and who may steer, but tokens \
                                       and everything sent travel in clear text: anyone on the path can read them \
                                       and then use a token as its holder would"
                    }
                    _ => {
                        "anyone who reaches it may read the scene, move its camera and reload it, and anyone on \
                          the path can read everything sent"
                    }
                };
                tracing::warn!(%listen, "serving to the network without {missing} (--insecure): {what}");
            }
        }
        // Where no token is asked for, only the daemon's own hosts are
        // served (a rebound name reaches it with no token to stop it).
        let site = site::Site {
            listen: Some(listen),
            check_host: matches!(access, Access::Open),
            hosts: options.allow_hosts.clone(),
            origins: options.allow_origins.clone(),
        };
        anyhow::ensure!(
            options.limits.global > 0 && options.limits.per_address > 0,
            "--max-connections and --max-connections-per-address must be at least 1"
        );
        Ok(Self { access, tls, site, limits: options.limits })
    }
}

/// gRPC (relief.v1, health, reflection) and HTTP on one router, every
/// call through the token check.
async fn router(calls: &Arc<Calls>, access: Access, site: site::Site) -> anyhow::Result<axum::Router> {
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
        .layer(axum::middleware::from_fn_with_state(access, auth::check))
        .layer(axum::middleware::from_fn_with_state(Arc::new(site), site::check))
        .layer(axum::middleware::from_fn_with_state(
            Arc::new(tokio::sync::Semaphore::new(HEALTH_WATCHES)),
            health_watches,
        )))
}

/// gRPC health Watch streams open at once: a health check needs no token,
/// so its streams are capped apart.
const HEALTH_WATCHES: usize = 64;

/// Holds each health Watch stream to one of [`HEALTH_WATCHES`] places;
/// past them, RESOURCE_EXHAUSTED.
async fn health_watches(
    axum::extract::State(open): axum::extract::State<Arc<tokio::sync::Semaphore>>,
    request: axum::extract::Request,
    next: axum::middleware::Next,
) -> axum::response::Response {
    if request.uri().path() != "/grpc.health.v1.Health/Watch" {
        return next.run(request).await;
    }
    let Ok(place) = open.try_acquire_owned() else {
        let status = tonic::Status::resource_exhausted(format!(
            "{HEALTH_WATCHES} health Watch streams are open already; use Check, or close one"
        ));
        return status.into_http::<axum::body::Body>();
    };
    next.run(request).await.map(|body| Held::body(body, place))
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
        let (scene, hub, shutdown) = (Arc::clone(&scene), Arc::clone(&calls.hub), shutdown.clone());
        tokio::spawn(async move {
            if let Err(e) = metrics::serve(metrics, scene, hub, shutdown).await {
                tracing::error!("{e:#}");
            }
        });
    }
    let router = router(&calls, guard.access, guard.site).await?;
    let connections = Connections::new(guard.limits);
    let limits = connections.limits();
    let mut builder = auto::Builder::new(TokioExecutor::new());
    // A request's headers in time (slowloris); HTTP/2 pings that must be
    // answered; wide HTTP/2 windows: a height tile (264 kB) goes out in one
    // flight.
    builder.http1().timer(TokioTimer::new()).header_read_timeout(limits.header_read);
    builder
        .http2()
        .timer(TokioTimer::new())
        .keep_alive_interval(limits.ping)
        .keep_alive_timeout(limits.ping)
        .initial_stream_window_size(WINDOW_BYTES)
        .initial_connection_window_size(2 * WINDOW_BYTES);
    let tasks = TaskTracker::new();
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
        let admitted = match connections.admit(peer.ip()) {
            Ok(a) => a,
            Err(why) => {
                tracing::debug!(%peer, "refused a connection: {why}");
                continue;
            }
        };
        // No Nagle: a reply's frames must not wait for the peer's delayed ACK.
        let _ = stream.set_nodelay(true);
        let (builder, router, tls, shutdown) = (builder.clone(), router.clone(), guard.tls.clone(), shutdown.clone());
        tasks.spawn(async move {
            let hold = Hold::new(Arc::new(admitted));
            let activity = Activity::new();
            let service = tracked(router, Arc::clone(&activity), hold, Secure(tls.is_some()));
            let ended = match tls {
                None => serve_one(&builder, TokioIo::new(stream), service, &activity, limits, &shutdown).await,
                Some(tls) => {
                    let Some(stream) = handshake(&tls, stream, peer).await else { return };
                    serve_one(&builder, TokioIo::new(stream), service, &activity, limits, &shutdown).await
                }
            };
            if let Err(e) = ended {
                tracing::debug!(%peer, "connection ended: {e}");
            }
        });
    }
    tasks.close();
    if tokio::time::timeout(DRAIN, tasks.wait()).await.is_err() {
        tracing::debug!("connections still open after {DRAIN:?}; closing them");
    }
    Ok(())
}

/// The router as one connection's service: each request, and its
/// response's body (a stream's whole life), counted as under way, and
/// holding the connection's place (`hold`) among the connections; each
/// says whether its connection is `secure`.
fn tracked(
    router: axum::Router,
    activity: Arc<Activity>,
    hold: Hold,
    secure: Secure,
) -> TowerToHyperService<
    impl tower::Service<
        hyper::Request<hyper::body::Incoming>,
        Response = axum::response::Response,
        Error = std::convert::Infallible,
        Future = impl Send,
    > + Clone
    + Send,
> {
    TowerToHyperService::new(tower::service_fn(move |mut request: hyper::Request<hyper::body::Incoming>| {
        let (mut router, under_way) = (router.clone(), activity.begin());
        request.extensions_mut().insert(hold.clone());
        request.extensions_mut().insert(secure);
        async move {
            let response = tower::Service::call(&mut router, request).await?;
            Ok(response.map(|body| Held::body(body, under_way)))
        }
    }))
}

/// Serves one connection until it ends: closed (gracefully) when it
/// makes no request in time, stays idle too long, or reliefd stops.
async fn serve_one<I, S>(
    builder: &auto::Builder<TokioExecutor>,
    io: I,
    service: S,
    activity: &Activity,
    limits: Limits,
    shutdown: &CancellationToken,
) -> Result<(), Box<dyn std::error::Error + Send + Sync>>
where
    I: hyper::rt::Read + hyper::rt::Write + Unpin + Send + 'static,
    S: hyper::service::Service<hyper::Request<hyper::body::Incoming>, Response = axum::response::Response>
        + Clone
        + Send
        + 'static,
    S::Future: Send + 'static,
    S::Error: Into<Box<dyn std::error::Error + Send + Sync>>,
{
    let connection = builder.serve_connection_with_upgrades(io, service);
    tokio::pin!(connection);
    let overdue = async {
        loop {
            tokio::time::sleep(Duration::from_millis(500)).await;
            if let Some(why) = activity.overdue(&limits) {
                return why;
            }
        }
    };
    tokio::select! {
        ended = connection.as_mut() => return ended,
        why = overdue => tracing::debug!("closing a connection: {why}"),
        () = shutdown.cancelled() => {}
    }
    connection.as_mut().graceful_shutdown();
    match tokio::time::timeout(DRAIN, connection).await {
        Ok(ended) => ended,
        Err(_) => Ok(()),
    }
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
