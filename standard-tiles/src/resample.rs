//! relief's geodetic tiles (EPSG:4326) read at the pixel centres of a Web
//! Mercator XYZ tile: heights bilinear on the corner lattice, colour
//! bilinear on the texel-centred lattice, weighted by alpha.
//!
//! Pixel (c, r) reads at the lon/lat of its centre. Longitude and latitude
//! are separable on both grids, so each pixel column and each pixel row
//! resolves once to the two samples it blends (their tile column or row and
//! their index in it); a pixel then reads the (up to) four tiles those name.
//! A sample with weight 0 is not read, so a pixel on a sample reads that
//! sample alone.

use std::collections::HashMap;
use std::sync::Arc;

use relief_source::{ColorTile, HeightTile, MAX_LEVEL, Payload, SampleKind, TileGrid, TileKey};

use crate::xyz::{XYZ_TILE_SIZE, xyz_pixel_lonlat};

/// One sample along one axis: the slot of its tile column (or row) in the
/// plan, and its index in that tile's lattice.
#[derive(Debug, Clone, Copy)]
struct Tap {
    slot: usize,
    index: usize,
}

/// The two samples a pixel column (or row) blends and their weights; a
/// second weight of 0 means the pixel stands on the first sample.
#[derive(Debug, Clone, Copy)]
struct AxisTaps {
    taps: [Tap; 2],
    weights: [f64; 2],
}

/// How one XYZ tile's pixels read one geodetic level: the two samples of
/// each pixel column and row, and the tile columns and rows they lie in.
struct Plan {
    level: u8,
    /// Tile columns, west to east from the XYZ tile's west edge (a column
    /// across the antimeridian comes after the last).
    cols: Vec<u32>,
    /// Tile rows, north to south.
    rows: Vec<u32>,
    xs: Vec<AxisTaps>,
    ys: Vec<AxisTaps>,
}

/// The slot of `tile` in `slots`, added at the end if new.
fn slot_of(slots: &mut Vec<u32>, tile: u32) -> usize {
    slots.iter().position(|&t| t == tile).unwrap_or_else(|| {
        slots.push(tile);
        slots.len() - 1
    })
}

impl Plan {
    /// None on a projected grid: XYZ tiles are lon/lat here, and its
    /// samples are not.
    fn new(grid: &TileGrid, level: u8, z: u8, x: u32, y: u32, kind: SampleKind) -> Option<Self> {
        if !grid.is_geodetic() {
            return None;
        }
        let level = level.min(MAX_LEVEL);
        let n = i64::from(grid.tile_size());
        let (total_x, total_y) = grid.samples_at(level);
        // Where a pixel reads: heights at its north-west corner, where
        // MapLibre GL JS and deck.gl put a raster-dem pixel (pixel i of a
        // tile at i / 256 of it); colours at its centre, as a raster layer
        // draws a pixel over its area.
        let half = |p: usize| match kind {
            SampleKind::Corner => p as f64,
            SampleKind::TexelWithBorder => p as f64 + 0.5,
        };
        // Global sample index -> (tile, index in the tile's lattice).
        let column = |g: i64| -> (u32, usize) {
            match kind {
                // The grid's own rule: a sample on a tile edge is read from
                // the tile to its east, and columns wrap.
                SampleKind::Corner => {
                    let (key, i, _) = grid.corner_sample(level, g, 0);
                    (key.x, i)
                }
                SampleKind::TexelWithBorder => {
                    let t = g.rem_euclid(total_x);
                    ((t / n) as u32, (t % n) as usize + 1)
                }
            }
        };
        // Mercator latitudes stop short of the poles, so corner rows never
        // fold over one; a texel row past a pole (a coarse level, a tile
        // touching 85.05) repeats the polar row.
        let row = |g: i64| -> (u32, usize) {
            match kind {
                SampleKind::Corner => {
                    let (key, _, j) = grid.corner_sample(level, 0, g.clamp(0, total_y));
                    (key.y, j)
                }
                SampleKind::TexelWithBorder => {
                    let t = g.clamp(0, total_y - 1);
                    ((t / n) as u32, (t % n) as usize + 1)
                }
            }
        };
        let offset = match kind {
            SampleKind::Corner => 0.0,
            SampleKind::TexelWithBorder => 0.5,
        };
        let taps = |g: f64, slots: &mut Vec<u32>, locate: &dyn Fn(i64) -> (u32, usize)| {
            let u = g - offset;
            let first = u.floor();
            let w = u - first;
            let (tile, index) = locate(first as i64);
            let a = Tap { slot: slot_of(slots, tile), index };
            let b = if w > 0.0 {
                let (tile, index) = locate(first as i64 + 1);
                Tap { slot: slot_of(slots, tile), index }
            } else {
                a
            };
            AxisTaps { taps: [a, b], weights: [1.0 - w, w] }
        };
        let (mut cols, mut rows) = (Vec::new(), Vec::new());
        let xs = (0..XYZ_TILE_SIZE)
            .map(|c| {
                let (lon, lat) = xyz_pixel_lonlat(z, x, y, half(c), 0.5);
                taps(grid.sample_coords(level, lon, lat).0, &mut cols, &column)
            })
            .collect();
        let ys = (0..XYZ_TILE_SIZE)
            .map(|r| {
                let (lon, lat) = xyz_pixel_lonlat(z, x, y, 0.5, half(r));
                taps(grid.sample_coords(level, lon, lat).1, &mut rows, &row)
            })
            .collect();
        Some(Self { level, cols, rows, xs, ys })
    }

    /// The tiles the plan reads, row by row from the north.
    fn keys(&self) -> Vec<TileKey> {
        self.rows.iter().flat_map(|&ty| self.cols.iter().map(move |&tx| TileKey::new(self.level, tx, ty))).collect()
    }

    /// The tiles as a table indexed `row_slot * cols + col_slot`; a tile
    /// missing, or not the payload `accept` takes, is None.
    fn table<'a, T>(
        &self,
        tiles: &'a [(TileKey, Option<Arc<Payload>>)],
        accept: impl Fn(&'a Payload) -> Option<&'a T>,
    ) -> Vec<Option<&'a T>> {
        let by_key: HashMap<TileKey, &'a Payload> =
            tiles.iter().filter_map(|(key, payload)| payload.as_deref().map(|p| (*key, p))).collect();
        self.keys().iter().map(|key| by_key.get(key).and_then(|p| accept(p))).collect()
    }

    /// Calls `read` with each pixel, row-major from the north-west, and the
    /// samples it blends: (row slot, col slot, i, j, weight), weight > 0.
    fn for_each_pixel(&self, mut read: impl FnMut(usize, &mut dyn Iterator<Item = (usize, usize, usize, f64)>)) {
        let ncols = self.cols.len();
        for (r, ys) in self.ys.iter().enumerate() {
            for (c, xs) in self.xs.iter().enumerate() {
                let mut samples = ys.taps.iter().zip(ys.weights).filter(|(_, w)| *w > 0.0).flat_map(|(ty, wy)| {
                    xs.taps
                        .iter()
                        .zip(xs.weights)
                        .filter(|(_, w)| *w > 0.0)
                        .map(move |(tx, wx)| (ty.slot * ncols + tx.slot, tx.index, ty.index, wy * wx))
                });
                read(r * XYZ_TILE_SIZE + c, &mut samples);
            }
        }
    }
}

/// The geodetic tiles (at `level`) whose samples an XYZ tile's pixels read
/// (for a batch fetch): row by row from the north, each row west to east
/// from the XYZ tile's west edge. `kind` is the lattice of the payload:
/// `Corner` for heights, `TexelWithBorder` for colour. Empty on a projected
/// grid. A level past relief's `MAX_LEVEL` reads `MAX_LEVEL`.
pub fn source_keys(grid: &TileGrid, level: u8, z: u8, x: u32, y: u32, kind: SampleKind) -> Vec<TileKey> {
    Plan::new(grid, level, z, x, y, kind).map(|plan| plan.keys()).unwrap_or_default()
}

/// 256 x 256 heights (metres, row-major from the north-west), bilinear on
/// the corner lattice at each pixel's north-west corner (where MapLibre GL
/// JS and deck.gl read a raster-dem pixel: pixel i of a tile at i / 256 of
/// its width); NaN where any sample it weighs
/// is NaN or its tile is missing. `tiles`: the payloads of
/// [`source_keys`] with `SampleKind::Corner` (found by key; None = not
/// available). A payload that is not a height tile of N+1 samples a side
/// counts as missing. All NaN on a projected grid.
pub fn resample_heights(
    grid: &TileGrid,
    level: u8,
    z: u8,
    x: u32,
    y: u32,
    tiles: &[(TileKey, Option<Arc<Payload>>)],
) -> Vec<f32> {
    let mut out = vec![f32::NAN; XYZ_TILE_SIZE * XYZ_TILE_SIZE];
    let Some(plan) = Plan::new(grid, level, z, x, y, SampleKind::Corner) else {
        return out;
    };
    let side = grid.tile_size() as usize + 1;
    let table = plan.table(tiles, |p| match p {
        Payload::Height(t @ HeightTile { size, heights }) if *size == side && heights.len() == side * side => Some(t),
        _ => None,
    });
    plan.for_each_pixel(|pixel, samples| {
        let mut h = 0.0;
        for (tile, i, j, w) in samples {
            match table[tile] {
                Some(t) => h += w * f64::from(t.get(i, j)),
                None => {
                    h = f64::NAN;
                    break;
                }
            }
        }
        out[pixel] = h as f32;
    });
    out
}

/// 256 x 256 straight RGBA8 (row-major from the north-west), bilinear on the
/// texel lattice at each pixel centre, weighting colour by alpha (the mean
/// of premultiplied colour, handed back straight); a missing tile reads as
/// transparent texels. `tiles`: the payloads of [`source_keys`] with
/// `SampleKind::TexelWithBorder` (found by key; None = not available). A
/// payload that is not a colour tile of N+2 texels a side counts as
/// missing. All transparent on a projected grid.
pub fn resample_colors(
    grid: &TileGrid,
    level: u8,
    z: u8,
    x: u32,
    y: u32,
    tiles: &[(TileKey, Option<Arc<Payload>>)],
) -> Vec<[u8; 4]> {
    let mut out = vec![[0u8; 4]; XYZ_TILE_SIZE * XYZ_TILE_SIZE];
    let Some(plan) = Plan::new(grid, level, z, x, y, SampleKind::TexelWithBorder) else {
        return out;
    };
    let side = grid.tile_size() as usize + 2;
    let table = plan.table(tiles, |p| match p {
        Payload::Color(t @ ColorTile { size, rgba }) if *size == side && rgba.len() == side * side * 4 => Some(t),
        _ => None,
    });
    plan.for_each_pixel(|pixel, samples| {
        // Premultiplied sums: alpha, and colour times alpha.
        let (mut alpha, mut rgb) = (0.0, [0.0f64; 3]);
        for (tile, i, j, w) in samples {
            let Some(t) = table[tile] else { continue };
            let at = (j * side + i) * 4;
            let texel = &t.rgba[at..at + 4];
            let wa = w * f64::from(texel[3]);
            alpha += wa;
            for (sum, c) in rgb.iter_mut().zip(texel) {
                *sum += wa * f64::from(*c);
            }
        }
        let a = alpha.round().clamp(0.0, 255.0) as u8;
        if a > 0 {
            let straight = rgb.map(|c| (c / alpha).round().clamp(0.0, 255.0) as u8);
            out[pixel] = [straight[0], straight[1], straight[2], a];
        }
    });
    out
}

#[cfg(test)]
mod tests;
