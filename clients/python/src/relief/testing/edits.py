"""Edits of GIS files made the way GIS tools make them (see the project's
notes on how QGIS, ogr2ogr and GDAL save):

- rasters: opened with GDAL in update mode, a window written with
  WriteArray at the pixels' existing offsets, then closed (as a GDAL
  script or QGIS's raster tools do: same file, same inode, CLOSE_WRITE at
  the close);
- shapefiles: updated in place through OGR (records, .shx and .dbf
  rewritten where they are, added features appended), as QGIS's "Save
  Layer Edits" does when nothing is deleted.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from relief.testing.scene import _gdal, polygon

FloatArray = npt.NDArray[np.float64]


# ---------------------------------------------------------------- rasters


def _close(ds: Any) -> None:
    ds.FlushCache()
    close = getattr(ds, "Close", None)  # GDAL >= 3.8; before, dropping the last reference closes
    if callable(close):
        close()


def read_window(path: str | Path, x: int, y: int, width: int, height: int, band: int = 1) -> FloatArray:
    """Pixels [x, x+width) x [y, y+height) of a band, read-only, as float64."""
    gdal = _gdal()
    ds = gdal.Open(str(path), gdal.GA_ReadOnly)
    try:
        data = ds.GetRasterBand(band).ReadAsArray(x, y, width, height)
        return np.asarray(data, dtype=np.float64)
    finally:
        del ds


def write_window(path: str | Path, x: int, y: int, values: npt.ArrayLike, band: int = 1) -> None:
    """Writes `values` (rows x columns) at pixel (x, y) of a band: GDAL
    update mode, WriteArray, close."""
    gdal = _gdal()
    array = np.asarray(values)
    if array.ndim != 2:
        raise ValueError(f"a window is rows x columns, not shape {array.shape}")
    ds = gdal.OpenEx(str(path), gdal.OF_RASTER | gdal.OF_UPDATE)
    b = ds.GetRasterBand(band)
    b.WriteArray(array, int(x), int(y))
    b.FlushCache()
    del b
    _close(ds)
    del ds


def edit_window(
    path: str | Path,
    x: int,
    y: int,
    width: int,
    height: int,
    change: Callable[[FloatArray], npt.ArrayLike],
    band: int = 1,
) -> FloatArray:
    """Rewrites a window with `change(old)` (old as float64 rows x columns),
    in one update-mode open and close; returns what was written."""
    gdal = _gdal()
    ds = gdal.OpenEx(str(path), gdal.OF_RASTER | gdal.OF_UPDATE)
    b = ds.GetRasterBand(band)
    old = np.asarray(b.ReadAsArray(int(x), int(y), int(width), int(height)), dtype=np.float64)
    new = np.asarray(change(old), dtype=np.float64)
    if new.shape != old.shape:
        raise ValueError(f"change() answered shape {new.shape} for a window of {old.shape}")
    b.WriteArray(new, int(x), int(y))
    b.FlushCache()
    del b
    _close(ds)
    del ds
    return new


def raise_window(path: str | Path, x: int, y: int, width: int, height: int, by_m: float, band: int = 1) -> FloatArray:
    """Adds `by_m` to every pixel of a window (as a raster calculator)."""
    return edit_window(path, x, y, width, height, lambda old: old + by_m, band)


def pixel_of(path: str | Path, x: float, y: float) -> tuple[int, int]:
    """The (column, row) of a north-up raster holding the point (x, y) in
    the raster's CRS."""
    gdal = _gdal()
    ds = gdal.Open(str(path), gdal.GA_ReadOnly)
    try:
        ox, px, _, oy, _, py = ds.GetGeoTransform()
    finally:
        del ds
    return (math.floor((x - ox) / px), math.floor((y - oy) / py))


# ---------------------------------------------------------------- shapefiles


def _open_vector(path: str | Path) -> Any:
    _gdal()
    from osgeo import gdal

    return gdal.OpenEx(str(path), gdal.OF_VECTOR | gdal.OF_UPDATE)


def feature_count(path: str | Path) -> int:
    """Features in the first layer, as OGR counts them."""
    _gdal()
    from osgeo import gdal

    ds = gdal.OpenEx(str(path), gdal.OF_VECTOR)
    try:
        return int(ds.GetLayer(0).GetFeatureCount())
    finally:
        del ds


def move_vertex(path: str | Path, fid: int, vertex: int, dx: float, dy: float, ring: int = 0) -> tuple[float, float]:
    """Moves vertex `vertex` of ring `ring` (0: the outer ring) of polygon
    feature `fid` by (dx, dy), in place (the ring's closing vertex moves
    with its first); returns the new position."""
    ds = _open_vector(path)
    layer = ds.GetLayer(0)
    feature = layer.GetFeature(int(fid))
    if feature is None:
        del layer, ds
        raise KeyError(f"no feature {fid} in {path}")
    geometry = feature.GetGeometryRef().Clone()
    polygon_geom = geometry.GetGeometryRef(0) if geometry.GetGeometryName() == "MULTIPOLYGON" else geometry
    linear = polygon_geom.GetGeometryRef(int(ring))
    count = linear.GetPointCount()
    if not 0 <= vertex < count:
        del layer, ds
        raise IndexError(f"ring {ring} of feature {fid} has {count} vertices, not {vertex + 1}")
    x, y = linear.GetX(vertex) + dx, linear.GetY(vertex) + dy
    linear.SetPoint_2D(vertex, x, y)
    closed = count > 1 and vertex in (0, count - 1)
    if closed:
        linear.SetPoint_2D(count - 1 if vertex == 0 else 0, x, y)
    feature.SetGeometry(geometry)
    layer.SetFeature(feature)
    layer.SyncToDisk()
    del feature, layer
    _close(ds)
    del ds
    return (x, y)


def add_feature(
    path: str | Path, ring: Sequence[tuple[float, float]], attributes: Mapping[str, Any] | None = None
) -> int:
    """Appends a polygon (one outer ring of (x, y)) with `attributes`, in
    place; returns its feature id."""
    ds = _open_vector(path)
    layer = ds.GetLayer(0)
    from osgeo import ogr

    feature = ogr.Feature(layer.GetLayerDefn())
    for name, value in (attributes or {}).items():
        feature.SetField(name, value)
    feature.SetGeometry(polygon(ring))
    layer.CreateFeature(feature)
    fid = int(feature.GetFID())
    layer.SyncToDisk()
    del feature, layer
    _close(ds)
    del ds
    return fid


def set_attribute(path: str | Path, fid: int, name: str, value: Any) -> None:
    """Changes one attribute of feature `fid`, in place."""
    ds = _open_vector(path)
    layer = ds.GetLayer(0)
    feature = layer.GetFeature(int(fid))
    if feature is None:
        del layer, ds
        raise KeyError(f"no feature {fid} in {path}")
    feature.SetField(name, value)
    layer.SetFeature(feature)
    layer.SyncToDisk()
    del feature, layer
    _close(ds)
    del ds
