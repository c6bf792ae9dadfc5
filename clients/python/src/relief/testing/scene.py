"""The test scene: an analytic Gaussian hill DEM and a few parcels, written
through GDAL's Python bindings, so every answer can be checked against the
formula the data came from.

The DEM is the Rust tests' hill: 400 x 400 Float32 pixels of 0.00125
degrees over 10..10.5 E, 45..45.5 N (EPSG:4326), a 500 m plain with a
Gaussian hill of 1500 m (so 2000 m at the top) at 10.25 E, 45.25 N, sigma
0.08 degrees. The parcels are a shapefile of polygons (fields `name` and
`height`), drawn onto a hillshade of the DEM with a `rasterize` and an
`overlay` source as in the README's manifest, and extruded as buildings.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

# The hill's formula and grid (the same as examples/src/lib.rs).
PLAIN_M = 500.0
PEAK_RISE_M = 1500.0
PEAK_LON = 10.25
PEAK_LAT = 45.25
SIGMA_DEG = 0.08
ORIGIN_LON = 10.0
ORIGIN_LAT = 45.5
PIXEL_DEG = 0.00125
WIDTH = 400
HEIGHT = 400
CRS = "EPSG:4326"

#: The parcels: (name, height attribute in m, outer ring as (lon, lat)).
PARCELS: tuple[tuple[str, float, tuple[tuple[float, float], ...]], ...] = (
    ("meadow", 12.0, ((10.05, 45.05), (10.15, 45.05), (10.15, 45.12), (10.05, 45.12), (10.05, 45.05))),
    ("summit", 30.0, ((10.23, 45.23), (10.27, 45.23), (10.27, 45.27), (10.23, 45.27), (10.23, 45.23))),
    ("forest", 8.0, ((10.32, 45.33), (10.45, 45.33), (10.45, 45.44), (10.32, 45.44), (10.32, 45.33))),
)

MANIFEST = """\
# Written by relief.testing: an analytic hill and parcels drawn on it.
[scene]
name = "hill"

[[source]]
id = "dem"
kind = "gdal"
path = "hill.tif"

[[source]]
id = "shade"
kind = "hillshade"
inputs = ["dem"]

[[source]]
id = "parcels"
kind = "shapefile"
path = "parcels.shp"

[[source]]
id = "parcels-drawn"
kind = "rasterize"
inputs = ["parcels"]
fill = "#d03020a0"
stroke = "#202020ff"
stroke_width_px = 2

[[source]]
id = "map"
kind = "overlay"
inputs = ["shade", "parcels-drawn"]

[[source]]
id = "buildings"
kind = "extrude"
inputs = ["parcels", "dem"]
height_attribute = "height"
min_level = 0

[layers]
height = "dem"
color = "map"
{extra}
[camera]
lon_deg = 10.25
lat_deg = 45.1
altitude_m = 9000
pitch_deg = -45
"""


def hill(lon: Any, lat: Any) -> Any:
    """The hill's height in metres at (lon, lat) degrees; numpy arrays work."""
    dx, dy = np.subtract(lon, PEAK_LON), np.subtract(lat, PEAK_LAT)
    return PLAIN_M + PEAK_RISE_M * np.exp(-(dx * dx + dy * dy) / (2.0 * SIGMA_DEG * SIGMA_DEG))


def hill_at(lon: float, lat: float) -> float:
    """The hill's height at one point, as a float."""
    dx, dy = lon - PEAK_LON, lat - PEAK_LAT
    return PLAIN_M + PEAK_RISE_M * math.exp(-(dx * dx + dy * dy) / (2.0 * SIGMA_DEG * SIGMA_DEG))


def hill_pixels() -> npt.NDArray[np.float32]:
    """The DEM's pixels (rows from the north), each the hill at its centre."""
    lons = ORIGIN_LON + (np.arange(WIDTH) + 0.5) * PIXEL_DEG
    lats = ORIGIN_LAT - (np.arange(HEIGHT) + 0.5) * PIXEL_DEG
    grid_lon, grid_lat = np.meshgrid(lons, lats)
    return np.asarray(hill(grid_lon, grid_lat), dtype=np.float32)


def _gdal() -> Any:
    try:
        from osgeo import gdal
    except ImportError as e:  # pragma: no cover - depends on the machine
        raise ImportError(
            "relief.testing writes scenes through GDAL's Python bindings: install python3-gdal "
            "(Debian) and make them visible (a venv made with --system-site-packages)"
        ) from e
    gdal.UseExceptions()
    return gdal


def _spatial_ref(epsg: int) -> Any:
    from osgeo import osr

    srs = osr.SpatialReference()
    srs.ImportFromEPSG(epsg)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return srs


def write_hill_dem(path: str | Path) -> Path:
    """Writes the hill as a Float32 GeoTIFF (plain strips, no compression)."""
    gdal = _gdal()
    out = Path(path)
    ds = gdal.GetDriverByName("GTiff").Create(str(out), WIDTH, HEIGHT, 1, gdal.GDT_Float32)
    ds.SetGeoTransform((ORIGIN_LON, PIXEL_DEG, 0.0, ORIGIN_LAT, 0.0, -PIXEL_DEG))
    ds.SetProjection(_spatial_ref(4326).ExportToWkt())
    band = ds.GetRasterBand(1)
    band.WriteArray(hill_pixels())
    band.FlushCache()
    ds.FlushCache()
    del band
    del ds
    return out


def write_polygons(
    path: str | Path,
    parcels: Sequence[tuple[str, float, Sequence[tuple[float, float]]]] = PARCELS,
) -> Path:
    """Writes polygons as an ESRI shapefile in EPSG:4326 through OGR (UTF-8,
    with a .cpg), fields `name` (string) and `height` (real)."""
    _gdal()
    from osgeo import ogr

    out = Path(path)
    driver = ogr.GetDriverByName("ESRI Shapefile")
    if out.exists():
        driver.DeleteDataSource(str(out))
    ds = driver.CreateDataSource(str(out))
    layer = ds.CreateLayer(out.stem, _spatial_ref(4326), ogr.wkbPolygon, options=["ENCODING=UTF-8"])
    layer.CreateField(ogr.FieldDefn("name", ogr.OFTString))
    layer.CreateField(ogr.FieldDefn("height", ogr.OFTReal))
    for name, height, ring in parcels:
        feature = ogr.Feature(layer.GetLayerDefn())
        feature.SetField("name", name)
        feature.SetField("height", float(height))
        feature.SetGeometry(polygon(ring))
        layer.CreateFeature(feature)
        del feature
    layer.SyncToDisk()
    del layer
    del ds
    return out


def polygon(ring: Sequence[tuple[float, float]]) -> Any:
    """An OGR polygon from one outer ring of (x, y); closed if it is not."""
    from osgeo import ogr

    points = list(ring)
    if points and points[0] != points[-1]:
        points.append(points[0])
    linear = ogr.Geometry(ogr.wkbLinearRing)
    for x, y in points:
        linear.AddPoint_2D(float(x), float(y))
    poly = ogr.Geometry(ogr.wkbPolygon)
    poly.AddGeometry(linear)
    return poly


@dataclass(frozen=True)
class HillScene:
    """A scene written by write_hill_scene: its folder and files."""

    dir: Path
    manifest: Path
    #: The hill DEM (source `dem`, the height layer).
    dem: Path
    #: The parcels shapefile (source `parcels`; drawn by `parcels-drawn`,
    #: laid over `shade` by `map`, the colour layer; extruded by `buildings`).
    parcels: Path

    @staticmethod
    def height(lon: float, lat: float) -> float:
        """The DEM's formula at (lon, lat)."""
        return hill_at(lon, lat)

    @staticmethod
    def pixel(lon: float, lat: float) -> tuple[int, int]:
        """The DEM's (column, row) holding (lon, lat)."""
        # The epsilon keeps a point on a pixel edge in the pixel east/south of it.
        return (math.floor((lon - ORIGIN_LON) / PIXEL_DEG + 1e-9), math.floor((ORIGIN_LAT - lat) / PIXEL_DEG + 1e-9))

    @staticmethod
    def centre(col: int, row: int) -> tuple[float, float]:
        """(lon, lat) of the centre of DEM pixel (col, row)."""
        return (ORIGIN_LON + (col + 0.5) * PIXEL_DEG, ORIGIN_LAT - (row + 0.5) * PIXEL_DEG)


def write_hill_scene(directory: str | Path, *, extra_manifest: str = "") -> HillScene:
    """Writes the hill DEM, the parcels and scene.toml into `directory`
    (created if needed). `extra_manifest` is TOML put after [layers] (say
    "[effects]\\nlighting = {}\\n" or a [watch] section)."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    dem = write_hill_dem(out / "hill.tif")
    parcels = write_polygons(out / "parcels.shp")
    manifest = out / "scene.toml"
    manifest.write_text(MANIFEST.format(extra=extra_manifest), encoding="utf-8")
    return HillScene(dir=out, manifest=manifest, dem=dem, parcels=parcels)
