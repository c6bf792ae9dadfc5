"""relief: a typed Python client of reliefd, the relief GIS scene daemon.

    import relief

    with relief.connect("127.0.0.1:50051") as client:
        print(client.state().generation)
        heights = client.elevation([(10.25, 45.25)])
        client.render(camera=relief.Camera(10.25, 45.1, 9000), size=(640, 360)).save("view.png")

`relief.aio` has the same calls for asyncio; `relief.testing` is a pytest
plugin that serves a scene with a real reliefd. No protobuf type appears in
any public signature: calls take and answer the dataclasses of
`relief.types`, and failures raise `relief.ReliefError` subclasses.
"""

from relief import aio
from relief.client import Client, Stream, connect
from relief.errors import (
    Cancelled,
    DeadlineExceeded,
    FailedPrecondition,
    Internal,
    InvalidArgument,
    NotFound,
    ReliefError,
    ResourceExhausted,
    Unavailable,
    Unimplemented,
)
from relief.types import (
    Camera,
    ColorTile,
    Counters,
    DirtyRegion,
    EffectState,
    PassState,
    Event,
    Extent,
    FeatureTile,
    FlyTo,
    Frame,
    FrameDrawn,
    GenerationEvent,
    InstanceClass,
    Gesture,
    Grid,
    HeightTile,
    ImageFormat,
    Instance,
    InstanceKind,
    InstanceTile,
    ManifestErrorEvent,
    MaskTile,
    MeshPart,
    MeshTile,
    Move,
    Orbit,
    Pan,
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
    Tile,
    TileBase,
    View,
    Zoom,
)

__version__ = "0.1.0"

__all__ = [
    "Camera",
    "Cancelled",
    "Client",
    "ColorTile",
    "Counters",
    "DeadlineExceeded",
    "DirtyRegion",
    "EffectState",
    "PassState",
    "Event",
    "Extent",
    "FailedPrecondition",
    "FeatureTile",
    "FlyTo",
    "Frame",
    "FrameDrawn",
    "InstanceClass",
    "GenerationEvent",
    "Gesture",
    "Grid",
    "HeightTile",
    "ImageFormat",
    "Instance",
    "InstanceKind",
    "InstanceTile",
    "Internal",
    "InvalidArgument",
    "ManifestErrorEvent",
    "MaskTile",
    "MeshPart",
    "MeshTile",
    "Move",
    "NotFound",
    "Orbit",
    "Pan",
    "PassTiming",
    "PayloadKind",
    "Pick",
    "Quality",
    "ReliefError",
    "ResourceExhausted",
    "SceneState",
    "SkippedFeature",
    "SnapshotEvent",
    "SourceErrorEvent",
    "SourceState",
    "SourceStatus",
    "Stream",
    "Tile",
    "TileBase",
    "Unavailable",
    "Unimplemented",
    "View",
    "Zoom",
    "aio",
    "connect",
]
