//! relief-source: the contract between relief's daemon and its sources.
//!
//! It owns the tile grids and the sample convention (written once, in
//! [`grid`]), the payload types, dirty regions, the [`Source`] trait that every
//! source crate implements, the named accuracy knobs, and WGS84 geodesy.
//!
//! It must never depend on GDAL, gRPC, the renderer or any source crate:
//! source crates depend on it, not the other way round.

pub mod colors;
mod crs;
mod dirty;
pub mod echo;
mod error;
mod features;
pub mod files;
pub mod geodesy;
mod grid;
pub mod objects;
pub mod patches;
mod payload;
mod quality;
pub mod regular;
mod source;
mod vector;

pub use crs::CrsTransform;
pub use dirty::DirtySet;
pub use error::SourceError;
pub use features::FeatureIndex;
pub use grid::{
    Direction, Extent, GridKind, Lattice, MAX_LEVEL, Neighbour, ProjectedGrid, SampleKind, TileGrid, TileKey,
};
pub use payload::{
    ColorTile, Feature, FeatureTile, Geometry, HeightTile, Instance, InstanceKind, InstanceTile, MaskTile, MeshPart,
    MeshTile, Payload, PayloadKind, Skipped,
};
pub use quality::{Quality, Resampling};
pub use source::{
    ClassCount, GenerateContext, GeodeticPoint, InputTiles, NoInputs, OptionValue, Refresh, Source, SourceInfo,
    SourceSpec,
};
pub use vector::{VectorFormat, VectorRead, VectorSource};
