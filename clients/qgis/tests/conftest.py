"""Fixtures for the plugin's tests in headless QGIS (see headless.py) and
a real reliefd serving relief.testing's hill scene (its parcels shapefile
is the layer the tests edit)."""

from __future__ import annotations

import sys
import traceback
from collections.abc import Callable, Iterator
from types import TracebackType
from typing import Any

import pytest
from headless import PLUGIN, PLUGIN_ZIP, Host, start_plugin as _start, stop_plugin, wait_for  # noqa: F401
from qgis.core import QgsProject, QgsVectorLayer

from relief.testing import HillScene, Reliefd

# An exception in a slot would make PyQt abort the process: keep it and
# fail the test it happened in instead (QGIS shows such errors the same way).
_SLOT_ERRORS: list[str] = []


def _keep_slot_error(kind: type[BaseException], value: BaseException, tb: TracebackType | None) -> None:
    _SLOT_ERRORS.append("".join(traceback.format_exception(kind, value, tb)))


sys.excepthook = _keep_slot_error


@pytest.fixture(autouse=True)
def no_slot_errors() -> Iterator[None]:
    _SLOT_ERRORS.clear()
    yield
    assert not _SLOT_ERRORS, "a slot raised:\n" + "\n".join(_SLOT_ERRORS)


def wait_until(condition: Callable[[], Any], timeout: float, what: str) -> Any:
    """Runs Qt's event loop until `condition()` is truthy (returns it);
    fails the test, saying `what` did not happen, after `timeout` seconds."""
    value = wait_for(condition, timeout)
    if not value:
        pytest.fail(f"{what}: not within {timeout} s")
    return value


@pytest.fixture
def scene(relief_scene: HillScene) -> HillScene:
    """relief.testing's hill scene (its pytest plugin's `relief_scene`)."""
    return relief_scene


@pytest.fixture
def daemon(reliefd: Reliefd) -> Reliefd:
    """reliefd serving it (relief.testing's `reliefd`)."""
    return reliefd


@pytest.fixture
def host() -> Iterator[Host]:
    import qgis.utils

    h = Host()
    try:
        yield h
    finally:
        QgsProject.instance().removeAllMapLayers()
        h.close()
        qgis.utils.iface = None


@pytest.fixture
def start_plugin(host: Host) -> Iterator[Callable[..., Any]]:
    """Starts the plugin as QGIS does, talking to the given address (with
    a token and a CA file when given); unloads it afterwards."""
    started = []

    def start(address: str, token: str = "", ca_file: str = "") -> Any:
        plugin = _start(host, address, token, ca_file)
        started.append(plugin)
        return plugin

    try:
        yield start
    finally:
        if started:
            stop_plugin()


@pytest.fixture
def plugin(start_plugin: Callable[[str], Any], daemon: Reliefd) -> Any:
    """The plugin, started against `daemon`, showing its first frame."""
    p = start_plugin(daemon.address)
    wait_until(lambda: p.dock.frames_shown > 0, 60, "the dock shows a frame")
    return p


@pytest.fixture
def parcels_layer(scene: HillScene) -> QgsVectorLayer:
    """The scene's parcels shapefile, opened in the project."""
    layer = QgsVectorLayer(str(scene.parcels), "parcels", "ogr")
    assert layer.isValid(), f"QGIS cannot open {scene.parcels}"
    QgsProject.instance().addMapLayer(layer)
    return layer
