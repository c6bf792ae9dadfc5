//! The demo people see (`relief-demo-scene`, `make demo`): real terrain,
//! the SRTM heights of the Maritime Alps' southern ranges and Provence
//! committed under `examples/data` (see its README for the provenance),
//! coloured at generation time by GDAL (`gdaldem color-relief` and
//! `hillshade`, through the gdal crate), with a town, a forest grown from
//! land cover classified by height, and the Lac de Sainte-Croix as water.
//!
//! The analytic range (`write_demo_scene`) stays the benches' and `make
//! accuracy`'s fixture: its heights have a formula to check against.

use std::path::{Path, PathBuf};

use anyhow::Context;
use gdal::Dataset;
use gdal::raster::processing::dem::{ColorReliefOptions, HillshadeOptions, color_relief, hillshade};

use crate::{BROADLEAF_FOREST, CONIFER_FOREST, GRASSLAND, NODATA, RasterSpec, SHRUBLAND, write_classes};

/// The committed DEM, as this crate was built from a checkout.
pub const ALPS_DEM: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/maritime-alps-srtm3.tif");

/// The committed DEM's extent: west, south, east, north (pixel edges).
pub const ALPS_EXTENT: [f64; 4] = [6.099_583_333, 43.550_416_667, 7.599_583_333, 44.000_416_667];

/// Where the demo's town stands (lon, lat): on the flat edge of the
/// Valensole plateau above the lake's northern shore, some 650 m up.
pub const ALPS_TOWN_CENTRE: (f64, f64) = (6.135, 43.79);

/// The Lac de Sainte-Croix: the box it lies in (west, south, east, north)
/// and the heights SRTM gives its surface, and the level the water effect
/// draws it at (a metre over that surface).
pub const ALPS_LAKE_BOX: [f64; 4] = [6.10, 43.70, 6.26, 43.82];
pub const ALPS_LAKE_SURFACE_M: std::ops::RangeInclusive<i16> = 468..=472;
pub const ALPS_LAKE_LEVEL_M: f64 = 471.0;

/// The hypsometric tint, as `gdaldem color-relief` reads it: metres, then
/// red, green, blue. Sea blue at 0 m (SRTM's sea), Mediterranean greens in
/// the valleys, olive and ochre on the plateaus, browns up the slopes,
/// rock grey and pale limestone on the summits.
const TINT: &str = "\
nv     128 128 128
-100    24  64 104
0       24  64 104
1       62 112  52
250     80 128  58
600    112 136  64
1000   146 128  76
1400   128  98  70
1750   140 128 116
2100   236 232 224
";

/// The baked shading: GDAL's hillshade from the west-north-west (the demo's
/// late sun comes from the west), as a factor that leaves flat ground its
/// tint, darkens slopes turned away and lightens those facing the light.
const SHADE_AZIMUTH_DEG: f64 = 290.0;
const SHADE_ALTITUDE_DEG: f64 = 45.0;
const SHADE_RANGE: (f64, f64) = (0.35, 1.25);
/// Metres per degree, for GDAL's hillshade over a geographic grid.
const METRES_PER_DEGREE: f64 = 111_120.0;

const ALPS_MANIFEST: &str = r#"# The demo scene, written by relief-demo-scene: real terrain (SRTM v3,
# public domain: examples/data/README.md), the Maritime Alps' southern
# ranges and Provence, from the Lac de Sainte-Croix to Nice.
[scene]
name = "maritime-alps"
grid = "geodetic"

[[source]]
id = "dem"
kind = "gdal"
path = "dem.tif"
vertical_datum = "EGM96 geoid (SRTM v3)"

# A hypsometric tint shaded by the relief, made from dem.tif when the scene
# was written (gdaldem color-relief with tint.txt, times a hillshade).
[[source]]
id = "ortho"
kind = "gdal"
path = "color.tif"

[[source]]
id = "shade"
kind = "hillshade"
inputs = ["dem"]
azimuth_deg = 290
altitude_deg = 40

# A town on the plateau above the lake: footprints with a height and a
# use, extruded onto the DEM and coloured by use.
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

# Land cover classified from the heights (1 conifer forest, 2 broadleaf
# forest, 3 shrubs, 4 grass and rock), read "nearest": classes are codes.
[[source]]
id = "landcover"
kind = "gdal"
path = "landcover.tif"
resampling = "nearest"

FOREST_SOURCES
# The Lac de Sainte-Croix's mask: 1 where SRTM has its flat surface.
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
# A thin haze low in the valleys: the far ridges soften, the near ones
# keep their contrast.
fog = { density = FOG_DENSITY, falloff_m = 600, color = '#c9d3de' }
# The ridges, the town and the trees cast shadows from the sun.
shadows = {}
# The lake, a metre over SRTM's flat surface: its shallows show the bottom.
water = { level_m = 471, clarity_m = 6 }
# Ground finer than SRTM's 90 m, its roughness fitted to the DEM's own.
detail = {}

# A late June afternoon: the sun low in the west-north-west, across the
# view, so the ridges model and cast shadows.
[sun]
time = "2026-06-21T18:30:00+02:00"

[quality]
resampling = "bilinear"
reprojection_error_px = 0.125
clipmap_grid_size = 127
clipmap_levels = 8

# Where `relief render` looks from unless told otherwise.
[camera]
lon_deg = CAM_LON
lat_deg = CAM_LAT
altitude_m = CAM_ALT
heading_deg = CAM_HEADING
pitch_deg = CAM_PITCH
"#;

/// The fog's extinction per metre at sea level.
const FOG_DENSITY: f64 = 0.000_03;

/// The demo's default view (`relief render` without a camera, and the
/// viewer's first frame): lon, lat, altitude m, heading and pitch degrees.
pub const ALPS_CAMERA: [f64; 5] = [6.24, 43.63, 2600.0, 10.0, -26.0];

/// The manifest text: `ALPS_MANIFEST` with its numbers filled in.
fn manifest() -> String {
    let [lon, lat, alt, heading, pitch] = ALPS_CAMERA;
    ALPS_MANIFEST
        .replace("FOREST_SOURCES\n", crate::FOREST_SOURCES)
        .replace("FOG_DENSITY", &FOG_DENSITY.to_string())
        .replace("CAM_LON", &lon.to_string())
        .replace("CAM_LAT", &lat.to_string())
        .replace("CAM_ALT", &alt.to_string())
        .replace("CAM_HEADING", &heading.to_string())
        .replace("CAM_PITCH", &pitch.to_string())
}

/// Writes the demo scene on the DEM `dem` (normally [`ALPS_DEM`]) into
/// `out`: the DEM copied as `dem.tif`, its colour (`color.tif`, from
/// `tint.txt`), a town, land cover for the forest, the lake's mask, and
/// the manifest. Returns the manifest's path.
pub fn write_alps_demo_scene(out: &Path, dem: &Path) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let dem_path = out.join("dem.tif");
    std::fs::copy(dem, &dem_path).with_context(|| format!("cannot copy the demo's DEM: {}", dem.display()))?;
    let ds = Dataset::open(&dem_path).with_context(|| format!("cannot open {}", dem_path.display()))?;
    let heights = Heights::read(&ds)?;

    let tint_table = out.join("tint.txt");
    std::fs::write(&tint_table, TINT)?;
    write_color(&ds, &tint_table, &heights, &out.join("color.tif"))?;
    crate::write_town(&out.join("town.shp"), ALPS_TOWN_CENTRE, crate::DEMO_TOWN_BUILDINGS)?;
    let grid = heights.spec();
    write_classes(&out.join("landcover.tif"), &grid, |lon, lat| alps_landcover(&heights, lon, lat))?;
    let lake = heights.cells().map(|(lon, lat, h)| u8::from(in_alps_lake(lon, lat, h))).collect();
    crate::write_geotiff(&out.join("lake.tif"), &RasterSpec { nodata: None, ..grid }, vec![lake])?;
    crate::write_manifest(out, &manifest())
}

/// The DEM's heights in memory, with its grid.
struct Heights {
    width: usize,
    height: usize,
    transform: [f64; 6],
    nodata: Option<f64>,
    values: Vec<i16>,
}

impl Heights {
    fn read(ds: &Dataset) -> anyhow::Result<Self> {
        let (width, height) = ds.raster_size();
        let band = ds.rasterband(1)?;
        let values = band.read_as::<i16>((0, 0), (width, height), (width, height), None)?.into_shape_and_vec().1;
        Ok(Self { width, height, transform: ds.geo_transform()?, nodata: band.no_data_value(), values })
    }

    fn spec(&self) -> RasterSpec<'static> {
        let t = self.transform;
        RasterSpec {
            width: self.width,
            height: self.height,
            origin_x: t[0],
            origin_y: t[3],
            pixel: t[1],
            crs: "EPSG:4326",
            nodata: None,
        }
    }

    /// The height at (lon, lat), nearest sample; None for nodata or outside.
    fn at(&self, lon: f64, lat: f64) -> Option<i16> {
        let t = self.transform;
        let (i, j) = (((lon - t[0]) / t[1]).floor(), ((lat - t[3]) / t[5]).floor());
        if i < 0.0 || j < 0.0 || i >= self.width as f64 || j >= self.height as f64 {
            return None;
        }
        let h = self.values[j as usize * self.width + i as usize];
        (self.nodata != Some(f64::from(h))).then_some(h)
    }

    /// Every sample's centre and height (None for nodata), row by row.
    fn cells(&self) -> impl Iterator<Item = (f64, f64, Option<i16>)> + '_ {
        let spec = self.spec();
        (0..self.height).flat_map(move |j| {
            (0..self.width).map(move |i| {
                let (lon, lat) = spec.centre(i, j);
                let h = self.values[j * self.width + i];
                (lon, lat, (self.nodata != Some(f64::from(h))).then_some(h))
            })
        })
    }
}

/// `gdaldem color-relief` of `ds` with the table at `table`, times GDAL's
/// hillshade (as a factor, 1 on flat ground), written as a three-band Byte
/// GeoTIFF on the DEM's grid.
fn write_color(ds: &Dataset, table: &Path, heights: &Heights, path: &Path) -> anyhow::Result<PathBuf> {
    let mut tint_options = ColorReliefOptions::new(table);
    tint_options.with_output_format("MEM");
    let tint = color_relief(ds, "tint", &tint_options).context("gdaldem color-relief failed on the demo's DEM")?;
    let mut shade_options = HillshadeOptions::new();
    shade_options
        .with_azimuth(SHADE_AZIMUTH_DEG)
        .with_altitude(SHADE_ALTITUDE_DEG)
        .with_scale(METRES_PER_DEGREE)
        .with_output_format("MEM")
        .with_compute_edges(true);
    let shade = hillshade(ds, "shade", &shade_options).context("gdaldem hillshade failed on the demo's DEM")?;
    let size = (heights.width, heights.height);
    let read = |d: &Dataset, b: usize| -> anyhow::Result<Vec<u8>> {
        Ok(d.rasterband(b)?.read_as::<u8>((0, 0), size, size, None)?.into_shape_and_vec().1)
    };
    let light = read(&shade, 1)?;
    let flat = 255.0 * SHADE_ALTITUDE_DEG.to_radians().sin();
    // Hillshade's 0 is its nodata (beside a void): leave the tint as it is.
    let factor: Vec<f64> = light
        .iter()
        .map(|&s| if s == 0 { 1.0 } else { (f64::from(s) / flat).clamp(SHADE_RANGE.0, SHADE_RANGE.1) })
        .collect();
    let planes = (1..=3)
        .map(|b| {
            let tint = read(&tint, b)?;
            Ok(tint.iter().zip(&factor).map(|(&c, f)| (f64::from(c) * f).round().clamp(0.0, 255.0) as u8).collect())
        })
        .collect::<anyhow::Result<Vec<Vec<u8>>>>()?;
    crate::write_geotiff(path, &heights.spec(), planes)
}

/// Whether a sample (lon, lat) of height `h` is the lake's surface.
fn in_alps_lake(lon: f64, lat: f64, h: Option<i16>) -> bool {
    let [w, s, e, n] = ALPS_LAKE_BOX;
    (w..=e).contains(&lon) && (s..=n).contains(&lat) && h.is_some_and(|h| ALPS_LAKE_SURFACE_M.contains(&h))
}

/// The demo's land cover at (lon, lat), from the height there with a
/// ragged border: broadleaf woods low down, conifers on the slopes, shrubs
/// above them, grass and rock on the tops and in the town; nodata over the
/// sea, the lake and SRTM's voids.
fn alps_landcover(heights: &Heights, lon: f64, lat: f64) -> u8 {
    let Some(h) = heights.at(lon, lat) else { return NODATA };
    if h <= 0 || in_alps_lake(lon, lat, Some(h)) {
        return NODATA;
    }
    let (cx, cy) = ALPS_TOWN_CENTRE;
    let half_m = 1500.0;
    if ((lat - cy) * 111_320.0).abs() < half_m && ((lon - cx) * 111_320.0 * cy.to_radians().cos()).abs() < half_m {
        return GRASSLAND;
    }
    let ragged = 120.0 * ((lon * 140.0).sin() * (lat * 170.0).cos() + 0.5 * (lon * 410.0 + lat * 290.0).sin());
    match f64::from(h) + ragged {
        h if h < 800.0 => BROADLEAF_FOREST,
        h if h < 1500.0 => CONIFER_FOREST,
        h if h < 1800.0 => SHRUBLAND,
        _ => GRASSLAND,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a test")]

    use super::*;

    #[test]
    fn demo_scene_tints_the_sea_and_masks_the_lake_from_the_committed_dem() {
        let dir = tempfile_dir();
        write_alps_demo_scene(&dir, Path::new(ALPS_DEM)).unwrap();
        let color = Dataset::open(dir.join("color.tif")).unwrap();
        let heights = Heights::read(&Dataset::open(dir.join("dem.tif")).unwrap()).unwrap();
        let pixel = |ds: &Dataset, band: usize, (lon, lat): (f64, f64)| {
            let t = heights.transform;
            let (i, j) = (((lon - t[0]) / t[1]) as isize, ((lat - t[3]) / t[5]) as isize);
            ds.rasterband(band).unwrap().read_as::<u8>((i, j), (1, 1), (1, 1), None).unwrap().data()[0]
        };
        // Off Nice the sea is 0 m: the tint's blue, unshaded.
        let sea = (7.4, 43.6);
        assert_eq!(heights.at(sea.0, sea.1), Some(0));
        assert_eq!([1, 2, 3].map(|b| pixel(&color, b, sea)), [24, 64, 104]);
        // The lake's mask covers its 22 km2 (cells of about 67 x 93 m).
        let lake = Dataset::open(dir.join("lake.tif")).unwrap();
        let mask = lake.rasterband(1).unwrap().read_band_as::<u8>().unwrap();
        let cells: usize = mask.data().iter().map(|&v| usize::from(v)).sum();
        assert!((2500..6000).contains(&cells), "{cells} lake cells");
        assert_eq!(pixel(&lake, 1, (6.1713, 43.7706)), 0, "the shore above the lake is dry");
        assert_eq!(alps_landcover(&heights, 7.4, 43.6), NODATA, "no trees at sea");
        std::fs::remove_dir_all(dir).unwrap();
    }

    fn tempfile_dir() -> PathBuf {
        let dir = std::env::temp_dir().join(format!("relief-alps-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }
}
