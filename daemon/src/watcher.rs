//! Notices changed source files and refreshes the scene.
//!
//! For now this polls file fingerprints (size and modification time) every
//! `[watch] poll_ms`; a source only re-reads what changed, and a file that
//! fails to read keeps its last good version.

use std::sync::Arc;
use std::time::Duration;

use tokio_util::sync::CancellationToken;

use crate::scene::Scene;

pub async fn poll(scene: Arc<Scene>, shutdown: CancellationToken) {
    let every = Duration::from_millis(scene.snapshot().manifest.poll_ms);
    let mut ticks = tokio::time::interval(every);
    ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            () = shutdown.cancelled() => return,
            _ = ticks.tick() => {}
        }
        let scene = Arc::clone(&scene);
        if tokio::task::spawn_blocking(move || scene.refresh(None, "files changed"))
            .await
            .is_err()
        {
            tracing::error!("the refresh task panicked; stopping the watcher");
            return;
        }
    }
}
