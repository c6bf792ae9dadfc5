"""The asyncio client (grpc.aio): the same calls as relief.Client, awaited.

    async with relief.aio.connect("127.0.0.1:50051") as client:
        state = await client.state()
        async with client.events() as events:
            async for event in events:
                ...
"""

from __future__ import annotations

import asyncio
import os
from collections.abc import AsyncIterator, Callable, Generator, Iterable, Sequence
from types import TracebackType
from typing import Any, Generic, TypeVar, overload

import grpc
import grpc.aio

from relief import _channel, _convert
from relief._bearer import aio_interceptors
from relief._proto.relief.v1 import relief_pb2 as pb
from relief.client import _expect
from relief.errors import Unavailable, from_rpc_error
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

__all__ = ["AsyncClient", "AsyncStream", "Connecting", "connect"]

T = TypeVar("T")
TileT = TypeVar("TileT", bound=Tile)


class AsyncStream(Generic[T]):
    """The messages of a server stream as relief's types: an async iterator,
    and an async context manager that cancels the call on exit."""

    def __init__(self, call: Any, convert: Callable[[Any], T | None], method: str) -> None:
        self._call = call
        self._convert = convert
        self._method = method
        self._closed = False

    def __aiter__(self) -> AsyncIterator[T]:
        return self

    async def __anext__(self) -> T:
        while True:
            try:
                message = await self._call.read()
            except asyncio.CancelledError:
                if self._closed:
                    raise StopAsyncIteration from None
                raise
            except grpc.RpcError as e:
                if self._closed and e.code() == grpc.StatusCode.CANCELLED:
                    raise StopAsyncIteration from None
                raise from_rpc_error(e, self._method) from None
            if message is grpc.aio.EOF:
                raise StopAsyncIteration
            item = self._convert(message)
            if item is not None:
                return item

    def close(self) -> None:
        """Cancels the call."""
        self._closed = True
        self._call.cancel()

    async def __aenter__(self) -> AsyncStream[T]:
        return self

    async def __aexit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


class AsyncClient(_channel.Connection[grpc.aio.Channel]):
    """A connection to reliefd for asyncio code. Use `relief.aio.connect()`
    as an async context manager (or await it, and `await client.close()`).
    `address`, `token`, `ca` and `tls` as for relief.Client: the token
    (RELIEF_TOKEN when None) goes as `authorization: Bearer` on every call,
    a CA (RELIEF_CA when None) or an https:// address means TLS."""

    def _open(self, to: _channel.Endpoint) -> grpc.aio.Channel:
        channel: grpc.aio.Channel = _channel.open_channel(to, grpc.aio, interceptors=aio_interceptors(to.token))
        return channel

    # ------------------------------------------------------------ lifecycle

    async def wait_ready(self, timeout: float = 10.0) -> None:
        """Waits until the channel is connected (Unavailable after `timeout`)."""
        try:
            await asyncio.wait_for(self._channel.channel_ready(), timeout)
        except asyncio.TimeoutError:
            raise Unavailable(_channel.unreachable(self.endpoint, timeout), method="connect") from None

    async def close(self) -> None:
        await self._channel.close()

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self.close()

    def __repr__(self) -> str:
        scheme = "https://" if self.endpoint.tls else ""
        return f"relief.aio.AsyncClient({scheme + self.address!r})"

    async def _unary(self, method: Any, name: str, request: Any, timeout: float | None) -> Any:
        try:
            return await method(request, timeout=self.timeout if timeout is None else timeout)
        except grpc.RpcError as e:
            raise from_rpc_error(e, name) from None

    # ------------------------------------------------------------ scene

    async def state(self, *, timeout: float | None = None) -> SceneState:
        """The whole scene state at the current generation."""
        r: pb.SceneState = await self._unary(self._scene.GetState, "GetState", pb.GetStateRequest(), timeout)
        return _convert.scene_state(r)

    async def wait_for_generation(self, generation: int, timeout: float = 30.0) -> SceneState:
        """The state once generation `generation` is served; DeadlineExceeded
        after `timeout` seconds (at most 600)."""
        min_generation, ms = _channel.wait_request(generation, timeout)
        request = pb.WaitForGenerationRequest(min_generation=min_generation, timeout_ms=ms)
        r: pb.SceneState = await self._unary(
            self._scene.WaitForGeneration, "WaitForGeneration", request, _channel.deadline_for_wait(timeout)
        )
        return _convert.scene_state(r)

    def events(self, from_generation: int = 0, *, timeout: float | None = None) -> AsyncStream[Event]:
        """Scene events: a SnapshotEvent first, then one per change after
        `from_generation`."""
        call = self._scene.Watch(pb.WatchRequest(from_generation=from_generation), timeout=timeout)
        return AsyncStream(call, _convert.event, "Watch")

    async def reload(self, sources: Iterable[str] | None = None, *, timeout: float | None = None) -> SceneState:
        """Re-reads the named sources (all when None) now; the state after."""
        request = pb.ReloadRequest(source_ids=list(sources or ()))
        r: pb.SceneState = await self._unary(self._scene.Reload, "Reload", request, timeout)
        return _convert.scene_state(r)

    async def set_source_parameter(
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
        r: pb.SceneState = await self._unary(self._scene.SetSourceParameter, "SetSourceParameter", request, timeout)
        return _convert.scene_state(r)

    # ------------------------------------------------------------ view

    async def camera(self, *, timeout: float | None = None) -> Camera:
        r: pb.Camera = await self._unary(self._view.GetCamera, "GetCamera", pb.GetCameraRequest(), timeout)
        return _convert.camera(r)

    async def set_camera(self, camera: Camera, *, timeout: float | None = None) -> Camera:
        request = pb.SetCameraRequest(camera=_convert.camera_to_pb(camera))
        r: pb.Camera = await self._unary(self._view.SetCamera, "SetCamera", request, timeout)
        return _convert.camera(r)

    async def render(
        self,
        camera: Camera | None = None,
        size: tuple[int, int] = (1280, 720),
        *,
        format: ImageFormat | str = ImageFormat.PNG,
        quality: Quality | None = None,
        sun: Sun | None = None,
        timeout: float = _channel.RENDER_TIMEOUT_S,
    ) -> Frame:
        request = _convert.render_request(camera, size, format, quality, sun)
        r: pb.RenderResponse = await self._unary(self._view.Render, "Render", request, timeout)
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
    ) -> AsyncStream[Frame]:
        request = _convert.stream_request(camera, size, format, quality, max_fps, view_id, sun)
        call = self._view.StreamFrames(request, timeout=timeout)
        return AsyncStream(call, _convert.frame, "StreamFrames")

    async def open_view(
        self, camera: Camera | None = None, *, follow_scene_camera: bool = False, timeout: float | None = None
    ) -> View:
        request = _convert.open_view_request(camera, follow_scene_camera)
        r: pb.ViewState = await self._unary(self._view.OpenView, "OpenView", request, timeout)
        return _convert.view(r)

    async def update_view(
        self,
        view_id: str,
        *,
        camera: Camera | None = None,
        follow_scene_camera: bool | None = None,
        interactive: bool | None = None,
        timeout: float | None = None,
    ) -> View:
        request = _convert.update_view_request(view_id, camera, follow_scene_camera, interactive)
        r: pb.ViewState = await self._unary(self._view.UpdateView, "UpdateView", request, timeout)
        return _convert.view(r)

    async def navigate(self, gesture: Gesture, *, view_id: str | None = None, timeout: float | None = None) -> Camera:
        request = _convert.navigate_request(gesture, view_id)
        r: pb.Camera = await self._unary(self._view.Navigate, "Navigate", request, timeout)
        return _convert.camera(r)

    async def pick(self, view_id: str, x: float, y: float, *, timeout: float | None = None) -> Pick:
        request = pb.PickRequest(view_id=view_id, x=x, y=y)
        r: pb.PickResponse = await self._unary(self._view.Pick, "Pick", request, timeout)
        return _convert.pick(r)

    # ------------------------------------------------------------ tiles

    @overload
    async def tile(
        self, source: str, level: int, x: int, y: int, *, quality: Quality | None = ..., timeout: float | None = ...
    ) -> Tile: ...

    @overload
    async def tile(
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

    async def tile(
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
        request = _convert.tile_request(source, level, x, y, quality)
        r: pb.GetTileResponse = await self._unary(self._tiles.GetTile, "GetTile", request, timeout)
        return _expect(_convert.tile(r), expect)

    async def elevation(
        self,
        points: Iterable[Sequence[float]],
        *,
        source: str | None = None,
        timeout: float | None = None,
    ) -> list[float | None]:
        request = _convert.elevation_request(points, source)
        r: pb.SampleElevationResponse = await self._unary(
            self._tiles.SampleElevation, "SampleElevation", request, timeout
        )
        return _convert.elevations(r)


class Connecting:
    """What `connect()` answers: `async with` it, or await it."""

    def __init__(self, make: Callable[[], AsyncClient], connect_timeout: float) -> None:
        self._make = make
        self._connect_timeout = connect_timeout
        self._client: AsyncClient | None = None

    async def _open(self) -> AsyncClient:
        client = self._make()
        try:
            await client.wait_ready(self._connect_timeout)
        except BaseException:
            await client.close()
            raise
        return client

    def __await__(self) -> Generator[Any, None, AsyncClient]:
        return self._open().__await__()

    async def __aenter__(self) -> AsyncClient:
        self._client = await self._open()
        return self._client

    async def __aexit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self._client is not None:
            await self._client.close()
            self._client = None


def connect(
    address: str | None = None,
    *,
    token: str | None = None,
    ca: str | os.PathLike[str] | bytes | None = None,
    tls: bool | None = None,
    timeout: float = _channel.DEFAULT_TIMEOUT_S,
    connect_timeout: float = 10.0,
    insecure: bool = False,
) -> Connecting:
    """An asyncio client connected to reliefd at `address`:
    `async with relief.aio.connect(addr) as client:` or
    `client = await relief.aio.connect(addr)`. The arguments are
    relief.connect's: `token` (RELIEF_TOKEN when None) goes as
    `authorization: Bearer` on every call; `ca` (RELIEF_CA when None) or an
    https:// address means TLS."""
    # Checked now: a bad address, CA or token fails at the call, not at await.
    _channel.endpoint(address, token=token, ca=ca, tls=tls, insecure=insecure)
    return Connecting(
        lambda: AsyncClient(address, timeout=timeout, token=token, ca=ca, tls=tls, insecure=insecure), connect_timeout
    )
