//! What a raster must pass when it opens: every block inside the file,
//! and overviews that agree with the base.

use rayon::prelude::*;
use relief_source::SourceError;

use super::blocks::BLOCK;
use super::halve;
use super::{PixelRect, Raster, format_err, tiff};

impl Raster {
    /// Checks that a windowed raster's blocks are all in the file (a TIFF's
    /// block tables), or reads its first and last base blocks (any other
    /// format): a file cut short fails here, when it opens, not at its
    /// first tile.
    pub(super) fn probe(self) -> Result<Self, SourceError> {
        if let Some(images) = tiff::images(&self.path) {
            for image in images.iter() {
                image.check_within(&self.path)?;
            }
            return Ok(self);
        }
        let (bw, bh) = (self.width().div_ceil(BLOCK), self.height().div_ceil(BLOCK));
        self.store.block(0, 0, 0)?;
        self.store.block(0, bw - 1, bh - 1)?;
        Ok(self)
    }

    /// Refuses a raster whose first overview is not a reduction of its base:
    /// at up to 16 places, each overview pixel must lie within the range of
    /// the four base pixels under it (with a little slack for smoothing
    /// kernels), as nearest, average, bilinear or mode overviews all do.
    pub(super) fn check_overviews(&self) -> Result<(), SourceError> {
        let levels = &self.store.levels;
        let Some(level) = levels.get(1).filter(|l| l.overview.is_some()) else {
            return Ok(());
        };
        const SIDE: usize = 8;
        // At each place, a block or two of each level is decoded: side by
        // side where relief decodes them (GDAL reads take a handle a thread).
        let probe = |k: usize| -> Result<Probe, SourceError> {
            let (fx, fy) = ((k % 4) as f64 / 3.0, (k / 4) as f64 / 3.0);
            let x0 = ((level.width.saturating_sub(SIDE)) as f64 * fx) as usize;
            let y0 = ((level.height.saturating_sub(SIDE)) as f64 * fy) as usize;
            let rect = PixelRect { x0, y0, x1: (x0 + SIDE).min(level.width), y1: (y0 + SIDE).min(level.height) };
            // Read straight from the file: a few pixels, not whole blocks.
            let over = self.store.read_file(level.overview, rect)?;
            let under = PixelRect {
                x0: 2 * rect.x0,
                y0: 2 * rect.y0,
                x1: (2 * rect.x1).min(self.width()),
                y1: (2 * rect.y1).min(self.height()),
            };
            let base = self.store.read_file(None, under)?;
            let (base_width, base_height) = (under.width(), under.height());
            let (mut checked, mut off, mut worst) = (0usize, 0usize, None);
            for (o, b) in over.iter().zip(&base) {
                for j in 0..rect.height() {
                    for i in 0..rect.width() {
                        let v = o[j * rect.width() + i];
                        let below: Vec<f32> = halve::under(b, base_width, base_height, i, j)
                            .into_iter()
                            .flatten()
                            .filter(|h| !h.is_nan())
                            .collect();
                        if v.is_nan() || below.is_empty() {
                            continue;
                        }
                        let lo = below.iter().copied().fold(f32::INFINITY, f32::min);
                        let hi = below.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                        let slack = 0.25 * (hi - lo) + 0.01 * hi.abs().max(lo.abs()) + 0.5 / 255.0;
                        checked += 1;
                        if v < lo - slack || v > hi + slack {
                            off += 1;
                            worst = Some((v, lo, hi));
                        }
                    }
                }
            }
            Ok(Probe { checked, off, worst })
        };
        let parallel = self.store.native.is_some() || self.store.tiling.is_some();
        let places: Vec<Probe> = if parallel {
            (0..16).into_par_iter().map(probe).collect::<Result<_, _>>()?
        } else {
            (0..16).map(probe).collect::<Result<_, _>>()?
        };
        let checked: usize = places.iter().map(|p| p.checked).sum();
        let off: usize = places.iter().map(|p| p.off).sum();
        let worst = places.iter().rev().find_map(|p| p.worst).unwrap_or((0.0, 0.0, 0.0));
        if checked > 0 && off * 10 > checked {
            return Err(format_err(
                format!(
                    "its overviews disagree with its base: {off} of {checked} sampled pixels of the first overview \
                     lie outside the range of the base pixels under them (e.g. {} over {}..{}); rebuild them \
                     (gdaladdo) or set overviews = false on the source",
                    worst.0, worst.1, worst.2
                ),
                &self.path,
            ));
        }
        Ok(())
    }
}

/// What one place of the overview check found: pixels checked, pixels
/// off, and the last one off (its value and the range under it).
struct Probe {
    checked: usize,
    off: usize,
    worst: Option<(f32, f32, f32)>,
}
