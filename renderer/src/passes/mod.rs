//! The passes a frame is drawn in, each in its own module, and what they
//! have cost. A renderer builds a pass (pipelines, buffers, textures) only
//! when the scene calls for it; the counters say which were built, how
//! often each ran and what it took.

pub mod atmosphere;
pub mod buildings;
pub mod casting;
pub mod counters;
pub mod fog;
pub mod instances;
pub mod lit;
pub mod overlay;
pub mod pipeline;
#[cfg(test)]
mod shaders;
pub mod shadows;
pub mod terrain;
pub mod water;
