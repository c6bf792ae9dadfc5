"""The dock against a real reliefd, issue 39's faults of the camera and
the stream: Follow map applied again on a reconnect and on a new address,
never on a guessed ground; a heading of 0 (left out of proto3 JSON) shown
as 0; no frames while the dock is hidden; Follow remembered across a
reload of the plugin; landscape frames."""

from __future__ import annotations

import math
from typing import Any, Optional

from conftest import wait_until
from headless import load_plugin, stop_plugin
from qgis.core import QgsSettings
from test_plugin import look_at, radii, show_hill

import relief
from relief.testing import HillScene, Reliefd, hill_at

CENTRE = (10.32, 45.18)


def follows(client: Any, centre: tuple[float, float] = CENTRE) -> Optional[relief.Camera]:
    """The daemon's camera when it looks at `centre` from the north-up map."""
    camera = client.camera()
    lon, lat = look_at(camera)
    turn = (camera.heading_deg + 180) % 360 - 180
    ok = abs(lon - centre[0]) < 2e-3 and abs(lat - centre[1]) < 2e-3 and abs(turn) < 0.1
    return camera if ok else None


def test_follow_is_applied_again_when_the_daemon_comes_back(plugin: Any, daemon: Reliefd, host: Any) -> None:
    show_hill(host, CENTRE)
    plugin.dock.follow.setChecked(True)
    with relief.connect(daemon.address) as client:
        wait_until(lambda: follows(client), 10, "the camera follows the map")
    address = daemon.address
    # The map stays still: no map signal (the banner resizing the window's
    # canvas would send one here) may stand in for the reconnect.
    host.canvas.blockSignals(True)
    try:
        daemon.stop()
        wait_until(plugin.dock.banner.isVisible, 20, "the banner shows")
        sent = plugin.cameras_sent
        daemon.listen = address
        daemon.start()  # A new process: the manifest's camera, not the map's.
        with relief.connect(daemon.address) as client:
            wait_until(lambda: follows(client), 30, "the camera follows the map again after the reconnect")
        assert plugin.cameras_sent > sent
    finally:
        host.canvas.blockSignals(False)


def test_follow_is_applied_to_a_new_address(plugin: Any, host: Any, scene: HillScene) -> None:
    show_hill(host, CENTRE)
    plugin.dock.follow.setChecked(True)
    wait_until(lambda: plugin.cameras_sent > 0, 10, "the camera follows the map")
    host.canvas.blockSignals(True)  # As above: only the new address may move it.
    try:
        with Reliefd(scene.manifest) as other, relief.connect(other.address) as client:
            assert not follows(client), "the other daemon starts from its manifest's camera"
            plugin.dock.address.setText(other.address)
            plugin.dock.address.editingFinished.emit()
            wait_until(lambda: follows(client), 30, "the new daemon's camera follows the map")
    finally:
        host.canvas.blockSignals(False)


def test_a_failed_height_lookup_leaves_the_camera_above_the_terrain(plugin: Any, daemon: Reliefd, host: Any) -> None:
    dock = plugin.dock
    with relief.connect(daemon.address) as client:
        before = client.camera()
        sent = plugin.cameras_sent

        # The lookup fails (as a timeout does): the camera is not moved to a guess.
        def failing(lon: float, lat: float, callback: Any) -> None:
            callback(None, "no answer from http://x within 5 s (timed out)")

        real = plugin.link.elevation
        plugin.link.elevation = failing
        try:
            show_hill(host, (10.25, 45.25))  # The summit: 2000 m.
            dock.follow.setChecked(True)
            wait_until(lambda: "no ground height" in dock.message.text(), 10, "the dock says why the camera stays")
            assert "timed out" in dock.message.text(), dock.message.text()
            assert plugin.cameras_sent == sent
            camera = client.camera()
            assert (camera.lon_deg, camera.lat_deg, camera.altitude_m) == (before.lon_deg, before.lat_deg, before.altitude_m)
            assert camera.altitude_m > hill_at(camera.lon_deg, camera.lat_deg)
        finally:
            plugin.link.elevation = real

        # Off the scene the height layer has no data: the same.
        host.canvas.setCenter(host.canvas.center().__class__(12.0, 47.0))
        wait_until(lambda: "has no data there" in dock.message.text(), 10, "the dock says there is no height there")
        assert plugin.cameras_sent == sent
        camera = client.camera()
        assert camera.altitude_m > hill_at(camera.lon_deg, camera.lat_deg)

        # Back over the scene: it follows.
        host.canvas.setCenter(host.canvas.center().__class__(*CENTRE))
        wait_until(lambda: follows(client), 10, "the camera follows the map again")
        camera = client.camera()
        assert camera.altitude_m > hill_at(camera.lon_deg, camera.lat_deg)
        wait_until(lambda: dock.message.text() == "", 10, "the message goes")


def test_a_scene_without_a_height_layer_is_followed_on_ground_at_0(plugin: Any, daemon: Reliefd, host: Any) -> None:
    # The state names the scene's layers: without "height" there is no
    # ground to look up (the daemon would refuse the lookup), it is 0 m.
    asked: list[tuple[float, float]] = []
    plugin.link.elevation = lambda lon, lat, callback: asked.append((lon, lat))
    plugin.link.state.emit({"name": "flat", "generation": "3", "layers": {"color": "map"}})
    show_hill(host, CENTRE)
    plugin.dock.follow.setChecked(True)
    # The map's height fills the field of view, from ground at 0 m.
    settings = host.canvas.mapSettings()
    height_m = math.radians(settings.mapUnitsPerPixel() * settings.outputSize().height()) * radii(CENTRE[1])[0]
    distance = 0.5 * height_m / math.tan(math.radians(0.5 * 50.0))
    rise = distance * math.sin(math.radians(-plugin.dock.pitch_deg()))
    with relief.connect(daemon.address) as client:
        wait_until(lambda: abs(client.camera().altitude_m - rise) < 0.01 * rise, 10, "the camera stands on 0 m")
        camera = client.camera()
        # South of the centre by as much as it is high (45 degrees down), looking north.
        back_deg = math.degrees(rise / radii(CENTRE[1])[0])
        assert abs(camera.lat_deg - (CENTRE[1] - back_deg)) < 1e-3 and abs(camera.lon_deg - CENTRE[0]) < 1e-6, camera
    assert asked == [], "no height lookup"
    assert plugin.dock.message.text() == ""


def test_a_heading_of_0_left_out_of_the_json_is_shown_as_0(plugin: Any, daemon: Reliefd) -> None:
    dock = plugin.dock
    with relief.connect(daemon.address) as client:
        camera = client.camera()
        client.set_camera(relief.Camera(camera.lon_deg, camera.lat_deg, camera.altitude_m, heading_deg=90.0, pitch_deg=-30.0))
        wait_until(lambda: dock.heading.value() == 90, 30, "the heading slider shows 90")
        # proto3 JSON leaves heading 0 out of the frame's camera.
        client.set_camera(relief.Camera(camera.lon_deg, camera.lat_deg, camera.altitude_m, heading_deg=0.0, pitch_deg=-30.0))
        wait_until(lambda: dock.heading.value() == 0, 30, "the heading slider shows 0")
        assert dock.heading_label.text() == "Heading 0°"
        assert dock.pitch.value() == 30


def test_frames_stop_while_the_dock_is_hidden_and_come_back_when_shown(plugin: Any, daemon: Reliefd) -> None:
    dock, link = plugin.dock, plugin.link
    assert link.streaming_frames
    dock.close()  # The dock's close button (its menu action hides it the same way).
    wait_until(lambda: not link.streaming_frames, 5, "the frame stream closes")
    shown = dock.frames_shown
    with relief.connect(daemon.address) as client:
        after = client.reload(["dem"])
        camera = client.camera()
        client.set_camera(relief.Camera(camera.lon_deg, camera.lat_deg, camera.altitude_m + 100.0))
    wait_until(lambda: plugin.state and int(plugin.state.get("generation", 0)) >= after.generation, 10, "the state still follows")
    assert dock.frames_shown == shown, "no frame is received while the dock is hidden"
    dock.show()
    wait_until(lambda: link.streaming_frames, 5, "the frame stream opens again")
    wait_until(lambda: dock.frames_shown > shown, 30, "frames come again")


def test_follow_is_remembered_across_a_plugin_reload(plugin: Any) -> None:
    plugin.dock.follow.setChecked(True)
    assert QgsSettings().value("relief_qgis/follow") in (True, "true")
    stop_plugin()
    again = load_plugin()
    assert again is not plugin
    assert again.dock.follow.isChecked(), "Follow map is on again"
    assert not again.dock.heading.isEnabled(), "and the heading is the map's"
    again.dock.follow.setChecked(False)
    stop_plugin()
    assert not load_plugin().dock.follow.isChecked()


def test_frames_are_landscape(plugin: Any) -> None:
    width, height = plugin.link.frame_size
    assert width > height, (width, height)
    image = plugin.dock.frame.image()
    assert abs(image.width() / image.height() - 16 / 9) < 0.05, (image.width(), image.height())
