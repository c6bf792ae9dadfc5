"""The asyncio client: the same calls, awaited (run with asyncio.run, so no
asyncio plugin for pytest is needed)."""

from __future__ import annotations

import asyncio
import math

import numpy as np
import pytest

import relief
import relief.aio
from relief.testing import HillScene, Reliefd, raise_window

PEAK = (10.25, 45.25)
CAMERA = relief.Camera(lon_deg=10.25, lat_deg=45.12, altitude_m=9000, pitch_deg=-45)
SIZE = (160, 120)


def test_every_call_awaited(shared_daemon: Reliefd, shared_scene: HillScene) -> None:
    async def main() -> None:
        async with relief.aio.connect(shared_daemon.address) as client:
            state = await client.state()
            assert state.name == "hill" and state.source("dem").status is relief.SourceStatus.READY
            assert (await client.wait_for_generation(state.generation, timeout=5)).generation >= state.generation
            assert (await client.elevation([PEAK, (0.0, 0.0)])) == [pytest.approx(2000.0, abs=1.0), None]
            col, row = state.grid.tile_at(9, *PEAK)
            heights = await client.tile("dem", 9, col, row, expect=relief.HeightTile)
            assert heights.heights.shape == (state.grid.tile_size + 1, state.grid.tile_size + 1)
            colour = await client.tile("map", 9, col, row)
            assert isinstance(colour, relief.ColorTile) and colour.rgba.shape[2] == 4
            features = await client.tile("parcels", 9, col, row, expect=relief.FeatureTile)
            assert any(f["properties"]["name"] == "summit" for f in features.features)
            mesh = await client.tile("buildings", 9, col, row, expect=relief.MeshTile)
            assert mesh.positions.shape[1] == 3 and mesh.indices.shape[1] == 3
            frame = await client.render(CAMERA, size=SIZE)
            assert frame.to_numpy().shape == (SIZE[1], SIZE[0], 4) and frame.camera == CAMERA
            camera = await client.camera()
            assert camera.lon_deg == pytest.approx(10.25)
            assert (await client.reload(["dem"])).name == "hill"
            async with client.events() as events:
                first = await events.__anext__()
            assert isinstance(first, relief.SnapshotEvent) and first.state.name == "hill"
            async with client.frames(CAMERA, size=SIZE, max_fps=5) as frames:
                async for streamed in frames:
                    assert streamed.camera == CAMERA
                    break
            view = await client.open_view(CAMERA)
            assert (await client.update_view(view.view_id, interactive=True)).interactive
            await client.update_view(view.view_id, interactive=False)
            async with client.frames(size=SIZE, view_id=view.view_id) as frames:
                await frames.__anext__()
            picked = await client.pick(view.view_id, 0.5, 0.5)
            assert picked.hit and picked.ground_height_m is not None
            moved = await client.navigate(relief.Orbit(heading_deg=20.0), view_id=view.view_id)
            assert math.isclose(moved.heading_deg % 360.0, 20.0, abs_tol=1.0)

    asyncio.run(main())


def test_errors_are_relief_errors(shared_daemon: Reliefd) -> None:
    async def main() -> None:
        client = await relief.aio.connect(shared_daemon.address)
        try:
            with pytest.raises(relief.NotFound, match="'nope'"):
                await client.tile("nope", 9, 0, 0)
            with pytest.raises(relief.InvalidArgument, match="lat_deg"):
                await client.render(relief.Camera(10.0, 100.0, 9000.0), size=SIZE)
            generation = (await client.state()).generation
            with pytest.raises(relief.DeadlineExceeded, match="not reached"):
                await client.wait_for_generation(generation + 50, timeout=0.2)
            with pytest.raises(relief.InvalidArgument, match="unknown option"):
                await client.set_source_parameter("dem", "x", 1)
        finally:
            await client.close()

    asyncio.run(main())


def test_unreachable_is_unavailable() -> None:
    async def main() -> None:
        with pytest.raises(relief.Unavailable):
            async with relief.aio.connect("127.0.0.1:9", connect_timeout=0.5):
                pass

    asyncio.run(main())


def test_an_edit_arrives_as_an_event_and_a_frame(relief_scene: HillScene, reliefd: Reliefd) -> None:
    async def main() -> None:
        async with relief.aio.connect(reliefd.address) as client:
            before = await client.state()
            await client.set_camera(CAMERA)
            async with client.events() as events, client.frames(size=SIZE, max_fps=5, timeout=120) as frames:
                snapshot = await events.__anext__()
                assert isinstance(snapshot, relief.SnapshotEvent)
                first = await frames.__anext__()
                col, row = relief_scene.pixel(*PEAK)
                await asyncio.to_thread(raise_window, relief_scene.dem, col - 20, row - 20, 40, 40, 300.0)
                changed = await asyncio.wait_for(_next_generation(events), 30)
                assert changed.generation > before.generation and "dem" in changed.changed_sources
                # Frames follow the generation.
                async def newer() -> relief.Frame:
                    async for f in frames:
                        if f.generation >= changed.generation:
                            return f
                    raise AssertionError("the frame stream ended")

                later = await asyncio.wait_for(newer(), 60)
                assert np.any(later.to_numpy() != first.to_numpy())
            [peak] = await client.elevation([PEAK])
            assert peak == pytest.approx(2300.0, abs=1.0)

    asyncio.run(main())


async def _next_generation(events: relief.aio.AsyncStream[relief.Event]) -> relief.GenerationEvent:
    async for e in events:
        if isinstance(e, relief.GenerationEvent):
            return e
    raise AssertionError("the event stream ended")
