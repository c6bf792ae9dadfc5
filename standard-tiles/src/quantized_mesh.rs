//! The quantized-mesh-1.0 encoder (github.com/CesiumGS/quantized-mesh):
//! little-endian throughout, in this order:
//!
//! 1. the 88-byte header: centre (ECEF), minimum and maximum height, bounding
//!    sphere, horizon occlusion point (ellipsoid-scaled ECEF);
//! 2. vertex data: the count, then u, v and height, each quantized to
//!    0..=32767 and zig-zag delta encoded;
//! 3. index data: padding to 2 bytes (16-bit indices) or 4 (32-bit, when
//!    there are more than 65536 vertices), the triangle count, then the
//!    indices high-water-mark encoded;
//! 4. edge indices: west, south, east and north, each a count and plain
//!    indices (west and east from south to north, south and north from west
//!    to east);
//! 5. extensions: `octvertexnormals` (id 1) when asked for.
//!
//! Edge lists are what a client hangs its skirts from: two neighbours whose
//! meshes put different vertices on their shared edge leave gaps of at most
//! twice the knob, which Cesium's skirts (walls dropped below every edge
//! vertex) close; see [`crate::EdgeVertices`] for edges that need none.

use std::io::Write as _;

use relief_source::geodesy::{WGS84_A, WGS84_B, ecef_from_geodetic, enu_axes};
use relief_source::{TileGrid, TileKey};

use crate::{StandardTileError, TerrainMesh};

/// The largest quantized u, v or height.
const MAX_QUANTIZED: f64 = 32767.0;
/// The extension id of oct-encoded per-vertex normals.
const OCT_VERTEX_NORMALS: u8 = 1;
/// The extension id of the water mask.
const WATER_MASK: u8 = 2;
/// Cells a side of a full water mask.
pub const WATER_MASK_SIZE: usize = 256;

/// Which optional parts to write (the client's `Accept` extensions).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EncodeOptions<'a> {
    pub octvertexnormals: bool,
    /// The `watermask` extension: 0 land to 255 water per cell,
    /// [`WATER_MASK_SIZE`] a side from the north-west corner, row by row
    /// (written as one byte when every cell is the same).
    pub watermask: Option<&'a [u8]>,
}

/// The quantized-mesh header, in the order the file holds it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuantizedMeshHeader {
    pub center_ecef: [f64; 3],
    pub min_height_m: f32,
    pub max_height_m: f32,
    pub bounding_sphere_center_ecef: [f64; 3],
    pub bounding_sphere_radius_m: f64,
    /// Ellipsoid-scaled ECEF (each axis divided by the ellipsoid's radius).
    pub horizon_occlusion_point: [f64; 3],
}

impl QuantizedMeshHeader {
    pub const BYTES: usize = 88;

    fn write_to(&self, out: &mut Vec<u8>) {
        for v in self.center_ecef {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.min_height_m.to_le_bytes());
        out.extend_from_slice(&self.max_height_m.to_le_bytes());
        for v in self.bounding_sphere_center_ecef {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.bounding_sphere_radius_m.to_le_bytes());
        for v in self.horizon_occlusion_point {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
}

/// One tile of quantized-mesh-1.0 terrain (uncompressed; see [`gzip`]).
/// `key` is relief's (y from the north); the URL's TMS row comes from
/// [`crate::tms_from_key`]. Only the geodetic grid can be encoded.
pub fn encode_quantized_mesh(
    mesh: &TerrainMesh,
    grid: &TileGrid,
    key: TileKey,
    options: EncodeOptions<'_>,
) -> Result<Vec<u8>, StandardTileError> {
    if !grid.is_geodetic() {
        return Err(StandardTileError::NotGeodetic { crs: grid.crs().to_owned() });
    }
    if !grid.contains_key(key) {
        return Err(StandardTileError::KeyOutsideGrid { key });
    }
    if mesh.triangles.is_empty() {
        return Err(StandardTileError::EmptyMesh);
    }
    // Vertices in the order the triangles first name them, as the
    // high-water-mark code needs; unused vertices are dropped.
    let mut order = Vec::with_capacity(mesh.vertices.len());
    let mut new_index = vec![u32::MAX; mesh.vertices.len()];
    let triangles: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .map(|t| {
            t.map(|v| {
                if new_index[v as usize] == u32::MAX {
                    new_index[v as usize] = order.len() as u32;
                    order.push(v as usize);
                }
                new_index[v as usize]
            })
        })
        .collect();
    let cells = mesh.cells as f64;
    let extent = grid.tile_extent(key);
    let (width, height) = (extent.width(), extent.height());
    let sample = |v: usize| {
        let [i, j] = mesh.vertices[v];
        (f64::from(i), f64::from(j), mesh.heights[v])
    };
    let lon_lat = |i: f64, j: f64| (extent.min_x + width * i / cells, extent.max_y - height * j / cells);

    let (lo, hi) = order
        .iter()
        .map(|&v| mesh.heights[v])
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), h| (lo.min(h), hi.max(h)));
    let (min_height_m, max_height_m) = (lo as f32, hi as f32);
    let (min_f, max_f) = (f64::from(min_height_m), f64::from(max_height_m));
    let quantize = |x: f64| x.clamp(0.0, MAX_QUANTIZED).round() as u16;
    let us: Vec<u16> = order.iter().map(|&v| quantize(sample(v).0 / cells * MAX_QUANTIZED)).collect();
    let vs: Vec<u16> = order.iter().map(|&v| quantize((cells - sample(v).1) / cells * MAX_QUANTIZED)).collect();
    let hs: Vec<u16> = order
        .iter()
        .map(|&v| if max_f > min_f { quantize((mesh.heights[v] - min_f) / (max_f - min_f) * MAX_QUANTIZED) } else { 0 })
        .collect();
    // The geometry the client will see: the dequantized vertices.
    let points: Vec<[f64; 3]> = (0..order.len())
        .map(|k| {
            let lon = extent.min_x + width * f64::from(us[k]) / MAX_QUANTIZED;
            let lat = extent.min_y + height * f64::from(vs[k]) / MAX_QUANTIZED;
            ecef_from_geodetic(lon, lat, min_f + (max_f - min_f) * f64::from(hs[k]) / MAX_QUANTIZED)
        })
        .collect();
    let (center_lon, center_lat) = lon_lat(cells / 2.0, cells / 2.0);
    let center_ecef = ecef_from_geodetic(center_lon, center_lat, f64::midpoint(lo, hi));
    let (bounding_sphere_center_ecef, bounding_sphere_radius_m) = bounding_sphere(&points);
    let header = QuantizedMeshHeader {
        center_ecef,
        min_height_m,
        max_height_m,
        bounding_sphere_center_ecef,
        bounding_sphere_radius_m,
        horizon_occlusion_point: horizon_occlusion_point(center_ecef, &points),
    };

    let vertex_count = order.len();
    let mut out = Vec::with_capacity(QuantizedMeshHeader::BYTES + vertex_count * 8 + triangles.len() * 6 + 64);
    header.write_to(&mut out);
    out.extend_from_slice(&(vertex_count as u32).to_le_bytes());
    for values in [&us, &vs, &hs] {
        let mut previous = 0i32;
        for &value in values {
            let delta = i32::from(value) - previous;
            previous = i32::from(value);
            out.extend_from_slice(&(((delta << 1) ^ (delta >> 31)) as u16).to_le_bytes());
        }
    }

    let wide = vertex_count > 65536;
    let write_index = |out: &mut Vec<u8>, index: u32| {
        if wide {
            out.extend_from_slice(&index.to_le_bytes());
        } else {
            out.extend_from_slice(&(index as u16).to_le_bytes());
        }
    };
    let align = if wide { 4 } else { 2 };
    while out.len() % align != 0 {
        out.push(0);
    }
    out.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    let mut highest = 0u32;
    for &index in triangles.iter().flatten() {
        let code = highest - index;
        write_index(&mut out, code);
        if code == 0 {
            highest += 1;
        }
    }

    // West and east from south to north, south and north from west to east.
    let n = mesh.cells as u32;
    let edge = |on: &dyn Fn([u32; 2]) -> bool, along: &dyn Fn([u32; 2]) -> i64| {
        let mut list: Vec<u32> = (0..vertex_count as u32).filter(|&k| on(mesh.vertices[order[k as usize]])).collect();
        list.sort_by_key(|&k| along(mesh.vertices[order[k as usize]]));
        list
    };
    let south_to_north = |[_, j]: [u32; 2]| -i64::from(j);
    let west_to_east = |[i, _]: [u32; 2]| i64::from(i);
    for list in [
        edge(&|[i, _]| i == 0, &south_to_north),
        edge(&|[_, j]| j == n, &west_to_east),
        edge(&|[i, _]| i == n, &south_to_north),
        edge(&|[_, j]| j == 0, &west_to_east),
    ] {
        out.extend_from_slice(&(list.len() as u32).to_le_bytes());
        for index in list {
            write_index(&mut out, index);
        }
    }

    if options.octvertexnormals {
        let normals = vertex_normals(&points, &triangles);
        out.push(OCT_VERTEX_NORMALS);
        out.extend_from_slice(&(2 * vertex_count as u32).to_le_bytes());
        for (normal, &v) in normals.iter().zip(&order) {
            let [x, y] = if normal.iter().all(|c| *c == 0.0) {
                // A vertex of degenerate triangles only: the ellipsoid's up.
                let (i, j, _) = sample(v);
                let (lon, lat) = lon_lat(i, j);
                oct_encode(enu_axes(lon, lat)[2])
            } else {
                oct_encode(*normal)
            };
            out.push(x);
            out.push(y);
        }
    }
    if let Some(mask) = options.watermask {
        if mask.len() != WATER_MASK_SIZE * WATER_MASK_SIZE {
            return Err(StandardTileError::WaterMaskSize { cells: mask.len() });
        }
        out.push(WATER_MASK);
        if mask.iter().all(|&m| m == mask[0]) {
            out.extend_from_slice(&1u32.to_le_bytes());
            out.push(mask[0]);
        } else {
            out.extend_from_slice(&(mask.len() as u32).to_le_bytes());
            out.extend_from_slice(mask);
        }
    }
    Ok(out)
}

/// The smallest sphere centred on the points' bounding box that holds them
/// all (not the smallest sphere, but close on a tile's few degrees).
fn bounding_sphere(points: &[[f64; 3]]) -> ([f64; 3], f64) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let center = [0, 1, 2].map(|a| f64::midpoint(lo[a], hi[a]));
    let radius = points.iter().map(|p| distance(*p, center)).fold(0.0, f64::max);
    // A millimetre over, so that rounding never leaves a vertex outside.
    (center, radius + 1e-3)
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn scaled(p: [f64; 3]) -> [f64; 3] {
    [p[0] / WGS84_A, p[1] / WGS84_A, p[2] / WGS84_B]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let length = dot(a, a).sqrt();
    if length > 0.0 { a.map(|c| c / length) } else { a }
}

/// The horizon occlusion point as Cesium computes it
/// (`EllipsoidalOccluder.computeHorizonCullingPointFromPoints`): in the
/// ellipsoid-scaled frame, the point along the direction of
/// `direction_ecef` nearest the ellipsoid from which every one of
/// `points_ecef` is at or above the horizon; points below the ellipsoid
/// count as on it. When no such point exists (a tile of about a hemisphere,
/// such as level 0's), the point is put 1e6 radii out along the direction,
/// where Cesium culls the tile only from well behind the planet.
pub fn horizon_occlusion_point(direction_ecef: [f64; 3], points_ecef: &[[f64; 3]]) -> [f64; 3] {
    const FAR: f64 = 1e6;
    let direction = normalize(scaled(direction_ecef));
    let mut magnitude = 0.0f64;
    for &p in points_ecef {
        let s = scaled(p);
        let magnitude_squared = dot(s, s);
        let to_point = s.map(|c| c / magnitude_squared.sqrt());
        let magnitude_squared = magnitude_squared.max(1.0);
        let point_magnitude = magnitude_squared.sqrt();
        let cos_alpha = dot(to_point, direction);
        let c = cross(to_point, direction);
        let sin_alpha = dot(c, c).sqrt();
        let cos_beta = 1.0 / point_magnitude;
        let sin_beta = (magnitude_squared - 1.0).sqrt() * cos_beta;
        let candidate = 1.0 / (cos_alpha * cos_beta - sin_alpha * sin_beta);
        if !(candidate.is_finite() && candidate > 0.0) {
            magnitude = FAR;
            break;
        }
        magnitude = magnitude.max(candidate);
    }
    direction.map(|c| c * magnitude.min(FAR))
}

/// Per-vertex unit normals in ECEF: each the area-weighted sum of its
/// triangles' normals (triangles counter-clockwise from above point out).
/// Degenerate triangles count for nothing: a triangle with two corners at a
/// pole (the same point, to rounding: cos 90 degrees is 6e-17) has a face
/// normal that is rounding noise, in any direction. A vertex of only such
/// triangles gets none (the caller puts the ellipsoid's up there).
fn vertex_normals(points: &[[f64; 3]], triangles: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let mut normals = vec![[0.0; 3]; points.len()];
    for t in triangles {
        let [a, b, c] = t.map(|v| points[v as usize]);
        let (ab, ac) = ([0, 1, 2].map(|k| b[k] - a[k]), [0, 1, 2].map(|k| c[k] - a[k]));
        let bc = [0, 1, 2].map(|k| c[k] - b[k]);
        let face = cross(ab, ac);
        // Twice the area against the longest side squared: below 1e-9 is a
        // sliver no real surface makes (a 1 mm rise over 1000 km).
        let longest = dot(ab, ab).max(dot(ac, ac)).max(dot(bc, bc));
        if dot(face, face) <= 1e-18 * longest * longest {
            continue;
        }
        for &v in t {
            let n = &mut normals[v as usize];
            for k in 0..3 {
                n[k] += face[k];
            }
        }
    }
    normals.into_iter().map(normalize).collect()
}

/// A unit vector oct-encoded into two bytes, as Cesium's
/// `AttributeCompression.octEncode` does it.
pub fn oct_encode(unit: [f64; 3]) -> [u8; 2] {
    let l1 = unit[0].abs() + unit[1].abs() + unit[2].abs();
    let (mut x, mut y) = (unit[0] / l1, unit[1] / l1);
    if unit[2] < 0.0 {
        let sign = |v: f64| if v < 0.0 { -1.0 } else { 1.0 };
        (x, y) = ((1.0 - y.abs()) * sign(x), (1.0 - x.abs()) * sign(y));
    }
    let snorm = |v: f64| ((v.clamp(-1.0, 1.0) * 0.5 + 0.5) * 255.0).round() as u8;
    [snorm(x), snorm(y)]
}

/// Gzip, for clients that send `Accept-Encoding: gzip`.
pub fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(bytes).expect("writing to a Vec cannot fail");
    encoder.finish().expect("writing to a Vec cannot fail")
}

#[cfg(test)]
mod tests {
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
            let keys: Vec<u16> =
                list.iter().map(|&k| if along == 1 { d.v[k as usize] } else { d.u[k as usize] }).collect();
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
                    encode_quantized_mesh(&mesh, &grid, key, EncodeOptions { octvertexnormals, watermask: None })
                        .unwrap();
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
        let bytes = encode_quantized_mesh(&mesh, &grid, key, EncodeOptions { octvertexnormals: true, watermask: None })
            .unwrap();
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
        for (name, f, tilt) in [("flat", (|_, _| 0.0) as fn(f64, f64) -> f64, false), ("slope", |x, _| 40.0 * x, true)]
        {
            let rtin = Rtin::new(&global_tile(CELLS, key, f)).unwrap();
            let mesh = rtin.mesh(0.0);
            let bytes =
                encode_quantized_mesh(&mesh, &grid, key, EncodeOptions { octvertexnormals: true, watermask: None })
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
}
