"""relief's own types: what the client's calls take and answer.

Plain frozen dataclasses and enums; no protobuf type appears here. Arrays
are numpy arrays (heights float32 with NaN for nodata, images H x W x 4
uint8).
"""

from __future__ import annotations

import enum
import io
import math
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Mapping
from typing import Any, Union

import numpy as np
import numpy.typing as npt

# ---------------------------------------------------------------- common


@dataclass(frozen=True)
class Camera:
    """A geodetic camera: longitude and latitude in degrees, altitude in
    metres (above the ellipsoid, or the grid's zero on a local scene),
    heading clockwise from north, pitch 0 level and -90 straight down."""

    lon_deg: float
    lat_deg: float
    altitude_m: float
    heading_deg: float = 0.0
    pitch_deg: float = -45.0
    roll_deg: float = 0.0
    vertical_fov_deg: float = 50.0


@dataclass(frozen=True)
class Extent:
    """An axis-aligned extent in the scene grid's CRS (degrees on the
    geodetic grid, metres on a projected one)."""

    min_x: float
    min_y: float
    max_x: float
    max_y: float

    @property
    def width(self) -> float:
        return self.max_x - self.min_x

    @property
    def height(self) -> float:
        return self.max_y - self.min_y

    @property
    def centre(self) -> tuple[float, float]:
        return ((self.min_x + self.max_x) / 2.0, (self.min_y + self.max_y) / 2.0)

    def contains(self, x: float, y: float) -> bool:
        return self.min_x <= x <= self.max_x and self.min_y <= y <= self.max_y


@dataclass(frozen=True)
class Quality:
    """Overrides of the manifest's [quality] for one request; None keeps
    the scene's value."""

    resampling: str | None = None
    reprojection_error_px: float | None = None
    clipmap_grid_size: int | None = None
    clipmap_levels: int | None = None
    #: Colour samples per terrain sample along a side (1, 2 or 4).
    color_detail: int | None = None
    #: Not drawn yet: reliefd refuses them (INVALID_ARGUMENT) rather than ignore them.
    precision: str | None = None
    #: Effects' knobs, refused for a scene that does not declare the effect.
    atmosphere_steps: int | None = None
    shadow_cascades: int | None = None
    shadow_map_size: int | None = None
    detail_octaves: int | None = None
    #: The instances layer's distance bands: three outer edges in metres,
    #: the share drawn in each band, and where models give way to billboards.
    instance_bands_m: tuple[float, float, float] | None = None
    instance_band_densities: tuple[float, float, float] | None = None
    instance_model_distance_m: float | None = None
    #: JPEG quality (1 to 100) of frames sent while a view is interactive,
    #: and of frames asked for as JPEG.
    frame_jpeg_quality: int | None = None


class ImageFormat(str, enum.Enum):
    """How a frame's pixels travel: PNG (lossless), JPEG (lossy, at the
    scene's frame_jpeg_quality), raw RGBA8 rows, or, for a stream, LIVE:
    JPEG while its view is interactive, PNG at rest (a frame says which
    it came as)."""

    PNG = "png"
    RGBA8 = "rgba8"
    JPEG = "jpeg"
    LIVE = "live"


# ---------------------------------------------------------------- scene


class SourceStatus(str, enum.Enum):
    UNSPECIFIED = "unspecified"
    #: Loaded and serving the current version.
    READY = "ready"
    #: The last refresh failed: the last good version is served, `error` says why.
    ERROR = "error"
    #: Never loaded successfully: nothing is served for it.
    FAILED = "failed"


class PayloadKind(str, enum.Enum):
    UNSPECIFIED = "unspecified"
    HEIGHT = "height"
    COLOR = "color"
    MASK = "mask"
    FEATURES = "features"
    INSTANCES = "instances"
    MESH = "mesh"


@dataclass(frozen=True)
class SourceState:
    id: str
    kind: str
    output: PayloadKind
    inputs: tuple[str, ...]
    status: SourceStatus
    #: Empty when the source is healthy.
    error: str
    #: The files the source reads (absolute paths).
    files: tuple[str, ...]
    #: Bumped each time a new version of the source is taken in.
    version: int
    #: True when a layer or a declared effect needs this source.
    active: bool
    #: Extent of the data in the scene grid's CRS, when known.
    extent: Extent | None
    crs: str
    vertical_datum: str
    vertical_units: str
    tiles_generated: int
    #: Free-form facts about the data (raster size, band types, nodata...).
    details: Mapping[str, str]
    #: For `scatter`: each land-cover class seen in the tiles built so far.
    instance_classes: tuple[InstanceClass, ...] = ()


@dataclass(frozen=True)
class InstanceClass:
    """A land-cover class a `scatter` source has met."""

    class_code: int
    #: False for a class the data has but the rules do not mention.
    has_rule: bool
    #: Instances placed, and class samples read, in the tiles built so far.
    instances: int
    samples: int


@dataclass(frozen=True)
class EffectState:
    name: str
    sources: tuple[str, ...]
    #: Whether a pass for it ran in the last frame, and its cost.
    ran: bool
    last_cost_ms: float


@dataclass(frozen=True)
class PassState:
    """One pass of the renderer (terrain, buildings, ...): built only when
    the scene calls for it."""

    name: str
    built: bool
    #: Frames it ran in since start, and their milliseconds in total.
    runs: int
    total_ms: float


@dataclass(frozen=True)
class Counters:
    tiles_generated: int
    cache_hits: int
    cache_misses: int
    cache_entries: int
    cache_bytes: int
    cache_budget_bytes: int
    frames_rendered: int
    reads_retried: int
    frame_views: int
    frame_streams: int
    open_views: int
    stream_frames_rendered: int
    #: Frames shown again for a later generation that changed nothing their
    #: view draws, instead of rendered.
    stream_frames_carried_over: int = 0
    #: What each of reliefd's caches holds now, bytes, by name ("tile
    #: cache", "raster blocks", "renderer: terrain", ..., "frames held for
    #: streams").
    memory: dict[str, int] = field(default_factory=dict)
    #: Sources read again because their files changed (an editor's lock
    #: and side files cause none).
    source_reads: int = 0


@dataclass(frozen=True)
class Grid:
    """The scene's tile grid. Row 0 is the northernmost row."""

    #: "geodetic" or "projected".
    kind: str
    crs: str
    #: N: height tiles are (N+1) x (N+1) samples, colour tiles N x N plus a
    #: one-texel border.
    tile_size: int
    extent: Extent
    level0_columns: int
    level0_rows: int

    def tiles_at(self, level: int) -> tuple[int, int]:
        """Columns and rows of tiles at `level`."""
        return (self.level0_columns << level, self.level0_rows << level)

    def tile_at(self, level: int, x: float, y: float) -> tuple[int, int]:
        """The (column, row) of the tile at `level` holding grid point (x, y)
        (longitude and latitude on the geodetic grid)."""
        cols, rows = self.tiles_at(level)
        e = self.extent
        col = math.floor((x - e.min_x) / e.width * cols)
        row = math.floor((e.max_y - y) / e.height * rows)
        return (min(max(col, 0), cols - 1), min(max(row, 0), rows - 1))

    def tile_extent(self, level: int, col: int, row: int) -> Extent:
        """The extent of tile (col, row) at `level`."""
        cols, rows = self.tiles_at(level)
        e = self.extent
        w, h = e.width / cols, e.height / rows
        return Extent(e.min_x + col * w, e.max_y - (row + 1) * h, e.min_x + (col + 1) * w, e.max_y - row * h)


@dataclass(frozen=True)
class Parameter:
    """A value a call set (SetSourceParameter), in force over the manifest's."""

    #: The source id, "[quality]", "[sun]" or "[effects.NAME]".
    target: str
    name: str
    #: In force, as TOML text.
    value: str
    #: The manifest's own value as TOML text; None where it leaves it to its default.
    manifest_value: str | None = None


@dataclass(frozen=True)
class SceneState:
    """The whole scene state at one generation."""

    name: str
    generation: int
    grid: Grid
    sources: tuple[SourceState, ...]
    effects: tuple[EffectState, ...]
    #: Layer name ("height", "color", ...) to source id.
    layers: Mapping[str, str]
    #: The effective [quality] settings.
    quality: Mapping[str, str]
    counters: Counters
    #: Path of the manifest.
    manifest: str
    #: Why the last edit of the manifest was not taken; empty when it was.
    manifest_error: str
    #: The renderer's passes: built or not, runs and time since start.
    passes: tuple[PassState, ...] = ()
    #: The parameters calls have set that are in force; the rest is as the
    #: manifest says.
    parameters: tuple[Parameter, ...] = ()

    def source(self, source_id: str) -> SourceState:
        """The source with this id (KeyError when there is none)."""
        for s in self.sources:
            if s.id == source_id:
                return s
        raise KeyError(f"no source has id {source_id!r} (sources: {', '.join(s.id for s in self.sources)})")


# ---------------------------------------------------------------- events


@dataclass(frozen=True)
class DirtyRegion:
    source_id: str
    extents: tuple[Extent, ...]


@dataclass(frozen=True)
class SnapshotEvent:
    """The first event of a stream: the state as it is."""

    generation: int
    state: SceneState


@dataclass(frozen=True)
class GenerationEvent:
    """A new generation was published."""

    generation: int
    changed_sources: tuple[str, ...]
    dirty: tuple[DirtyRegion, ...]
    #: Cached tiles the change touched, generated again before publishing.
    tiles_rebuilt: int
    #: Cached tiles whose old version was dropped.
    tiles_invalidated: int
    #: Cached tiles the change did not touch, kept.
    tiles_carried_over: int
    #: Derived tiles kept because their input tiles came out the same.
    tiles_cut_off: int
    elapsed_ms: float
    reason: str


@dataclass(frozen=True)
class SourceErrorEvent:
    """A source's file turned bad."""

    generation: int
    source_id: str
    error: str
    #: True when the last good version keeps being served.
    kept_last_good: bool


@dataclass(frozen=True)
class ManifestErrorEvent:
    """An edit of the manifest was not taken: the scene stays as it was."""

    generation: int
    error: str


Event = Union[SnapshotEvent, GenerationEvent, SourceErrorEvent, ManifestErrorEvent]


# ---------------------------------------------------------------- frames


@dataclass(frozen=True)
class PassTiming:
    name: str
    elapsed_ms: float


@dataclass(frozen=True)
class FrameDrawn:
    buildings: int
    #: Instances drawn as models and as billboards (one cross-fading from
    #: one to the other counts in both).
    models: int
    billboards: int
    #: The terrain's clipmap level blocks (16 x 16 cells) with cells to
    #: draw, and those drawn: the rest lay wholly outside the view or, on
    #: the planet, wholly beyond its horizon (those last are counted in
    #: ``terrain_blocks_beyond_horizon``).
    terrain_blocks: int = 0
    terrain_blocks_drawn: int = 0
    #: Shadow cascades drawn for this frame, and kept from the frame before
    #: (the same cascades over the same casters: a still camera draws none).
    shadow_maps_drawn: int = 0
    shadow_maps_kept: int = 0
    #: Blocks inside the view's frustum left out because the planet's
    #: horizon hid them.
    terrain_blocks_beyond_horizon: int = 0
    #: Shadow maps redrawn only over what changed in their casters (an
    #: edit), the regions redrawn, and the map texels drawn in all.
    shadow_maps_redrawn_in_part: int = 0
    shadow_regions: int = 0
    shadow_texels: int = 0
    #: Texels of the water's coverage read, level samples written, and
    #: building mesh and instance tiles brought to the device this frame.
    water_coverage_texels: int = 0
    level_samples_written: int = 0
    building_tiles_built: int = 0
    instance_tiles_built: int = 0


@dataclass(frozen=True)
class SunPosition:
    """The sun a frame was lit by, over its camera: azimuth clockwise from
    north and elevation above the horizon (degrees), and where it came from
    ("at 2026-06-21T15:00:00+02:00" or "fixed: ...")."""

    azimuth_deg: float
    elevation_deg: float
    source: str


#: A frame's sun: a date-time with its UTC offset ("2026-06-21T15:00:00+02:00",
#: placed by NREL's SPA over the camera), or fixed (azimuth_deg, elevation_deg).
Sun = str | tuple[float, float]


@dataclass(frozen=True, eq=False)
class Frame:
    """A rendered view: the image (PNG, JPEG or raw RGBA8), the generation
    it shows, the camera it was rendered from and each pass's cost."""

    generation: int
    width: int
    height: int
    format: ImageFormat
    image: bytes = field(repr=False)
    camera: Camera
    passes: tuple[PassTiming, ...]
    #: Every pass of the renderer as of this frame (as SceneState.passes).
    pass_counters: tuple[PassState, ...] = ()
    #: What the frame drew besides the terrain.
    drawn: FrameDrawn | None = None
    #: The sun it was lit by.
    sun: SunPosition | None = None
    #: An earlier generation's frame shown again: this generation changed
    #: nothing the view draws, so it was not rendered again.
    carried_over: bool = False

    def to_numpy(self) -> npt.NDArray[np.uint8]:
        """The pixels, H x W x 4 uint8 (straight RGBA)."""
        if self.format is ImageFormat.RGBA8:
            return np.frombuffer(self.image, dtype=np.uint8).reshape(self.height, self.width, 4).copy()
        return decode_png(self.image)

    def png(self) -> bytes:
        """The image as PNG bytes (encoded here when it came as RGBA8)."""
        if self.format is ImageFormat.PNG:
            return self.image
        return encode_png(self.to_numpy())

    def save(self, path: str | Path) -> Path:
        """Writes the image as a PNG file and returns its path."""
        out = Path(path)
        out.write_bytes(self.png())
        return out

    @property
    def pass_ms(self) -> dict[str, float]:
        """Milliseconds per pass name."""
        return {p.name: p.elapsed_ms for p in self.passes}


def decode_png(data: bytes) -> npt.NDArray[np.uint8]:
    """A PNG's (or a JPEG's) pixels as H x W x 4 uint8."""
    from PIL import Image

    with Image.open(io.BytesIO(data)) as img:
        rgba = img.convert("RGBA")
        return np.asarray(rgba, dtype=np.uint8).copy()


def encode_png(rgba: npt.NDArray[np.uint8]) -> bytes:
    """H x W x 4 uint8 pixels as a PNG."""
    from PIL import Image

    out = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgba, dtype=np.uint8), mode="RGBA").save(out, format="PNG")
    return out.getvalue()


# ---------------------------------------------------------------- views


@dataclass(frozen=True)
class View:
    """A view of the caller's own (OpenView): its camera moves without
    moving the scene camera, unless it follows the scene camera."""

    view_id: str
    camera: Camera
    follow_scene_camera: bool
    interactive: bool


@dataclass(frozen=True)
class Orbit:
    """Turns the camera about the ground point at the centre of the view."""

    heading_deg: float = 0.0
    pitch_deg: float = 0.0


@dataclass(frozen=True)
class Pan:
    """Drags the ground under (from_x, from_y) to (to_x, to_y), fractions of
    the image from the top left."""

    from_x: float
    from_y: float
    to_x: float
    to_y: float


@dataclass(frozen=True)
class Zoom:
    """Moves towards the point under (x, y), keeping `factor` of the
    distance (0.5 halves it)."""

    factor: float
    x: float = 0.5
    y: float = 0.5


@dataclass(frozen=True)
class Move:
    """Moves along the heading, across it and up, in units of the camera's
    height above the ground; turns the heading clockwise."""

    forward: float = 0.0
    right: float = 0.0
    up: float = 0.0
    turn_deg: float = 0.0


@dataclass(frozen=True)
class FlyTo:
    """Frames a source's extent."""

    source_id: str


Gesture = Union[Orbit, Pan, Zoom, Move, FlyTo]


@dataclass(frozen=True)
class Pick:
    """The point of the scene under a pixel of a view's last frame."""

    #: False where the pixel shows sky.
    hit: bool
    lon_deg: float
    lat_deg: float
    surface_height_m: float
    #: The height layer's data there; None over nodata.
    ground_height_m: float | None
    distance_m: float
    generation: int


# ---------------------------------------------------------------- tiles


@dataclass(frozen=True)
class SkippedFeature:
    """A feature an op left out of a tile, and why."""

    feature_id: int
    reason: str


@dataclass(frozen=True)
class MeshPart:
    """The triangles of one feature: rows first_triangle .. first_triangle +
    triangle_count of MeshTile.indices."""

    feature_id: int
    first_index: int
    index_count: int
    #: The feature's colour, straight RGBA (0-255 each).
    rgba: tuple[int, int, int, int] = (0, 0, 0, 0)
    #: True: heights are relative, the feature's lowest vertex belongs on
    #: the terrain (extruded buildings, MultiPatch with z = "relative");
    #: False: heights as written (MultiPatch, z = "absolute").
    on_ground: bool = False

    @property
    def first_triangle(self) -> int:
        return self.first_index // 3

    @property
    def triangle_count(self) -> int:
        return self.index_count // 3


class InstanceKind(str, enum.Enum):
    UNSPECIFIED = "unspecified"
    MODEL = "model"
    BILLBOARD = "billboard"


@dataclass(frozen=True)
class Instance:
    feature_id: int
    #: Grid CRS x and y, height in metres.
    x: float
    y: float
    z: float
    kind: InstanceKind
    model: str
    scale: float
    #: Clockwise from north about the vertical.
    rotation_deg: float


@dataclass(frozen=True, eq=False)
class TileBase:
    """What every tile answer says besides its payload."""

    source_id: str
    level: int
    x: int
    y: int
    generation: int
    #: xxh3 of the payload bytes, stable across runs.
    content_hash: int
    kind: PayloadKind
    #: The tile's extent in the grid CRS (without the colour border).
    extent: Extent
    crs: str


@dataclass(frozen=True, eq=False)
class HeightTile(TileBase):
    #: Heights in metres, rows from the north-west corner; NaN for nodata.
    heights: npt.NDArray[np.float32] = field(repr=False)


@dataclass(frozen=True, eq=False)
class ColorTile(TileBase):
    #: H x W x 4 uint8, the one-texel border included.
    rgba: npt.NDArray[np.uint8] = field(repr=False)
    png: bytes = field(repr=False)


@dataclass(frozen=True, eq=False)
class MaskTile(TileBase):
    #: One byte per sample, H x W.
    mask: npt.NDArray[np.uint8] = field(repr=False)


@dataclass(frozen=True, eq=False)
class FeatureTile(TileBase):
    #: A GeoJSON FeatureCollection in the grid's CRS; each feature's "id" is
    #: its record number in the source.
    geojson: Mapping[str, Any] = field(repr=False)

    @property
    def features(self) -> list[dict[str, Any]]:
        found = self.geojson.get("features", [])
        return list(found) if isinstance(found, list) else []


@dataclass(frozen=True, eq=False)
class MeshTile(TileBase):
    #: Vertex positions, N x 3 float64: grid x, y, height in metres.
    positions: npt.NDArray[np.float64] = field(repr=False)
    #: Triangles, M x 3 uint32 vertex indices, counter-clockwise from outside.
    indices: npt.NDArray[np.uint32] = field(repr=False)
    parts: tuple[MeshPart, ...]
    skipped: tuple[SkippedFeature, ...]


@dataclass(frozen=True, eq=False)
class InstanceTile(TileBase):
    instances: tuple[Instance, ...]
    skipped: tuple[SkippedFeature, ...]


Tile = Union[HeightTile, ColorTile, MaskTile, FeatureTile, MeshTile, InstanceTile]
