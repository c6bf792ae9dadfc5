/// Why a standard tile cannot be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StandardTileError {
    #[error("cannot mesh height tile: {samples} samples is not (2^k+1)^2 with k >= 1")]
    NotPowerOfTwoPlusOne { samples: usize },
    #[error("cannot mesh height tile: {samples} samples, but size {size} needs {expected}")]
    WrongSampleCount { size: usize, samples: usize, expected: usize },
    #[error("cannot encode quantized-mesh: the format is EPSG:4326 or EPSG:3857 only, and the scene's grid is {crs}")]
    NotGeodetic { crs: String },
    #[error("cannot encode quantized-mesh: tile {key} is not in the grid")]
    KeyOutsideGrid { key: relief_source::TileKey },
    #[error("cannot encode quantized-mesh: the mesh has no triangles")]
    EmptyMesh,
    #[error("cannot encode quantized-mesh: a water mask has {cells} cells, not 256 x 256")]
    WaterMaskSize { cells: usize },
    #[error("cannot write glTF: {reason}")]
    BadMesh { reason: String },
    #[error("cannot write glTF: instance of feature {feature_id}: {reason}")]
    BadInstance { feature_id: u64, reason: String },
    #[error("cannot write glTF: model '{model}': {reason}")]
    BadModel { model: String, reason: String },
    #[error("cannot write glTF: {what} is {size} bytes, past the 4 GiB a GLB can hold")]
    TooLarge { what: &'static str, size: u64 },
    #[error("cannot encode png tile: {pixels} pixels, but a 256 x 256 tile has {expected}")]
    WrongPixelCount { pixels: usize, expected: usize },
    #[error("cannot encode png tile")]
    Png(#[source] image::ImageError),
}
