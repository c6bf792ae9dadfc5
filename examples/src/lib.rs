//! relief-examples: example scenes written through GDAL. The analytic
//! terrains have known heights: the end-to-end tests and the benchmarks use
//! them (the analytic range of `write_demo_scene` included), so each can
//! check its answers against the formula the data came from. The demo
//! people see (`relief-demo-scene`, `make demo`) is real terrain instead:
//! the committed SRTM crop under `data/` (`write_alps_demo_scene`).

mod alps;
mod landcover;

use std::path::{Path, PathBuf};

use anyhow::Context;
use gdal::DriverManager;
use gdal::raster::Buffer;
use gdal::spatial_ref::SpatialRef;

pub use alps::{
    ALPS_CAMERA, ALPS_DEM, ALPS_EXTENT, ALPS_LAKE_BOX, ALPS_LAKE_LEVEL_M, ALPS_LAKE_SURFACE_M, ALPS_TOWN_CENTRE,
    write_alps_demo_scene,
};
pub use landcover::{BROADLEAF_FOREST, CONIFER_FOREST, GRASSLAND, NODATA, SHRUBLAND, demo_landcover, write_classes};

/// A north-up raster: origin is the north-west pixel edge.
#[derive(Clone, Copy)]
pub struct RasterSpec<'a> {
    pub width: usize,
    pub height: usize,
    pub origin_x: f64,
    pub origin_y: f64,
    pub pixel: f64,
    pub crs: &'a str,
    pub nodata: Option<f64>,
}

impl RasterSpec<'_> {
    /// Centres of every pixel, row by row from the north-west.
    pub fn pixels(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        (0..self.height).flat_map(move |j| (0..self.width).map(move |i| self.centre(i, j)))
    }

    /// World coordinates of the centre of pixel (i, j).
    pub fn centre(&self, i: usize, j: usize) -> (f64, f64) {
        (self.origin_x + (i as f64 + 0.5) * self.pixel, self.origin_y - (j as f64 + 0.5) * self.pixel)
    }
}

/// Writes a Float32 GeoTIFF whose pixel (i, j) holds `height(x, y)` at the
/// pixel's centre.
pub fn write_dem(path: &Path, spec: &RasterSpec<'_>, height: impl Fn(f64, f64) -> f64) -> anyhow::Result<PathBuf> {
    let data = spec.pixels().map(|(x, y)| height(x, y) as f32).collect();
    write_geotiff(path, spec, vec![data])
}

/// Writes one band per plane as a north-up GeoTIFF described by `spec`.
pub(crate) fn write_geotiff<T: gdal::raster::GdalType + Copy>(
    path: &Path,
    spec: &RasterSpec<'_>,
    planes: Vec<Vec<T>>,
) -> anyhow::Result<PathBuf> {
    let driver = DriverManager::get_driver_by_name("GTiff")?;
    let mut ds = driver
        .create_with_band_type::<T, _>(path, spec.width, spec.height, planes.len())
        .with_context(|| format!("cannot create {}", path.display()))?;
    ds.set_geo_transform(&[spec.origin_x, spec.pixel, 0.0, spec.origin_y, 0.0, -spec.pixel])?;
    ds.set_spatial_ref(&SpatialRef::from_definition(spec.crs)?)?;
    let size = (spec.width, spec.height);
    for (b, plane) in planes.into_iter().enumerate() {
        let mut band = ds.rasterband(b + 1)?;
        band.set_no_data_value(spec.nodata)?;
        band.write((0, 0), size, &mut Buffer::new(size, plane))?;
    }
    Ok(path.to_path_buf())
}

/// A Gaussian hill: 500 m plain, 1500 m peak at (10.25 E, 45.25 N), sigma
/// 0.08 degrees.
pub fn hill(lon: f64, lat: f64) -> f64 {
    let (dx, dy) = (lon - 10.25, lat - 45.25);
    500.0 + 1500.0 * (-(dx * dx + dy * dy) / (2.0 * 0.08 * 0.08)).exp()
}

/// The hill on a 0.00125-degree grid over 10..10.5 E, 45..45.5 N (EPSG:4326).
pub fn hill_spec() -> RasterSpec<'static> {
    RasterSpec {
        width: 400,
        height: 400,
        origin_x: 10.0,
        origin_y: 45.5,
        pixel: 0.00125,
        crs: "EPSG:4326",
        nodata: None,
    }
}

/// The whole planet on a 0.5-degree grid (EPSG:4326): columns wrap at the
/// antimeridian, the first and last rows reach the poles.
pub fn globe_spec() -> RasterSpec<'static> {
    RasterSpec { width: 720, height: 360, origin_x: -180.0, origin_y: 90.0, pixel: 0.5, crs: "EPSG:4326", nodata: None }
}

/// The 20 km square of UTM 12N round `utm_surface` that analytic scenes
/// are served on: CRS, west and south edges and side, metres.
pub const UTM_SQUARE: (&str, f64, f64, f64) = ("EPSG:32612", 290_000.0, 5_090_000.0, 20_000.0);

/// A smooth analytic surface in UTM 12N metres, around Storm Lake, Montana.
pub fn utm_surface(x: f64, y: f64) -> f64 {
    2500.0 + 0.05 * (x - 300_000.0) - 0.02 * (y - 5_100_000.0) + 80.0 * ((x / 700.0).sin() * (y / 900.0).cos())
}

/// A fractal surface in metres over plane x and y in metres (any projected
/// grid; the detail effect's bench and `make accuracy` lay it over 20 km of
/// UTM 12N): 1500 m plus sines in 16 octaves, from 2.5 km down to 8 cm
/// across, each octave half the last's wavelength and height (120 m for
/// the first) and turned 1.7 radians from it. Rough at every scale, so it
/// can be the data down to one level and the truth below it.
pub fn fractal(x: f64, y: f64) -> f64 {
    let (mut h, mut wavelength, mut amplitude) = (1500.0, 2500.0, 120.0);
    for k in 0..16 {
        let a = f64::from(k) * 1.7;
        h += amplitude * ((a.cos() * x + a.sin() * y) / wavelength * std::f64::consts::TAU + a).sin();
        wavelength /= 2.0;
        amplitude /= 2.0;
    }
    h
}

/// 300 x 200 pixels of 30 m in EPSG:32612.
pub fn utm_spec() -> RasterSpec<'static> {
    RasterSpec {
        width: 300,
        height: 200,
        origin_x: 300_000.0,
        origin_y: 5_106_000.0,
        pixel: 30.0,
        crs: "EPSG:32612",
        nodata: None,
    }
}

/// Writes a manifest beside the data and returns its path.
pub fn write_manifest(dir: &Path, text: &str) -> anyhow::Result<PathBuf> {
    let path = dir.join("scene.toml");
    std::fs::write(&path, text)?;
    Ok(path)
}

/// A tiny deterministic generator for test points (no dependency needed).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

/// The demo's mountain range: a ridge running north-east with three peaks
/// (up to about 3100 m) over a 400 m valley floor, in degrees on WGS84.
pub fn demo_terrain(lon: f64, lat: f64) -> f64 {
    let peak =
        |cx: f64, cy: f64, h: f64, s: f64| h * (-((lon - cx).powi(2) + (lat - cy).powi(2)) / (2.0 * s * s)).exp();
    let along = (lon - 6.5) * 0.6 + (lat - 45.3) * 0.8;
    let across = -(lon - 6.5) * 0.8 + (lat - 45.3) * 0.6;
    let ridge = 1400.0 * (-(across * across) / (2.0 * 0.06 * 0.06)).exp() * (1.0 + 0.3 * (along * 40.0).sin());
    400.0
        + ridge
        + peak(6.35, 45.18, 1300.0, 0.05)
        + peak(6.62, 45.38, 1100.0, 0.04)
        + peak(6.8, 45.47, 900.0, 0.06)
        + 60.0 * ((lon * 90.0).sin() * (lat * 70.0).cos())
}

/// A hypsometric tint for the demo's "orthophoto": green valleys, brown
/// slopes, grey rock, white summits.
pub fn demo_color(height_m: f64) -> [u8; 3] {
    const STOPS: [(f64, [f64; 3]); 5] = [
        (300.0, [70.0, 120.0, 60.0]),
        (1000.0, [120.0, 150.0, 80.0]),
        (1800.0, [140.0, 110.0, 80.0]),
        (2500.0, [150.0, 150.0, 150.0]),
        (3000.0, [250.0, 250.0, 250.0]),
    ];
    let h = height_m.clamp(STOPS[0].0, STOPS[4].0);
    let k = STOPS.windows(2).position(|w| h <= w[1].0).unwrap_or(3);
    let ((h0, c0), (h1, c1)) = (STOPS[k], STOPS[k + 1]);
    let t = (h - h0) / (h1 - h0);
    [0, 1, 2].map(|i| (c0[i] + t * (c1[i] - c0[i])).round() as u8)
}

/// Writes a three-band Byte GeoTIFF, pixel (i, j) coloured by `color(x, y)`
/// at its centre.
pub fn write_rgb(path: &Path, spec: &RasterSpec<'_>, color: impl Fn(f64, f64) -> [u8; 3]) -> anyhow::Result<PathBuf> {
    let colors: Vec<[u8; 3]> = spec.pixels().map(|(x, y)| color(x, y)).collect();
    let planes = (0..3).map(|b| colors.iter().map(|c| c[b]).collect()).collect();
    write_geotiff(path, spec, planes)
}

/// The demo forests' `scatter` source and its rules over the land cover's
/// classes (1 conifer, 2 broadleaf, 3 shrubs; 4 grass and rock has none),
/// shared by both demo scenes' manifests.
pub(crate) const FOREST_SOURCES: &str = r#"# The forest: trees and shrubs scattered over the land cover, each class by
# its own rule, anchored on the DEM. Grass and rock (4) have no rule.
[[source]]
id = "forest"
kind = "scatter"
inputs = ["landcover", "dem"]
seed = 1

[[source.rule]]
class = 1
models = { conifer = 0.85, broadleaf = 0.15 }
density = 21000
spacing = 2
scale = [0.7, 1.3]

[[source.rule]]
class = 2
models = { broadleaf = 0.8, conifer = 0.1, shrub = 0.1 }
density = 21000
spacing = 3
scale = [0.6, 1.2]

[[source.rule]]
class = 3
models = { shrub = 0.9, conifer = 0.1 }
density = 8000
scale = [0.5, 1.1]

"#;

const DEMO_MANIFEST: &str = r#"# The analytic demo range: written by relief-examples' write_demo_scene.
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

# A town in the valley south of the range: footprints with a height and
# a use, extruded onto the DEM and coloured by use.
[[source]]
id = "town-footprints"
kind = "shapefile"
path = "town.shp"

[[source]]
id = "town"
kind = "extrude"
inputs = ["town-footprints", "dem"]
height_attribute = "height"
color_by = "use"
min_level = 10

# Land cover (class codes: 1 conifer forest, 2 broadleaf forest, 3 shrubs,
# 4 grass and rock), read "nearest": classes are codes, not quantities.
[[source]]
id = "landcover"
kind = "gdal"
path = "landcover.tif"
resampling = "nearest"

FOREST_SOURCES
# The lake's mask: 1 where there is water (a raster; a rasterized polygon
# layer's coverage would do as well).
[[source]]
id = "lake"
kind = "gdal"
path = "lake.tif"

[layers]
height = "dem"
color = "ortho"
buildings = "town"
instances = "forest"
water = "lake"

[effects]
lighting = {}
# Rayleigh and Mie scattering: a sky, and distance in blue.
atmosphere = {}
# A light haze: the far ridges fade into it.
fog = { density = 0.00006, falloff_m = 2000, color = '#c4ccd6' }
# The ridges, the town and the trees cast shadows from the sun.
shadows = {}
# The lake (lake.tif, 1 for water) at 430 m: its shallows show the bottom.
water = { level_m = 430, clarity_m = 6 }
# Ground finer than the DEM's 100 m, its roughness fitted to the DEM's own.
detail = {}

# A late June afternoon: the sun in the west.
[sun]
time = "2026-06-21T17:00:00+02:00"

[quality]
resampling = "bilinear"
reprojection_error_px = 0.125
clipmap_grid_size = 127
clipmap_levels = 8

# Where `relief render` looks from unless told otherwise: south of the
# range, looking north-north-east along it.
[camera]
lon_deg = 6.45
lat_deg = 44.95
altitude_m = 9000
heading_deg = 15
pitch_deg = -25
"#;

/// Writes the analytic demo range into `out`: a synthetic mountain range
/// (DEM with a small nodata void), an "orthophoto" tinted by height, a
/// town, the land cover a forest grows from, and the manifest. The benches
/// and `make accuracy` measure against it (its heights are
/// [`demo_terrain`]); the demo shown to people is
/// [`write_alps_demo_scene`]. Returns the manifest's path.
pub fn write_demo_scene(out: &Path) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
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
    write_dem(
        &out.join("dem.tif"),
        &dem,
        |lon, lat| {
            if in_demo_void(lon, lat) { -9999.0 } else { demo_terrain(lon, lat) }
        },
    )?;
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
    write_town(&out.join("town.shp"), DEMO_TOWN_CENTRE, DEMO_TOWN_BUILDINGS)?;
    let cover = RasterSpec { width: 2000, height: 1200, pixel: 0.0005, nodata: None, ..dem };
    write_classes(&out.join("landcover.tif"), &cover, demo_landcover)?;
    let lake = RasterSpec { nodata: None, ..cover };
    write_dem(&out.join("lake.tif"), &lake, |lon, lat| if in_demo_lake(lon, lat) { 1.0 } else { 0.0 })?;
    write_manifest(out, &DEMO_MANIFEST.replace("FOREST_SOURCES\n", FOREST_SOURCES))
}

/// Where the demo's town is (lon, lat) and how many buildings it has.
pub const DEMO_TOWN_CENTRE: (f64, f64) = (6.6, 45.09);
pub const DEMO_TOWN_BUILDINGS: usize = 2000;

/// A camera over an example scene as plain numbers, level (no roll), for
/// callers to turn into the renderer's `Pose` (this crate does not depend
/// on the renderer).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Viewpoint {
    /// Longitude and latitude in degrees, then height in metres above the
    /// ellipsoid.
    pub position: [f64; 3],
    /// Clockwise from north.
    pub heading_deg: f64,
    /// 0 looks at the horizon, -90 straight down.
    pub pitch_deg: f64,
    pub vertical_fov_deg: f64,
}

/// 60 m over the demo's wood 0.035 degrees (3.9 km) south of the town,
/// looking north across the wood and the town, 8 degrees down: the trees
/// near and far, the view the instances bench and `make accuracy` measure
/// the instance bands in.
pub fn demo_forest_view() -> Viewpoint {
    let (lon, lat) = DEMO_TOWN_CENTRE;
    let (lon, lat) = (lon, lat - 0.035);
    Viewpoint {
        position: [lon, lat, demo_terrain(lon, lat) + 60.0],
        heading_deg: 5.0,
        pitch_deg: -8.0,
        vertical_fov_deg: 50.0,
    }
}

/// Writes `count` building footprints round `centre` as a shapefile, or a
/// GeoPackage (layer `town`) where `path` ends in `.gpkg` (with GDAL, as a
/// GIS would): rectangles 12 to 30 m a side on a jittered
/// 60 m lattice, each with a `height` (6 to 24 m) and a `use`
/// (residential, commercial, industrial or civic). The same every run.
pub fn write_town(path: &Path, centre: (f64, f64), count: usize) -> anyhow::Result<PathBuf> {
    use gdal::vector::{FieldDefn, Geometry, LayerAccess, LayerOptions, OGRFieldType, OGRwkbGeometryType};

    let gpkg = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gpkg"));
    let driver = gdal::DriverManager::get_driver_by_name(if gpkg { "GPKG" } else { "ESRI Shapefile" })?;
    let mut ds = driver.create_vector_only(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut srs = gdal::spatial_ref::SpatialRef::from_epsg(4326)?;
    srs.set_axis_mapping_strategy(gdal::spatial_ref::AxisMappingStrategy::TraditionalGisOrder);
    let layer = ds.create_layer(LayerOptions {
        name: "town",
        srs: Some(&srs),
        ty: OGRwkbGeometryType::wkbPolygon,
        options: None,
    })?;
    FieldDefn::new("height", OGRFieldType::OFTReal)?.add_to_layer(&layer)?;
    FieldDefn::new("use", OGRFieldType::OFTString)?.add_to_layer(&layer)?;
    // A small linear congruential generator: the same town every run.
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut random = move || {
        state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let side = (count as f64).sqrt().ceil() as usize;
    let (deg_lat, deg_lon) = (1.0 / 111_320.0, 1.0 / (111_320.0 * centre.1.to_radians().cos()));
    for k in 0..count {
        let (i, j) = ((k % side) as f64 - side as f64 / 2.0, (k / side) as f64 - side as f64 / 2.0);
        let (x, y) =
            (centre.0 + (i * 60.0 + 20.0 * random()) * deg_lon, centre.1 + (j * 60.0 + 20.0 * random()) * deg_lat);
        let (w, d) = ((12.0 + 18.0 * random()) * deg_lon, (12.0 + 18.0 * random()) * deg_lat);
        let ring = format!("POLYGON(({x} {y},{x2} {y},{x2} {y2},{x} {y2},{x} {y}))", x2 = x + w, y2 = y + d);
        let uses = ["residential", "residential", "residential", "commercial", "industrial", "civic"];
        let mut feature = gdal::vector::Feature::new(layer.defn())?;
        feature.set_geometry(Geometry::from_wkt(&ring)?)?;
        feature.set_field_double(0, (6.0 + 18.0 * random()).round())?;
        feature.set_field_string(1, uses[(random() * uses.len() as f64) as usize % uses.len()])?;
        feature.create(&layer)?;
    }
    Ok(path.to_path_buf())
}

/// The demo DEM's extent (west, south, east, north) and its nodata void
/// (centre lon, lat and radius in degrees).
pub const DEMO_EXTENT: [f64; 4] = [6.0, 45.0, 7.0, 45.6];
pub const DEMO_VOID: [f64; 3] = [6.2, 45.45, 0.01];

/// The demo's lake (centre lon, lat and radius in degrees) round the void,
/// and its level: the water layer's mask, drawn at that level.
pub const DEMO_LAKE: [f64; 3] = [6.2, 45.45, 0.03];
pub const DEMO_LAKE_LEVEL_M: f64 = 430.0;

/// Whether (lon, lat) is in the demo's lake mask.
pub fn in_demo_lake(lon: f64, lat: f64) -> bool {
    (lon - DEMO_LAKE[0]).powi(2) + (lat - DEMO_LAKE[1]).powi(2) < DEMO_LAKE[2].powi(2)
}

/// Whether (lon, lat) is in the demo DEM's nodata void.
pub fn in_demo_void(lon: f64, lat: f64) -> bool {
    (lon - DEMO_VOID[0]).powi(2) + (lat - DEMO_VOID[1]).powi(2) < DEMO_VOID[2].powi(2)
}

/// How finely `write_textured_cog`'s texture is woven.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Texture {
    /// Soft sinusoids some 40 pixels across: a JPEG's error stays within
    /// a block's quantisation step.
    Smooth,
    /// Sinusoids a few pixels across, squared off into edges: a JPEG
    /// overview's error goes well beyond it.
    Fine,
}

/// The grey level of band `band` of `texture` at pixel (i, j).
pub fn texture_level(texture: Texture, band: usize, i: usize, j: usize) -> u8 {
    let (x, y, b) = (i as f64, j as f64, band as f64);
    let v = match texture {
        Texture::Smooth => 128.0 + 60.0 * (x / (7.0 + b) + y / 11.0).sin() * (y / (5.0 + b)).cos(),
        Texture::Fine => {
            let s = (x / (4.0 + b) + y / 6.4).sin() * (y / (2.8 + b) - x / 13.0).cos();
            128.0 + 90.0 * (s * 3.0).clamp(-1.0, 1.0)
        }
    };
    v.round().clamp(0.0, 255.0) as u8
}

/// Writes a 512 x 512 RGB image of `texture` (north-west corner at 7 E,
/// 46 N, pixels of 0.0001 degrees) as a Cloud-Optimized GeoTIFF with
/// `creation` options (`COMPRESS=JPEG`, `QUALITY=75`...), in 256-pixel
/// blocks, so it has one overview, made by GDAL's COG driver. The plain
/// GeoTIFF it was made from is left beside it (`<stem>.src.tif`).
pub fn write_textured_cog(path: &Path, texture: Texture, creation: &[&str]) -> anyhow::Result<PathBuf> {
    let spec = RasterSpec {
        width: 512,
        height: 512,
        origin_x: 7.0,
        origin_y: 46.0,
        pixel: 0.0001,
        crs: "EPSG:4326",
        nodata: None,
    };
    let planes = (0..3)
        .map(|b| (0..spec.height).flat_map(|j| (0..spec.width).map(move |i| texture_level(texture, b, i, j))).collect())
        .collect();
    let plain = path.with_extension("src.tif");
    write_geotiff::<u8>(&plain, &spec, planes)?;
    let source = gdal::Dataset::open(&plain)?;
    let driver = DriverManager::get_driver_by_name("COG")?;
    let options = creation.iter().copied().chain(["BLOCKSIZE=256"]).collect::<gdal::raster::RasterCreationOptions>();
    source.create_copy(&driver, path, &options).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(path.to_path_buf())
}
