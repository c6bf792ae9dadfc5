//! Tile grids, tile keys and the sample convention. This is the one place
//! where "which point does sample (i, j) of tile k stand for" is written.
//!
//! The convention (from DESIGN.md):
//! - Tiles are numbered from the north-west: `x` grows east, `y` grows south.
//! - A height tile has (N+1) x (N+1) corner-aligned samples. Its edge rows and
//!   columns are shared with its neighbours, so seams agree bit for bit.
//! - A colour (or mask) tile has N x N texel-centred samples plus a one-texel
//!   border copied from the neighbours: (N+2) x (N+2) in all.
//!
//! Sample positions are computed from a *global* sample index at each level
//! (`min + index * step`), never from a tile's own corner, so two tiles that
//! share a sample compute the very same f64 for it.

use std::fmt;

/// The finest level any grid supports. Level 30 would overflow the u32 key
/// arithmetic of the geodetic grid's 2^(l+1) columns.
pub const MAX_LEVEL: u8 = 24;

/// How far from its CRS's origin a projected grid may reach, in CRS units.
const FARTHEST: f64 = 1.0e9;

/// A tile: its level and its column and row, counted from the north-west.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileKey {
    pub level: u8,
    pub x: u32,
    pub y: u32,
}

impl TileKey {
    pub const fn new(level: u8, x: u32, y: u32) -> Self {
        Self { level, x, y }
    }

    /// The tile one level coarser that contains this one.
    pub fn parent(self) -> Option<Self> {
        (self.level > 0).then(|| Self::new(self.level - 1, self.x / 2, self.y / 2))
    }
}

impl fmt::Display for TileKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}/{}", self.level, self.x, self.y)
    }
}

/// An axis-aligned extent in a grid's CRS (degrees or metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extent {
    pub min_x: f64,
    pub min_y: f64,
    pub max_x: f64,
    pub max_y: f64,
}

impl Extent {
    pub const fn new(min_x: f64, min_y: f64, max_x: f64, max_y: f64) -> Self {
        Self { min_x, min_y, max_x, max_y }
    }

    pub fn width(&self) -> f64 {
        self.max_x - self.min_x
    }

    pub fn height(&self) -> f64 {
        self.max_y - self.min_y
    }

    /// Finite, with max >= min: a point or a line is a valid extent.
    pub fn is_valid(&self) -> bool {
        [self.min_x, self.min_y, self.max_x, self.max_y].iter().all(|v| v.is_finite())
            && self.max_x >= self.min_x
            && self.max_y >= self.min_y
    }

    pub fn is_empty(&self) -> bool {
        !(self.max_x > self.min_x && self.max_y > self.min_y)
    }

    /// True when the two extents share interior area (touching edges do not count).
    pub fn overlaps(&self, other: &Self) -> bool {
        self.min_x < other.max_x && other.min_x < self.max_x && self.min_y < other.max_y && other.min_y < self.max_y
    }

    /// True when the extents overlap or touch.
    pub fn touches(&self, other: &Self) -> bool {
        self.min_x <= other.max_x && other.min_x <= self.max_x && self.min_y <= other.max_y && other.min_y <= self.max_y
    }

    pub fn contains(&self, x: f64, y: f64) -> bool {
        x >= self.min_x && x <= self.max_x && y >= self.min_y && y <= self.max_y
    }

    #[must_use]
    pub fn union(&self, other: &Self) -> Self {
        Self::new(
            self.min_x.min(other.min_x),
            self.min_y.min(other.min_y),
            self.max_x.max(other.max_x),
            self.max_y.max(other.max_y),
        )
    }

    pub fn intersection(&self, other: &Self) -> Option<Self> {
        let e = Self::new(
            self.min_x.max(other.min_x),
            self.min_y.max(other.min_y),
            self.max_x.min(other.max_x),
            self.max_y.min(other.max_y),
        );
        (!e.is_empty()).then_some(e)
    }

    /// Grows the extent by `dx` and `dy` on each side.
    #[must_use]
    pub fn dilate(&self, dx: f64, dy: f64) -> Self {
        Self::new(self.min_x - dx, self.min_y - dy, self.max_x + dx, self.max_y + dy)
    }
}

/// A local scene's grid: square tiles in a projected CRS, one tile at level 0.
#[derive(Debug, Clone, PartialEq)]
pub struct ProjectedGrid {
    /// The CRS as the manifest names it, for example "EPSG:32612".
    pub crs: String,
    /// South-west corner of the level-0 tile, in CRS units (metres).
    pub min_x: f64,
    pub min_y: f64,
    /// Side of the level-0 tile, in CRS units.
    pub size: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub enum GridKind {
    /// The planet: level l has 2^(l+1) x 2^l tiles over lon [-180, 180] x lat [-90, 90].
    Geodetic,
    /// A local scene in a projected CRS: level l has 2^l x 2^l tiles.
    Projected(ProjectedGrid),
}

/// Which sample lattice of a tile: heights (corner-aligned) or colour
/// (texel-centred with a one-texel border).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleKind {
    Corner,
    TexelWithBorder,
}

/// The positions of a tile's samples: sample (i, j) stands for
/// `(x(i), y(j))`, with `i` growing east and `j` growing south.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lattice {
    pub cols: usize,
    pub rows: usize,
    /// Global index of sample 0 at this level, plus 0.5 for texel centres.
    first_x: f64,
    first_y: f64,
    origin_x: f64,
    origin_y: f64,
    pub step_x: f64,
    pub step_y: f64,
}

impl Lattice {
    pub fn x(&self, i: usize) -> f64 {
        self.origin_x + (self.first_x + i as f64) * self.step_x
    }

    pub fn y(&self, j: usize) -> f64 {
        self.origin_y - (self.first_y + j as f64) * self.step_y
    }
}

/// A neighbouring tile and whether it lies across a pole (then it is turned
/// by 180 degrees relative to the tile it neighbours).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Neighbour {
    pub key: TileKey,
    pub across_pole: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    North,
    South,
    East,
    West,
}

/// A scene's tile grid: its kind and its tile size N.
#[derive(Debug, Clone, PartialEq)]
pub struct TileGrid {
    pub kind: GridKind,
    tile_size: u32,
}

impl TileGrid {
    pub const DEFAULT_TILE_SIZE: u32 = 256;

    /// A grid with tiles of `tile_size` (N) samples a side. N must be a power
    /// of two from 16 to 4096, so that sample steps are exact in f64.
    pub fn new(kind: GridKind, tile_size: u32) -> Result<Self, String> {
        if !(16..=4096).contains(&tile_size) || !tile_size.is_power_of_two() {
            return Err(format!("tile size {tile_size} must be a power of two from 16 to 4096"));
        }
        if let GridKind::Projected(p) = &kind {
            if !(p.size.is_finite() && p.size > 0.0 && p.min_x.is_finite() && p.min_y.is_finite()) {
                return Err(format!("projected grid extent is not finite and positive: {p:?}"));
            }
            // Positions are f64 in CRS units: far enough from the CRS's
            // origin they no longer resolve the grid's own samples (at 1e15
            // they hold to 0.125 units). No map of this planet reaches 1e9
            // units (it is some 4e7 m round, 1.3e8 feet); refuse such
            // coordinates, and any where a small grid's samples would blur,
            // rather than serve collapsed tiles.
            let largest =
                [p.min_x, p.min_y, p.min_x + p.size, p.min_y + p.size].into_iter().fold(0.0, |m, v| v.abs().max(m));
            let resolution = largest * f64::EPSILON;
            let spacing = p.size / f64::from(tile_size);
            if largest > FARTHEST {
                return Err(format!(
                    "projected grid coordinates reach {largest:.1e} CRS units, farther from the CRS's origin than \
                     any map of this planet ({FARTHEST:e}), where f64 holds positions only to {resolution:.1e} \
                     units: refused"
                ));
            }
            if resolution > spacing / 1000.0 {
                return Err(format!(
                    "projected grid coordinates reach {largest:.1e} CRS units, where f64 holds positions only to \
                     {resolution:.1e} units, coarser than a thousandth of the grid's sample spacing \
                     ({spacing:e}): refused"
                ));
            }
        }
        Ok(Self { kind, tile_size })
    }

    pub fn geodetic(tile_size: u32) -> Result<Self, String> {
        Self::new(GridKind::Geodetic, tile_size)
    }

    pub fn tile_size(&self) -> u32 {
        self.tile_size
    }

    pub fn is_geodetic(&self) -> bool {
        matches!(self.kind, GridKind::Geodetic)
    }

    /// The grid's CRS as a string PROJ and GDAL understand.
    pub fn crs(&self) -> &str {
        match &self.kind {
            GridKind::Geodetic => "EPSG:4326",
            GridKind::Projected(p) => &p.crs,
        }
    }

    /// The whole area the grid covers. Samples are counted from its
    /// north-west corner, so a projected grid's south edge is where they
    /// end, `size` south of its north edge (within a rounding of `min_y`).
    pub fn extent(&self) -> Extent {
        match &self.kind {
            GridKind::Geodetic => Extent::new(-180.0, -90.0, 180.0, 90.0),
            GridKind::Projected(p) => {
                let max_y = p.min_y + p.size;
                Extent::new(p.min_x, max_y - p.size, p.min_x + p.size, max_y)
            }
        }
    }

    /// The grid's sides in CRS units, east and south: the lengths every
    /// span and step divides (never `max - min` of the extent, which
    /// rounds differently east and south far from the CRS's origin).
    fn sides(&self) -> (f64, f64) {
        match &self.kind {
            GridKind::Geodetic => (360.0, 180.0),
            GridKind::Projected(p) => (p.size, p.size),
        }
    }

    /// Columns and rows of tiles at `level`.
    pub fn tiles_at(&self, level: u8) -> (u32, u32) {
        let n = 1u32 << level.min(MAX_LEVEL);
        match self.kind {
            GridKind::Geodetic => (2 * n, n),
            GridKind::Projected(_) => (n, n),
        }
    }

    /// Size of one tile at `level`, in CRS units: (width, height).
    pub fn tile_span(&self, level: u8) -> (f64, f64) {
        let (cols, rows) = self.tiles_at(level);
        let (width, height) = self.sides();
        (width / f64::from(cols), height / f64::from(rows))
    }

    /// Cells of the global corner-sample lattice at `level` across and down
    /// the grid (tiles times N); samples run from 0 to these, inclusive.
    pub fn samples_at(&self, level: u8) -> (i64, i64) {
        let (cols, rows) = self.tiles_at(level);
        let n = i64::from(self.tile_size);
        (i64::from(cols) * n, i64::from(rows) * n)
    }

    /// Spacing of the corner samples at `level`, in CRS units (the same
    /// east and south on both kinds of grid).
    pub fn sample_step(&self, level: u8) -> f64 {
        self.tile_span(level).0 / f64::from(self.tile_size)
    }

    /// The first level whose samples are at least as fine as `spacing` (CRS
    /// units): where data of that spacing has its own samples; at most
    /// `MAX_LEVEL - 1`.
    pub fn level_for_spacing(&self, spacing: f64) -> u8 {
        (0..MAX_LEVEL - 1).find(|&l| self.sample_step(l) <= spacing).unwrap_or(MAX_LEVEL - 1)
    }

    /// The point of global corner sample (gx, gy) at `level` (gx east, gy
    /// south of the grid's north-west corner; any integer).
    pub fn sample_point(&self, level: u8, gx: i64, gy: i64) -> (f64, f64) {
        let e = self.extent();
        let s = self.sample_step(level);
        (e.min_x + gx as f64 * s, e.max_y - gy as f64 * s)
    }

    /// Point (x, y) in continuous corner-sample coordinates at `level`.
    pub fn sample_coords(&self, level: u8, x: f64, y: f64) -> (f64, f64) {
        let e = self.extent();
        let s = self.sample_step(level);
        ((x - e.min_x) / s, (e.max_y - y) / s)
    }

    pub fn contains_key(&self, key: TileKey) -> bool {
        let (cols, rows) = self.tiles_at(key.level);
        key.level <= MAX_LEVEL && key.x < cols && key.y < rows
    }

    /// The area a tile covers: its N x N core, without the colour border.
    pub fn tile_extent(&self, key: TileKey) -> Extent {
        let e = self.extent();
        let (w, h) = self.tile_span(key.level);
        Extent::new(
            e.min_x + f64::from(key.x) * w,
            e.max_y - f64::from(key.y + 1) * h,
            e.min_x + f64::from(key.x + 1) * w,
            e.max_y - f64::from(key.y) * h,
        )
    }

    /// The tile and in-tile index (i east, j south) holding global corner
    /// sample (gx, gy) at `level`. On the geodetic grid columns wrap and rows
    /// past a pole continue half way round the planet; a projected grid
    /// repeats its edge samples. A sample on a tile edge is read from the
    /// tile to its south-east unless that is past the grid.
    pub fn corner_sample(&self, level: u8, gx: i64, gy: i64) -> (TileKey, usize, usize) {
        let n = i64::from(self.tile_size);
        let (cols, rows) = self.tiles_at(level);
        let (total_x, total_y) = self.samples_at(level);
        let (mut x, mut y) = (gx, gy);
        match self.kind {
            GridKind::Geodetic => {
                // Fold over the poles (repeatedly, for absurd inputs).
                y = y.rem_euclid(2 * total_y);
                if y > total_y {
                    y = 2 * total_y - y;
                    x += total_x / 2;
                }
                x = x.rem_euclid(total_x);
            }
            GridKind::Projected(_) => {
                x = x.clamp(0, total_x);
                y = y.clamp(0, total_y);
            }
        }
        let tx = (x / n).min(i64::from(cols) - 1);
        let ty = (y / n).min(i64::from(rows) - 1);
        (TileKey::new(level, tx as u32, ty as u32), (x - tx * n) as usize, (y - ty * n) as usize)
    }

    /// The tile at `level` that owns point (x, y). Tiles own [west, east) x
    /// (south, north]; the last column and row also own their closing edge.
    /// On the geodetic grid longitudes wrap, so 180 belongs to column 0.
    /// Returns None for points outside a projected grid or not finite.
    pub fn key_at(&self, level: u8, x: f64, y: f64) -> Option<TileKey> {
        if !x.is_finite() || !y.is_finite() || level > MAX_LEVEL {
            return None;
        }
        let e = self.extent();
        let x = match self.kind {
            GridKind::Geodetic => wrap_longitude(x),
            GridKind::Projected(_) => x,
        };
        if !e.contains(x, y) {
            return None;
        }
        let (cols, rows) = self.tiles_at(level);
        let (w, h) = self.tile_span(level);
        let mut col = (((x - e.min_x) / w).floor() as u32).min(cols - 1);
        let mut row = (((e.max_y - y) / h).floor() as u32).min(rows - 1);
        // The quotient may round across an edge that `tile_extent` puts
        // on the other side: the tile whose extent holds the point wins.
        let west = |col: u32| e.min_x + f64::from(col) * w;
        let north = |row: u32| e.max_y - f64::from(row) * h;
        if col > 0 && x < west(col) {
            col -= 1;
        } else if col + 1 < cols && x >= west(col + 1) {
            col += 1;
        }
        if row > 0 && y > north(row) {
            row -= 1;
        } else if row + 1 < rows && y <= north(row + 1) {
            row += 1;
        }
        Some(TileKey::new(level, col, row))
    }

    /// Every tile at `level` that shares area with `area` (touching edges do
    /// not count), clipped to the grid.
    pub fn keys_overlapping(&self, level: u8, area: &Extent) -> Vec<TileKey> {
        let Some(a) = area.intersection(&self.extent()) else {
            return Vec::new();
        };
        let e = self.extent();
        let (cols, rows) = self.tiles_at(level);
        let (w, h) = self.tile_span(level);
        // One tile more each side than the quotients say (they may round
        // past an edge); the overlap test below keeps exactly the right ones.
        let first_col = (((a.min_x - e.min_x) / w).floor().max(0.0) as u32).saturating_sub(1);
        let last_col = (((a.max_x - e.min_x) / w).ceil() as u32).min(cols - 1);
        let first_row = (((e.max_y - a.max_y) / h).floor().max(0.0) as u32).saturating_sub(1);
        let last_row = (((e.max_y - a.min_y) / h).ceil() as u32).min(rows - 1);
        let mut keys = Vec::new();
        for y in first_row..=last_row {
            for x in first_col..=last_col {
                let key = TileKey::new(level, x, y);
                if self.tile_extent(key).overlaps(&a) {
                    keys.push(key);
                }
            }
        }
        keys
    }

    /// Where the samples of `key` stand, for height (corner) or colour
    /// (texel with border) tiles.
    pub fn lattice(&self, key: TileKey, kind: SampleKind) -> Lattice {
        let n = self.tile_size as usize;
        let e = self.extent();
        let (cols, rows) = self.tiles_at(key.level);
        // The steps of `sample_point`, bit for bit: dividing by a power of
        // two never rounds.
        let (width, height) = self.sides();
        let step_x = width / (f64::from(cols) * f64::from(self.tile_size));
        let step_y = height / (f64::from(rows) * f64::from(self.tile_size));
        let (count, offset) = match kind {
            SampleKind::Corner => (n + 1, 0.0),
            SampleKind::TexelWithBorder => (n + 2, -0.5),
        };
        Lattice {
            cols: count,
            rows: count,
            first_x: f64::from(key.x) * f64::from(self.tile_size) + offset,
            first_y: f64::from(key.y) * f64::from(self.tile_size) + offset,
            origin_x: e.min_x,
            origin_y: e.max_y,
            step_x,
            step_y,
        }
    }

    /// The tile next to `key` in `direction`. On the geodetic grid columns
    /// wrap across the antimeridian, and the row past a pole is the same row
    /// half way round the planet. A projected grid has no tiles past its edge.
    pub fn neighbour(&self, key: TileKey, direction: Direction) -> Option<Neighbour> {
        let (cols, rows) = self.tiles_at(key.level);
        if !self.contains_key(key) {
            return None;
        }
        let plain = |x, y| Some(Neighbour { key: TileKey::new(key.level, x, y), across_pole: false });
        let across_pole =
            || Some(Neighbour { key: TileKey::new(key.level, (key.x + cols / 2) % cols, key.y), across_pole: true });
        match (&self.kind, direction) {
            (GridKind::Geodetic, Direction::East) => plain((key.x + 1) % cols, key.y),
            (GridKind::Geodetic, Direction::West) => plain((key.x + cols - 1) % cols, key.y),
            (GridKind::Geodetic, Direction::North) if key.y == 0 => across_pole(),
            (GridKind::Geodetic, Direction::South) if key.y == rows - 1 => across_pole(),
            (_, Direction::North) if key.y > 0 => plain(key.x, key.y - 1),
            (_, Direction::South) if key.y + 1 < rows => plain(key.x, key.y + 1),
            (_, Direction::East) if key.x + 1 < cols => plain(key.x + 1, key.y),
            (_, Direction::West) if key.x > 0 => plain(key.x - 1, key.y),
            _ => None,
        }
    }
}

/// Wraps a longitude into [-180, 180).
pub fn wrap_longitude(lon: f64) -> f64 {
    let wrapped = (lon + 180.0).rem_euclid(360.0) - 180.0;
    // rem_euclid can return 360 for tiny negative inputs.
    if wrapped >= 180.0 { wrapped - 360.0 } else { wrapped }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn grids() -> Vec<TileGrid> {
        vec![
            TileGrid::geodetic(256).unwrap(),
            TileGrid::new(
                GridKind::Projected(ProjectedGrid {
                    crs: "EPSG:26912".into(),
                    min_x: 420_000.0,
                    min_y: 5_090_000.0,
                    size: 4096.0 * 3.0,
                }),
                64,
            )
            .unwrap(),
        ]
    }

    #[test]
    fn each_level_covers_the_grid_exactly_without_overlap_or_gap() {
        for grid in grids() {
            let e = grid.extent();
            for level in 0..=8u8 {
                let (cols, rows) = grid.tiles_at(level);
                let mut area = 0.0;
                for y in 0..rows {
                    for x in 0..cols {
                        let t = grid.tile_extent(TileKey::new(level, x, y));
                        area += t.width() * t.height();
                        // Shared edges are bit-identical: no gap, no overlap.
                        if x + 1 < cols {
                            assert_eq!(t.max_x, grid.tile_extent(TileKey::new(level, x + 1, y)).min_x);
                        } else {
                            assert_eq!(t.max_x, e.max_x);
                        }
                        if y + 1 < rows {
                            assert_eq!(t.min_y, grid.tile_extent(TileKey::new(level, x, y + 1)).max_y);
                        } else {
                            assert_eq!(t.min_y, e.min_y);
                        }
                        if x == 0 {
                            assert_eq!(t.min_x, e.min_x);
                        }
                        if y == 0 {
                            assert_eq!(t.max_y, e.max_y);
                        }
                    }
                }
                let rel = (area - e.width() * e.height()).abs() / (e.width() * e.height());
                assert!(rel < 1e-12, "level {level}: area off by {rel}");
            }
        }
    }

    #[test]
    fn geodetic_levels_have_two_to_one_tiles() {
        let grid = TileGrid::geodetic(256).unwrap();
        assert_eq!(grid.tiles_at(0), (2, 1));
        assert_eq!(grid.tiles_at(3), (16, 8));
        assert_eq!(grid.tile_extent(TileKey::new(0, 0, 0)), Extent::new(-180.0, -90.0, 0.0, 90.0));
    }

    #[test]
    fn shared_edge_samples_agree_bit_for_bit() {
        for grid in grids() {
            let n = grid.tile_size() as usize;
            for level in [1u8, 3, 7] {
                let (cols, rows) = grid.tiles_at(level);
                let (x, y) = (cols / 2 - 1, rows.saturating_sub(1) / 2);
                let a = grid.lattice(TileKey::new(level, x, y), SampleKind::Corner);
                let east = grid.lattice(TileKey::new(level, x + 1, y), SampleKind::Corner);
                assert_eq!(a.x(n), east.x(0));
                if y + 1 < rows {
                    let south = grid.lattice(TileKey::new(level, x, y + 1), SampleKind::Corner);
                    assert_eq!(a.y(n), south.y(0));
                }
                // Texel border of one tile = first core texel of the next.
                let ca = grid.lattice(TileKey::new(level, x, y), SampleKind::TexelWithBorder);
                let ce = grid.lattice(TileKey::new(level, x + 1, y), SampleKind::TexelWithBorder);
                assert_eq!(ca.x(n + 1), ce.x(1));
                assert_eq!(ca.x(n), ce.x(0));
            }
        }
    }

    #[test]
    fn lattices_match_tile_extents() {
        let grid = TileGrid::geodetic(256).unwrap();
        let key = TileKey::new(5, 40, 9);
        let e = grid.tile_extent(key);
        let l = grid.lattice(key, SampleKind::Corner);
        assert_eq!((l.x(0), l.y(0), l.x(256), l.y(256)), (e.min_x, e.max_y, e.max_x, e.min_y));
        let c = grid.lattice(key, SampleKind::TexelWithBorder);
        assert_eq!(c.cols, 258);
        assert!((c.x(1) - (e.min_x + l.step_x / 2.0)).abs() < 1e-12);
        assert!((c.x(0) - (e.min_x - l.step_x / 2.0)).abs() < 1e-12);
    }

    #[test]
    fn neighbours_wrap_across_the_antimeridian() {
        let grid = TileGrid::geodetic(256).unwrap();
        let (cols, _) = grid.tiles_at(4);
        let east_edge = TileKey::new(4, cols - 1, 5);
        let n = grid.neighbour(east_edge, Direction::East).unwrap();
        assert_eq!(n, Neighbour { key: TileKey::new(4, 0, 5), across_pole: false });
        let w = grid.neighbour(TileKey::new(4, 0, 5), Direction::West).unwrap();
        assert_eq!(w.key, east_edge);
        // The east edge of the last column is the west edge of the first, round the planet.
        assert_eq!(grid.tile_extent(east_edge).max_x - 360.0, grid.tile_extent(n.key).min_x);
    }

    #[test]
    fn neighbours_across_the_poles_are_half_way_round() {
        let grid = TileGrid::geodetic(256).unwrap();
        for level in 0..6u8 {
            let (cols, rows) = grid.tiles_at(level);
            for x in 0..cols {
                let north = grid.neighbour(TileKey::new(level, x, 0), Direction::North).unwrap();
                assert!(north.across_pole);
                assert_eq!(north.key, TileKey::new(level, (x + cols / 2) % cols, 0));
                // Going over the pole twice comes back.
                let back = grid.neighbour(north.key, Direction::North).unwrap();
                assert_eq!(back.key, TileKey::new(level, x, 0));
                let south = grid.neighbour(TileKey::new(level, x, rows - 1), Direction::South).unwrap();
                assert!(south.across_pole);
                assert_eq!(south.key, TileKey::new(level, (x + cols / 2) % cols, rows - 1));
                // The tile over the pole covers the longitudes opposite.
                let here = grid.tile_extent(TileKey::new(level, x, 0));
                let there = grid.tile_extent(north.key);
                let opposite = wrap_longitude(here.min_x + 180.0);
                assert!((there.min_x - opposite).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn projected_grids_stop_at_their_edges() {
        let grid = grids().remove(1);
        assert_eq!(grid.neighbour(TileKey::new(2, 0, 0), Direction::West), None);
        assert_eq!(grid.neighbour(TileKey::new(2, 0, 0), Direction::North), None);
        assert_eq!(grid.neighbour(TileKey::new(2, 3, 3), Direction::East), None);
        assert_eq!(grid.neighbour(TileKey::new(2, 0, 0), Direction::East).unwrap().key, TileKey::new(2, 1, 0));
    }

    #[test]
    fn keys_overlapping_finds_exactly_the_touched_tiles() {
        let grid = TileGrid::geodetic(256).unwrap();
        // Exactly one level-3 tile (22.5 degrees a side).
        let t = grid.tile_extent(TileKey::new(3, 9, 2));
        assert_eq!(grid.keys_overlapping(3, &t), vec![TileKey::new(3, 9, 2)]);
        // A point-sized extent on a corner touches no interior.
        let corner = Extent::new(t.min_x, t.min_y, t.min_x, t.min_y);
        assert!(grid.keys_overlapping(3, &corner).is_empty());
        // Slightly larger: the four tiles round the corner.
        let around = corner.dilate(1e-6, 1e-6);
        assert_eq!(grid.keys_overlapping(3, &around).len(), 4);
    }

    #[test]
    fn poles_and_antimeridian_points_have_one_owner() {
        let grid = TileGrid::geodetic(256).unwrap();
        let (cols, rows) = grid.tiles_at(5);
        assert_eq!(grid.key_at(5, 180.0, 0.0), grid.key_at(5, -180.0, 0.0));
        assert_eq!(grid.key_at(5, -180.0, 0.0).unwrap().x, 0);
        assert_eq!(grid.key_at(5, 179.999_999, 0.0).unwrap().x, cols - 1);
        assert_eq!(grid.key_at(5, 10.0, 90.0).unwrap().y, 0);
        assert_eq!(grid.key_at(5, 10.0, -90.0).unwrap().y, rows - 1);
        assert_eq!(grid.key_at(5, f64::NAN, 0.0), None);
        assert_eq!(grid.key_at(5, 0.0, 90.5), None);
    }

    proptest! {
        #[test]
        fn point_key_extent_round_trip(lon in -180.0f64..180.0, lat in -90.0f64..=90.0, level in 0u8..=MAX_LEVEL) {
            let grid = TileGrid::geodetic(256).unwrap();
            let key = grid.key_at(level, lon, lat).unwrap();
            prop_assert!(grid.contains_key(key));
            let e = grid.tile_extent(key);
            prop_assert!(e.contains(lon, lat), "{key} {e:?} does not contain {lon},{lat}");
            // The centre of the owner maps back to it.
            let c = grid.key_at(level, f64::midpoint(e.min_x, e.max_x), f64::midpoint(e.min_y, e.max_y)).unwrap();
            prop_assert_eq!(c, key);
            // The parent contains the child.
            if let Some(p) = key.parent() {
                let pe = grid.tile_extent(p);
                prop_assert!(pe.min_x <= e.min_x && pe.max_x >= e.max_x && pe.min_y <= e.min_y && pe.max_y >= e.max_y);
            }
        }

        #[test]
        fn wrapped_longitudes_land_in_range(lon in -1.0e6f64..1.0e6) {
            let w = wrap_longitude(lon);
            prop_assert!((-180.0..180.0).contains(&w));
            let turns = (lon - w) / 360.0;
            prop_assert!((turns - turns.round()).abs() < 1e-6);
        }

        #[test]
        fn covering_keys_cover(min_x in -180.0f64..170.0, min_y in -90.0f64..80.0, w in 0.001f64..10.0, h in 0.001f64..10.0, level in 0u8..9) {
            let grid = TileGrid::geodetic(256).unwrap();
            let area = Extent::new(min_x, min_y, (min_x + w).min(180.0), (min_y + h).min(90.0));
            let keys = grid.keys_overlapping(level, &area);
            prop_assert!(!keys.is_empty());
            let covered: f64 = keys.iter().filter_map(|k| grid.tile_extent(*k).intersection(&area)).map(|e| e.width() * e.height()).sum();
            let total = area.width() * area.height();
            prop_assert!((covered - total).abs() <= total * 1e-9, "{covered} vs {total}");
        }
    }
}
