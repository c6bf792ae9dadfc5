//! Coarser pixels from finer ones: how a mip pixel is made from the (up
//! to) four pixels under it, for heights, colour and codes. Each pixel
//! under weighs what of it lies on the raster (a last column or row that
//! hangs over the edge weighs less), so a coarse pixel is the mean of the
//! ground it covers.

/// How a mip pixel is made from the (up to) four under it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Halving {
    /// Heights: the mean of the valid ones (NaN when none is).
    HeightMean,
    /// Premultiplied colour: the plain mean (transparent weighs nothing).
    ColorMean,
    /// Codes: the most common valid value (the first of equals, row by row).
    Mode,
}

/// The (up to) four pixels of `plane` (`width` x `height`) under pixel
/// (i, j) of the next level; None past the plane's edge.
pub(crate) fn under(plane: &[f32], width: usize, height: usize, i: usize, j: usize) -> [Option<f32>; 4] {
    [(0, 0), (1, 0), (0, 1), (1, 1)]
        .map(|(dx, dy)| (2 * i + dx, 2 * j + dy))
        .map(|(x, y)| (x < width && y < height).then(|| plane[y * width + x]))
}

/// What of each column and row of a plane lies on the raster (1 for all
/// but a partial last one).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Covers<'a> {
    pub columns: &'a [f64],
    pub rows: &'a [f64],
}

impl Covers<'_> {
    fn weight(&self, x: usize, y: usize) -> f64 {
        self.columns.get(x).copied().unwrap_or(1.0) * self.rows.get(y).copied().unwrap_or(1.0)
    }
}

/// One pixel of the next level, from the (up to) four pixels under it in
/// `plane` (`width` x `height`, its origin on an even pixel of the level
/// below), each weighed by its `covers`.
pub(crate) fn halved_pixel(
    plane: &[f32],
    (width, height): (usize, usize),
    covers: Covers<'_>,
    (i, j): (usize, usize),
    halving: Halving,
) -> f32 {
    let under = under(plane, width, height, i, j);
    let weights = [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(dx, dy)| covers.weight(2 * i + dx, 2 * j + dy));
    let valid = || under.iter().zip(weights).filter_map(|(v, w)| v.filter(|v| !v.is_nan()).map(|v| (v, w)));
    if halving == Halving::Mode {
        let count = |v: f32| valid().filter(|u| u.0 == v).map(|u| u.1).sum::<f64>();
        return valid()
            .fold(None, |best: Option<f32>, (v, _)| match best {
                Some(b) if count(b) >= count(v) => Some(b),
                _ => Some(v),
            })
            .unwrap_or(f32::NAN);
    }
    let skip_nan = halving == Halving::HeightMean;
    let (mut sum, mut counted, mut cells) = (0.0f64, 0.0f64, 0.0f64);
    let mut any = false;
    for (v, w) in under.into_iter().zip(weights) {
        let Some(v) = v else { continue };
        cells += w;
        if !(skip_nan && v.is_nan()) {
            sum += w * f64::from(v);
            counted += w;
            any = true;
        }
    }
    let divisor = if skip_nan { counted } else { cells };
    if any { (sum / divisor) as f32 } else { f32::NAN }
}

/// The `out` (width, height) pixels of the next level over `plane`
/// (`width` x `height`, its origin on an even pixel of the level below).
/// Four valid full pixels take the fast path, with the same sum in the
/// same order as `halved_pixel`, so the bits are the same.
pub(crate) fn halve_window(
    plane: &[f32],
    width: usize,
    height: usize,
    covers: Covers<'_>,
    out: (usize, usize),
    halving: Halving,
) -> Vec<f32> {
    let full = |x: usize, y: usize| covers.weight(x, y) == 1.0 && covers.weight(x + 1, y + 1) == 1.0;
    let mut pixels = Vec::with_capacity(out.0 * out.1);
    for j in 0..out.1 {
        let (top, bottom) = (2 * j * width, (2 * j + 1) * width);
        for i in 0..out.0 {
            let (x0, x1) = (2 * i, 2 * i + 1);
            if halving != Halving::Mode && x1 < width && 2 * j + 1 < height && full(x0, 2 * j) {
                let (a, b, c, d) = (plane[top + x0], plane[top + x1], plane[bottom + x0], plane[bottom + x1]);
                if !(a.is_nan() || b.is_nan() || c.is_nan() || d.is_nan()) {
                    let sum = 0.0 + f64::from(a) + f64::from(b) + f64::from(c) + f64::from(d);
                    pixels.push((sum / 4.0) as f32);
                    continue;
                }
            }
            pixels.push(halved_pixel(plane, (width, height), covers, (i, j), halving));
        }
    }
    pixels
}

/// Every pixel wholly on the raster.
#[cfg(test)]
const FULL: Covers<'static> = Covers { columns: &[], rows: &[] };

#[cfg(test)]
/// A whole plane halved: `width.div_ceil(2)` x `height.div_ceil(2)` pixels.
pub(crate) fn halve(plane: &[f32], width: usize, height: usize, halving: Halving) -> Vec<f32> {
    let (w, h) = (width.div_ceil(2), height.div_ceil(2));
    (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| halved_pixel(plane, (width, height), FULL, (i, j), halving))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halving_ignores_nodata_and_keeps_all_void_blocks_void() {
        let n = f32::NAN;
        let plane = [1.0, 3.0, n, n, 5.0, n, n, n, 2.0];
        let out = halve(&plane, 3, 3, Halving::HeightMean);
        // Codes: the most common valid value, never a mean of classes.
        let codes = [3.0, 7.0, 7.0, f32::NAN];
        assert_eq!(halve(&codes, 2, 2, Halving::Mode), vec![7.0]);
        assert_eq!(halve(&[5.0, 9.0, f32::NAN, f32::NAN], 2, 2, Halving::Mode), vec![5.0]);
        assert!(halve(&[f32::NAN; 4], 2, 2, Halving::Mode)[0].is_nan());
        assert_eq!(out.len(), 4);
        assert_eq!(out[0], 3.0); // (1 + 3 + 5) / 3: the void does not pull it down
        assert!(out[1].is_nan()); // n, n over n: nothing valid
        assert!(out[2].is_nan() && out[3] == 2.0);
        // The fast path gives the same bits as the general one.
        let plane: Vec<f32> =
            (0..35).map(|i| if i % 11 == 3 { f32::NAN } else { (i as f32 * 0.37).sin() * 1e3 }).collect();
        for halving in [Halving::HeightMean, Halving::ColorMean, Halving::Mode] {
            let fast = halve_window(&plane, 7, 5, FULL, (4, 3), halving);
            let slow = halve(&plane, 7, 5, halving);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&fast), bits(&slow), "{halving:?}");
        }
        // A last column covering a quarter of its pixel weighs a quarter.
        let covers = Covers { columns: &[1.0, 0.25], rows: &[1.0, 1.0] };
        assert_eq!(halve_window(&[1.0, 5.0, 1.0, 5.0], 2, 2, covers, (1, 1), Halving::HeightMean), vec![1.8]);
        assert_eq!(
            halve_window(&[1.0, 5.0, 1.0, n], 2, 2, covers, (1, 1), Halving::HeightMean),
            vec![(2.0 + 1.25) / 2.25]
        );
        assert_eq!(halve_window(&[3.0, 7.0, 3.0, 7.0], 2, 2, covers, (1, 1), Halving::Mode), vec![3.0]);
        // Colour: transparent pixels weigh in as zero.
        assert_eq!(halve(&[1.0, 0.0, 0.0, 1.0], 2, 2, Halving::ColorMean), vec![0.5]);
    }
}
