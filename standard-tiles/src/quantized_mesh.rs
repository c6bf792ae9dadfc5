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
mod tests;
