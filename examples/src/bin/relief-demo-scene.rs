//! Writes the demo scene: a synthetic mountain range (DEM), an "orthophoto"
//! tinted by height, and a manifest that drapes it and shades the relief.
//!
//! relief-demo-scene OUT_DIR

use std::path::PathBuf;

use anyhow::Context;
use relief_examples::{RasterSpec, demo_color, demo_terrain, write_dem, write_manifest, write_rgb};

const MANIFEST: &str = r#"# The demo scene: written by relief-demo-scene.
[scene]
name = "demo-range"
grid = "geodetic"

[[source]]
id = "dem"
kind = "gdal"
path = "dem.tif"
vertical_datum = "WGS84 ellipsoid (synthetic)"

[[source]]
id = "ortho"
kind = "gdal"
path = "ortho.tif"

[[source]]
id = "shade"
kind = "hillshade"
inputs = ["dem"]
azimuth_deg = 315
altitude_deg = 40

[layers]
height = "dem"
color = "ortho"

[effects]
lighting = {}

[quality]
resampling = "bilinear"
reprojection_error_px = 0.125
"#;

fn main() -> anyhow::Result<()> {
    let out = PathBuf::from(std::env::args().nth(1).context("usage: relief-demo-scene OUT_DIR")?);
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let dem = RasterSpec {
        width: 1000,
        height: 600,
        origin_x: 6.0,
        origin_y: 45.6,
        pixel: 0.001,
        crs: "EPSG:4326",
        nodata: Some(-9999.0),
    };
    // A small void (a lake the survey missed) so nodata handling shows.
    write_dem(&out.join("dem.tif"), &dem, |lon, lat| {
        if (lon - 6.2).powi(2) + (lat - 45.45).powi(2) < 0.01f64.powi(2) { -9999.0 } else { demo_terrain(lon, lat) }
    })?;
    let ortho = RasterSpec {
        width: 500,
        height: 300,
        origin_x: 6.0,
        origin_y: 45.6,
        pixel: 0.002,
        crs: "EPSG:4326",
        nodata: None,
    };
    write_rgb(&out.join("ortho.tif"), &ortho, |lon, lat| demo_color(demo_terrain(lon, lat)))?;
    let manifest = write_manifest(&out, MANIFEST)?;
    #[expect(clippy::print_stdout, reason = "tells the caller where the scene is")]
    {
        println!("{}", manifest.display());
    }
    Ok(())
}
