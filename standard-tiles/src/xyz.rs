//! The Web Mercator XYZ grid (EPSG:3857) that MapLibre GL JS, deck.gl and
//! every slippy map read: zoom z has 2^z x 2^z tiles of 256 pixels, `x`
//! growing east from -180 and `y` growing south from the north edge at
//! [`MERCATOR_MAX_LAT`]. Addresses, extents in lon/lat degrees, and the
//! tiles over an area; which geodetic level feeds a zoom.

use std::f64::consts::PI;

use relief_source::{Extent, MAX_LEVEL, TileGrid};

/// Pixels a side of an XYZ tile.
pub const XYZ_TILE_SIZE: usize = 256;

/// Web Mercator's latitude limit, degrees: atan(sinh(pi)), where the square
/// world ends (85.0511287798...).
pub const MERCATOR_MAX_LAT: f64 = 85.051_128_779_806_6;

/// The deepest zoom this module addresses: 2^z columns must fit a u32.
pub const XYZ_MAX_ZOOM: u8 = 30;

/// A block of XYZ tiles at one zoom: columns `x[0]..=x[1]` and rows
/// `y[0]..=y[1]`, rows counted from the north.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct XyzRange {
    pub z: u8,
    pub x: [u32; 2],
    pub y: [u32; 2],
}

impl XyzRange {
    /// Every tile of zoom `z`; None past [`XYZ_MAX_ZOOM`].
    pub fn world(z: u8) -> Option<Self> {
        (z <= XYZ_MAX_ZOOM).then(|| {
            let last = (1u32 << z) - 1;
            Self { z, x: [0, last], y: [0, last] }
        })
    }

    /// Whether tile (x, y) at this range's zoom is in the range (with
    /// [`XyzRange::world`], whether an address is valid at all).
    pub fn contains(&self, x: u32, y: u32) -> bool {
        (self.x[0]..=self.x[1]).contains(&x) && (self.y[0]..=self.y[1]).contains(&y)
    }

    /// How many tiles the range holds.
    pub fn count(&self) -> u64 {
        (u64::from(self.x[1] - self.x[0]) + 1) * (u64::from(self.y[1] - self.y[0]) + 1)
    }
}

/// Tiles a side at zoom `z`, as f64 (exact for any u8).
fn tiles_a_side(z: u8) -> f64 {
    f64::from(z).exp2()
}

/// Longitude of the meridian `t` of the way across the world (0 west, 1 east).
fn lon_from_fraction(t: f64) -> f64 {
    t * 360.0 - 180.0
}

/// Latitude of the parallel `t` of the way down the Mercator square (0
/// north, 1 south).
fn lat_from_fraction(t: f64) -> f64 {
    (PI * (1.0 - 2.0 * t)).sinh().atan().to_degrees()
}

/// How far down the Mercator square latitude `lat` lies (0 north, 1 south).
fn fraction_from_lat(lat: f64) -> f64 {
    (1.0 - lat.to_radians().tan().asinh() / PI) / 2.0
}

/// The lon/lat degrees an XYZ tile covers (x, y below 2^z).
pub fn xyz_extent(z: u8, x: u32, y: u32) -> Extent {
    let n = tiles_a_side(z);
    Extent::new(
        lon_from_fraction(f64::from(x) / n),
        lat_from_fraction((f64::from(y) + 1.0) / n),
        lon_from_fraction((f64::from(x) + 1.0) / n),
        lat_from_fraction(f64::from(y) / n),
    )
}

/// The lon/lat of point (px, py) of tile z/x/y, in pixels from its north-west
/// corner (0..=256; pixel (c, r)'s centre is (c + 0.5, r + 0.5)).
pub fn xyz_pixel_lonlat(z: u8, x: u32, y: u32, px: f64, py: f64) -> (f64, f64) {
    let n = tiles_a_side(z);
    let size = XYZ_TILE_SIZE as f64;
    (lon_from_fraction((f64::from(x) + px / size) / n), lat_from_fraction((f64::from(y) + py / size) / n))
}

/// Clamps one axis of an area to `[lo, hi]`. An axis of zero length (a
/// point or a line) must lie inside; a longer one must keep some length.
fn clamp_axis(min: f64, max: f64, lo: f64, hi: f64) -> Option<(f64, f64)> {
    if !(min.is_finite() && max.is_finite() && max >= min) {
        return None;
    }
    if min == max {
        return (lo..=hi).contains(&min).then_some((min, max));
    }
    let (a, b) = (min.max(lo), max.min(hi));
    (b > a).then_some((a, b))
}

/// The first and last of `count` cells (cell `i` spanning `edge(i)` to
/// `edge(i + 1)`, increasing) that share length with `[a, b]`, or touch it
/// when it is a point. `guess` brackets the answer from the formulas; the
/// edge test settles it, so rounding in the guess costs nothing.
fn cells_over(count: u32, guess: (f64, f64), a: f64, b: f64, edge: impl Fn(u32) -> f64) -> Option<[u32; 2]> {
    let last = count - 1;
    let to_cell = |g: f64| (g.floor().max(0.0) as u32).min(last);
    let hits = |i: u32| {
        let (lo, hi) = (edge(i), edge(i + 1));
        if a == b { lo <= b && a <= hi } else { lo < b && a < hi }
    };
    let mut first = to_cell(guess.0).saturating_sub(1);
    let mut end = to_cell(guess.1).saturating_add(1).min(last);
    while first <= end && !hits(first) {
        first += 1;
    }
    while end > first && !hits(end) {
        end -= 1;
    }
    (first <= end && hits(first)).then_some([first, end])
}

/// The XYZ tiles at zoom `z` that share area with `area` (lon/lat degrees;
/// touching edges do not count, but a point or a line picks the tiles it
/// touches), after clamping it to longitudes -180..180 and the Mercator
/// latitudes. None when it misses them, is not finite, or z is past
/// [`XYZ_MAX_ZOOM`]. An area across the antimeridian must be split by the
/// caller: longitudes past ±180 are clamped, not wrapped.
pub fn xyz_range(z: u8, area: &Extent) -> Option<XyzRange> {
    if z > XYZ_MAX_ZOOM {
        return None;
    }
    let (west, east) = clamp_axis(area.min_x, area.max_x, -180.0, 180.0)?;
    let (south, north) = clamp_axis(area.min_y, area.max_y, -MERCATOR_MAX_LAT, MERCATOR_MAX_LAT)?;
    let count = 1u32 << z;
    let n = tiles_a_side(z);
    let x = cells_over(count, ((west + 180.0) / 360.0 * n, (east + 180.0) / 360.0 * n), west, east, |i| {
        lon_from_fraction(f64::from(i) / n)
    })?;
    // Rows grow south: cell i spans -lat(i) .. -lat(i + 1), increasing.
    let y = cells_over(count, (fraction_from_lat(north) * n, fraction_from_lat(south) * n), -north, -south, |i| {
        -lat_from_fraction(f64::from(i) / n)
    })?;
    Some(XyzRange { z, x, y })
}

/// The coarsest level of a geodetic `grid` whose sample step (degrees) is at
/// or finer than an XYZ pixel's longitude span at zoom `z`, at most
/// `max_level` (and relief's `MAX_LEVEL`). Past `max_level` the XYZ tile
/// magnifies the finest geodetic tiles. On a projected grid, whose steps
/// are not degrees, this is `max_level`.
pub fn geodetic_level_for(grid: &TileGrid, z: u8, max_level: u8) -> u8 {
    let max_level = max_level.min(MAX_LEVEL);
    if !grid.is_geodetic() {
        return max_level;
    }
    let pixel_deg = 360.0 / (tiles_a_side(z) * XYZ_TILE_SIZE as f64);
    (0..=max_level).find(|&level| grid.sample_step(level) <= pixel_deg).unwrap_or(max_level)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The slippy-map formulas, written out again: lon = x / 2^z * 360 -
    /// 180, lat = atan(sinh(pi * (1 - 2 y / 2^z))).
    fn reference_lon(z: u8, x: f64) -> f64 {
        x / 2f64.powi(i32::from(z)) * 360.0 - 180.0
    }

    fn reference_lat(z: u8, y: f64) -> f64 {
        (std::f64::consts::PI * (1.0 - 2.0 * y / 2f64.powi(i32::from(z)))).sinh().atan().to_degrees()
    }

    #[test]
    fn the_latitude_limit_is_where_the_square_world_ends() {
        assert!((MERCATOR_MAX_LAT - std::f64::consts::PI.sinh().atan().to_degrees()).abs() < 1e-12);
        assert!((MERCATOR_MAX_LAT - 85.051_128_779_8).abs() < 1e-9);
    }

    #[test]
    fn zoom_zero_is_the_whole_mercator_world() {
        let e = xyz_extent(0, 0, 0);
        assert_eq!((e.min_x, e.max_x), (-180.0, 180.0));
        assert!((e.max_y - MERCATOR_MAX_LAT).abs() < 1e-12);
        assert!((e.min_y + MERCATOR_MAX_LAT).abs() < 1e-12);
    }

    #[test]
    fn extents_match_the_slippy_map_formulas() {
        // A published value: tile 2/1/1 spans -90..0 and 0..66.51326044311186.
        let e = xyz_extent(2, 1, 1);
        assert_eq!((e.min_x, e.max_x), (-90.0, 0.0));
        assert!(e.min_y.abs() < 1e-12);
        assert!((e.max_y - 66.513_260_443_111_86).abs() < 1e-12);
        for (z, x, y) in [(1u8, 1u32, 0u32), (10, 163, 395), (14, 8_716, 5_824), (20, 1_048_575, 0), (3, 7, 7)] {
            let e = xyz_extent(z, x, y);
            let (x, y) = (f64::from(x), f64::from(y));
            assert!((e.min_x - reference_lon(z, x)).abs() < 1e-9, "{z}/{x}/{y} {e:?}");
            assert!((e.max_x - reference_lon(z, x + 1.0)).abs() < 1e-9);
            assert!((e.max_y - reference_lat(z, y)).abs() < 1e-9);
            assert!((e.min_y - reference_lat(z, y + 1.0)).abs() < 1e-9);
        }
    }

    #[test]
    fn pixel_points_run_from_corner_to_corner() {
        let (z, x, y) = (5u8, 17u32, 9u32);
        let e = xyz_extent(z, x, y);
        let (lon, lat) = xyz_pixel_lonlat(z, x, y, 0.0, 0.0);
        assert!((lon - e.min_x).abs() < 1e-12 && (lat - e.max_y).abs() < 1e-12);
        let (lon, lat) = xyz_pixel_lonlat(z, x, y, 256.0, 256.0);
        assert!((lon - e.max_x).abs() < 1e-12 && (lat - e.min_y).abs() < 1e-12);
        // A pixel centre: half a pixel in, on the Mercator (not the lat) scale.
        let (lon, lat) = xyz_pixel_lonlat(z, x, y, 0.5, 0.5);
        assert!((lon - reference_lon(z, f64::from(x) + 0.5 / 256.0)).abs() < 1e-12);
        assert!((lat - reference_lat(z, f64::from(y) + 0.5 / 256.0)).abs() < 1e-12);
    }

    #[test]
    fn ranges_clamp_to_the_mercator_latitudes_and_miss_outside_them() {
        let world = Extent::new(-180.0, -90.0, 180.0, 90.0);
        assert_eq!(xyz_range(0, &world), XyzRange::world(0));
        assert_eq!(xyz_range(4, &world), XyzRange::world(4));
        // Wholly north of 85.05: no XYZ tile shows it.
        assert_eq!(xyz_range(3, &Extent::new(0.0, 86.0, 10.0, 89.0)), None);
        assert_eq!(xyz_range(3, &Extent::new(0.0, -90.0, 10.0, -86.0)), None);
        assert_eq!(xyz_range(3, &Extent::new(f64::NAN, 0.0, 1.0, 1.0)), None);
        assert_eq!(xyz_range(3, &Extent::new(181.0, 0.0, 190.0, 1.0)), None);
        assert_eq!(xyz_range(XYZ_MAX_ZOOM + 1, &world), None);
        // A band reaching past the limit keeps the polar row.
        let r = xyz_range(3, &Extent::new(-1.0, 80.0, 1.0, 90.0)).unwrap();
        assert_eq!(r, XyzRange { z: 3, x: [3, 4], y: [0, 0] });
    }

    #[test]
    fn points_pick_the_tiles_they_touch() {
        // Inside tile 2/1/1.
        let p = Extent::new(-45.0, 30.0, -45.0, 30.0);
        assert_eq!(xyz_range(2, &p), Some(XyzRange { z: 2, x: [1, 1], y: [1, 1] }));
        // On the corner of four tiles: all four.
        let corner = Extent::new(0.0, 0.0, 0.0, 0.0);
        assert_eq!(xyz_range(2, &corner), Some(XyzRange { z: 2, x: [1, 2], y: [1, 2] }));
        // An area whose edge lies on a tile edge does not take the neighbour.
        let e = xyz_extent(6, 20, 30);
        assert_eq!(xyz_range(6, &e), Some(XyzRange { z: 6, x: [20, 20], y: [30, 30] }));
    }

    #[test]
    fn world_ranges_validate_addresses() {
        let w = XyzRange::world(3).unwrap();
        assert!(w.contains(7, 7) && w.contains(0, 0));
        assert!(!w.contains(8, 0) && !w.contains(0, 8));
        assert_eq!(w.count(), 64);
        assert_eq!(XyzRange::world(XYZ_MAX_ZOOM).unwrap().x[1], (1 << 30) - 1);
        assert_eq!(XyzRange::world(31), None);
    }

    #[test]
    fn geodetic_levels_follow_the_pixel_span() {
        let grid = TileGrid::geodetic(256).unwrap();
        // Independently: the least l with 180 / (N 2^l) <= 360 / (256 2^z).
        for n in [16u32, 256, 512] {
            let grid = TileGrid::geodetic(n).unwrap();
            for z in 0..=22u8 {
                let pixel = 360.0 / (256.0 * 2f64.powi(i32::from(z)));
                let want = (0..=MAX_LEVEL)
                    .find(|&l| 180.0 / (f64::from(n) * 2f64.powi(i32::from(l))) <= pixel)
                    .unwrap_or(MAX_LEVEL);
                assert_eq!(geodetic_level_for(&grid, z, MAX_LEVEL), want, "n {n} z {z}");
            }
        }
        // N = 256: level 0 serves zooms 0 and 1, then one level per zoom.
        assert_eq!(geodetic_level_for(&grid, 0, 20), 0);
        assert_eq!(geodetic_level_for(&grid, 1, 20), 0);
        assert_eq!(geodetic_level_for(&grid, 2, 20), 1);
        assert_eq!(geodetic_level_for(&grid, 12, 20), 11);
        // Capped by the scene's finest level.
        assert_eq!(geodetic_level_for(&grid, 18, 9), 9);
    }

    proptest! {
        #[test]
        fn ranges_hold_exactly_the_overlapping_tiles(
            west in -180.0f64..179.0, south in -89.0f64..89.0, w in 0.0001f64..60.0, h in 0.0001f64..40.0, z in 0u8..=12,
        ) {
            let area = Extent::new(west, south, (west + w).min(180.0), (south + h).min(90.0));
            let clamped = Extent::new(area.min_x, area.min_y.max(-MERCATOR_MAX_LAT), area.max_x, area.max_y.min(MERCATOR_MAX_LAT));
            let Some(r) = xyz_range(z, &area) else {
                // Only an area outside the Mercator latitudes misses.
                prop_assert!(area.min_y >= MERCATOR_MAX_LAT || area.max_y <= -MERCATOR_MAX_LAT, "{area:?}");
                return Ok(());
            };
            let last = (1u32 << z) - 1;
            prop_assert!(r.x[0] <= r.x[1] && r.y[0] <= r.y[1] && r.x[1] <= last && r.y[1] <= last);
            for y in r.y[0]..=r.y[1] {
                for x in [r.x[0], r.x[1]] {
                    prop_assert!(xyz_extent(z, x, y).overlaps(&clamped), "{z}/{x}/{y} misses {area:?}");
                }
            }
            for x in r.x[0]..=r.x[1] {
                for y in [r.y[0], r.y[1]] {
                    prop_assert!(xyz_extent(z, x, y).overlaps(&clamped), "{z}/{x}/{y} misses {area:?}");
                }
            }
            // The tiles just outside do not overlap.
            let mid_y = u32::midpoint(r.y[0], r.y[1]);
            let mid_x = u32::midpoint(r.x[0], r.x[1]);
            if r.x[0] > 0 { prop_assert!(!xyz_extent(z, r.x[0] - 1, mid_y).overlaps(&clamped)); }
            if r.x[1] < last { prop_assert!(!xyz_extent(z, r.x[1] + 1, mid_y).overlaps(&clamped)); }
            if r.y[0] > 0 { prop_assert!(!xyz_extent(z, mid_x, r.y[0] - 1).overlaps(&clamped)); }
            if r.y[1] < last { prop_assert!(!xyz_extent(z, mid_x, r.y[1] + 1).overlaps(&clamped)); }
        }
    }
}
