//! The planet's horizon: what the ground near the eye hides of the ground
//! beyond it. The occluder is the ellipsoid every drawn point lies on or
//! above; in the space that scales it to the unit sphere (an affine map,
//! so sight lines stay straight and what hides what is unchanged), a point
//! is hidden when it lies beyond the plane of the eye's tangent circle and
//! inside the cone of sight lines that meet the sphere (Cozzi & Ring,
//! "horizon culling", as Cesium does it).

use glam::DVec3;
use relief_source::geodesy::{WGS84_A, WGS84_B, WGS84_E2};

/// The occluding ellipsoid seen from the eye.
#[derive(Debug, Clone)]
pub struct Horizon {
    /// Divides world axes into the occluder's scaled space.
    scale: DVec3,
    /// The most one metre becomes there.
    stretch: f64,
    /// The eye's distance from the centre there.
    eye: f64,
    /// Towards the centre from the eye.
    axis: DVec3,
    /// The eye's distance from the centre, squared, less one: the tangent's
    /// length squared.
    beyond: f64,
    /// The farthest a sight line can travel from the eye before it first
    /// meets the occluder, metres.
    pub reach_m: f64,
}

impl Horizon {
    /// The ellipsoid no lower than geodetic height `floor_m` anywhere, seen
    /// from `eye` (world, metres from the planet's centre); None when the
    /// eye is not above it.
    pub fn new(eye: DVec3, floor_m: f64) -> Option<Self> {
        // The surface at a constant geodetic height h lies on or outside
        // the ellipsoid of semi-axes a + h and b + h where h >= 0; below
        // sea level it dips inside, by about |h| e^4 / 32 (1.55 cm at
        // -11 km; `tests`): taken four times over, and a centimetre.
        let h = floor_m - floor_m.min(0.0).abs() * WGS84_E2 * WGS84_E2 / 8.0 - 0.01;
        let (a, b) = (WGS84_A + h, WGS84_B + h);
        let scale = DVec3::new(1.0 / a, 1.0 / a, 1.0 / b);
        let scaled = eye * scale;
        let distance = scaled.length();
        let beyond = distance * distance - 1.0;
        (beyond > 0.0 && distance.is_finite()).then(|| Self {
            scale,
            stretch: 1.0 / b,
            eye: distance,
            axis: -scaled / distance,
            beyond,
            reach_m: beyond.sqrt() * a,
        })
    }

    /// True when every point of the sphere (centre relative to the eye,
    /// metres) is hidden: beyond the tangent circle's plane and inside the
    /// occluder's cone, so each sight line to it meets the occluder first.
    pub fn hides(&self, centre: DVec3, radius: f64) -> bool {
        let d = centre * self.scale;
        let r = radius * self.stretch;
        let along = d.dot(self.axis);
        if along - r < self.beyond / self.eye {
            return false;
        }
        let off_axis = (d - self.axis * along).length();
        let (sin, cos) = (1.0 / self.eye, self.beyond.sqrt() / self.eye);
        along * sin - off_axis * cos >= r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use relief_source::geodesy::ecef_from_geodetic;

    fn world(lon: f64, lat: f64, h: f64) -> DVec3 {
        DVec3::from(ecef_from_geodetic(lon, lat, h))
    }

    /// The first place the segment from `from` to `to` meets the ellipsoid
    /// of geodetic height `h`, found by marching in f64 against the
    /// geodetic height of each point (an independent reference).
    fn meets_height(from: DVec3, to: DVec3, h: f64) -> bool {
        let steps = 20_000;
        (1..steps).any(|k| {
            let p = from.lerp(to, f64::from(k) / f64::from(steps));
            relief_source::geodesy::geodetic_from_ecef(p.to_array()).2 < h
        })
    }

    #[test]
    fn the_occluder_lies_under_every_point_at_the_floor() {
        for floor in [-11_000.0, -4_000.0, -430.0, 0.0, 500.0, 4_800.0, 9_000.0] {
            let horizon = Horizon::new(world(0.0, 0.0, 100_000.0), floor).unwrap();
            for k in 0..=3600 {
                let lat = -90.0 + f64::from(k) * 0.05;
                let scaled = world(33.0, lat, floor) * horizon.scale;
                assert!(scaled.length() >= 1.0, "floor {floor}, lat {lat}: {}", scaled.length());
            }
        }
    }

    #[test]
    fn what_it_hides_lies_behind_the_ground() {
        // Eyes low and high, near the equator, a pole and the antimeridian;
        // spheres all round: every one hidden has each of its sampled
        // points behind the ground at the floor, as a march in f64 finds.
        let eyes = [(10.0, 44.5, 501.7), (179.99, 0.0, 502.0), (0.0, 89.9, 510.0), (-70.0, -30.0, 9_000.0)];
        let (mut hidden, mut seen) = (0, 0);
        for (lon, lat, alt) in eyes {
            let eye = world(lon, lat, alt);
            let horizon = Horizon::new(eye, 500.0).unwrap();
            for k in 0..400 {
                let (bearing, range) = (f64::from(k) * 7.3, 1_000.0 * 1.1f64.powi(k % 60));
                let (dlon, dlat) =
                    (range / 111_000.0 * bearing.to_radians().sin(), range / 111_000.0 * bearing.to_radians().cos());
                let top = [0.0, 30.0, 600.0, 3_000.0][k as usize % 4];
                let centre =
                    world(lon + dlon / lat.to_radians().cos().max(0.05), (lat + dlat).clamp(-90.0, 90.0), 500.0 + top);
                let radius = 50.0 + top;
                if !horizon.hides(centre - eye, radius) {
                    seen += 1;
                    continue;
                }
                hidden += 1;
                let (u, v) = (DVec3::X.cross(centre).normalize(), DVec3::Z);
                for p in [centre, centre + u * radius, centre - u * radius, centre + v * radius, centre - v * radius] {
                    assert!(meets_height(eye, p, 500.0), "eye {lon} {lat} {alt}: {p:?} is in sight");
                }
            }
        }
        assert!(hidden > 100 && seen > 100, "{hidden} hidden, {seen} seen");
    }

    #[test]
    fn nothing_is_hidden_from_below_the_floor_or_above_it_in_sight() {
        assert!(Horizon::new(world(10.0, 45.0, 400.0), 500.0).is_none(), "an eye under the occluder");
        let eye = world(10.0, 45.0, 502.0);
        let horizon = Horizon::new(eye, 500.0).unwrap();
        // A peak 3 km high 100 km away stands over the horizon (5 km away).
        let peak = world(10.0, 45.9, 3_500.0);
        assert!(!horizon.hides(peak - eye, 10.0));
        // Flat ground there is hidden, and a sphere round the eye never is.
        assert!(horizon.hides(world(10.0, 45.9, 500.0) - eye, 10.0));
        assert!(!horizon.hides(DVec3::ZERO, 1.0));
    }
}
