from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class SourceStatus(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    SOURCE_STATUS_UNSPECIFIED: _ClassVar[SourceStatus]
    SOURCE_STATUS_READY: _ClassVar[SourceStatus]
    SOURCE_STATUS_ERROR: _ClassVar[SourceStatus]
    SOURCE_STATUS_FAILED: _ClassVar[SourceStatus]

class PayloadKind(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    PAYLOAD_KIND_UNSPECIFIED: _ClassVar[PayloadKind]
    PAYLOAD_KIND_HEIGHT: _ClassVar[PayloadKind]
    PAYLOAD_KIND_COLOR: _ClassVar[PayloadKind]
    PAYLOAD_KIND_MASK: _ClassVar[PayloadKind]
    PAYLOAD_KIND_FEATURES: _ClassVar[PayloadKind]
    PAYLOAD_KIND_INSTANCES: _ClassVar[PayloadKind]
    PAYLOAD_KIND_MESH: _ClassVar[PayloadKind]

class ImageFormat(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    IMAGE_FORMAT_UNSPECIFIED: _ClassVar[ImageFormat]
    IMAGE_FORMAT_PNG: _ClassVar[ImageFormat]
    IMAGE_FORMAT_RGBA8: _ClassVar[ImageFormat]
    IMAGE_FORMAT_JPEG: _ClassVar[ImageFormat]

class InstanceKind(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    INSTANCE_KIND_UNSPECIFIED: _ClassVar[InstanceKind]
    INSTANCE_KIND_MODEL: _ClassVar[InstanceKind]
    INSTANCE_KIND_BILLBOARD: _ClassVar[InstanceKind]
SOURCE_STATUS_UNSPECIFIED: SourceStatus
SOURCE_STATUS_READY: SourceStatus
SOURCE_STATUS_ERROR: SourceStatus
SOURCE_STATUS_FAILED: SourceStatus
PAYLOAD_KIND_UNSPECIFIED: PayloadKind
PAYLOAD_KIND_HEIGHT: PayloadKind
PAYLOAD_KIND_COLOR: PayloadKind
PAYLOAD_KIND_MASK: PayloadKind
PAYLOAD_KIND_FEATURES: PayloadKind
PAYLOAD_KIND_INSTANCES: PayloadKind
PAYLOAD_KIND_MESH: PayloadKind
IMAGE_FORMAT_UNSPECIFIED: ImageFormat
IMAGE_FORMAT_PNG: ImageFormat
IMAGE_FORMAT_RGBA8: ImageFormat
IMAGE_FORMAT_JPEG: ImageFormat
INSTANCE_KIND_UNSPECIFIED: InstanceKind
INSTANCE_KIND_MODEL: InstanceKind
INSTANCE_KIND_BILLBOARD: InstanceKind

class TileKey(_message.Message):
    __slots__ = ("level", "x", "y")
    LEVEL_FIELD_NUMBER: _ClassVar[int]
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    level: int
    x: int
    y: int
    def __init__(self, level: _Optional[int] = ..., x: _Optional[int] = ..., y: _Optional[int] = ...) -> None: ...

class Extent(_message.Message):
    __slots__ = ("min_x", "min_y", "max_x", "max_y")
    MIN_X_FIELD_NUMBER: _ClassVar[int]
    MIN_Y_FIELD_NUMBER: _ClassVar[int]
    MAX_X_FIELD_NUMBER: _ClassVar[int]
    MAX_Y_FIELD_NUMBER: _ClassVar[int]
    min_x: float
    min_y: float
    max_x: float
    max_y: float
    def __init__(self, min_x: _Optional[float] = ..., min_y: _Optional[float] = ..., max_x: _Optional[float] = ..., max_y: _Optional[float] = ...) -> None: ...

class GeodeticPoint(_message.Message):
    __slots__ = ("lon_deg", "lat_deg")
    LON_DEG_FIELD_NUMBER: _ClassVar[int]
    LAT_DEG_FIELD_NUMBER: _ClassVar[int]
    lon_deg: float
    lat_deg: float
    def __init__(self, lon_deg: _Optional[float] = ..., lat_deg: _Optional[float] = ...) -> None: ...

class QualityOverrides(_message.Message):
    __slots__ = ("resampling", "reprojection_error_px", "clipmap_grid_size", "clipmap_levels", "precision", "atmosphere_steps", "instance_bands_m", "instance_band_densities", "instance_model_distance_m", "shadow_cascades", "shadow_map_size", "detail_octaves", "color_detail", "frame_jpeg_quality")
    RESAMPLING_FIELD_NUMBER: _ClassVar[int]
    REPROJECTION_ERROR_PX_FIELD_NUMBER: _ClassVar[int]
    CLIPMAP_GRID_SIZE_FIELD_NUMBER: _ClassVar[int]
    CLIPMAP_LEVELS_FIELD_NUMBER: _ClassVar[int]
    PRECISION_FIELD_NUMBER: _ClassVar[int]
    ATMOSPHERE_STEPS_FIELD_NUMBER: _ClassVar[int]
    INSTANCE_BANDS_M_FIELD_NUMBER: _ClassVar[int]
    INSTANCE_BAND_DENSITIES_FIELD_NUMBER: _ClassVar[int]
    INSTANCE_MODEL_DISTANCE_M_FIELD_NUMBER: _ClassVar[int]
    SHADOW_CASCADES_FIELD_NUMBER: _ClassVar[int]
    SHADOW_MAP_SIZE_FIELD_NUMBER: _ClassVar[int]
    DETAIL_OCTAVES_FIELD_NUMBER: _ClassVar[int]
    COLOR_DETAIL_FIELD_NUMBER: _ClassVar[int]
    FRAME_JPEG_QUALITY_FIELD_NUMBER: _ClassVar[int]
    resampling: str
    reprojection_error_px: float
    clipmap_grid_size: int
    clipmap_levels: int
    precision: str
    atmosphere_steps: int
    instance_bands_m: _containers.RepeatedScalarFieldContainer[float]
    instance_band_densities: _containers.RepeatedScalarFieldContainer[float]
    instance_model_distance_m: float
    shadow_cascades: int
    shadow_map_size: int
    detail_octaves: int
    color_detail: int
    frame_jpeg_quality: int
    def __init__(self, resampling: _Optional[str] = ..., reprojection_error_px: _Optional[float] = ..., clipmap_grid_size: _Optional[int] = ..., clipmap_levels: _Optional[int] = ..., precision: _Optional[str] = ..., atmosphere_steps: _Optional[int] = ..., instance_bands_m: _Optional[_Iterable[float]] = ..., instance_band_densities: _Optional[_Iterable[float]] = ..., instance_model_distance_m: _Optional[float] = ..., shadow_cascades: _Optional[int] = ..., shadow_map_size: _Optional[int] = ..., detail_octaves: _Optional[int] = ..., color_detail: _Optional[int] = ..., frame_jpeg_quality: _Optional[int] = ...) -> None: ...

class GetStateRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class WatchRequest(_message.Message):
    __slots__ = ("from_generation",)
    FROM_GENERATION_FIELD_NUMBER: _ClassVar[int]
    from_generation: int
    def __init__(self, from_generation: _Optional[int] = ...) -> None: ...

class WaitForGenerationRequest(_message.Message):
    __slots__ = ("min_generation", "timeout_ms")
    MIN_GENERATION_FIELD_NUMBER: _ClassVar[int]
    TIMEOUT_MS_FIELD_NUMBER: _ClassVar[int]
    min_generation: int
    timeout_ms: int
    def __init__(self, min_generation: _Optional[int] = ..., timeout_ms: _Optional[int] = ...) -> None: ...

class SetSourceParameterRequest(_message.Message):
    __slots__ = ("source_id", "name", "value", "reset")
    SOURCE_ID_FIELD_NUMBER: _ClassVar[int]
    NAME_FIELD_NUMBER: _ClassVar[int]
    VALUE_FIELD_NUMBER: _ClassVar[int]
    RESET_FIELD_NUMBER: _ClassVar[int]
    source_id: str
    name: str
    value: str
    reset: bool
    def __init__(self, source_id: _Optional[str] = ..., name: _Optional[str] = ..., value: _Optional[str] = ..., reset: _Optional[bool] = ...) -> None: ...

class ReloadRequest(_message.Message):
    __slots__ = ("source_ids",)
    SOURCE_IDS_FIELD_NUMBER: _ClassVar[int]
    source_ids: _containers.RepeatedScalarFieldContainer[str]
    def __init__(self, source_ids: _Optional[_Iterable[str]] = ...) -> None: ...

class SourceState(_message.Message):
    __slots__ = ("id", "kind", "output", "inputs", "status", "error", "files", "version", "active", "extent", "crs", "vertical_datum", "vertical_units", "tiles_generated", "details", "instance_classes", "warnings")
    class DetailsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: str
        def __init__(self, key: _Optional[str] = ..., value: _Optional[str] = ...) -> None: ...
    ID_FIELD_NUMBER: _ClassVar[int]
    KIND_FIELD_NUMBER: _ClassVar[int]
    OUTPUT_FIELD_NUMBER: _ClassVar[int]
    INPUTS_FIELD_NUMBER: _ClassVar[int]
    STATUS_FIELD_NUMBER: _ClassVar[int]
    ERROR_FIELD_NUMBER: _ClassVar[int]
    FILES_FIELD_NUMBER: _ClassVar[int]
    VERSION_FIELD_NUMBER: _ClassVar[int]
    ACTIVE_FIELD_NUMBER: _ClassVar[int]
    EXTENT_FIELD_NUMBER: _ClassVar[int]
    CRS_FIELD_NUMBER: _ClassVar[int]
    VERTICAL_DATUM_FIELD_NUMBER: _ClassVar[int]
    VERTICAL_UNITS_FIELD_NUMBER: _ClassVar[int]
    TILES_GENERATED_FIELD_NUMBER: _ClassVar[int]
    DETAILS_FIELD_NUMBER: _ClassVar[int]
    INSTANCE_CLASSES_FIELD_NUMBER: _ClassVar[int]
    WARNINGS_FIELD_NUMBER: _ClassVar[int]
    id: str
    kind: str
    output: PayloadKind
    inputs: _containers.RepeatedScalarFieldContainer[str]
    status: SourceStatus
    error: str
    files: _containers.RepeatedScalarFieldContainer[str]
    version: int
    active: bool
    extent: Extent
    crs: str
    vertical_datum: str
    vertical_units: str
    tiles_generated: int
    details: _containers.ScalarMap[str, str]
    instance_classes: _containers.RepeatedCompositeFieldContainer[InstanceClass]
    warnings: _containers.RepeatedScalarFieldContainer[str]
    def __init__(self, id: _Optional[str] = ..., kind: _Optional[str] = ..., output: _Optional[_Union[PayloadKind, str]] = ..., inputs: _Optional[_Iterable[str]] = ..., status: _Optional[_Union[SourceStatus, str]] = ..., error: _Optional[str] = ..., files: _Optional[_Iterable[str]] = ..., version: _Optional[int] = ..., active: _Optional[bool] = ..., extent: _Optional[_Union[Extent, _Mapping]] = ..., crs: _Optional[str] = ..., vertical_datum: _Optional[str] = ..., vertical_units: _Optional[str] = ..., tiles_generated: _Optional[int] = ..., details: _Optional[_Mapping[str, str]] = ..., instance_classes: _Optional[_Iterable[_Union[InstanceClass, _Mapping]]] = ..., warnings: _Optional[_Iterable[str]] = ...) -> None: ...

class InstanceClass(_message.Message):
    __slots__ = ("has_rule", "instances", "samples")
    CLASS_FIELD_NUMBER: _ClassVar[int]
    HAS_RULE_FIELD_NUMBER: _ClassVar[int]
    INSTANCES_FIELD_NUMBER: _ClassVar[int]
    SAMPLES_FIELD_NUMBER: _ClassVar[int]
    has_rule: bool
    instances: int
    samples: int
    def __init__(self, has_rule: _Optional[bool] = ..., instances: _Optional[int] = ..., samples: _Optional[int] = ..., **kwargs) -> None: ...

class EffectState(_message.Message):
    __slots__ = ("name", "sources", "ran", "last_cost_ms")
    NAME_FIELD_NUMBER: _ClassVar[int]
    SOURCES_FIELD_NUMBER: _ClassVar[int]
    RAN_FIELD_NUMBER: _ClassVar[int]
    LAST_COST_MS_FIELD_NUMBER: _ClassVar[int]
    name: str
    sources: _containers.RepeatedScalarFieldContainer[str]
    ran: bool
    last_cost_ms: float
    def __init__(self, name: _Optional[str] = ..., sources: _Optional[_Iterable[str]] = ..., ran: _Optional[bool] = ..., last_cost_ms: _Optional[float] = ...) -> None: ...

class Counters(_message.Message):
    __slots__ = ("tiles_generated", "cache_hits", "cache_misses", "cache_entries", "cache_bytes", "cache_budget_bytes", "frames_rendered", "reads_retried", "source_reads", "frame_views", "frame_streams", "open_views", "stream_frames_rendered", "outer_stores", "raster_cache_bytes", "raster_cache_budget_bytes", "stream_frames_carried_over", "renderer_caches", "memory", "standard_tiles", "object_bytes_read", "object_version_checks")
    TILES_GENERATED_FIELD_NUMBER: _ClassVar[int]
    CACHE_HITS_FIELD_NUMBER: _ClassVar[int]
    CACHE_MISSES_FIELD_NUMBER: _ClassVar[int]
    CACHE_ENTRIES_FIELD_NUMBER: _ClassVar[int]
    CACHE_BYTES_FIELD_NUMBER: _ClassVar[int]
    CACHE_BUDGET_BYTES_FIELD_NUMBER: _ClassVar[int]
    FRAMES_RENDERED_FIELD_NUMBER: _ClassVar[int]
    READS_RETRIED_FIELD_NUMBER: _ClassVar[int]
    SOURCE_READS_FIELD_NUMBER: _ClassVar[int]
    FRAME_VIEWS_FIELD_NUMBER: _ClassVar[int]
    FRAME_STREAMS_FIELD_NUMBER: _ClassVar[int]
    OPEN_VIEWS_FIELD_NUMBER: _ClassVar[int]
    STREAM_FRAMES_RENDERED_FIELD_NUMBER: _ClassVar[int]
    OUTER_STORES_FIELD_NUMBER: _ClassVar[int]
    RASTER_CACHE_BYTES_FIELD_NUMBER: _ClassVar[int]
    RASTER_CACHE_BUDGET_BYTES_FIELD_NUMBER: _ClassVar[int]
    STREAM_FRAMES_CARRIED_OVER_FIELD_NUMBER: _ClassVar[int]
    RENDERER_CACHES_FIELD_NUMBER: _ClassVar[int]
    MEMORY_FIELD_NUMBER: _ClassVar[int]
    STANDARD_TILES_FIELD_NUMBER: _ClassVar[int]
    OBJECT_BYTES_READ_FIELD_NUMBER: _ClassVar[int]
    OBJECT_VERSION_CHECKS_FIELD_NUMBER: _ClassVar[int]
    tiles_generated: int
    cache_hits: int
    cache_misses: int
    cache_entries: int
    cache_bytes: int
    cache_budget_bytes: int
    frames_rendered: int
    reads_retried: int
    source_reads: int
    frame_views: int
    frame_streams: int
    open_views: int
    stream_frames_rendered: int
    outer_stores: _containers.RepeatedCompositeFieldContainer[OuterStore]
    raster_cache_bytes: int
    raster_cache_budget_bytes: int
    stream_frames_carried_over: int
    renderer_caches: CacheWork
    memory: _containers.RepeatedCompositeFieldContainer[MemoryUse]
    standard_tiles: StandardTiles
    object_bytes_read: int
    object_version_checks: int
    def __init__(self, tiles_generated: _Optional[int] = ..., cache_hits: _Optional[int] = ..., cache_misses: _Optional[int] = ..., cache_entries: _Optional[int] = ..., cache_bytes: _Optional[int] = ..., cache_budget_bytes: _Optional[int] = ..., frames_rendered: _Optional[int] = ..., reads_retried: _Optional[int] = ..., source_reads: _Optional[int] = ..., frame_views: _Optional[int] = ..., frame_streams: _Optional[int] = ..., open_views: _Optional[int] = ..., stream_frames_rendered: _Optional[int] = ..., outer_stores: _Optional[_Iterable[_Union[OuterStore, _Mapping]]] = ..., raster_cache_bytes: _Optional[int] = ..., raster_cache_budget_bytes: _Optional[int] = ..., stream_frames_carried_over: _Optional[int] = ..., renderer_caches: _Optional[_Union[CacheWork, _Mapping]] = ..., memory: _Optional[_Iterable[_Union[MemoryUse, _Mapping]]] = ..., standard_tiles: _Optional[_Union[StandardTiles, _Mapping]] = ..., object_bytes_read: _Optional[int] = ..., object_version_checks: _Optional[int] = ...) -> None: ...

class StandardTiles(_message.Message):
    __slots__ = ("terrain_tiles_built", "terrain_tiles_served", "not_modified", "change_notices_sent", "change_streams", "encoded_bytes", "terrarium_tiles_built", "imagery_tiles_built", "glb_tiles_built")
    TERRAIN_TILES_BUILT_FIELD_NUMBER: _ClassVar[int]
    TERRAIN_TILES_SERVED_FIELD_NUMBER: _ClassVar[int]
    NOT_MODIFIED_FIELD_NUMBER: _ClassVar[int]
    CHANGE_NOTICES_SENT_FIELD_NUMBER: _ClassVar[int]
    CHANGE_STREAMS_FIELD_NUMBER: _ClassVar[int]
    ENCODED_BYTES_FIELD_NUMBER: _ClassVar[int]
    TERRARIUM_TILES_BUILT_FIELD_NUMBER: _ClassVar[int]
    IMAGERY_TILES_BUILT_FIELD_NUMBER: _ClassVar[int]
    GLB_TILES_BUILT_FIELD_NUMBER: _ClassVar[int]
    terrain_tiles_built: int
    terrain_tiles_served: int
    not_modified: int
    change_notices_sent: int
    change_streams: int
    encoded_bytes: int
    terrarium_tiles_built: int
    imagery_tiles_built: int
    glb_tiles_built: int
    def __init__(self, terrain_tiles_built: _Optional[int] = ..., terrain_tiles_served: _Optional[int] = ..., not_modified: _Optional[int] = ..., change_notices_sent: _Optional[int] = ..., change_streams: _Optional[int] = ..., encoded_bytes: _Optional[int] = ..., terrarium_tiles_built: _Optional[int] = ..., imagery_tiles_built: _Optional[int] = ..., glb_tiles_built: _Optional[int] = ...) -> None: ...

class MemoryUse(_message.Message):
    __slots__ = ("name", "bytes")
    NAME_FIELD_NUMBER: _ClassVar[int]
    BYTES_FIELD_NUMBER: _ClassVar[int]
    name: str
    bytes: int
    def __init__(self, name: _Optional[str] = ..., bytes: _Optional[int] = ...) -> None: ...

class CacheWork(_message.Message):
    __slots__ = ("level_samples_written", "water_coverage_texels", "shadow_maps_drawn", "shadow_maps_redrawn_in_part", "shadow_maps_kept", "shadow_regions", "shadow_texels", "building_tiles_built", "instance_tiles_built", "detail_fits")
    LEVEL_SAMPLES_WRITTEN_FIELD_NUMBER: _ClassVar[int]
    WATER_COVERAGE_TEXELS_FIELD_NUMBER: _ClassVar[int]
    SHADOW_MAPS_DRAWN_FIELD_NUMBER: _ClassVar[int]
    SHADOW_MAPS_REDRAWN_IN_PART_FIELD_NUMBER: _ClassVar[int]
    SHADOW_MAPS_KEPT_FIELD_NUMBER: _ClassVar[int]
    SHADOW_REGIONS_FIELD_NUMBER: _ClassVar[int]
    SHADOW_TEXELS_FIELD_NUMBER: _ClassVar[int]
    BUILDING_TILES_BUILT_FIELD_NUMBER: _ClassVar[int]
    INSTANCE_TILES_BUILT_FIELD_NUMBER: _ClassVar[int]
    DETAIL_FITS_FIELD_NUMBER: _ClassVar[int]
    level_samples_written: int
    water_coverage_texels: int
    shadow_maps_drawn: int
    shadow_maps_redrawn_in_part: int
    shadow_maps_kept: int
    shadow_regions: int
    shadow_texels: int
    building_tiles_built: int
    instance_tiles_built: int
    detail_fits: int
    def __init__(self, level_samples_written: _Optional[int] = ..., water_coverage_texels: _Optional[int] = ..., shadow_maps_drawn: _Optional[int] = ..., shadow_maps_redrawn_in_part: _Optional[int] = ..., shadow_maps_kept: _Optional[int] = ..., shadow_regions: _Optional[int] = ..., shadow_texels: _Optional[int] = ..., building_tiles_built: _Optional[int] = ..., instance_tiles_built: _Optional[int] = ..., detail_fits: _Optional[int] = ...) -> None: ...

class OuterStore(_message.Message):
    __slots__ = ("name", "hits", "misses", "writes")
    NAME_FIELD_NUMBER: _ClassVar[int]
    HITS_FIELD_NUMBER: _ClassVar[int]
    MISSES_FIELD_NUMBER: _ClassVar[int]
    WRITES_FIELD_NUMBER: _ClassVar[int]
    name: str
    hits: int
    misses: int
    writes: int
    def __init__(self, name: _Optional[str] = ..., hits: _Optional[int] = ..., misses: _Optional[int] = ..., writes: _Optional[int] = ...) -> None: ...

class GridInfo(_message.Message):
    __slots__ = ("kind", "crs", "tile_size", "extent", "level0_columns", "level0_rows")
    KIND_FIELD_NUMBER: _ClassVar[int]
    CRS_FIELD_NUMBER: _ClassVar[int]
    TILE_SIZE_FIELD_NUMBER: _ClassVar[int]
    EXTENT_FIELD_NUMBER: _ClassVar[int]
    LEVEL0_COLUMNS_FIELD_NUMBER: _ClassVar[int]
    LEVEL0_ROWS_FIELD_NUMBER: _ClassVar[int]
    kind: str
    crs: str
    tile_size: int
    extent: Extent
    level0_columns: int
    level0_rows: int
    def __init__(self, kind: _Optional[str] = ..., crs: _Optional[str] = ..., tile_size: _Optional[int] = ..., extent: _Optional[_Union[Extent, _Mapping]] = ..., level0_columns: _Optional[int] = ..., level0_rows: _Optional[int] = ...) -> None: ...

class Parameter(_message.Message):
    __slots__ = ("target", "name", "value", "manifest_value", "origin")
    TARGET_FIELD_NUMBER: _ClassVar[int]
    NAME_FIELD_NUMBER: _ClassVar[int]
    VALUE_FIELD_NUMBER: _ClassVar[int]
    MANIFEST_VALUE_FIELD_NUMBER: _ClassVar[int]
    ORIGIN_FIELD_NUMBER: _ClassVar[int]
    target: str
    name: str
    value: str
    manifest_value: str
    origin: str
    def __init__(self, target: _Optional[str] = ..., name: _Optional[str] = ..., value: _Optional[str] = ..., manifest_value: _Optional[str] = ..., origin: _Optional[str] = ...) -> None: ...

class SceneState(_message.Message):
    __slots__ = ("name", "generation", "grid", "sources", "effects", "layers", "quality", "counters", "manifest", "manifest_error", "passes", "parameters")
    class LayersEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: str
        def __init__(self, key: _Optional[str] = ..., value: _Optional[str] = ...) -> None: ...
    class QualityEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: str
        def __init__(self, key: _Optional[str] = ..., value: _Optional[str] = ...) -> None: ...
    NAME_FIELD_NUMBER: _ClassVar[int]
    GENERATION_FIELD_NUMBER: _ClassVar[int]
    GRID_FIELD_NUMBER: _ClassVar[int]
    SOURCES_FIELD_NUMBER: _ClassVar[int]
    EFFECTS_FIELD_NUMBER: _ClassVar[int]
    LAYERS_FIELD_NUMBER: _ClassVar[int]
    QUALITY_FIELD_NUMBER: _ClassVar[int]
    COUNTERS_FIELD_NUMBER: _ClassVar[int]
    MANIFEST_FIELD_NUMBER: _ClassVar[int]
    MANIFEST_ERROR_FIELD_NUMBER: _ClassVar[int]
    PASSES_FIELD_NUMBER: _ClassVar[int]
    PARAMETERS_FIELD_NUMBER: _ClassVar[int]
    name: str
    generation: int
    grid: GridInfo
    sources: _containers.RepeatedCompositeFieldContainer[SourceState]
    effects: _containers.RepeatedCompositeFieldContainer[EffectState]
    layers: _containers.ScalarMap[str, str]
    quality: _containers.ScalarMap[str, str]
    counters: Counters
    manifest: str
    manifest_error: str
    passes: _containers.RepeatedCompositeFieldContainer[PassState]
    parameters: _containers.RepeatedCompositeFieldContainer[Parameter]
    def __init__(self, name: _Optional[str] = ..., generation: _Optional[int] = ..., grid: _Optional[_Union[GridInfo, _Mapping]] = ..., sources: _Optional[_Iterable[_Union[SourceState, _Mapping]]] = ..., effects: _Optional[_Iterable[_Union[EffectState, _Mapping]]] = ..., layers: _Optional[_Mapping[str, str]] = ..., quality: _Optional[_Mapping[str, str]] = ..., counters: _Optional[_Union[Counters, _Mapping]] = ..., manifest: _Optional[str] = ..., manifest_error: _Optional[str] = ..., passes: _Optional[_Iterable[_Union[PassState, _Mapping]]] = ..., parameters: _Optional[_Iterable[_Union[Parameter, _Mapping]]] = ...) -> None: ...

class PassState(_message.Message):
    __slots__ = ("name", "built", "runs", "total_ms")
    NAME_FIELD_NUMBER: _ClassVar[int]
    BUILT_FIELD_NUMBER: _ClassVar[int]
    RUNS_FIELD_NUMBER: _ClassVar[int]
    TOTAL_MS_FIELD_NUMBER: _ClassVar[int]
    name: str
    built: bool
    runs: int
    total_ms: float
    def __init__(self, name: _Optional[str] = ..., built: _Optional[bool] = ..., runs: _Optional[int] = ..., total_ms: _Optional[float] = ...) -> None: ...

class DirtyRegion(_message.Message):
    __slots__ = ("source_id", "extents")
    SOURCE_ID_FIELD_NUMBER: _ClassVar[int]
    EXTENTS_FIELD_NUMBER: _ClassVar[int]
    source_id: str
    extents: _containers.RepeatedCompositeFieldContainer[Extent]
    def __init__(self, source_id: _Optional[str] = ..., extents: _Optional[_Iterable[_Union[Extent, _Mapping]]] = ...) -> None: ...

class SceneEvent(_message.Message):
    __slots__ = ("generation", "snapshot", "generation_changed", "source_error", "manifest_error")
    GENERATION_FIELD_NUMBER: _ClassVar[int]
    SNAPSHOT_FIELD_NUMBER: _ClassVar[int]
    GENERATION_CHANGED_FIELD_NUMBER: _ClassVar[int]
    SOURCE_ERROR_FIELD_NUMBER: _ClassVar[int]
    MANIFEST_ERROR_FIELD_NUMBER: _ClassVar[int]
    generation: int
    snapshot: SceneState
    generation_changed: GenerationEvent
    source_error: SourceErrorEvent
    manifest_error: ManifestErrorEvent
    def __init__(self, generation: _Optional[int] = ..., snapshot: _Optional[_Union[SceneState, _Mapping]] = ..., generation_changed: _Optional[_Union[GenerationEvent, _Mapping]] = ..., source_error: _Optional[_Union[SourceErrorEvent, _Mapping]] = ..., manifest_error: _Optional[_Union[ManifestErrorEvent, _Mapping]] = ...) -> None: ...

class ManifestErrorEvent(_message.Message):
    __slots__ = ("error",)
    ERROR_FIELD_NUMBER: _ClassVar[int]
    error: str
    def __init__(self, error: _Optional[str] = ...) -> None: ...

class GenerationEvent(_message.Message):
    __slots__ = ("changed_sources", "dirty", "tiles_rebuilt", "tiles_invalidated", "elapsed_ms", "reason", "tiles_carried_over", "tiles_cut_off")
    CHANGED_SOURCES_FIELD_NUMBER: _ClassVar[int]
    DIRTY_FIELD_NUMBER: _ClassVar[int]
    TILES_REBUILT_FIELD_NUMBER: _ClassVar[int]
    TILES_INVALIDATED_FIELD_NUMBER: _ClassVar[int]
    ELAPSED_MS_FIELD_NUMBER: _ClassVar[int]
    REASON_FIELD_NUMBER: _ClassVar[int]
    TILES_CARRIED_OVER_FIELD_NUMBER: _ClassVar[int]
    TILES_CUT_OFF_FIELD_NUMBER: _ClassVar[int]
    changed_sources: _containers.RepeatedScalarFieldContainer[str]
    dirty: _containers.RepeatedCompositeFieldContainer[DirtyRegion]
    tiles_rebuilt: int
    tiles_invalidated: int
    elapsed_ms: float
    reason: str
    tiles_carried_over: int
    tiles_cut_off: int
    def __init__(self, changed_sources: _Optional[_Iterable[str]] = ..., dirty: _Optional[_Iterable[_Union[DirtyRegion, _Mapping]]] = ..., tiles_rebuilt: _Optional[int] = ..., tiles_invalidated: _Optional[int] = ..., elapsed_ms: _Optional[float] = ..., reason: _Optional[str] = ..., tiles_carried_over: _Optional[int] = ..., tiles_cut_off: _Optional[int] = ...) -> None: ...

class SourceErrorEvent(_message.Message):
    __slots__ = ("source_id", "error", "kept_last_good")
    SOURCE_ID_FIELD_NUMBER: _ClassVar[int]
    ERROR_FIELD_NUMBER: _ClassVar[int]
    KEPT_LAST_GOOD_FIELD_NUMBER: _ClassVar[int]
    source_id: str
    error: str
    kept_last_good: bool
    def __init__(self, source_id: _Optional[str] = ..., error: _Optional[str] = ..., kept_last_good: _Optional[bool] = ...) -> None: ...

class Camera(_message.Message):
    __slots__ = ("lon_deg", "lat_deg", "altitude_m", "heading_deg", "pitch_deg", "roll_deg", "vertical_fov_deg")
    LON_DEG_FIELD_NUMBER: _ClassVar[int]
    LAT_DEG_FIELD_NUMBER: _ClassVar[int]
    ALTITUDE_M_FIELD_NUMBER: _ClassVar[int]
    HEADING_DEG_FIELD_NUMBER: _ClassVar[int]
    PITCH_DEG_FIELD_NUMBER: _ClassVar[int]
    ROLL_DEG_FIELD_NUMBER: _ClassVar[int]
    VERTICAL_FOV_DEG_FIELD_NUMBER: _ClassVar[int]
    lon_deg: float
    lat_deg: float
    altitude_m: float
    heading_deg: float
    pitch_deg: float
    roll_deg: float
    vertical_fov_deg: float
    def __init__(self, lon_deg: _Optional[float] = ..., lat_deg: _Optional[float] = ..., altitude_m: _Optional[float] = ..., heading_deg: _Optional[float] = ..., pitch_deg: _Optional[float] = ..., roll_deg: _Optional[float] = ..., vertical_fov_deg: _Optional[float] = ...) -> None: ...

class SetCameraRequest(_message.Message):
    __slots__ = ("camera",)
    CAMERA_FIELD_NUMBER: _ClassVar[int]
    camera: Camera
    def __init__(self, camera: _Optional[_Union[Camera, _Mapping]] = ...) -> None: ...

class GetCameraRequest(_message.Message):
    __slots__ = ()
    def __init__(self) -> None: ...

class RenderRequest(_message.Message):
    __slots__ = ("camera", "width", "height", "format", "quality", "sun")
    CAMERA_FIELD_NUMBER: _ClassVar[int]
    WIDTH_FIELD_NUMBER: _ClassVar[int]
    HEIGHT_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    QUALITY_FIELD_NUMBER: _ClassVar[int]
    SUN_FIELD_NUMBER: _ClassVar[int]
    camera: Camera
    width: int
    height: int
    format: ImageFormat
    quality: QualityOverrides
    sun: Sun
    def __init__(self, camera: _Optional[_Union[Camera, _Mapping]] = ..., width: _Optional[int] = ..., height: _Optional[int] = ..., format: _Optional[_Union[ImageFormat, str]] = ..., quality: _Optional[_Union[QualityOverrides, _Mapping]] = ..., sun: _Optional[_Union[Sun, _Mapping]] = ...) -> None: ...

class Sun(_message.Message):
    __slots__ = ("time", "azimuth_deg", "elevation_deg")
    TIME_FIELD_NUMBER: _ClassVar[int]
    AZIMUTH_DEG_FIELD_NUMBER: _ClassVar[int]
    ELEVATION_DEG_FIELD_NUMBER: _ClassVar[int]
    time: str
    azimuth_deg: float
    elevation_deg: float
    def __init__(self, time: _Optional[str] = ..., azimuth_deg: _Optional[float] = ..., elevation_deg: _Optional[float] = ...) -> None: ...

class SunPosition(_message.Message):
    __slots__ = ("azimuth_deg", "elevation_deg", "source")
    AZIMUTH_DEG_FIELD_NUMBER: _ClassVar[int]
    ELEVATION_DEG_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FIELD_NUMBER: _ClassVar[int]
    azimuth_deg: float
    elevation_deg: float
    source: str
    def __init__(self, azimuth_deg: _Optional[float] = ..., elevation_deg: _Optional[float] = ..., source: _Optional[str] = ...) -> None: ...

class PassTiming(_message.Message):
    __slots__ = ("elapsed_ms",)
    PASS_FIELD_NUMBER: _ClassVar[int]
    ELAPSED_MS_FIELD_NUMBER: _ClassVar[int]
    elapsed_ms: float
    def __init__(self, elapsed_ms: _Optional[float] = ..., **kwargs) -> None: ...

class RenderResponse(_message.Message):
    __slots__ = ("generation", "width", "height", "format", "image", "passes", "camera", "pass_counters", "drawn", "sun", "carried_over")
    GENERATION_FIELD_NUMBER: _ClassVar[int]
    WIDTH_FIELD_NUMBER: _ClassVar[int]
    HEIGHT_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    IMAGE_FIELD_NUMBER: _ClassVar[int]
    PASSES_FIELD_NUMBER: _ClassVar[int]
    CAMERA_FIELD_NUMBER: _ClassVar[int]
    PASS_COUNTERS_FIELD_NUMBER: _ClassVar[int]
    DRAWN_FIELD_NUMBER: _ClassVar[int]
    SUN_FIELD_NUMBER: _ClassVar[int]
    CARRIED_OVER_FIELD_NUMBER: _ClassVar[int]
    generation: int
    width: int
    height: int
    format: ImageFormat
    image: bytes
    passes: _containers.RepeatedCompositeFieldContainer[PassTiming]
    camera: Camera
    pass_counters: _containers.RepeatedCompositeFieldContainer[PassState]
    drawn: FrameDrawn
    sun: SunPosition
    carried_over: bool
    def __init__(self, generation: _Optional[int] = ..., width: _Optional[int] = ..., height: _Optional[int] = ..., format: _Optional[_Union[ImageFormat, str]] = ..., image: _Optional[bytes] = ..., passes: _Optional[_Iterable[_Union[PassTiming, _Mapping]]] = ..., camera: _Optional[_Union[Camera, _Mapping]] = ..., pass_counters: _Optional[_Iterable[_Union[PassState, _Mapping]]] = ..., drawn: _Optional[_Union[FrameDrawn, _Mapping]] = ..., sun: _Optional[_Union[SunPosition, _Mapping]] = ..., carried_over: _Optional[bool] = ...) -> None: ...

class FrameDrawn(_message.Message):
    __slots__ = ("buildings", "models", "billboards", "terrain_blocks", "terrain_blocks_drawn", "terrain_blocks_beyond_horizon", "shadow_maps_drawn", "shadow_maps_kept", "shadow_maps_redrawn_in_part", "shadow_regions", "shadow_texels", "water_coverage_texels", "level_samples_written", "building_tiles_built", "instance_tiles_built")
    BUILDINGS_FIELD_NUMBER: _ClassVar[int]
    MODELS_FIELD_NUMBER: _ClassVar[int]
    BILLBOARDS_FIELD_NUMBER: _ClassVar[int]
    TERRAIN_BLOCKS_FIELD_NUMBER: _ClassVar[int]
    TERRAIN_BLOCKS_DRAWN_FIELD_NUMBER: _ClassVar[int]
    TERRAIN_BLOCKS_BEYOND_HORIZON_FIELD_NUMBER: _ClassVar[int]
    SHADOW_MAPS_DRAWN_FIELD_NUMBER: _ClassVar[int]
    SHADOW_MAPS_KEPT_FIELD_NUMBER: _ClassVar[int]
    SHADOW_MAPS_REDRAWN_IN_PART_FIELD_NUMBER: _ClassVar[int]
    SHADOW_REGIONS_FIELD_NUMBER: _ClassVar[int]
    SHADOW_TEXELS_FIELD_NUMBER: _ClassVar[int]
    WATER_COVERAGE_TEXELS_FIELD_NUMBER: _ClassVar[int]
    LEVEL_SAMPLES_WRITTEN_FIELD_NUMBER: _ClassVar[int]
    BUILDING_TILES_BUILT_FIELD_NUMBER: _ClassVar[int]
    INSTANCE_TILES_BUILT_FIELD_NUMBER: _ClassVar[int]
    buildings: int
    models: int
    billboards: int
    terrain_blocks: int
    terrain_blocks_drawn: int
    terrain_blocks_beyond_horizon: int
    shadow_maps_drawn: int
    shadow_maps_kept: int
    shadow_maps_redrawn_in_part: int
    shadow_regions: int
    shadow_texels: int
    water_coverage_texels: int
    level_samples_written: int
    building_tiles_built: int
    instance_tiles_built: int
    def __init__(self, buildings: _Optional[int] = ..., models: _Optional[int] = ..., billboards: _Optional[int] = ..., terrain_blocks: _Optional[int] = ..., terrain_blocks_drawn: _Optional[int] = ..., terrain_blocks_beyond_horizon: _Optional[int] = ..., shadow_maps_drawn: _Optional[int] = ..., shadow_maps_kept: _Optional[int] = ..., shadow_maps_redrawn_in_part: _Optional[int] = ..., shadow_regions: _Optional[int] = ..., shadow_texels: _Optional[int] = ..., water_coverage_texels: _Optional[int] = ..., level_samples_written: _Optional[int] = ..., building_tiles_built: _Optional[int] = ..., instance_tiles_built: _Optional[int] = ...) -> None: ...

class StreamFramesRequest(_message.Message):
    __slots__ = ("width", "height", "format", "max_fps", "quality", "camera", "view_id", "sun")
    WIDTH_FIELD_NUMBER: _ClassVar[int]
    HEIGHT_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    MAX_FPS_FIELD_NUMBER: _ClassVar[int]
    QUALITY_FIELD_NUMBER: _ClassVar[int]
    CAMERA_FIELD_NUMBER: _ClassVar[int]
    VIEW_ID_FIELD_NUMBER: _ClassVar[int]
    SUN_FIELD_NUMBER: _ClassVar[int]
    width: int
    height: int
    format: ImageFormat
    max_fps: float
    quality: QualityOverrides
    camera: Camera
    view_id: str
    sun: Sun
    def __init__(self, width: _Optional[int] = ..., height: _Optional[int] = ..., format: _Optional[_Union[ImageFormat, str]] = ..., max_fps: _Optional[float] = ..., quality: _Optional[_Union[QualityOverrides, _Mapping]] = ..., camera: _Optional[_Union[Camera, _Mapping]] = ..., view_id: _Optional[str] = ..., sun: _Optional[_Union[Sun, _Mapping]] = ...) -> None: ...

class OpenViewRequest(_message.Message):
    __slots__ = ("camera", "follow_scene_camera")
    CAMERA_FIELD_NUMBER: _ClassVar[int]
    FOLLOW_SCENE_CAMERA_FIELD_NUMBER: _ClassVar[int]
    camera: Camera
    follow_scene_camera: bool
    def __init__(self, camera: _Optional[_Union[Camera, _Mapping]] = ..., follow_scene_camera: _Optional[bool] = ...) -> None: ...

class UpdateViewRequest(_message.Message):
    __slots__ = ("view_id", "camera", "follow_scene_camera", "interactive")
    VIEW_ID_FIELD_NUMBER: _ClassVar[int]
    CAMERA_FIELD_NUMBER: _ClassVar[int]
    FOLLOW_SCENE_CAMERA_FIELD_NUMBER: _ClassVar[int]
    INTERACTIVE_FIELD_NUMBER: _ClassVar[int]
    view_id: str
    camera: Camera
    follow_scene_camera: bool
    interactive: bool
    def __init__(self, view_id: _Optional[str] = ..., camera: _Optional[_Union[Camera, _Mapping]] = ..., follow_scene_camera: _Optional[bool] = ..., interactive: _Optional[bool] = ...) -> None: ...

class ViewState(_message.Message):
    __slots__ = ("view_id", "camera", "follow_scene_camera", "interactive")
    VIEW_ID_FIELD_NUMBER: _ClassVar[int]
    CAMERA_FIELD_NUMBER: _ClassVar[int]
    FOLLOW_SCENE_CAMERA_FIELD_NUMBER: _ClassVar[int]
    INTERACTIVE_FIELD_NUMBER: _ClassVar[int]
    view_id: str
    camera: Camera
    follow_scene_camera: bool
    interactive: bool
    def __init__(self, view_id: _Optional[str] = ..., camera: _Optional[_Union[Camera, _Mapping]] = ..., follow_scene_camera: _Optional[bool] = ..., interactive: _Optional[bool] = ...) -> None: ...

class NavigateRequest(_message.Message):
    __slots__ = ("view_id", "orbit", "pan", "zoom", "move", "fly_to_source")
    VIEW_ID_FIELD_NUMBER: _ClassVar[int]
    ORBIT_FIELD_NUMBER: _ClassVar[int]
    PAN_FIELD_NUMBER: _ClassVar[int]
    ZOOM_FIELD_NUMBER: _ClassVar[int]
    MOVE_FIELD_NUMBER: _ClassVar[int]
    FLY_TO_SOURCE_FIELD_NUMBER: _ClassVar[int]
    view_id: str
    orbit: Orbit
    pan: Pan
    zoom: Zoom
    move: Move
    fly_to_source: str
    def __init__(self, view_id: _Optional[str] = ..., orbit: _Optional[_Union[Orbit, _Mapping]] = ..., pan: _Optional[_Union[Pan, _Mapping]] = ..., zoom: _Optional[_Union[Zoom, _Mapping]] = ..., move: _Optional[_Union[Move, _Mapping]] = ..., fly_to_source: _Optional[str] = ...) -> None: ...

class Orbit(_message.Message):
    __slots__ = ("heading_deg", "pitch_deg")
    HEADING_DEG_FIELD_NUMBER: _ClassVar[int]
    PITCH_DEG_FIELD_NUMBER: _ClassVar[int]
    heading_deg: float
    pitch_deg: float
    def __init__(self, heading_deg: _Optional[float] = ..., pitch_deg: _Optional[float] = ...) -> None: ...

class Pan(_message.Message):
    __slots__ = ("from_x", "from_y", "to_x", "to_y")
    FROM_X_FIELD_NUMBER: _ClassVar[int]
    FROM_Y_FIELD_NUMBER: _ClassVar[int]
    TO_X_FIELD_NUMBER: _ClassVar[int]
    TO_Y_FIELD_NUMBER: _ClassVar[int]
    from_x: float
    from_y: float
    to_x: float
    to_y: float
    def __init__(self, from_x: _Optional[float] = ..., from_y: _Optional[float] = ..., to_x: _Optional[float] = ..., to_y: _Optional[float] = ...) -> None: ...

class Zoom(_message.Message):
    __slots__ = ("factor", "x", "y")
    FACTOR_FIELD_NUMBER: _ClassVar[int]
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    factor: float
    x: float
    y: float
    def __init__(self, factor: _Optional[float] = ..., x: _Optional[float] = ..., y: _Optional[float] = ...) -> None: ...

class Move(_message.Message):
    __slots__ = ("forward", "right", "up", "turn_deg")
    FORWARD_FIELD_NUMBER: _ClassVar[int]
    RIGHT_FIELD_NUMBER: _ClassVar[int]
    UP_FIELD_NUMBER: _ClassVar[int]
    TURN_DEG_FIELD_NUMBER: _ClassVar[int]
    forward: float
    right: float
    up: float
    turn_deg: float
    def __init__(self, forward: _Optional[float] = ..., right: _Optional[float] = ..., up: _Optional[float] = ..., turn_deg: _Optional[float] = ...) -> None: ...

class PickRequest(_message.Message):
    __slots__ = ("view_id", "x", "y")
    VIEW_ID_FIELD_NUMBER: _ClassVar[int]
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    view_id: str
    x: float
    y: float
    def __init__(self, view_id: _Optional[str] = ..., x: _Optional[float] = ..., y: _Optional[float] = ...) -> None: ...

class PickResponse(_message.Message):
    __slots__ = ("hit", "lon_deg", "lat_deg", "surface_height_m", "ground_height_m", "distance_m", "generation")
    HIT_FIELD_NUMBER: _ClassVar[int]
    LON_DEG_FIELD_NUMBER: _ClassVar[int]
    LAT_DEG_FIELD_NUMBER: _ClassVar[int]
    SURFACE_HEIGHT_M_FIELD_NUMBER: _ClassVar[int]
    GROUND_HEIGHT_M_FIELD_NUMBER: _ClassVar[int]
    DISTANCE_M_FIELD_NUMBER: _ClassVar[int]
    GENERATION_FIELD_NUMBER: _ClassVar[int]
    hit: bool
    lon_deg: float
    lat_deg: float
    surface_height_m: float
    ground_height_m: float
    distance_m: float
    generation: int
    def __init__(self, hit: _Optional[bool] = ..., lon_deg: _Optional[float] = ..., lat_deg: _Optional[float] = ..., surface_height_m: _Optional[float] = ..., ground_height_m: _Optional[float] = ..., distance_m: _Optional[float] = ..., generation: _Optional[int] = ...) -> None: ...

class GetTileRequest(_message.Message):
    __slots__ = ("source_id", "key", "quality")
    SOURCE_ID_FIELD_NUMBER: _ClassVar[int]
    KEY_FIELD_NUMBER: _ClassVar[int]
    QUALITY_FIELD_NUMBER: _ClassVar[int]
    source_id: str
    key: TileKey
    quality: QualityOverrides
    def __init__(self, source_id: _Optional[str] = ..., key: _Optional[_Union[TileKey, _Mapping]] = ..., quality: _Optional[_Union[QualityOverrides, _Mapping]] = ...) -> None: ...

class GetTileResponse(_message.Message):
    __slots__ = ("source_id", "key", "generation", "content_hash", "kind", "width", "height", "extent", "crs", "heights_f32_le", "color_png", "mask_u8", "features_geojson", "mesh", "instances")
    SOURCE_ID_FIELD_NUMBER: _ClassVar[int]
    KEY_FIELD_NUMBER: _ClassVar[int]
    GENERATION_FIELD_NUMBER: _ClassVar[int]
    CONTENT_HASH_FIELD_NUMBER: _ClassVar[int]
    KIND_FIELD_NUMBER: _ClassVar[int]
    WIDTH_FIELD_NUMBER: _ClassVar[int]
    HEIGHT_FIELD_NUMBER: _ClassVar[int]
    EXTENT_FIELD_NUMBER: _ClassVar[int]
    CRS_FIELD_NUMBER: _ClassVar[int]
    HEIGHTS_F32_LE_FIELD_NUMBER: _ClassVar[int]
    COLOR_PNG_FIELD_NUMBER: _ClassVar[int]
    MASK_U8_FIELD_NUMBER: _ClassVar[int]
    FEATURES_GEOJSON_FIELD_NUMBER: _ClassVar[int]
    MESH_FIELD_NUMBER: _ClassVar[int]
    INSTANCES_FIELD_NUMBER: _ClassVar[int]
    source_id: str
    key: TileKey
    generation: int
    content_hash: int
    kind: PayloadKind
    width: int
    height: int
    extent: Extent
    crs: str
    heights_f32_le: bytes
    color_png: bytes
    mask_u8: bytes
    features_geojson: bytes
    mesh: Mesh
    instances: InstanceList
    def __init__(self, source_id: _Optional[str] = ..., key: _Optional[_Union[TileKey, _Mapping]] = ..., generation: _Optional[int] = ..., content_hash: _Optional[int] = ..., kind: _Optional[_Union[PayloadKind, str]] = ..., width: _Optional[int] = ..., height: _Optional[int] = ..., extent: _Optional[_Union[Extent, _Mapping]] = ..., crs: _Optional[str] = ..., heights_f32_le: _Optional[bytes] = ..., color_png: _Optional[bytes] = ..., mask_u8: _Optional[bytes] = ..., features_geojson: _Optional[bytes] = ..., mesh: _Optional[_Union[Mesh, _Mapping]] = ..., instances: _Optional[_Union[InstanceList, _Mapping]] = ...) -> None: ...

class SkippedFeature(_message.Message):
    __slots__ = ("feature_id", "reason")
    FEATURE_ID_FIELD_NUMBER: _ClassVar[int]
    REASON_FIELD_NUMBER: _ClassVar[int]
    feature_id: int
    reason: str
    def __init__(self, feature_id: _Optional[int] = ..., reason: _Optional[str] = ...) -> None: ...

class Mesh(_message.Message):
    __slots__ = ("positions_f64_le", "indices_u32_le", "parts", "skipped")
    POSITIONS_F64_LE_FIELD_NUMBER: _ClassVar[int]
    INDICES_U32_LE_FIELD_NUMBER: _ClassVar[int]
    PARTS_FIELD_NUMBER: _ClassVar[int]
    SKIPPED_FIELD_NUMBER: _ClassVar[int]
    positions_f64_le: bytes
    indices_u32_le: bytes
    parts: _containers.RepeatedCompositeFieldContainer[MeshPart]
    skipped: _containers.RepeatedCompositeFieldContainer[SkippedFeature]
    def __init__(self, positions_f64_le: _Optional[bytes] = ..., indices_u32_le: _Optional[bytes] = ..., parts: _Optional[_Iterable[_Union[MeshPart, _Mapping]]] = ..., skipped: _Optional[_Iterable[_Union[SkippedFeature, _Mapping]]] = ...) -> None: ...

class MeshPart(_message.Message):
    __slots__ = ("feature_id", "first_index", "index_count", "rgba", "on_ground")
    FEATURE_ID_FIELD_NUMBER: _ClassVar[int]
    FIRST_INDEX_FIELD_NUMBER: _ClassVar[int]
    INDEX_COUNT_FIELD_NUMBER: _ClassVar[int]
    RGBA_FIELD_NUMBER: _ClassVar[int]
    ON_GROUND_FIELD_NUMBER: _ClassVar[int]
    feature_id: int
    first_index: int
    index_count: int
    rgba: int
    on_ground: bool
    def __init__(self, feature_id: _Optional[int] = ..., first_index: _Optional[int] = ..., index_count: _Optional[int] = ..., rgba: _Optional[int] = ..., on_ground: _Optional[bool] = ...) -> None: ...

class Instance(_message.Message):
    __slots__ = ("feature_id", "x", "y", "z", "kind", "model", "scale", "rotation_deg")
    FEATURE_ID_FIELD_NUMBER: _ClassVar[int]
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_FIELD_NUMBER: _ClassVar[int]
    KIND_FIELD_NUMBER: _ClassVar[int]
    MODEL_FIELD_NUMBER: _ClassVar[int]
    SCALE_FIELD_NUMBER: _ClassVar[int]
    ROTATION_DEG_FIELD_NUMBER: _ClassVar[int]
    feature_id: int
    x: float
    y: float
    z: float
    kind: InstanceKind
    model: str
    scale: float
    rotation_deg: float
    def __init__(self, feature_id: _Optional[int] = ..., x: _Optional[float] = ..., y: _Optional[float] = ..., z: _Optional[float] = ..., kind: _Optional[_Union[InstanceKind, str]] = ..., model: _Optional[str] = ..., scale: _Optional[float] = ..., rotation_deg: _Optional[float] = ...) -> None: ...

class InstanceList(_message.Message):
    __slots__ = ("instances", "skipped")
    INSTANCES_FIELD_NUMBER: _ClassVar[int]
    SKIPPED_FIELD_NUMBER: _ClassVar[int]
    instances: _containers.RepeatedCompositeFieldContainer[Instance]
    skipped: _containers.RepeatedCompositeFieldContainer[SkippedFeature]
    def __init__(self, instances: _Optional[_Iterable[_Union[Instance, _Mapping]]] = ..., skipped: _Optional[_Iterable[_Union[SkippedFeature, _Mapping]]] = ...) -> None: ...

class SampleElevationRequest(_message.Message):
    __slots__ = ("points", "source_id")
    POINTS_FIELD_NUMBER: _ClassVar[int]
    SOURCE_ID_FIELD_NUMBER: _ClassVar[int]
    points: _containers.RepeatedCompositeFieldContainer[GeodeticPoint]
    source_id: str
    def __init__(self, points: _Optional[_Iterable[_Union[GeodeticPoint, _Mapping]]] = ..., source_id: _Optional[str] = ...) -> None: ...

class ElevationSample(_message.Message):
    __slots__ = ("height_m",)
    HEIGHT_M_FIELD_NUMBER: _ClassVar[int]
    height_m: float
    def __init__(self, height_m: _Optional[float] = ...) -> None: ...

class SampleElevationResponse(_message.Message):
    __slots__ = ("generation", "source_id", "samples")
    GENERATION_FIELD_NUMBER: _ClassVar[int]
    SOURCE_ID_FIELD_NUMBER: _ClassVar[int]
    SAMPLES_FIELD_NUMBER: _ClassVar[int]
    generation: int
    source_id: str
    samples: _containers.RepeatedCompositeFieldContainer[ElevationSample]
    def __init__(self, generation: _Optional[int] = ..., source_id: _Optional[str] = ..., samples: _Optional[_Iterable[_Union[ElevationSample, _Mapping]]] = ...) -> None: ...
