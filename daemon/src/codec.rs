//! Image encodings of RGBA frames and colour tiles: PNG (lossless, for
//! tiles and frames at rest) and JPEG (lossy, for frames while the camera
//! moves, at `[quality] frame_jpeg_quality`).

use image::ImageEncoder;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};

/// How a frame travels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Codec {
    Png,
    /// Quality 1 to 100.
    Jpeg(u8),
}

impl Codec {
    /// A name for pass timings and tables: "png", "jpeg 80".
    pub fn name(self) -> String {
        match self {
            Self::Png => "png".to_owned(),
            Self::Jpeg(q) => format!("jpeg {q}"),
        }
    }

    /// Encodes `rgba` (width x height, 8 bits a channel).
    pub fn encode(self, rgba: &[u8], width: u32, height: u32) -> Result<Vec<u8>, String> {
        match self {
            Self::Png => png(rgba, width, height),
            Self::Jpeg(quality) => jpeg(rgba, width, height, quality),
        }
    }
}

/// Encodes `rgba` (width x height, 8 bits a channel) as PNG, with fast
/// compression: frames are encoded on every change, and a few percent of
/// size costs less than the milliseconds of a tighter deflate.
pub fn png(rgba: &[u8], width: u32, height: u32) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    PngEncoder::new_with_quality(std::io::Cursor::new(&mut out), CompressionType::Fast, FilterType::Adaptive)
        .write_image(rgba, width, height, image::ExtendedColorType::Rgba8)
        .map_err(|e| format!("cannot encode PNG: {e}"))?;
    Ok(out)
}

/// Encodes `rgba` as a baseline JPEG of `quality` (1 to 100; alpha
/// dropped: frames are opaque), chroma subsampled 4:2:0 as browsers
/// decode fastest.
pub fn jpeg(rgba: &[u8], width: u32, height: u32, quality: u8) -> Result<Vec<u8>, String> {
    let (w, h) = (u16::try_from(width), u16::try_from(height));
    let (Ok(w), Ok(h)) = (w, h) else {
        return Err(format!("cannot encode JPEG: {width} x {height} is larger than 65,535 pixels a side"));
    };
    let mut out = Vec::new();
    let mut encoder = jpeg_encoder::Encoder::new(&mut out, quality.clamp(1, 100));
    encoder.set_sampling_factor(jpeg_encoder::SamplingFactor::R_4_2_0);
    encoder.encode(rgba, w, h, jpeg_encoder::ColorType::Rgba).map_err(|e| format!("cannot encode JPEG: {e}"))?;
    Ok(out)
}
