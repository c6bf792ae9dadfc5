//! Every call, implemented once (`scene.rs`, `tiles.rs`, `view.rs`), as
//! both transports hand them on.

use std::sync::Arc;

use tokio_util::sync::CancellationToken;

use super::{scene, tiles, view};
use crate::frames::FrameHub;
use crate::scene::Scene;
use crate::standard::StandardTiles;
use crate::view::Viewer;

/// Every call, once, for both transports.
pub struct Calls {
    pub scene: scene::SceneCalls,
    pub tiles: tiles::TileCalls,
    pub view: view::ViewCalls,
    /// The frame hub the calls share, for the metrics page.
    pub hub: Arc<FrameHub>,
    /// The scene in standard tile formats (`/tiles/`).
    pub standard: Arc<StandardTiles>,
}

impl Calls {
    pub fn new(scene: &Arc<Scene>, shutdown: &CancellationToken) -> Arc<Self> {
        let viewer = Viewer::new(scene);
        let hub = FrameHub::start(scene, &viewer, shutdown.clone());
        let standard = StandardTiles::new(scene, shutdown.clone());
        Arc::new(Self {
            scene: scene::SceneCalls::new(Arc::clone(scene), Arc::clone(&hub), Arc::clone(&standard), shutdown.clone()),
            tiles: tiles::TileCalls::new(Arc::clone(scene)),
            view: view::ViewCalls::new(Arc::clone(scene), Arc::clone(&hub), shutdown.clone()),
            hub,
            standard,
        })
    }
}
