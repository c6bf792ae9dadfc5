//! The hard cases of relief's pure maths (docs/hard-cases.md): the poles
//! and the antimeridian in the grid and the geodesy, huge coordinates,
//! a grid round a single pixel, and degenerate vectors through the
//! feature index every vector source shares.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use std::collections::BTreeMap;

use relief_source::geodesy::{self, WGS84_B};
use relief_source::{
    CrsTransform, Direction, Extent, Feature, FeatureIndex, Geometry, GridKind, MAX_LEVEL, ProjectedGrid, SourceError,
    TileGrid, TileKey,
};

fn projected(min_x: f64, min_y: f64, size: f64, tile_size: u32) -> Result<TileGrid, String> {
    TileGrid::new(GridKind::Projected(ProjectedGrid { crs: "EPSG:32612".into(), min_x, min_y, size }), tile_size)
}

/// Exact poles and the antimeridian through ECEF and back: the pole's
/// latitude exactly, its height to a nanometre, and +-180 one meridian.
#[test]
fn poles_and_the_antimeridian_round_trip_through_ecef() {
    for h in [-11_000.0, 0.0, 1.0, 40_000_000.0] {
        for lon in [-180.0, -45.0, 0.0, 123.0, 180.0] {
            for lat in [90.0, -90.0] {
                let p = geodesy::ecef_from_geodetic(lon, lat, h);
                assert!(p[0].abs() < 1e-6 && p[1].abs() < 1e-6, "({lon}, {lat}, {h}): {p:?}");
                assert!((p[2].abs() - (WGS84_B + h)).abs() < 1e-6, "({lon}, {lat}, {h}): {p:?}");
                let (_, lat2, h2) = geodesy::geodetic_from_ecef(p);
                assert!(lat2 == lat && (h2 - h).abs() < 1e-9, "({lon}, {lat}, {h}) -> ({lat2}, {h2})");
            }
            let (a, b) = (geodesy::ecef_from_geodetic(180.0, 10.0, h), geodesy::ecef_from_geodetic(-180.0, 10.0, h));
            assert!((0..3).all(|k| (a[k] - b[k]).abs() < 1e-6), "+-180 at {h} m: {a:?} {b:?}");
            let (lon2, _, _) = geodesy::geodetic_from_ecef(a);
            assert!(lon2.abs() == 180.0, "{lon2}");
        }
    }
    // Up at a pole is the axis; east and north stay a right-handed frame.
    let [e, n, u] = geodesy::enu_axes(77.0, 90.0);
    assert!((u[2] - 1.0).abs() < 1e-15);
    let cross = [e[1] * n[2] - e[2] * n[1], e[2] * n[0] - e[0] * n[2], e[0] * n[1] - e[1] * n[0]];
    assert!((0..3).all(|k| (cross[k] - u[k]).abs() < 1e-15), "{cross:?} vs {u:?}");
    // A metre across the pole is a metre.
    let d = geodesy::enu_from_geodetic([0.0, 90.0, 0.0], [180.0, 90.0 - 1.0 / 111_694.0, 0.0]);
    assert!((d[0].hypot(d[1]) - 1.0).abs() < 1e-3, "{d:?}");
    assert!(geodesy::haversine_m(179.999_999, 0.0, -179.999_999, 0.0) < 0.25);
}

/// Every tile round a pole shares the pole; the antimeridian's owner is
/// column 0 at every level; keys past the grid are not keys.
#[test]
fn the_poles_and_the_antimeridian_on_the_grid_at_every_level() {
    let grid = TileGrid::geodetic(256).unwrap();
    for level in 0..=MAX_LEVEL {
        let (cols, rows) = grid.tiles_at(level);
        assert_eq!(grid.key_at(level, 180.0, 0.0).unwrap().x, 0);
        assert_eq!(grid.key_at(level, -180.0, -90.0), Some(TileKey::new(level, 0, rows - 1)));
        assert_eq!(grid.key_at(level, 179.999_999_999, 90.0), Some(TileKey::new(level, cols - 1, 0)));
        assert_eq!(grid.tile_extent(TileKey::new(level, 0, 0)).max_y, 90.0);
        assert_eq!(grid.tile_extent(TileKey::new(level, cols - 1, rows - 1)).max_x, 180.0);
        assert!(!grid.contains_key(TileKey::new(level, cols, 0)) && !grid.contains_key(TileKey::new(level, 0, rows)));
        let n = grid.neighbour(TileKey::new(level, 0, 0), Direction::North).unwrap();
        assert!(n.across_pole && n.key == TileKey::new(level, cols / 2, 0));
        for lat in [90.0, -90.0] {
            let (gx, gy) = grid.sample_coords(level, 37.0, lat);
            assert_eq!(gy.fract(), 0.0, "a pole is a sample row at level {level}");
            let (_, _, j) = grid.corner_sample(level, gx.floor() as i64, gy as i64);
            assert_eq!(j, if lat > 0.0 { 0 } else { 256 }, "the pole row is a tile's edge row");
        }
    }
    assert_eq!(grid.key_at(0, f64::INFINITY, 0.0), None);
    assert_eq!(grid.key_at(0, 0.0, f64::NAN), None);
    assert_eq!(grid.key_at(MAX_LEVEL + 1, 0.0, 0.0), None);
}

/// Huge coordinates: a false easting or northing of 10,000 km keeps every
/// level's tiles distinct and exact, down to a grid one metre wide (a
/// single 1 m pixel in a southern UTM zone); coordinates of 1e12 and
/// beyond, where f64 no longer resolves the grid's samples, are refused
/// with the reason.
#[test]
fn huge_coordinates_are_held_exactly_or_refused_with_the_reason() {
    for (min_x, min_y, size) in [
        (10_000_000.0, 10_000_000.0, 20_000.0),
        (500_000.0, 10_000_000.0, 1.0),
        (1.0e8, -1.0e8, 30.0),
        (0.0, 0.0, 0.01),
    ] {
        let grid = projected(min_x, min_y, size, 256).unwrap();
        for level in 0..=MAX_LEVEL {
            let k = TileKey::new(level, (1 << level) - 1, 0);
            let t = grid.tile_extent(k);
            assert!(t.max_x > t.min_x && t.max_y > t.min_y, "({min_x}, {min_y}, {size}) level {level}: {t:?}");
            assert_eq!(grid.key_at(level, f64::midpoint(t.min_x, t.max_x), f64::midpoint(t.min_y, t.max_y)), Some(k));
        }
        assert_eq!(grid.extent().max_x, min_x + size);
        assert_eq!(grid.extent().max_y, min_y + size);
    }
    for (min_x, min_y, size, why) in [
        (1.0e15, 1.0e15, 300.0, "farther from the CRS's origin than any map of this planet"),
        (-1.0e15, 0.0, 1.0e6, "farther from the CRS's origin than any map of this planet"),
        (0.0, 1e300, 1.0, "farther from the CRS's origin than any map of this planet"),
        (0.0, 0.0, 2.0e9, "farther from the CRS's origin than any map of this planet"),
        (5.0e8, 0.0, 0.001, "coarser than a thousandth of the grid's sample spacing"),
    ] {
        let message = projected(min_x, min_y, size, 256).unwrap_err();
        assert!(message.contains(why) && message.ends_with("refused"), "{message}");
    }
    assert!(projected(f64::NAN, 0.0, 1.0, 256).is_err());
    assert!(projected(0.0, 0.0, f64::INFINITY, 256).is_err());
    assert!(projected(0.0, 0.0, 0.0, 256).is_err());
}

/// A grid round a single pixel (a 30 m raster of one pixel is its scene):
/// one tile at level 0, whose key and extent are the pixel's.
#[test]
fn a_grid_round_a_single_pixel_has_one_tile_that_is_the_pixel() {
    let grid = projected(300_000.0, 5_100_000.0, 30.0, 256).unwrap();
    assert_eq!(grid.tiles_at(0), (1, 1));
    assert_eq!(grid.tile_extent(TileKey::new(0, 0, 0)), Extent::new(300_000.0, 5_100_000.0, 300_030.0, 5_100_030.0));
    assert_eq!(grid.key_at(0, 300_015.0, 5_100_015.0), Some(TileKey::new(0, 0, 0)));
    assert_eq!(grid.key_at(0, 300_030.0, 5_100_000.0), Some(TileKey::new(0, 0, 0)), "the closing corner");
    assert_eq!(grid.key_at(0, 300_030.1, 5_100_015.0), None);
    assert_eq!(grid.keys_overlapping(3, &grid.extent()).len(), 64);
}

/// The daemon's transform stand-in: the identity, and NaN for points a
/// CRS could not hold (as PROJ gives them back).
#[derive(Debug)]
struct Identity;

impl CrsTransform for Identity {
    fn transform(&self, _from: &str, _to: &str, xs: &mut [f64], ys: &mut [f64]) -> Result<(), SourceError> {
        for (x, y) in xs.iter_mut().zip(ys.iter_mut()) {
            if !(x.abs() <= 180.0 && y.abs() <= 90.0) {
                (*x, *y) = (f64::NAN, f64::NAN);
            }
        }
        Ok(())
    }
}

fn ring(points: &[(f64, f64)]) -> Vec<[f64; 3]> {
    points.iter().map(|&(x, y)| [x, y, f64::NAN]).collect()
}

fn polygon(id: u64, points: &[(f64, f64)]) -> Feature {
    Feature { id, geometry: Geometry::Polygons(vec![vec![ring(points)]]), properties: BTreeMap::new() }
}

/// Degenerate vectors in the index every vector source shares: a polygon
/// of no area, a self-intersecting bow-tie, duplicate points, a ring of
/// two points, a line of one point, an empty geometry, coordinates no CRS
/// can hold (1e15). Each indexes without a panic or a NaN box: the ones
/// with a place reach the tiles they touch, the ones without none.
#[test]
fn degenerate_vectors_index_without_panics_or_nan_boxes() {
    let features = vec![
        polygon(1, &[(10.0, 45.0), (10.1, 45.0), (10.2, 45.0), (10.0, 45.0)]),
        polygon(2, &[(10.0, 45.0), (10.1, 45.1), (10.1, 45.0), (10.0, 45.1), (10.0, 45.0)]),
        polygon(3, &[(10.0, 45.0), (10.0, 45.0), (10.1, 45.0), (10.1, 45.0), (10.1, 45.1), (10.0, 45.0), (10.0, 45.0)]),
        polygon(4, &[(10.0, 45.0), (10.1, 45.1)]),
        polygon(5, &[(10.05, 45.05)]),
        Feature { id: 6, geometry: Geometry::Lines(vec![ring(&[(10.0, 45.0)])]), properties: BTreeMap::new() },
        Feature { id: 7, geometry: Geometry::Polygons(vec![vec![]]), properties: BTreeMap::new() },
        Feature { id: 8, geometry: Geometry::Points(vec![]), properties: BTreeMap::new() },
        polygon(9, &[(1e15, 1e15), (1e15 + 1.0, 1e15), (1e15, 1e15 + 1.0), (1e15, 1e15)]),
        Feature {
            id: 10,
            geometry: Geometry::Points(ring(&[(f64::NAN, 45.0), (1e15, 0.0)])),
            properties: BTreeMap::new(),
        },
    ];
    let grid = TileGrid::geodetic(256).unwrap();
    let index = FeatureIndex::new(features, "EPSG:4326", &grid, &Identity).unwrap();
    let extent = index.extent().unwrap();
    assert!(extent.is_valid(), "{extent:?}");
    assert_eq!(extent, Extent::new(10.0, 45.0, 10.2, 45.1));
    let tile = grid.key_at(8, 10.05, 45.05).unwrap();
    let ids: Vec<u64> = index.tile(&grid, tile).features.iter().map(|f| f.id).collect();
    assert_eq!(ids, vec![1, 2, 3, 4, 5, 6], "the ones with a place, in the tile they touch");
    for level in [0, 4, 12] {
        for (x, y) in [(0u32, 0u32), (5, 3)] {
            let key = TileKey::new(level, x << level, y << level);
            let tile = index.tile(&grid, key);
            assert!(tile.features.iter().all(|f| ![7, 8, 9, 10].contains(&f.id)), "level {level}: {tile:?}");
        }
    }
    // An index compared with itself has no dirt; with nothing, every place.
    assert!(index.dirt_since(&index).is_none());
    let empty = FeatureIndex::new(Vec::new(), "EPSG:4326", &grid, &Identity).unwrap();
    let dirt = index.dirt_since(&empty).extents(&grid);
    assert!(dirt.iter().all(Extent::is_valid) && !dirt.is_empty(), "{dirt:?}");
}
