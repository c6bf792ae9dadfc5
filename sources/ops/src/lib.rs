//! relief-source-ops: derived sources, computed from other sources' tiles.
//!
//! Ops read no data files: their inputs arrive as tiles through
//! `GenerateContext::inputs`, so they depend on `relief-source` (and
//! `relief-models`, to check the glTF models `scatter` and `instances`
//! place) only.

mod extrude;
mod hillshade;
mod instances;
mod models;
mod overlay;
mod placement;
mod rasterize;
mod scatter;
mod window;

pub use extrude::{EXTRUDE_INPUTS, EXTRUDE_KIND, Extrude};
pub use hillshade::{HILLSHADE_INPUTS, HILLSHADE_KIND, Hillshade};
pub use instances::{INSTANCES_INPUTS, INSTANCES_KIND, Instances};
pub use overlay::{OVERLAY_INPUTS, OVERLAY_KIND, Overlay};
pub use rasterize::{RASTERIZE_INPUTS, RASTERIZE_KIND, Rasterize, Style, Width, render};
pub use relief_source::colors::parse_color;
pub use scatter::{SCATTER_INPUTS, SCATTER_KIND, Scatter, default_level as scatter_default_level, scatter_input_kinds};
pub use window::HeightWindow;
