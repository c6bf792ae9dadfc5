//! reliefd: the relief scene daemon.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use clap::{Parser, Subcommand};
use relief_daemon::scene::Scene;
use relief_daemon::service::{Guard, GuardOptions, Limits};
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;

#[derive(Parser)]
#[command(
    name = "reliefd",
    version,
    about = "relief scene daemon: watches GIS files, serves tiles and views over gRPC"
)]
struct Args {
    #[command(subcommand)]
    command: Command,
}

/// What `reliefd serve` is told.
#[derive(clap::Args)]
struct Serve {
    /// The scene manifest (TOML).
    manifest: PathBuf,
    /// Address to bind; port 0 picks a free one.
    #[arg(long, default_value = "127.0.0.1:50051")]
    listen: SocketAddr,
    /// Start even if some sources fail to load (they show as failed).
    #[arg(long)]
    keep_going: bool,
    /// Tile worker threads (default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Bearer tokens callers must send, one `read|control TOKEN` per
    /// line (read: state, tiles, renders, frames; control: also the
    /// scene camera, reloads, source parameters).
    #[arg(long)]
    token_file: Option<PathBuf>,
    /// TLS certificate chain (PEM), with --tls-key.
    #[arg(long, requires = "tls_key")]
    tls_cert: Option<PathBuf>,
    /// TLS private key (PEM), with --tls-cert.
    #[arg(long, requires = "tls_cert")]
    tls_key: Option<PathBuf>,
    /// Serve an address other machines reach without tokens or TLS.
    #[arg(long)]
    insecure: bool,
    /// A host name reliefd is reached by besides its address (its page
    /// and HTTP calls answer only their own hosts where no token is
    /// asked for); repeat for more.
    #[arg(long, value_name = "NAME")]
    allow_host: Vec<String>,
    /// An origin (`https://maps.example.org`) whose pages may call
    /// reliefd's HTTP API from a browser; repeat for more.
    #[arg(long, value_name = "ORIGIN")]
    allow_origin: Vec<String>,
    /// Connections open at once, in all (more are closed at once).
    #[arg(long, default_value_t = Limits::DEFAULT.global, value_name = "N")]
    max_connections: usize,
    /// Connections open at once from one address other than loopback.
    #[arg(long, default_value_t = Limits::DEFAULT.per_address, value_name = "N")]
    max_connections_per_address: usize,
    /// Serve Prometheus metrics at http://ADDR/metrics (a loopback
    /// address; port 0 picks a free one).
    #[arg(long)]
    metrics_listen: Option<SocketAddr>,
}

#[derive(Subcommand)]
enum Command {
    /// Serve a scene over gRPC and HTTP (the browser viewer at http://ADDR/).
    Serve(Box<Serve>),
    /// Load a scene, report every problem, and exit.
    Check { manifest: PathBuf },
}

/// A mosaic's members are kept open by the hundred (each file's plan for
/// reading it), on top of sockets and GDAL's handles: the soft limit on
/// open files (often 1024) is raised to the hard one.
fn raise_open_file_limit() {
    use rustix::process::{Resource, Rlimit, getrlimit, setrlimit};
    let limit = getrlimit(Resource::Nofile);
    if let (Some(current), Some(maximum)) = (limit.current, limit.maximum)
        && current < maximum
        && let Err(e) = setrlimit(Resource::Nofile, Rlimit { current: Some(maximum), maximum: Some(maximum) })
    {
        tracing::debug!("the open-file limit stays {current}: {e}");
    }
}

/// glibc's malloc as a server that makes and frees large buffers on many
/// threads wants it: tiles and frames (hundreds of KB each, made and freed
/// at every edit) always mapped and unmapped, not left in per-thread arenas
/// whose mmap threshold rises with each free. Untuned, the soak bench's
/// resident set grew 128 MB in 10 minutes that no cache held; tuned, 17 MB
/// in 4 (jemalloc and mimalloc as the global allocator kept more). glibc
/// reads these settings only when a process starts, so reliefd starts
/// itself again with them, unless its environment already sets any.
fn tune_malloc() {
    const TUNED: [(&str, &str); 3] =
        [("MALLOC_ARENA_MAX", "2"), ("MALLOC_MMAP_THRESHOLD_", "131072"), ("MALLOC_TRIM_THRESHOLD_", "1048576")];
    if TUNED.iter().any(|(name, _)| std::env::var_os(name).is_some()) || std::env::var_os("GLIBC_TUNABLES").is_some() {
        return;
    }
    let Ok(exe) = std::env::current_exe() else { return };
    let error = std::os::unix::process::CommandExt::exec(
        std::process::Command::new(exe).args(std::env::args_os().skip(1)).envs(TUNED),
    );
    // Still here: the exec failed; serve with malloc as it is.
    eprintln!("reliefd: cannot restart with malloc tuned ({error}); going on without");
}

fn main() -> ExitCode {
    tune_malloc();
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()))
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    raise_open_file_limit();
    let args = Args::parse();
    match run(args) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("reliefd: {e:#}");
            ExitCode::from(1)
        }
    }
}

fn threads(asked: Option<usize>) -> usize {
    asked.unwrap_or_else(|| std::thread::available_parallelism().map_or(2, std::num::NonZero::get))
}

/// Loads the scene, printing each error on its own line.
fn load(manifest: &std::path::Path, keep_going: bool, threads: usize) -> Option<Scene> {
    match Scene::load_checked(manifest, keep_going, threads, relief_daemon::picture::check) {
        Ok((scene, warnings)) => {
            for w in warnings {
                tracing::warn!("{w}");
            }
            Some(scene)
        }
        Err(errors) => {
            for e in errors {
                eprintln!("reliefd: {e}");
            }
            None
        }
    }
}

fn run(args: Args) -> anyhow::Result<ExitCode> {
    match args.command {
        Command::Check { manifest } => {
            let Some(scene) = load(&manifest, false, 1) else {
                return Ok(ExitCode::from(2));
            };
            let snap = scene.snapshot();
            #[expect(clippy::print_stdout, reason = "check reports to the terminal")]
            {
                println!("ok: scene '{}' with {} sources", snap.manifest.name, snap.slots.len());
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Serve(asked_for) => {
            let Serve {
                manifest,
                listen,
                keep_going,
                threads: asked,
                token_file,
                tls_cert,
                tls_key,
                insecure,
                metrics_listen,
                allow_host,
                allow_origin,
                max_connections,
                max_connections_per_address,
            } = *asked_for;
            let options = GuardOptions {
                token_file,
                tls_cert,
                tls_key,
                insecure,
                allow_hosts: allow_host,
                allow_origins: allow_origin,
                limits: Limits { global: max_connections, per_address: max_connections_per_address, ..Limits::DEFAULT },
            };
            // Refused before the scene loads: a bind that would be unsafe fails at once.
            let guard = Guard::for_listen(listen, &options)?;
            if let Some(m) = metrics_listen {
                anyhow::ensure!(
                    m.ip().is_loopback(),
                    "--metrics-listen {m}: metrics are served on a loopback address only (they name sources and files)"
                );
            }
            let Some(scene) = load(&manifest, keep_going, threads(asked)) else {
                return Ok(ExitCode::from(2));
            };
            let runtime = tokio::runtime::Builder::new_multi_thread()
                .enable_all()
                .thread_name("relief-rt")
                .build()
                .context("cannot start the async runtime")?;
            let served = runtime.block_on(serve(Arc::new(scene), listen, guard, metrics_listen));
            // A blocking task still stuck (a read that never returns) must
            // not keep the process: the runtime waits at most a second.
            runtime.shutdown_timeout(Duration::from_secs(1));
            served?;
            Ok(ExitCode::SUCCESS)
        }
    }
}

async fn serve(
    scene: Arc<Scene>,
    listen: SocketAddr,
    guard: Guard,
    metrics_listen: Option<SocketAddr>,
) -> anyhow::Result<()> {
    let scheme = if guard.tls.is_some() { "https" } else { "http" };
    let listener = tokio::net::TcpListener::bind(listen).await.with_context(|| format!("cannot listen on {listen}"))?;
    let addr = listener.local_addr().context("cannot read the bound address")?;
    let metrics = match metrics_listen {
        Some(m) => {
            let l =
                tokio::net::TcpListener::bind(m).await.with_context(|| format!("cannot listen on {m} for metrics"))?;
            Some(l)
        }
        None => None,
    };
    let metrics_addr = metrics.as_ref().map(tokio::net::TcpListener::local_addr).transpose()?;
    let shutdown = CancellationToken::new();
    let tasks = TaskTracker::new();
    let settings = scene.snapshot().manifest.watch;
    let watch = relief_daemon::watcher::FileWatch::start(Arc::clone(&scene), settings)
        .context("cannot watch the scene's files")?;
    let watch_shutdown = shutdown.clone();
    tasks.spawn(async move {
        if let Err(e) = watch.run(watch_shutdown).await {
            tracing::error!("file watching stopped: {e:#}; use `relief reload` to pick up changes");
        }
    });
    let server =
        tasks.spawn(relief_daemon::service::serve(Arc::clone(&scene), listener, guard, metrics, shutdown.clone()));
    tasks.close();
    #[expect(clippy::print_stdout, reason = "the one line clients and tests read the address from")]
    {
        println!("listening on {addr}");
        println!("viewer: {scheme}://{addr}/");
        if let Some(m) = metrics_addr {
            println!("metrics: http://{m}/metrics");
        }
    }
    use std::io::Write as _;
    let _ = std::io::stdout().flush();
    tracing::info!(%addr, scene = %scene.snapshot().manifest.name, "serving");

    tokio::select! {
        () = shutdown_signal() => tracing::info!("shutting down"),
        result = server => {
            // The server stopped on its own: report why.
            result.context("the server task failed")??;
        }
    }
    shutdown.cancel();
    if tokio::time::timeout(Duration::from_secs(5), tasks.wait()).await.is_err() {
        tracing::warn!("tasks still running after 5 s; exiting anyway");
    }
    Ok(())
}

async fn shutdown_signal() {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        let Ok(mut term) = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) else {
            return ctrl_c.await.unwrap_or(());
        };
        tokio::select! {
            _ = ctrl_c => {}
            _ = term.recv() => {}
        }
    }
    #[cfg(not(unix))]
    let _ = ctrl_c.await;
}
