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

/// One axis of a mip level, as the base level's coordinates see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LevelAxis {
    /// The level's pixels along the axis.
    pub size: usize,
    /// Base pixels per full pixel of the level.
    pub pixel: f64,
    /// The raster's base pixels along the axis.
    pub base: usize,
    /// The axis wraps round (the longitudes of a whole-planet raster).
    pub wrap: bool,
}

/// Taps for base-level edge coordinate `u` on `axis` of a level, or None
/// off the raster. The base level is GDAL's convention (`axis_taps`). A
/// coarser level uses the kernel on its even lattice where the taps stay
/// on full pixels; near an edge, and beside a last pixel that hangs over
/// it, it interpolates linearly between the two pixels round `u` at
/// their true centres (the middle of the part on the raster), and holds
/// the outer pixel's value from its centre to the raster's edge, as the
/// base level and GDAL do (never a value outside the pixels'). A coarse
/// level thus reaches the raster's edge and no farther, with each value
/// where the ground it averages lies.
pub(crate) fn level_taps(u: f64, axis: LevelAxis, kernel: Resampling) -> Option<Taps> {
    let LevelAxis { size, pixel, base, wrap } = axis;
    if pixel == 1.0 {
        return axis_taps(u, size, kernel, wrap);
    }
    let extent = base as f64;
    if size == 0 || !u.is_finite() || (!wrap && !(0.0..=extent).contains(&u)) {
        return None;
    }
    let x = if wrap { u.rem_euclid(extent) } else { u } / pixel;
    let (last, period) = (size - 1, extent / pixel);
    let cover = (period - last as f64).clamp(1e-9, 1.0);
    let full = cover == 1.0;
    let mut t = Taps { index: [0; MAX_TAPS], weight: [0.0; MAX_TAPS], len: 0 };
    if kernel == Resampling::Nearest {
        t.index[0] = (x.floor() as usize).min(last);
        t.weight[0] = 1.0;
        t.len = 1;
        return Some(t);
    }
    // The kernel's reach on the even lattice: off the edges and off a
    // partial last pixel, the level is even there.
    let nearest = (x - 0.5).floor() as i64;
    let radius = kernel.radius() as i64;
    let (first_tap, last_tap) = (nearest - radius + 1, nearest + radius);
    let even_to = last as i64 - i64::from(!full);
    if (wrap && full) || (first_tap >= 0 && last_tap <= even_to) {
        return axis_taps(x, size, kernel, wrap);
    }
    let own = |i: usize| if i == last { last as f64 + cover / 2.0 } else { i as f64 + 0.5 };
    let centre = |i: i64| -> f64 {
        match usize::try_from(i) {
            Err(_) => own(last) - period,
            Ok(i) if i > last => own(0) + period,
            Ok(i) => own(i),
        }
    };
    let last_i = last as i64;
    let x = if wrap {
        x
    } else if size == 1 {
        t.index[0] = 0;
        t.weight[0] = 1.0;
        t.len = 1;
        return Some(t);
    } else {
        x.clamp(centre(0), centre(last_i))
    };
    // The pixel centre at or before x, and the next: across the seam on a
    // wrapped axis, the outer two on a plain one.
    let below = if x < centre(0) {
        if wrap { -1 } else { 0 }
    } else if x >= centre(last_i) {
        if wrap { last_i } else { last_i - 1 }
    } else {
        ((x - 0.5).floor() as i64).min(last_i - 1)
    };
    let (a, b) = (centre(below), centre(below + 1));
    let s = (x - a) / (b - a);
    let place = |k: i64| k.rem_euclid(size as i64) as usize;
    for (k, w) in [(below, 1.0 - s), (below + 1, s)] {
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
            // Normalised by the weights' sums (1 but for rounding), each a
            // reciprocal: two products, not a division, a sample.
            let (rx, ry) = (1.0 / (tx.weight[0] + tx.weight[1]), 1.0 / (ty.weight[0] + ty.weight[1]));
            return ((ty.weight[0] * top + ty.weight[1] * bottom) * rx * ry) as f32;
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

/// A column's two bilinear taps, their weights, and their sum's reciprocal.
type Pair = (usize, usize, f64, f64, f64);

/// Heights of a tile whose columns and rows map to the level's columns and
/// rows (`columns` a row's taps, `rows` a column's), into the samples of
/// `out` still NaN (an earlier raster of a mosaic keeps its samples).
/// Each sample is what `height_from_taps` gives it, bit for bit; the
/// bilinear case takes each row's two lines of pixels and each column's
/// taps once, not once a sample.
pub(crate) fn heights_by_rows(level: &Window, columns: &[Option<Taps>], rows: &[Option<Taps>], out: &mut [f32]) {
    let (plane, width) = (&level.planes[0], level.width);
    let pairs: Vec<Option<Pair>> = columns
        .iter()
        .map(|t| {
            t.filter(|t| t.len == 2)
                .map(|t| (t.index[0], t.index[1], t.weight[0], t.weight[1], 1.0 / (t.weight[0] + t.weight[1])))
        })
        .collect();
    for (ty, row_out) in rows.iter().zip(out.chunks_exact_mut(columns.len())) {
        let Some(ty) = ty else { continue };
        let each = |o: &mut f32, tx: &Option<Taps>| {
            if o.is_nan()
                && let Some(tx) = tx
            {
                *o = height_from_taps(level, tx, ty);
            }
        };
        if ty.len != 2 {
            row_out.iter_mut().zip(columns).for_each(|(o, tx)| each(o, tx));
            continue;
        }
        let (line0, line1) = (&plane[ty.index[0] * width..][..width], &plane[ty.index[1] * width..][..width]);
        let (wy0, wy1, ry) = (ty.weight[0], ty.weight[1], 1.0 / (ty.weight[0] + ty.weight[1]));
        for ((o, pair), tx) in row_out.iter_mut().zip(&pairs).zip(columns) {
            if !o.is_nan() {
                continue;
            }
            if let Some((a, b, wx0, wx1, rx)) = *pair {
                let h = [line0[a], line0[b], line1[a], line1[b]];
                if !h.iter().any(|v| v.is_nan()) {
                    // height_from_taps's bilinear arithmetic, term for term.
                    let top = wx0 * f64::from(h[0]) + wx1 * f64::from(h[1]);
                    let bottom = wx0 * f64::from(h[2]) + wx1 * f64::from(h[3]);
                    *o = ((wy0 * top + wy1 * bottom) * rx * ry) as f32;
                    continue;
                }
            }
            each(o, tx);
        }
    }
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

    /// The value the taps give over a level's pixels `values`.
    fn through(t: &Taps, values: &[f64]) -> f64 {
        (0..t.len).map(|k| t.weight[k] * values[t.index[k]]).sum::<f64>() / t.weight[..t.len].iter().sum::<f64>()
    }

    #[test]
    fn a_coarse_levels_partial_last_pixel_stands_at_the_middle_of_its_ground() {
        // 10 base pixels at 4 a level pixel: 3 pixels, the last covering
        // 2 of 4 (base 8..10, its middle at 9). A line h = u (base edge
        // coordinates) halved is the pixels' middles: 2, 6, 9.
        let axis = LevelAxis { size: 3, pixel: 4.0, base: 10, wrap: false };
        let values = [2.0, 6.0, 9.0];
        for kernel in Resampling::ALL.into_iter().filter(|k| *k != Resampling::Nearest) {
            for u in [2.0, 3.0, 4.5, 6.0, 7.0, 8.5, 9.0] {
                let t = level_taps(u, axis, kernel).unwrap();
                assert!((through(&t, &values) - u).abs() < 1e-9, "{kernel} at {u}: {}", through(&t, &values));
            }
            // Held from the outer centres to the edge, nothing past it.
            for (u, want) in [(0.0, 2.0), (1.0, 2.0), (9.5, 9.0), (10.0, 9.0)] {
                assert_eq!(through(&level_taps(u, axis, kernel).unwrap(), &values), want, "{kernel} at {u}");
            }
            assert!(level_taps(10.01, axis, kernel).is_none() && level_taps(-0.01, axis, kernel).is_none());
        }
        assert_eq!(level_taps(9.9, axis, Resampling::Nearest).unwrap().index[0], 2);
        // Wrapped (a whole-planet raster): across the seam from the partial
        // pixel's middle (9) to the first's (2 + 10).
        let axis = LevelAxis { wrap: true, ..axis };
        let t = level_taps(10.5, axis, Resampling::Bilinear).unwrap();
        let (a, b) = (t.weight[..t.len].to_vec(), t.index[..t.len].to_vec());
        assert_eq!(b, [2, 0]);
        assert!((a[0] - 1.5 / 3.0).abs() < 1e-12 && (a[1] - 1.5 / 3.0).abs() < 1e-12, "{a:?}");
        // A level whose pixels all lie on the raster (an overview's even
        // spread, or a multiple) is the kernel on its even lattice inside.
        let even = LevelAxis { size: 4, pixel: 2.5, base: 10, wrap: false };
        let t = level_taps(5.0, even, Resampling::Cubic).unwrap();
        let u = axis_taps(2.0, 4, Resampling::Cubic, false).unwrap();
        assert_eq!((t.index, t.weight, t.len), (u.index, u.weight, u.len));
    }

    proptest! {
        /// The row path gives each sample what `height_from_taps` gives
        /// it, bit for bit: over voids, at the edges, for every kernel
        /// (bilinear takes the row path's own arithmetic, the others go
        /// through), and it leaves samples an earlier raster set.
        #[test]
        fn rows_give_every_sample_what_its_taps_give(
            seed in 0u64..1000,
            kernel in proptest::sample::select(Resampling::ALL.to_vec()),
            spacing in 0.3f64..2.5,
            start in -1.0f64..3.0,
        ) {
            let l = level(23, 19, |i, j| {
                let k = (i as u64 * 7919 + j as u64 * 104_729 + seed * 31) % 101;
                if k < 6 { f32::NAN } else { k as f32 * 3.7 - 40.0 }
            });
            let axis = |size: usize, n: usize| -> Vec<Option<Taps>> {
                (0..n).map(|i| axis_taps(start + i as f64 * spacing, size, kernel, false)).collect()
            };
            let (columns, rows) = (axis(23, 13), axis(19, 11));
            let mut out: Vec<f32> = (0..13 * 11).map(|n| if n % 17 == 5 { 1234.5 } else { f32::NAN }).collect();
            let earlier = out.clone();
            heights_by_rows(&l, &columns, &rows, &mut out);
            for (n, (got, before)) in out.iter().zip(&earlier).enumerate() {
                let (tx, ty) = (&columns[n % 13], &rows[n / 13]);
                let want = if before.is_nan() {
                    tx.as_ref().zip(ty.as_ref()).map_or(f32::NAN, |(tx, ty)| height_from_taps(&l, tx, ty))
                } else {
                    *before
                };
                prop_assert_eq!(got.to_bits(), want.to_bits(), "sample {}", n);
            }
        }

        #[test]
        fn interpolated_heights_stay_within_their_taps(u in 0.0f64..16.0, v in 0.0f64..16.0, seed in 0u32..1000) {
            let l = level(16, 16, |i, j| ((i * 31 + j * 17 + seed as usize) % 97) as f32);
            let h = height_at(&l, u, v, Resampling::Bilinear, false);
            prop_assert!((0.0..=96.0).contains(&h), "{h}");
        }
    }
}
