//! Property tests of the tile grids' key and extent maths (part of the
//! hard-case suite, docs/hard-cases.md): random levels from 0 to
//! MAX_LEVEL, random points with the hard ones (tile edges and corners,
//! the grid's own edges, the poles and the antimeridian, longitudes past
//! a turn) over the planet's geodetic grid and projected grids of every
//! size and offset, false eastings included. Everything here is exact: no
//! tolerance but where one is stated.

#![allow(clippy::unwrap_used, reason = "tests: a failed unwrap is a failed test")]

use proptest::prelude::*;
use relief_source::{Direction, Extent, GridKind, MAX_LEVEL, ProjectedGrid, SampleKind, TileGrid, TileKey};

/// The planet's grid, or a projected one with its corner anywhere within
/// 100,000 km of the CRS's origin and a side from 1 m to 100,000 km.
fn grids() -> impl Strategy<Value = TileGrid> {
    let tile = prop::sample::select(vec![16u32, 64, 256, 4096]);
    let corner =
        prop_oneof![Just(0.0), Just(420_000.0), Just(10_000_000.0), Just(-20_037_508.342_789_244), -1.0e8..1.0e8f64,];
    let size = prop_oneof![
        Just(12_288.0),
        Just(20_000.0),
        Just(40_075_016.685_578_49),
        (0.0..8.0f64).prop_map(|e| 10f64.powf(e))
    ];
    prop_oneof![
        tile.clone().prop_map(|n| TileGrid::geodetic(n).unwrap()),
        (tile, corner.clone(), corner, size).prop_map(|(n, min_x, min_y, size)| {
            TileGrid::new(GridKind::Projected(ProjectedGrid { crs: "EPSG:32612".into(), min_x, min_y, size }), n)
                .unwrap()
        }),
    ]
}

fn levels() -> impl Strategy<Value = u8> {
    prop_oneof![0..=MAX_LEVEL, Just(0), Just(MAX_LEVEL)]
}

/// A key of `grid` at `level` from two numbers in [0, 1).
fn key_of(grid: &TileGrid, level: u8, fx: f64, fy: f64) -> TileKey {
    let (cols, rows) = grid.tiles_at(level);
    TileKey::new(level, ((fx * f64::from(cols)) as u32).min(cols - 1), ((fy * f64::from(rows)) as u32).min(rows - 1))
}

/// A point of `grid`: anywhere (`pick` 0), on a corner or an edge of a
/// tile at `level` (1, 2), on the grid's own edges and corners (3).
fn point_of(grid: &TileGrid, level: u8, pick: u8, fx: f64, fy: f64) -> (f64, f64) {
    let e = grid.extent();
    let inside = |f: f64, lo: f64, hi: f64| (lo + f * (hi - lo)).clamp(lo, hi);
    match pick {
        0 => (inside(fx, e.min_x, e.max_x), inside(fy, e.min_y, e.max_y)),
        1 | 2 => {
            let t = grid.tile_extent(key_of(grid, level, fx, fy));
            let x = if fx * 8.0 % 1.0 < 0.5 { t.min_x } else { t.max_x };
            let y = if fy * 8.0 % 1.0 < 0.5 { t.min_y } else { t.max_y };
            if pick == 1 { (x, y) } else { (x, inside(fy * 8.0 % 1.0, t.min_y, t.max_y)) }
        }
        _ => {
            let x = [e.min_x, e.max_x, inside(fx, e.min_x, e.max_x)][(fx * 3.0) as usize % 3];
            let y = [e.min_y, e.max_y, inside(fy, e.min_y, e.max_y)][(fy * 3.0) as usize % 3];
            (x, y)
        }
    }
}

/// `x` as the grid holds it: longitudes wrapped into [-180, 180).
fn held(grid: &TileGrid, x: f64) -> f64 {
    if grid.is_geodetic() {
        let w = (x + 180.0).rem_euclid(360.0) - 180.0;
        if w >= 180.0 { w - 360.0 } else { w }
    } else {
        x
    }
}

fn children(key: TileKey) -> [TileKey; 4] {
    let (l, x, y) = (key.level + 1, 2 * key.x, 2 * key.y);
    [TileKey::new(l, x, y), TileKey::new(l, x + 1, y), TileKey::new(l, x, y + 1), TileKey::new(l, x + 1, y + 1)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2048))]

    /// A point maps to the one key that owns it: a key of the grid, whose
    /// extent holds the point; tiles own [west, east) x (south, north],
    /// the last column and row their closing edges too.
    #[test]
    fn a_point_lies_in_the_extent_of_the_key_it_maps_to(
        grid in grids(), level in levels(), pick in 0u8..4, fx in 0.0..1.0f64, fy in 0.0..1.0f64,
    ) {
        let (x, y) = point_of(&grid, level, pick, fx, fy);
        let key = grid.key_at(level, x, y).unwrap();
        prop_assert!(grid.contains_key(key), "{key} is not a key of the grid");
        let (cols, rows) = grid.tiles_at(level);
        let t = grid.tile_extent(key);
        let x = held(&grid, x);
        prop_assert!(t.contains(x, y), "{key} {t:?} does not hold ({x}, {y})");
        prop_assert!(x < t.max_x || key.x == cols - 1, "{key} {t:?}: ({x}, {y}) is on its east edge, owned by its east neighbour");
        prop_assert!(y > t.min_y || key.y == rows - 1, "{key} {t:?}: ({x}, {y}) is on its south edge, owned by its south neighbour");
    }

    /// Levels nest: the owner of a point at level l + 1 is a child of its
    /// owner at level l.
    #[test]
    fn owners_at_successive_levels_are_parent_and_child(
        grid in grids(), level in 0..MAX_LEVEL, pick in 0u8..4, fx in 0.0..1.0f64, fy in 0.0..1.0f64,
    ) {
        let (x, y) = point_of(&grid, level + 1, pick, fx, fy);
        let fine = grid.key_at(level + 1, x, y).unwrap();
        prop_assert_eq!(fine.parent(), grid.key_at(level, x, y), "({}, {}) at level {}", x, y, level + 1);
    }

    /// A parent's four children tile it exactly: their shared edges and
    /// their outer edges are the parent's, bit for bit.
    #[test]
    fn children_tile_their_parent_exactly(grid in grids(), level in 0..MAX_LEVEL, fx in 0.0..1.0f64, fy in 0.0..1.0f64) {
        let key = key_of(&grid, level, fx, fy);
        let p = grid.tile_extent(key);
        let [nw, ne, sw, se] = children(key).map(|c| {
            assert_eq!(c.parent(), Some(key));
            assert!(grid.contains_key(c));
            grid.tile_extent(c)
        });
        prop_assert_eq!((nw.min_x, nw.max_y, ne.max_x, ne.max_y), (p.min_x, p.max_y, p.max_x, p.max_y));
        prop_assert_eq!((sw.min_x, sw.min_y, se.max_x, se.min_y), (p.min_x, p.min_y, p.max_x, p.min_y));
        prop_assert_eq!((nw.max_x, sw.max_x, nw.min_y, ne.min_y), (ne.min_x, se.min_x, sw.max_y, se.max_y));
        prop_assert!(!nw.is_empty() && !se.is_empty(), "{key}: children without area {nw:?} {se:?}");
    }

    /// The keys covering an extent are exactly the tiles that share area
    /// with it: each one does, no other tile does, every point inside the
    /// extent is owned by one of them, and their pieces add up to it.
    #[test]
    fn the_keys_covering_an_extent_cover_every_point_in_it(
        grid in grids(), level in levels(), fx in 0.0..1.0f64, fy in 0.0..1.0f64,
        tiles_w in 0.01..6.0f64, tiles_h in 0.01..6.0f64, points in prop::collection::vec((0.0..1.0f64, 0.0..1.0f64), 16),
    ) {
        let e = grid.extent();
        let (span_x, span_y) = grid.tile_span(level);
        let (x0, y0) = point_of(&grid, level, 0, fx, fy);
        let area = Extent::new(x0, y0, (x0 + tiles_w * span_x).min(e.max_x), (y0 + tiles_h * span_y).min(e.max_y));
        prop_assume!(!area.is_empty());
        let keys = grid.keys_overlapping(level, &area);
        prop_assert!(!keys.is_empty());
        let mut sorted = keys.clone();
        sorted.sort_unstable();
        sorted.dedup();
        prop_assert_eq!(sorted.len(), keys.len(), "a key listed twice");
        for k in &keys {
            prop_assert!(grid.tile_extent(*k).overlaps(&area), "{k} does not share area with {area:?}");
        }
        // No tile round the listed block is left out that shares area.
        let (cols, rows) = grid.tiles_at(level);
        let (min_col, max_col) = keys.iter().fold((u32::MAX, 0), |(a, b), k| (a.min(k.x), b.max(k.x)));
        let (min_row, max_row) = keys.iter().fold((u32::MAX, 0), |(a, b), k| (a.min(k.y), b.max(k.y)));
        for y in min_row.saturating_sub(1)..=(max_row + 1).min(rows - 1) {
            for x in min_col.saturating_sub(1)..=(max_col + 1).min(cols - 1) {
                let k = TileKey::new(level, x, y);
                prop_assert_eq!(keys.contains(&k), grid.tile_extent(k).overlaps(&area), "{} and {:?}", k, area);
            }
        }
        for (u, v) in points {
            let (x, y) = (area.min_x + u * area.width(), area.min_y + v * area.height());
            if x > area.min_x && x < area.max_x && y > area.min_y && y < area.max_y {
                let owner = grid.key_at(level, x, y).unwrap();
                prop_assert!(keys.contains(&owner), "({x}, {y}) in {area:?} is owned by {owner}, not listed");
            }
        }
        // Stated tolerance: the pieces' areas add up to the extent's to 1e-9.
        let covered: f64 = keys.iter().filter_map(|k| grid.tile_extent(*k).intersection(&area)).map(|i| i.width() * i.height()).sum();
        let total = area.width() * area.height();
        prop_assert!((covered - total).abs() <= total * 1e-9, "{covered} of {total}");
    }

    /// Neighbours share an edge bit for bit and lead back: east then west
    /// (across the antimeridian on the planet), north then south (over a
    /// pole the row half way round, and over it again back home).
    #[test]
    fn neighbours_share_their_edges_and_lead_back(grid in grids(), level in levels(), fx in 0.0..1.0f64, fy in 0.0..1.0f64) {
        let key = key_of(&grid, level, fx, fy);
        let t = grid.tile_extent(key);
        let turn = if grid.is_geodetic() { 360.0 } else { 0.0 };
        if let Some(east) = grid.neighbour(key, Direction::East) {
            let e = grid.tile_extent(east.key);
            prop_assert!(e.min_x == t.max_x || e.min_x == t.max_x - turn, "{key} east {:?}: {t:?} {e:?}", east.key);
            prop_assert_eq!((e.min_y, e.max_y), (t.min_y, t.max_y));
            prop_assert_eq!(grid.neighbour(east.key, Direction::West).map(|n| n.key), Some(key));
        } else {
            prop_assert!(!grid.is_geodetic() && t.max_x == grid.extent().max_x);
        }
        for (there, back) in [(Direction::North, Direction::South), (Direction::South, Direction::North)] {
            match grid.neighbour(key, there) {
                Some(n) if n.across_pole => {
                    prop_assert!(grid.is_geodetic());
                    prop_assert_eq!(grid.neighbour(n.key, there).map(|m| m.key), Some(key));
                    let e = grid.tile_extent(n.key);
                    prop_assert_eq!((e.min_y, e.max_y), (t.min_y, t.max_y));
                }
                Some(n) => {
                    let e = grid.tile_extent(n.key);
                    prop_assert!(e.max_y == t.min_y || e.min_y == t.max_y, "{key} {there:?}: {t:?} {e:?}");
                    prop_assert_eq!(grid.neighbour(n.key, back).map(|m| m.key), Some(key));
                }
                None => prop_assert!(!grid.is_geodetic()),
            }
        }
    }

    /// A tile's corner lattice spans its extent exactly, its samples are
    /// the level's global samples bit for bit, and the tile a global sample
    /// is read from holds it at the index it says.
    #[test]
    fn lattices_global_samples_and_their_tiles_agree(
        grid in grids(), level in levels(), fx in 0.0..1.0f64, fy in 0.0..1.0f64, fi in 0.0..1.0f64, fj in 0.0..1.0f64,
    ) {
        let n = grid.tile_size() as usize;
        let key = key_of(&grid, level, fx, fy);
        let t = grid.tile_extent(key);
        let l = grid.lattice(key, SampleKind::Corner);
        prop_assert_eq!((l.x(0), l.y(0), l.x(n), l.y(n)), (t.min_x, t.max_y, t.max_x, t.min_y));
        let (i, j) = ((fi * (n + 1) as f64) as usize, (fj * (n + 1) as f64) as usize);
        let (gx, gy) = (i64::from(key.x) * n as i64 + i as i64, i64::from(key.y) * n as i64 + j as i64);
        prop_assert_eq!(grid.sample_point(level, gx, gy), (l.x(i), l.y(j)));
        // Stated tolerance: back to the same sample within 4 units in the
        // last place of the grid's largest coordinate.
        let (back_x, back_y) = grid.sample_coords(level, l.x(i), l.y(j));
        let e = grid.extent();
        let ulp = [e.min_x, e.min_y, e.max_x, e.max_y].into_iter().fold(0.0, |m: f64, v| m.max(v.abs())) * f64::EPSILON;
        let step = grid.sample_step(level);
        prop_assert!(
            (back_x - gx as f64).abs() * step <= 4.0 * ulp && (back_y - gy as f64).abs() * step <= 4.0 * ulp,
            "({gx}, {gy}) came back as ({back_x}, {back_y})"
        );
        let (owner, oi, oj) = grid.corner_sample(level, gx, gy);
        prop_assert!(grid.contains_key(owner) && oi <= n && oj <= n);
        let o = grid.lattice(owner, SampleKind::Corner);
        prop_assert_eq!((held(&grid, o.x(oi)), o.y(oj)), (held(&grid, l.x(i)), l.y(j)), "sample ({}, {}) read from {} ({}, {})", gx, gy, owner, oi, oj);
    }

    /// On the planet a longitude and the same longitude turns away have
    /// one owner.
    #[test]
    fn longitudes_a_turn_apart_have_one_owner(level in levels(), lon in -180.0..180.0f64, lat in -90.0..=90.0f64, turns in -3i32..=3) {
        let grid = TileGrid::geodetic(256).unwrap();
        let lon = (lon * 1e6).round() / 1e6;
        prop_assert_eq!(grid.key_at(level, lon + 360.0 * f64::from(turns), lat), grid.key_at(level, lon, lat));
    }
}
