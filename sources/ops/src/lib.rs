//! relief-source-ops: derived sources, computed from other sources' tiles.
//!
//! Ops never read files: their inputs arrive as tiles through
//! `GenerateContext::inputs`, so they depend on `relief-source` only.

mod hillshade;
mod overlay;
mod rasterize;
mod window;

pub use hillshade::{HILLSHADE_INPUTS, HILLSHADE_KIND, Hillshade};
pub use overlay::{OVERLAY_INPUTS, OVERLAY_KIND, Overlay};
pub use rasterize::{RASTERIZE_INPUTS, RASTERIZE_KIND, Rasterize, Style, Width, render};
pub use window::HeightWindow;
