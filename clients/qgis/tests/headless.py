"""Headless QGIS for the plugin's tests and its benchmark: one
QgsApplication (offscreen Qt, settings in a temporary folder), the plugin
installed from the zip `make qgis-plugin` builds (unpacked into a plugins
folder on sys.path, so tests of its modules import that copy too), a host
window with a real map canvas standing in for the QGIS desktop around the
plugin, and the plugin started the way QGIS starts plugins (qgis.utils).

Import it before anything else from Qt: it makes the application."""

from __future__ import annotations

import atexit
import os
import shutil
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from qgis.core import QgsApplication, QgsProject, QgsSettings  # noqa: E402
from qgis.gui import QgsLayerTreeMapCanvasBridge, QgsMapCanvas  # noqa: E402
from qgis.PyQt.QtCore import QCoreApplication, QSettings, Qt  # noqa: E402
from qgis.PyQt.QtTest import QTest  # noqa: E402
from qgis.PyQt.QtWidgets import QDockWidget, QMainWindow, QMenu  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
import package  # noqa: E402

PLUGIN = package.PLUGIN

_SETTINGS = tempfile.mkdtemp(prefix="relief-qgis-settings-")
atexit.register(shutil.rmtree, _SETTINGS, True)
QCoreApplication.setOrganizationName("relief-tests")
QCoreApplication.setApplicationName("relief-qgis-tests")
QSettings.setDefaultFormat(QSettings.IniFormat)
QSettings.setPath(QSettings.IniFormat, QSettings.UserScope, _SETTINGS)
_APP = QgsApplication([], True)
_APP.initQgis()

_PLUGINS = Path(tempfile.mkdtemp(prefix="relief-qgis-plugins-"))
atexit.register(shutil.rmtree, _PLUGINS, True)
PLUGIN_ZIP = package.build(_PLUGINS / f"{PLUGIN}.zip")
PLUGINS_DIR = _PLUGINS / "plugins"
with zipfile.ZipFile(PLUGIN_ZIP) as _z:
    _z.extractall(PLUGINS_DIR)
sys.path.insert(0, str(PLUGINS_DIR))


def wait_for(condition: Callable[[], Any], timeout: float) -> Any:
    """Runs Qt's event loop until `condition()` is truthy (returns it) or
    `timeout` seconds pass (returns None)."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            return None
        QTest.qWait(5)


class Host:
    """The part of QGIS's QgisInterface the plugin calls, over a real main
    window and a real map canvas fed from the project's layer tree."""

    def __init__(self) -> None:
        self.window = QMainWindow()
        self.canvas = QgsMapCanvas(self.window)
        self.window.setCentralWidget(self.canvas)
        # A child of the window: it goes with the canvas it feeds (left
        # behind, it would set layers on a deleted canvas when the next
        # test's project changes).
        self.bridge = QgsLayerTreeMapCanvasBridge(QgsProject.instance().layerTreeRoot(), self.canvas, self.window)
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
        self.bridge.deleteLater()
        self.window.close()
        self.window.deleteLater()


def start_plugin(host: Host, address: str, token: str = "", ca_file: str = "") -> Any:
    """Starts the installed plugin with qgis.utils, as QGIS does, talking
    to reliefd at `address` with `token` (none when empty) and trusting the
    CA certificates in `ca_file` too; returns the plugin object."""
    import qgis.utils

    qgis.utils.iface = host
    settings = QgsSettings()
    settings.setValue(f"{PLUGIN}/address", address)
    settings.setValue(f"{PLUGIN}/token", token)
    settings.setValue(f"{PLUGIN}/ca_file", ca_file)
    settings.setValue(f"{PLUGIN}/follow", False)
    return load_plugin()


def load_plugin() -> Any:
    """Loads and starts the installed plugin as QGIS does, with the
    settings as they are (a plugin reload, or QGIS started again)."""
    import qgis.utils

    qgis.utils.plugin_paths = [str(PLUGINS_DIR)]
    qgis.utils.updateAvailablePlugins()
    if PLUGIN not in qgis.utils.available_plugins:
        raise RuntimeError(f"QGIS does not find the plugin's metadata in {PLUGINS_DIR}")
    if not qgis.utils.loadPlugin(PLUGIN):
        raise RuntimeError("QGIS could not load the plugin")
    if not qgis.utils.startPlugin(PLUGIN):
        raise RuntimeError("QGIS could not start the plugin")
    return qgis.utils.plugins[PLUGIN]


def stop_plugin() -> None:
    import qgis.utils

    qgis.utils.unloadPlugin(PLUGIN)


def qgis_version() -> str:
    from qgis.core import Qgis

    return str(Qgis.QGIS_VERSION)
