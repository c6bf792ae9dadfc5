"""The blocking client: every relief.v1 call as a typed method.

    with relief.connect("127.0.0.1:50051") as client:
        state = client.state()
        frame = client.render(camera=relief.Camera(10.25, 45.1, 9000), size=(640, 360))
        frame.save("view.png")
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from types import TracebackType
from typing import Any, Generic, TypeVar, overload

import grpc

from relief import _channel, _convert
from relief._bearer import Bearer
from relief._proto.relief.v1 import relief_pb2 as pb
from relief.errors import ReliefError, Unavailable, from_rpc_error
from relief.types import (
    Camera,
    Event,
    Frame,
    Sun,
    Gesture,
    ImageFormat,
    Pick,
    Quality,
    SceneState,
    Tile,
    TileBase,
    View,
)

T = TypeVar("T")
TileT = TypeVar("TileT", bound=Tile)


class Stream(Generic[T]):
    """The messages of a server stream as relief's types: an iterator, and a
    context manager that cancels the call on exit. `close()` ends it early;
    the iteration then stops quietly."""

    def __init__(self, call: Any, convert: Callable[[Any], T | None], method: str) -> None:
        self._call = call
        self._convert = convert
        self._method = method
        self._closed = False

    def __iter__(self) -> Iterator[T]:
        return self

    def __next__(self) -> T:
        while True:
            try:
                message = next(self._call)
            except StopIteration:
                raise
            except grpc.RpcError as e:
                if self._closed and e.code() == grpc.StatusCode.CANCELLED:
                    raise StopIteration from None
                raise from_rpc_error(e, self._method) from None
            item = self._convert(message)
            if item is not None:
                return item

    def close(self) -> None:
        """Cancels the call."""
        self._closed = True
        self._call.cancel()

    def __enter__(self) -> Stream[T]:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __del__(self) -> None:
        if not self._closed:
            try:
                self._call.cancel()
            except Exception:  # noqa: BLE001 - the interpreter may be shutting down
                pass


class Client(_channel.Connection[grpc.Channel]):
    """A connection to reliefd. Use `relief.connect()`; close it (or use it
    as a context manager) when done. Every method raises a ReliefError
    subclass when the call fails, with the server's message.

    `address` is "HOST:PORT" or a URL ("https://HOST:PORT" for TLS);
    RELIEF_SERVER or 127.0.0.1:50051 when None. `token` goes as
    `authorization: Bearer TOKEN` on every call (RELIEF_TOKEN when None;
    "" sends none). `ca` (a PEM file's path, or PEM bytes) is the CA to
    trust and means TLS (RELIEF_CA names one when None); `tls=True` with no
    CA trusts the system's certificates, `tls=False` forces plaintext."""

    #: The channel itself, which `wait_ready` and `close` act on (the one
    #: that sends the token only wraps it).
    _raw: grpc.Channel

    def _open(self, to: _channel.Endpoint) -> grpc.Channel:
        self._raw = _channel.open_channel(to, grpc)
        if to.token is None:
            return self._raw
        return grpc.intercept_channel(self._raw, Bearer(to.token))

    # ------------------------------------------------------------ lifecycle

    def wait_ready(self, timeout: float = 10.0) -> None:
        """Waits until the channel is connected (Unavailable after `timeout`)."""
        try:
            grpc.channel_ready_future(self._raw).result(timeout=timeout)
        except grpc.FutureTimeoutError:
            raise Unavailable(_channel.unreachable(self.endpoint, timeout), method="connect") from None

    def close(self) -> None:
        # (The intercepted channel, when there is one, only wraps this one.)
        self._raw.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        scheme = "https://" if self.endpoint.tls else ""
        return f"relief.Client({scheme + self.address!r})"

    def _unary(self, method: Any, name: str, request: Any, timeout: float | None) -> Any:
        try:
            return method(request, timeout=self.timeout if timeout is None else timeout)
        except grpc.RpcError as e:
            raise from_rpc_error(e, name) from None

    # ------------------------------------------------------------ scene

    def state(self, *, timeout: float | None = None) -> SceneState:
        """The whole scene state at the current generation."""
        r: pb.SceneState = self._unary(self._scene.GetState, "GetState", pb.GetStateRequest(), timeout)
        return _convert.scene_state(r)

    def wait_for_generation(self, generation: int, timeout: float = 30.0) -> SceneState:
        """The state once generation `generation` (or a later one) is served;
        DeadlineExceeded after `timeout` seconds (at most 600)."""
        min_generation, ms = _channel.wait_request(generation, timeout)
        request = pb.WaitForGenerationRequest(min_generation=min_generation, timeout_ms=ms)
        r: pb.SceneState = self._unary(
            self._scene.WaitForGeneration, "WaitForGeneration", request, _channel.deadline_for_wait(timeout)
        )
        return _convert.scene_state(r)

    def events(self, from_generation: int = 0, *, timeout: float | None = None) -> Stream[Event]:
        """Scene events: a SnapshotEvent first, then one event per change
        after `from_generation` (GenerationEvent, SourceErrorEvent,
        ManifestErrorEvent). With `timeout`, the stream ends with
        DeadlineExceeded once that many seconds have passed."""
        call = self._scene.Watch(pb.WatchRequest(from_generation=from_generation), timeout=timeout)
        return Stream(call, _convert.event, "Watch")

    def reload(self, sources: Iterable[str] | None = None, *, timeout: float | None = None) -> SceneState:
        """Re-reads the named sources (all when None) now; the state after."""
        request = pb.ReloadRequest(source_ids=list(sources or ()))
        r: pb.SceneState = self._unary(self._scene.Reload, "Reload", request, timeout)
        return _convert.scene_state(r)

    def set_source_parameter(
        self,
        source_id: str,
        name: str,
        value: object = None,
        *,
        reset: bool = False,
        timeout: float | None = None,
    ) -> SceneState:
        """Sets a parameter as if the manifest said so, checked as the manifest
        is; the state after the new generation, which dirties what it touches.

        ``source_id`` is a source's id (any option but kind, path, paths,
        inputs and layer), ``"[quality]"``, ``"[sun]"`` or
        ``"[effects.NAME]"``. ``value`` is a Python number, bool, string, list
        or dict (sent as TOML) or TOML text; ``reset=True`` puts the
        manifest's value back. A refused value raises ``InvalidArgument``.
        """
        request = _convert.parameter_request(source_id, name, value, reset)
        r: pb.SceneState = self._unary(self._scene.SetSourceParameter, "SetSourceParameter", request, timeout)
        return _convert.scene_state(r)

    # ------------------------------------------------------------ view

    def camera(self, *, timeout: float | None = None) -> Camera:
        """The scene camera."""
        r: pb.Camera = self._unary(self._view.GetCamera, "GetCamera", pb.GetCameraRequest(), timeout)
        return _convert.camera(r)

    def set_camera(self, camera: Camera, *, timeout: float | None = None) -> Camera:
        """Moves the scene camera; answers the camera as set."""
        request = pb.SetCameraRequest(camera=_convert.camera_to_pb(camera))
        r: pb.Camera = self._unary(self._view.SetCamera, "SetCamera", request, timeout)
        return _convert.camera(r)

    def render(
        self,
        camera: Camera | None = None,
        size: tuple[int, int] = (1280, 720),
        *,
        format: ImageFormat | str = ImageFormat.PNG,
        quality: Quality | None = None,
        sun: Sun | None = None,
        timeout: float = _channel.RENDER_TIMEOUT_S,
    ) -> Frame:
        """One frame from `camera` (the scene camera when None), `size` as
        (width, height) pixels, lit by `sun` (a date-time with its UTC offset,
        or (azimuth_deg, elevation_deg); the scene's [sun] when None)."""
        request = _convert.render_request(camera, size, format, quality, sun)
        r: pb.RenderResponse = self._unary(self._view.Render, "Render", request, timeout)
        return _convert.frame(r)

    def frames(
        self,
        camera: Camera | None = None,
        size: tuple[int, int] = (1280, 720),
        *,
        max_fps: float = 10.0,
        format: ImageFormat | str = ImageFormat.PNG,
        quality: Quality | None = None,
        view_id: str | None = None,
        sun: Sun | None = None,
        timeout: float | None = None,
    ) -> Stream[Frame]:
        """Frames of the scene camera (or a fixed `camera`, or an open view):
        one now, then one whenever the generation or the camera changes, at
        most `max_fps`."""
        request = _convert.stream_request(camera, size, format, quality, max_fps, view_id, sun)
        call = self._view.StreamFrames(request, timeout=timeout)
        return Stream(call, _convert.frame, "StreamFrames")

    def open_view(
        self, camera: Camera | None = None, *, follow_scene_camera: bool = False, timeout: float | None = None
    ) -> View:
        """A view of your own (closed a minute after its last stream)."""
        request = _convert.open_view_request(camera, follow_scene_camera)
        r: pb.ViewState = self._unary(self._view.OpenView, "OpenView", request, timeout)
        return _convert.view(r)

    def update_view(
        self,
        view_id: str,
        *,
        camera: Camera | None = None,
        follow_scene_camera: bool | None = None,
        interactive: bool | None = None,
        timeout: float | None = None,
    ) -> View:
        """Changes what is given of a view; None leaves it."""
        request = _convert.update_view_request(view_id, camera, follow_scene_camera, interactive)
        r: pb.ViewState = self._unary(self._view.UpdateView, "UpdateView", request, timeout)
        return _convert.view(r)

    def navigate(self, gesture: Gesture, *, view_id: str | None = None, timeout: float | None = None) -> Camera:
        """Moves a view's camera (the scene camera when view_id is None) by
        a gesture; answers the new camera."""
        request = _convert.navigate_request(gesture, view_id)
        r: pb.Camera = self._unary(self._view.Navigate, "Navigate", request, timeout)
        return _convert.camera(r)

    def pick(self, view_id: str, x: float, y: float, *, timeout: float | None = None) -> Pick:
        """The point under (x, y) (fractions of the image from the top left)
        of a view's last frame."""
        request = pb.PickRequest(view_id=view_id, x=x, y=y)
        r: pb.PickResponse = self._unary(self._view.Pick, "Pick", request, timeout)
        return _convert.pick(r)

    # ------------------------------------------------------------ tiles

    @overload
    def tile(
        self, source: str, level: int, x: int, y: int, *, quality: Quality | None = ..., timeout: float | None = ...
    ) -> Tile: ...

    @overload
    def tile(
        self,
        source: str,
        level: int,
        x: int,
        y: int,
        *,
        expect: type[TileT],
        quality: Quality | None = ...,
        timeout: float | None = ...,
    ) -> TileT: ...

    def tile(
        self,
        source: str,
        level: int,
        x: int,
        y: int,
        *,
        expect: type[TileBase] | None = None,
        quality: Quality | None = None,
        timeout: float | None = None,
    ) -> Tile:
        """Tile (level, x, y) of a source (row 0 is the northernmost): a
        HeightTile, ColorTile, MaskTile, FeatureTile, MeshTile or
        InstanceTile. With `expect` (one of those classes) any other kind
        raises a ReliefError."""
        request = _convert.tile_request(source, level, x, y, quality)
        r: pb.GetTileResponse = self._unary(self._tiles.GetTile, "GetTile", request, timeout)
        return _expect(_convert.tile(r), expect)

    def elevation(
        self,
        points: Iterable[Sequence[float]],
        *,
        source: str | None = None,
        timeout: float | None = None,
    ) -> list[float | None]:
        """Heights at (lon_deg, lat_deg) points from the height layer (or
        `source`); None where there is no data."""
        request = _convert.elevation_request(points, source)
        r: pb.SampleElevationResponse = self._unary(self._tiles.SampleElevation, "SampleElevation", request, timeout)
        return _convert.elevations(r)


def _expect(tile: Tile, expect: type[TileBase] | None) -> Tile:
    if expect is not None and not isinstance(tile, expect):
        raise ReliefError(
            f"tile {tile.level}/{tile.x}/{tile.y} of source '{tile.source_id}' holds {tile.kind.value}, "
            f"not a {expect.__name__}",
            method="GetTile",
            code="CLIENT",
        )
    return tile


def connect(
    address: str | None = None,
    *,
    token: str | None = None,
    ca: str | os.PathLike[str] | bytes | None = None,
    tls: bool | None = None,
    timeout: float = _channel.DEFAULT_TIMEOUT_S,
    connect_timeout: float = 10.0,
    insecure: bool = False,
) -> Client:
    """A client connected to reliefd at `address` ("HOST:PORT", or
    "https://HOST:PORT" for TLS; RELIEF_SERVER or 127.0.0.1:50051 when None).

    `token`: sent as `authorization: Bearer TOKEN` on every call; read from
    RELIEF_TOKEN when None ("" sends none). `ca`: the CA certificate to
    trust (a PEM file's path, or PEM bytes), which means TLS; read from the
    file RELIEF_CA names when None. `tls`: True for TLS with the system's
    certificates, False for plaintext whatever RELIEF_CA says. A token is
    never sent in plaintext to another machine unless `insecure` is True.

    `timeout` is the default deadline of each call; Unavailable when reliefd
    is not reachable within `connect_timeout` (with TLS, also when its
    certificate is not one the CA signed). A missing or wrong token is
    Unauthenticated at the first call; a read token steering the scene is
    PermissionDenied."""
    client = Client(address, timeout=timeout, token=token, ca=ca, tls=tls, insecure=insecure)
    try:
        client.wait_ready(connect_timeout)
    except BaseException:
        client.close()
        raise
    return client
