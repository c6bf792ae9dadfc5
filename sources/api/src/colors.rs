//! Colours as manifests and files give them: "#rrggbb[aa]" options, KML's
//! aabbggrr styles, and a fixed palette for colouring by an attribute.

use crate::SourceError;

/// "#rrggbb" or "#rrggbbaa".
pub fn parse_color(field: &str, text: &str) -> Result<[f64; 4], SourceError> {
    let hex = text.trim_start_matches('#');
    let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16);
    let bad = || SourceError::option(field, format!("'{text}' is not #rrggbb or #rrggbbaa"));
    if !(hex.len() == 6 || hex.len() == 8) || !hex.is_ascii() {
        return Err(bad());
    }
    let mut c = [0.0, 0.0, 0.0, 1.0];
    for (k, slot) in c.iter_mut().enumerate().take(hex.len() / 2) {
        *slot = f64::from(byte(2 * k).map_err(|_| bad())?) / 255.0;
    }
    Ok(c)
}

/// KML's aabbggrr colours, as styles in KML files give them.
pub fn kml_color(text: &str) -> Option<[f64; 4]> {
    let v = u32::from_str_radix(text.trim(), 16).ok()?;
    let c = |shift: u32| f64::from((v >> shift) & 0xff) / 255.0;
    Some([c(0), c(8), c(16), c(24)])
}

const PALETTE: [[f64; 3]; 8] = [
    [0.89, 0.10, 0.11],
    [0.22, 0.49, 0.72],
    [0.30, 0.69, 0.29],
    [0.60, 0.31, 0.64],
    [1.00, 0.50, 0.00],
    [0.65, 0.34, 0.16],
    [0.97, 0.51, 0.75],
    [0.40, 0.76, 0.65],
];

/// The palette's colour for an attribute value (the same value, the same
/// colour, in every tile and every run).
pub fn by_value(value: &str) -> [f64; 3] {
    let h = value.bytes().fold(0u64, |h, b| h.wrapping_mul(31).wrapping_add(u64::from(b)));
    PALETTE[(h % PALETTE.len() as u64) as usize]
}

/// A feature's colour, as buildings take it: by the `color_by` attribute's
/// value (the palette, opaque), else its KML style's fill (made opaque),
/// else `default`.
pub fn feature_color(feature: &crate::Feature, color_by: Option<&str>, default: [f64; 4]) -> [u8; 4] {
    if let Some(value) = color_by.and_then(|a| feature.properties.get(a)) {
        let c = by_value(value);
        return rgba8([c[0], c[1], c[2], 1.0]);
    }
    let kml = feature.properties.get("fill_color").and_then(|c| kml_color(c));
    rgba8(kml.map_or(default, |c| [c[0], c[1], c[2], 1.0]))
}

/// 0..1 RGBA as RGBA8.
pub fn rgba8(c: [f64; 4]) -> [u8; 4] {
    c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
}
