"""The plugin against a reliefd that wants tokens and speaks TLS: the token
on every request and stream, a refusal (HTTP 401) shown as one with what to
do, a read token's refused reload, and https:// with a CA file."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from conftest import wait_until
from qgis.core import QgsSettings

from relief.testing import HillScene, Reliefd, make_certificates, write_token_file


def test_the_token_lets_the_plugin_in_and_a_read_token_cannot_reload(
    start_plugin: Any, scene: HillScene, tmp_path: Path
) -> None:
    tokens = write_token_file(tmp_path / "secrets")
    with Reliefd(scene.manifest, args=tokens.args) as daemon:
        plugin = start_plugin(daemon.address, token=tokens.read)
        dock = plugin.dock
        wait_until(lambda: dock.frames_shown > 0, 60, "the dock shows a frame")
        wait_until(lambda: dock.sources.topLevelItemCount() > 0, 10, "the dock lists the sources")
        assert not dock.banner.isVisible() and plugin.link.refused == 0
        dock.reload_button.click()
        wait_until(lambda: "HTTP 403" in dock.message.text(), 10, "a refused reload is shown")
        assert "control token" in dock.message.text(), dock.message.text()
        # The frames go on: a refused request is not a daemon down.
        shown = dock.frames_shown
        with daemon.connect(token=tokens.control) as client:
            client.reload(["dem"])
        wait_until(lambda: dock.frames_shown > shown, 30, "frames of the new generation")
        assert not dock.banner.isVisible()


def test_no_token_is_reported_as_a_refusal_and_entering_one_connects(
    start_plugin: Any, scene: HillScene, tmp_path: Path
) -> None:
    tokens = write_token_file(tmp_path / "secrets")
    with Reliefd(scene.manifest, args=tokens.args) as daemon:
        plugin = start_plugin(daemon.address)
        dock = plugin.dock
        wait_until(dock.banner.isVisible, 20, "the banner shows")
        text = dock.banner.text()
        assert plugin.link.refused == 401, text
        assert "refused (HTTP 401): missing token" in text and "it wants a token" in text, text
        assert "Token field" in text, text
        assert daemon.address in text and "not reachable" not in text, text
        assert dock.frames_shown == 0

        # A wrong token says so.
        dock.token.setText("read-0123456789abcdeX")
        dock.token.editingFinished.emit()
        wait_until(lambda: "the token is wrong" in dock.banner.text(), 20, "the banner names a wrong token")
        assert "not one this reliefd accepts" in dock.banner.text(), dock.banner.text()

        # The right one, typed into the dock: kept in the settings, and the link comes up.
        dock.token.setText(tokens.read)
        dock.token.editingFinished.emit()
        assert QgsSettings().value("relief_qgis/token") == tokens.read
        wait_until(lambda: dock.frames_shown > 0, 60, "the dock shows a frame once the token is given")
        wait_until(lambda: not dock.banner.isVisible(), 10, "the banner goes")
        assert plugin.link.refused == 0


def test_https_with_the_ca_file(start_plugin: Any, scene: HillScene, tmp_path: Path) -> None:
    tokens = write_token_file(tmp_path / "secrets")
    certs = make_certificates(tmp_path / "tls")
    with Reliefd(scene.manifest, args=(*tokens.args, *certs.args)) as daemon:
        assert daemon.tls, daemon.viewer_url
        port = daemon.address.rsplit(":", 1)[1]
        address = f"https://127.0.0.1:{port}"

        # Without the CA, Qt does not trust the certificate: the banner says so.
        plugin = start_plugin(address, token=tokens.read)
        dock = plugin.dock
        wait_until(dock.banner.isVisible, 20, "the banner shows")
        text = dock.banner.text()
        assert "SSL handshake failed: " in text and "certificate" in text and dock.frames_shown == 0, text

        # With it, frames come over TLS (the streams included).
        dock.ca_file.setText(str(certs.ca))
        dock.ca_file.editingFinished.emit()
        assert QgsSettings().value("relief_qgis/ca_file") == str(certs.ca)
        wait_until(lambda: dock.frames_shown > 0, 60, "the dock shows a frame over TLS")
        wait_until(lambda: not dock.banner.isVisible(), 10, "the banner goes")
        wait_until(lambda: dock.sources.topLevelItemCount() > 0, 10, "the events stream's state arrives")

        # A CA file that is not one is named.
        dock.ca_file.setText(str(tmp_path / "nope.pem"))
        dock.ca_file.editingFinished.emit()
        wait_until(lambda: "nope.pem" in dock.banner.text(), 20, "the banner names the CA file")


def test_a_token_never_goes_in_plaintext_to_another_machine(start_plugin: Any) -> None:
    # Nothing listens there, and nothing is sent: the banner says why first.
    plugin = start_plugin("http://10.255.255.1:50051", token="read-0123456789abcdef")
    dock = plugin.dock
    wait_until(dock.banner.isVisible, 20, "the banner shows")
    text = dock.banner.text()
    assert "refusing to send the token over plain http://" in text and "https://" in text, text
    assert dock.frames_shown == 0
