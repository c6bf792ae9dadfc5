//! Gestures on a view (orbit, pan, zoom, move, fly to a source) and the
//! point under a pixel. Each refers to what the view's last frame shows:
//! its depth buffer gives the ground under the cursor exactly as drawn.
//! Without a frame, rays meet the ellipsoid (or the grid's plane) raised
//! to the ground under the camera.

use glam::DVec3;
use relief_renderer::{MAX_ALTITUDE_M, RenderError, Surface, View};

use crate::camera::{Camera, camera_of, framing, ground_height, pose, to_geodetic};
use crate::frames::HubFrame;
use crate::graph::SceneSnapshot;
use crate::view::ViewError;

/// Image size that rays of a view without a frame are taken in.
const NOMINAL_SIZE: (u32, u32) = (1280, 720);

#[derive(Debug, Clone, PartialEq)]
pub enum Gesture {
    /// Degrees clockwise about the ground at the centre, and up.
    Orbit { heading_deg: f64, pitch_deg: f64 },
    /// The ground under `from` comes under `to` (fractions of the image).
    Pan { from: (f64, f64), to: (f64, f64) },
    /// Keeps `factor` of the distance to the point under `at`.
    Zoom { factor: f64, at: (f64, f64) },
    /// In units of the camera's height above the ground.
    Move { forward: f64, right: f64, up: f64, turn_deg: f64 },
    /// Frames a source's extent.
    FlyTo(String),
}

/// The point under a pixel of a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Picked {
    pub lon_deg: f64,
    pub lat_deg: f64,
    pub surface_height_m: f64,
    pub ground_height_m: Option<f64>,
    pub distance_m: f64,
    pub generation: u64,
}

fn bad(field: &'static str, message: String) -> ViewError {
    ViewError::Invalid(RenderError::Request { field, message })
}

fn fraction(field: &'static str, (x, y): (f64, f64)) -> Result<(f64, f64), ViewError> {
    for v in [x, y] {
        if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
            return Err(bad(field, format!("{v} is not a fraction of the image from 0 to 1")));
        }
    }
    Ok((x, y))
}

/// The pixel (column, row) a fraction of the image falls in; `View`'s rays
/// go through its centre.
fn pixel_of((fx, fy): (f64, f64), width: u32, height: u32) -> (f64, f64) {
    (
        (fx * f64::from(width)).floor().clamp(0.0, f64::from(width) - 1.0),
        (fy * f64::from(height)).floor().clamp(0.0, f64::from(height) - 1.0),
    )
}

/// The world point a frame drew at a fraction of its image, from its depth;
/// None for sky.
fn drawn_at(frame: &HubFrame, at: (f64, f64)) -> Option<DVec3> {
    let fr = &frame.rendered.frame;
    let (px, py) = pixel_of(at, fr.width, fr.height);
    let depth = fr.depth[py as usize * fr.width as usize + px as usize];
    fr.view.world_at(px, py, fr.width, fr.height, depth)
}

/// Where a gesture's rays come from: the last frame's view and depth, or
/// the camera's own view over the ground level.
struct Scene<'a> {
    surface: Surface,
    view: View,
    frame: Option<&'a HubFrame>,
    ground_m: f64,
}

impl Scene<'_> {
    fn size(&self) -> (u32, u32) {
        self.frame.map_or(NOMINAL_SIZE, |f| (f.rendered.frame.width, f.rendered.frame.height))
    }

    fn pixel(&self, at: (f64, f64)) -> (f64, f64) {
        let (w, h) = self.size();
        pixel_of(at, w, h)
    }

    /// The camera's ray through a fraction of the image.
    fn ray(&self, at: (f64, f64)) -> DVec3 {
        let (w, h) = self.size();
        let (px, py) = self.pixel(at);
        self.view.ray(px, py, w, h)
    }

    /// The ground drawn under a fraction of the image: from the frame's
    /// depth, else where the ray meets the ground level.
    fn point(&self, at: (f64, f64)) -> Option<DVec3> {
        self.frame
            .and_then(|f| drawn_at(f, at))
            .or_else(|| self.surface.intersect(self.view.eye, self.ray(at), self.ground_m))
    }
}

/// The camera after `gesture`. Blocking (the ground height may read data).
pub fn navigate(
    snap: &SceneSnapshot,
    camera: &Camera,
    frame: Option<&HubFrame>,
    gesture: &Gesture,
) -> Result<Camera, ViewError> {
    let start = pose(snap, camera)?;
    let surface = Surface::new(snap.grid.clone());
    let view = surface.view(&start);
    let ground_m = ground_height(snap, camera.lon_deg, camera.lat_deg).unwrap_or(0.0);
    let s = Scene { surface, view, frame, ground_m };
    let above_ground = (camera.altitude_m - ground_m).max(1.0);
    let moved = match gesture {
        Gesture::Orbit { heading_deg, pitch_deg } => {
            for (field, v) in [("orbit.heading_deg", heading_deg), ("orbit.pitch_deg", pitch_deg)] {
                if !v.is_finite() {
                    return Err(bad(field, format!("{v} is not a finite number")));
                }
            }
            let pivot = s.point((0.5, 0.5)).unwrap_or(s.view.eye);
            s.surface.orbit(&start, pivot, *heading_deg, *pitch_deg)
        }
        Gesture::Pan { from, to } => {
            let (from, to) = (fraction("pan.from_x", *from)?, fraction("pan.to_x", *to)?);
            match s.point(from) {
                Some(grab) => s.surface.pan(&start, grab, s.ray(to)),
                None => start,
            }
        }
        Gesture::Zoom { factor, at } => {
            if !(factor.is_finite() && (0.01..=100.0).contains(factor)) {
                return Err(bad("zoom.factor", format!("{factor} is not from 0.01 to 100")));
            }
            let at = fraction("zoom.x", *at)?;
            let target = s.point(at).unwrap_or_else(|| s.view.eye + s.ray(at) * above_ground);
            s.surface.zoom(&start, target, *factor)
        }
        Gesture::Move { forward, right, up, turn_deg } => {
            for (field, v) in [("move.forward", forward), ("move.right", right), ("move.up", up)] {
                if !(v.is_finite() && v.abs() <= 100.0) {
                    return Err(bad(field, format!("{v} is not from -100 to 100 heights above the ground")));
                }
            }
            if !turn_deg.is_finite() {
                return Err(bad("move.turn_deg", format!("{turn_deg} is not a finite number")));
            }
            let g = above_ground;
            s.surface.travel(
                &start,
                forward * g,
                right * g,
                (up * g).max(ground_m + 1.0 - camera.altitude_m),
                *turn_deg,
            )
        }
        Gesture::FlyTo(id) => {
            let slot = snap
                .index_of(id)
                .map(|i| &snap.slots[i])
                .ok_or_else(|| ViewError::UnknownSource(relief_source::echo::echoed(id)))?;
            let extent = slot.source.as_ref().and_then(|src| src.info().extent).ok_or_else(|| {
                bad("fly_to_source", format!("source '{id}' has no extent to fly to (it has no data loaded)"))
            })?;
            return Ok(framing(snap, extent, false));
        }
    };
    let mut camera = camera_of(snap, &moved).map_err(|e| bad("camera", e))?;
    camera.altitude_m = camera.altitude_m.clamp(-11_000.0, MAX_ALTITUDE_M);
    pose(snap, &camera)?;
    Ok(camera)
}

/// The point of the scene drawn at a fraction of `frame`, None for sky.
/// Blocking (it samples the height layer there).
pub fn pick(snap: &SceneSnapshot, frame: &HubFrame, at: (f64, f64)) -> Result<Option<Picked>, ViewError> {
    let Some(world) = drawn_at(frame, fraction("x", at)?) else { return Ok(None) };
    let fr = &frame.rendered.frame;
    let surface = Surface::new(snap.grid.clone());
    let [x, y, h] = surface.grid_point(world);
    let (lon, lat) = to_geodetic(snap, x, y).map_err(|e| bad("x", e))?;
    Ok(Some(Picked {
        lon_deg: (lon + 180.0).rem_euclid(360.0) - 180.0,
        lat_deg: lat,
        surface_height_m: h,
        ground_height_m: ground_height(snap, lon, lat),
        distance_m: (world - fr.view.eye).length(),
        generation: frame.rendered.generation,
    }))
}
