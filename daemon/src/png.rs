//! PNG encoding of RGBA images (frames and colour tiles).

use image::ImageEncoder;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};

/// Encodes `rgba` (width x height, 8 bits a channel) as PNG, with fast
/// compression: frames are encoded on every change, and a few percent of
/// size costs less than the milliseconds of a tighter deflate.
pub fn encode(rgba: &[u8], width: u32, height: u32) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    PngEncoder::new_with_quality(std::io::Cursor::new(&mut out), CompressionType::Fast, FilterType::Adaptive)
        .write_image(rgba, width, height, image::ExtendedColorType::Rgba8)
        .map_err(|e| format!("cannot encode PNG: {e}"))?;
    Ok(out)
}
