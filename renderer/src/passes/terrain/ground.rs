//! The terrain as the level pass draws it, on the CPU: the same vertices,
//! morphed towards the coarser level by the same weights as the shader's
//! `vs_level`, and the same triangles (diagonal north-west to south-east).
//! What stands on the terrain (buildings) is anchored to this, so it sits
//! on the drawn surface at every level of detail, not on the data.

use glam::DVec3;

use crate::camera::Pose;
use crate::clipmap::{ClipLevel, Clipmap};
use crate::surface::Surface;

/// The coarser level's surface under fine sample (gx, gy) (`coarse_at`).
fn coarse_at(c: &ClipLevel, gx: i64, gy: i64) -> Option<DVec3> {
    let (x0, y0) = (gx >> 1, gy >> 1);
    Some(match (gx & 1 == 1, gy & 1 == 1) {
        (true, true) => 0.5 * (c.sample(x0, y0)? + c.sample(x0 + 1, y0 + 1)?),
        (true, false) => 0.5 * (c.sample(x0, y0)? + c.sample(x0 + 1, y0)?),
        (false, true) => 0.5 * (c.sample(x0, y0)? + c.sample(x0, y0 + 1)?),
        (false, false) => c.sample(x0, y0)?,
    })
}

/// Sample coordinates of grid point (x, y) at `level`, turned (on the
/// planet) to the copy of the longitude nearest the window's centre.
fn window_coords(surface: &Surface, level: &ClipLevel, x: f64, y: f64) -> (f64, f64) {
    let (mut sx, sy) = surface.sample_coords(level.tile_level, x, y);
    if surface.is_planet() {
        let total = surface.revolution(level.tile_level) as f64;
        let centre = level.origin.0 as f64 + (level.n / 2) as f64;
        sx += total * ((centre - sx) / total).round();
    }
    (sx, sy)
}

/// The world point of the drawn terrain over grid point (x, y): on the
/// finest active level whose cells hold it. In that level's outermost two
/// cells the next coarser level is drawn too (the overlap that covers
/// T-junction pinholes) and the two surfaces may differ a little: the
/// higher is taken, the one seen from above. None off every level or over
/// a sample off the grid.
pub fn drawn_point(surface: &Surface, clipmap: &Clipmap, active: &[u8], pose: &Pose, x: f64, y: f64) -> Option<DVec3> {
    let up = surface.enu(x, y)[2];
    for k in (0..active.len()).rev() {
        let Some((p, overlap)) = on_level(surface, clipmap, active, k, pose, x, y) else { continue };
        let coarse = if overlap && k > 0 { on_level(surface, clipmap, active, k - 1, pose, x, y) } else { None };
        return Some(match coarse {
            Some((q, _)) if q.dot(up) > p.dot(up) => q,
            _ => p,
        });
    }
    None
}

/// The drawn surface of active level `k` over (x, y), and whether the point
/// lies in the level's outermost two cells; None outside its window.
fn on_level(
    surface: &Surface,
    clipmap: &Clipmap,
    active: &[u8],
    k: usize,
    pose: &Pose,
    x: f64,
    y: f64,
) -> Option<(DVec3, bool)> {
    let level = clipmap.level(active[k])?;
    let n = level.n as i64;
    let (sx, sy) = window_coords(surface, level, x, y);
    let (fi, fj) = (sx - level.origin.0 as f64, sy - level.origin.1 as f64);
    if !(fi >= 0.0 && fj >= 0.0 && fi < (n - 1) as f64 && fj < (n - 1) as f64) {
        return None;
    }
    let coarser = k.checked_sub(1).and_then(|c| clipmap.level(active[c]));
    let (bx, by) = {
        let (cx, cy) = window_coords(surface, level, pose.position[0], pose.position[1]);
        (cx - level.origin.0 as f64, cy - level.origin.1 as f64)
    };
    let half = (n - 1) as f64 * 0.5;
    let w = (level.n as f64 / 10.0).max(2.0);
    let vertex = |i: i64, j: i64| -> Option<DVec3> {
        let (gx, gy) = (level.origin.0 + i, level.origin.1 + j);
        let fine = level.sample(gx, gy)?;
        let Some(c) = coarser else { return Some(fine) };
        let d = (i as f64 - bx).abs().max((j as f64 - by).abs());
        let edge = i == 0 || j == 0 || i == n - 1 || j == n - 1;
        let alpha = if edge { 1.0 } else { ((d - (half - w - 1.0)) / w).clamp(0.0, 1.0) };
        Some(fine.lerp(coarse_at(c, gx, gy)?, alpha))
    };
    let (i0, j0) = (fi.floor() as i64, fj.floor() as i64);
    let (u, v) = (fi - i0 as f64, fj - j0 as f64);
    let a = vertex(i0, j0)?;
    let d = vertex(i0 + 1, j0 + 1)?;
    // Cells split a-c-d (v >= u) and a-d-b, as `cell_indices` does.
    let other = if v >= u { vertex(i0, j0 + 1)? } else { vertex(i0 + 1, j0)? };
    // Where the vertical through (x, y) meets that triangle's plane.
    let (foot, up) = (surface.world(x, y, 0.0), surface.enu(x, y)[2]);
    let normal = (other - a).cross(d - a);
    let along = up.dot(normal);
    if along.abs() < 1e-12 * normal.length() {
        return None; // A vertical triangle: no single height.
    }
    let overlap = i0 < 2 || j0 < 2 || i0 >= n - 3 || j0 >= n - 3;
    Some((foot + up * ((a - foot).dot(normal) / along), overlap))
}

/// The drawn terrain's height over grid point (x, y), metres above the
/// grid's zero (the ellipsoid on the planet), along the local up.
pub fn drawn_height(surface: &Surface, clipmap: &Clipmap, active: &[u8], pose: &Pose, x: f64, y: f64) -> Option<f64> {
    let p = drawn_point(surface, clipmap, active, pose, x, y)?;
    Some((p - surface.world(x, y, 0.0)).dot(surface.enu(x, y)[2]))
}

/// The least distance, metres along the ground, from grid point (x, y) to
/// the edge of `level`'s window: every ground point nearer than this is
/// drawn by that level or a finer one. 0 on a flat grid, outside the
/// window, or where the window reaches past a pole.
pub fn reach_m(surface: &Surface, level: &ClipLevel, x: f64, y: f64) -> f64 {
    if !surface.is_planet() {
        return 0.0;
    }
    let last = (level.n - 1) as i64;
    let (sx, sy) = window_coords(surface, level, x, y);
    let (fi, fj) = (sx - level.origin.0 as f64, sy - level.origin.1 as f64);
    let (across, down) = (fi.min(last as f64 - fi), fj.min(last as f64 - fj));
    let lats = [level.origin.1, level.origin.1 + last].map(|gy| surface.sample_point(level.tile_level, 0, gy).1);
    if across <= 0.0 || down <= 0.0 || lats.iter().any(|lat| lat.abs() >= 90.0) {
        return 0.0;
    }
    // A degree of latitude is at least a (1 - e^2) pi / 180 metres, and of
    // longitude that times the cosine of the window's farthest latitude.
    let metres = surface.spacing_m(level.tile_level) * (1.0 - relief_source::geodesy::WGS84_E2);
    let cos = lats.iter().map(|lat| lat.to_radians().cos()).fold(1.0, f64::min);
    (across * metres * cos).min(down * metres)
}
