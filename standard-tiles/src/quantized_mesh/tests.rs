use std::collections::HashMap;
use std::io::Read as _;

use relief_source::{GridKind, HeightTile, ProjectedGrid};

use super::*;
use crate::decode::{Decoded, decode, oct_decode};
use crate::{EdgeVertices, Rtin};

const CELLS: usize = 64;

fn grid() -> TileGrid {
    TileGrid::geodetic(CELLS as u32).unwrap()
}

/// A tile of `key` sampling `f` at global sample coordinates, so that
/// neighbours share their edge samples as relief's grid does.
fn global_tile(cells: usize, key: TileKey, f: impl Fn(f64, f64) -> f64) -> HeightTile {
    let size = cells + 1;
    let (x0, y0) = ((key.x as usize * cells) as f64, (key.y as usize * cells) as f64);
    let mut heights = Vec::with_capacity(size * size);
    for j in 0..size {
        for i in 0..size {
            heights.push(f(x0 + i as f64, y0 + j as f64) as f32);
        }
    }
    HeightTile { size, heights }
}

fn hill(x: f64, y: f64) -> f64 {
    1200.0 * (-((x - 700.0).powi(2) + (y - 420.0).powi(2)) / (2.0 * 15.0f64.powi(2))).exp() + 0.3 * x + 50.0
}

/// Per decoded vertex: (i, j) in (fractional) samples from the
/// north-west, and the height in metres.
fn dequantized(d: &Decoded, cells: usize) -> Vec<(f64, f64, f64)> {
    let n = cells as f64;
    (0..d.u.len())
        .map(|k| {
            let h = f64::from(d.min_height)
                + f64::from(d.h[k]) / 32767.0 * (f64::from(d.max_height) - f64::from(d.min_height));
            (f64::from(d.u[k]) / 32767.0 * n, n - f64::from(d.v[k]) / 32767.0 * n, h)
        })
        .collect()
}

/// Everything the spec says of one encoded tile, checked against the
/// mesh it came from.
fn check_round_trip(mesh: &TerrainMesh, grid: &TileGrid, key: TileKey, bytes: &[u8]) -> Decoded {
    let d = decode(bytes);
    let cells = mesh.cells;
    let vertices = dequantized(&d, cells);
    let used: std::collections::HashSet<u32> = mesh.triangles.iter().flatten().copied().collect();
    assert_eq!(d.u.len(), used.len());
    // Positions within half a quantization step (in samples: cells / 32767).
    let step = cells as f64 / 32767.0;
    let position = |k: u32| {
        let (x, y, _) = vertices[k as usize];
        let (i, j) = (x.round(), y.round());
        assert!((x - i).abs() <= step / 2.0 + 1e-9 && (y - j).abs() <= step / 2.0 + 1e-9);
        [i as u32, j as u32]
    };
    // Triangles identical, in order and winding.
    assert_eq!(d.triangles.len(), mesh.triangles.len());
    let height_step = (f64::from(d.max_height) - f64::from(d.min_height)) / 32767.0;
    for (got, want) in d.triangles.iter().zip(&mesh.triangles) {
        for (g, w) in got.iter().zip(want) {
            assert_eq!(position(*g), mesh.vertices[*w as usize]);
            let h = vertices[*g as usize].2;
            let original = mesh.heights[*w as usize];
            assert!((h - original).abs() <= height_step / 2.0 + 1e-3, "height {h} for {original}");
        }
    }
    // Heights within min and max, which are the mesh's (to f32).
    let (lo, hi) = mesh.heights.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| (l.min(x), h.max(x)));
    assert_eq!((d.min_height, d.max_height), (lo as f32, hi as f32));
    for &(_, _, h) in &vertices {
        assert!(h >= f64::from(d.min_height) && h <= f64::from(d.max_height));
    }
    // Edge lists: every vertex on an edge, in its edge's list, in order.
    let n = cells as u32;
    let on_edge = |pred: &dyn Fn([u32; 2]) -> bool| -> Vec<u32> {
        (0..d.u.len() as u32).filter(|&k| pred(position(k))).collect()
    };
    for (list, pred, along) in [
        (&d.west, &(|[i, _]: [u32; 2]| i == 0) as &dyn Fn([u32; 2]) -> bool, 1usize),
        (&d.south, &|[_, j]: [u32; 2]| j == n, 0),
        (&d.east, &|[i, _]: [u32; 2]| i == n, 1),
        (&d.north, &|[_, j]: [u32; 2]| j == 0, 0),
    ] {
        let mut want = on_edge(pred);
        let mut got = list.clone();
        got.sort_unstable();
        want.sort_unstable();
        assert_eq!(got, want);
        // West and east south to north (v up), south and north west to east.
        let keys: Vec<u16> = list.iter().map(|&k| if along == 1 { d.v[k as usize] } else { d.u[k as usize] }).collect();
        assert!(keys.windows(2).all(|w| w[0] < w[1]), "edge list out of order: {keys:?}");
    }
    // Every dequantized vertex inside the bounding sphere; the centre
    // is the tile's at mid-height.
    let extent = grid.tile_extent(key);
    for &(x, y, h) in &vertices {
        let lon = extent.min_x + extent.width() * x / cells as f64;
        let lat = extent.max_y - extent.height() * y / cells as f64;
        let p = ecef_from_geodetic(lon, lat, h);
        assert!(distance(p, d.sphere_center) <= d.sphere_radius + 1e-6);
    }
    let mid = ecef_from_geodetic(
        f64::midpoint(extent.min_x, extent.max_x),
        f64::midpoint(extent.min_y, extent.max_y),
        f64::midpoint(lo, hi),
    );
    assert!(distance(mid, d.center) < 1e-6);
    d
}

/// Cesium's `EllipsoidalOccluder.isScaledSpacePointVisible`.
fn cesium_sees(camera: [f64; 3], occludee: [f64; 3]) -> bool {
    let vh2 = dot(camera, camera) - 1.0;
    let vt = [0, 1, 2].map(|k| occludee[k] - camera[k]);
    let vt_dot_vc = -dot(vt, camera);
    let occluded =
        if vh2 < 0.0 { vt_dot_vc > 0.0 } else { vt_dot_vc > vh2 && vt_dot_vc * vt_dot_vc / dot(vt, vt) > vh2 };
    !occluded
}

/// Whether scaled point `p` (lifted to the unit sphere if below it) is
/// truly in sight of `camera` over the unit sphere.
fn truly_visible(camera: [f64; 3], p: [f64; 3]) -> bool {
    let m = dot(p, p).sqrt();
    let p = if m < 1.0 { p.map(|c| c / m) } else { p };
    let d = [0, 1, 2].map(|k| p[k] - camera[k]);
    let t = (-dot(camera, d) / dot(d, d)).clamp(0.0, 1.0);
    let closest = [0, 1, 2].map(|k| camera[k] + t * d[k]);
    dot(closest, closest) >= 1.0 - 1e-9
}

#[test]
fn a_tile_round_trips_through_an_independent_decoder() {
    let grid = grid();
    let key = TileKey::new(3, 10, 6);
    let rtin = Rtin::new(&global_tile(CELLS, key, hill)).unwrap();
    for knob in [0.0, 0.5, 5.0, 100.0] {
        let mesh = rtin.mesh(knob);
        for octvertexnormals in [false, true] {
            let bytes =
                encode_quantized_mesh(&mesh, &grid, key, EncodeOptions { octvertexnormals, watermask: None }).unwrap();
            let d = check_round_trip(&mesh, &grid, key, &bytes);
            assert_eq!(d.extensions.len(), usize::from(octvertexnormals));
            if octvertexnormals {
                assert_eq!(d.extensions[0].0, 1);
                assert_eq!(d.extensions[0].1.len(), 2 * d.u.len());
            }
            let mut unzipped = Vec::new();
            flate2::read::GzDecoder::new(&gzip(&bytes)[..]).read_to_end(&mut unzipped).unwrap();
            assert_eq!(unzipped, bytes);
        }
    }
}

#[test]
fn normals_at_the_poles_face_up() {
    let grid = grid();
    // Level 0's tiles: each has its whole top row at the north pole and
    // its bottom row at the south pole; a flat tile.
    for key in [TileKey::new(0, 0, 0), TileKey::new(0, 1, 0)] {
        let mesh = Rtin::new(&global_tile(CELLS, key, |_, _| 0.0)).unwrap().mesh(1.0);
        let options = EncodeOptions { octvertexnormals: true, watermask: None };
        let d = check_round_trip(&mesh, &grid, key, &encode_quantized_mesh(&mesh, &grid, key, options).unwrap());
        let normals = &d.extensions[0].1;
        for k in 0..d.u.len() {
            let lat = -90.0 + 180.0 * f64::from(d.v[k]) / MAX_QUANTIZED;
            let lon = grid.tile_extent(key).min_x + 180.0 * f64::from(d.u[k]) / MAX_QUANTIZED;
            let up = enu_axes(lon, lat)[2];
            let got = oct_decode(normals[2 * k], normals[2 * k + 1]);
            assert!(dot(got, up) > 0.99, "{key} vertex at ({lon}, {lat}): normal {got:?}, up {up:?}");
        }
    }
}

#[test]
fn a_water_mask_follows_the_normals_whole_or_as_one_byte() {
    let grid = grid();
    let key = TileKey::new(3, 10, 6);
    let mesh = Rtin::new(&global_tile(CELLS, key, hill)).unwrap().mesh(5.0);
    let mixed: Vec<u8> = (0..WATER_MASK_SIZE * WATER_MASK_SIZE).map(|k| if k % 7 == 0 { 255 } else { 0 }).collect();
    let all_water = vec![255u8; WATER_MASK_SIZE * WATER_MASK_SIZE];
    for (mask, written) in [(&mixed[..], &mixed[..]), (&all_water[..], &[255u8][..])] {
        let options = EncodeOptions { octvertexnormals: true, watermask: Some(mask) };
        let d = check_round_trip(&mesh, &grid, key, &encode_quantized_mesh(&mesh, &grid, key, options).unwrap());
        assert_eq!(d.extensions.iter().map(|(id, _)| *id).collect::<Vec<_>>(), [1, 2]);
        assert_eq!(d.extensions[1].1, written);
    }
    let short = EncodeOptions { octvertexnormals: false, watermask: Some(&mixed[..100]) };
    assert!(matches!(
        encode_quantized_mesh(&mesh, &grid, key, short),
        Err(StandardTileError::WaterMaskSize { cells: 100 })
    ));
}

#[test]
fn more_than_65536_vertices_take_32_bit_indices_after_padding() {
    let grid = TileGrid::geodetic(256).unwrap();
    let key = TileKey::new(6, 40, 20);
    // Noise at every sample: a knob of 0 keeps all 257^2 = 66049 (odd) vertices.
    let tile = global_tile(256, key, |x, y| ((x * 12.9898 + y * 78.233).sin() * 43758.5453).fract() * 10.0);
    let rtin = Rtin::new(&tile).unwrap();
    let mesh = rtin.mesh(0.0);
    assert_eq!(mesh.vertices.len(), 257 * 257);
    let bytes =
        encode_quantized_mesh(&mesh, &grid, key, EncodeOptions { octvertexnormals: true, watermask: None }).unwrap();
    // 88 + 4 + 6 * 66049 is 2 past a multiple of 4: two bytes of padding.
    assert_eq!(&bytes[88 + 4 + 6 * 66049..][..2], &[0, 0]);
    check_round_trip(&mesh, &grid, key, &bytes);
}

#[test]
fn the_horizon_occlusion_point_hides_the_tile_only_when_no_vertex_is_in_sight() {
    let grid = grid();
    for key in [TileKey::new(3, 10, 6), TileKey::new(1, 0, 0), TileKey::new(5, 63, 31)] {
        let rtin = Rtin::new(&global_tile(CELLS, key, |x, y| hill(x, y) - 400.0)).unwrap();
        let mesh = rtin.mesh(1.0);
        let bytes = encode_quantized_mesh(&mesh, &grid, key, EncodeOptions::default()).unwrap();
        let d = decode(&bytes);
        let extent = grid.tile_extent(key);
        let points: Vec<[f64; 3]> = dequantized(&d, CELLS)
            .into_iter()
            .map(|(x, y, h)| {
                let lon = extent.min_x + extent.width() * x / CELLS as f64;
                let lat = extent.max_y - extent.height() * y / CELLS as f64;
                scaled(ecef_from_geodetic(lon, lat, h))
            })
            .collect();
        let (mut culled, mut seen) = (0, 0);
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..3000 {
            let mut next = || {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                (seed >> 11) as f64 / (1u64 << 53) as f64
            };
            let dir = normalize([next() - 0.5, next() - 0.5, next() - 0.5]);
            let r = 1.0 + 2.0 * next().powi(3);
            let camera = dir.map(|c| c * r);
            if points.iter().any(|&p| truly_visible(camera, p)) {
                assert!(cesium_sees(camera, d.horizon), "{key}: culled though a vertex is in sight");
                seen += 1;
            } else if !cesium_sees(camera, d.horizon) {
                culled += 1;
            }
        }
        assert!(seen > 0 && culled > 0, "{key}: seen {seen}, culled {culled}");
    }
}

#[test]
fn normals_point_up_on_flat_ground_and_downhill_on_a_slope() {
    let grid = grid();
    // Small enough (0.04 degrees) that two triangles hardly bend with the ellipsoid.
    let key = TileKey::new(12, 4000, 1000);
    let extent = grid.tile_extent(key);
    for (name, f, tilt) in [("flat", (|_, _| 0.0) as fn(f64, f64) -> f64, false), ("slope", |x, _| 40.0 * x, true)] {
        let rtin = Rtin::new(&global_tile(CELLS, key, f)).unwrap();
        let mesh = rtin.mesh(0.0);
        let bytes = encode_quantized_mesh(&mesh, &grid, key, EncodeOptions { octvertexnormals: true, watermask: None })
            .unwrap();
        let d = decode(&bytes);
        let normals = &d.extensions[0].1;
        for (k, (x, y, _)) in dequantized(&d, CELLS).into_iter().enumerate() {
            let n = oct_decode(normals[2 * k], normals[2 * k + 1]);
            let lon = extent.min_x + extent.width() * x / CELLS as f64;
            let lat = extent.max_y - extent.height() * y / CELLS as f64;
            let [east, _, up] = enu_axes(lon, lat);
            if tilt {
                // Rising east: the normal leans west.
                assert!(dot(n, east) < -0.05 && dot(n, up) > 0.5, "{name}: {n:?}");
            } else {
                assert!(dot(n, up) > 0.999, "{name}: {n:?}");
            }
        }
    }
    // Oct encoding agrees with Cesium's on the axes.
    assert_eq!(oct_encode([0.0, 0.0, 1.0]), [128, 128]);
    assert_eq!(oct_encode([1.0, 0.0, 0.0]), [255, 128]);
    assert_eq!(oct_encode([0.0, 0.0, -1.0]), [255, 255]);
}

#[test]
fn only_the_geodetic_grid_is_encoded() {
    let projected = TileGrid::new(
        GridKind::Projected(ProjectedGrid { crs: "EPSG:32612".into(), min_x: 0.0, min_y: 0.0, size: 1000.0 }),
        64,
    )
    .unwrap();
    let mesh = Rtin::new(&global_tile(CELLS, TileKey::new(0, 0, 0), hill)).unwrap().mesh(1.0);
    let err = encode_quantized_mesh(&mesh, &projected, TileKey::new(0, 0, 0), EncodeOptions::default());
    assert!(matches!(err, Err(StandardTileError::NotGeodetic { .. })));
    let err = encode_quantized_mesh(&mesh, &grid(), TileKey::new(0, 2, 0), EncodeOptions::default());
    assert!(matches!(err, Err(StandardTileError::KeyOutsideGrid { .. })));
}

/// The shared edge of west tile `a` and east tile `b`: per tile, its
/// edge vertices (j, metres) from the decoded edge lists, south to north.
fn shared_edge(a: &Decoded, b: &Decoded) -> [Vec<(f64, f64)>; 2] {
    let pick = |d: &Decoded, list: &[u32]| {
        let v = dequantized(d, CELLS);
        list.iter().map(|&k| (v[k as usize].1, v[k as usize].2)).collect::<Vec<_>>()
    };
    [pick(a, &a.east), pick(b, &b.west)]
}

/// The height along an edge polyline at row `j` (linear between its
/// vertices, which run south to north: j descending).
fn along(edge: &[(f64, f64)], j: f64) -> f64 {
    for w in edge.windows(2) {
        let ((j0, h0), (j1, h1)) = (w[0], w[1]);
        if j <= j0 + 1e-6 && j >= j1 - 1e-6 {
            return h0 + (h1 - h0) * (j0 - j) / (j0 - j1);
        }
    }
    panic!("row {j} is off the edge");
}

#[test]
fn neighbours_meet_without_cracks_at_any_knob() {
    let grid = grid();
    let (west, east) = (TileKey::new(3, 10, 6), TileKey::new(3, 11, 6));
    // A hill astride the edge, and a plane with a peak deep in the east
    // tile, whose splits pull vertices onto the east tile's side only.
    let inside = |x: f64, y: f64| {
        0.3 * x + 900.0 * (-((x - 735.0).powi(2) + (y - 400.0).powi(2)) / (2.0 * 6.0f64.powi(2))).exp()
    };
    let mut differed = false;
    for edges in [EdgeVertices::AsNeeded, EdgeVertices::EverySample] {
        for f in [hill as fn(f64, f64) -> f64, inside] {
            let ra = Rtin::with_edges(&global_tile(CELLS, west, f), edges).unwrap();
            let rb = Rtin::with_edges(&global_tile(CELLS, east, f), edges).unwrap();
            for knob in [0.0, 3.0, 30.0] {
                let (ma, mb) = (ra.mesh(knob), rb.mesh(knob));
                assert!(ma.max_error_m(ra.heights()) <= knob && mb.max_error_m(rb.heights()) <= knob);
                // Mesh level: shared positions have the very same heights.
                let edge_of = |m: &TerrainMesh, i: u32| -> HashMap<u32, f64> {
                    m.vertices.iter().zip(&m.heights).filter(|(v, _)| v[0] == i).map(|(v, h)| (v[1], *h)).collect()
                };
                let (ea, eb) = (edge_of(&ma, CELLS as u32), edge_of(&mb, 0));
                for (j, h) in &ea {
                    if let Some(hb) = eb.get(j) {
                        assert_eq!(h, hb);
                    }
                }
                if edges == EdgeVertices::EverySample {
                    assert_eq!(ea.len(), CELLS + 1);
                    assert_eq!(ea, eb, "every edge sample on both sides");
                }
                differed |= ea != eb;
                let a = decode(&encode_quantized_mesh(&ma, &grid, west, EncodeOptions::default()).unwrap());
                let b = decode(&encode_quantized_mesh(&mb, &grid, east, EncodeOptions::default()).unwrap());
                let [pa, pb] = shared_edge(&a, &b);
                let quantum = |d: &Decoded| (f64::from(d.max_height) - f64::from(d.min_height)) / 32767.0;
                let slack = quantum(&a) + quantum(&b) + 2e-3;
                // The two edge polylines, from the decoded edge lists
                // alone, part by at most twice the knob (each is within
                // it of the samples), by nothing past quantization at a
                // knob of 0 or with every edge sample kept: skirts at
                // least twice the knob deep close any gap.
                let mut gap = 0.0f64;
                for j in 0..=CELLS {
                    let j = j as f64;
                    gap = gap.max((along(&pa, j) - along(&pb, j)).abs());
                }
                assert!(gap <= 2.0 * knob + slack, "knob {knob}: gap {gap}");
                if knob == 0.0 || edges == EdgeVertices::EverySample {
                    assert!(gap <= slack, "{edges:?}, knob {knob}: gap {gap}");
                }
            }
        }
    }
    assert!(differed, "no loose knob put different vertices on the shared edge: the skirt case went untested");
}
