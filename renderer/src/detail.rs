//! The `detail` effect's terrain: samples finer than the data synthesized
//! as Losasso and Hoppe do, each finer level from the one above by the C1
//! four-point subdivision (weights -1/16, 9/16, 9/16, -1/16; it reproduces
//! cubics) plus Gaussian noise whose amplitude per octave is fitted to the
//! data's own spectrum: the RMS of what the four-point prediction misses
//! at the data's own level and the one above, carried on by their ratio. The noise
//! is a hash of the level and the sample: the same terrain every frame and
//! every run. Only what is drawn changes; the tiles stay the data's.

use std::ops::Range;

use crate::clipmap::TerrainSamples;
use crate::surface::Surface;

/// Synthesized detail: octaves below the terrain's finest level, and the
/// noise: what the four-point prediction misses at the data's own level
/// (RMS, metres) and its ratio from one octave to the next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detail {
    /// Levels synthesized below the terrain's finest (`detail_octaves`):
    /// an accuracy knob, each octave halving the drawn sample spacing.
    pub octaves: u32,
    pub sigma_m: f64,
    pub ratio: f64,
    /// The tile level whose samples are the data's own.
    pub data_level: u8,
}

impl Detail {
    pub const DEFAULT_OCTAVES: u32 = 2;
    pub const MAX_OCTAVES: u32 = 6;

    /// The noise's RMS at tile level `level`, below the data's.
    pub fn sigma_at(&self, level: u8) -> f64 {
        self.sigma_m * self.ratio.powi(i32::from(level) - i32::from(self.data_level))
    }

    /// Fits the noise to `terrain`'s spectrum round corner sample `at` of
    /// `data_level`, the level whose samples are the data's own: the
    /// four-point prediction's residual RMS there and at the level above
    /// (blocks of 64 x 64), and the ratio between them (bounded to
    /// 0.25-0.75, a fractal's range) that carries it on to finer octaves.
    /// None while the data is not ready.
    pub fn fit(terrain: &dyn TerrainSamples, at: (i64, i64), data_level: u8, octaves: u32) -> Option<Self> {
        let finest = data_level;
        if finest < 2 {
            return None;
        }
        let residual = |level: u8, (x, y): (i64, i64)| -> Option<f64> {
            const SIDE: i64 = 64;
            let (x0, y0) = (x - SIDE / 2, y - SIDE / 2);
            let fine = terrain.heights(level, x0..x0 + SIDE, y0..y0 + SIDE)?;
            let (cx, cy) = (x0.div_euclid(2) - 2, y0.div_euclid(2) - 2);
            let coarse = Block::read(terrain, level - 1, cx..cx + SIDE / 2 + 5, cy..cy + SIDE / 2 + 5)?;
            let predicted = coarse.subdivide(x0..x0 + SIDE, y0..y0 + SIDE);
            let (sum, n) = fine
                .iter()
                .zip(&predicted)
                .filter(|(a, b)| a.is_finite() && b.is_finite())
                .fold((0.0, 0usize), |(s, n), (a, b)| (s + f64::from(a - b).powi(2), n + 1));
            (n > 0).then(|| (sum / n as f64).sqrt())
        };
        let fine = residual(finest, at)?;
        let above = residual(finest - 1, (at.0.div_euclid(2), at.1.div_euclid(2)))?;
        let ratio = if above > 1e-9 { (fine / above).clamp(0.25, 0.75) } else { 0.5 };
        Some(Self { octaves, sigma_m: fine, ratio, data_level })
    }
}

/// A block of samples of one level: `xs` x `ys`, row-major.
struct Block {
    xs: Range<i64>,
    ys: Range<i64>,
    values: Vec<f32>,
}

impl Block {
    fn read(terrain: &dyn TerrainSamples, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Self> {
        let values = terrain.heights(level, xs.clone(), ys.clone())?;
        Some(Self { xs, ys, values })
    }

    fn at(&self, x: i64, y: i64) -> f32 {
        let cols = (self.xs.end - self.xs.start) as usize;
        self.values[(y - self.ys.start) as usize * cols + (x - self.xs.start) as usize]
    }

    /// The next finer level's samples `xs` x `ys` by the four-point scheme,
    /// rows first, then columns (the block must reach two coarse samples
    /// past each side).
    fn subdivide(&self, xs: Range<i64>, ys: Range<i64>) -> Vec<f32> {
        let along = |g: i64, get: &dyn Fn(i64) -> f32| -> f32 {
            let k = g.div_euclid(2);
            if g.rem_euclid(2) == 0 {
                return get(k);
            }
            let taps = [get(k - 1), get(k), get(k + 1), get(k + 2)];
            let v = (-taps[0] + 9.0 * taps[1] + 9.0 * taps[2] - taps[3]) / 16.0;
            if v.is_finite() {
                v
            } else {
                // Beside nodata: the nearer of the two neighbours that exist.
                [taps[1], taps[2]].into_iter().find(|t| t.is_finite()).unwrap_or(f32::NAN)
            }
        };
        // Rows of the coarse block refined along x, then down the columns.
        let rows: Vec<Vec<f32>> =
            self.ys.clone().map(|cy| xs.clone().map(|gx| along(gx, &|cx| self.at(cx, cy))).collect()).collect();
        let mut out = Vec::with_capacity(xs.clone().count() * ys.clone().count());
        for gy in ys {
            for (i, _) in xs.clone().enumerate() {
                out.push(along(gy, &|cy| rows[(cy - self.ys.start) as usize][i]));
            }
        }
        out
    }
}

/// The terrain with synthesized detail below its finest level.
pub struct Detailed<'a> {
    inner: &'a dyn TerrainSamples,
    surface: &'a Surface,
    detail: Detail,
}

impl<'a> Detailed<'a> {
    /// `inner` with every level below the data's own (`detail.data_level`)
    /// synthesized, down to `detail.octaves` below it.
    pub fn new(inner: &'a dyn TerrainSamples, surface: &'a Surface, detail: Detail) -> Self {
        Self { inner, surface, detail }
    }
}

/// A standard normal deviate from a hash of (level, x, y): splitmix64,
/// then Box and Muller.
fn gaussian(level: u8, x: i64, y: i64) -> f64 {
    let mix = |mut z: u64| {
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    let seed = mix(u64::from(level) ^ mix(x as u64 ^ mix((y as u64).wrapping_add(0x9e37_79b9_7f4a_7c15))));
    let (a, b) = (mix(seed), mix(seed ^ 0x5851_f42d_4c95_7f2d));
    let u1 = ((a >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = (b >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

impl TerrainSamples for Detailed<'_> {
    fn heights(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<f32>> {
        if level <= self.detail.data_level {
            return self.inner.heights(level, xs, ys);
        }
        // The coarser level's samples two past each side, then refined.
        let (cx, cy) = (xs.start.div_euclid(2) - 2, ys.start.div_euclid(2) - 2);
        let (cx1, cy1) = ((xs.end - 1).div_euclid(2) + 3, (ys.end - 1).div_euclid(2) + 3);
        let coarse = Block { xs: cx..cx1, ys: cy..cy1, values: self.heights(level - 1, cx..cx1, cy..cy1)? };
        let mut out = coarse.subdivide(xs.clone(), ys.clone());
        let sigma = self.detail.sigma_at(level);
        // Noise keyed by the sample's place round the planet, so a wrapped
        // index draws the same.
        let turn = self.surface.is_planet().then(|| self.surface.revolution(level));
        for (k, v) in out.iter_mut().enumerate() {
            let cols = (xs.end - xs.start) as usize;
            let (gx, gy) = (xs.start + (k % cols) as i64, ys.start + (k / cols) as i64);
            let gx = turn.map_or(gx, |t| gx.rem_euclid(t));
            *v += (sigma * gaussian(level, gx, gy)) as f32;
        }
        Some(out)
    }

    fn colors(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<[u8; 4]>> {
        self.inner.colors(level, xs, ys)
    }

    fn max_level(&self) -> u8 {
        let synthesized =
            (u32::from(self.detail.data_level) + self.detail.octaves).min(u32::from(relief_source::MAX_LEVEL - 1));
        (synthesized as u8).max(self.inner.max_level())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a test")]

    use super::*;
    use relief_source::TileGrid;

    /// A cubic surface in sample units of level 0 of the planet's grid.
    struct Cubic;

    fn cubic(level: u8, x: i64, y: i64) -> f64 {
        let s = f64::from(1u32 << level);
        let (u, v) = (x as f64 / s, y as f64 / s);
        0.01 * u * u * u - 0.3 * u * v + 2.0 * v * v + 5.0 * v
    }

    impl TerrainSamples for Cubic {
        fn heights(&self, level: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<f32>> {
            Some(ys.flat_map(|y| xs.clone().map(move |x| cubic(level, x, y) as f32)).collect())
        }
        fn colors(&self, _: u8, xs: Range<i64>, ys: Range<i64>) -> Option<Vec<[u8; 4]>> {
            Some(vec![[0; 4]; xs.count() * ys.count()])
        }
        fn max_level(&self) -> u8 {
            3
        }
    }

    #[test]
    fn without_noise_the_subdivision_reproduces_a_cubic() {
        let surface = Surface::new(TileGrid::geodetic(256).unwrap());
        let detail = Detail { octaves: 2, sigma_m: 0.0, ratio: 0.5, data_level: 3 };
        let d = Detailed::new(&Cubic, &surface, detail);
        assert_eq!(d.max_level(), 5);
        for level in [4u8, 5] {
            let got = d.heights(level, 37..53, -9..4).unwrap();
            let want = Cubic.heights(level, 37..53, -9..4).unwrap();
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).abs() <= 1e-3 * w.abs().max(1.0), "level {level}: {g} against {w}");
            }
        }
    }

    #[test]
    fn the_noise_is_the_same_every_time_and_has_its_rms() {
        let surface = Surface::new(TileGrid::geodetic(256).unwrap());
        let detail = Detail { octaves: 1, sigma_m: 4.0, ratio: 0.5, data_level: 3 };
        let d = Detailed::new(&Cubic, &surface, detail);
        let a = d.heights(4, 0..100, 0..100).unwrap();
        assert_eq!(a, d.heights(4, 0..100, 0..100).unwrap());
        let plain =
            Detailed::new(&Cubic, &surface, Detail { sigma_m: 0.0, ..detail }).heights(4, 0..100, 0..100).unwrap();
        let rms = (a.iter().zip(&plain).map(|(x, y)| f64::from(x - y).powi(2)).sum::<f64>() / 1e4).sqrt();
        assert!((rms - 2.0).abs() < 0.1, "noise RMS {rms}");
        // A block overlapping another gives the same samples where they meet.
        let b = d.heights(4, 50..60, 50..60).unwrap();
        assert_eq!(b[0], a[50 * 100 + 50]);
    }

    #[test]
    fn the_fit_of_a_smooth_cubic_is_no_noise() {
        let fit = Detail::fit(&Cubic, (40, 20), 3, 2).unwrap();
        assert!(fit.sigma_m < 1e-3, "{fit:?}");
    }
}
