//! A drawn surface against the formula its data came from: what the
//! renderer's benches and `make accuracy` measure a frame's terrain by,
//! over plain numbers (a depth buffer and how to unproject it), so this
//! crate need not depend on the renderer.

use relief_source::geodesy;

/// RMS and max of (drawn - `relief_examples::demo_terrain`), in metres,
/// over every 4th pixel of every 4th row of a `width` x `height` depth
/// buffer (row-major; 0 where nothing was drawn) whose ground shows the
/// demo DEM: inside `DEMO_EXTENT` less 0.01 degrees at each side, outside
/// its nodata void. `point_in_ecef(px, py, depth)` is the ECEF point pixel
/// (px, py) shows at that depth. None when no pixel shows the DEM.
pub fn demo_surface_error(
    depth: &[f32],
    width: u32,
    height: u32,
    point_in_ecef: impl Fn(u32, u32, f32) -> [f64; 3],
) -> Option<(f64, f64)> {
    let [w0, s0, e0, n0] = relief_examples::DEMO_EXTENT;
    let (mut sum_squares, mut max, mut count) = (0.0, 0.0f64, 0usize);
    for py in (0..height).step_by(4) {
        for px in (0..width).step_by(4) {
            let d = depth[(py * width + px) as usize];
            if d <= 0.0 {
                continue;
            }
            let (lon, lat, h) = geodesy::geodetic_from_ecef(point_in_ecef(px, py, d));
            if !(w0 + 0.01..e0 - 0.01).contains(&lon)
                || !(s0 + 0.01..n0 - 0.01).contains(&lat)
                || relief_examples::in_demo_void(lon, lat)
            {
                continue;
            }
            let difference = h - relief_examples::demo_terrain(lon, lat);
            sum_squares += difference * difference;
            max = max.max(difference.abs());
            count += 1;
        }
    }
    (count > 0).then(|| ((sum_squares / count as f64).sqrt(), max))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64 x 48 buffer over the demo's west, its void included: pixel
    /// (px, py) shows the formula plus `offset_m` at 0.005 degrees a pixel;
    /// only the pixels where `drawn` holds have a depth.
    fn error_of(offset_m: f64, drawn: impl Fn(u32, u32) -> bool) -> Option<(f64, f64)> {
        let (width, height) = (64u32, 48u32);
        let depth: Vec<f32> =
            (0..width * height).map(|i| if drawn(i % width, i / width) { 0.5 } else { 0.0 }).collect();
        demo_surface_error(&depth, width, height, |px, py, _| {
            let (lon, lat) = (6.0 + f64::from(px) * 0.005, 45.3 + f64::from(py) * 0.005);
            geodesy::ecef_from_geodetic(lon, lat, relief_examples::demo_terrain(lon, lat) + offset_m)
        })
    }

    #[test]
    fn surface_error_is_the_offset_from_the_formula() {
        let (rms, max) = error_of(2.0, |_, _| true).expect("the buffer shows the DEM");
        assert!((rms - 2.0).abs() < 1e-6 && (max - 2.0).abs() < 1e-6, "rms {rms}, max {max}");
    }

    #[test]
    fn surface_error_is_none_where_nothing_shows_the_dem() {
        // Nothing drawn, then only the first column: 0.01 degrees from the west edge at most.
        assert_eq!(error_of(2.0, |_, _| false), None);
        assert_eq!(error_of(2.0, |px, _| px == 0), None);
    }
}
