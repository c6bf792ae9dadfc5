"""The dock when reliefd is not there, not reliefd, hung or far away: what
it says (in words, naming the address), how soon, that nothing stale stays
up, and Retry now. Issue 39's faults of the connection."""

from __future__ import annotations

import os
import signal
import time
from typing import Any

from conftest import wait_until
from fake_servers import NotRelief, Silent, free_port

from relief.testing import HillScene, Reliefd

#: How soon the dock must say that a daemon does not answer.
HUNG_DEADLINE_S = 5.0


def test_disconnection_clears_the_frame_and_the_sources(plugin: Any, daemon: Reliefd) -> None:
    dock = plugin.dock
    wait_until(lambda: dock.sources.topLevelItemCount() > 0, 10, "the dock lists the sources")
    assert not dock.frame.image().isNull()
    daemon.stop()
    wait_until(dock.banner.isVisible, 20, "the banner shows")
    assert dock.frame.image().isNull(), "the last frame is not shown while disconnected"
    assert dock.frame.pixmap() is None or dock.frame.pixmap().isNull()
    assert "disconnected" in dock.frame.text(), dock.frame.text()
    assert dock.sources.topLevelItemCount() == 0, "no source is listed as ready while disconnected"
    assert dock.generation_label.text() == "not connected"
    assert dock.retry_button.isVisible()


def test_a_server_that_is_not_relief_is_named_as_such(start_plugin: Any) -> None:
    with NotRelief() as server:
        plugin = start_plugin(server.address)
        dock = plugin.dock
        wait_until(dock.banner.isVisible, 20, "the banner shows")
        text = dock.banner.text()
        assert f"http://{server.address} is not a relief daemon (HTTP 404" in text, text
        assert "<" not in text and "Not Found</" not in text, f"raw HTML in the banner: {text}"
        assert dock.frames_shown == 0


def test_a_server_that_never_answers_is_seen_within_5_s_as_timed_out(start_plugin: Any) -> None:
    with Silent() as server:
        began = time.monotonic()
        plugin = start_plugin(server.address)
        dock = plugin.dock
        wait_until(dock.banner.isVisible, HUNG_DEADLINE_S, "the dock says the daemon does not answer")
        elapsed = time.monotonic() - began
        text = dock.banner.text()
        assert elapsed < HUNG_DEADLINE_S, elapsed
        assert server.accepted >= 1, "the server took the connection"
        assert f"no answer from http://{server.address} within 3.5 s (timed out)" in text, text
        assert "Operation canceled" not in text, text


def test_a_daemon_that_hangs_while_connected_is_seen_within_5_s(plugin: Any, daemon: Reliefd) -> None:
    # SIGSTOP: the kernel still accepts its connections and the open
    # streams stay open; nothing answers.
    dock = plugin.dock
    assert not dock.banner.isVisible()
    os.kill(daemon.pid, signal.SIGSTOP)
    try:
        began = time.monotonic()
        wait_until(dock.banner.isVisible, HUNG_DEADLINE_S, "the dock says the daemon hangs")
        elapsed = time.monotonic() - began
        assert elapsed < HUNG_DEADLINE_S, elapsed
        assert "timed out" in dock.banner.text() and daemon.address in dock.banner.text(), dock.banner.text()
        assert dock.frame.image().isNull()
    finally:
        os.kill(daemon.pid, signal.SIGCONT)
    # Back: the retries find it again.
    wait_until(lambda: not dock.banner.isVisible(), 30, "the banner goes when reliefd answers again")


def test_an_address_without_a_port_uses_reliefds_default_port(start_plugin: Any) -> None:
    plugin = start_plugin("127.0.0.1")
    assert plugin.link.url == "http://127.0.0.1:50051", "not HTTP's port 80"
    note = plugin.dock.address_note
    assert not note.isHidden(), "the dock says which port it assumed"
    assert note.text() == "no port given in '127.0.0.1': using reliefd's default port 50051", note.text()


def test_an_address_that_is_not_one_is_refused_in_words(start_plugin: Any) -> None:
    plugin = start_plugin("127.0.0.1:notaport")
    dock = plugin.dock
    wait_until(dock.banner.isVisible, 5, "the banner shows")
    assert "'127.0.0.1:notaport' is not an address: use host:port" in dock.banner.text(), dock.banner.text()
    assert plugin.link.probes == 0, "nothing is sent to an address that is not one"
    # Corrected in the dock: the note goes.
    dock.address.setText("127.0.0.1:50051")
    dock.address.editingFinished.emit()
    assert dock.address_note.isHidden()
    assert plugin.link.url == "http://127.0.0.1:50051"


def test_retry_now_connects_without_waiting_for_the_next_try(start_plugin: Any, scene: HillScene) -> None:
    from relief_qgis.link import Backoff

    address = f"127.0.0.1:{free_port()}"
    plugin = start_plugin(address)
    dock = plugin.dock
    plugin.link.backoff = Backoff(first=60.0, most=60.0)
    wait_until(lambda: "trying again in 60 s" in dock.banner.text(), 20, "the plugin waits a minute between tries")
    probes = plugin.link.probes
    with Reliefd(scene.manifest, listen=address):
        assert dock.retry_button.isVisible()
        dock.retry_button.click()
        assert plugin.link.probes == probes + 1, "Retry now asks at once"
        wait_until(lambda: not dock.banner.isVisible(), 10, "Retry now connects (the next try was a minute away)")
        wait_until(lambda: dock.frames_shown > 0, 60, "frames come")
        assert not dock.retry_button.isVisible()
