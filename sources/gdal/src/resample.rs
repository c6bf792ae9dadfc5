//! Kernels applied to a window of a mip level at a point, with the nodata
//! policy of the crate docs. Coordinates are pixel-edge coordinates of the
//! level (GDAL's convention: pixel (0, 0) spans [0, 1) x [0, 1)); taps are
//! found on the whole level and then moved into the window read for them.

use relief_source::Resampling;

use crate::raster::Window;

const MAX_TAPS: usize = 6;

/// The taps of a 1-D kernel: clamped indices and weights.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Taps {
    index: [usize; MAX_TAPS],
    weight: [f64; MAX_TAPS],
    len: usize,
}

impl Taps {
    /// The first and last pixel the taps read.
    pub(crate) fn span(&self) -> (usize, usize) {
        let used = &self.index[..self.len];
        (used.iter().copied().min().unwrap_or(0), used.iter().copied().max().unwrap_or(0))
    }

    /// The same taps in a window starting at pixel `origin`.
    pub(crate) fn shifted(mut self, origin: usize) -> Self {
        for i in &mut self.index[..self.len] {
            *i -= origin;
        }
        self
    }
}

/// Taps for edge coordinate `u` on an axis of `size` pixels, or None when
/// `u` lies beyond the raster's outer edge.
#[cfg(test)]
pub(crate) fn taps(u: f64, size: usize, kernel: Resampling) -> Option<Taps> {
    axis_taps(u, size, kernel, false)
}

/// Taps along an axis that `wrap`s round (the longitudes of a raster that
/// spans the whole planet: the antimeridian is no edge) or stops at the
/// raster's outer edge.
pub(crate) fn axis_taps(u: f64, size: usize, kernel: Resampling, wrap: bool) -> Option<Taps> {
    if !u.is_finite() || (!wrap && (u < 0.0 || u > size as f64)) {
        return None;
    }
    let last = size as i64 - 1;
    let place = |k: i64| {
        if wrap { k.rem_euclid(size as i64) as usize } else { k.clamp(0, last) as usize }
    };
    let mut t = Taps { index: [0; MAX_TAPS], weight: [0.0; MAX_TAPS], len: 0 };
    if kernel == Resampling::Nearest {
        t.index[0] = place(u.floor() as i64);
        t.weight[0] = 1.0;
        t.len = 1;
        return Some(t);
    }
    // Centre-based coordinate: pixel i's centre is at i.
    let f = u - 0.5;
    let base = f.floor() as i64;
    let radius = kernel.radius() as i64;
    for k in (base - radius + 1)..=(base + radius) {
        let w = kernel.weight(f - k as f64);
        if w != 0.0 {
            t.index[t.len] = place(k);
            t.weight[t.len] = w;
            t.len += 1;
        }
    }
    Some(t)
}

/// A height at edge coordinates (u, v) of a level of `size` pixels, read
/// from `window` of it (which holds the taps). NaN when the point is off
/// the raster or mostly over nodata.
#[cfg(test)]
pub(crate) fn height_at(
    window: &Window,
    size: (usize, usize),
    u: f64,
    v: f64,
    kernel: Resampling,
    wrap_x: bool,
) -> f32 {
    match (axis_taps(u, size.0, kernel, wrap_x), taps(v, size.1, kernel)) {
        (Some(tx), Some(ty)) => height_from_taps(window, &tx, &ty),
        _ => f32::NAN,
    }
}

/// A height from taps already found (a tile whose columns and rows map to
/// source columns and rows finds them once per column and row).
pub(crate) fn height_from_taps(level: &Window, tx: &Taps, ty: &Taps) -> f32 {
    let plane = &level.planes[0];
    if tx.len == 2 && ty.len == 2 {
        // Bilinear, the common case, without the general loops.
        let (r0, r1) = (ty.index[0] * level.width, ty.index[1] * level.width);
        let h = [plane[r0 + tx.index[0]], plane[r0 + tx.index[1]], plane[r1 + tx.index[0]], plane[r1 + tx.index[1]]];
        if !h.iter().any(|v| v.is_nan()) {
            let top = tx.weight[0] * f64::from(h[0]) + tx.weight[1] * f64::from(h[1]);
            let bottom = tx.weight[0] * f64::from(h[2]) + tx.weight[1] * f64::from(h[3]);
            return ((ty.weight[0] * top + ty.weight[1] * bottom)
                / ((tx.weight[0] + tx.weight[1]) * (ty.weight[0] + ty.weight[1]))) as f32;
        }
    }
    let (mut sum, mut valid_w, mut total_w) = (0.0f64, 0.0f64, 0.0f64);
    for y in 0..ty.len {
        let row = ty.index[y] * level.width;
        for x in 0..tx.len {
            let w = tx.weight[x] * ty.weight[y];
            total_w += w;
            let h = plane[row + tx.index[x]];
            if !h.is_nan() {
                sum += w * f64::from(h);
                valid_w += w;
            }
        }
    }
    if valid_w > 1e-9 && valid_w >= 0.5 * total_w { (sum / valid_w) as f32 } else { f32::NAN }
}

/// Premultiplied RGBA from taps already found.
pub(crate) fn color_from_taps(level: &Window, tx: &Taps, ty: &Taps) -> [f32; 4] {
    let mut acc = [0.0f64; 4];
    let mut total_w = 0.0;
    for y in 0..ty.len {
        let row = ty.index[y] * level.width;
        for x in 0..tx.len {
            let w = tx.weight[x] * ty.weight[y];
            total_w += w;
            for (a, plane) in acc.iter_mut().zip(&level.planes) {
                *a += w * f64::from(plane[row + tx.index[x]]);
            }
        }
    }
    acc.map(|a| (a / total_w).clamp(0.0, 1.0) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn level(width: usize, height: usize, f: impl Fn(usize, usize) -> f32) -> Window {
        let plane = (0..height).flat_map(|j| (0..width).map(move |i| (i, j))).map(|(i, j)| f(i, j)).collect();
        Window { width, height, planes: vec![plane] }
    }

    fn height_at(l: &Window, u: f64, v: f64, kernel: Resampling, wrap_x: bool) -> f32 {
        super::height_at(l, (l.width, l.height), u, v, kernel, wrap_x)
    }

    #[test]
    fn bilinear_reproduces_a_plane_exactly() {
        // h = 3 i + 2 j at pixel centres; bilinear is exact for planes.
        let l = level(8, 6, |i, j| 3.0 * i as f32 + 2.0 * j as f32);
        let h = height_at(&l, 2.75, 3.25, Resampling::Bilinear, false);
        assert!((h - (3.0 * 2.25 + 2.0 * 2.75)).abs() < 1e-5, "{h}");
    }

    #[test]
    fn nodata_is_never_blended_into_heights() {
        // A void next to 100 m ground.
        let l = level(4, 4, |i, _| if i == 2 { f32::NAN } else { 100.0 });
        for u in [1.6, 2.0, 2.4, 2.6, 3.0] {
            let h = height_at(&l, u, 2.0, Resampling::Bilinear, false);
            assert!(h.is_nan() || (h - 100.0).abs() < 1e-4, "u={u}: {h}");
        }
        // Mostly over the void: nodata, not an extrapolated height.
        assert!(height_at(&l, 2.5, 2.0, Resampling::Bilinear, false).is_nan());
        for kernel in Resampling::ALL {
            let h = height_at(&l, 1.9, 2.0, kernel, false);
            assert!(h.is_nan() || (h - 100.0).abs() < 1e-3, "{kernel}: {h}");
        }
    }

    #[test]
    fn wrapped_axes_interpolate_across_the_antimeridian() {
        // Columns hold 0, 10, 20, 30: between the last and the first the
        // height runs 30 -> 0, as it does across the date line.
        let l = level(4, 1, |i, _| 10.0 * i as f32);
        let t = axis_taps(4.0, 4, Resampling::Bilinear, true).unwrap();
        let ty = axis_taps(0.5, 1, Resampling::Bilinear, false).unwrap();
        assert_eq!(height_from_taps(&l, &t, &ty), 15.0);
        let t = axis_taps(0.0, 4, Resampling::Bilinear, true).unwrap();
        assert_eq!(height_from_taps(&l, &t, &ty), 15.0, "the same point from the other side");
        assert!(axis_taps(-0.5, 4, Resampling::Bilinear, false).is_none());
        assert!(axis_taps(f64::NAN, 4, Resampling::Bilinear, true).is_none());
    }

    #[test]
    fn the_raster_reaches_its_outer_edge_and_no_farther() {
        let l = level(3, 3, |_, _| 7.0);
        assert_eq!(height_at(&l, 0.0, 0.0, Resampling::Bilinear, false), 7.0);
        assert_eq!(height_at(&l, 3.0, 3.0, Resampling::Cubic, false), 7.0);
        assert!(height_at(&l, -0.01, 1.0, Resampling::Bilinear, false).is_nan());
        assert!(height_at(&l, 1.0, 3.01, Resampling::Nearest, false).is_nan());
        assert!(height_at(&l, f64::NAN, 1.0, Resampling::Nearest, false).is_nan());
    }

    proptest! {
        #[test]
        fn interpolated_heights_stay_within_their_taps(u in 0.0f64..16.0, v in 0.0f64..16.0, seed in 0u32..1000) {
            let l = level(16, 16, |i, j| ((i * 31 + j * 17 + seed as usize) % 97) as f32);
            let h = height_at(&l, u, v, Resampling::Bilinear, false);
            prop_assert!((0.0..=96.0).contains(&h), "{h}");
        }
    }
}
