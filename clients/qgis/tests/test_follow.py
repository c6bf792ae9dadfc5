"""Follow map's geometry against a reference of the test's own: WGS 84
radii of curvature and the projections' known properties (Mercator and
polar stereographic are conformal, so a map turned r degrees turns the
camera r degrees there; polar stereographic's grid north at longitude L
is L - L0 east of true north). Tolerances: 1e-4 degrees for headings,
0.1 % for ground sizes (the step up the screen is 1 % of the map's height)."""

from __future__ import annotations

import math

import pytest
from conftest import PLUGIN  # noqa: F401 (the plugin's folder is on sys.path)
from qgis.core import (
    QgsCoordinateReferenceSystem,
    QgsCoordinateTransform,
    QgsMapSettings,
    QgsPointXY,
    QgsProject,
    QgsRectangle,
)
from qgis.PyQt.QtCore import QSize
from relief_qgis.follow import MapView, camera_for, map_view
from test_plugin import A, radii

HEADING_TOL = 1e-4


def settings(crs: str, centre: tuple[float, float], height: float, rotation: float = 0.0) -> QgsMapSettings:
    """A 800 x 600 map in `crs` centred on the point (given in WGS 84),
    `height` map units tall."""
    ms = QgsMapSettings()
    target = QgsCoordinateReferenceSystem(crs)
    ms.setDestinationCrs(target)
    ms.setOutputSize(QSize(800, 600))
    to_map = QgsCoordinateTransform(QgsCoordinateReferenceSystem("EPSG:4326"), target, QgsProject.instance())
    c = to_map.transform(QgsPointXY(*centre))
    w = height * 800 / 600
    ms.setExtent(QgsRectangle(c.x() - w / 2, c.y() - height / 2, c.x() + w / 2, c.y() + height / 2))
    ms.setRotation(rotation)
    return ms


def turn(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def test_a_plate_carree_map_north_up() -> None:
    view = map_view(settings("EPSG:4326", (10.3, 45.3), 0.2))
    assert view is not None
    assert abs(view.lon_deg - 10.3) < 1e-9 and abs(view.lat_deg - 45.3) < 1e-9
    assert turn(view.heading_deg, 0.0) < HEADING_TOL
    expected = math.radians(0.2) * radii(45.3)[0]
    assert abs(view.height_m - expected) < 1e-3 * expected


@pytest.mark.parametrize("rotation", [30.0, -75.0, 180.0])
def test_world_mercator_is_conformal_so_the_map_turns_the_camera_as_much(rotation: float) -> None:
    view = map_view(settings("EPSG:3395", (10.3, 60.0), 20000.0, rotation))
    assert view is not None
    assert turn(view.heading_deg, -rotation) < HEADING_TOL, view
    # A map unit is N cos(lat) / a metres on the ellipsoid, every way.
    expected = 20000.0 * radii(60.0)[1] * math.cos(math.radians(60.0)) / A
    assert abs(view.height_m - expected) < 1e-3 * expected, (view.height_m, expected)


@pytest.mark.parametrize("rotation", [0.0, 30.0, -75.0])
def test_web_mercator_is_not_conformal_on_the_ellipsoid_and_follow_map_knows(rotation: float) -> None:
    # EPSG:3857 puts x = a lon, y = a ln tan(pi/4 + lat/2) with geodetic
    # lat: a map unit east is N cos(lat) / a metres, north M cos(lat) / a.
    # The screen's up (-sin r, cos r) is then at azimuth atan2(-N sin r, M cos r),
    # up to 0.04 degrees off -r at 60 N.
    view = map_view(settings("EPSG:3857", (10.3, 60.0), 20000.0, rotation))
    assert view is not None
    m, n = radii(60.0)
    r = math.radians(rotation)
    assert turn(view.heading_deg, math.degrees(math.atan2(-n * math.sin(r), m * math.cos(r)))) < HEADING_TOL, view
    if rotation == 0.0:
        expected = 20000.0 * m * math.cos(math.radians(60.0)) / A
        assert abs(view.height_m - expected) < 1e-3 * expected, (view.height_m, expected)


@pytest.mark.parametrize(("lon", "rotation"), [(0.0, 0.0), (0.0, 30.0), (100.0, 0.0), (-120.0, 10.0)])
def test_polar_stereographic_grid_north_is_turned_by_the_longitude(lon: float, rotation: float) -> None:
    # EPSG:3413: NSIDC sea ice polar stereographic north, L0 = -45.
    view = map_view(settings("EPSG:3413", (lon, 70.0), 50000.0, rotation))
    assert view is not None
    assert turn(view.heading_deg, lon + 45.0 - rotation) < HEADING_TOL, view


def test_a_map_centred_on_the_pole_gives_a_finite_camera() -> None:
    view = map_view(settings("EPSG:3413", (0.0, 90.0), 50000.0))
    assert view is not None
    assert view.lat_deg > 89.99 and 0.0 <= view.heading_deg < 360.0
    camera = camera_for(view, -45.0, 0.0)
    assert all(math.isfinite(v) for v in camera.values())
    assert -90.0 <= camera["latDeg"] <= 90.0 and -180.0 <= camera["lonDeg"] < 180.0


def test_a_map_across_the_antimeridian() -> None:
    # EPSG:3832, Mercator centred on 150 E: 180 is inside its map.
    view = map_view(settings("EPSG:3832", (180.0, -17.0), 20000.0, 0.0))
    assert view is not None
    assert abs(abs(view.lon_deg) - 180.0) < 1e-6 and -180.0 <= view.lon_deg < 180.0
    assert turn(view.heading_deg, 0.0) < HEADING_TOL
    camera = camera_for(view, -30.0, 12.0)
    assert -180.0 <= camera["lonDeg"] < 180.0
    # Standing south of the centre, looking north.
    assert camera["latDeg"] < -17.0 and abs(abs(camera["lonDeg"]) - 180.0) < 1e-6


def test_the_camera_stands_back_along_the_heading_at_the_pitch() -> None:
    view = MapView(lon_deg=10.0, lat_deg=45.0, heading_deg=90.0, height_m=10000.0)
    camera = camera_for(view, -30.0, 250.0, fov_deg=50.0)
    distance = 5000.0 / math.tan(math.radians(25.0))
    assert abs(camera["altitudeM"] - (250.0 + distance * 0.5)) < 1e-6
    m, n = radii(45.0)
    back = distance * math.cos(math.radians(30.0))
    # Looking east, so standing west of the centre, on its parallel
    # (to the geodesic's small curvature over a few km).
    assert abs(camera["lonDeg"] - (10.0 - math.degrees(back / (n * math.cos(math.radians(45.0)))))) < 1e-5
    assert abs(camera["latDeg"] - 45.0) < 1e-4
    assert camera["headingDeg"] == 90.0 and camera["pitchDeg"] == -30.0


def test_a_map_without_a_size_or_off_the_earth_follows_nothing() -> None:
    ms = QgsMapSettings()
    ms.setDestinationCrs(QgsCoordinateReferenceSystem("EPSG:3857"))
    assert map_view(ms) is None  # No size yet.
    # An orthographic view of the earth from above 45 N 10 E: its disc has
    # a radius of about 6378 km, and 9000 km east of its centre is space.
    ortho = QgsCoordinateReferenceSystem.fromProj("+proj=ortho +lat_0=45 +lon_0=10 +datum=WGS84 +units=m +no_defs")
    assert ortho.isValid()
    space = QgsMapSettings()
    space.setDestinationCrs(ortho)
    space.setOutputSize(QSize(800, 600))
    space.setExtent(QgsRectangle(8.9e6, -1e5, 9.1e6, 1e5))
    assert map_view(space) is None
    # Its centre is fine.
    space.setExtent(QgsRectangle(-1e5, -1e5, 1e5, 1e5))
    view = map_view(space)
    assert view is not None and abs(view.lon_deg - 10.0) < 1e-9 and abs(view.lat_deg - 45.0) < 1e-9
    assert turn(view.heading_deg, 0.0) < HEADING_TOL
