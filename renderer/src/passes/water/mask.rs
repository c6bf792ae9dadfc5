//! The water mask around the camera: a square window in the local east and
//! north metres round the ground under the eye, each texel the water
//! layer's coverage there, read from one block of the layer's samples at
//! the tile level whose spacing matches the texels. Kept while the eye
//! stays well inside it; where the layer changes, only the texels over
//! the change are read again.

use std::ops::Range;

use glam::DVec3;
use rayon::prelude::*;
use relief_source::Extent;

use crate::surface::Surface;

/// Texels to a side of the mask window.
pub const MASK_SIZE: usize = 1024;

/// The most samples one window reads.
const MAX_BLOCK: i64 = 4 * 1024 * 1024;

/// The water layer as the renderer asks for it.
pub trait WaterSamples: Sync {
    /// Water coverage, 0 (dry) to 255 (water), at every sample of the
    /// block; None while its tiles are not ready.
    fn coverage(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<u8>>;
    /// The finest tile level worth reading.
    fn finest_level(&self) -> u8;
}

/// A mask window: where it is and what it holds.
pub struct Window {
    /// The window's centre (world) and its east and north axes there.
    pub centre: DVec3,
    pub east: DVec3,
    pub north: DVec3,
    /// Half its side, metres.
    pub half_m: f64,
    /// Coverage, rows from the north.
    pub texels: Vec<u8>,
    /// The grid area it read (for invalidation).
    pub area: Extent,
    /// East and north metres (min, max) round the centre that hold water;
    /// None for a window without any.
    pub wet: Option<([f64; 2], [f64; 2])>,
    /// The grid point under its centre, and the tile level it reads.
    under: (f64, f64),
    level: u8,
}

/// A block of texels: columns and rows of the window.
pub type TexelBlock = (Range<usize>, Range<usize>);

impl Window {
    /// Whether this window still serves an eye over `ground` wanting
    /// `half_m`: the eye inside its middle half, the size within a quarter.
    pub fn serves(&self, ground: DVec3, half_m: f64) -> bool {
        let d = ground - self.centre;
        let (e, n) = (d.dot(self.east).abs(), d.dot(self.north).abs());
        e < self.half_m / 4.0 && n < self.half_m / 4.0 && (half_m / self.half_m - 1.0).abs() < 0.25
    }

    fn texel_m(&self) -> f64 {
        2.0 * self.half_m / MASK_SIZE as f64
    }

    /// Reads the window round grid point (x, y) on `surface`, `half_m`
    /// metres each way; None while the layer's tiles are not ready.
    pub fn read(surface: &Surface, water: &dyn WaterSamples, (x, y): (f64, f64), half_m: f64) -> Option<Self> {
        let centre = surface.world(x, y, 0.0);
        let [east, north, _] = surface.enu(x, y);
        let texel = 2.0 * half_m / MASK_SIZE as f64;
        // The tile level whose samples are about a texel apart.
        let mut level = 0u8;
        while level < water.finest_level() && surface.spacing_m(level) > texel {
            level += 1;
        }
        let mut window = Self {
            centre,
            east,
            north,
            half_m,
            texels: vec![0; MASK_SIZE * MASK_SIZE],
            area: Extent { min_x: x, min_y: y, max_x: x, max_y: y },
            wet: None,
            under: (x, y),
            level,
        };
        let (level, area) = window.fill(surface, water, (0..MASK_SIZE, 0..MASK_SIZE), true)?;
        (window.level, window.area) = (level, area);
        window.wet = window.wet_part();
        Some(window)
    }

    /// Reads again the texels whose ground the scene rebuilt (`area`, grid
    /// units): the block of texels over it, with a margin for the
    /// bilinear taps. Returns the block written (None when the area misses
    /// the window), or Err while the layer's tiles are not ready.
    pub fn refresh(
        &mut self,
        surface: &Surface,
        water: &dyn WaterSamples,
        area: &Extent,
    ) -> Result<Option<TexelBlock>, ()> {
        // On the planet the window may read longitudes a turn off the
        // area's.
        let turns: &[f64] = if surface.is_planet() { &[0.0, 360.0, -360.0] } else { &[0.0] };
        let shifted = |t: f64| Extent { min_x: area.min_x + t, max_x: area.max_x + t, ..*area };
        let Some(area) = turns.iter().map(|&t| shifted(t)).find(|a| self.area.overlaps(a)) else {
            return Ok(None);
        };
        let area = &area;
        // The area's ground in the window's texels (a lattice over it, the
        // window being a plane round its centre).
        let texel = self.texel_m();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for i in 0..=4 {
            for j in 0..=4 {
                let gx = area.min_x + (area.max_x - area.min_x) * f64::from(i) / 4.0;
                let gy = area.min_y + (area.max_y - area.min_y) * f64::from(j) / 4.0;
                let d = surface.world(gx, gy, 0.0) - self.centre;
                let (col, row) = ((d.dot(self.east) + self.half_m) / texel, (self.half_m - d.dot(self.north)) / texel);
                (lo, hi) = ([lo[0].min(col), lo[1].min(row)], [hi[0].max(col), hi[1].max(row)]);
            }
        }
        let clamp = |v: f64| (v.max(0.0) as usize).min(MASK_SIZE);
        let cols = clamp(lo[0].floor() - 2.0)..clamp(hi[0].ceil() + 2.0);
        let rows = clamp(lo[1].floor() - 2.0)..clamp(hi[1].ceil() + 2.0);
        if cols.is_empty() || rows.is_empty() {
            return Ok(None);
        }
        self.fill(surface, water, (cols.clone(), rows.clone()), false).ok_or(())?;
        self.wet = self.wet_part();
        Ok(Some((cols, rows)))
    }

    /// Reads the texels of `block` from the layer at the window's level (a
    /// coarser one where the block's samples would be too many round a
    /// pole, when `may_coarsen`); the level read and the grid area.
    fn fill(
        &mut self,
        surface: &Surface,
        water: &dyn WaterSamples,
        (cols, rows): TexelBlock,
        may_coarsen: bool,
    ) -> Option<(u8, Extent)> {
        let x = self.under.0;
        let (half_m, texel) = (self.half_m, self.texel_m());
        let (centre, east, north) = (self.centre, self.east, self.north);
        let width = cols.len();
        // Each texel centre's grid point (longitudes kept near the
        // centre's, so a window over the antimeridian reads one block).
        let points: Vec<(f64, f64)> = (0..width * rows.len())
            .into_par_iter()
            .map(|k| {
                let (row, col) = (rows.start + k / width, cols.start + k % width);
                let e = (col as f64 + 0.5) * texel - half_m;
                let n = half_m - (row as f64 + 0.5) * texel;
                let [mut gx, gy, _] = surface.grid_point(centre + east * e + north * n);
                if surface.is_planet() {
                    gx = x + (gx - x + 540.0).rem_euclid(360.0) - 180.0;
                }
                (gx, gy)
            })
            .collect();
        // Their places in the level's samples, and the block they span: a
        // coarser level where it would be too large (round a pole).
        let mut level = self.level;
        let (places, xs, ys) = loop {
            let places: Vec<(f64, f64)> =
                points.par_iter().map(|&(gx, gy)| surface.sample_coords(level, gx, gy)).collect();
            let (lo, hi) = places
                .iter()
                .fold(((f64::INFINITY, f64::INFINITY), (f64::NEG_INFINITY, f64::NEG_INFINITY)), |(lo, hi), s| {
                    ((lo.0.min(s.0), lo.1.min(s.1)), (hi.0.max(s.0), hi.1.max(s.1)))
                });
            let xs = lo.0.floor() as i64..hi.0.floor() as i64 + 2;
            let ys = lo.1.floor() as i64..hi.1.floor() as i64 + 2;
            if !may_coarsen || level == 0 || (xs.end - xs.start) * (ys.end - ys.start) <= MAX_BLOCK {
                break (places, xs, ys);
            }
            level -= 1;
        };
        let block_cols = (xs.end - xs.start) as usize;
        let samples = water.coverage(level, xs.clone(), ys.clone())?;
        let at = |i: i64, j: i64| f64::from(samples[(j - ys.start) as usize * block_cols + (i - xs.start) as usize]);
        let values: Vec<u8> = places
            .par_iter()
            .map(|&(sx, sy)| {
                let (i, j) = (sx.floor() as i64, sy.floor() as i64);
                let (fx, fy) = (sx - i as f64, sy - j as f64);
                let top = at(i, j) * (1.0 - fx) + at(i + 1, j) * fx;
                let bottom = at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx;
                (top * (1.0 - fy) + bottom * fy).round() as u8
            })
            .collect();
        for (k, row) in rows.enumerate() {
            let first = row * MASK_SIZE + cols.start;
            self.texels[first..first + width].copy_from_slice(&values[k * width..(k + 1) * width]);
        }
        let (a, b) = (surface.sample_point(level, xs.start, ys.start), surface.sample_point(level, xs.end, ys.end));
        let area = Extent { min_x: a.0.min(b.0), min_y: a.1.min(b.1), max_x: a.0.max(b.0), max_y: a.1.max(b.1) };
        Some((level, area))
    }

    /// East and north metres (min, max) round the centre that hold water.
    fn wet_part(&self) -> Option<([f64; 2], [f64; 2])> {
        let texel = self.texel_m();
        let half_m = self.half_m;
        self.texels.iter().enumerate().filter(|(_, v)| **v > 0).fold(None, |acc, (k, _)| {
            let (row, col) = (k / MASK_SIZE, k % MASK_SIZE);
            let e = (col as f64 + 0.5) * texel - half_m;
            let n = half_m - (row as f64 + 0.5) * texel;
            let ([e0, e1], [n0, n1]) = acc.unwrap_or(([e, e], [n, n]));
            Some(([e0.min(e), e1.max(e)], [n0.min(n), n1.max(n)]))
        })
    }
}
