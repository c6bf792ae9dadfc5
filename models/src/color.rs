//! sRGB transfer functions: glTF colour factors and vertex colours are
//! linear, a [`Model`](crate::Model)'s colours are sRGB-encoded.

/// `v` held to 0..1, with NaN (possible in a file's vertex colours) as 0.
pub(crate) fn clamp_unit(v: f32) -> f32 {
    if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) }
}

/// The sRGB encoding of a linear 0..1 value.
pub(crate) fn srgb_from_linear(linear: f32) -> f32 {
    let v = clamp_unit(linear);
    if v <= 0.003_130_8 {
        v * 12.92
    } else if v >= 1.0 {
        // Exact, where the formula would give 0.99999994.
        1.0
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The linear value of an sRGB-encoded 0..1 value.
pub(crate) fn linear_from_srgb(srgb: f32) -> f32 {
    let v = srgb.clamp(0.0, 1.0);
    if v <= 0.040_45 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_and_keeps_the_ends() {
        assert_eq!(srgb_from_linear(0.0), 0.0);
        assert_eq!(srgb_from_linear(1.0), 1.0);
        assert_eq!(srgb_from_linear(f32::NAN), 0.0);
        assert_eq!(srgb_from_linear(f32::INFINITY), 1.0);
        assert!((srgb_from_linear(0.214_041) - 0.5).abs() < 1e-4);
        for i in 0..=20 {
            let v = i as f32 / 20.0;
            assert!((srgb_from_linear(linear_from_srgb(v)) - v).abs() < 1e-5, "{v}");
        }
    }
}
