"""Every call of the blocking client against a real reliefd serving the hill
scene, checked against the formula the DEM was written from."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import relief
from relief.testing import PARCELS, HillScene, Reliefd, hill, write_hill_scene

PEAK = (10.25, 45.25)
CAMERA = relief.Camera(lon_deg=10.25, lat_deg=45.12, altitude_m=9000, heading_deg=0, pitch_deg=-45)
SIZE = (160, 120)
# Level 9 tiles of the geodetic grid are about 0.35 degrees: one holds the summit.
LEVEL = 9


def summit_tile(state: relief.SceneState) -> tuple[int, int]:
    return state.grid.tile_at(LEVEL, *PEAK)


# ---------------------------------------------------------------- scene


def test_state_describes_the_scene(shared_client: relief.Client, shared_scene: HillScene) -> None:
    state = shared_client.state()
    assert state.name == "hill"
    assert state.generation >= 1
    assert Path(state.manifest).resolve() == shared_scene.manifest.resolve()
    assert state.manifest_error == ""
    assert dict(state.layers) == {"height": "dem", "color": "map"}
    assert {"resampling", "clipmap_levels"} <= set(state.quality)
    assert [s.id for s in state.sources] == ["dem", "shade", "parcels", "parcels-drawn", "map", "buildings"]
    dem = state.source("dem")
    assert dem.kind == "gdal"
    assert dem.status is relief.SourceStatus.READY and dem.error == ""
    assert dem.output is relief.PayloadKind.HEIGHT
    assert dem.active
    assert dem.files == (str(shared_scene.dem.resolve()),) or dem.files == (str(shared_scene.dem),)
    assert dem.extent is not None
    assert (dem.extent.min_x, dem.extent.min_y, dem.extent.max_x, dem.extent.max_y) == pytest.approx(
        (10.0, 45.0, 10.5, 45.5)
    )
    assert dem.version >= 1
    assert state.source("map").inputs == ("shade", "parcels-drawn")
    assert state.source("map").output is relief.PayloadKind.COLOR
    assert state.source("parcels").output is relief.PayloadKind.FEATURES
    assert state.source("buildings").output is relief.PayloadKind.MESH
    assert state.grid.kind == "geodetic" and state.grid.crs == "EPSG:4326"
    assert state.grid.tile_size > 0
    assert isinstance(state.counters, relief.Counters)
    assert state.counters.cache_budget_bytes > 0
    assert [e.name for e in state.effects] == ["lighting"]
    assert state.effects[0].sources == ("dem",)
    with pytest.raises(KeyError, match="no source has id 'nope'"):
        state.source("nope")
    # Plain frozen dataclasses all the way down.
    assert dataclasses.is_dataclass(state) and dataclasses.is_dataclass(dem)
    with pytest.raises(dataclasses.FrozenInstanceError):
        state.name = "x"  # type: ignore[misc]


def test_grid_helpers_find_the_tile_of_a_point(shared_client: relief.Client) -> None:
    grid = shared_client.state().grid
    col, row = grid.tile_at(LEVEL, *PEAK)
    extent = grid.tile_extent(LEVEL, col, row)
    assert extent.contains(*PEAK)
    cols, rows = grid.tiles_at(LEVEL)
    assert cols == grid.level0_columns * 2**LEVEL and rows == grid.level0_rows * 2**LEVEL


def test_wait_for_a_served_generation_answers_at_once(shared_client: relief.Client) -> None:
    state = shared_client.state()
    again = shared_client.wait_for_generation(state.generation, timeout=5)
    assert again.generation >= state.generation


def test_events_start_with_a_snapshot(shared_client: relief.Client) -> None:
    with shared_client.events(timeout=30) as events:
        first = next(events)
    assert isinstance(first, relief.SnapshotEvent)
    assert first.state.name == "hill"
    assert first.generation == first.state.generation


def test_reload_rereads_sources(shared_client: relief.Client) -> None:
    state = shared_client.reload()
    assert state.name == "hill"
    assert shared_client.reload(["dem"]).source("dem").status is relief.SourceStatus.READY


def test_set_source_parameter_is_checked_as_the_manifest_and_shown_in_the_state(tmp_path: Path) -> None:
    scene = write_hill_scene(tmp_path / "scene", extra_manifest="[effects]\nlighting = {}\n")
    with Reliefd(scene.manifest) as daemon, relief.connect(daemon.address) as client:
        before = client.state()
        state = client.set_source_parameter("[quality]", "resampling", "cubic")
        assert state.generation == before.generation + 1
        assert state.quality["resampling"] == "cubic"
        assert state.parameters == (relief.Parameter("[quality]", "resampling", '"cubic"', None),)
        state = client.set_source_parameter("[sun]", "time", "2026-06-21T15:00:00+02:00")
        assert ("[sun]", "time") in {(p.target, p.name) for p in state.parameters}
        # A time and a fixed sun together are refused, as in the manifest.
        with pytest.raises(relief.InvalidArgument, match="not both"):
            client.set_source_parameter("[sun]", "elevation_deg", 30)
        # Refused as the manifest would refuse them; the scene stays.
        with pytest.raises(relief.InvalidArgument, match="chooses what the source reads"):
            client.set_source_parameter("dem", "path", "other.tif")
        with pytest.raises(relief.InvalidArgument, match="brightness"):
            client.set_source_parameter("dem", "brightness", 1.2)
        with pytest.raises(relief.InvalidArgument, match="resampling"):
            client.set_source_parameter("[quality]", "resampling", "blurry")
        with pytest.raises(relief.NotFound, match="'nope'"):
            client.set_source_parameter("nope", "azimuth_deg", 1)
        assert client.state().generation == state.generation
        state = client.set_source_parameter("[quality]", "resampling", reset=True)
        assert state.quality["resampling"] == "bilinear"
        assert [p.target for p in state.parameters] == ["[sun]"]


# ---------------------------------------------------------------- tiles


def test_height_tiles_hold_the_hill(shared_client: relief.Client) -> None:
    state = shared_client.state()
    col, row = summit_tile(state)
    tile = shared_client.tile("dem", LEVEL, col, row)
    assert isinstance(tile, relief.HeightTile)
    assert (tile.source_id, tile.level, tile.x, tile.y) == ("dem", LEVEL, col, row)
    assert tile.kind is relief.PayloadKind.HEIGHT
    assert tile.crs == "EPSG:4326"
    assert tile.generation >= 1 and tile.content_hash != 0
    n = state.grid.tile_size
    assert tile.heights.dtype == np.float32
    assert tile.heights.shape == (n + 1, n + 1)
    # Sample (i, j) sits on the corner grid of the tile's extent.
    e = tile.extent
    lons = e.min_x + np.arange(n + 1) * (e.width / n)
    lats = e.max_y - np.arange(n + 1) * (e.height / n)
    grid_lon, grid_lat = np.meshgrid(lons, lats)
    margin = 0.01
    inside = (grid_lon > 10.0 + margin) & (grid_lon < 10.5 - margin) & (grid_lat > 45.0 + margin) & (grid_lat < 45.5 - margin)
    outside = (grid_lon < 10.0 - margin) | (grid_lon > 10.5 + margin) | (grid_lat < 45.0 - margin) | (grid_lat > 45.5 + margin)
    assert inside.any() and outside.any()
    expected = hill(grid_lon, grid_lat)
    assert np.nanmax(np.abs(tile.heights[inside] - expected[inside])) < 5.0
    assert np.isnan(tile.heights[outside]).all(), "nodata outside the DEM is NaN"
    # The typed form says what it answers.
    typed: relief.HeightTile = shared_client.tile("dem", LEVEL, col, row, expect=relief.HeightTile)
    assert typed.content_hash == tile.content_hash
    with pytest.raises(relief.ReliefError, match="not a ColorTile"):
        shared_client.tile("dem", LEVEL, col, row, expect=relief.ColorTile)


def test_colour_tiles_decode_to_rgba(shared_client: relief.Client) -> None:
    state = shared_client.state()
    col, row = summit_tile(state)
    tile = shared_client.tile("map", LEVEL, col, row, expect=relief.ColorTile)
    assert tile.kind is relief.PayloadKind.COLOR
    assert tile.rgba.dtype == np.uint8 and tile.rgba.ndim == 3 and tile.rgba.shape[2] == 4
    assert tile.rgba.shape[0] in (state.grid.tile_size, state.grid.tile_size + 2)
    assert tile.png.startswith(b"\x89PNG")
    # The parcels are drawn in red over grey shading.
    red = (tile.rgba[..., 0].astype(int) - tile.rgba[..., 1].astype(int)) > 60
    assert red.any(), "the summit parcel is drawn on the map"


def test_feature_tiles_are_geojson(shared_client: relief.Client) -> None:
    col, row = summit_tile(shared_client.state())
    tile = shared_client.tile("parcels", LEVEL, col, row, expect=relief.FeatureTile)
    assert tile.geojson["type"] == "FeatureCollection"
    names = {f["properties"]["name"] for f in tile.features}
    assert "summit" in names
    summit = next(f for f in tile.features if f["properties"]["name"] == "summit")
    # The shapefile reader gives attributes as text.
    assert float(summit["properties"]["height"]) == pytest.approx(30.0)
    assert summit["geometry"]["type"] in ("Polygon", "MultiPolygon")


def test_mesh_tiles_hold_the_extruded_parcels(shared_client: relief.Client) -> None:
    col, row = summit_tile(shared_client.state())
    tile = shared_client.tile("buildings", LEVEL, col, row, expect=relief.MeshTile)
    assert tile.positions.dtype == np.float64 and tile.positions.ndim == 2 and tile.positions.shape[1] == 3
    assert tile.indices.dtype == np.uint32 and tile.indices.ndim == 2 and tile.indices.shape[1] == 3
    assert len(tile.positions) > 0 and len(tile.indices) > 0
    assert int(tile.indices.max()) < len(tile.positions)
    assert tile.parts and all(isinstance(p, relief.MeshPart) for p in tile.parts)
    assert sum(p.triangle_count for p in tile.parts) <= len(tile.indices)
    # Feature ids are record numbers (0-based, as OGR's FIDs).
    summit = next(i for i, (name, _, _) in enumerate(PARCELS) if name == "summit")
    assert summit in [p.feature_id for p in tile.parts]
    # No colour option: extrude's default, a light warm grey, opaque.
    assert all(p.rgba == (217, 209, 194, 255) for p in tile.parts), [p.rgba for p in tile.parts]
    # The summit parcel's roof: the ground there (about 1900 to 2000 m) plus 30 m.
    roof = tile.positions[:, 2].max()
    assert 1900.0 < roof < 2100.0


def test_elevation_follows_the_formula_and_says_none_off_the_data(
    shared_client: relief.Client, shared_scene: HillScene
) -> None:
    points = [PEAK, (10.1, 45.4), (10.4, 45.1), (30.0, 10.0)]
    heights = shared_client.elevation(points)
    assert len(heights) == 4
    for (lon, lat), h in zip(points[:3], heights[:3]):
        assert h is not None and h == pytest.approx(shared_scene.height(lon, lat), abs=1.0)
    assert heights[3] is None
    assert shared_client.elevation([PEAK], source="dem")[0] == pytest.approx(2000.0, abs=1.0)
    assert shared_client.elevation([]) == []


# ---------------------------------------------------------------- view


def test_render_answers_a_png_frame(shared_client: relief.Client, tmp_path: Path) -> None:
    frame = shared_client.render(CAMERA, size=SIZE)
    assert (frame.width, frame.height) == SIZE
    assert frame.format is relief.ImageFormat.PNG
    assert frame.image.startswith(b"\x89PNG")
    assert frame.generation >= 1
    assert frame.camera == CAMERA
    assert frame.passes and all(p.elapsed_ms >= 0 for p in frame.passes)
    assert "encode png" in frame.pass_ms
    lighting = shared_client.state().effects[0]
    assert lighting.ran and lighting.last_cost_ms > 0
    assert shared_client.state().counters.frames_rendered >= 1
    terrain = next(p for p in frame.pass_counters if p.name == "terrain")
    assert terrain.built and terrain.runs >= 1 and terrain.total_ms > 0
    assert next(p for p in shared_client.state().passes if p.name == "terrain").runs >= terrain.runs
    pixels = frame.to_numpy()
    assert pixels.shape == (SIZE[1], SIZE[0], 4) and pixels.dtype == np.uint8
    assert pixels[..., :3].std() > 1.0, "not a blank image"
    path = frame.save(tmp_path / "view.png")
    with Image.open(path) as img:
        assert img.size == SIZE
        assert np.array_equal(np.asarray(img.convert("RGBA")), pixels)


def test_frames_say_what_they_drew_and_instance_knobs_are_checked(shared_client: relief.Client) -> None:
    bands = relief.Quality(instance_bands_m=(500, 1000, 2000), instance_band_densities=(1, 0.5, 0.25))
    frame = shared_client.render(CAMERA, size=SIZE, quality=bands)
    # The hill scene has no instances layer: nothing placed, no pass built.
    assert frame.drawn is not None and (frame.drawn.models, frame.drawn.billboards) == (0, 0)
    # The terrain's level blocks outside the view were left out.
    assert 0 < frame.drawn.terrain_blocks_drawn < frame.drawn.terrain_blocks
    instances = next(p for p in frame.pass_counters if p.name == "instances")
    assert not instances.built and instances.runs == 0
    assert all(s.instance_classes == () for s in shared_client.state().sources)
    with pytest.raises(relief.InvalidArgument, match="instance_bands_m"):
        shared_client.render(CAMERA, size=SIZE, quality=relief.Quality(instance_bands_m=(700, 600, 3000)))
    with pytest.raises(relief.InvalidArgument, match="atmosphere"):
        shared_client.render(CAMERA, size=SIZE, quality=relief.Quality(atmosphere_steps=8))


def test_a_frame_takes_its_own_sun_and_says_which_lit_it(shared_client: relief.Client) -> None:
    default = shared_client.render(CAMERA, size=SIZE)
    assert default.sun is not None and default.sun.source.startswith("fixed")
    assert (default.sun.azimuth_deg, default.sun.elevation_deg) == (315.0, 45.0)
    study = shared_client.render(CAMERA, size=SIZE, sun="2026-06-21T15:00:00+02:00")
    assert study.sun is not None and study.sun.source == "at 2026-06-21T15:00:00+02:00"
    # Mid-afternoon in northern Italy in June: south-west, high.
    assert 200 < study.sun.azimuth_deg < 280 and 40 < study.sun.elevation_deg < 65
    night = shared_client.render(CAMERA, size=SIZE, sun=(0.0, -30.0), format="rgba8")
    assert night.sun is not None and night.sun.elevation_deg == -30.0
    assert night.to_numpy()[..., :3].mean() < default.to_numpy()[..., :3].mean()
    with pytest.raises(relief.InvalidArgument, match="sun.time"):
        shared_client.render(CAMERA, size=SIZE, sun="21 June, 15:00")


def test_render_answers_raw_rgba_too(shared_client: relief.Client, tmp_path: Path) -> None:
    png = shared_client.render(CAMERA, size=SIZE)
    raw = shared_client.render(CAMERA, size=SIZE, format="rgba8")
    assert raw.format is relief.ImageFormat.RGBA8
    assert len(raw.image) == SIZE[0] * SIZE[1] * 4
    diff = np.abs(raw.to_numpy().astype(int) - png.to_numpy().astype(int))
    assert diff.max() <= 2, "the same view, whichever way it travels"
    assert raw.png().startswith(b"\x89PNG")
    with Image.open(raw.save(tmp_path / "raw.png")) as img:
        assert img.size == SIZE


def test_frames_travel_as_jpeg_at_a_quality_knob(shared_client: relief.Client) -> None:
    png = shared_client.render(CAMERA, size=SIZE)
    jpeg = shared_client.render(CAMERA, size=SIZE, format="jpeg")
    assert jpeg.format is relief.ImageFormat.JPEG and jpeg.image.startswith(b"\xff\xd8\xff")
    assert "encode jpeg" in jpeg.pass_ms
    rough = shared_client.render(CAMERA, size=SIZE, format="jpeg", quality=relief.Quality(frame_jpeg_quality=20))
    assert len(rough.image) < len(jpeg.image) < len(png.image)
    diff = np.abs(jpeg.to_numpy().astype(int) - png.to_numpy().astype(int))[..., :3]
    assert diff.mean() < 4.0, "JPEG at the default quality is within a few levels of the lossless frame"
    with pytest.raises(relief.InvalidArgument, match="frame_jpeg_quality"):
        shared_client.render(CAMERA, size=SIZE, quality=relief.Quality(frame_jpeg_quality=0))
    # A stream at rest sends lossless frames however it asked (live).
    with shared_client.frames(CAMERA, size=SIZE, format="live", max_fps=5, timeout=120) as frames:
        first = next(frames)
    assert first.format is relief.ImageFormat.PNG and not first.carried_over
    state = shared_client.state()
    assert state.counters.memory["tile cache"] > 0
    assert any(name.startswith("renderer: ") for name in state.counters.memory)


def test_frames_stream_the_current_view(shared_client: relief.Client) -> None:
    with shared_client.frames(CAMERA, size=SIZE, max_fps=5, timeout=120) as frames:
        first = next(frames)
    assert isinstance(first, relief.Frame)
    assert (first.width, first.height) == SIZE
    assert first.camera == CAMERA
    assert first.to_numpy().shape == (SIZE[1], SIZE[0], 4)


def test_views_navigate_and_pick(shared_client: relief.Client) -> None:
    view = shared_client.open_view(CAMERA)
    assert view.view_id and view.camera == CAMERA and not view.follow_scene_camera
    updated = shared_client.update_view(view.view_id, interactive=True)
    assert updated.interactive
    updated = shared_client.update_view(view.view_id, interactive=False)
    assert not updated.interactive
    with shared_client.frames(size=SIZE, view_id=view.view_id, timeout=120) as frames:
        first = next(frames)
    assert first.camera == CAMERA
    picked = shared_client.pick(view.view_id, 0.5, 0.5)
    assert picked.hit
    assert 10.0 < picked.lon_deg < 10.5 and 45.0 < picked.lat_deg < 45.5
    assert picked.ground_height_m is not None
    assert picked.ground_height_m == pytest.approx(hill(picked.lon_deg, picked.lat_deg), abs=5.0)
    assert picked.distance_m > 0
    sky = shared_client.pick(view.view_id, 0.5, 0.0)
    assert isinstance(sky.hit, bool)
    moved = shared_client.navigate(relief.Orbit(heading_deg=30.0), view_id=view.view_id)
    assert math.isclose((moved.heading_deg - CAMERA.heading_deg) % 360.0, 30.0, abs_tol=1.0)
    closer = shared_client.navigate(relief.Zoom(factor=0.5), view_id=view.view_id)
    assert closer.altitude_m < moved.altitude_m
    shared_client.navigate(relief.Move(forward=0.1, turn_deg=5.0), view_id=view.view_id)
    shared_client.navigate(relief.Pan(0.5, 0.5, 0.45, 0.5), view_id=view.view_id)


def test_the_scene_camera_can_be_set_and_flown(relief_client: relief.Client) -> None:
    start = relief_client.camera()
    assert start.lon_deg == pytest.approx(10.25) and start.altitude_m == pytest.approx(9000.0)
    assert start.pitch_deg == pytest.approx(-45.0)
    wanted = relief.Camera(10.3, 45.2, 5000.0, heading_deg=90.0, pitch_deg=-20.0)
    assert relief_client.set_camera(wanted) == wanted
    assert relief_client.camera() == wanted
    frame = relief_client.render(size=SIZE)
    assert frame.camera == wanted
    flown = relief_client.navigate(relief.FlyTo("dem"))
    assert 10.0 <= flown.lon_deg <= 10.5
    assert relief_client.camera() == flown
