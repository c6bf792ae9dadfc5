//! What can go wrong when a model file is read.

use crate::{MAX_FILE_BYTES, MAX_TRIANGLES, MAX_VERTICES};

/// Why a model could not be loaded. Every message names the file (the path
/// as given, or the name passed to [`from_slice`](crate::from_slice)) and
/// says what is wrong in plain words.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// The file itself could not be read (missing, unreadable).
    #[error("cannot read model file {path}: {source}")]
    Read {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// The file is larger than [`MAX_FILE_BYTES`]; it is refused unread.
    #[error("{path} is {} MiB: model files over {} MiB are not read", bytes >> 20, MAX_FILE_BYTES >> 20)]
    TooLarge { path: String, bytes: u64 },
    /// The bytes are not a glTF 2.0 asset: not JSON, not a GLB container, a
    /// glTF 1.0 file, or JSON that breaks the glTF schema.
    #[error("{path} is not a glTF 2.0 file: {reason}")]
    NotGltf { path: String, reason: String },
    /// The file requires an extension that changes geometry in a way this
    /// loader does not read (mesh compression, for example).
    #[error("{path} requires the glTF extension {extension}, which relief cannot read")]
    UnsupportedExtension { path: String, extension: String },
    /// A buffer's data could not be found or decoded.
    #[error("{path}: buffer {index} refers to '{uri}', which cannot be read: {reason}")]
    Buffer { path: String, index: usize, uri: String, reason: String },
    /// A primitive draws points or lines.
    #[error("{path}: {mesh} primitive {primitive} uses mode {mode}: only triangles are drawn")]
    NotTriangles { path: String, mesh: String, primitive: usize, mode: &'static str },
    /// The file is valid glTF but its default scene draws no triangle.
    #[error("{path} has no triangles")]
    NoTriangles { path: String },
    /// More vertices than [`MAX_VERTICES`], counted after node instancing.
    #[error("{path} has {vertices} vertices: at most {MAX_VERTICES} are drawn")]
    TooManyVertices { path: String, vertices: usize },
    /// More triangles than [`MAX_TRIANGLES`], counted after node instancing.
    #[error("{path} has {triangles} triangles: at most {MAX_TRIANGLES} are drawn")]
    TooManyTriangles { path: String, triangles: usize },
    /// The data contradicts itself: an accessor reaching past its buffer, an
    /// index past the last vertex, a position that is not a finite number.
    #[error("{path}: {message}")]
    Invalid { path: String, message: String },
}

impl ModelError {
    pub(crate) fn invalid(path: &str, message: impl Into<String>) -> Self {
        Self::Invalid { path: path.to_owned(), message: message.into() }
    }

    pub(crate) fn not_gltf(path: &str, reason: impl Into<String>) -> Self {
        Self::NotGltf { path: path.to_owned(), reason: reason.into() }
    }
}
