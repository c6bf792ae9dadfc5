//! Cameras as viewers give them (geodetic, on any scene), and the
//! renderer's poses (in the grid's CRS): both ways, and the cameras that
//! frame an extent.

use relief_renderer::{Pose, RenderError};
use relief_source::{CrsTransform, Extent, GeodeticPoint};

use crate::graph::SceneSnapshot;

/// A camera as viewers give it: geodetic position on any scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub lon_deg: f64,
    pub lat_deg: f64,
    pub altitude_m: f64,
    pub heading_deg: f64,
    pub pitch_deg: f64,
    pub roll_deg: f64,
    pub vertical_fov_deg: f64,
}

/// Grid x, y of geodetic points on a projected scene (unchanged on the
/// planet).
fn to_grid(snap: &SceneSnapshot, field: &'static str, lon: f64, lat: f64) -> Result<(f64, f64), RenderError> {
    if snap.grid.is_geodetic() {
        return Ok((lon, lat));
    }
    let (mut xs, mut ys) = ([lon], [lat]);
    relief_source_gdal::OsrTransform
        .transform("EPSG:4326", snap.grid.crs(), &mut xs, &mut ys)
        .map_err(|e| RenderError::Camera { field, message: format!("cannot place it in {}: {e}", snap.grid.crs()) })?;
    Ok((xs[0], ys[0]))
}

/// Longitude and latitude of a grid point.
pub fn to_geodetic(snap: &SceneSnapshot, x: f64, y: f64) -> Result<(f64, f64), String> {
    if snap.grid.is_geodetic() {
        return Ok((x, y));
    }
    let (mut xs, mut ys) = ([x], [y]);
    relief_source_gdal::OsrTransform
        .transform(snap.grid.crs(), "EPSG:4326", &mut xs, &mut ys)
        .map_err(|e| format!("cannot take ({x}, {y}) from {} to longitude and latitude: {e}", snap.grid.crs()))?;
    Ok((xs[0], ys[0]))
}

/// The renderer's pose for a geodetic camera: longitude and latitude go to
/// the grid's CRS on a projected scene.
pub fn pose(snap: &SceneSnapshot, c: &Camera) -> Result<Pose, RenderError> {
    let mut pose = Pose {
        position: [c.lon_deg, c.lat_deg, c.altitude_m],
        heading_deg: c.heading_deg,
        pitch_deg: c.pitch_deg,
        roll_deg: c.roll_deg,
        vertical_fov_deg: c.vertical_fov_deg,
    };
    pose.validate(true)?;
    if !snap.grid.is_geodetic() {
        let (x, y) = to_grid(snap, "lon_deg", c.lon_deg, c.lat_deg)?;
        pose.position = [x, y, c.altitude_m];
        pose.validate(false)?;
    }
    Ok(pose)
}

/// The geodetic camera of a pose, longitude wrapped to [-180, 180).
pub fn camera_of(snap: &SceneSnapshot, pose: &Pose) -> Result<Camera, String> {
    let [x, y, h] = pose.position;
    let (lon, lat) = to_geodetic(snap, x, y)?;
    Ok(Camera {
        lon_deg: (lon + 180.0).rem_euclid(360.0) - 180.0,
        lat_deg: lat.clamp(-90.0, 90.0),
        altitude_m: h,
        heading_deg: pose.heading_deg,
        pitch_deg: pose.pitch_deg,
        roll_deg: pose.roll_deg,
        vertical_fov_deg: pose.vertical_fov_deg,
    })
}

/// The height layer's data at a point, None over nodata or without one.
/// Blocking.
pub fn ground_height(snap: &SceneSnapshot, lon_deg: f64, lat_deg: f64) -> Option<f64> {
    let source = snap.layer("height")?.source.as_ref()?;
    let heights = source.sample_heights(&[GeodeticPoint { lon_deg, lat_deg }], &snap.manifest.quality).ok()?;
    heights.first().copied().flatten()
}

/// A camera that shows `extent` (in the grid's CRS) whole: from the south,
/// 35 degrees down. The manifest's `[camera]` fields win where `manifest`
/// is set.
pub fn framing(snap: &SceneSnapshot, extent: Extent, manifest: bool) -> Camera {
    let raw = if manifest { snap.manifest.picture.camera } else { crate::manifest::RawCamera::default() };
    let (mut lon, mut lat) = (f64::midpoint(extent.min_x, extent.max_x), f64::midpoint(extent.min_y, extent.max_y));
    let metres = |d: f64| d * if snap.grid.is_geodetic() { 111_320.0 } else { 1.0 };
    let size_m = metres(extent.height()).clamp(100.0, 2.0e7);
    if let Ok(p) = to_geodetic(snap, lon, lat) {
        (lon, lat) = p;
    }
    let altitude = 0.5 * size_m + 2000.0;
    let back_deg = (0.6 * size_m / 111_320.0).min(30.0);
    Camera {
        lon_deg: raw.lon_deg.unwrap_or(lon),
        lat_deg: raw.lat_deg.unwrap_or((lat - back_deg).clamp(-89.0, 89.0)),
        altitude_m: raw.altitude_m.unwrap_or(altitude),
        heading_deg: raw.heading_deg.unwrap_or(0.0),
        pitch_deg: raw.pitch_deg.unwrap_or(-35.0),
        roll_deg: raw.roll_deg.unwrap_or(0.0),
        vertical_fov_deg: raw.vertical_fov_deg.unwrap_or(50.0),
    }
}

/// The manifest's `[camera]`, its gaps filled to frame the height layer
/// (or the whole grid).
pub fn default_camera(snap: &SceneSnapshot) -> Camera {
    let layer_extent = ["height", "color"]
        .iter()
        .filter_map(|l| snap.layer(l))
        .find_map(|slot| slot.source.as_ref().and_then(|s| s.info().extent));
    framing(snap, layer_extent.unwrap_or_else(|| snap.grid.extent()), true)
}
