//! Cameras: a pose on the surface (f64), checked, and the eye-relative
//! view and reversed-Z projection the GPU gets (f32).

use glam::{DVec3, Mat4, Vec4};

use crate::error::RenderError;

/// Where the camera is and where it looks. `position` is in the surface's
/// coordinates: longitude and latitude in degrees on the planet, grid x and
/// y on a flat scene; then height in metres (above the ellipsoid, or above
/// the grid's zero).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub position: [f64; 3],
    /// Clockwise from north (grid north on a flat scene).
    pub heading_deg: f64,
    /// 0 looks at the horizon, -90 straight down.
    pub pitch_deg: f64,
    pub roll_deg: f64,
    pub vertical_fov_deg: f64,
}

/// The nearest distance drawn. Reversed-Z with an infinite far plane keeps
/// f32 depth precise from here to beyond 40,000 km.
pub const NEAR_M: f64 = 0.05;

/// The highest camera accepted: far beyond the Moon's orbit.
pub const MAX_ALTITUDE_M: f64 = 1.0e9;

impl Pose {
    /// Checks every field, naming the first bad one.
    pub fn validate(&self, planet: bool) -> Result<(), RenderError> {
        let bad = |field: &'static str, why: String| Err(RenderError::Camera { field, message: why });
        let [x, y, h] = self.position;
        for (field, v) in [
            ("lon_deg", x),
            ("lat_deg", y),
            ("altitude_m", h),
            ("heading_deg", self.heading_deg),
            ("pitch_deg", self.pitch_deg),
            ("roll_deg", self.roll_deg),
            ("vertical_fov_deg", self.vertical_fov_deg),
        ] {
            if !v.is_finite() {
                return bad(field, format!("{v} is not a finite number"));
            }
        }
        if planet && !(-90.0..=90.0).contains(&y) {
            return bad("lat_deg", format!("{y} is not a latitude from -90 to 90"));
        }
        if !(-12_000.0..=MAX_ALTITUDE_M).contains(&h) {
            return bad("altitude_m", format!("{h} m is not from -12,000 m to {MAX_ALTITUDE_M} m"));
        }
        if !(-90.0..=90.0).contains(&self.pitch_deg) {
            return bad("pitch_deg", format!("{} is not from -90 to 90", self.pitch_deg));
        }
        if !(-360.0..=360.0).contains(&self.heading_deg) {
            return bad("heading_deg", format!("{} is not from -360 to 360", self.heading_deg));
        }
        if !(-180.0..=180.0).contains(&self.roll_deg) {
            return bad("roll_deg", format!("{} is not from -180 to 180", self.roll_deg));
        }
        if !(1.0..=170.0).contains(&self.vertical_fov_deg) {
            return bad("vertical_fov_deg", format!("{} is not from 1 to 170 degrees", self.vertical_fov_deg));
        }
        Ok(())
    }
}

/// A camera in world space (ECEF metres on the planet, grid metres on a flat
/// scene): the eye in f64 and an orthonormal basis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    pub eye: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    pub forward: DVec3,
    pub vertical_fov_deg: f64,
}

impl View {
    /// The view from `eye` with the local east, north and up axes `enu`.
    pub fn new(eye: DVec3, enu: [DVec3; 3], pose: &Pose) -> Self {
        let [e, n, u] = enu;
        let (h, p, r) = (pose.heading_deg.to_radians(), pose.pitch_deg.to_radians(), pose.roll_deg.to_radians());
        let level = h.sin() * e + h.cos() * n;
        let forward = (p.cos() * level + p.sin() * u).normalize();
        let right0 = (h.cos() * e - h.sin() * n).normalize();
        let up0 = right0.cross(forward);
        let right = right0 * r.cos() + up0 * r.sin();
        let up = up0 * r.cos() - right0 * r.sin();
        Self { eye, right, up, forward, vertical_fov_deg: pose.vertical_fov_deg }
    }

    /// Eye-relative world position to clip space: the rotation into view
    /// space, then a reversed-Z projection with an infinite far plane
    /// (depth = NEAR / distance along the view axis).
    pub fn view_projection(&self, aspect: f64) -> Mat4 {
        let f = 1.0 / (self.vertical_fov_deg.to_radians() / 2.0).tan();
        let (r, u, b) = (self.right.as_vec3(), self.up.as_vec3(), (-self.forward).as_vec3());
        let view = Mat4::from_cols(
            Vec4::new(r.x, u.x, b.x, 0.0),
            Vec4::new(r.y, u.y, b.y, 0.0),
            Vec4::new(r.z, u.z, b.z, 0.0),
            Vec4::W,
        );
        let projection = Mat4::from_cols(
            Vec4::new((f / aspect) as f32, 0.0, 0.0, 0.0),
            Vec4::new(0.0, f as f32, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 0.0, -1.0),
            Vec4::new(0.0, 0.0, NEAR_M as f32, 0.0),
        );
        projection * view
    }

    /// The view's frustum for images `aspect` wide per unit of height.
    pub fn frustum(&self, aspect: f64) -> Frustum {
        let tan_y = (self.vertical_fov_deg.to_radians() / 2.0).tan();
        Frustum { right: self.right, up: self.up, forward: self.forward, tan_x: tan_y * aspect, tan_y }
    }

    /// The ray through pixel centre (px, py) of a width x height image,
    /// unit length, and the distance along it of a reversed-Z `depth`.
    pub fn unproject(&self, px: f64, py: f64, width: u32, height: u32, depth: f32) -> (DVec3, f64) {
        let tan = (self.vertical_fov_deg.to_radians() / 2.0).tan();
        let aspect = f64::from(width) / f64::from(height);
        let sx = (2.0 * (px + 0.5) / f64::from(width) - 1.0) * tan * aspect;
        let sy = (1.0 - 2.0 * (py + 0.5) / f64::from(height)) * tan;
        let dir = (self.forward + sx * self.right + sy * self.up).normalize();
        let along_axis = NEAR_M / f64::from(depth);
        (dir, along_axis / dir.dot(self.forward))
    }
}

/// The view's four side planes and its near side, for spheres relative to
/// the eye.
pub struct Frustum {
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    tan_x: f64,
    tan_y: f64,
}

/// A volume things are culled by: the camera's frustum, or the box a
/// shadow cascade sees from the sun.
pub trait Sees {
    /// True unless the sphere (centre relative to the eye) lies wholly
    /// outside the volume.
    fn sees(&self, centre: DVec3, radius: f64) -> bool;
}

impl Sees for Frustum {
    fn sees(&self, centre: DVec3, radius: f64) -> bool {
        let z = centre.dot(self.forward);
        if z < -radius {
            return false;
        }
        let x = centre.dot(self.right).abs();
        let y = centre.dot(self.up).abs();
        x <= z * self.tan_x + radius * (1.0 + self.tan_x * self.tan_x).sqrt()
            && y <= z * self.tan_y + radius * (1.0 + self.tan_y * self.tan_y).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> Pose {
        Pose {
            position: [0.0, 0.0, 100.0],
            heading_deg: 30.0,
            pitch_deg: -40.0,
            roll_deg: 10.0,
            vertical_fov_deg: 50.0,
        }
    }

    #[test]
    fn the_basis_is_orthonormal_and_right_handed() {
        let view = View::new(DVec3::ZERO, [DVec3::X, DVec3::Y, DVec3::Z], &pose());
        assert!((view.right.cross(view.up) - (-view.forward)).length() < 1e-12);
        assert!(view.forward.z < 0.0, "pitch -40 looks down");
        let down = View::new(DVec3::ZERO, [DVec3::X, DVec3::Y, DVec3::Z], &Pose { pitch_deg: -90.0, ..pose() });
        assert!((down.forward - DVec3::NEG_Z).length() < 1e-12);
    }

    #[test]
    fn depth_unprojects_to_the_point_that_was_projected() {
        let view = View::new(DVec3::ZERO, [DVec3::X, DVec3::Y, DVec3::Z], &pose());
        let point = DVec3::new(120.0, 300.0, -200.0);
        let clip = view.view_projection(16.0 / 9.0) * point.as_vec3().extend(1.0);
        let ndc = clip.truncate() / clip.w;
        let (w, h) = (1600u32, 900u32);
        let px = f64::midpoint(f64::from(ndc.x), 1.0) * f64::from(w) - 0.5;
        let py = (1.0 - f64::from(ndc.y)) / 2.0 * f64::from(h) - 0.5;
        let (dir, distance) = view.unproject(px, py, w, h, ndc.z);
        assert!((dir * distance - point).length() < 1e-3 * point.length(), "{:?}", dir * distance);
    }

    #[test]
    fn bad_fields_are_named() {
        let mut p = pose();
        p.position[1] = f64::NAN;
        assert!(matches!(p.validate(true), Err(RenderError::Camera { field: "lat_deg", .. })));
        let p = Pose { vertical_fov_deg: 0.0, ..pose() };
        assert!(matches!(p.validate(true), Err(RenderError::Camera { field: "vertical_fov_deg", .. })));
        assert!(Pose { position: [0.0, 95.0, 1.0], ..pose() }.validate(true).is_err());
        assert!(Pose { position: [500_000.0, 5e6, 1.0], ..pose() }.validate(false).is_ok());
    }
}
