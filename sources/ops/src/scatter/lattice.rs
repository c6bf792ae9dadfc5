//! The global jittered lattice a rule's candidates come from, and the
//! hashes that place and draw them.
//!
//! One lattice per rule, fixed on the planet (or on the projected CRS's
//! origin), never on the tile asked: cell size s = 1/sqrt(density), one
//! candidate per cell at the cell's centre plus a hashed offset within
//! ±(s - spacing)/2 on each axis, so neighbouring cells keep `spacing`
//! apart. A candidate is a pure function of (seed, class, cell), so every
//! tile, at every level and in any order, computes the same f64 position.
//!
//! On the geodetic grid the lattice is in metres on the WGS84 ellipsoid:
//! rows are s metres of meridian arc counted from the equator, and each
//! row has round(circumference / s) cells (at least 1), so a row wraps at
//! the antimeridian with no seam and shrinks to one cell at a pole.

use std::f64::consts::PI;

use relief_source::geodesy::{WGS84_A, WGS84_E2, WGS84_F};
use relief_source::{Extent, TileGrid};

/// splitmix64's finaliser: a bijection on u64 that mixes every input bit
/// into every output bit.
pub fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A stable hash of a tuple of integers (the same on every machine).
pub fn hash(parts: &[u64]) -> u64 {
    parts.iter().fold(0x7265_6c69_6566_u64, |h, &p| mix(h ^ p))
}

/// Independent draws from one hash: draw `k` is a number in [0, 1).
#[derive(Debug, Clone, Copy)]
pub struct Draws(pub u64);

/// What each draw of a candidate is for.
pub mod draw {
    pub const ACCEPT: u64 = 1;
    pub const JITTER_X: u64 = 2;
    pub const JITTER_Y: u64 = 3;
    pub const MODEL: u64 = 4;
    pub const SCALE: u64 = 5;
    pub const ROTATION: u64 = 6;
    pub const ID: u64 = 7;
}

impl Draws {
    pub fn bits(self, k: u64) -> u64 {
        mix(self.0 ^ k.wrapping_mul(0xd6e8_feb8_6659_fd93))
    }

    pub fn unit(self, k: u64) -> f64 {
        (self.bits(k) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A feature id for a scattered instance: well mixed (the renderer
    /// thins by it), independent of the other draws, top bit set so it
    /// never meets a point feature's id.
    pub fn feature_id(self) -> u64 {
        self.bits(draw::ID) | (1 << 63)
    }
}

/// One cell's candidate: its position in the grid's CRS and its draws.
#[derive(Debug, Clone, Copy)]
pub struct Candidate {
    pub x: f64,
    pub y: f64,
    pub draws: Draws,
}

/// A rule's lattice: cell size and spacing in metres, and the hash of
/// (seed, class) its cells are drawn from.
#[derive(Debug, Clone, Copy)]
pub struct JitteredLattice {
    pub cell_m: f64,
    pub spacing_m: f64,
    pub key: u64,
}

impl JitteredLattice {
    /// The cell size for a density: s = 1/sqrt(density), in metres; None
    /// for a density of 0 (no candidates at all).
    pub fn cell_size_m(density_per_km2: f64) -> Option<f64> {
        (density_per_km2 > 0.0).then(|| 1000.0 / density_per_km2.sqrt())
    }

    /// Calls `f` with every candidate whose cell may reach into `area` (a
    /// few more: the caller keeps those the tile owns), row by row.
    pub fn for_each<E>(
        &self,
        grid: &TileGrid,
        area: &Extent,
        f: impl FnMut(Candidate) -> Result<(), E>,
    ) -> Result<(), E> {
        if grid.is_geodetic() { self.geodetic(area, f) } else { self.projected(area, f) }
    }

    fn draws(&self, row: i64, col: i64) -> Draws {
        Draws(hash(&[self.key, row as u64, col as u64]))
    }

    /// A projected grid: square cells in grid units from the CRS origin, so
    /// the lattice does not move when the grid's extent does.
    fn projected<E>(&self, area: &Extent, mut f: impl FnMut(Candidate) -> Result<(), E>) -> Result<(), E> {
        let s = self.cell_m;
        let jitter = s - self.spacing_m;
        let (i0, i1) = ((area.min_x / s).floor() as i64 - 1, (area.max_x / s).floor() as i64 + 1);
        let (j0, j1) = ((area.min_y / s).floor() as i64 - 1, (area.max_y / s).floor() as i64 + 1);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let draws = self.draws(j, i);
                let x = (i as f64 + 0.5) * s + (draws.unit(draw::JITTER_X) - 0.5) * jitter;
                let y = (j as f64 + 0.5) * s + (draws.unit(draw::JITTER_Y) - 0.5) * jitter;
                f(Candidate { x, y, draws })?;
            }
        }
        Ok(())
    }

    /// The geodetic grid: rows of s metres of meridian arc from the
    /// equator, each row's cells s metres wide (about) at its latitude.
    fn geodetic<E>(&self, area: &Extent, mut f: impl FnMut(Candidate) -> Result<(), E>) -> Result<(), E> {
        let s = self.cell_m;
        let m = self.spacing_m;
        let quarter = meridian_arc_m(90.0);
        let last_row = (quarter / s).ceil() as i64 - 1;
        let r0 = ((meridian_arc_m(area.min_y.max(-90.0)) / s).floor() as i64 - 1).max(-last_row - 1);
        let r1 = ((meridian_arc_m(area.max_y.min(90.0)) / s).floor() as i64 + 1).min(last_row);
        for r in r0..=r1 {
            let row = Row::new(r, s, m, quarter);
            let (c0, c1) = (
                ((area.min_x + 180.0) / row.width_deg).floor() as i64 - 1,
                ((area.max_x + 180.0) / row.width_deg).floor() as i64 + 1,
            );
            // A range as wide as the row is the whole row, each cell once.
            let (c0, c1) = if c1 - c0 + 1 >= row.count { (0, row.count - 1) } else { (c0, c1) };
            for c in c0..=c1 {
                let c = c.rem_euclid(row.count);
                let draws = self.draws(r, c);
                let arc = row.centre_arc_m + (draws.unit(draw::JITTER_Y) - 0.5) * (s - m);
                if arc.abs() > quarter {
                    continue;
                }
                let lat = latitude_of_arc(arc).clamp(-90.0, 90.0);
                let fraction = 0.5 + (draws.unit(draw::JITTER_X) - 0.5) * row.jitter_x;
                let lon = wrap_lon(-180.0 + (c as f64 + fraction) * row.width_deg);
                f(Candidate { x: lon, y: lat, draws })?;
            }
        }
        Ok(())
    }
}

/// One row of the geodetic lattice.
#[derive(Debug)]
struct Row {
    /// Cells round the planet in this row.
    count: i64,
    width_deg: f64,
    centre_arc_m: f64,
    /// The share of a cell's width a candidate may move east or west.
    jitter_x: f64,
}

impl Row {
    fn new(r: i64, s: f64, m: f64, quarter: f64) -> Self {
        let centre_arc_m = (r as f64 + 0.5) * s;
        let radius = |arc: f64| parallel_radius_m(latitude_of_arc(arc.clamp(-quarter, quarter)));
        let mut count = (2.0 * PI * radius(centre_arc_m) / s).round().max(1.0);
        let mut jitter_x = 1.0;
        if m > 0.0 {
            // Candidates of neighbouring cells are closest at the row's
            // poleward edge, where the parallel is smallest: there their
            // chord must be `m` at least, so they must be `gap` apart in
            // longitude (a whole turn when the parallel is shorter than m).
            let poleward = if r >= 0 { (r + 1) as f64 * s - m / 2.0 } else { r as f64 * s + m / 2.0 };
            let narrowest = radius(poleward);
            let gap = if m < 2.0 * narrowest { 2.0 * (m / (2.0 * narrowest)).asin() } else { 2.0 * PI };
            count = count.min((2.0 * PI / gap).floor()).max(1.0);
            jitter_x = (1.0 - gap * count / (2.0 * PI)).clamp(0.0, 1.0);
        }
        Self { count: count as i64, width_deg: 360.0 / count, centre_arc_m, jitter_x }
    }
}

/// Wraps a longitude into [-180, 180).
pub fn wrap_lon(lon: f64) -> f64 {
    let w = (lon + 180.0).rem_euclid(360.0) - 180.0;
    if w >= 180.0 { w - 360.0 } else { w }
}

/// Third flattening n = f / (2 - f), the series parameter below.
const N: f64 = WGS84_F / (2.0 - WGS84_F);

/// The rectifying radius: a quarter meridian is (π/2) times this.
fn rectifying_radius_m() -> f64 {
    let n2 = N * N;
    WGS84_A / (1.0 + N) * (1.0 + n2 / 4.0 + n2 * n2 / 64.0)
}

/// Signed distance along a meridian from the equator to `lat_deg`, metres
/// (Helmert's series in n, sub-millimetre).
pub fn meridian_arc_m(lat_deg: f64) -> f64 {
    let (n, n2) = (N, N * N);
    let phi = lat_deg.to_radians();
    let b2 = -1.5 * n + 9.0 / 16.0 * n * n2;
    let b4 = 15.0 / 16.0 * n2 - 15.0 / 32.0 * n2 * n2;
    let b6 = -35.0 / 48.0 * n * n2;
    let b8 = 315.0 / 512.0 * n2 * n2;
    rectifying_radius_m()
        * (phi + b2 * (2.0 * phi).sin() + b4 * (4.0 * phi).sin() + b6 * (6.0 * phi).sin() + b8 * (8.0 * phi).sin())
}

/// The latitude (degrees) at `arc_m` metres along a meridian from the
/// equator: the inverse of [`meridian_arc_m`] (footpoint latitude series).
pub fn latitude_of_arc(arc_m: f64) -> f64 {
    let (n, n2) = (N, N * N);
    let mu = arc_m / rectifying_radius_m();
    let d2 = 1.5 * n - 27.0 / 32.0 * n * n2;
    let d4 = 21.0 / 16.0 * n2 - 55.0 / 32.0 * n2 * n2;
    let d6 = 151.0 / 96.0 * n * n2;
    let d8 = 1097.0 / 512.0 * n2 * n2;
    (mu + d2 * (2.0 * mu).sin() + d4 * (4.0 * mu).sin() + d6 * (6.0 * mu).sin() + d8 * (8.0 * mu).sin()).to_degrees()
}

/// Radius of the parallel at `lat_deg` (distance from the polar axis), metres.
pub fn parallel_radius_m(lat_deg: f64) -> f64 {
    let (sin, cos) = lat_deg.to_radians().sin_cos();
    (WGS84_A * cos / (1.0 - WGS84_E2 * sin * sin).sqrt()).max(0.0)
}

/// Radius of curvature of the meridian at `lat_deg`, metres.
pub fn meridian_radius_m(lat_deg: f64) -> f64 {
    let sin = lat_deg.to_radians().sin();
    WGS84_A * (1.0 - WGS84_E2) / (1.0 - WGS84_E2 * sin * sin).powf(1.5)
}

/// Grid-unit offsets (east, north) of `d_m` metres at a point: metres on
/// a projected grid, degrees on the geodetic one (east capped at 180
/// degrees near a pole).
pub fn offsets(grid: &TileGrid, lat_deg: f64, d_m: f64) -> (f64, f64) {
    if !grid.is_geodetic() {
        return (d_m, d_m);
    }
    let north = (d_m / meridian_radius_m(lat_deg)).to_degrees();
    let east = (d_m / parallel_radius_m(lat_deg)).to_degrees();
    (if east.is_finite() { east.min(180.0) } else { 180.0 }, north)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_meridian_arc_and_its_inverse_agree() {
        // A quarter meridian of WGS84 is 10 001 965.729 m.
        assert!((meridian_arc_m(90.0) - 10_001_965.729).abs() < 1e-3, "{}", meridian_arc_m(90.0));
        // One degree of latitude at 45 degrees is about 111 132 m.
        assert!((meridian_arc_m(45.5) - meridian_arc_m(44.5) - 111_132.0).abs() < 1.0);
        for lat in [-90.0, -89.9, -45.0, 0.0, 12.345, 60.0, 89.999, 90.0] {
            let back = latitude_of_arc(meridian_arc_m(lat));
            let err_m = (back - lat).abs().to_radians() * 6.4e6;
            assert!(err_m < 1e-4, "{lat} -> {back}");
        }
    }

    #[test]
    fn draws_are_uniform_and_independent_of_the_id() {
        let mut sum = 0.0;
        let mut top = 0;
        for i in 0..10_000u64 {
            let d = Draws(hash(&[7, 311, i, 0]));
            sum += d.unit(draw::ACCEPT);
            assert!((0.0..1.0).contains(&d.unit(draw::ACCEPT)));
            top += u32::from(d.feature_id() >> 62 & 1 == 1);
        }
        assert!((sum / 10_000.0 - 0.5).abs() < 0.01, "{sum}");
        // The bit under the top one is a fair coin.
        assert!((4_800..5_200).contains(&top), "{top}");
    }

    #[test]
    fn rows_wrap_round_the_planet_and_narrow_to_one_cell_at_a_pole() {
        let quarter = meridian_arc_m(90.0);
        let s = 10.0;
        let equator = Row::new(0, s, 0.0, quarter);
        assert_eq!(equator.count, (2.0 * PI * WGS84_A / s).round() as i64);
        let last = (quarter / s).ceil() as i64 - 1;
        let polar = Row::new(last, s, 0.0, quarter);
        assert!(polar.count >= 1 && polar.count < 10, "{}", polar.count);
        // With spacing, neighbouring cells' candidates stay `m` apart (as a
        // chord) at the poleward edge.
        let m = 4.0;
        for r in [last - 3, last - 1, 1000] {
            let row = Row::new(r, s, m, quarter);
            let narrowest = parallel_radius_m(latitude_of_arc((r + 1) as f64 * s - m / 2.0));
            let closest = (1.0 - row.jitter_x) * row.width_deg.to_radians();
            assert!(row.count == 1 || 2.0 * narrowest * (closest / 2.0).sin() >= m - 1e-9, "row {r}");
        }
    }
}
