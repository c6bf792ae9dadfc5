"""Follow map: the camera that shows what the QGIS map canvas shows.

The canvas gives a centre, a scale and a rotation in its own CRS; relief's
camera is geodetic (WGS 84 longitude and latitude, metres, heading from
true north). The canvas's "up" is measured where it is: a short step up
the screen from the centre, taken through the canvas CRS to WGS 84, gives
the true heading (so a polar stereographic or rotated map turns the
camera the right way) and the ground metres per map unit there (so a Web
Mercator map far from the equator is not shown too far away). The camera
then stands back from the centre along that heading, `pitch` below the
horizon, far enough that the canvas's height in metres fills its
vertical field of view at the centre."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

from qgis.core import (
    QgsCoordinateReferenceSystem,
    QgsCoordinateTransform,
    QgsCsException,
    QgsDistanceArea,
    QgsMapSettings,
    QgsPointXY,
    QgsProject,
)

WGS84 = QgsCoordinateReferenceSystem("EPSG:4326")

#: The fraction of the canvas height the step up the screen takes.
STEP = 0.01
#: Nearer a pole than this (degrees of latitude), the centre has no heading
#: of its own.
POLE_DEG = 89.9999


@dataclass(frozen=True)
class MapView:
    """What the canvas shows, on the ground: its centre (degrees), the true
    heading of the screen's up (degrees clockwise from north, [0, 360)) and
    its height in metres at the centre."""

    lon_deg: float
    lat_deg: float
    heading_deg: float
    height_m: float


def _geodesic() -> QgsDistanceArea:
    """Distances and bearings on the WGS 84 ellipsoid."""
    da = QgsDistanceArea()
    da.setSourceCrs(WGS84, QgsProject.instance().transformContext())
    da.setEllipsoid("WGS84")
    return da


def map_view(settings: QgsMapSettings) -> Optional[MapView]:
    """The ground the canvas shows; None when its centre has no place in
    WGS 84 (outside the CRS's area) or the canvas has no size yet."""
    size = settings.outputSize()
    per_pixel = settings.mapUnitsPerPixel()
    if size.height() <= 0 or not per_pixel > 0 or not math.isfinite(per_pixel):
        return None
    height = per_pixel * size.height()
    centre = settings.visibleExtent().center()
    # The screen's up in map units: the map is turned `rotation` clockwise,
    # so up points that far anticlockwise from the CRS's +y.
    r = math.radians(settings.rotation())
    step = STEP * height
    up = QgsPointXY(centre.x() - step * math.sin(r), centre.y() + step * math.cos(r))
    down = QgsPointXY(centre.x() + step * math.sin(r), centre.y() - step * math.cos(r))
    to_wgs84 = QgsCoordinateTransform(settings.destinationCrs(), WGS84, QgsProject.instance())
    try:
        c, u, d = (to_wgs84.transform(p) for p in (centre, up, down))
    except QgsCsException:
        return None
    values = (c.x(), c.y(), u.x(), u.y(), d.x(), d.y())
    if not all(math.isfinite(v) for v in values):
        return None
    da = _geodesic()
    across = da.measureLine(d, u)
    if not across > 0:
        return None
    if abs(c.y()) < POLE_DEG:
        # At the centre: the bearings to the step up and (turned round) to
        # the step down; their mean cancels the step's first-order error.
        up_deg = math.degrees(da.bearing(c, u))
        down_deg = math.degrees(da.bearing(c, d)) + 180.0
        heading = (up_deg + 0.5 * ((down_deg - up_deg + 180.0) % 360.0 - 180.0)) % 360.0
    else:
        # On a pole no bearing starts at the centre: from below it to above.
        heading = math.degrees(da.bearing(d, u)) % 360.0
    return MapView(_wrap(c.x()), max(-90.0, min(90.0, c.y())), heading, across / (2.0 * STEP))


def camera_for(view: MapView, pitch_deg: float, ground_m: float, fov_deg: float = 50.0) -> dict:
    """The camera (relief.v1.Camera as JSON) looking at the view's centre
    on ground at `ground_m` (the height there, which the caller must know:
    a guess could put the camera under the terrain), `pitch_deg` below the
    horizon (negative), the view's height filling `fov_deg`."""
    pitch = max(-90.0, min(-1.0, pitch_deg))
    distance = 0.5 * view.height_m / math.tan(math.radians(0.5 * fov_deg))
    back = distance * math.cos(math.radians(pitch))
    rise = distance * math.sin(math.radians(-pitch))
    lon, lat = view.lon_deg, view.lat_deg
    if back > 1e-3:
        behind = math.radians((view.heading_deg + 180.0) % 360.0)
        p = _geodesic().computeSpheroidProject(QgsPointXY(lon, lat), back, behind)
        if math.isfinite(p.x()) and math.isfinite(p.y()):
            lon, lat = _wrap(p.x()), max(-90.0, min(90.0, p.y()))
    return {
        "lonDeg": lon,
        "latDeg": lat,
        "altitudeM": float(ground_m) + rise,
        "headingDeg": view.heading_deg,
        "pitchDeg": pitch,
        "rollDeg": 0.0,
        "verticalFovDeg": fov_deg,
    }


def _wrap(lon: float) -> float:
    """Longitude in [-180, 180)."""
    return (lon + 180.0) % 360.0 - 180.0
