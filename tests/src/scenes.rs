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
    let request =
        pb::RenderRequest { camera: Some(camera), width, height, format: pb::ImageFormat::Rgba8 as i32, quality: None };
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
