//! Gestures on a view (orbit, pan, zoom, move, fly to a source) and the
//! point under a pixel. Each refers to what the view's last frame shows:
//! its depth buffer gives the ground under the cursor exactly as drawn.
//! Without a frame, rays are marched over the height layer's data.
//!
//! No gesture leaves the camera where it cannot see the scene: every one
//! ends above the ground under the eye (plus `CLEARANCE_M`) and inside the
//! scene's extent plus a margin (`keep_in_scene`), so a camera put under
//! the ground or far away (by a script, an old manifest) comes back with
//! its next gesture.

use glam::DVec3;
use relief_renderer::{MAX_ALTITUDE_M, Pose, RenderError, Surface, View};
use relief_source::{Extent, GeodeticPoint};

use crate::camera::{Camera, camera_of, ground_height, pose, to_geodetic};
use crate::frames::HubFrame;
use crate::graph::SceneSnapshot;
use crate::view::ViewError;

/// Image size that rays of a view without a frame are taken in.
const NOMINAL_SIZE: (u32, u32) = (1280, 720);
/// The least height of the eye above the ground under it after a gesture.
pub const CLEARANCE_M: f64 = 10.0;
/// The least height above the ground that moves and sky zooms scale with:
/// a camera near the ground still moves `MIN_SPEED_HEIGHT_M` x the step.
pub const MIN_SPEED_HEIGHT_M: f64 = 100.0;
/// Samples of a ray marched over the height layer (no frame to read).
const MARCH_SAMPLES: usize = 192;
/// The pitch a camera framing an extent looks down at.
const FRAMING_PITCH_DEG: f64 = -35.0;
/// Metres per degree of latitude (and of longitude at the equator).
const METRES_PER_DEG: f64 = 111_320.0;

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
    /// How far a marched ray looks for the ground.
    reach_m: f64,
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
    fn point(&self, snap: &SceneSnapshot, at: (f64, f64)) -> Option<DVec3> {
        match self.frame {
            Some(f) => drawn_at(f, at),
            None => march(snap, &self.surface, self.view.eye, self.ray(at), self.reach_m),
        }
    }
}

/// Where the ray from `eye` along unit `dir` first goes under the height
/// layer's ground (nodata and no height layer are the ellipsoid, or the
/// grid's plane), within `reach_m`: samples spaced geometrically from a
/// metre, the crossing interpolated between the two about it. Blocking.
fn march(snap: &SceneSnapshot, surface: &Surface, eye: DVec3, dir: DVec3, reach_m: f64) -> Option<DVec3> {
    let ratio = reach_m.max(2.0).powf(1.0 / (MARCH_SAMPLES - 1) as f64);
    let along: Vec<f64> = (0..MARCH_SAMPLES).map(|i| ratio.powi(i32::try_from(i).unwrap_or(0))).collect();
    let points: Vec<[f64; 3]> = along.iter().map(|d| surface.grid_point(eye + dir * *d)).collect();
    let grounds = ground_heights(snap, &points);
    let mut last: Option<(f64, f64)> = None; // (distance, height above the ground)
    for ((d, p), g) in along.iter().zip(&points).zip(grounds) {
        let above = p[2] - g;
        if above <= 0.0 {
            let Some((d0, a0)) = last else { return Some(eye + dir * *d) };
            let t = a0 / (a0 - above);
            return Some(eye + dir * (d0 + (d - d0) * t));
        }
        last = Some((*d, above));
    }
    None
}

/// The height layer's ground at grid points (their heights ignored); 0
/// where it has none. Blocking.
fn ground_heights(snap: &SceneSnapshot, points: &[[f64; 3]]) -> Vec<f64> {
    let geodetic: Vec<GeodeticPoint> = points
        .iter()
        .map(|[x, y, _]| {
            let (lon, lat) = to_geodetic(snap, *x, *y).unwrap_or((*x, *y));
            GeodeticPoint { lon_deg: (lon + 180.0).rem_euclid(360.0) - 180.0, lat_deg: lat.clamp(-90.0, 90.0) }
        })
        .collect();
    let heights = snap
        .layer("height")
        .and_then(|slot| slot.source.as_ref())
        .and_then(|source| source.sample_heights(&geodetic, &snap.manifest.quality).ok());
    match heights {
        Some(h) if h.len() == points.len() => h.into_iter().map(|v| v.unwrap_or(0.0)).collect(),
        _ => vec![0.0; points.len()],
    }
}

/// The scene's extent in the grid's CRS: the height layer's, else the
/// colour layer's, else the whole grid.
pub fn scene_extent(snap: &SceneSnapshot) -> Extent {
    ["height", "color"]
        .iter()
        .filter_map(|l| snap.layer(l))
        .find_map(|slot| slot.source.as_ref().and_then(|s| s.info().extent))
        .unwrap_or_else(|| snap.grid.extent())
}

/// The larger side of an extent in metres (degrees taken at its middle
/// latitude on the planet).
fn size_m(snap: &SceneSnapshot, e: &Extent) -> f64 {
    if snap.grid.is_geodetic() {
        let cos = f64::midpoint(e.min_y, e.max_y).to_radians().cos().max(0.01);
        (e.width() * cos).max(e.height()) * METRES_PER_DEG
    } else {
        e.width().max(e.height())
    }
}

/// How far outside the scene's extent a camera may go: half its larger
/// side, at least a kilometre (in grid units).
fn margin(snap: &SceneSnapshot, e: &Extent) -> f64 {
    let m = (0.5 * size_m(snap, e)).max(1000.0);
    if snap.grid.is_geodetic() { m / METRES_PER_DEG } else { m }
}

/// A pose kept inside the scene: its place within the extent plus the
/// margin, its height at most twice the scene's size (plus 10 km) above
/// the ground and at least `CLEARANCE_M` above the ground under it.
/// Blocking (it samples the height layer there).
pub fn keep_in_scene(snap: &SceneSnapshot, pose: &Pose) -> Pose {
    let extent = scene_extent(snap);
    let m = margin(snap, &extent);
    let mut kept = *pose;
    let [x, y, _] = &mut kept.position;
    let whole_planet = snap.grid.is_geodetic() && extent.width() + 2.0 * m >= 360.0;
    if !whole_planet {
        *x = x.clamp(extent.min_x - m, extent.max_x + m);
    }
    *y = y.clamp(extent.min_y - m, extent.max_y + m);
    if snap.grid.is_geodetic() {
        *y = y.clamp(-90.0, 90.0);
    }
    let ground = ground_heights(snap, &[kept.position])[0];
    let ceiling = (ground + 2.0 * size_m(snap, &extent) + 10_000.0).min(MAX_ALTITUDE_M);
    kept.position[2] = kept.position[2].min(ceiling).max(ground + CLEARANCE_M);
    kept
}

/// A camera that shows `extent` (in the grid's CRS) whole in a landscape
/// image: from the south, looking 35 degrees down at its middle, as far as
/// every corner needs to be inside the vertical field of view (on both
/// axes, so any image at least as wide as it is tall shows it all).
/// Blocking (it samples the ground at the middle).
pub fn framing(snap: &SceneSnapshot, extent: Extent, vertical_fov_deg: f64) -> Camera {
    let (cx, cy) = (f64::midpoint(extent.min_x, extent.max_x), f64::midpoint(extent.min_y, extent.max_y));
    let ground = ground_heights(snap, &[[cx, cy, 0.0]])[0];
    // Half sides in metres along east and north.
    let (half_e, half_n, metres_y) = if snap.grid.is_geodetic() {
        let cos = cy.to_radians().cos().max(0.01);
        (0.5 * extent.width() * METRES_PER_DEG * cos, 0.5 * extent.height() * METRES_PER_DEG, METRES_PER_DEG)
    } else {
        (0.5 * extent.width(), 0.5 * extent.height(), 1.0)
    };
    let pitch = FRAMING_PITCH_DEG.to_radians();
    let (forward, up) = (DVec3::new(0.0, pitch.cos(), pitch.sin()), DVec3::new(0.0, -pitch.sin(), pitch.cos()));
    // 90 % of the half field of view: a small border round the extent.
    let tan_half = 0.9 * (0.5 * vertical_fov_deg.clamp(1.0, 170.0)).to_radians().tan();
    let fits = |distance: f64| {
        let eye = -forward * distance;
        [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)].iter().all(|(sx, sy)| {
            let v = DVec3::new(sx * half_e, sy * half_n, 0.0) - eye;
            let z = v.dot(forward);
            z > 0.0 && v.dot(up).abs() <= tan_half * z && v.x.abs() <= tan_half * z
        })
    };
    let mut distance = (half_e.max(half_n)).max(50.0);
    while !fits(distance) && distance < 4.0e7 {
        distance *= 1.05;
    }
    let distance = distance.min(4.0e7);
    let (x, y) = (cx, cy - distance * pitch.cos() / metres_y);
    let (lon, lat) = to_geodetic(snap, x, y).unwrap_or((x, y));
    Camera {
        lon_deg: (lon + 180.0).rem_euclid(360.0) - 180.0,
        lat_deg: lat.clamp(-89.0, 89.0),
        altitude_m: (ground - distance * pitch.sin()).min(MAX_ALTITUDE_M),
        heading_deg: 0.0,
        pitch_deg: FRAMING_PITCH_DEG,
        roll_deg: 0.0,
        vertical_fov_deg,
    }
}

/// The camera after `gesture`, kept inside the scene (`keep_in_scene`).
/// Blocking (the ground height may read data).
pub fn navigate(
    snap: &SceneSnapshot,
    camera: &Camera,
    frame: Option<&HubFrame>,
    gesture: &Gesture,
) -> Result<Camera, ViewError> {
    let start = pose(snap, camera)?;
    let surface = Surface::new(snap.grid.clone());
    let view = surface.view(&start);
    let extent = scene_extent(snap);
    let ground_m = ground_heights(snap, &[start.position])[0];
    // Rays without a frame reach past the scene seen from its far corner.
    let reach_m = 4.0 * size_m(snap, &extent) + 4.0 * (camera.altitude_m - ground_m).abs() + 10_000.0;
    let s = Scene { surface, view, frame, reach_m };
    // Moves and sky zooms scale with the height above the ground, never
    // slower than at `MIN_SPEED_HEIGHT_M`.
    let speed_m = (camera.altitude_m - ground_m).max(MIN_SPEED_HEIGHT_M);
    let moved = match gesture {
        Gesture::Orbit { heading_deg, pitch_deg } => {
            for (field, v) in [("orbit.heading_deg", heading_deg), ("orbit.pitch_deg", pitch_deg)] {
                if !v.is_finite() {
                    return Err(bad(field, format!("{v} is not a finite number")));
                }
            }
            let pivot = s.point(snap, (0.5, 0.5)).unwrap_or(s.view.eye);
            let orbited = s.surface.orbit(&start, pivot, *heading_deg, *pitch_deg);
            // An orbit that would take the eye under the ground turns only
            // (the tilt is what lowers it), then is lifted where needed.
            if below_ground(snap, &orbited) { s.surface.orbit(&start, pivot, *heading_deg, 0.0) } else { orbited }
        }
        Gesture::Pan { from, to } => {
            let (from, to) = (fraction("pan.from_x", *from)?, fraction("pan.to_x", *to)?);
            match s.point(snap, from) {
                Some(grab) => s.surface.pan(&start, grab, s.ray(to)),
                None => start,
            }
        }
        Gesture::Zoom { factor, at } => {
            if !(factor.is_finite() && (0.01..=100.0).contains(factor)) {
                return Err(bad("zoom.factor", format!("{factor} is not from 0.01 to 100")));
            }
            let at = fraction("zoom.x", *at)?;
            // Toward the ground under the cursor (never reaching it: the
            // zoom keeps a share of the distance); over the sky, a step
            // as long as the height above the ground.
            let target = s.point(snap, at).unwrap_or_else(|| s.view.eye + s.ray(at) * speed_m);
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
            s.surface.travel(&start, forward * speed_m, right * speed_m, up * speed_m, *turn_deg)
        }
        Gesture::FlyTo(id) => {
            let slot = snap
                .index_of(id)
                .map(|i| &snap.slots[i])
                .ok_or_else(|| ViewError::UnknownSource(relief_source::echo::echoed(id)))?;
            let extent = slot.source.as_ref().and_then(|src| src.info().extent).ok_or_else(|| {
                bad("fly_to_source", format!("source '{id}' has no extent to fly to (it has no data loaded)"))
            })?;
            let framed = framing(snap, extent, camera.vertical_fov_deg);
            pose(snap, &framed)?
        }
    };
    let kept = keep_in_scene(snap, &moved);
    let mut camera = camera_of(snap, &kept).map_err(|e| bad("camera", e))?;
    camera.altitude_m = camera.altitude_m.clamp(-11_000.0, MAX_ALTITUDE_M);
    pose(snap, &camera)?;
    Ok(camera)
}

/// Whether a pose's eye is under the ground plus the clearance.
fn below_ground(snap: &SceneSnapshot, pose: &Pose) -> bool {
    pose.position[2] < ground_heights(snap, &[pose.position])[0] + CLEARANCE_M
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
