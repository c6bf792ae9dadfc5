//! Camera gestures as a viewer makes them (orbit, pan, zoom, move), in
//! world space: f64 throughout, on the ellipsoid or the flat grid, so a
//! gesture one metre above the ground or across the antimeridian is as
//! exact as the camera itself.

use glam::{DQuat, DVec3};

use crate::camera::{Pose, View};
use crate::surface::Surface;

/// The steepest a gesture tilts the camera: straight down.
const MIN_PITCH_DEG: f64 = -90.0;
/// The flattest an orbit leaves it: just under the horizon, so the pivot
/// stays in view.
const MAX_ORBIT_PITCH_DEG: f64 = -2.0;
/// The closest a zoom comes to the point it zooms at.
const MIN_DISTANCE_M: f64 = 2.0;

impl Surface {
    /// The pose of a camera at world position `eye` looking along `forward`
    /// with `up` as the image's up: the inverse of `View::new`.
    pub fn pose_at(&self, eye: DVec3, forward: DVec3, up: DVec3, vertical_fov_deg: f64) -> Pose {
        let [x, y, h] = self.grid_point(eye);
        let [e, n, u] = self.enu(x, y);
        let forward = forward.normalize();
        // atan2 rather than asin: exact near straight down.
        let pitch = forward.dot(u).atan2((forward - forward.dot(u) * u).length());
        // Looking straight up or down, the heading is where the image's up
        // points; otherwise where the view points.
        let level = if forward.dot(u).abs() > 0.999_999 { up * -forward.dot(u).signum() } else { forward };
        let heading = level.dot(e).atan2(level.dot(n));
        let right0 = heading.cos() * e - heading.sin() * n;
        let up0 = right0.cross(forward);
        let roll = (-up.dot(right0)).atan2(up.dot(up0));
        Pose {
            position: [x, y, h],
            heading_deg: heading.to_degrees().rem_euclid(360.0),
            pitch_deg: pitch.to_degrees(),
            roll_deg: roll.to_degrees(),
            vertical_fov_deg,
        }
    }

    /// Grid point and height of a world position.
    pub fn grid_point(&self, world: DVec3) -> [f64; 3] {
        if self.is_planet() {
            let (lon, lat, h) = relief_source::geodesy::geodetic_from_ecef(world.to_array());
            [lon, lat, h]
        } else {
            world.to_array()
        }
    }

    /// The surface's up at a world position.
    pub fn up_at(&self, world: DVec3) -> DVec3 {
        let [x, y, _] = self.grid_point(world);
        self.enu(x, y)[2]
    }

    /// Where a ray from `eye` along unit `dir` meets the surface raised by
    /// `height_m` (the ellipsoid, or the plane z = height), if it does.
    pub fn intersect(&self, eye: DVec3, dir: DVec3, height_m: f64) -> Option<DVec3> {
        if !self.is_planet() {
            let t = (height_m - eye.z) / dir.z;
            return (t.is_finite() && t > 0.0).then(|| eye + dir * t);
        }
        // Scale to a unit sphere: the ellipsoid of semi-axes a + h, b + h.
        let a = relief_source::geodesy::WGS84_A + height_m;
        let b = relief_source::geodesy::WGS84_B + height_m;
        let scale = DVec3::new(1.0 / a, 1.0 / a, 1.0 / b);
        let (o, d) = (eye * scale, dir * scale);
        let (qa, qb, qc) = (d.dot(d), 2.0 * o.dot(d), o.dot(o) - 1.0);
        let disc = qb * qb - 4.0 * qa * qc;
        if disc < 0.0 {
            return None;
        }
        let sq = disc.sqrt();
        // The nearer root in front of the eye (the far one when inside).
        let t = [(-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)].into_iter().find(|t| *t > 0.0)?;
        Some(eye + dir * t)
    }

    /// Turns the camera about `pivot`: `heading_deg` clockwise about the
    /// surface's up there, `pitch_deg` up about the camera's right. The
    /// pitch stays between straight down and just under the horizon.
    pub fn orbit(&self, pose: &Pose, pivot: DVec3, heading_deg: f64, pitch_deg: f64) -> Pose {
        let view = self.view(pose);
        let up_p = self.up_at(pivot);
        let turn = DQuat::from_axis_angle(up_p, -heading_deg.to_radians());
        let (eye, forward, up) = (pivot + turn * (view.eye - pivot), turn * view.forward, turn * view.up);
        let right = forward.cross(up).normalize();
        // Tilt within the allowed pitch, measured at the pivot.
        let now = forward.dot(up_p).atan2((forward - forward.dot(up_p) * up_p).length()).to_degrees();
        let target = (now + pitch_deg).clamp(MIN_PITCH_DEG, MAX_ORBIT_PITCH_DEG.max(now.min(0.0)));
        let tilt = DQuat::from_axis_angle(right, (target - now).to_radians());
        let eye = pivot + tilt * (eye - pivot);
        self.pose_at(eye, tilt * forward, tilt * up, pose.vertical_fov_deg)
    }

    /// Moves the camera parallel to the ground at `grab` (a world point
    /// under the cursor) so that `grab` comes to lie on the ray `to_dir`
    /// from the eye. A ray at or above the horizon there moves nothing.
    pub fn pan(&self, pose: &Pose, grab: DVec3, to_dir: DVec3) -> Pose {
        let view = self.view(pose);
        let up_g = self.up_at(grab);
        let above = (view.eye - grab).dot(up_g);
        let down = to_dir.dot(up_g);
        if down > -0.02 || above <= 0.0 {
            return *pose;
        }
        let s = -above / down;
        let eye = grab - to_dir * s;
        let mut moved = self.pose_at(eye, view.forward, view.up, pose.vertical_fov_deg);
        // Over the curved planet keep the height above the ellipsoid.
        moved.position[2] = pose.position[2];
        moved
    }

    /// Moves towards `target` keeping `factor` of the distance to it, never
    /// closer than two metres.
    pub fn zoom(&self, pose: &Pose, target: DVec3, factor: f64) -> Pose {
        let view = self.view(pose);
        let offset = view.eye - target;
        let distance = offset.length();
        if !(factor.is_finite() && factor > 0.0) || distance <= 0.0 {
            return *pose;
        }
        let new_distance = (distance * factor).max(MIN_DISTANCE_M.min(distance));
        let eye = target + offset * (new_distance / distance);
        self.pose_at(eye, view.forward, view.up, pose.vertical_fov_deg)
    }

    /// Moves `forward` metres along the heading, `right` across it and `up`
    /// along the vertical, then turns the heading by `turn_deg`. The height
    /// above the ellipsoid changes by `up` only.
    pub fn travel(&self, pose: &Pose, forward: f64, right: f64, up: f64, turn_deg: f64) -> Pose {
        let [x, y, h] = pose.position;
        let [e, n, _] = self.enu(x, y);
        let heading = pose.heading_deg.to_radians();
        let ahead = heading.sin() * e + heading.cos() * n;
        let side = heading.cos() * e - heading.sin() * n;
        let eye = self.world(x, y, h) + ahead * forward + side * right;
        let [nx, ny, _] = self.grid_point(eye);
        Pose { position: [nx, ny, h + up], heading_deg: (pose.heading_deg + turn_deg).rem_euclid(360.0), ..*pose }
    }
}

impl View {
    /// The world point drawn at pixel (px, py) of a frame of this view, from
    /// its reversed-Z depth; None for sky.
    pub fn world_at(&self, px: f64, py: f64, width: u32, height: u32, depth: f32) -> Option<DVec3> {
        if depth.is_nan() || depth <= 0.0 {
            return None;
        }
        let (dir, distance) = self.unproject(px, py, width, height, depth);
        Some(self.eye + dir * distance)
    }

    /// The unit ray through pixel (px, py).
    pub fn ray(&self, px: f64, py: f64, width: u32, height: u32) -> DVec3 {
        self.unproject(px, py, width, height, 1.0).0
    }
}

#[cfg(test)]
mod tests {
    use relief_source::{GridKind, ProjectedGrid, TileGrid};

    use super::*;

    fn planet() -> Surface {
        Surface::new(TileGrid::geodetic(256).unwrap())
    }

    fn pose(lon: f64, lat: f64, h: f64, heading: f64, pitch: f64, roll: f64) -> Pose {
        Pose { position: [lon, lat, h], heading_deg: heading, pitch_deg: pitch, roll_deg: roll, vertical_fov_deg: 50.0 }
    }

    fn close(a: &Pose, b: &Pose) -> bool {
        let angle = |x: f64, y: f64| ((x - y + 540.0).rem_euclid(360.0) - 180.0).abs() < 1e-6;
        (a.position[0] - b.position[0]).abs() < 1e-9
            && (a.position[1] - b.position[1]).abs() < 1e-9
            && (a.position[2] - b.position[2]).abs() < 1e-5
            && angle(a.heading_deg, b.heading_deg)
            && (a.pitch_deg - b.pitch_deg).abs() < 1e-6
            && angle(a.roll_deg, b.roll_deg)
    }

    #[test]
    fn pose_at_inverts_the_view_on_the_planet_and_the_grid() {
        let utm = ProjectedGrid { crs: "EPSG:32632".into(), min_x: 0.0, min_y: 0.0, size: 1e5 };
        let flat = Surface::new(TileGrid::new(GridKind::Projected(utm), 256).unwrap());
        for surface in [planet(), flat] {
            for p in [
                pose(179.999, 45.0, 1.0, 30.0, -40.0, 10.0),
                pose(-179.5, -89.9, 4000.0, 300.0, -10.0, 0.0),
                pose(6.5, 45.3, 9000.0, 90.0, -90.0, 0.0),
                pose(0.0, 0.0, 4.0e7, 0.0, 0.0, -20.0),
            ] {
                let p = if surface.is_planet() { p } else { Pose { position: [5e4, 5e4, p.position[2]], ..p } };
                let v = surface.view(&p);
                let back = surface.pose_at(v.eye, v.forward, v.up, p.vertical_fov_deg);
                assert!(close(&back, &p), "{p:?} came back as {back:?}");
            }
        }
    }

    #[test]
    fn an_orbit_keeps_the_distance_to_the_pivot_and_turns_the_heading() {
        let s = planet();
        let p = pose(179.99, 60.0, 3000.0, 10.0, -45.0, 0.0);
        let v = s.view(&p);
        let pivot = s.intersect(v.eye, v.forward, 0.0).unwrap();
        let o = s.orbit(&p, pivot, 90.0, 0.0);
        let ov = s.view(&o);
        assert!(((ov.eye - pivot).length() - (v.eye - pivot).length()).abs() < 1e-6);
        assert!(((o.heading_deg - 100.0 + 540.0).rem_euclid(360.0) - 180.0).abs() < 0.2, "{o:?}");
        // The pivot stays at the centre of the view.
        assert!((ov.forward - (pivot - ov.eye).normalize()).length() < 1e-9);
        // Tilting past straight down stops there; past the horizon stops short.
        let down = s.orbit(&p, pivot, 0.0, -80.0);
        // Tilting about the camera's right, which the curvature turns 0.04
        // degrees from the pivot's horizontal: straight down within 1e-4.
        assert!((down.pitch_deg + 90.0).abs() < 1e-4, "{down:?}");
        assert!(s.orbit(&p, pivot, 0.0, 80.0).pitch_deg <= MAX_ORBIT_PITCH_DEG + 1e-9);
    }

    #[test]
    fn a_pan_brings_the_grabbed_point_under_the_target_pixel() {
        let s = planet();
        let p = pose(-179.995, 45.0, 1.0, 0.0, -30.0, 0.0);
        let v = s.view(&p);
        let (w, h) = (640, 480);
        let grab = s.intersect(v.eye, v.ray(300.0, 400.0, w, h), 0.0).unwrap();
        let to = v.ray(340.0, 380.0, w, h);
        let moved = s.pan(&p, grab, to);
        let mv = s.view(&moved);
        let seen = (grab - mv.eye).normalize();
        assert!(seen.dot(to) > 1.0 - 1e-9, "the point is {:.3e} rad off", seen.dot(to).acos());
        assert!((moved.position[2] - 1.0).abs() < 1e-9);
    }

    #[test]
    fn zoom_and_travel_move_by_what_they_say() {
        let s = planet();
        let p = pose(10.0, 89.99, 500.0, 45.0, -30.0, 0.0);
        let v = s.view(&p);
        let target = s.intersect(v.eye, v.forward, 0.0).unwrap();
        let z = s.zoom(&p, target, 0.5);
        assert!(((s.view(&z).eye - target).length() - 0.5 * (v.eye - target).length()).abs() < 1e-6);
        let near = s.zoom(&p, target, 1e-9);
        assert!(((s.view(&near).eye - target).length() - MIN_DISTANCE_M).abs() < 1e-6);
        let t = s.travel(&p, 100.0, 0.0, 10.0, 15.0);
        assert!(((s.view(&t).eye - v.eye).length() - (100.0f64.powi(2) + 10.0f64.powi(2)).sqrt()).abs() < 0.01);
        assert!((t.heading_deg - 60.0).abs() < 1e-9 && (t.position[2] - 510.0).abs() < 1e-9);
    }

    #[test]
    fn rays_meet_the_surface_or_miss_it() {
        let s = planet();
        let v = s.view(&pose(0.0, 0.0, 1000.0, 0.0, -90.0, 0.0));
        let hit = s.intersect(v.eye, v.forward, 0.0).unwrap();
        assert!((hit.length() - relief_source::geodesy::WGS84_A).abs() < 1e-6);
        assert!(s.intersect(v.eye, -v.forward, 0.0).is_none());
        let up = s.view(&pose(0.0, 0.0, 1000.0, 0.0, 10.0, 0.0));
        assert!(s.intersect(up.eye, up.forward, 0.0).is_none());
    }
}
