"""Headless PyQGIS for the plugin's tests: one QgsApplication (offscreen Qt,
settings in a temporary folder), a host window with a real map canvas
standing in for the QGIS desktop around the plugin, the plugin installed
from the zip `make qgis-plugin` builds and started the way QGIS starts
plugins (qgis.utils), and a real reliefd serving relief.testing's hill
scene (its parcels shapefile is the layer the tests edit)."""

from __future__ import annotations

import atexit
import os
import shutil
import sys
import tempfile
import time
import traceback
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path
from types import TracebackType
from typing import Any

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
_SETTINGS = tempfile.mkdtemp(prefix="relief-qgis-settings-")
atexit.register(shutil.rmtree, _SETTINGS, True)

from qgis.core import QgsApplication, QgsProject, QgsVectorLayer  # noqa: E402
from qgis.gui import QgsLayerTreeMapCanvasBridge, QgsMapCanvas  # noqa: E402
from qgis.PyQt.QtCore import QCoreApplication, QSettings, Qt  # noqa: E402
from qgis.PyQt.QtTest import QTest  # noqa: E402
from qgis.PyQt.QtWidgets import QDockWidget, QMainWindow, QMenu  # noqa: E402

from relief.testing import HillScene, Reliefd, write_hill_scene  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "scripts"))
import package  # noqa: E402

PLUGIN = "relief_qgis"

QCoreApplication.setOrganizationName("relief-tests")
QCoreApplication.setApplicationName("relief-qgis-tests")
QSettings.setDefaultFormat(QSettings.IniFormat)
QSettings.setPath(QSettings.IniFormat, QSettings.UserScope, _SETTINGS)
_APP = QgsApplication([], True)
_APP.initQgis()


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
    """Runs Qt's event loop until `condition()` is truthy (returns it) or
    `timeout` seconds pass (fails, saying `what` did not happen)."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"{what}: not within {timeout} s")
        QTest.qWait(20)


class Host:
    """The part of QGIS's QgisInterface the plugin calls, over a real main
    window and a real map canvas fed from the project's layer tree."""

    def __init__(self) -> None:
        self.window = QMainWindow()
        self.canvas = QgsMapCanvas(self.window)
        self.window.setCentralWidget(self.canvas)
        self.bridge = QgsLayerTreeMapCanvasBridge(QgsProject.instance().layerTreeRoot(), self.canvas)
        self.menus: dict[str, QMenu] = {}
        self.window.resize(1200, 800)
        self.window.show()

    def mainWindow(self) -> QMainWindow:  # noqa: N802 (QGIS's names)
        return self.window

    def mapCanvas(self) -> QgsMapCanvas:  # noqa: N802
        return self.canvas

    def addDockWidget(self, area: Qt.DockWidgetArea, dock: QDockWidget) -> None:  # noqa: N802
        self.window.addDockWidget(area, dock)

    def removeDockWidget(self, dock: QDockWidget) -> None:  # noqa: N802
        self.window.removeDockWidget(dock)

    def addPluginToMenu(self, name: str, action: Any) -> None:  # noqa: N802
        if name not in self.menus:
            self.menus[name] = self.window.menuBar().addMenu(name)
        self.menus[name].addAction(action)

    def removePluginMenu(self, name: str, action: Any) -> None:  # noqa: N802
        if name in self.menus:
            self.menus[name].removeAction(action)

    def close(self) -> None:
        self.window.close()
        self.window.deleteLater()


# The plugin as QGIS installs it: the zip `make qgis-plugin` builds,
# unpacked into a plugins folder on sys.path (the tests of its modules
# import this copy too).
_PLUGINS = Path(tempfile.mkdtemp(prefix="relief-qgis-plugins-"))
atexit.register(shutil.rmtree, _PLUGINS, True)
PLUGIN_ZIP = package.build(_PLUGINS / f"{PLUGIN}.zip")
with zipfile.ZipFile(PLUGIN_ZIP) as _z:
    _z.extractall(_PLUGINS / "plugins")
sys.path.insert(0, str(_PLUGINS / "plugins"))


@pytest.fixture
def scene(tmp_path: Path) -> HillScene:
    return write_hill_scene(tmp_path / "scene")


@pytest.fixture
def daemon(scene: HillScene) -> Iterator[Reliefd]:
    d = Reliefd(scene.manifest)
    d.start()
    try:
        yield d
    finally:
        d.stop()


@pytest.fixture
def host() -> Iterator[Host]:
    import qgis.utils

    h = Host()
    qgis.utils.iface = h
    try:
        yield h
    finally:
        QgsProject.instance().removeAllMapLayers()
        h.close()
        qgis.utils.iface = None


@pytest.fixture
def start_plugin(host: Host) -> Iterator[Callable[[str], Any]]:
    """Starts the plugin with qgis.utils, as QGIS does, talking to the
    given address; unloads it afterwards."""
    import qgis.utils
    from qgis.core import QgsSettings

    started = []

    def start(address: str) -> Any:
        QgsSettings().setValue(f"{PLUGIN}/address", address)
        qgis.utils.plugin_paths = [str(_PLUGINS / "plugins")]
        qgis.utils.updateAvailablePlugins()
        assert PLUGIN in qgis.utils.available_plugins, "QGIS does not find the plugin's metadata"
        assert qgis.utils.loadPlugin(PLUGIN), "QGIS could not load the plugin"
        assert qgis.utils.startPlugin(PLUGIN), "QGIS could not start the plugin"
        started.append(True)
        return qgis.utils.plugins[PLUGIN]

    try:
        yield start
    finally:
        if started:
            qgis.utils.unloadPlugin(PLUGIN)


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
