//! relief-models: 3D models for the instances layer.
//!
//! The renderer draws trees and houses as instanced models; this crate turns
//! a glTF 2.0 file (`.glb`, or `.gltf` with its `.bin` buffers beside it or
//! inline as `data:` URIs) into a [`Model`]: plain triangles with normals
//! and per-vertex colours, in metres, with the node transforms of the
//! default scene applied. It also makes the stock models ([`STOCK`]), which
//! are written as `.glb` files and read back through the same loader as a
//! user's files.
//!
//! Colour comes from each material's base colour factor times the `COLOR_0`
//! vertex colours; textures are not read (a textured model draws in its
//! factor's colour, white by default). Skins, morph targets, cameras and
//! lights are ignored: a skinned model is drawn in its bind pose.
//!
//! Every read is bounded: files over [`MAX_FILE_BYTES`] are refused unread,
//! and a model may have at most [`MAX_VERTICES`] vertices and
//! [`MAX_TRIANGLES`] triangles after node instancing. Malformed data gives a
//! [`ModelError`], never a panic.
//!
//! This crate depends on no other relief crate, and on nothing that draws.

mod accessor;
mod color;
mod encode;
mod error;
mod flatten;
mod glb;
mod load;
mod math;
mod model;
mod stock;
mod uri;

pub use error::ModelError;
pub use load::{from_slice, load};
pub use model::{Bounds, Model};
pub use stock::{STOCK, stock, stock_glb, write_stock};

/// The largest model file that is read, in bytes (256 MiB). External `.bin`
/// buffers are held to the same limit each.
pub const MAX_FILE_BYTES: u64 = 256 << 20;

/// The most vertices a model may have, counted after node instancing.
pub const MAX_VERTICES: usize = 1_000_000;

/// The most triangles a model may have, counted after node instancing.
pub const MAX_TRIANGLES: usize = 2_000_000;
