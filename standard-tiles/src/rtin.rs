//! The right-triangulated irregular network (RTIN) of Evans et al. (2001),
//! laid out as Mapbox's Martini lays it out, over a height tile's
//! (2^k+1) x (2^k+1) corner-aligned samples.
//!
//! Martini's error of a triangle is the error at its hypotenuse's midpoint,
//! raised to its children's: a heuristic that a coarse triangle can exceed
//! (the children's errors are measured against the children, not against
//! it). Here a triangle's error is *exact*: the largest vertical distance
//! from any sample inside it (edges included) to its plane. Raising it to
//! the children's, and storing it at the hypotenuse's midpoint (shared by
//! the two triangles on either side of that hypotenuse), keeps Martini's
//! crack-free splitting, so every emitted triangle is within the knob and
//! the mesh is conforming.

use relief_source::HeightTile;

use crate::StandardTileError;

/// A height tile's RTIN: the filled heights and each split's error, computed
/// once; [`Rtin::mesh`] then cuts a mesh at any error.
#[derive(Debug, Clone)]
pub struct Rtin {
    /// Cells a side (N = 2^k); the tile has (N+1)^2 samples.
    cells: usize,
    heights: Vec<f64>,
    /// Per sample: the error of splitting the triangles whose hypotenuse's
    /// midpoint it is (0 for samples that are no such midpoint).
    errors: Vec<f64>,
}

/// Which of a tile's edge samples become vertices.
///
/// Two neighbours share their edge samples, but RTIN picks edge vertices
/// for the interior's sake too, so each tile may put different ones on the
/// shared edge: T-junctions. Both edge polylines lie within the knob of the
/// samples, so they part by at most twice the knob (not at all at a knob of
/// 0); a client closes that gap with skirts, walls hung below every edge
/// vertex from the edge lists, as Cesium does for all its terrain.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum EdgeVertices {
    /// Only those the knob needs (fewest triangles; skirts close the gaps).
    #[default]
    AsNeeded,
    /// Every edge sample: neighbours' edges are identical, watertight
    /// without skirts, at the cost of a strip of small triangles along each
    /// edge (some 8N triangles more at worst for N cells a side).
    EverySample,
}

/// A triangle mesh over a tile's samples.
#[derive(Debug, Clone, PartialEq)]
pub struct TerrainMesh {
    /// Cells a side of the tile (N); sample indices run 0..=N.
    pub cells: usize,
    /// Each vertex's sample: (i east, j south of the north-west corner).
    pub vertices: Vec<[u32; 2]>,
    /// Each vertex's height, metres (nodata filled, see [`Rtin::new`]).
    pub heights: Vec<f64>,
    /// Triangles, counter-clockwise seen from above (east, north).
    pub triangles: Vec<[u32; 3]>,
}

impl Rtin {
    /// The RTIN of a height tile of (2^k+1)^2 samples, k >= 1.
    ///
    /// Nodata (NaN) samples are filled before meshing: each pass sets every
    /// nodata sample that has a valid one among its 8 neighbours to the mean
    /// of those, until none is left; a tile with no valid sample is 0 m
    /// throughout. Two neighbours fill a hole on their shared edge alike only
    /// if the hole lies on the edge alone; elsewhere their skirts hide it.
    pub fn new(tile: &HeightTile) -> Result<Self, StandardTileError> {
        Self::with_edges(tile, EdgeVertices::AsNeeded)
    }

    /// [`Rtin::new`], with the tile's edge vertices chosen by `edges`.
    pub fn with_edges(tile: &HeightTile, edges: EdgeVertices) -> Result<Self, StandardTileError> {
        let size = tile.size;
        let cells = size.wrapping_sub(1);
        if size < 3 || !cells.is_power_of_two() {
            return Err(StandardTileError::NotPowerOfTwoPlusOne { samples: tile.heights.len() });
        }
        if tile.heights.len() != size * size {
            return Err(StandardTileError::WrongSampleCount {
                size,
                samples: tile.heights.len(),
                expected: size * size,
            });
        }
        let heights = fill_nodata(size, &tile.heights);
        let errors = split_errors(cells, &heights, edges);
        Ok(Self { cells, heights, errors })
    }

    pub fn cells(&self) -> usize {
        self.cells
    }

    /// The filled heights, row-major from the north-west.
    pub fn heights(&self) -> &[f64] {
        &self.heights
    }

    /// The coarsest RTIN mesh with every sample within
    /// `terrain_mesh_error_m` metres (vertically) of it. A plane gives two
    /// triangles (with [`EdgeVertices::AsNeeded`]); 0 keeps every bend. The
    /// knob must be finite.
    pub fn mesh(&self, terrain_mesh_error_m: f64) -> TerrainMesh {
        let n = self.cells as i64;
        let size = self.cells + 1;
        let mut index = vec![u32::MAX; size * size];
        let mut mesh = TerrainMesh { cells: self.cells, vertices: Vec::new(), heights: Vec::new(), triangles: vec![] };
        // (a, b, c): a-b is the hypotenuse, c the right angle.
        let mut stack = vec![[[n, n], [0, 0], [0, n]], [[0, 0], [n, n], [n, 0]]];
        while let Some([a, b, c]) = stack.pop() {
            let m = [i64::midpoint(a[0], b[0]), i64::midpoint(a[1], b[1])];
            let leg = (a[0] - c[0]).abs() + (a[1] - c[1]).abs();
            if leg > 1 && self.errors[m[1] as usize * size + m[0] as usize] > terrain_mesh_error_m {
                stack.push([b, c, m]);
                stack.push([c, a, m]);
                continue;
            }
            let mut tri = [a, b, c].map(|p| {
                let k = p[1] as usize * size + p[0] as usize;
                if index[k] == u32::MAX {
                    index[k] = mesh.vertices.len() as u32;
                    mesh.vertices.push([p[0] as u32, p[1] as u32]);
                    mesh.heights.push(self.heights[k]);
                }
                index[k]
            });
            // Counter-clockwise with y north is clockwise with j south.
            if cross(a, b, c) > 0 {
                tri.swap(1, 2);
            }
            mesh.triangles.push(tri);
        }
        mesh
    }
}

impl TerrainMesh {
    /// The largest vertical distance, metres, from any of `heights`'
    /// samples (the tile's, row-major) to this mesh.
    pub fn max_error_m(&self, heights: &[f64]) -> f64 {
        let size = self.cells + 1;
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| {
                    let [i, j] = self.vertices[v as usize];
                    [i64::from(i), i64::from(j)]
                });
                triangle_error(size, heights, a, b, c)
            })
            .fold(0.0, f64::max)
    }
}

impl TerrainMesh {
    /// The mesh's height at every sample of the tile, row-major from the
    /// north-west (NaN at a sample no triangle covers, which a mesh from
    /// [`Rtin::mesh`] never leaves).
    pub fn surface_heights(&self) -> Vec<f64> {
        let size = self.cells + 1;
        let mut out = vec![f64::NAN; size * size];
        for t in &self.triangles {
            let [a, b, c] = t.map(|v| {
                let [i, j] = self.vertices[v as usize];
                [i64::from(i), i64::from(j)]
            });
            let [ha, hb, hc] = t.map(|v| self.heights[v as usize]);
            let mut area2 = cross(a, b, c);
            let sign = if area2 < 0 { -1 } else { 1 };
            area2 *= sign;
            if area2 == 0 {
                continue;
            }
            for y in a[1].min(b[1]).min(c[1])..=a[1].max(b[1]).max(c[1]) {
                for x in a[0].min(b[0]).min(c[0])..=a[0].max(b[0]).max(c[0]) {
                    let p = [x, y];
                    let (wa, wb, wc) = (sign * cross(b, c, p), sign * cross(c, a, p), sign * cross(a, b, p));
                    if wa >= 0 && wb >= 0 && wc >= 0 {
                        out[y as usize * size + x as usize] =
                            (wa as f64 * ha + wb as f64 * hb + wc as f64 * hc) / area2 as f64;
                    }
                }
            }
        }
        out
    }
}

fn cross(a: [i64; 2], b: [i64; 2], c: [i64; 2]) -> i64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// The largest |sample - plane| over the samples inside triangle a, b, c
/// (integer sample coordinates), edges included. Integer barycentric
/// weights keep a plane of integer heights exact.
fn triangle_error(size: usize, heights: &[f64], a: [i64; 2], b: [i64; 2], c: [i64; 2]) -> f64 {
    let mut area2 = cross(a, b, c);
    let sign = if area2 < 0 { -1 } else { 1 };
    area2 *= sign;
    if area2 == 0 {
        return 0.0;
    }
    let h = |p: [i64; 2]| heights[p[1] as usize * size + p[0] as usize];
    let (ha, hb, hc) = (h(a), h(b), h(c));
    let (x0, x1) = (a[0].min(b[0]).min(c[0]), a[0].max(b[0]).max(c[0]));
    let (y0, y1) = (a[1].min(b[1]).min(c[1]), a[1].max(b[1]).max(c[1]));
    let mut worst = 0.0f64;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let p = [x, y];
            let (wa, wb, wc) = (sign * cross(b, c, p), sign * cross(c, a, p), sign * cross(a, b, p));
            if wa < 0 || wb < 0 || wc < 0 {
                continue;
            }
            let plane = (wa as f64 * ha + wb as f64 * hb + wc as f64 * hc) / area2 as f64;
            worst = worst.max((h(p) - plane).abs());
        }
    }
    worst
}

/// Every split's error, bottom-up over Martini's triangle numbering (ids
/// 2.., each level twice the last, down to hypotenuses of 2 cells).
fn split_errors(cells: usize, heights: &[f64], edges: EdgeVertices) -> Vec<f64> {
    let size = cells + 1;
    let n = cells as i64;
    let count = cells * cells * 2 - 2;
    let parents = count - cells * cells;
    let mut errors = vec![0.0f64; size * size];
    if edges == EdgeVertices::EverySample {
        // Every edge sample is the hypotenuse midpoint of a triangle along
        // the edge; an infinite error there splits it and, raised up the
        // levels, every triangle above it.
        for k in 1..cells {
            for s in [k, cells * size + k, k * size, k * size + cells] {
                errors[s] = f64::INFINITY;
            }
        }
    }
    for i in (0..count).rev() {
        let mut id = i + 2;
        let (mut a, mut b, mut c) = if id & 1 == 1 { ([0, 0], [n, n], [0, n]) } else { ([n, n], [0, 0], [n, 0]) };
        loop {
            id >>= 1;
            if id <= 1 {
                break;
            }
            let m = [(a[0] + b[0]) >> 1, (a[1] + b[1]) >> 1];
            if id & 1 == 1 {
                (a, b) = (c, a);
            } else {
                (a, b) = (b, c);
            }
            c = m;
        }
        let m = [(a[0] + b[0]) >> 1, (a[1] + b[1]) >> 1];
        let k = m[1] as usize * size + m[0] as usize;
        let mut e = errors[k].max(triangle_error(size, heights, a, b, c));
        if i < parents {
            let left = [(a[0] + c[0]) >> 1, (a[1] + c[1]) >> 1];
            let right = [(b[0] + c[0]) >> 1, (b[1] + c[1]) >> 1];
            e = e
                .max(errors[left[1] as usize * size + left[0] as usize])
                .max(errors[right[1] as usize * size + right[0] as usize]);
        }
        errors[k] = e;
    }
    errors
}

fn fill_nodata(size: usize, samples: &[f32]) -> Vec<f64> {
    let mut heights: Vec<f64> = samples.iter().map(|&h| f64::from(h)).collect();
    if heights.iter().all(|h| h.is_nan()) {
        return vec![0.0; size * size];
    }
    let mut holes: Vec<usize> = (0..heights.len()).filter(|&k| heights[k].is_nan()).collect();
    while !holes.is_empty() {
        let filled: Vec<(usize, f64)> = holes
            .iter()
            .filter_map(|&k| {
                let (i, j) = ((k % size) as i64, (k / size) as i64);
                let (mut sum, mut count) = (0.0, 0u32);
                for (di, dj) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
                    let (x, y) = (i + di, j + dj);
                    if x < 0 || y < 0 || x >= size as i64 || y >= size as i64 {
                        continue;
                    }
                    let h = heights[y as usize * size + x as usize];
                    if !h.is_nan() {
                        sum += h;
                        count += 1;
                    }
                }
                (count > 0).then(|| (k, sum / f64::from(count)))
            })
            .collect();
        for &(k, h) in &filled {
            heights[k] = h;
        }
        holes.retain(|&k| heights[k].is_nan());
    }
    heights
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn tile(cells: usize, f: impl Fn(f64, f64) -> f64) -> HeightTile {
        let size = cells + 1;
        let mut heights = Vec::with_capacity(size * size);
        for j in 0..size {
            for i in 0..size {
                heights.push(f(i as f64, j as f64) as f32);
            }
        }
        HeightTile { size, heights }
    }

    /// The f64 reference: each sample's height on the mesh, found by
    /// barycentric interpolation in a triangle that holds it, against the
    /// sample itself. Panics if a sample lies in no triangle.
    fn reference_max_error(mesh: &TerrainMesh, heights: &[f64]) -> f64 {
        let size = mesh.cells + 1;
        let mut on_mesh = vec![f64::NAN; size * size];
        for t in &mesh.triangles {
            let p = t.map(|v| {
                let [x, y] = mesh.vertices[v as usize];
                (f64::from(x), f64::from(y), mesh.heights[v as usize])
            });
            let det = (p[1].1 - p[2].1) * (p[0].0 - p[2].0) + (p[2].0 - p[1].0) * (p[0].1 - p[2].1);
            let (x0, x1) = (p[0].0.min(p[1].0).min(p[2].0), p[0].0.max(p[1].0).max(p[2].0));
            let (y0, y1) = (p[0].1.min(p[1].1).min(p[2].1), p[0].1.max(p[1].1).max(p[2].1));
            for j in y0 as usize..=y1 as usize {
                for i in x0 as usize..=x1 as usize {
                    let (px, py) = (i as f64, j as f64);
                    let l0 = ((p[1].1 - p[2].1) * (px - p[2].0) + (p[2].0 - p[1].0) * (py - p[2].1)) / det;
                    let l1 = ((p[2].1 - p[0].1) * (px - p[2].0) + (p[0].0 - p[2].0) * (py - p[2].1)) / det;
                    let l2 = 1.0 - l0 - l1;
                    if l0 >= -1e-12 && l1 >= -1e-12 && l2 >= -1e-12 {
                        on_mesh[j * size + i] = l0 * p[0].2 + l1 * p[1].2 + l2 * p[2].2;
                    }
                }
            }
        }
        let mut worst = 0.0f64;
        for (k, h) in on_mesh.iter().enumerate() {
            assert!(!h.is_nan(), "sample ({}, {}) is in no triangle", k % size, k / size);
            worst = worst.max((h - heights[k]).abs());
        }
        worst
    }

    fn area_sum(mesh: &TerrainMesh) -> i64 {
        mesh.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| {
                    let [x, y] = mesh.vertices[v as usize];
                    [i64::from(x), -i64::from(y)]
                });
                let area2 = cross(a, b, c);
                assert!(area2 > 0, "triangle {t:?} is not counter-clockwise seen from above");
                area2
            })
            .sum()
    }

    #[test]
    fn a_plane_gives_two_triangles_at_any_error() {
        for cells in [2, 16, 64] {
            let rtin = Rtin::new(&tile(cells, |x, y| 3.0 * x - 2.0 * y + 100.0)).unwrap();
            for knob in [0.0, 0.01, 1.0, 1e6] {
                let mesh = rtin.mesh(knob);
                assert_eq!(mesh.triangles.len(), 2, "cells {cells}, knob {knob}");
                assert_eq!(reference_max_error(&mesh, rtin.heights()), 0.0);
            }
        }
    }

    fn paraboloid(x: f64, y: f64) -> f64 {
        0.05 * ((x - 20.0).powi(2) + (y - 41.0).powi(2))
    }

    fn gaussian_hill(x: f64, y: f64) -> f64 {
        300.0 * (-((x - 30.0).powi(2) + (y - 25.0).powi(2)) / (2.0 * 9.0f64.powi(2))).exp()
    }

    #[test]
    fn every_sample_is_within_the_knob_and_smaller_knobs_never_give_fewer_triangles() {
        type Surface = (&'static str, fn(f64, f64) -> f64);
        let surfaces: [Surface; 3] = [
            ("paraboloid", paraboloid),
            ("gaussian hill", gaussian_hill),
            ("ridges", |x, y| 40.0 * (x * 0.31).sin() * (y * 0.17).cos() + 0.5 * x),
        ];
        for (name, f) in surfaces {
            let rtin = Rtin::new(&tile(64, f)).unwrap();
            let mut last = usize::MAX;
            for knob in [0.0, 0.01, 0.1, 0.5, 1.0, 2.0, 5.0, 10.0, 50.0, 1000.0] {
                let mesh = rtin.mesh(knob);
                let error = reference_max_error(&mesh, rtin.heights());
                assert!(error <= knob + 1e-9, "{name}: knob {knob} m, error {error} m");
                assert!((mesh.max_error_m(rtin.heights()) - error).abs() < 1e-9, "{name}: own measure");
                assert!(mesh.triangles.len() <= last, "{name}: knob {knob} gave more triangles than a smaller one");
                last = mesh.triangles.len();
                // The triangles tile the square exactly once.
                assert_eq!(area_sum(&mesh), 2 * 64 * 64, "{name}: knob {knob}");
                // The surface at every sample agrees with the reference's worst.
                let surface = mesh.surface_heights();
                let worst = surface.iter().zip(rtin.heights()).map(|(m, h)| (m - h).abs()).fold(0.0, f64::max);
                assert!(surface.iter().all(|h| h.is_finite()), "{name}: every sample covered");
                assert!((worst - error).abs() < 1e-9, "{name}: knob {knob}: surface {worst} m, reference {error} m");
            }
        }
    }

    #[test]
    fn nodata_is_the_mean_of_valid_neighbours_and_an_empty_tile_is_zero() {
        let mut t = tile(4, |_, _| 10.0);
        t.heights[2 * 5 + 2] = f32::NAN;
        t.heights[0] = f32::NAN;
        let rtin = Rtin::new(&t).unwrap();
        assert_eq!(rtin.heights()[12], 10.0);
        assert_eq!(rtin.heights()[0], 10.0);
        assert_eq!(rtin.mesh(0.0).triangles.len(), 2);
        let empty = HeightTile { size: 5, heights: vec![f32::NAN; 25] };
        let rtin = Rtin::new(&empty).unwrap();
        assert!(rtin.heights().iter().all(|&h| h == 0.0));
        // A hole wider than one sample fills from its rim inwards.
        let mut t = tile(8, |x, _| x);
        for j in 2..7 {
            for i in 2..7 {
                t.heights[j * 9 + i] = f32::NAN;
            }
        }
        assert!(Rtin::new(&t).unwrap().heights().iter().all(|h| h.is_finite()));
    }

    #[test]
    fn tiles_not_two_to_the_k_plus_one_are_refused() {
        assert!(Rtin::new(&HeightTile { size: 6, heights: vec![0.0; 36] }).is_err());
        assert!(Rtin::new(&HeightTile { size: 2, heights: vec![0.0; 4] }).is_err());
        assert!(Rtin::new(&HeightTile { size: 5, heights: vec![0.0; 24] }).is_err());
    }
}
