//! Which instance tiles a frame asks for: those of the layer's level
//! within the last band's reach of the camera, whole across the
//! antimeridian, coarser near the poles, and never more than MAX_TILES.

use relief_source::TileKey;

use super::view::InstancesView;

/// How many levels coarser than the layer's own instance tiles are asked
/// for near the poles.
const COARSER_NEAR_POLES: u8 = 3;
/// The most instance tiles a frame asks for.
const MAX_TILES: usize = 1024;

/// The instance tiles at `level` within `reach` metres of the camera's
/// ground point (on the planet, whole across the antimeridian); none
/// when the camera is higher above the ground than the reach.
pub fn keys(at: &InstancesView<'_>, level: u8, reach: f64) -> Vec<TileKey> {
    /// Above the highest ground on Earth, for a camera over no terrain.
    const HIGHEST_GROUND_M: f64 = 9000.0;
    let (surface, camera) = (at.surface, at.camera);
    if camera[2] - at.ground_m.unwrap_or(HIGHEST_GROUND_M) > reach {
        return Vec::new();
    }
    let half = reach / surface.metres_per_unit();
    // Towards a pole a tile narrows with the cosine of its latitude: ask
    // coarser tiles there (up to COARSER_NEAR_POLES levels; a source's
    // coarser tile holds its finer tiles' instances), so a ring of reach
    // is not tens of thousands of slivers.
    let level = if surface.is_planet() {
        let lat = (camera[1].abs() + half).min(90.0);
        let narrowing = 1.0 / lat.to_radians().cos().max(1e-9);
        level.saturating_sub((narrowing.log2().floor() as u8).min(COARSER_NEAR_POLES))
    } else {
        level
    };
    let mut seen = std::collections::HashSet::new();
    let mut keys: Vec<TileKey> = Vec::new();
    for part in &surface.around(camera[0], camera[1], half) {
        keys.extend(surface.grid().keys_overlapping(level, part).into_iter().filter(|k| seen.insert(*k)));
    }
    if keys.len() > MAX_TILES {
        // The nearest tiles only (on the pole's ring, the ones round the camera).
        let grid = surface.grid();
        let distance = |k: &TileKey| {
            let e = grid.tile_extent(*k);
            let (x, y) = (f64::midpoint(e.min_x, e.max_x), f64::midpoint(e.min_y, e.max_y));
            (surface.world(x, y, 0.0) - at.view.eye).length()
        };
        keys.sort_by(|a, b| distance(a).total_cmp(&distance(b)));
        keys.truncate(MAX_TILES);
    }
    keys
}
