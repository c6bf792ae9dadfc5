//! Prometheus metrics at `/metrics`, on a listener of their own that only
//! this machine reaches. Events are recorded where they happen, through
//! the `metrics` facade (reloads and their tiles in `scene.rs`, render
//! passes in `view.rs`, errors per source, event streams); totals the
//! daemon already keeps (the tile cache, tiles generated per source, frame
//! streams) are read when the page is scraped. Without this listener no
//! recorder is installed and the facade's calls do nothing.

use std::sync::{Arc, OnceLock};
use std::time::Duration;

use axum::Router;
use axum::extract::State;
use axum::http::header;
use axum::response::IntoResponse;
use axum::routing::get;
use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

use crate::frames::FrameHub;
use crate::scene::Scene;

/// Bucket bounds for every `*_seconds` histogram: 1 ms to 30 s.
const SECONDS_BUCKETS: &[f64] = &[0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0];

/// The process's one recorder, installed on first use.
fn handle() -> anyhow::Result<PrometheusHandle> {
    static HANDLE: OnceLock<PrometheusHandle> = OnceLock::new();
    if let Some(h) = HANDLE.get() {
        return Ok(h.clone());
    }
    let recorder = PrometheusBuilder::new()
        .set_buckets_for_metric(Matcher::Suffix("_seconds".into()), SECONDS_BUCKETS)?
        .build_recorder();
    let handle = recorder.handle();
    metrics::set_global_recorder(recorder).map_err(|e| anyhow::anyhow!("cannot install the metrics recorder: {e}"))?;
    describe();
    Ok(HANDLE.get_or_init(|| handle).clone())
}

fn describe() {
    use metrics::{Unit, describe_counter, describe_gauge, describe_histogram};
    describe_histogram!(
        "relief_reload_seconds",
        Unit::Seconds,
        "from a change seen to its generation served, by the changed source's kind"
    );
    describe_counter!("relief_generations_total", "generations published");
    describe_counter!("relief_tiles_rebuilt_total", "cached tiles generated again after a change");
    describe_counter!(
        "relief_tiles_carried_total",
        "cached tiles a change did not touch, carried to the new generation"
    );
    describe_counter!("relief_tiles_cut_off_total", "tiles rebuilt to the same bytes as before (early cutoff)");
    describe_counter!("relief_tile_cache_hits_total", "tile requests answered from the cache");
    describe_counter!("relief_tile_cache_misses_total", "tile requests that generated the tile");
    describe_gauge!("relief_tile_cache_bytes", Unit::Bytes, "bytes held by the tile cache");
    describe_gauge!("relief_tile_cache_tiles", "tiles held by the tile cache");
    describe_gauge!("relief_raster_cache_bytes", Unit::Bytes, "bytes of decoded raster blocks held");
    describe_counter!("relief_tiles_generated_total", "tiles generated, by source");
    describe_histogram!("relief_render_pass_seconds", Unit::Seconds, "time of each render pass per frame, by pass");
    describe_gauge!("relief_streams_active", "open streams, by kind (frames, events)");
    describe_counter!("relief_source_errors_total", "failed reads and loads, by source");
}

/// What a scrape reads from the daemon's own totals.
fn collect(scene: &Scene, hub: &FrameHub) {
    let store = &scene.store;
    let stats = store.counters();
    metrics::counter!("relief_tile_cache_hits_total").absolute(stats.hits);
    metrics::counter!("relief_tile_cache_misses_total").absolute(stats.misses);
    metrics::gauge!("relief_tile_cache_bytes").set(stats.bytes as f64);
    metrics::gauge!("relief_tile_cache_tiles").set(stats.entries as f64);
    metrics::gauge!("relief_raster_cache_bytes").set(relief_source_gdal::cached_bytes() as f64);
    for (source, n) in store.generated() {
        metrics::counter!("relief_tiles_generated_total", "source" => source).absolute(n);
    }
    metrics::gauge!("relief_streams_active", "kind" => "frames").set(hub.counters().streams as f64);
}

async fn page(State((scene, hub)): State<(Arc<Scene>, Arc<FrameHub>)>) -> impl IntoResponse {
    collect(&scene, &hub);
    let text = handle().map_or_else(
        |e| format!("# {e:#}\n"),
        |h| {
            h.run_upkeep();
            h.render()
        },
    );
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text)
}

/// Serves `/metrics` on `listener` until `shutdown`. The address must be
/// loopback: the page names sources and files.
pub async fn serve(
    listener: TcpListener,
    scene: Arc<Scene>,
    hub: Arc<FrameHub>,
    shutdown: CancellationToken,
) -> anyhow::Result<()> {
    handle()?;
    let router = Router::new().route("/metrics", get(page)).with_state((scene, hub));
    axum::serve(listener, router)
        .with_graceful_shutdown(async move { shutdown.cancelled().await })
        .await
        .map_err(|e| anyhow::anyhow!("the metrics listener stopped: {e}"))?;
    // Let a scrape in flight finish.
    tokio::time::sleep(Duration::from_millis(10)).await;
    Ok(())
}

/// Counts an open stream of `kind` until dropped.
pub struct StreamGauge(&'static str);

impl StreamGauge {
    pub fn open(kind: &'static str) -> Self {
        metrics::gauge!("relief_streams_active", "kind" => kind).increment(1.0);
        Self(kind)
    }
}

impl Drop for StreamGauge {
    fn drop(&mut self) {
        metrics::gauge!("relief_streams_active", "kind" => self.0).decrement(1.0);
    }
}
