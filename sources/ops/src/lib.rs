//! relief-source-ops: derived sources, computed from other sources' tiles.
//!
//! Ops never read files: their inputs arrive as tiles through
//! `GenerateContext::inputs`, so they depend on `relief-source` only.

mod colors;
mod extrude;
mod hillshade;
mod instances;
mod overlay;
mod placement;
mod rasterize;
mod window;

pub use extrude::{EXTRUDE_INPUTS, EXTRUDE_KIND, Extrude};
pub use hillshade::{HILLSHADE_INPUTS, HILLSHADE_KIND, Hillshade};
pub use instances::{INSTANCES_INPUTS, INSTANCES_KIND, Instances};
pub use overlay::{OVERLAY_INPUTS, OVERLAY_KIND, Overlay};
pub use rasterize::{RASTERIZE_INPUTS, RASTERIZE_KIND, Rasterize, Style, Width, render};
pub use window::HeightWindow;
