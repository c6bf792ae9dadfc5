//! reliefd's library: the serving side over the scene engine
//! (`relief-engine`): both transports, auth, TLS and metrics (`service`),
//! the frame hub and views (`frames`), the viewer that draws the scene's
//! tiles with relief-renderer (`view`, `scene_tiles`), cameras, gestures,
//! the sun, the effects' options and the picture a manifest asks for.
//!
//! The engine's modules are re-exported under their names, so that
//! `relief_daemon::scene::Scene` and `crate::scene` read as before.

pub use relief_engine::{graph, manifest, scene, tiles, watcher};

pub mod camera;
pub mod codec;
pub mod effects;
pub mod frames;
pub mod navigate;
pub mod picture;
pub mod scene_tiles;
pub mod service;
pub mod standard;
pub mod sun;
pub mod view;
