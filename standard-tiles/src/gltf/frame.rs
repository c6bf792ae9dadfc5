//! Where a tile's glTF content stands: ECEF offsets from an f64 centre in
//! glTF's y-up axes, and the region (3D Tiles' geographic bounding volume)
//! of what was written.

/// glTF axes from ECEF axes. 3D Tiles reads glTF content as y-up and turns
/// it to z-up (+90 degrees about x: (x, y, z) -> (x, -z, y)), so an ECEF
/// offset (x, y, z) is stored as (x, z, -y).
pub(crate) fn y_up(v: [f64; 3]) -> [f64; 3] {
    [v[0], v[2], -v[1]]
}

/// The tile transform of content whose positions are offsets from `centre`
/// (ECEF): a translation, column-major as 3D Tiles writes it.
pub(crate) fn translation(centre: [f64; 3]) -> [f64; 16] {
    let [x, y, z] = centre;
    [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, x, y, z, 1.0]
}

/// The ECEF centre of the box around `points` (ECEF): the f64 origin that
/// keeps the f32 offsets smallest.
pub(crate) fn box_centre(points: impl Iterator<Item = [f64; 3]>) -> [f64; 3] {
    let (lo, hi) = points.fold(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |(lo, hi), p| {
        ([lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])], [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])])
    });
    if lo[0] > hi[0] {
        return [0.0; 3];
    }
    [f64::midpoint(lo[0], hi[0]), f64::midpoint(lo[1], hi[1]), f64::midpoint(lo[2], hi[2])]
}

/// The geographic box of what a tile wrote, grown point by point.
/// Longitudes are unwrapped about the tile's centre longitude, so content
/// that reaches past the antimeridian gives a region whose west is east of
/// its east, as 3D Tiles writes a region across it.
pub(crate) struct RegionBounds {
    about_lon_deg: f64,
    west: f64,
    east: f64,
    south: f64,
    north: f64,
    low: f64,
    high: f64,
    every_longitude: bool,
}

impl RegionBounds {
    pub(crate) fn new(about_lon_deg: f64) -> Self {
        Self {
            about_lon_deg,
            west: f64::INFINITY,
            east: f64::NEG_INFINITY,
            south: f64::INFINITY,
            north: f64::NEG_INFINITY,
            low: f64::INFINITY,
            high: f64::NEG_INFINITY,
            every_longitude: false,
        }
    }

    pub(crate) fn add(&mut self, lon_deg: f64, lat_deg: f64, height_m: f64) {
        let lon = self.about_lon_deg + signed_degrees(lon_deg - self.about_lon_deg);
        self.west = self.west.min(lon);
        self.east = self.east.max(lon);
        self.south = self.south.min(lat_deg);
        self.north = self.north.max(lat_deg);
        self.low = self.low.min(height_m);
        self.high = self.high.max(height_m);
    }

    /// Takes every longitude (content round a pole).
    pub(crate) fn add_every_longitude(&mut self) {
        self.every_longitude = true;
    }

    /// Grows the box by `degrees` each way and `metres` up and down.
    pub(crate) fn pad(&mut self, degrees: f64, metres: f64) {
        self.west -= degrees;
        self.east += degrees;
        self.south -= degrees;
        self.north += degrees;
        self.low -= metres;
        self.high += metres;
    }

    /// West, south, east, north (radians) and the lowest and highest
    /// height (metres); None when nothing was added.
    pub(crate) fn region(&self) -> Option<[f64; 6]> {
        if self.west > self.east {
            return None;
        }
        let (west, east) = if self.every_longitude || self.east - self.west >= 360.0 {
            (-180.0, 180.0)
        } else {
            (wrap_west(self.west), wrap_east(self.east))
        };
        let (south, north) = (self.south.max(-90.0), self.north.min(90.0));
        Some([west.to_radians(), south.to_radians(), east.to_radians(), north.to_radians(), self.low, self.high])
    }
}

/// An angle in degrees into (-180, 180].
fn signed_degrees(d: f64) -> f64 {
    let r = d.rem_euclid(360.0);
    if r > 180.0 { r - 360.0 } else { r }
}

/// A west edge into [-180, 180).
fn wrap_west(lon: f64) -> f64 {
    let w = (lon + 180.0).rem_euclid(360.0) - 180.0;
    // rem_euclid can give 360 for tiny negative inputs.
    if w >= 180.0 { w - 360.0 } else { w }
}

/// An east edge into (-180, 180]: 180 stays 180, not -180.
fn wrap_east(lon: f64) -> f64 {
    -wrap_west(-lon)
}

/// A colour channel as glTF's `COLOR_0` holds it (linear, 0..=65535) from
/// an sRGB-encoded one in 0..=1, as relief's colours and models hold them.
/// Alpha is linear already and is only scaled.
pub(crate) fn linear_u16(srgb: f32, is_alpha: bool) -> u16 {
    let c = f64::from(srgb).clamp(0.0, 1.0);
    let linear = if is_alpha {
        c
    } else if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    };
    (linear * 65535.0).round() as u16
}

/// An RGBA colour (sRGB, straight, 0..=1) as four `COLOR_0` channels.
pub(crate) fn color_u16(rgba: [f32; 4]) -> [u16; 4] {
    [linear_u16(rgba[0], false), linear_u16(rgba[1], false), linear_u16(rgba[2], false), linear_u16(rgba[3], true)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn region_across_the_antimeridian_has_west_east_of_east() {
        let mut b = RegionBounds::new(179.99);
        b.add(179.98, 10.0, 0.0);
        b.add(-179.99, 10.01, 5.0);
        let r = b.region().unwrap();
        assert!((r[0] - 179.98f64.to_radians()).abs() < 1e-12);
        assert!((r[2] - (-179.99f64).to_radians()).abs() < 1e-12);
        assert!(r[0] > r[2]);
        assert_eq!((r[4], r[5]), (0.0, 5.0));
    }

    #[test]
    fn region_touching_the_antimeridian_ends_at_180() {
        let mut b = RegionBounds::new(179.5);
        b.add(179.0, 0.0, 0.0);
        b.add(180.0, 0.0, 0.0);
        let r = b.region().unwrap();
        assert_eq!(r[2], std::f64::consts::PI);
        assert!(r[0] < r[2]);
    }

    #[test]
    fn y_up_then_the_runtime_turn_gives_back_ecef() {
        let v = [1.0, 2.0, 3.0];
        let s = y_up(v);
        // The runtime's y-up to z-up: (x, y, z) -> (x, -z, y).
        assert_eq!([s[0], -s[2], s[1]], v);
    }

    #[test]
    fn colours_linearize() {
        assert_eq!(linear_u16(0.0, false), 0);
        assert_eq!(linear_u16(1.0, false), 65535);
        // sRGB 0.5 is linear 0.2140.
        assert!((f64::from(linear_u16(0.5, false)) / 65535.0 - 0.214_041).abs() < 1e-5);
        assert_eq!(linear_u16(0.5, true), 32768);
    }
}
