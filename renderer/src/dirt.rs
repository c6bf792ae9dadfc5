//! What a scene generation changed, as the renderer reads it: the dirty
//! extents of each layer its caches are made from. Each cache refreshes
//! only where its own layer changed (`Renderer::invalidate`); the buildings
//! and instances are followed by their tiles' contents instead.

use relief_source::Extent;

/// Dirty extents (grid units) by the layer the renderer reads them through.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Dirt {
    /// The height or colour layer: the levels' samples, the base, and the
    /// terrain cast into the shadow maps.
    pub terrain: Vec<Extent>,
    /// The water layer: the coverage round the camera.
    pub water: Vec<Extent>,
    /// What the levels finer than this tile level draw changed everywhere
    /// (the detail effect's noise, fitted again): those levels are read
    /// again whole, the coarser ones keep theirs.
    pub finer_than: Option<u8>,
}

impl Dirt {
    /// The whole of `extent` changed in every layer.
    pub fn everything(extent: Extent) -> Self {
        Self { terrain: vec![extent], water: vec![extent], finer_than: None }
    }

    pub fn is_empty(&self) -> bool {
        self.terrain.is_empty() && self.water.is_empty() && self.finer_than.is_none()
    }

    /// This and `other`.
    pub fn extend(&mut self, other: &Self) {
        self.terrain.extend_from_slice(&other.terrain);
        self.water.extend_from_slice(&other.water);
        self.finer_than = match (self.finer_than, other.finer_than) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
    }
}
