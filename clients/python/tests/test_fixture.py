"""The pytest plugin's fixtures and edit helpers, and the events that edits
bring, against a real reliefd."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import relief
from relief.testing import (
    PARCELS,
    HillScene,
    Reliefd,
    add_feature,
    feature_count,
    find_reliefd,
    move_vertex,
    pixel_of,
    raise_window,
    read_window,
    write_hill_scene,
    write_window,
)

PEAK = (10.25, 45.25)


class Collector:
    """Every event of a Watch stream, gathered on a thread."""

    def __init__(self, client: relief.Client) -> None:
        self.events: list[relief.Event] = []
        self._stream = client.events(timeout=120)
        first = next(self._stream)
        assert isinstance(first, relief.SnapshotEvent)
        self.events.append(first)
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            for event in self._stream:
                with self._lock:
                    self.events.append(event)
        except relief.ReliefError:
            pass

    def wait_for(self, what: Callable[[relief.Event], bool], timeout: float = 30.0) -> relief.Event:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                for e in self.events:
                    if what(e):
                        return e
            time.sleep(0.02)
        raise AssertionError(f"no such event within {timeout} s; got {self.events!r}")

    def close(self) -> None:
        self._stream.close()
        self._thread.join(5.0)


def until(client: relief.Client, check: Callable[[], bool], timeout: float = 30.0) -> None:
    """Waits, generation by generation, until `check()` holds."""
    deadline = time.monotonic() + timeout
    while not check():
        left = deadline - time.monotonic()
        assert left > 0, "not reached in time"
        try:
            client.wait_for_generation(client.state().generation + 1, timeout=left)
        except relief.DeadlineExceeded:
            assert check(), "not reached in time"
            return


def test_the_fixture_serves_the_hill_scene(
    relief_client: relief.Client, relief_scene: HillScene, reliefd: Reliefd
) -> None:
    assert relief_scene.manifest.is_file() and relief_scene.dem.is_file()
    for ext in (".shp", ".shx", ".dbf", ".prj"):
        assert relief_scene.parcels.with_suffix(ext).is_file(), ext
    assert feature_count(relief_scene.parcels) == len(PARCELS)
    assert reliefd.is_running() and reliefd.address.startswith("127.0.0.1:")
    assert reliefd.viewer_url.startswith("http://127.0.0.1:")
    assert relief_client.address == reliefd.address
    state = relief_client.state()
    assert state.name == "hill"
    assert all(s.status is relief.SourceStatus.READY for s in state.sources), [(s.id, s.error) for s in state.sources]
    assert relief_scene.pixel(*PEAK) == (200, 200)
    assert pixel_of(relief_scene.dem, *PEAK) == (200, 200)
    assert relief_scene.centre(0, 0) == pytest.approx((10.000625, 45.499375))


def test_the_daemon_stops_on_sigterm(relief_scene: HillScene) -> None:
    with Reliefd(relief_scene.manifest) as daemon:
        with daemon.connect() as client:
            assert client.state().name == "hill"
        pid = daemon.pid
    assert not daemon.is_running()
    assert daemon.stop() == 0
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)
    assert any("serving" in line for line in daemon.log), daemon.log_text()
    assert daemon.problems() == [], daemon.log_text()


def test_the_binary_is_found(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    found = find_reliefd()
    assert found.is_file()
    monkeypatch.setenv("RELIEF_BIN", str(tmp_path / "missing"))
    with pytest.raises(FileNotFoundError, match="RELIEF_BIN"):
        find_reliefd()


def test_a_bad_manifest_stops_the_start_with_its_error(tmp_path: Path) -> None:
    scene = write_hill_scene(tmp_path / "scene")
    scene.manifest.write_text(scene.manifest.read_text().replace('path = "hill.tif"', 'path = "missing.tif"'))
    with pytest.raises(RuntimeError, match="reliefd did not start") as caught:
        Reliefd(scene.manifest, start_timeout=30).start()
    assert "source 'dem'" in str(caught.value)


def test_raster_window_edits_become_a_generation_with_dirty_extents(
    relief_client: relief.Client, relief_scene: HillScene
) -> None:
    events = Collector(relief_client)
    try:
        before = relief_client.state()
        col, row = relief_scene.pixel(*PEAK)
        written = raise_window(relief_scene.dem, col - 10, row - 10, 20, 20, by_m=250.0)
        assert np.allclose(read_window(relief_scene.dem, col - 10, row - 10, 20, 20), written)
        changed = events.wait_for(lambda e: isinstance(e, relief.GenerationEvent) and "dem" in e.changed_sources)
        assert isinstance(changed, relief.GenerationEvent)
        assert changed.generation > before.generation
        assert changed.elapsed_ms >= 0 and changed.reason
        dirty = {d.source_id: d.extents for d in changed.dirty}
        assert "dem" in dirty and dirty["dem"]
        assert any(e.contains(*PEAK) for e in dirty["dem"]), dirty["dem"]
        # Only blocks near the edit are dirty, never the whole DEM.
        assert all(e.width < 0.5 for e in dirty["dem"])
        assert changed.tiles_rebuilt + changed.tiles_invalidated + changed.tiles_carried_over >= 0
        after = relief_client.wait_for_generation(changed.generation, timeout=10)
        assert after.source("dem").version > before.source("dem").version
        assert relief_client.elevation([PEAK])[0] == pytest.approx(relief_scene.height(*PEAK) + 250.0, abs=1.0)
        # A second edit, written whole: the next generation that names the
        # DEM serves the new data.
        write_window(relief_scene.dem, col - 1, row - 1, np.full((2, 2), 100.0))
        again = events.wait_for(
            lambda e: isinstance(e, relief.GenerationEvent)
            and e.generation > changed.generation
            and "dem" in e.changed_sources
        )
        relief_client.wait_for_generation(again.generation, timeout=10)
        assert relief_client.elevation([PEAK])[0] == pytest.approx(100.0, abs=1.0)
    finally:
        events.close()


def test_shapefile_edits_in_place_reach_feature_tiles(relief_client: relief.Client, relief_scene: HillScene) -> None:
    state = relief_client.state()
    col, row = state.grid.tile_at(9, *PEAK)

    def names() -> dict[str, dict[str, object]]:
        tile = relief_client.tile("parcels", 9, col, row, expect=relief.FeatureTile)
        return {str(f["properties"]["name"]): f for f in tile.features}

    assert "summit" in names() and "hut" not in names()
    # Move the summit parcel's first vertex (and so its closing one) west.
    summit = next(i for i, (name, _, _) in enumerate(PARCELS) if name == "summit")
    x, y = move_vertex(relief_scene.parcels, summit, 0, -0.01, 0.0)
    assert (x, y) == pytest.approx((10.22, 45.23))

    def west_edge() -> float:
        ring = names()["summit"]["geometry"]
        assert isinstance(ring, dict)
        return float(np.asarray(ring["coordinates"], dtype=float).reshape(-1, 2)[:, 0].min())

    state = relief_client.wait_for_generation(state.generation + 1, timeout=30)
    until(relief_client, lambda: west_edge() == pytest.approx(10.22))
    # Add a feature, as QGIS appends one.
    fid = add_feature(
        relief_scene.parcels,
        [(10.26, 45.26), (10.265, 45.26), (10.265, 45.265), (10.26, 45.265)],
        {"name": "hut", "height": 5.0},
    )
    assert fid == len(PARCELS)
    assert feature_count(relief_scene.parcels) == len(PARCELS) + 1
    relief_client.wait_for_generation(state.generation + 1, timeout=30)
    until(relief_client, lambda: "hut" in names())
    assert relief_client.state().source("parcels").status is relief.SourceStatus.READY


def test_a_broken_file_is_a_source_error_and_the_last_good_version_stays(
    relief_client: relief.Client, relief_scene: HillScene
) -> None:
    events = Collector(relief_client)
    try:
        good = relief_scene.dem.read_bytes()
        relief_scene.dem.write_bytes(b"this is not a GeoTIFF")
        error = events.wait_for(lambda e: isinstance(e, relief.SourceErrorEvent))
        assert isinstance(error, relief.SourceErrorEvent)
        assert error.source_id == "dem" and error.kept_last_good and error.error
        state = relief_client.state()
        assert state.source("dem").status is relief.SourceStatus.ERROR
        assert state.source("dem").error
        assert relief_client.elevation([PEAK])[0] == pytest.approx(2000.0, abs=1.0), "last good version"
        # Restored as it was: the source is healthy again (its data did not
        # change, so no generation needs to name it).
        relief_scene.dem.write_bytes(good)
        deadline = time.monotonic() + 30
        while relief_client.state().source("dem").status is not relief.SourceStatus.READY:
            assert time.monotonic() < deadline, relief_client.state().source("dem").error
            time.sleep(0.05)
    finally:
        events.close()


def test_a_bad_manifest_edit_is_a_manifest_error(relief_client: relief.Client, relief_scene: HillScene) -> None:
    events = Collector(relief_client)
    try:
        text = relief_scene.manifest.read_text()
        relief_scene.manifest.write_text(text.replace('inputs = ["dem"]', 'inputs = ["no-such-source"]'))
        error = events.wait_for(lambda e: isinstance(e, relief.ManifestErrorEvent))
        assert isinstance(error, relief.ManifestErrorEvent)
        assert "no-such-source" in error.error
        state = relief_client.state()
        assert "no-such-source" in state.manifest_error
        assert state.source("shade").inputs == ("dem",), "the scene stays as it was"
        relief_scene.manifest.write_text(text)
    finally:
        events.close()
