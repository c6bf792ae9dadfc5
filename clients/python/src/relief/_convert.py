"""The one place relief.v1 messages become relief's types and back. Nothing
outside this module and the two clients touches protobuf."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

from relief._proto.relief.v1 import relief_pb2 as pb
from relief.errors import ReliefError
from relief.types import (
    Camera,
    ColorTile,
    Counters,
    DirtyRegion,
    EffectState,
    Event,
    Extent,
    FeatureTile,
    FlyTo,
    Frame,
    FrameDrawn,
    GenerationEvent,
    Gesture,
    Grid,
    HeightTile,
    ImageFormat,
    Instance,
    InstanceClass,
    InstanceKind,
    InstanceTile,
    ManifestErrorEvent,
    MaskTile,
    MeshPart,
    Parameter,
    MeshTile,
    Move,
    Orbit,
    Pan,
    PassState,
    PassTiming,
    PayloadKind,
    Pick,
    Quality,
    SceneState,
    SkippedFeature,
    SnapshotEvent,
    SourceErrorEvent,
    SourceState,
    SourceStatus,
    Sun,
    SunPosition,
    Tile,
    View,
    Zoom,
    decode_png,
)

_T = TypeVar("_T", bound=np.generic)

_STATUS = {
    pb.SOURCE_STATUS_READY: SourceStatus.READY,
    pb.SOURCE_STATUS_ERROR: SourceStatus.ERROR,
    pb.SOURCE_STATUS_FAILED: SourceStatus.FAILED,
}

_PAYLOAD = {
    pb.PAYLOAD_KIND_HEIGHT: PayloadKind.HEIGHT,
    pb.PAYLOAD_KIND_COLOR: PayloadKind.COLOR,
    pb.PAYLOAD_KIND_MASK: PayloadKind.MASK,
    pb.PAYLOAD_KIND_FEATURES: PayloadKind.FEATURES,
    pb.PAYLOAD_KIND_INSTANCES: PayloadKind.INSTANCES,
    pb.PAYLOAD_KIND_MESH: PayloadKind.MESH,
}

_INSTANCE = {
    pb.INSTANCE_KIND_MODEL: InstanceKind.MODEL,
    pb.INSTANCE_KIND_BILLBOARD: InstanceKind.BILLBOARD,
}

_FORMAT_TO_PB: dict[ImageFormat, pb.ImageFormat] = {
    ImageFormat.PNG: pb.IMAGE_FORMAT_PNG,
    ImageFormat.RGBA8: pb.IMAGE_FORMAT_RGBA8,
    ImageFormat.JPEG: pb.IMAGE_FORMAT_JPEG,
    ImageFormat.LIVE: pb.IMAGE_FORMAT_UNSPECIFIED,
}

_FORMAT_FROM_PB = {
    pb.IMAGE_FORMAT_RGBA8: ImageFormat.RGBA8,
    pb.IMAGE_FORMAT_JPEG: ImageFormat.JPEG,
}

# ---------------------------------------------------------------- to relief.v1


def camera_to_pb(c: Camera) -> pb.Camera:
    return pb.Camera(
        lon_deg=c.lon_deg,
        lat_deg=c.lat_deg,
        altitude_m=c.altitude_m,
        heading_deg=c.heading_deg,
        pitch_deg=c.pitch_deg,
        roll_deg=c.roll_deg,
        vertical_fov_deg=c.vertical_fov_deg,
    )


def quality_to_pb(q: Quality | None) -> pb.QualityOverrides | None:
    if q is None:
        return None
    out = pb.QualityOverrides()
    if q.resampling is not None:
        out.resampling = q.resampling
    if q.reprojection_error_px is not None:
        out.reprojection_error_px = q.reprojection_error_px
    if q.clipmap_grid_size is not None:
        out.clipmap_grid_size = q.clipmap_grid_size
    if q.clipmap_levels is not None:
        out.clipmap_levels = q.clipmap_levels
    if q.precision is not None:
        out.precision = q.precision
    for knob in (
        "color_detail",
        "atmosphere_steps",
        "shadow_cascades",
        "shadow_map_size",
        "detail_octaves",
        "frame_jpeg_quality",
    ):
        if getattr(q, knob) is not None:
            setattr(out, knob, getattr(q, knob))
    if q.instance_bands_m is not None:
        out.instance_bands_m.extend(q.instance_bands_m)
    if q.instance_band_densities is not None:
        out.instance_band_densities.extend(q.instance_band_densities)
    if q.instance_model_distance_m is not None:
        out.instance_model_distance_m = q.instance_model_distance_m
    return out


def image_format(f: ImageFormat | str) -> pb.ImageFormat:
    try:
        return _FORMAT_TO_PB[ImageFormat(f)]
    except ValueError:
        raise ValueError(f"format {f!r} is not one of {', '.join(x.value for x in ImageFormat)}") from None


def _size(size: tuple[int, int]) -> tuple[int, int]:
    width, height = size
    return int(width), int(height)


def sun_to_pb(sun: Sun | None) -> pb.Sun | None:
    if sun is None:
        return None
    if isinstance(sun, str):
        return pb.Sun(time=sun)
    azimuth_deg, elevation_deg = sun
    return pb.Sun(azimuth_deg=float(azimuth_deg), elevation_deg=float(elevation_deg))


def render_request(
    camera: Camera | None,
    size: tuple[int, int],
    fmt: ImageFormat | str,
    quality: Quality | None,
    sun: Sun | None = None,
) -> pb.RenderRequest:
    width, height = _size(size)
    r = pb.RenderRequest(width=width, height=height, format=image_format(fmt))
    if camera is not None:
        r.camera.CopyFrom(camera_to_pb(camera))
    q = quality_to_pb(quality)
    if q is not None:
        r.quality.CopyFrom(q)
    s = sun_to_pb(sun)
    if s is not None:
        r.sun.CopyFrom(s)
    return r


def stream_request(
    camera: Camera | None,
    size: tuple[int, int],
    fmt: ImageFormat | str,
    quality: Quality | None,
    max_fps: float,
    view_id: str | None,
    sun: Sun | None = None,
) -> pb.StreamFramesRequest:
    width, height = _size(size)
    r = pb.StreamFramesRequest(
        width=width,
        height=height,
        format=image_format(fmt),
        max_fps=max_fps,
        view_id=view_id or "",
    )
    if camera is not None:
        r.camera.CopyFrom(camera_to_pb(camera))
    q = quality_to_pb(quality)
    if q is not None:
        r.quality.CopyFrom(q)
    s = sun_to_pb(sun)
    if s is not None:
        r.sun.CopyFrom(s)
    return r


def navigate_request(gesture: Gesture, view_id: str | None) -> pb.NavigateRequest:
    r = pb.NavigateRequest(view_id=view_id or "")
    if isinstance(gesture, Orbit):
        r.orbit.CopyFrom(pb.Orbit(heading_deg=gesture.heading_deg, pitch_deg=gesture.pitch_deg))
    elif isinstance(gesture, Pan):
        r.pan.CopyFrom(pb.Pan(from_x=gesture.from_x, from_y=gesture.from_y, to_x=gesture.to_x, to_y=gesture.to_y))
    elif isinstance(gesture, Zoom):
        r.zoom.CopyFrom(pb.Zoom(factor=gesture.factor, x=gesture.x, y=gesture.y))
    elif isinstance(gesture, Move):
        r.move.CopyFrom(
            pb.Move(forward=gesture.forward, right=gesture.right, up=gesture.up, turn_deg=gesture.turn_deg)
        )
    elif isinstance(gesture, FlyTo):
        r.fly_to_source = gesture.source_id
    else:
        raise TypeError(f"{gesture!r} is not a gesture (Orbit, Pan, Zoom, Move or FlyTo)")
    return r


def update_view_request(
    view_id: str, camera: Camera | None, follow_scene_camera: bool | None, interactive: bool | None
) -> pb.UpdateViewRequest:
    r = pb.UpdateViewRequest(view_id=view_id)
    if camera is not None:
        r.camera.CopyFrom(camera_to_pb(camera))
    if follow_scene_camera is not None:
        r.follow_scene_camera = follow_scene_camera
    if interactive is not None:
        r.interactive = interactive
    return r


def open_view_request(camera: Camera | None, follow_scene_camera: bool) -> pb.OpenViewRequest:
    r = pb.OpenViewRequest(follow_scene_camera=follow_scene_camera)
    if camera is not None:
        r.camera.CopyFrom(camera_to_pb(camera))
    return r


def elevation_request(points: Iterable[Sequence[float]], source: str | None) -> pb.SampleElevationRequest:
    r = pb.SampleElevationRequest(source_id=source or "")
    for p in points:
        if len(p) != 2:
            raise ValueError(f"a point is (lon_deg, lat_deg), not {tuple(p)!r}")
        r.points.add(lon_deg=float(p[0]), lat_deg=float(p[1]))
    return r


def tile_request(source: str, level: int, x: int, y: int, quality: Quality | None) -> pb.GetTileRequest:
    r = pb.GetTileRequest(source_id=source, key=pb.TileKey(level=level, x=x, y=y))
    q = quality_to_pb(quality)
    if q is not None:
        r.quality.CopyFrom(q)
    return r


# ---------------------------------------------------------------- from relief.v1


def extent(e: pb.Extent) -> Extent:
    return Extent(e.min_x, e.min_y, e.max_x, e.max_y)


def camera(c: pb.Camera) -> Camera:
    return Camera(
        lon_deg=c.lon_deg,
        lat_deg=c.lat_deg,
        altitude_m=c.altitude_m,
        heading_deg=c.heading_deg,
        pitch_deg=c.pitch_deg,
        roll_deg=c.roll_deg,
        vertical_fov_deg=c.vertical_fov_deg,
    )


def source_state(s: pb.SourceState) -> SourceState:
    return SourceState(
        id=s.id,
        kind=s.kind,
        output=_PAYLOAD.get(s.output, PayloadKind.UNSPECIFIED),
        inputs=tuple(s.inputs),
        status=_STATUS.get(s.status, SourceStatus.UNSPECIFIED),
        error=s.error,
        files=tuple(s.files),
        version=s.version,
        active=s.active,
        extent=extent(s.extent) if s.HasField("extent") else None,
        crs=s.crs,
        vertical_datum=s.vertical_datum,
        vertical_units=s.vertical_units,
        tiles_generated=s.tiles_generated,
        details=dict(sorted(s.details.items())),
        instance_classes=tuple(
            InstanceClass(class_code=getattr(c, "class"), has_rule=c.has_rule, instances=c.instances, samples=c.samples)
            for c in s.instance_classes
        ),
    )


def scene_state(s: pb.SceneState) -> SceneState:
    g, c = s.grid, s.counters
    return SceneState(
        name=s.name,
        generation=s.generation,
        grid=Grid(
            kind=g.kind,
            crs=g.crs,
            tile_size=g.tile_size,
            extent=extent(g.extent),
            level0_columns=g.level0_columns,
            level0_rows=g.level0_rows,
        ),
        sources=tuple(source_state(x) for x in s.sources),
        effects=tuple(
            EffectState(name=e.name, sources=tuple(e.sources), ran=e.ran, last_cost_ms=e.last_cost_ms)
            for e in s.effects
        ),
        layers=dict(sorted(s.layers.items())),
        quality=dict(sorted(s.quality.items())),
        counters=Counters(
            tiles_generated=c.tiles_generated,
            cache_hits=c.cache_hits,
            cache_misses=c.cache_misses,
            cache_entries=c.cache_entries,
            cache_bytes=c.cache_bytes,
            cache_budget_bytes=c.cache_budget_bytes,
            frames_rendered=c.frames_rendered,
            reads_retried=c.reads_retried,
            frame_views=c.frame_views,
            frame_streams=c.frame_streams,
            open_views=c.open_views,
            stream_frames_rendered=c.stream_frames_rendered,
            stream_frames_carried_over=c.stream_frames_carried_over,
            memory={m.name: m.bytes for m in c.memory},
            source_reads=c.source_reads,
        ),
        manifest=s.manifest,
        manifest_error=s.manifest_error,
        parameters=tuple(
            Parameter(
                target=p.target,
                name=p.name,
                value=p.value,
                manifest_value=p.manifest_value if p.HasField("manifest_value") else None,
            )
            for p in s.parameters
        ),
        passes=pass_states(s.passes),
    )


def event(e: pb.SceneEvent) -> Event | None:
    """A relief.v1 SceneEvent; None for an event kind this client does not
    know (a newer daemon), which the streams skip."""
    which = e.WhichOneof("event")
    if which == "snapshot":
        return SnapshotEvent(generation=e.generation, state=scene_state(e.snapshot))
    if which == "generation_changed":
        g = e.generation_changed
        return GenerationEvent(
            generation=e.generation,
            changed_sources=tuple(g.changed_sources),
            dirty=tuple(
                DirtyRegion(source_id=d.source_id, extents=tuple(extent(x) for x in d.extents)) for d in g.dirty
            ),
            tiles_rebuilt=g.tiles_rebuilt,
            tiles_invalidated=g.tiles_invalidated,
            tiles_carried_over=g.tiles_carried_over,
            tiles_cut_off=g.tiles_cut_off,
            elapsed_ms=g.elapsed_ms,
            reason=g.reason,
        )
    if which == "source_error":
        s = e.source_error
        return SourceErrorEvent(
            generation=e.generation, source_id=s.source_id, error=s.error, kept_last_good=s.kept_last_good
        )
    if which == "manifest_error":
        return ManifestErrorEvent(generation=e.generation, error=e.manifest_error.error)
    return None


def frame(r: pb.RenderResponse) -> Frame:
    fmt = _FORMAT_FROM_PB.get(r.format, ImageFormat.PNG)
    return Frame(
        generation=r.generation,
        width=r.width,
        height=r.height,
        format=fmt,
        image=bytes(r.image),
        camera=camera(r.camera),
        # `pass` is a Python keyword: the field is only reachable by name.
        passes=tuple(PassTiming(name=str(getattr(p, "pass")), elapsed_ms=p.elapsed_ms) for p in r.passes),
        pass_counters=pass_states(r.pass_counters),
        drawn=FrameDrawn(
            buildings=r.drawn.buildings,
            models=r.drawn.models,
            billboards=r.drawn.billboards,
            terrain_blocks=r.drawn.terrain_blocks,
            terrain_blocks_drawn=r.drawn.terrain_blocks_drawn,
            terrain_blocks_beyond_horizon=r.drawn.terrain_blocks_beyond_horizon,
            shadow_maps_drawn=r.drawn.shadow_maps_drawn,
            shadow_maps_kept=r.drawn.shadow_maps_kept,
            shadow_maps_redrawn_in_part=r.drawn.shadow_maps_redrawn_in_part,
            shadow_regions=r.drawn.shadow_regions,
            shadow_texels=r.drawn.shadow_texels,
            water_coverage_texels=r.drawn.water_coverage_texels,
            level_samples_written=r.drawn.level_samples_written,
            building_tiles_built=r.drawn.building_tiles_built,
            instance_tiles_built=r.drawn.instance_tiles_built,
        )
        if r.HasField("drawn")
        else None,
        sun=SunPosition(azimuth_deg=r.sun.azimuth_deg, elevation_deg=r.sun.elevation_deg, source=r.sun.source)
        if r.HasField("sun")
        else None,
        carried_over=r.carried_over,
    )


def pass_states(passes: Iterable[pb.PassState]) -> tuple[PassState, ...]:
    return tuple(PassState(name=p.name, built=p.built, runs=p.runs, total_ms=p.total_ms) for p in passes)


def view(v: pb.ViewState) -> View:
    return View(
        view_id=v.view_id,
        camera=camera(v.camera),
        follow_scene_camera=v.follow_scene_camera,
        interactive=v.interactive,
    )


def pick(p: pb.PickResponse) -> Pick:
    return Pick(
        hit=p.hit,
        lon_deg=p.lon_deg,
        lat_deg=p.lat_deg,
        surface_height_m=p.surface_height_m,
        ground_height_m=p.ground_height_m if p.HasField("ground_height_m") else None,
        distance_m=p.distance_m,
        generation=p.generation,
    )


def elevations(r: pb.SampleElevationResponse) -> list[float | None]:
    return [s.height_m if s.HasField("height_m") else None for s in r.samples]


def _skipped(items: Iterable[pb.SkippedFeature]) -> tuple[SkippedFeature, ...]:
    return tuple(SkippedFeature(feature_id=s.feature_id, reason=s.reason) for s in items)


def tile(r: pb.GetTileResponse) -> Tile:
    common: dict[str, Any] = {
        "source_id": r.source_id,
        "level": r.key.level,
        "x": r.key.x,
        "y": r.key.y,
        "generation": r.generation,
        "content_hash": r.content_hash,
        "kind": _PAYLOAD.get(r.kind, PayloadKind.UNSPECIFIED),
        "extent": extent(r.extent),
        "crs": r.crs,
    }
    which = r.WhichOneof("payload")
    if which == "heights_f32_le":
        data = np.frombuffer(r.heights_f32_le, dtype="<f4").astype(np.float32)
        return HeightTile(**common, heights=_square(data, r.width, r.height, "heights"))
    if which == "color_png":
        png = bytes(r.color_png)
        return ColorTile(**common, rgba=decode_png(png), png=png)
    if which == "mask_u8":
        data8 = np.frombuffer(r.mask_u8, dtype=np.uint8).copy()
        return MaskTile(**common, mask=_square(data8, r.width, r.height, "mask"))
    if which == "features_geojson":
        parsed = json.loads(bytes(r.features_geojson).decode("utf-8")) if r.features_geojson else {}
        if not isinstance(parsed, dict):
            raise ReliefError("a features tile is not a GeoJSON object", method="GetTile", code="DATA_LOSS")
        return FeatureTile(**common, geojson=parsed)
    if which == "mesh":
        m = r.mesh
        positions = np.frombuffer(m.positions_f64_le, dtype="<f8").astype(np.float64).reshape(-1, 3)
        indices = np.frombuffer(m.indices_u32_le, dtype="<u4").astype(np.uint32).reshape(-1, 3)
        parts = tuple(
            MeshPart(
                feature_id=p.feature_id,
                first_index=p.first_index,
                index_count=p.index_count,
                rgba=(p.rgba >> 24 & 0xFF, p.rgba >> 16 & 0xFF, p.rgba >> 8 & 0xFF, p.rgba & 0xFF),
                on_ground=p.on_ground,
            )
            for p in m.parts
        )
        return MeshTile(**common, positions=positions, indices=indices, parts=parts, skipped=_skipped(m.skipped))
    if which == "instances":
        instances = tuple(
            Instance(
                feature_id=i.feature_id,
                x=i.x,
                y=i.y,
                z=i.z,
                kind=_INSTANCE.get(i.kind, InstanceKind.UNSPECIFIED),
                model=i.model,
                scale=i.scale,
                rotation_deg=i.rotation_deg,
            )
            for i in r.instances.instances
        )
        return InstanceTile(**common, instances=instances, skipped=_skipped(r.instances.skipped))
    raise ReliefError(
        f"tile {r.key.level}/{r.key.x}/{r.key.y} of source '{r.source_id}' has no payload this client knows",
        method="GetTile",
        code="DATA_LOSS",
    )


def _square(data: npt.NDArray[_T], width: int, height: int, what: str) -> npt.NDArray[_T]:
    if width * height != data.size:
        side = math.isqrt(data.size)
        if side * side != data.size:
            raise ReliefError(
                f"a {what} tile says {width} x {height} but holds {data.size} samples", method="GetTile", code="DATA_LOSS"
            )
        width = height = side
    return data.reshape(height, width)


def parameter_request(source_id: str, name: str, value: object, reset: bool) -> pb.SetSourceParameterRequest:
    """The SetSourceParameter request for a value (or a reset)."""
    if reset:
        return pb.SetSourceParameterRequest(source_id=source_id, name=name, reset=True)
    if value is None:
        raise ValueError("set_source_parameter needs a value (or reset=True)")
    return pb.SetSourceParameterRequest(source_id=source_id, name=name, value=toml_value(value))


def toml_value(value: object) -> str:
    """A Python value as the TOML text SetSourceParameter reads (a string
    that is not TOML is sent as it is, and read as a string)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return value
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_item(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml_item(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot send {type(value).__name__} as a parameter value")


def _toml_item(value: object) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return toml_value(value)
