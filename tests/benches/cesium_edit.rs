//! An edit reaching a CesiumJS page through relief's standard tiles
//! (issue 40). Prints a table; never asserts a time.
//!
//! The Cesium test's scene (`consumers::hill_and_town`: the analytic hill
//! and an extruded town) served by the real reliefd, the Cesium page of
//! `tests/pages` in headless Chromium (no network but loopback) following
//! `/tiles/changes` with relief-tiles.js. Each edit rewrites a 40 x 40
//! pixel window of the DEM in place through GDAL, as an editor saves it,
//! raising it by 100 m and lowering it back by turns.
//!
//! - edit to new height: from the end of the file's write until
//!   `sampleTerrainMostDetailed` in the page gives the new height at the
//!   window's centre (polled every 10 ms; the page's own work included:
//!   the notice, a new terrain provider from layer.json, the tile);
//! - edit to change notice: from the end of the write until a `changes`
//!   event arrives on `GET /tiles/changes` (read by a plain HTTP client
//!   beside the page).
//!
//! `cargo bench -p relief-tests --bench cesium_edit` (the reliefd beside the
//! bench binary: `cargo build --release --bins` first);
//! RELIEF_BENCH_EDITS (default 10) and RELIEF_BENCH_NOTICES (default 25).

#![expect(clippy::print_stdout, reason = "a bench binary prints its table")]

use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use relief_tests::bench::{env_u64, median};
use relief_tests::consumers::{self, PAGE_TIMEOUT};
use relief_tests::{edit, http};

/// The edited window and its centre.
const EDITED: [f64; 4] = [10.175, 45.225, 10.225, 45.275];
const PROBE: (f64, f64) = (10.2, 45.25);
const STEP_M: f32 = 100.0;
/// A height within this of the edit's is the new one (the mesh's error
/// is 1 m at the deepest level by default; the step is 100 m).
const NEW_HEIGHT_WITHIN_M: f64 = 5.0;
/// Longest an edit may take to show before the bench gives up.
const GIVE_UP: Duration = Duration::from_secs(60);

/// The nearest-rank percentile `p` (0..=100) of `v`.
fn percentile(mut v: Vec<f64>, p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    let rank = ((p / 100.0) * v.len() as f64).ceil() as usize;
    v.get(rank.saturating_sub(1)).copied().unwrap_or(f64::NAN)
}

async fn sample(page: &relief_tests::browser::Browser) -> anyhow::Result<f64> {
    let v = page.eval(&format!("page.sample([[{}, {}]])", PROBE.0, PROBE.1)).await?;
    v[0].as_f64().context("no height")
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let Some(pages) = consumers::pages("the cesium_edit bench") else { return Ok(()) };
    let (edits, notices) = (env_u64("RELIEF_BENCH_EDITS", 10), env_u64("RELIEF_BENCH_NOTICES", 25));
    let dir = tempfile::tempdir()?;
    let (manifest, dem) = consumers::hill_and_town(dir.path())?;
    let daemon = consumers::reliefd(&manifest, &pages)?;
    let relief = daemon.url();
    let page = consumers::open(&pages, "/cesium.html", &relief, (960, 600)).await?;
    page.eval("page.start({terrain: true})").await?;
    page.eval(&format!("page.look({}, {}, 6000, 0, -45)", PROBE.0, PROBE.1 - 0.05)).await?;
    page.wait_for("page.settled()", PAGE_TIMEOUT).await?;

    // The change notices, read beside the page.
    let (tx, notices_rx) = mpsc::sync_channel::<Instant>(256);
    let url = format!("{relief}/tiles/changes");
    std::thread::Builder::new().name("bench-changes".into()).spawn(move || {
        let Ok(mut events) = http::Events::open(&url) else { return };
        while let Ok(Some((name, _))) = events.next_event() {
            if name == "changes" && tx.send(Instant::now()).is_err() {
                break;
            }
        }
    })?;

    let (x, y, w, h) = consumers::window(EDITED);
    // Raised and lowered back by turns; the write's end is the start.
    let mut raised = false;
    let mut edit_once = |dem: &std::path::Path| -> anyhow::Result<(Instant, f32)> {
        let step = if raised { -STEP_M } else { STEP_M };
        raised = !raised;
        edit::rewrite_window(dem, x, y, w, h, |_, _, v| v + step)?;
        Ok((Instant::now(), step))
    };

    let mut to_height = Vec::new();
    for _ in 0..edits {
        let before = sample(&page).await?;
        let (written, step) = edit_once(&dem)?;
        let want = before + f64::from(step);
        loop {
            if (sample(&page).await? - want).abs() <= NEW_HEIGHT_WITHIN_M {
                break;
            }
            if written.elapsed() > GIVE_UP {
                bail!("the page did not show the edit within {GIVE_UP:?}");
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        to_height.push(written.elapsed().as_secs_f64() * 1000.0);
        while notices_rx.try_recv().is_ok() {}
    }

    let mut to_notice = Vec::new();
    for _ in 0..notices {
        while notices_rx.try_recv().is_ok() {}
        let (written, _) = edit_once(&dem)?;
        let arrived = notices_rx.recv_timeout(GIVE_UP).context("no change notice")?;
        to_notice.push(arrived.saturating_duration_since(written).as_secs_f64() * 1000.0);
        // Let the page follow before the next edit.
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let errors = consumers::page_errors(&page).await?;
    drop(page);
    daemon.stop(&[])?;

    println!("cesium_edit: {} (reliefd: {})", relief_tests::machine(), relief_tests::bin("reliefd").display());
    println!("| measure | edits | p50 ms | p95 ms |");
    println!("|---|---:|---:|---:|");
    let row = |name: &str, v: &[f64]| {
        println!("| {name} | {} | {:.0} | {:.0} |", v.len(), median(v.to_vec()), percentile(v.to_vec(), 95.0));
    };
    row("edit to new height in the CesiumJS page", &to_height);
    row("edit to change notice (SSE)", &to_notice);
    if !errors.is_empty() {
        println!("the page reported errors: {errors:?}");
    }
    Ok(())
}
