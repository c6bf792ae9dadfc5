"""gRPC errors become relief exceptions that carry the server's message."""

from __future__ import annotations

import math
import socket
import time

import pytest

import relief

PEAK = (10.25, 45.25)


def test_an_unknown_source_is_not_found(shared_client: relief.Client) -> None:
    with pytest.raises(relief.NotFound, match="no source has id 'nope'") as caught:
        shared_client.tile("nope", 9, 0, 0)
    error = caught.value
    assert isinstance(error, relief.ReliefError)
    assert error.code == "NOT_FOUND" and error.method == "GetTile"
    assert "no source has id 'nope'" in error.message
    assert str(error).startswith("NOT_FOUND (GetTile): ")
    with pytest.raises(relief.NotFound, match="'nope'"):
        shared_client.elevation([PEAK], source="nope")
    with pytest.raises(relief.NotFound, match="'nope'"):
        shared_client.reload(["dem", "nope"])


@pytest.mark.parametrize(
    ("camera", "field"),
    [
        (relief.Camera(10.25, 95.0, 9000.0), "lat_deg"),
        (relief.Camera(10.25, math.nan, 9000.0), "lat_deg"),
        (relief.Camera(10.25, 45.1, 9000.0, vertical_fov_deg=0.0), "vertical_fov_deg"),
    ],
)
def test_a_bad_camera_is_an_invalid_argument_naming_the_field(
    shared_client: relief.Client, camera: relief.Camera, field: str
) -> None:
    with pytest.raises(relief.InvalidArgument, match=f"field '{field}'") as caught:
        shared_client.render(camera, size=(64, 48))
    assert caught.value.code == "INVALID_ARGUMENT"
    with pytest.raises(relief.InvalidArgument, match=f"field '{field}'"):
        shared_client.open_view(camera)


def test_a_bad_request_field_is_named(shared_client: relief.Client) -> None:
    with pytest.raises(relief.InvalidArgument, match="'width'"):
        shared_client.render(size=(5000, 100))
    with pytest.raises(relief.InvalidArgument, match=r"points\[1\]"):
        shared_client.elevation([PEAK, (10.0, 120.0)])
    with pytest.raises(relief.InvalidArgument, match="max_fps"):
        next(iter(shared_client.frames(size=(64, 48), max_fps=1000.0)))


def test_setting_a_bad_scene_camera_is_refused(relief_client: relief.Client) -> None:
    before = relief_client.camera()
    with pytest.raises(relief.InvalidArgument, match="lat_deg"):
        relief_client.set_camera(relief.Camera(10.25, -91.0, 9000.0))
    assert relief_client.camera() == before


def test_waiting_past_the_timeout_is_deadline_exceeded(shared_client: relief.Client) -> None:
    generation = shared_client.state().generation
    started = time.monotonic()
    with pytest.raises(relief.DeadlineExceeded, match=f"generation {generation + 100} not reached") as caught:
        shared_client.wait_for_generation(generation + 100, timeout=0.3)
    assert time.monotonic() - started < 10.0
    assert caught.value.method == "WaitForGeneration"


def test_a_view_that_is_not_open_is_not_found(shared_client: relief.Client) -> None:
    with pytest.raises(relief.NotFound):
        shared_client.pick("no-such-view", 0.5, 0.5)
    with pytest.raises(relief.NotFound):
        shared_client.update_view("no-such-view", interactive=True)


def test_no_daemon_is_unavailable() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    # Nothing listens there now.
    with pytest.raises(relief.Unavailable, match=f"127.0.0.1:{port}"):
        relief.connect(f"127.0.0.1:{port}", connect_timeout=0.5)
    client = relief.Client(f"http://127.0.0.1:{port}", timeout=2.0)
    assert client.address == f"127.0.0.1:{port}"
    with pytest.raises(relief.Unavailable), client:
        client.state()


def test_bad_arguments_fail_before_the_call(shared_client: relief.Client) -> None:
    with pytest.raises(ValueError, match="format"):
        shared_client.render(size=(64, 48), format="gif")
    with pytest.raises(ValueError, match="lon_deg, lat_deg"):
        shared_client.elevation([(10.0, 45.0, 3.0)])
    with pytest.raises(ValueError, match="negative"):
        shared_client.wait_for_generation(-1)
