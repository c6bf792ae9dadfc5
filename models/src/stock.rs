//! The stock models, made procedurally: low-poly shapes, since the renderer
//! may draw a hundred thousand of them on a software rasterizer.
//!
//! Each is built from flat-shaded convex pieces, written as a `.glb` and
//! read back through the same loader as a user's file. Every stock model
//! reaches 1 m below its origin (the trunk or the walls go down to
//! y = -1), so that it never floats above terrain drawn a little lower than
//! the point it stands on.

use std::f32::consts::TAU;
use std::path::{Path, PathBuf};

use crate::encode::{self, Part};
use crate::{Model, from_slice};

/// The stock models' names:
///
/// - `conifer`: a brown six-sided trunk under three stacked dark green
///   cones, 12 m tall, 2.5 m in radius (60 triangles);
/// - `broadleaf`: a trunk under a mid green ellipsoidal crown, 10 m tall,
///   3.5 m in radius (92 triangles);
/// - `shrub`: an olive squashed dome, 1.5 m tall, 1.2 m in radius (48
///   triangles);
/// - `house`: an 8 m (x) by 10 m (z) box of 3 m plaster walls under a
///   red-brown gable roof, its ridge along z at 6 m (14 triangles).
///
/// Each is flat-shaded, and reaches 1 m below its origin (the trunk or the
/// walls go down to y = -1) so that it never floats above terrain drawn a
/// little lower than the point it stands on.
pub const STOCK: &[&str] = &["conifer", "broadleaf", "shrub", "house"];

/// How far below its origin every stock model reaches, in metres.
const BELOW_GROUND_M: f32 = 1.0;

const BARK: [f32; 3] = [0.36, 0.25, 0.17];
const NEEDLES: [f32; 3] = [0.15, 0.30, 0.17];
const LEAVES: [f32; 3] = [0.30, 0.50, 0.20];
const OLIVE: [f32; 3] = [0.42, 0.47, 0.22];
const PLASTER: [f32; 3] = [0.90, 0.86, 0.78];
const ROOF_TILES: [f32; 3] = [0.55, 0.23, 0.16];

/// A stock model as the bytes of a `.glb` file (the same bytes every time);
/// `None` for a name not in [`STOCK`].
pub fn stock_glb(name: &str) -> Option<Vec<u8>> {
    let parts = match name {
        "conifer" => conifer(),
        "broadleaf" => broadleaf(),
        "shrub" => vec![shrub()],
        "house" => house(),
        _ => return None,
    };
    Some(encode::glb(name, &parts))
}

/// A stock model, parsed from [`stock_glb`] through the same loader as a
/// user's files; `None` for a name not in [`STOCK`].
pub fn stock(name: &str) -> Option<Model> {
    let bytes = stock_glb(name)?;
    // Generated and tested valid; a loader refusal would leave the model
    // out (drawn as unknown), never panic a renderer.
    from_slice(&format!("stock model '{name}'"), &bytes).ok()
}

/// Writes each stock model as `<dir>/<name>.glb`, creating `dir` if needed,
/// and returns the paths. A file that already holds the same bytes is left
/// alone; others are replaced whole (written aside, then renamed), so a
/// reader never sees half a file.
pub fn write_stock(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)?;
    let mut paths = Vec::with_capacity(STOCK.len());
    for name in STOCK {
        let Some(bytes) = stock_glb(name) else { continue };
        let path = dir.join(format!("{name}.glb"));
        if std::fs::read(&path).ok().as_deref() != Some(&bytes[..]) {
            let aside = dir.join(format!(".{name}.glb.partial"));
            std::fs::write(&aside, &bytes)?;
            std::fs::rename(&aside, &path)?;
        }
        paths.push(path);
    }
    Ok(paths)
}

/// About 12 m tall and 2.5 m wide in radius: a six-sided trunk under three
/// stacked nine-sided cones, each turned a little from the one below.
fn conifer() -> Vec<Part> {
    let mut needles = Part::new("needles", NEEDLES);
    // (base height, base radius, apex height) of each tier.
    for (tier, (base_m, radius_m, apex_m)) in
        [(1.2, 2.5, 6.5), (3.6, 2.0, 9.3), (6.2, 1.4, 12.0)].into_iter().enumerate()
    {
        cone(&mut needles, 9, radius_m, base_m, apex_m, tier as f32 * 0.35);
    }
    vec![trunk(0.25, 2.0), needles]
}

/// About 10 m tall and 3.5 m wide in radius: a trunk under an ellipsoidal
/// crown (an icosahedron subdivided once, 80 facets).
fn broadleaf() -> Vec<Part> {
    let mut leaves = Part::new("leaves", LEAVES);
    let (centre_y, radius_m, half_height_m) = (6.6, 3.5, 3.4);
    let centre = [0.0, centre_y, 0.0];
    for [a, b, c] in subdivided_icosahedron() {
        let place = |p: [f32; 3]| [p[0] * radius_m, centre_y + p[1] * half_height_m, p[2] * radius_m];
        leaves.facet(&[place(a), place(b), place(c)], centre);
    }
    vec![trunk(0.3, 4.5), leaves]
}

/// 1.5 m tall and 1.2 m wide in radius: a squashed dome of eight segments,
/// its widest ring half a metre up, closed underground at y = -1.
fn shrub() -> Part {
    let mut part = Part::new("foliage", OLIVE);
    let segments = 8;
    let (equator_y, radius_m) = (0.5, 1.2);
    // Rings from the top down: (height, radius); the top and bottom are points.
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let rings = [
        (1.5, 0.0),
        (equator_y + 1.0 * s, radius_m * s),
        (equator_y, radius_m),
        (equator_y - (equator_y + BELOW_GROUND_M) * s, radius_m * s),
        (-BELOW_GROUND_M, 0.0),
    ];
    let inside = [0.0, equator_y, 0.0];
    for pair in rings.windows(2) {
        let [(y0, r0), (y1, r1)] = [pair[0], pair[1]];
        for i in 0..segments {
            let corners = [ring(r0, y0, i, segments, 0.0), ring(r0, y0, i + 1, segments, 0.0)];
            let below = [ring(r1, y1, i + 1, segments, 0.0), ring(r1, y1, i, segments, 0.0)];
            let mut polygon: Vec<[f32; 3]> = corners.into_iter().chain(below).collect();
            // A ring of radius zero is a single point: the polygon is a triangle.
            polygon.dedup();
            part.facet(&polygon, inside);
        }
    }
    part
}

/// An 8 m (x) by 10 m (z) house: 3 m plaster walls under a gable roof whose
/// ridge runs along z at 6 m and whose eaves overhang by half a metre.
fn house() -> Vec<Part> {
    let (half_x, half_z, wall_m, ridge_m, overhang_m) = (4.0, 5.0, 3.0, 6.0, 0.5);
    let mut walls = Part::new("walls", PLASTER);
    let inside = [0.0, 1.0, 0.0];
    let y0 = -BELOW_GROUND_M;
    for x in [-half_x, half_x] {
        walls.facet(&[[x, y0, -half_z], [x, y0, half_z], [x, wall_m, half_z], [x, wall_m, -half_z]], inside);
    }
    for z in [-half_z, half_z] {
        let gable = [[-half_x, y0, z], [half_x, y0, z], [half_x, wall_m, z], [0.0, ridge_m, z], [-half_x, wall_m, z]];
        walls.facet(&gable, inside);
    }
    let mut roof = Part::new("roof", ROOF_TILES);
    let eave_x = half_x + overhang_m;
    let eave_y = wall_m - overhang_m * (ridge_m - wall_m) / half_x;
    let roof_z = half_z + overhang_m;
    for x in [-eave_x, eave_x] {
        let slope = [[x, eave_y, -roof_z], [x, eave_y, roof_z], [0.0, ridge_m, roof_z], [0.0, ridge_m, -roof_z]];
        roof.facet(&slope, [0.0, 0.0, 0.0]);
    }
    vec![walls, roof]
}

/// A six-sided trunk from 1 m underground up to `top_m`, open at both ends
/// (the bottom is underground, the top inside the crown).
fn trunk(radius_m: f32, top_m: f32) -> Part {
    let mut part = Part::new("bark", BARK);
    for i in 0..6 {
        let [a, b] = [ring(radius_m, -BELOW_GROUND_M, i, 6, 0.0), ring(radius_m, -BELOW_GROUND_M, i + 1, 6, 0.0)];
        let [c, d] = [ring(radius_m, top_m, i + 1, 6, 0.0), ring(radius_m, top_m, i, 6, 0.0)];
        part.facet(&[a, b, c, d], [0.0, 0.0, 0.0]);
    }
    part
}

/// A cone of `sides` facets with its base (a flat polygon, seen from below)
/// at `base_m` and its apex at `apex_m`, turned by `turn` radians.
fn cone(part: &mut Part, sides: usize, radius_m: f32, base_m: f32, apex_m: f32, turn: f32) {
    let inside = [0.0, base_m + (apex_m - base_m) / 4.0, 0.0];
    let apex = [0.0, apex_m, 0.0];
    for i in 0..sides {
        part.facet(&[ring(radius_m, base_m, i, sides, turn), ring(radius_m, base_m, i + 1, sides, turn), apex], inside);
    }
    let base: Vec<[f32; 3]> = (0..sides).map(|i| ring(radius_m, base_m, i, sides, turn)).collect();
    part.facet(&base, inside);
}

/// Corner `i` of `sides` around a circle of radius `radius_m` at height `y`,
/// counter-clockwise seen from above, turned by `turn` radians.
fn ring(radius_m: f32, y: f32, i: usize, sides: usize, turn: f32) -> [f32; 3] {
    let angle = turn + TAU * (i % sides) as f32 / sides as f32;
    [radius_m * angle.cos(), y, -radius_m * angle.sin()]
}

/// The 80 triangles of an icosahedron whose faces are each cut in four,
/// with every corner on the unit sphere.
fn subdivided_icosahedron() -> Vec<[[f32; 3]; 3]> {
    // The golden ratio, (1 + sqrt 5) / 2.
    let phi = 0.5 + 1.25f32.sqrt();
    let corners = [
        [-1.0, phi, 0.0],
        [1.0, phi, 0.0],
        [-1.0, -phi, 0.0],
        [1.0, -phi, 0.0],
        [0.0, -1.0, phi],
        [0.0, 1.0, phi],
        [0.0, -1.0, -phi],
        [0.0, 1.0, -phi],
        [phi, 0.0, -1.0],
        [phi, 0.0, 1.0],
        [-phi, 0.0, -1.0],
        [-phi, 0.0, 1.0],
    ];
    const FACES: [[usize; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let on_sphere = |p: [f32; 3]| {
        let length = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        p.map(|v| v / length)
    };
    let mid = |a: [f32; 3], b: [f32; 3]| on_sphere([a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
    FACES
        .iter()
        .flat_map(|&[a, b, c]| {
            let [a, b, c] = [a, b, c].map(|i| on_sphere(corners[i]));
            let [ab, bc, ca] = [mid(a, b), mid(b, c), mid(c, a)];
            [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
        })
        .collect()
}
