use std::f64::consts::PI;

use relief_source::{GridKind, ProjectedGrid};

use super::*;
use crate::xyz::geodetic_level_for;

const SIDE: usize = XYZ_TILE_SIZE;

/// The pixel centre of (c, r), from the Mercator formulas written out
/// again (not through `xyz_pixel_lonlat`): where a colour pixel reads.
fn reference_centre(z: u8, x: u32, y: u32, c: usize, r: usize) -> (f64, f64) {
    reference_point(z, x, y, c as f64 + 0.5, r as f64 + 0.5)
}

/// The north-west corner of pixel (c, r): where a height pixel reads.
fn reference_corner(z: u8, x: u32, y: u32, c: usize, r: usize) -> (f64, f64) {
    reference_point(z, x, y, c as f64, r as f64)
}

fn reference_point(z: u8, x: u32, y: u32, px: f64, py: f64) -> (f64, f64) {
    let n = 2f64.powi(i32::from(z));
    let lon = (f64::from(x) + px / 256.0) / n * 360.0 - 180.0;
    let lat = (PI * (1.0 - 2.0 * (f64::from(y) + py / 256.0) / n)).sinh().atan().to_degrees();
    (lon, lat)
}

fn height_tile(grid: &TileGrid, key: TileKey, f: impl Fn(f64, f64) -> f64) -> Arc<Payload> {
    let l = grid.lattice(key, SampleKind::Corner);
    let heights = (0..l.rows).flat_map(|j| (0..l.cols).map(move |i| (i, j))).map(|(i, j)| f(l.x(i), l.y(j)) as f32);
    Arc::new(Payload::Height(HeightTile { size: l.cols, heights: heights.collect() }))
}

fn color_tile(grid: &TileGrid, rgba: [u8; 4]) -> Arc<Payload> {
    let side = grid.tile_size() as usize + 2;
    Arc::new(Payload::Color(ColorTile { size: side, rgba: rgba.repeat(side * side) }))
}

/// Every source key of an XYZ tile, filled by `fill` (None = missing).
fn fetch(
    grid: &TileGrid,
    level: u8,
    (z, x, y): (u8, u32, u32),
    kind: SampleKind,
    fill: impl Fn(TileKey) -> Option<Arc<Payload>>,
) -> Vec<(TileKey, Option<Arc<Payload>>)> {
    source_keys(grid, level, z, x, y, kind).into_iter().map(|k| (k, fill(k))).collect()
}

#[test]
fn a_tilted_plane_comes_back_exact_at_the_pixel_corners() {
    let plane = |lon: f64, lat: f64| 3.0 * lon - 5.0 * lat + 100.0;
    // (N, level, z/x/y): levels that match the zoom, magnify it (several
    // pixels per sample, across geodetic tile edges) and shrink it (many
    // source tiles); tiles touching 85.05 north and south.
    let cases = [
        (256, None, (0, 0, 0)),
        (256, None, (1, 0, 1)),
        (256, None, (7, 37, 50)),
        (16, Some(3), (5, 10, 12)),
        (16, Some(1), (6, 20, 33)),
        (64, Some(5), (3, 2, 1)),
        (16, Some(1), (2, 1, 0)),
        (16, Some(2), (3, 5, 7)),
        (16, Some(0), (1, 0, 1)),
    ];
    for (n, level, (z, x, y)) in cases {
        let grid = TileGrid::geodetic(n).unwrap();
        let level = level.unwrap_or_else(|| geodetic_level_for(&grid, z, MAX_LEVEL));
        let tiles = fetch(&grid, level, (z, x, y), SampleKind::Corner, |k| Some(height_tile(&grid, k, plane)));
        let heights = resample_heights(&grid, level, z, x, y, &tiles);
        assert_eq!(heights.len(), SIDE * SIDE);
        for r in 0..SIDE {
            for c in 0..SIDE {
                let (lon, lat) = reference_corner(z, x, y, c, r);
                let got = f64::from(heights[r * SIDE + c]);
                let want = plane(lon, lat);
                assert!((got - want).abs() < 1e-3, "n {n} level {level} {z}/{x}/{y} ({c}, {r}): {got} vs {want}");
            }
        }
    }
}

#[test]
fn at_the_matching_level_texels_line_up_and_corners_reach_one_sample_over() {
    // N = 256 and zoom 1 at level 0, the level geodetic_level_for picks:
    // one sample per pixel (both grids halve 360 degrees). Pixel centres
    // are texel centres, so a colour tile reads one geodetic tile; pixel
    // corners (where heights are read) are corner samples, so a height
    // tile reads one too.
    let grid = TileGrid::geodetic(256).unwrap();
    assert_eq!(geodetic_level_for(&grid, 1, MAX_LEVEL), 0);
    assert_eq!(source_keys(&grid, 0, 1, 1, 1, SampleKind::TexelWithBorder), vec![TileKey::new(0, 1, 0)]);
    assert_eq!(source_keys(&grid, 0, 1, 0, 0, SampleKind::Corner), vec![TileKey::new(0, 0, 0)]);
    // Zoom 0: two samples a pixel, corners on even samples: no wrap.
    assert_eq!(source_keys(&grid, 0, 0, 0, 0, SampleKind::Corner), vec![TileKey::new(0, 0, 0), TileKey::new(0, 1, 0)]);
}

#[test]
fn pixels_past_a_tiles_last_own_sample_read_its_neighbour() {
    // N = 16, level 3: columns of 22.5 degrees, 1.40625 a sample. XYZ 4/4/6
    // is geodetic column 4 (-90..-67.5) exactly, 16 pixels a sample; the
    // pixels whose corners lie east of column 4's sample 15 blend in sample
    // 16, which is column 5's first (the corner lattice shares it).
    let grid = TileGrid::geodetic(16).unwrap();
    let (level, z, x, y) = (3u8, 4u8, 4u32, 6u32);
    let keys = source_keys(&grid, level, z, x, y, SampleKind::Corner);
    let east_col = 5u32;
    assert!(keys.iter().any(|k| k.x == east_col) && keys.iter().any(|k| k.x == 4));
    let tiles = fetch(&grid, level, (z, x, y), SampleKind::Corner, |k| {
        (k.x != east_col).then(|| height_tile(&grid, k, |_, _| 42.0))
    });
    let heights = resample_heights(&grid, level, z, x, y, &tiles);
    let step = grid.sample_step(level);
    let first_east = f64::from(east_col * 16);
    let mut nan_columns = 0;
    for c in 0..SIDE {
        let (lon, _) = reference_corner(z, x, y, c, 100);
        let gx = (lon + 180.0) / step;
        // Reads sample `first_east` (with weight) exactly when gx > first_east - 1.
        let reads_east = gx > first_east - 1.0;
        let h = heights[100 * SIDE + c];
        assert_eq!(h.is_nan(), reads_east, "column {c} at gx {gx}: {h}");
        if !reads_east {
            assert!((h - 42.0).abs() < 1e-4);
        }
        nan_columns += usize::from(reads_east);
    }
    // The last sample interval less the pixel on sample 15: 15 pixels.
    assert_eq!(nan_columns, 15);
}

#[test]
fn one_nodata_sample_blanks_only_the_pixels_that_weigh_it() {
    let grid = TileGrid::geodetic(16).unwrap();
    let (level, z, x, y) = (2u8, 4u8, 9u32, 5u32);
    let tiles = fetch(&grid, level, (z, x, y), SampleKind::Corner, |k| Some(height_tile(&grid, k, |_, _| 7.0)));
    // Put a NaN at one sample inside the XYZ tile's footprint.
    let (lon, lat) = reference_corner(z, x, y, 128, 128);
    let (gx, gy) = grid.sample_coords(level, lon, lat);
    let (key, i, j) = grid.corner_sample(level, gx.floor() as i64, gy.floor() as i64);
    let tiles: Vec<_> = tiles
        .into_iter()
        .map(|(k, p)| {
            if k != key {
                return (k, p);
            }
            let Some(Payload::Height(mut t)) = p.map(|p| (*p).clone()) else { panic!("{k} holds no heights") };
            t.heights[j * t.size + i] = f32::NAN;
            (k, Some(Arc::new(Payload::Height(t))))
        })
        .collect();
    let heights = resample_heights(&grid, level, z, x, y, &tiles);
    let (sx, sy) = (gx.floor(), gy.floor());
    for r in 0..SIDE {
        for c in 0..SIDE {
            let (lon, lat) = reference_corner(z, x, y, c, r);
            let (px, py) = grid.sample_coords(level, lon, lat);
            let weighs = (px - sx).abs() < 1.0 && (py - sy).abs() < 1.0;
            let h = heights[r * SIDE + c];
            assert_eq!(h.is_nan(), weighs, "({c}, {r})");
        }
    }
}

#[test]
fn the_antimeridian_tiles_read_both_sides() {
    // N = 16 at level 0: two tiles, 11.25 degrees a sample, far coarser
    // than zoom 3's pixels. XYZ x = 7 ends at 180, where column 0 begins.
    let grid = TileGrid::geodetic(16).unwrap();
    let (west, east) = (TileKey::new(0, 0, 0), TileKey::new(0, 1, 0));
    let keys = source_keys(&grid, 0, 3, 7, 3, SampleKind::Corner);
    assert_eq!(keys, vec![east, west]);
    let fill = |k: TileKey| Some(height_tile(&grid, k, move |_, _| if k == west { 300.0 } else { 100.0 }));
    let heights = resample_heights(&grid, 0, 3, 7, 3, &fetch(&grid, 0, (3, 7, 3), SampleKind::Corner, fill));
    let step = grid.sample_step(0);
    for c in [0, 200, 250, 255] {
        let (lon, _) = reference_corner(3, 7, 3, c, 0);
        let gx = (lon + 180.0) / step;
        // Between sample 31 (east tile) and 32 (= column 0's first, at -180).
        let w = gx - 31.0;
        let want = if w > 0.0 { 100.0 * (1.0 - w) + 300.0 * w } else { 100.0 };
        let got = f64::from(heights[c]);
        assert!((got - want).abs() < 1e-3, "column {c}: {got} vs {want}");
    }
    // And colour at x = 0: its first pixels blend column 1's last texel
    // (east of 168.75) into column 0's first.
    let keys = source_keys(&grid, 0, 3, 0, 3, SampleKind::TexelWithBorder);
    assert_eq!(keys, vec![east, west]);
    let (red, blue) = ([255, 0, 0, 255], [0, 0, 255, 255]);
    let tiles = fetch(&grid, 0, (3, 0, 3), SampleKind::TexelWithBorder, |k| {
        Some(color_tile(&grid, if k == east { red } else { blue }))
    });
    let rgba = resample_colors(&grid, 0, 3, 0, 3, &tiles);
    let (lon, _) = reference_centre(3, 0, 3, 0, 0);
    let u = (lon + 180.0) / step - 0.5; // texel coordinate, -0.49 here
    let red_weight = -u;
    assert!(red_weight > 0.4 && red_weight < 0.5);
    let want = [(255.0 * red_weight).round() as u8, 0, (255.0 * (1.0 - red_weight)).round() as u8, 255];
    for (a, b) in rgba[0].iter().zip(want) {
        assert!(a.abs_diff(b) <= 1, "{:?} vs {want:?}", rgba[0]);
    }
}

#[test]
fn a_constant_colour_stays_constant_even_at_the_poles() {
    let colour = [200, 100, 50, 255];
    let translucent = [10, 220, 130, 77];
    for (n, level, (z, x, y)) in
        [(16, 0u8, (0u8, 0u32, 0u32)), (16, 2, (4, 3, 15)), (256, 3, (5, 31, 0)), (64, 4, (2, 2, 1))]
    {
        let grid = TileGrid::geodetic(n).unwrap();
        for c in [colour, translucent] {
            let tiles = fetch(&grid, level, (z, x, y), SampleKind::TexelWithBorder, |_| Some(color_tile(&grid, c)));
            let rgba = resample_colors(&grid, level, z, x, y, &tiles);
            assert!(rgba.iter().all(|p| *p == c), "n {n} {z}/{x}/{y}: {:?}", rgba.iter().find(|p| **p != c));
        }
    }
}

#[test]
fn a_transparent_neighbour_lowers_alpha_only_at_the_seam() {
    // Level 3 (22.5-degree columns of 16 texels); XYZ 3/4/3 spans 0..45,
    // across the column edge at 22.5. Columns 9 on (east of 22.5) are
    // transparent, missing altogether, or present but clear: the same
    // either way.
    let grid = TileGrid::geodetic(16).unwrap();
    let (level, z, x, y) = (3u8, 3u8, 4u32, 3u32);
    let colour = [200, 100, 50, 255];
    let clear_col = 9u32;
    for missing in [false, true] {
        let tiles = fetch(&grid, level, (z, x, y), SampleKind::TexelWithBorder, |k| {
            if k.x < clear_col {
                Some(color_tile(&grid, colour))
            } else if missing {
                None
            } else {
                Some(color_tile(&grid, [0, 0, 0, 0]))
            }
        });
        let rgba = resample_colors(&grid, level, z, x, y, &tiles);
        let step = grid.sample_step(level);
        let first_clear = f64::from(clear_col * 16);
        let mut seam = 0;
        for c in 0..SIDE {
            let (lon, _) = reference_centre(z, x, y, c, 0);
            let u = (lon + 180.0) / step - 0.5;
            let t0 = u.floor();
            let opaque_weight = if t0 + 1.0 < first_clear {
                1.0
            } else if t0 >= first_clear {
                0.0
            } else {
                seam += 1;
                1.0 - (u - t0)
            };
            for r in [0, 128, 255] {
                let p = rgba[r * SIDE + c];
                let want = (255.0 * opaque_weight).round() as u8;
                assert!(p[3].abs_diff(want) <= 1, "column {c}: alpha {} vs {want}", p[3]);
                if p[3] > 0 {
                    // The colour never darkens towards the clear side.
                    assert_eq!(p[..3], colour[..3], "column {c}");
                }
            }
        }
        // The pixels between the last opaque and the first clear texel
        // centres: 22.5 / 16 degrees over 45 / 256 per pixel.
        assert_eq!(seam, 8);
        // Half way between the texel centres, at the seam: pixels 127 and
        // 128 stand either side of it, their alphas about half, summing to 255.
        let (a, b) = (rgba[127][3], rgba[128][3]);
        assert!(a.abs_diff(128) <= 16 && b.abs_diff(128) <= 16 && (u16::from(a) + u16::from(b)).abs_diff(255) <= 1);
    }
}

#[test]
fn missing_tiles_and_foreign_payloads_read_as_nodata() {
    let grid = TileGrid::geodetic(16).unwrap();
    let keys = source_keys(&grid, 2, 3, 3, 3, SampleKind::Corner);
    let none: Vec<_> = keys.iter().map(|&k| (k, None)).collect();
    assert!(resample_heights(&grid, 2, 3, 3, 3, &none).iter().all(|h| h.is_nan()));
    // A colour tile where heights are wanted, or a height tile of the wrong size.
    let wrong: Vec<_> = keys
        .iter()
        .enumerate()
        .map(|(n, &k)| {
            let p = if n % 2 == 0 {
                color_tile(&grid, [1, 2, 3, 4])
            } else {
                Arc::new(Payload::Height(HeightTile { size: 3, heights: vec![0.0; 9] }))
            };
            (k, Some(p))
        })
        .collect();
    assert!(resample_heights(&grid, 2, 3, 3, 3, &wrong).iter().all(|h| h.is_nan()));
    assert!(resample_colors(&grid, 2, 3, 3, 3, &none).iter().all(|p| *p == [0; 4]));
}

#[test]
fn a_projected_grid_has_no_xyz_tiles() {
    let grid = TileGrid::new(
        GridKind::Projected(ProjectedGrid {
            crs: "EPSG:26912".into(),
            min_x: 420_000.0,
            min_y: 5_090_000.0,
            size: 4096.0,
        }),
        64,
    )
    .unwrap();
    assert!(source_keys(&grid, 3, 2, 1, 1, SampleKind::Corner).is_empty());
    assert!(resample_heights(&grid, 3, 2, 1, 1, &[]).iter().all(|h| h.is_nan()));
    assert!(resample_colors(&grid, 3, 2, 1, 1, &[]).iter().all(|p| *p == [0; 4]));
}

#[test]
fn source_keys_are_the_tiles_under_the_footprint() {
    // Independently: every geodetic tile whose (closed, one-sample-dilated)
    // extent touches a pixel centre. The plan may read fewer (a centre on
    // an edge reads one side), never one outside.
    let grid = TileGrid::geodetic(64).unwrap();
    for (level, (z, x, y)) in [(5u8, (3u8, 2u32, 1u32)), (2, (6, 40, 20)), (0, (2, 3, 0))] {
        let keys = source_keys(&grid, level, z, x, y, SampleKind::Corner);
        let mut seen = std::collections::HashSet::new();
        let lons: Vec<f64> = (0..SIDE).map(|c| reference_centre(z, x, y, c, 0).0).collect();
        let lats: Vec<f64> = (0..SIDE).map(|r| reference_centre(z, x, y, 0, r).1).collect();
        for &k in &keys {
            assert!(seen.insert(k), "{k} twice");
            let e = grid.tile_extent(k).dilate(grid.sample_step(level), grid.sample_step(level));
            // Longitudes round the planet: the last column reads column 0.
            let near =
                lons.iter().any(|&lon| [-360.0, 0.0, 360.0].iter().any(|t| (e.min_x..=e.max_x).contains(&(lon + t))))
                    && lats.iter().any(|&lat| (e.min_y..=e.max_y).contains(&lat));
            assert!(near, "{k} is not under {z}/{x}/{y}");
        }
        // And every tile holding a pixel centre is there.
        for c in (0..SIDE).step_by(7) {
            for r in (0..SIDE).step_by(7) {
                let (lon, lat) = reference_centre(z, x, y, c, r);
                let owner = grid.key_at(level, lon, lat).unwrap();
                assert!(keys.contains(&owner), "{owner} missing for {z}/{x}/{y}");
            }
        }
    }
}
