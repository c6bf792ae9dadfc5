"""The plugin: wires the dock, the daemon link, the map canvas and the
project's layers together. Nothing here blocks QGIS: every call to reliefd
answers later on the event loop.

Follow map is applied again whenever the daemon becomes reachable (a
reconnect, a new address): a daemon that restarted has its own camera.
When the ground height at the map's centre is not known (the lookup
failed, timed out, or the height layer has no data there), the camera is
not moved: a guessed ground (0 m, or a height from elsewhere) could put it
under the terrain and draw a black frame. The dock says why, and the next
map move or reconnect tries again. (A scene whose state names no height
layer has its ground at 0 m: there is nothing to look up.)"""

from __future__ import annotations

from typing import Any, Callable, Optional

from qgis.core import QgsMapLayer, QgsProject, QgsSettings, QgsVectorLayer
from qgis.PyQt.QtCore import QObject, Qt, QTimer
from qgis.PyQt.QtWidgets import QAction

from . import proto_json as pj
from .dock import ReliefDock
from .edits import layer_file, sources_reading
from .follow import camera_for, map_view
from .link import DEFAULT_ADDRESS, DaemonLink

#: Where the daemon's address is kept between sessions.
ADDRESS_KEY = "relief_qgis/address"
#: The bearer token a reliefd serving with --token-file wants (empty: none),
#: kept in QGIS's settings file like the address.
TOKEN_KEY = "relief_qgis/token"
#: A PEM file of CA certificates to trust for an https:// address, beside
#: the system's (empty: the system's only).
CA_FILE_KEY = "relief_qgis/ca_file"
#: Whether Follow map is on, kept like the address.
FOLLOW_KEY = "relief_qgis/follow"
#: How long the map must rest before the camera follows it (ms).
FOLLOW_DEBOUNCE_MS = 150
#: How long a slider must rest before the camera turns (ms).
SLIDER_DEBOUNCE_MS = 100


def _debounced(ms: int, action: Callable[[], None]) -> QTimer:
    timer = QTimer()
    timer.setSingleShot(True)
    timer.setInterval(ms)
    timer.timeout.connect(action)
    return timer


class ReliefPlugin:
    """relief's live 3D view in QGIS (classFactory's answer)."""

    def __init__(self, iface: Any) -> None:
        self.iface = iface
        self.link: Optional[DaemonLink] = None
        self.dock: Optional[ReliefDock] = None
        self.action: Optional[QAction] = None
        #: The last scene state (GetState as JSON).
        self.state: dict = {}
        #: Reloads asked for after commits, and follow cameras sent.
        self.reloads_requested = 0
        #: Ask for a reload when a layer the scene reads is committed (off:
        #: the daemon's file watcher alone takes the edit, after it settles).
        self.reload_on_commit = True
        self.cameras_sent = 0
        #: Follow map's last word when it could not move the camera ("" when it could).
        self.follow_problem = ""
        self._camera: dict = {}
        self._follow_serial = 0
        self._turn_serial = 0
        #: Vector layers watched for commits, with the slot connected.
        self._layers: dict[str, tuple[QgsVectorLayer, Callable[[], None]]] = {}
        self._follow_timer = _debounced(FOLLOW_DEBOUNCE_MS, self._follow_now)
        self._turn_timer = _debounced(SLIDER_DEBOUNCE_MS, self._turn_now)

    # ------------------------------------------------------------ QGIS hooks

    def initGui(self) -> None:  # noqa: N802 (QGIS's name)
        settings = QgsSettings()
        address = str(settings.value(ADDRESS_KEY, DEFAULT_ADDRESS))
        token = str(settings.value(TOKEN_KEY, "") or "")
        ca_file = str(settings.value(CA_FILE_KEY, "") or "")
        follow = _setting_bool(settings.value(FOLLOW_KEY, False))
        window = self.iface.mainWindow()
        self.link = DaemonLink(address, token=token, ca_file=ca_file)
        self.dock = ReliefDock(address, window, token=token, ca_file=ca_file, follow=follow)
        self.dock.show_address_note(self.link.address_note)
        self.iface.addDockWidget(Qt.RightDockWidgetArea, self.dock)

        # The dock's own show/hide action: it stays right when the dock is
        # tabbed with other panels (hidden behind a tab is not closed).
        self.action = self.dock.toggleViewAction()
        self.action.setText("relief 3D view")
        self.iface.addPluginToMenu("&relief", self.action)

        link, dock = self.link, self.dock
        link.frame.connect(self._frame)
        link.state.connect(self._state)
        link.reachable.connect(self._reachable)
        link.failed.connect(dock.show_message)
        dock.address_changed.connect(self._address_changed)
        dock.credentials_changed.connect(self._credentials_changed)
        dock.reload_clicked.connect(lambda: link.reload([], self._state))
        dock.retry_clicked.connect(link.retry_now)
        # Frames only while the dock shows (closed, or a tab behind another).
        dock.visibilityChanged.connect(link.set_frames_wanted)
        dock.frame_size_changed.connect(link.set_frame_size)
        dock.follow_toggled.connect(self._follow_toggled)
        dock.pitch_changed.connect(self._slider_moved)
        dock.heading_changed.connect(self._slider_moved)
        dock.dragging.connect(link.set_interactive)

        canvas = self.iface.mapCanvas()
        canvas.extentsChanged.connect(self._map_moved)
        canvas.rotationChanged.connect(self._map_moved)
        canvas.destinationCrsChanged.connect(self._map_moved)

        project = QgsProject.instance()
        project.layersAdded.connect(self._watch_layers)
        project.layersWillBeRemoved.connect(self._forget_layers)
        self._watch_layers(list(project.mapLayers().values()))

        link.start()

    def unload(self) -> None:
        self._follow_timer.stop()
        self._turn_timer.stop()
        if self.link is not None:
            self.link.stop()
            self.link.deleteLater()
        canvas = self.iface.mapCanvas()
        project = QgsProject.instance()
        for signal, slot in (
            (canvas.extentsChanged, self._map_moved),
            (canvas.rotationChanged, self._map_moved),
            (canvas.destinationCrsChanged, self._map_moved),
            (project.layersAdded, self._watch_layers),
            (project.layersWillBeRemoved, self._forget_layers),
        ):
            try:
                signal.disconnect(slot)
            except TypeError:
                pass
        for layer_id in list(self._layers):
            self._forget_layers([layer_id])
        if self.action is not None:
            self.iface.removePluginMenu("&relief", self.action)
        if self.dock is not None:
            # Nothing it says once gone reaches the link or the settings
            # (a line edit losing focus as it goes says "editing finished").
            self.dock.blockSignals(True)
            for child in self.dock.findChildren(QObject):
                child.blockSignals(True)
            self.iface.removeDockWidget(self.dock)
            self.dock.deleteLater()
        self.link = self.dock = self.action = None

    # ------------------------------------------------------------ the daemon

    def _frame(self, image: Any, generation: int, camera: dict) -> None:
        self._camera = camera
        if self.dock is not None:
            # While a slider's change waits to be sent, frames drawn from
            # the camera before it must not move the slider back.
            settling = self._turn_timer.isActive() or self._follow_timer.isActive()
            self.dock.show_frame(image, generation, None if settling else camera)
            self.dock.show_message(self.follow_problem)

    def _reachable(self, up: bool, message: str) -> None:
        if self.dock is not None:
            self.dock.show_reachable(up, message)
        if not up:
            self.state = {}
        elif self.dock is not None and self.dock.follow.isChecked():
            # A daemon that restarted, or another one: its camera is its own.
            self._follow_now()

    def _state(self, state: dict) -> None:
        self.state = state
        if self.dock is not None:
            self.dock.show_state(state)

    def _address_changed(self, address: str) -> None:
        QgsSettings().setValue(ADDRESS_KEY, address)
        if self.link is not None:
            self.link.set_address(address)
            if self.dock is not None:
                self.dock.show_address_note(self.link.address_note)

    def _credentials_changed(self, token: str, ca_file: str) -> None:
        settings = QgsSettings()
        settings.setValue(TOKEN_KEY, token)
        settings.setValue(CA_FILE_KEY, ca_file)
        if self.link is not None:
            self.link.set_credentials(token, ca_file)

    # ------------------------------------------------------------ edits

    def _watch_layers(self, layers: list[QgsMapLayer]) -> None:
        for layer in layers:
            if isinstance(layer, QgsVectorLayer) and layer.id() not in self._layers:
                slot = self._commit_slot(layer.id())
                layer.afterCommitChanges.connect(slot)
                self._layers[layer.id()] = (layer, slot)

    def _commit_slot(self, layer_id: str) -> Callable[[], None]:
        return lambda: self._committed(layer_id)

    def _forget_layers(self, layer_ids: list[str]) -> None:
        for layer_id in layer_ids:
            watched = self._layers.pop(layer_id, None)
            if watched is not None:
                layer, slot = watched
                try:
                    layer.afterCommitChanges.disconnect(slot)
                except (TypeError, RuntimeError):
                    pass  # Already gone with its layer.

    def _committed(self, layer_id: str) -> None:
        """A layer's edits are on disk: reload the sources reading its file."""
        watched = self._layers.get(layer_id)
        path = layer_file(watched[0]) if watched is not None else None
        ids = sources_reading(self.state, path) if path else []
        if ids and self.link is not None and self.reload_on_commit:
            self.reloads_requested += 1
            self.link.reload(ids, self._state)

    # ------------------------------------------------------------ the camera

    def _follow_toggled(self, on: bool) -> None:
        QgsSettings().setValue(FOLLOW_KEY, on)
        self.follow_problem = ""
        if on:
            self._follow_now()

    def _map_moved(self, *_: Any) -> None:
        if self.dock is not None and self.dock.follow.isChecked():
            self._follow_timer.start()

    def _follow_now(self) -> None:
        """The camera that shows what the map shows: ground height at the
        map's centre first, then the camera, the newest request winning."""
        if self.link is None or self.dock is None or not self.dock.follow.isChecked():
            return
        view = map_view(self.iface.mapCanvas().mapSettings())
        if view is None:
            self.dock.show_message("Follow map: the map's centre has no place in WGS 84")
            return
        self._follow_serial += 1
        serial, pitch = self._follow_serial, self.dock.pitch_deg()
        fov = pj.number(self._camera, "verticalFovDeg") or 50.0

        def with_ground(ground_m: Optional[float], why: str) -> None:
            if serial != self._follow_serial or self.link is None or self.dock is None:
                return
            if ground_m is None:
                # Never guess the ground: the camera stays where it is.
                self.follow_problem = f"Follow map: no ground height at the map's centre ({why}); the camera stays"
                self.dock.show_message(self.follow_problem)
                return
            self.follow_problem = ""
            self.cameras_sent += 1
            self.link.set_camera(camera_for(view, pitch, ground_m, fov))

        if self.state and not pj.text(pj.message(self.state, "layers"), "height"):
            # The scene has no height layer: its ground is its zero.
            with_ground(0.0, "")
            return
        self.link.elevation(view.lon_deg, view.lat_deg, with_ground)

    def _slider_moved(self, _: float) -> None:
        if self.dock is not None and self.dock.follow.isChecked():
            self._follow_timer.start()
        else:
            self._turn_timer.start()

    def _turn_now(self) -> None:
        """Turns the scene camera about the ground at the view's centre to
        the sliders' pitch and heading, from the camera as it is now."""
        if self.link is None or self.dock is None:
            return
        self._turn_serial += 1
        # The sliders' values now: frames arriving before the answer may
        # move the sliders meanwhile.
        serial, want_pitch, want_heading = self._turn_serial, self.dock.pitch_deg(), float(self.dock.heading.value())

        def turn(camera: dict) -> None:
            if serial != self._turn_serial or self.link is None:
                return
            pitch = want_pitch - pj.number(camera, "pitchDeg")
            heading = (want_heading - pj.number(camera, "headingDeg") + 180.0) % 360.0 - 180.0
            if abs(pitch) > 1e-6 or abs(heading) > 1e-6:
                self.link.orbit(heading, pitch)

        self.link.camera(turn)


def _setting_bool(value: Any) -> bool:
    """A bool from QgsSettings (an ini file gives back "true" or "false")."""
    if isinstance(value, str):
        return value.strip().lower() in ("true", "1", "yes")
    return bool(value)
