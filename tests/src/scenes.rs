//! Scenes the end-to-end tests serve, written from analytic fixtures.

use std::path::{Path, PathBuf};

use relief_proto::v1 as pb;

use crate::fixtures;

/// The hill DEM (`dem`) and an "orthophoto" tinted by height (`tint`), with
/// `effects` (a manifest fragment, say "[effects]\nlighting = {}\n") and a
/// camera south of the hill at 9 km, 45 degrees down.
pub fn hill(dir: &Path, effects: &str) -> anyhow::Result<PathBuf> {
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill)?;
    fixtures::write_rgb(&dir.join("tint.tif"), &fixtures::hill_spec(), |x, y| {
        fixtures::demo_color(fixtures::hill(x, y))
    })?;
    fixtures::write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"hill\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n[[source]]\nid = \"tint\"\nkind = \"gdal\"\npath = \"tint.tif\"\n\n[layers]\nheight = \"dem\"\ncolor = \"tint\"\n{effects}\n[camera]\nlon_deg = 10.25\nlat_deg = 45.1\naltitude_m = 9000\npitch_deg = -45\n"
        ),
    )
}

/// One frame from `camera`, `size` pixels, as raw RGBA8.
pub async fn render_rgba(
    channel: &tonic::transport::Channel,
    camera: pb::Camera,
    (width, height): (u32, u32),
) -> anyhow::Result<pb::RenderResponse> {
    let format = pb::ImageFormat::Rgba8 as i32;
    let request = pb::RenderRequest { camera: Some(camera), width, height, format, ..Default::default() };
    Ok(relief_proto::v1::view_service_client::ViewServiceClient::new(channel.clone())
        .max_decoding_message_size(64 << 20)
        .render(request)
        .await?
        .into_inner())
}

/// A camera with no roll and a 50 degree field of view.
pub fn camera(lon: f64, lat: f64, alt: f64, heading: f64, pitch: f64) -> pb::Camera {
    pb::Camera {
        lon_deg: lon,
        lat_deg: lat,
        altitude_m: alt,
        heading_deg: heading,
        pitch_deg: pitch,
        roll_deg: 0.0,
        vertical_fov_deg: 50.0,
    }
}

/// The parcels a town GeoPackage holds: 30 squares 0.02 degrees wide in
/// 5 columns and 6 rows over the hill, each with a `name` and a `height`.
pub fn town_parcels() -> String {
    let squares: Vec<(String, f64, f64, f64)> = (0..30)
        .map(|k| {
            let (col, row) = (f64::from(k % 5), f64::from(k / 5));
            (
                format!(r#"{{"name": "p{k}", "height": {}}}"#, 1.5 * f64::from(k)),
                10.05 + 0.08 * col,
                45.03 + 0.07 * row,
                0.02,
            )
        })
        .collect();
    let borrowed: Vec<(&str, f64, f64, f64)> = squares.iter().map(|(p, w, s, d)| (p.as_str(), *w, *s, *d)).collect();
    crate::vectors::squares(&borrowed)
}

/// The roads of the town GeoPackage: three lines.
pub const TOWN_ROADS: &str = r#"{"type": "FeatureCollection", "features": [
{"type": "Feature", "properties": {"ref": "A1"}, "geometry": {"type": "LineString", "coordinates": [[10.0, 45.0], [10.5, 45.5]]}},
{"type": "Feature", "properties": {"ref": "B2"}, "geometry": {"type": "LineString", "coordinates": [[10.1, 45.4], [10.4, 45.1]]}},
{"type": "Feature", "properties": {"ref": "C3"}, "geometry": {"type": "LineString", "coordinates": [[10.2, 45.0], [10.2, 45.5]]}}]}"#;

/// A town scene over the hill: `town.gpkg` with layers `parcels` and
/// `roads`, each an `ogr` source of the same name, the parcels drawn
/// (`drawn`, rasterize) as the colour layer. The manifest and the
/// GeoPackage; `watch` is a `[watch]` fragment (or empty).
pub fn town(dir: &Path, watch: &str) -> anyhow::Result<(PathBuf, PathBuf)> {
    fixtures::write_dem(&dir.join("hill.tif"), &fixtures::hill_spec(), fixtures::hill)?;
    let gpkg =
        crate::vectors::geopackage(&dir.join("town.gpkg"), &[("parcels", &town_parcels()), ("roads", TOWN_ROADS)])?;
    let manifest = fixtures::write_manifest(
        dir,
        &format!(
            "[scene]\nname = \"town\"\n\n[[source]]\nid = \"dem\"\nkind = \"gdal\"\npath = \"hill.tif\"\n\n[[source]]\nid = \"parcels\"\nkind = \"ogr\"\npath = \"town.gpkg\"\nlayer = \"parcels\"\n\n[[source]]\nid = \"roads\"\nkind = \"ogr\"\npath = \"town.gpkg\"\nlayer = \"roads\"\n\n[[source]]\nid = \"drawn\"\nkind = \"rasterize\"\ninputs = [\"parcels\"]\n\n[layers]\nheight = \"dem\"\ncolor = \"drawn\"\n{watch}"
        ),
    )?;
    Ok((manifest, gpkg))
}
