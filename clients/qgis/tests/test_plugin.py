"""The plugin in headless QGIS against a real reliefd: the dock's frame and
state, a committed edit reaching the dock, Follow map driving the camera,
the sliders, Reload now, a source error, and a daemon that goes away and
comes back."""

from __future__ import annotations

import math
import time
from typing import Any

from conftest import PLUGIN_ZIP, wait_until
from qgis.core import QgsCoordinateReferenceSystem, QgsGeometry, QgsPointXY, QgsProject, QgsRectangle
from qgis.PyQt.QtCore import QTimer

import relief
from relief.testing import Reliefd, hill_at, raise_window, write_hill_scene

#: A commit must reach the dock's frame within this (the daemon takes 50-90 ms
#: to make the generation on this kind of machine; lavapipe draws the frame).
COMMIT_TIMEOUT_S = 30.0

# WGS 84, for the test's own geodesy (independent of QGIS's).
A = 6378137.0
F = 1 / 298.257223563
E2 = F * (2 - F)


def radii(lat_deg: float) -> tuple[float, float]:
    """Meridian (M) and prime-vertical (N) radii of curvature at a latitude."""
    s = math.sin(math.radians(lat_deg))
    w = math.sqrt(1 - E2 * s * s)
    return A * (1 - E2) / w**3, A / w


def look_at(camera: relief.Camera) -> tuple[float, float]:
    """Where the camera's line of sight meets the ground below it, taking
    the ground as level at the height under that point (the hill's
    formula): a few steps of fixed point from a level plane at 0."""
    ground = 0.0
    lon = lat = 0.0
    for _ in range(20):
        back = (camera.altitude_m - ground) / math.tan(math.radians(-camera.pitch_deg))
        m, n = radii(camera.lat_deg)
        h = math.radians(camera.heading_deg)
        lat = camera.lat_deg + math.degrees(back * math.cos(h) / m)
        lon = camera.lon_deg + math.degrees(back * math.sin(h) / (n * math.cos(math.radians(camera.lat_deg))))
        ground = hill_at(lon, lat)
    return lon, lat


def show_hill(host: Any, centre: tuple[float, float], half_deg: float = 0.1) -> None:
    canvas = host.canvas
    canvas.setDestinationCrs(QgsCoordinateReferenceSystem("EPSG:4326"))
    canvas.setExtent(
        QgsRectangle(centre[0] - half_deg, centre[1] - half_deg, centre[0] + half_deg, centre[1] + half_deg)
    )
    canvas.refresh()


def test_the_zip_installs_one_plugin_with_qgis_qt_only() -> None:
    import zipfile

    with zipfile.ZipFile(PLUGIN_ZIP) as z:
        names = z.namelist()
        assert "relief_qgis/metadata.txt" in names and "relief_qgis/__init__.py" in names
        assert all(n.startswith("relief_qgis/") for n in names), names
        assert not any("__pycache__" in n for n in names)
        for name in names:
            if name.endswith(".py"):
                text = z.read(name).decode("utf-8")
                for banned in ("import PyQt5", "from PyQt5", "import PyQt6", "from PyQt6", "import requests", "import grpc"):
                    assert banned not in text, f"{name} has '{banned}': the plugin uses qgis.PyQt and the standard library only"
        metadata = z.read("relief_qgis/metadata.txt").decode("utf-8")
        assert "qgisMinimumVersion=3.22" in metadata


def test_the_dock_shows_frames_the_generation_and_each_source(plugin: Any, daemon: Any) -> None:
    dock = plugin.dock
    assert not dock.frame.pixmap().isNull()
    assert dock.frame_generation >= 1
    wait_until(lambda: dock.sources.topLevelItemCount() > 0, 10, "the dock lists the sources")
    rows = {
        dock.sources.topLevelItem(i).text(0): dock.sources.topLevelItem(i).text(2)
        for i in range(dock.sources.topLevelItemCount())
    }
    assert set(rows) == {"dem", "shade", "parcels", "parcels-drawn", "map", "buildings"}, rows
    assert rows["dem"] == "ready"
    assert "generation" in dock.generation_label.text()
    assert not dock.banner.isVisible()


def test_a_committed_vertex_move_reaches_the_dock(plugin: Any, daemon: Any, parcels_layer: Any) -> None:
    dock = plugin.dock
    with relief.connect(daemon.address) as client:
        before = client.state()
        parcels_before = next(s for s in before.sources if s.id == "parcels").version
    shown = dock.frame_generation
    assert parcels_layer.startEditing()
    feature = next(parcels_layer.getFeatures())
    vertex = feature.geometry().vertexAt(0)
    assert parcels_layer.moveVertex(vertex.x() + 0.01, vertex.y() + 0.01, feature.id(), 0)
    assert parcels_layer.commitChanges(), parcels_layer.commitErrors()
    assert plugin.reloads_requested == 1, "the commit asks reliefd for a reload"
    wait_until(lambda: dock.frame_generation > shown, COMMIT_TIMEOUT_S, "the dock shows the edited scene")
    with relief.connect(daemon.address) as client:
        after = client.state()
    parcels = next(s for s in after.sources if s.id == "parcels")
    assert parcels.version > parcels_before
    assert after.generation >= dock.frame_generation > shown


def test_follow_map_points_the_camera_at_the_map(plugin: Any, daemon: Any, host: Any) -> None:
    dock = plugin.dock
    with relief.connect(daemon.address) as client:
        show_hill(host, (10.25, 45.25))
        dock.follow.setChecked(True)
        assert not dock.heading.isEnabled(), "following, the map's rotation sets the heading"

        def follows(centre: tuple[float, float], heading: float) -> relief.Camera | None:
            camera = client.camera()
            lon, lat = look_at(camera)
            turn = (camera.heading_deg - heading + 180) % 360 - 180
            ok = abs(lon - centre[0]) < 2e-3 and abs(lat - centre[1]) < 2e-3 and abs(turn) < 0.1
            return camera if ok else None

        camera = wait_until(lambda: follows((10.25, 45.25), 0.0), 10, "the camera looks at the map's centre")
        assert camera.pitch_deg == dock.pitch_deg()
        # The map's height (0.2 degrees of latitude) fills the vertical field of view.
        settings = host.canvas.mapSettings()
        height_deg = settings.mapUnitsPerPixel() * settings.outputSize().height()
        height_m = math.radians(height_deg) * radii(45.25)[0]
        distance = 0.5 * height_m / math.tan(math.radians(0.5 * camera.vertical_fov_deg))
        rise = camera.altitude_m - hill_at(10.25, 45.25)
        assert abs(rise - distance * math.sin(math.radians(-camera.pitch_deg))) < 0.01 * distance

        host.canvas.setCenter(QgsPointXY(10.32, 45.18))  # a pan
        wait_until(lambda: follows((10.32, 45.18), 0.0), 10, "the camera follows the pan")
        # The map turned 30 degrees clockwise. On this plate carree map a
        # degree east is drawn as long as a degree north, so the screen's up
        # is not 330 on the ground: it is the azimuth of (-sin 30, cos 30)
        # degrees there.
        host.canvas.setRotation(30.0)
        m, n = radii(45.18)
        up = math.degrees(math.atan2(-math.sin(math.radians(30)) * n * math.cos(math.radians(45.18)), math.cos(math.radians(30)) * m)) % 360
        wait_until(lambda: follows((10.32, 45.18), up), 10, "the camera follows the rotation")
        dock.pitch.setValue(70)
        wait_until(lambda: abs(client.camera().pitch_deg + 70.0) < 1e-6, 10, "the pitch slider tilts the camera")
        assert follows((10.32, 45.18), up), "tilting keeps the camera on the map's centre"


def test_the_sliders_turn_the_camera_about_the_view_centre(plugin: Any, daemon: Any) -> None:
    dock = plugin.dock
    with relief.connect(daemon.address) as client:
        start = client.camera()
        centre = look_at(start)
        dock.heading.setValue(90)
        wait_until(lambda: abs(client.camera().heading_deg - 90.0) < 0.5, 10, "the heading slider turns the camera")
        dock.pitch.setValue(60)
        def tilted() -> relief.Camera | None:
            c = client.camera()
            return c if abs(c.pitch_deg + 60.0) < 0.5 else None

        camera = wait_until(tilted, 10, "the pitch slider tilts the camera")
        lon, lat = look_at(camera)
        # Turned about the ground at the centre of the view: it stays there
        # (within the daemon's ground intersection and this test's level ground).
        assert abs(lon - centre[0]) < 5e-3 and abs(lat - centre[1]) < 5e-3, (centre, (lon, lat))


def test_reload_now_reads_an_edit_the_watcher_has_not_taken_yet(start_plugin: Any, tmp_path: Any) -> None:
    # A watcher that waits a minute before it reads a change: only the
    # button can make the new generation within the test's timeout.
    slow = "[watch]\nfast_path = false\ndebounce_ms = 60000\nwrite_timeout_ms = 60000\n"
    scene = write_hill_scene(tmp_path / "slow", extra_manifest=slow)
    with Reliefd(scene.manifest) as daemon, relief.connect(daemon.address) as client:
        plugin = start_plugin(daemon.address)
        dock = plugin.dock
        wait_until(lambda: dock.frames_shown > 0, 60, "the dock shows a frame")
        before = client.state()
        col, row = scene.pixel(10.25, 45.25)
        raise_window(scene.dem, col - 10, row - 10, 20, 20, by_m=300.0)
        dock.reload_button.click()
        # (The test waits running Qt's loop: the click's request is sent there.)
        after = wait_until(
            lambda: (st := client.state()).generation > before.generation and st, 10, "Reload now makes a generation"
        )
        dem = next(s for s in after.sources if s.id == "dem")
        assert dem.version > next(s for s in before.sources if s.id == "dem").version
        assert client.elevation([(10.25, 45.25)])[0] > hill_at(10.25, 45.25) + 250
        wait_until(lambda: dock.frame_generation >= after.generation, 30, "the dock shows the reloaded scene")


def test_a_broken_source_shows_its_error_and_the_last_good_frame_stays(plugin: Any, daemon: Any, scene: Any) -> None:
    dock = plugin.dock
    scene.dem.write_bytes(b"this is not a GeoTIFF any more")

    def dem_row() -> str:
        for i in range(dock.sources.topLevelItemCount()):
            item = dock.sources.topLevelItem(i)
            if item.text(0) == "dem" and item.text(2).startswith("error"):
                return item.text(2)
        return ""

    text = wait_until(dem_row, 30, "the dock shows the DEM's error")
    assert "hill.tif" in text, text
    assert not dock.frame.pixmap().isNull()
    assert not dock.banner.isVisible()


def test_a_daemon_that_goes_away_shows_a_banner_and_comes_back(plugin: Any, daemon: Any) -> None:
    dock = plugin.dock
    address = daemon.address
    # The UI thread must stay free: a timer ticking every 50 ms records gaps.
    ticks: list[float] = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(time.monotonic()))
    timer.start(50)
    try:
        daemon.stop()
        wait_until(dock.banner.isVisible, 20, "the banner shows")
        assert "not reachable" in dock.banner.text() and address in dock.banner.text(), dock.banner.text()
        # Retries with backoff while it is away.
        wait_until(lambda: plugin.link.backoff.next >= 2.0, 20, "the plugin retries with a growing delay")
        shown = dock.frames_shown
        daemon.listen = address
        daemon.start()
        wait_until(lambda: not dock.banner.isVisible(), 30, "the banner goes when reliefd is back")
        wait_until(lambda: dock.frames_shown > shown, 30, "frames come again")
    finally:
        timer.stop()
    gaps = [b - a for a, b in zip(ticks, ticks[1:])]
    assert gaps and max(gaps) < 1.0, f"the UI thread was blocked for {max(gaps):.2f} s"


def test_a_layer_the_scene_does_not_read_asks_for_no_reload(plugin: Any, tmp_path: Any) -> None:
    from relief.testing import write_polygons
    from qgis.core import QgsVectorLayer

    other = write_polygons(tmp_path / "elsewhere.shp")
    layer = QgsVectorLayer(str(other), "elsewhere", "ogr")
    QgsProject.instance().addMapLayer(layer)
    assert layer.startEditing()
    feature = next(layer.getFeatures())
    assert layer.changeGeometry(feature.id(), QgsGeometry.fromPointXY(QgsPointXY(10.3, 45.3)).buffer(0.01, 4))
    assert layer.commitChanges(), layer.commitErrors()
    assert plugin.reloads_requested == 0

