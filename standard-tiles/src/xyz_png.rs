//! XYZ tiles as PNG: heights in Mapzen's Terrarium encoding (what MapLibre
//! GL JS's `raster-dem` with `encoding: "terrarium"` and deck.gl's
//! `TerrainLayer` decode), and straight RGBA imagery.

use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder};

use crate::StandardTileError;
use crate::xyz::XYZ_TILE_SIZE;

/// The highest Terrarium value, v = h + 32768: all three bytes 255.
const TERRARIUM_MAX: f64 = 65_535.0 + 255.0 / 256.0;

/// Mapzen Terrarium: v = h + 32768; R = floor(v / 256), G = floor(v) mod
/// 256, B = floor(frac(v) * 256), so R * 256 + G + B / 256 - 32768 decodes
/// to within 1/256 m below h. NaN (nodata) is 0 m; heights past
/// -32768..32767.996 m are clamped to it.
pub fn terrarium_rgb(height_m: f32) -> [u8; 3] {
    let h = if height_m.is_nan() { 0.0 } else { f64::from(height_m) };
    // Exact: an f32 plus 32768 fits f64's mantissa, and so does frac * 256.
    let v = (h + 32_768.0).clamp(0.0, TERRARIUM_MAX);
    let whole = v.floor();
    [(whole / 256.0).floor() as u8, (whole % 256.0) as u8, ((v - whole) * 256.0).floor() as u8]
}

fn check_pixels(pixels: usize) -> Result<(), StandardTileError> {
    let expected = XYZ_TILE_SIZE * XYZ_TILE_SIZE;
    if pixels == expected { Ok(()) } else { Err(StandardTileError::WrongPixelCount { pixels, expected }) }
}

fn encode_png(bytes: &[u8], color: ExtendedColorType) -> Result<Vec<u8>, StandardTileError> {
    let mut png = Vec::new();
    let side = XYZ_TILE_SIZE as u32;
    PngEncoder::new(&mut png).write_image(bytes, side, side, color).map_err(StandardTileError::Png)?;
    Ok(png)
}

/// A 256 x 256 RGB PNG of Terrarium-encoded heights (metres, row-major from
/// the north-west, as [`crate::resample_heights`] makes them).
pub fn terrarium_png(heights: &[f32]) -> Result<Vec<u8>, StandardTileError> {
    check_pixels(heights.len())?;
    let rgb: Vec<u8> = heights.iter().flat_map(|&h| terrarium_rgb(h)).collect();
    encode_png(&rgb, ExtendedColorType::Rgb8)
}

/// A 256 x 256 RGBA PNG of straight (not premultiplied) RGBA8 pixels,
/// row-major from the north-west, as [`crate::resample_colors`] makes them.
pub fn rgba_png(rgba: &[[u8; 4]]) -> Result<Vec<u8>, StandardTileError> {
    check_pixels(rgba.len())?;
    encode_png(rgba.as_flattened(), ExtendedColorType::Rgba8)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode_terrarium([r, g, b]: [u8; 3]) -> f64 {
        f64::from(r) * 256.0 + f64::from(g) + f64::from(b) / 256.0 - 32_768.0
    }

    #[test]
    fn terrarium_round_trips_within_a_256th_of_a_metre() {
        // Every 0.37 m from the Mariana Trench to above Everest, plus a
        // spread of fractions.
        let mut h = -11_000.0f64;
        while h <= 9_000.0 {
            for frac in [0.0, 0.001, 0.5, 0.996, 0.999_9] {
                let height = (h + frac) as f32;
                let back = decode_terrarium(terrarium_rgb(height));
                let err = f64::from(height) - back;
                assert!((0.0..1.0 / 256.0).contains(&err), "{height} decoded as {back}");
            }
            h += 0.37;
        }
    }

    #[test]
    fn terrarium_matches_the_published_examples() {
        assert_eq!(terrarium_rgb(0.0), [128, 0, 0]);
        assert_eq!(terrarium_rgb(1.5), [128, 1, 128]);
        assert_eq!(terrarium_rgb(-1.0), [127, 255, 0]);
        assert_eq!(terrarium_rgb(8_848.0), [162, 144, 0]);
    }

    #[test]
    fn terrarium_sends_nodata_to_sea_level_and_clamps_the_rest() {
        assert_eq!(terrarium_rgb(f32::NAN), [128, 0, 0]);
        assert_eq!(terrarium_rgb(-40_000.0), [0, 0, 0]);
        assert_eq!(terrarium_rgb(f32::NEG_INFINITY), [0, 0, 0]);
        assert_eq!(terrarium_rgb(40_000.0), [255, 255, 255]);
        assert_eq!(terrarium_rgb(f32::INFINITY), [255, 255, 255]);
    }

    #[test]
    fn terrarium_pngs_decode_to_the_same_values() {
        let heights: Vec<f32> = (0..256 * 256)
            .map(|i| if i % 1_000 == 7 { f32::NAN } else { (i % 256) as f32 * 37.25 - (i / 256) as f32 * 41.5 })
            .collect();
        let png = terrarium_png(&heights).unwrap();
        let img = image::load_from_memory_with_format(&png, image::ImageFormat::Png).unwrap();
        assert_eq!((img.width(), img.height()), (256, 256));
        assert_eq!(img.color(), image::ColorType::Rgb8);
        let rgb = img.to_rgb8();
        for (i, (px, &h)) in rgb.pixels().zip(&heights).enumerate() {
            assert_eq!(px.0, terrarium_rgb(h), "pixel {i}");
            let back = decode_terrarium(px.0);
            let want = if h.is_nan() { 0.0 } else { f64::from(h) };
            assert!((want - back).abs() < 1.0 / 256.0);
        }
    }

    #[test]
    fn rgba_pngs_decode_to_the_same_values() {
        let rgba: Vec<[u8; 4]> = (0..256 * 256u32)
            .map(|i| [(i % 256) as u8, (i / 256) as u8, (i * 7 % 251) as u8, (i % 13 * 19) as u8])
            .collect();
        let png = rgba_png(&rgba).unwrap();
        let img = image::load_from_memory_with_format(&png, image::ImageFormat::Png).unwrap();
        assert_eq!(img.color(), image::ColorType::Rgba8);
        let back: Vec<[u8; 4]> = img.to_rgba8().pixels().map(|p| p.0).collect();
        assert_eq!(back, rgba);
    }

    #[test]
    fn pngs_of_the_wrong_size_are_refused() {
        assert!(matches!(
            terrarium_png(&[0.0; 100]),
            Err(StandardTileError::WrongPixelCount { pixels: 100, expected: 65_536 })
        ));
        assert!(matches!(rgba_png(&[]), Err(StandardTileError::WrongPixelCount { pixels: 0, .. })));
    }
}
