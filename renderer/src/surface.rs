//! The surface the terrain lies on: the WGS84 ellipsoid for a geodetic grid
//! (world = ECEF metres), or a plane for a projected grid (world = grid x,
//! y and height). World positions are f64; only eye- or anchor-relative
//! offsets go to the GPU as f32.

use glam::DVec3;
use relief_source::{Extent, TileGrid, geodesy};

use crate::camera::{Pose, View};

#[derive(Debug, Clone, PartialEq)]
pub struct Surface {
    grid: TileGrid,
}

impl Surface {
    pub fn new(grid: TileGrid) -> Self {
        Self { grid }
    }

    pub fn grid(&self) -> &TileGrid {
        &self.grid
    }

    pub fn is_planet(&self) -> bool {
        self.grid.is_geodetic()
    }

    /// The world position of grid point (x, y) at height `h` metres. On the
    /// planet, latitudes past a pole continue over it (the ECEF formula does
    /// that by itself), so a clipmap that reaches over a pole folds back.
    pub fn world(&self, x: f64, y: f64, h: f64) -> DVec3 {
        if self.is_planet() { DVec3::from(geodesy::ecef_from_geodetic(x, y, h)) } else { DVec3::new(x, y, h) }
    }

    /// East, north and up at grid point (x, y).
    pub fn enu(&self, x: f64, y: f64) -> [DVec3; 3] {
        if self.is_planet() {
            geodesy::enu_axes(x, y.clamp(-90.0, 90.0)).map(DVec3::from)
        } else {
            [DVec3::X, DVec3::Y, DVec3::Z]
        }
    }

    pub fn view(&self, pose: &Pose) -> View {
        let [x, y, h] = pose.position;
        View::new(self.world(x, y, h), self.enu(x, y), pose)
    }

    /// Corner-sample spacing at tile level `level`, in grid units.
    pub fn step(&self, level: u8) -> f64 {
        self.grid.sample_step(level)
    }

    /// Grid point of global corner sample (gx, gy) at `level`.
    pub fn sample_point(&self, level: u8, gx: i64, gy: i64) -> (f64, f64) {
        self.grid.sample_point(level, gx, gy)
    }

    /// Continuous sample coordinates of grid point (x, y) at `level`.
    pub fn sample_coords(&self, level: u8, x: f64, y: f64) -> (f64, f64) {
        self.grid.sample_coords(level, x, y)
    }

    /// Corner samples round the planet at `level` (a revolution).
    pub fn revolution(&self, level: u8) -> i64 {
        self.grid.samples_at(level).0
    }

    /// An area of grid units as the parts to look tiles up in: itself on a
    /// flat scene; on the planet, brought back to the turn holding
    /// [-180, 180) (windows follow the camera round the planet without
    /// bound) and shifted a turn east and west, so an area across the
    /// antimeridian is whole.
    pub fn turns(&self, e: Extent) -> Vec<Extent> {
        if !self.is_planet() {
            return vec![e];
        }
        let turn = 360.0 * (f64::midpoint(e.min_x, e.max_x) / 360.0).round();
        [-360.0 - turn, -turn, 360.0 - turn]
            .iter()
            .map(|s| Extent::new(e.min_x + s, e.min_y, e.max_x + s, e.max_y))
            .collect()
    }

    /// The square of `half` grid units of latitude (or of the flat grid)
    /// round grid point (x, y), as `turns` gives it: on the planet as far
    /// east and west on the ground as north and south (wider towards the
    /// poles, at most the whole turn).
    pub fn around(&self, x: f64, y: f64, half: f64) -> Vec<Extent> {
        let half_x = if self.is_planet() { (half / y.to_radians().cos().max(1e-6)).min(180.0) } else { half };
        self.turns(Extent::new(x - half_x, y - half, x + half_x, y + half))
    }

    /// Metres per grid unit along the ground (at the equator on the planet).
    pub fn metres_per_unit(&self) -> f64 {
        if self.is_planet() { geodesy::WGS84_A.to_radians() } else { 1.0 }
    }

    /// Corner-sample spacing at tile level `level`, metres along the
    /// ground (at the equator on the planet).
    pub fn spacing_m(&self, level: u8) -> f64 {
        self.step(level) * self.metres_per_unit()
    }

    /// Whether a sample lies on the grid; a flat scene ends at its edges.
    pub fn on_grid(&self, level: u8, gx: i64, gy: i64) -> bool {
        if self.is_planet() {
            return true;
        }
        let (cols, rows) = self.grid.samples_at(level);
        (0..=cols).contains(&gx) && (0..=rows).contains(&gy)
    }
}
