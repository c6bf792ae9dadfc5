"""reliefd's quantized-mesh-1.0 terrain (`/tiles/terrain`) read by an
independent decoder, quantized-mesh-tile (PyPI), over every tile of levels
0 to 10 of a geodetic scene whose heights have a formula.

The DEM is a Gaussian bump, H exp(-r^2 / 2 sigma^2), on 0.0007 degree
pixels (so the layer's finest level is 10, whose sample step is 180 / 2^18
= 0.000687 degrees), reaching 5 sigma from the peak each way: at its edges
the bump is below 5 mm, so the 0 m that reliefd gives outside the DEM is
the formula there too, and no cliff runs round the data.

What is checked, for each tile: it decodes (the decoder also refuses
trailing bytes); every vertex is within the level's stated error
(`relief:level_error_m`) of the formula, plus the height quantization step
and the resampling tolerance below; the header's min/max bound the
vertices; the bounding sphere holds them; the edge index lists name
exactly the vertices on each edge; the normals are unit vectors facing up.
Between neighbours: coinciding edge vertices have the same height, and
every edge vertex lies on the neighbour's edge polyline. One tile is also
fetched gzipped.
"""

from __future__ import annotations

import gzip
import io
import json
import math
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from quantized_mesh_tile import TerrainTile

from relief.testing import Reliefd

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

# The bump and its DEM.
PEAK_M = 1200.0
SIGMA_DEG = 0.06
PEAK_LON = 10.3
PEAK_LAT = 45.3
PIXEL_DEG = 0.0007
HALF_WIDTH_DEG = 5 * SIGMA_DEG
PIXELS = round(2 * HALF_WIDTH_DEG / PIXEL_DEG)
WEST = PEAK_LON - PIXELS * PIXEL_DEG / 2
NORTH = PEAK_LAT + PIXELS * PIXEL_DEG / 2

#: quantized-mesh's u, v and height range.
QMAX = 32767
#: The highest level checked.
TOP_LEVEL = 10
#: WGS84.
A_M = 6378137.0
E2 = 6.69437999014e-3

MANIFEST = """\
[scene]
name = "bump"
grid = "geodetic"

[[source]]
id = "dem"
kind = "gdal"
path = "bump.tif"

[layers]
height = "dem"
"""


def bump(lon: Any, lat: Any) -> Any:
    dx, dy = np.subtract(lon, PEAK_LON), np.subtract(lat, PEAK_LAT)
    return PEAK_M * np.exp(-(dx * dx + dy * dy) / (2 * SIGMA_DEG * SIGMA_DEG))


def resampling_tolerance_m(level: int) -> float:
    """How far a tile sample of `level` may fairly be from the formula.

    reliefd's samples at level z are the DEM's nodata-aware mip pyramid
    (2 x 2 means of pixels that are the formula at their centres, in
    float32) read bilinearly from the mip level whose pixel w is at most
    the level's sample step s = 180 / 2^z / 256 degrees
    (sources/gdal: mip = floor(log2(step / pixel))). A w x w box mean of
    f is within (w^2 / 8) max(|f_xx| + 2|f_xy| + |f_yy|) of f at the box's
    centre (Taylor, |dx|, |dy| <= w / 2, linear terms cancel by
    symmetry), and bilinear interpolation between points w apart adds at
    most (w^2 / 8) max(|f_xx| + |f_yy|). For the bump |f_xx|, |f_yy| <=
    H / sigma^2 and |f_xy| <= H / (e sigma^2), so the sum is at most
    (w^2 / 4) (2 + 1 / e) H / sigma^2 <= 0.6 s^2 H / sigma^2. Every step
    (means, bilinear weights, edge clamping, 0 m outside) is a convex
    combination of values in [0, H], so no sample is further than H from
    the formula either: the bound is capped there (levels 0 to 4). 1 cm
    covers float32 rounding of the pixels and the bump's 5 mm at the
    DEM's edge."""
    step = 180.0 / 256 / (1 << level)
    return min(0.6 * step * step * PEAK_M / SIGMA_DEG**2, PEAK_M) + 0.01


def write_bump_scene(folder: Path) -> Path:
    from osgeo import gdal, osr

    gdal.UseExceptions()
    lons = WEST + (np.arange(PIXELS) + 0.5) * PIXEL_DEG
    lats = NORTH - (np.arange(PIXELS) + 0.5) * PIXEL_DEG
    grid_lon, grid_lat = np.meshgrid(lons, lats)
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    ds = gdal.GetDriverByName("GTiff").Create(str(folder / "bump.tif"), PIXELS, PIXELS, 1, gdal.GDT_Float32)
    ds.SetGeoTransform((WEST, PIXEL_DEG, 0.0, NORTH, 0.0, -PIXEL_DEG))
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).WriteArray(np.asarray(bump(grid_lon, grid_lat), dtype=np.float32))
    ds.FlushCache()
    del ds
    manifest = folder / "scene.toml"
    manifest.write_text(MANIFEST, encoding="utf-8")
    return manifest


@dataclass
class Tile:
    z: int
    x: int
    y: int  # TMS row, from the south
    raw: bytes
    mesh: Any  # TerrainTile
    bounds: tuple[float, float, float, float]  # west, south, east, north
    u: IntArray
    v: IntArray
    lon: FloatArray
    lat: FloatArray
    height: FloatArray
    step_m: float  # the height quantization step

    def edge(self, side: str) -> IntArray:
        """Indices of the vertices on one edge, sorted along it."""
        if side in ("west", "east"):
            on = np.flatnonzero(self.u == (0 if side == "west" else QMAX))
            return on[np.argsort(self.v[on])]
        on = np.flatnonzero(self.v == (0 if side == "south" else QMAX))
        return on[np.argsort(self.u[on])]


def geodetic_bounds(z: int, x: int, y: int) -> tuple[float, float, float, float]:
    """EPSG:4326 TMS tile bounds: 2 x 1 tiles at level 0."""
    span = 180.0 / 2**z
    return (-180.0 + x * span, -90.0 + y * span, -180.0 + (x + 1) * span, -90.0 + (y + 1) * span)


def ecef(lon: FloatArray, lat: FloatArray, h: FloatArray) -> FloatArray:
    lo, la = np.radians(lon), np.radians(lat)
    n = A_M / np.sqrt(1 - E2 * np.sin(la) ** 2)
    return np.stack(
        [(n + h) * np.cos(la) * np.cos(lo), (n + h) * np.cos(la) * np.sin(lo), (n * (1 - E2) + h) * np.sin(la)], axis=-1
    )


def get(url: str, headers: dict[str, str] | None = None) -> tuple[bytes, Any]:
    request = urllib.request.Request(url, headers=headers or {})
    with urllib.request.urlopen(request, timeout=60) as answer:
        return answer.read(), answer.headers


@pytest.fixture(scope="module")
def terrain(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[dict[str, Any], dict[tuple[int, int, int], Tile], str]]:
    manifest = write_bump_scene(tmp_path_factory.mktemp("bump"))
    with Reliefd(manifest) as daemon:
        base = daemon.viewer_url.rstrip("/") + "/tiles/terrain"
        layer = json.loads(get(base + "/layer.json")[0])
        tiles: dict[tuple[int, int, int], Tile] = {}
        for z in range(min(TOP_LEVEL, layer["maxzoom"]) + 1):
            for r in layer["available"][z]:
                for x in range(r["startX"], r["endX"] + 1):
                    for y in range(r["startY"], r["endY"] + 1):
                        tiles[(z, x, y)] = fetch_tile(base, layer["version"], z, x, y)
        yield layer, tiles, base
        problems = daemon.problems()
    assert not problems, "\n".join(problems)


def fetch_tile(base: str, version: str, z: int, x: int, y: int) -> Tile:
    raw, headers = get(
        f"{base}/{z}/{x}/{y}.terrain?v={version}",
        {"Accept": "application/vnd.quantized-mesh;extensions=octvertexnormals"},
    )
    assert headers.get("Content-Encoding") is None, f"{z}/{x}/{y} came encoded without Accept-Encoding"
    bounds = geodetic_bounds(z, x, y)
    west, south, east, north = bounds
    mesh = TerrainTile(west=west, south=south, east=east, north=north)
    # Raises on a malformed tile, and on bytes left after the extensions.
    mesh.fromBytesIO(io.BytesIO(raw), hasLighting=True)
    u, v = np.asarray(mesh.u, dtype=np.int64), np.asarray(mesh.v, dtype=np.int64)
    h = np.asarray(mesh.h, dtype=np.int64)
    assert u.min() >= 0 and u.max() <= QMAX and v.min() >= 0 and v.max() <= QMAX, f"{z}/{x}/{y}: u or v out of range"
    assert h.min() >= 0 and h.max() <= QMAX, f"{z}/{x}/{y}: a quantized height out of 0..32767"
    lo, hi = mesh.header["minimumHeight"], mesh.header["maximumHeight"]
    coords = np.asarray(mesh.getVerticesCoordinates(), dtype=np.float64)
    return Tile(
        z, x, y, raw, mesh, bounds, u, v, coords[:, 0], coords[:, 1], coords[:, 2], step_m=(hi - lo) / QMAX
    )


def test_layer_json_reaches_level_10_over_the_bump(terrain: Any) -> None:
    layer, tiles, _ = terrain
    assert layer["format"] == "quantized-mesh-1.0" and layer["scheme"] == "tms"
    assert layer["maxzoom"] == TOP_LEVEL
    assert "octvertexnormals" in layer["extensions"]
    errors = layer["relief:level_error_m"]
    assert len(errors) == layer["maxzoom"] + 1
    assert errors[TOP_LEVEL] == layer["relief:terrain_mesh_error_m"]
    assert {z for z, _, _ in tiles} == set(range(TOP_LEVEL + 1))
    # Few tiles: the bump spans 0.6 degrees, level 10's tiles 0.18.
    assert len(tiles) < 80, len(tiles)


def test_every_vertex_is_within_the_stated_error_of_the_formula(terrain: Any) -> None:
    layer, tiles, _ = terrain
    failures = []
    for (z, x, y), t in sorted(tiles.items()):
        west, south, east, north = t.bounds
        assert (t.lon >= west - 1e-9).all() and (t.lon <= east + 1e-9).all(), f"{z}/{x}/{y}"
        assert (t.lat >= south - 1e-9).all() and (t.lat <= north + 1e-9).all(), f"{z}/{x}/{y}"
        allowed = layer["relief:level_error_m"][z] + t.step_m + resampling_tolerance_m(z)
        miss = np.abs(t.height - bump(t.lon, t.lat))
        worst = int(np.argmax(miss))
        if miss[worst] > allowed:
            failures.append(
                f"{z}/{x}/{y}: vertex at ({t.lon[worst]:.5f}, {t.lat[worst]:.5f}) is {t.height[worst]:.3f} m, "
                f"the formula {bump(t.lon[worst], t.lat[worst]):.3f} m: {miss[worst]:.3f} m off, allowed {allowed:.3f}"
            )
    assert not failures, "\n".join(failures)


def test_the_header_bounds_the_vertices(terrain: Any) -> None:
    _, tiles, _ = terrain
    for (z, x, y), t in tiles.items():
        header = t.mesh.header
        lo, hi = header["minimumHeight"], header["maximumHeight"]
        assert lo <= hi, f"{z}/{x}/{y}"
        assert (t.height >= lo - 1e-6).all() and (t.height <= hi + 1e-6).all(), f"{z}/{x}/{y}"
        # The range is the vertices' own: some vertex is at each end.
        assert t.height.min() - lo <= t.step_m + 1e-6 and hi - t.height.max() <= t.step_m + 1e-6, f"{z}/{x}/{y}"
        # The bounding sphere holds every vertex, give or take where
        # quantization moved it: half a quantum of the tile in u, v and h.
        centre = np.array([header[f"boundingSphereCenter{c}"] for c in "XYZ"])
        radius = header["boundingSphereRadius"]
        west, south, east, north = t.bounds
        slack = 0.5 * A_M * math.radians((east - west) + (north - south)) / QMAX + t.step_m + 1e-6 * radius
        distance = np.linalg.norm(ecef(t.lon, t.lat, t.height) - centre, axis=1)
        assert distance.max() <= radius + slack, f"{z}/{x}/{y}: a vertex {distance.max() - radius:.3f} m outside"
        # The tile's centre, in the header, is an ECEF point near the surface.
        assert np.linalg.norm([header[f"center{c}"] for c in "XYZ"]) > A_M * 0.99, f"{z}/{x}/{y}"


def test_edge_lists_and_normals_are_whole(terrain: Any) -> None:
    _, tiles, _ = terrain
    for (z, x, y), t in tiles.items():
        m = t.mesh
        for side, listed in (("west", m.westI), ("south", m.southI), ("east", m.eastI), ("north", m.northI)):
            assert sorted(listed) == sorted(t.edge(side).tolist()), f"{z}/{x}/{y}: the {side} edge list"
        indices = np.asarray(m.indices)
        assert len(indices) % 3 == 0 and indices.max() < len(t.u), f"{z}/{x}/{y}"
        normals = np.asarray(m.vLight, dtype=np.float64)
        assert normals.shape == (len(t.u), 3), f"{z}/{x}/{y}: {normals.shape} normals for {len(t.u)} vertices"
        assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6), f"{z}/{x}/{y}"
        # Slopes here are at most about 20 degrees: every normal faces up
        # (the poles apart: test_normals_at_the_poles_face_up).
        polar = np.abs(t.lat) == 90.0
        facing = (normals * up(t.lon, t.lat)).sum(axis=1)
        assert (facing[~polar] > 0.5).all(), f"{z}/{x}/{y}: a normal faces down or sideways"


def up(lon: FloatArray, lat: FloatArray) -> FloatArray:
    """The ellipsoid's unit normal (geodetic up) in ECEF."""
    lo, la = np.radians(lon), np.radians(lat)
    return np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)


def test_normals_at_the_poles_face_up(terrain: Any) -> None:
    _, tiles, _ = terrain
    failures = []
    for (z, x, y), t in sorted(tiles.items()):
        polar = np.abs(t.lat) == 90.0
        if not polar.any():
            continue
        normals = np.asarray(t.mesh.vLight, dtype=np.float64)[polar]
        facing = (normals * up(t.lon[polar], t.lat[polar])).sum(axis=1)
        if facing.min() <= 0.5:
            failures.append(f"{z}/{x}/{y}: a pole's normal is {normals[np.argmin(facing)].round(4).tolist()}")
    assert not failures, "\n".join(failures)


def on_polyline(along: IntArray, heights: FloatArray, at: IntArray) -> FloatArray:
    """The polyline (along, heights), sorted by `along`, at `at`."""
    return np.interp(at, along, heights)


def test_neighbours_share_their_edges(terrain: Any) -> None:
    layer, tiles, _ = terrain
    failures = []
    checked = 0
    for (z, x, y), t in sorted(tiles.items()):
        for (dx, dy), mine, theirs in (((1, 0), "east", "west"), ((0, 1), "north", "south")):
            other = tiles.get((z, x + dx, y + dy))
            if other is None:
                continue
            checked += 1
            a, b = t.edge(mine), other.edge(theirs)
            # Along the edge: v on east/west edges, u on north/south ones;
            # both tiles quantize the shared edge's span the same way.
            along_a = (t.v if dx else t.u)[a]
            along_b = (other.v if dx else other.u)[b]
            q = max(t.step_m, other.step_m)
            shared, ia, ib = np.intersect1d(along_a, along_b, return_indices=True)
            same = np.abs(t.height[a][ia] - other.height[b][ib])
            if len(shared) and same.max() > q + 1e-6:
                failures.append(f"{z}/{x}/{y} {mine}: a shared vertex differs by {same.max():.3f} m (step {q:.3f})")
            allowed = 2 * layer["relief:level_error_m"][z] + 2 * q
            for (pa, ha), (pb, hb) in (
                ((along_a, t.height[a]), (along_b, other.height[b])),
                ((along_b, other.height[b]), (along_a, t.height[a])),
            ):
                off = np.abs(ha - on_polyline(pb, hb, pa))
                if off.max() > allowed:
                    failures.append(
                        f"{z}/{x}/{y} {mine}: an edge vertex is {off.max():.3f} m off its neighbour's edge "
                        f"(allowed {allowed:.3f})"
                    )
    assert checked > 0
    assert not failures, "\n".join(failures)


def test_a_gzipped_tile_inflates_to_the_same_bytes(terrain: Any) -> None:
    layer, tiles, base = terrain
    (z, x, y), t = max(tiles.items(), key=lambda kv: len(kv[1].raw))
    packed, headers = get(
        f"{base}/{z}/{x}/{y}.terrain?v={layer['version']}",
        {"Accept": "application/vnd.quantized-mesh;extensions=octvertexnormals", "Accept-Encoding": "gzip"},
    )
    assert headers.get("Content-Encoding") == "gzip"
    assert len(packed) < len(t.raw)
    assert gzip.decompress(packed) == t.raw
