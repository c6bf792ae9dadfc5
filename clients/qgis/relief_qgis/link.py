"""The plugin's one connection to reliefd: its HTTP transport (the same calls
as gRPC, as JSON, streams as Server-Sent Events), through Qt's own network
stack. Nothing here blocks: every request answers through a signal or a
callback on the UI thread's event loop.

Two streams run while the daemon is up: /api/frames (a view opened to
follow the scene camera, pushed, PNG) and /api/events (the scene's generations and source
errors; each is followed by one GET /api/state). When either ends or
fails, the link reports the daemon down, stops both and retries
GET /api/state with a growing delay until it answers.

A reliefd serving with --token-file wants `Authorization: Bearer TOKEN` on
every request, the streams included (Qt sets headers on them, so the token
never goes in a URL); one refused (HTTP 401) is reported as such, with what
to do. An https:// address speaks TLS through Qt's own TLS, trusting the
system's CA certificates and, when given, those of a PEM file."""

from __future__ import annotations

import base64
import ipaddress
import json
from typing import Callable, Optional
from urllib.parse import urlencode

from qgis.PyQt.QtCore import QByteArray, QObject, QTimer, QUrl, pyqtSignal
from qgis.PyQt.QtGui import QImage
from qgis.PyQt.QtNetwork import (
    QNetworkAccessManager,
    QNetworkReply,
    QNetworkRequest,
    QSslCertificate,
    QSslConfiguration,
)

from .sse import SseParser

#: Where a fresh install looks for reliefd (`reliefd serve`'s default).
DEFAULT_ADDRESS = "127.0.0.1:50051"
#: How long a single request may take before it counts as unanswered.
REQUEST_TIMEOUT_MS = 5000
#: The reply property holding why Qt did not trust the daemon's certificate.
TLS_ERRORS = "relief_tls_errors"


class Backoff:
    """Delays between retries: `first` seconds, doubling, at most `most`."""

    def __init__(self, first: float = 0.5, most: float = 8.0) -> None:
        self.first, self.most = first, most
        self.next = first

    def take(self) -> float:
        delay = self.next
        self.next = min(self.next * 2.0, self.most)
        return delay

    def reset(self) -> None:
        self.next = self.first


def base_url(address: str) -> str:
    """`host:port` or a URL, as the URL the calls hang from (no trailing /)."""
    address = address.strip().rstrip("/")
    return address if "://" in address else f"http://{address}"


def is_loopback(host: str) -> bool:
    """Whether `host` is this machine (localhost, 127.0.0.0/8, ::1)."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def error_text(reply: QNetworkReply) -> str:
    """What went wrong with a reply: the daemon's own message (its JSON
    error body names the field) when it answered, else Qt's reason."""
    status = reply.attribute(QNetworkRequest.HttpStatusCodeAttribute)
    body = bytes(reply.readAll())
    if status:
        try:
            message = str(json.loads(body.decode("utf-8"))["message"])
        except (ValueError, KeyError, TypeError, UnicodeDecodeError):
            message = body[:200].decode("utf-8", errors="replace").strip()
        if status in (401, 403):
            return f"refused (HTTP {status}): {message}"
        return f"HTTP {status}: {message}"
    tls = reply.property(TLS_ERRORS)
    if tls:
        return f"{reply.errorString()}: {tls}"
    return reply.errorString()


def is_refusal(reply: QNetworkReply) -> int:
    """401 or 403 when the daemon refused the request's token, else 0."""
    status = reply.attribute(QNetworkRequest.HttpStatusCodeAttribute)
    return int(status) if status in (401, 403) else 0


class Credentials:
    """What every request carries: the bearer token (empty: none) and, for
    https://, the TLS settings with the CA certificates to trust."""

    def __init__(self, token: str = "", ca_file: str = "", insecure: bool = False) -> None:
        self.token = token.strip()
        self.ca_file = ca_file.strip()
        #: Send the token over plain http:// to another machine anyway.
        self.insecure = insecure
        #: Why the CA file cannot be used ("" when it can, or none is set).
        self.ca_error = ""
        self._ssl: Optional[QSslConfiguration] = None
        if self.ca_file:
            certificates = QSslCertificate.fromPath(self.ca_file)
            if not certificates:
                self.ca_error = f"the CA file holds no PEM certificate or cannot be read: {self.ca_file}"
            else:
                self._ssl = QSslConfiguration.defaultConfiguration()
                self._ssl.setCaCertificates(self._ssl.caCertificates() + certificates)

    def refusal(self, url: str) -> str:
        """Why no request may go to `url` with this token ("" when one may):
        over plain http:// to another machine anyone on the path could read
        the token and use it."""
        address = QUrl(url)
        host = address.host().strip("[]")
        if not self.token or self.insecure or address.scheme() != "http" or is_loopback(host):
            return ""
        return (
            f"refusing to send the token over plain http:// to {host}: anyone on the path could read it and use it; "
            "serve reliefd with TLS (--tls-cert, --tls-key) and connect to https://"
        )

    def apply(self, request: QNetworkRequest) -> QNetworkRequest:
        if self.token:
            request.setRawHeader(b"Authorization", b"Bearer " + self.token.encode("utf-8"))
        if self._ssl is not None and request.url().scheme() == "https":
            request.setSslConfiguration(self._ssl)
        return request


class _Stream(QObject):
    """One Server-Sent Events request; `received` for each event, `ended`
    (with the reason) once when it stops by itself."""

    received = pyqtSignal(str, str)
    ended = pyqtSignal(str)

    def __init__(self, manager: QNetworkAccessManager, url: str, credentials: Credentials, parent: QObject) -> None:
        super().__init__(parent)
        request = credentials.apply(QNetworkRequest(QUrl(url)))
        request.setRawHeader(b"Accept", b"text/event-stream")
        request.setAttribute(QNetworkRequest.CacheLoadControlAttribute, QNetworkRequest.AlwaysNetwork)
        self._parser = SseParser()
        self._closing = False
        #: The message of an `error` event the daemon sent before ending.
        self.error = ""
        #: 401 or 403 when the daemon refused the stream's token.
        self.refused = 0
        self._reply = manager.get(request)
        self._reply.readyRead.connect(self._read)
        self._reply.finished.connect(self._finished)

    def _read(self) -> None:
        if self._reply.attribute(QNetworkRequest.HttpStatusCodeAttribute) not in (None, 200):
            return  # An error body: `finished` reports it.
        for name, data in self._parser.feed(bytes(self._reply.readAll())):
            if name == "error":
                self.error = _message(data)
            self.received.emit(name, data)

    def _finished(self) -> None:
        if self._closing:
            return
        self._closing = True
        failed = self._reply.error() != QNetworkReply.NoError
        self.refused = is_refusal(self._reply)
        if self.error:
            self.ended.emit(f"it answered: {self.error}")
        else:
            self.ended.emit(error_text(self._reply) if failed else "the daemon ended the stream")
        self._reply.deleteLater()

    def close(self) -> None:
        if not self._closing:
            self._closing = True
            self._reply.abort()
            self._reply.deleteLater()
        self.deleteLater()


class DaemonLink(QObject):
    """reliefd at one address. Signals carry decoded JSON (proto3 JSON
    mapping: lowerCamelCase names, 64-bit integers as strings)."""

    #: A pushed frame: the image, its scene generation, its camera.
    frame = pyqtSignal(QImage, int, dict)
    #: The scene state (GetState), after each generation and source error.
    state = pyqtSignal(dict)
    #: The daemon became reachable (True, "") or not (False, why, when next).
    reachable = pyqtSignal(bool, str)
    #: A request the daemon answered with an error, its message.
    failed = pyqtSignal(str)

    def __init__(
        self,
        address: str = DEFAULT_ADDRESS,
        parent: Optional[QObject] = None,
        *,
        token: str = "",
        ca_file: str = "",
    ) -> None:
        super().__init__(parent)
        self._manager = QNetworkAccessManager(self)
        self._manager.sslErrors.connect(_keep_tls_errors)
        self._address = address
        self._credentials = Credentials(token, ca_file)
        #: 401 or 403 while the daemon refuses the token, else 0.
        self.refused = 0
        self._size = (640, 360)
        self._max_fps = 10.0
        self._streams: dict[str, _Stream] = {}
        self._pending: set[QNetworkReply] = set()
        self._view_id = ""
        #: Bumped on every restart and stop: answers to requests made
        #: before are dropped (an old address's late failure must not tear
        #: down the new connection).
        self._epoch = 0
        self._running = False
        self._up: Optional[bool] = None
        self.backoff = Backoff()
        self._retry = QTimer(self)
        self._retry.setSingleShot(True)
        self._retry.timeout.connect(self._probe)

    # ------------------------------------------------------------ settings

    @property
    def address(self) -> str:
        return self._address

    @property
    def is_up(self) -> bool:
        return bool(self._up)

    def set_address(self, address: str) -> None:
        if address.strip() == self._address:
            return
        self._address = address.strip()
        if self._running:
            self._restart()

    @property
    def token(self) -> str:
        return self._credentials.token

    @property
    def ca_file(self) -> str:
        return self._credentials.ca_file

    def set_credentials(self, token: str, ca_file: str) -> None:
        """The bearer token (empty: none) and a PEM file of CA certificates
        to trust for https:// (empty: the system's only); reconnects."""
        if (token.strip(), ca_file.strip()) == (self._credentials.token, self._credentials.ca_file):
            return
        self._credentials = Credentials(token, ca_file)
        # Qt keeps connections (and what it made of their certificates) per
        # host: new trust must start from new ones.
        self._forget_requests()
        self._close_streams()
        self._manager.clearConnectionCache()
        if self._running:
            self._restart()

    def set_frame_size(self, width: int, height: int) -> None:
        """The pushed frames' size in pixels (the stream is opened again)."""
        size = (max(16, min(int(width), 4096)), max(16, min(int(height), 4096)))
        if size == self._size:
            return
        self._size = size
        if self._running and self._view_id and "frames" in self._streams:
            self._open_frames()

    # ------------------------------------------------------------ lifetime

    def start(self) -> None:
        self._running = True
        self._restart()

    def stop(self) -> None:
        self._running = False
        self._retry.stop()
        self._forget_requests()
        self._close_streams()

    def _restart(self) -> None:
        self._forget_requests()
        self._close_streams()
        self._retry.stop()
        self.backoff.reset()
        self._up = None
        self._probe()

    def _forget_requests(self) -> None:
        self._epoch += 1
        self._view_id = ""
        for reply in list(self._pending):
            reply.abort()
        self._pending.clear()

    def _close_streams(self) -> None:
        for stream in self._streams.values():
            stream.close()
        self._streams.clear()

    def _probe(self) -> None:
        """GET /api/state; the streams open once it answers."""
        if not self._running:
            return
        self.refused = 0
        if self._credentials.ca_error:
            self._down(self._credentials.ca_error)
            return
        refusal = self._credentials.refusal(base_url(self._address))
        if refusal:
            self._down(refusal)
            return
        self._get("/api/state", self._probed, on_error=self._down)

    def _probed(self, state: dict) -> None:
        if not self._running:
            return
        self.refused = 0
        self._set_up(True, "")
        self.state.emit(state)
        # The dock's own view of the scene camera: its frames carry depth, so
        # the sliders turn the camera about the ground drawn at their centre.
        self._send("POST", "/api/views", {"followSceneCamera": True}, self._view_opened)
        self._open_events()

    def _view_opened(self, view: dict) -> None:
        self._view_id = str(view.get("viewId", ""))
        if self._running and self._view_id:
            self._open_frames()

    def _down(self, why: str) -> None:
        self._close_streams()
        if not self._running or (self._up is False and self._retry.isActive()):
            return  # Already waiting to try again.
        delay = self.backoff.take()
        if self.refused == 401:
            what = "the token is wrong" if self._credentials.token else "it wants a token"
            message = (
                f"reliefd at {self._address}: {why}; {what}: enter one of its token file in the dock's "
                f"Token field; trying again in {delay:g} s"
            )
        else:
            message = f"reliefd at {self._address}: not reachable or not drawing ({why}); trying again in {delay:g} s"
        self._set_up(False, message)
        self._retry.start(int(delay * 1000))

    def _set_up(self, up: bool, message: str) -> None:
        # The delay grows until a frame arrives (a daemon that answers but
        # cannot draw is retried less and less often, not every 0.5 s).
        if up != self._up or not up:
            self._up = up
            self.reachable.emit(up, message)

    # ------------------------------------------------------------ streams

    def _open(self, name: str, path: str, on_event: Callable[[str, str], None]) -> None:
        old = self._streams.pop(name, None)
        if old is not None:
            old.close()
        stream = _Stream(self._manager, base_url(self._address) + path, self._credentials, self)
        stream.received.connect(on_event)
        stream.ended.connect(lambda why, s=stream: self._ended(s, why))
        self._streams[name] = stream

    def _ended(self, stream: _Stream, why: str) -> None:
        if stream in self._streams.values():
            if stream.refused == 401:
                self.refused = 401
            self._down(why)

    def _open_frames(self) -> None:
        width, height = self._size
        query = urlencode(
            {"view": self._view_id, "width": width, "height": height, "format": "png", "max_fps": self._max_fps}
        )
        self._open("frames", f"/api/frames?{query}", self._on_frame)

    def _open_events(self) -> None:
        self._open("events", "/api/events", self._on_scene_event)

    def _on_frame(self, name: str, data: str) -> None:
        if name == "error":
            self.failed.emit(_message(data))
            return
        try:
            message = json.loads(data)
            image = QImage.fromData(QByteArray(base64.b64decode(message.get("image", ""))), "PNG")
            generation = int(message.get("generation", 0))
        except (ValueError, TypeError) as e:
            self.failed.emit(f"a frame from reliefd could not be read: {e}")
            return
        if image.isNull():
            self.failed.emit("a frame from reliefd is not a PNG image")
            return
        self.backoff.reset()
        self.frame.emit(image, generation, message.get("camera") or {})

    def _on_scene_event(self, name: str, data: str) -> None:
        if name == "error":
            self.failed.emit(_message(data))
            return
        try:
            message = json.loads(data)
        except ValueError:
            return
        if "snapshot" in message:
            self.state.emit(message["snapshot"])
        else:
            self.refresh_state()

    # ------------------------------------------------------------ calls

    def refresh_state(self) -> None:
        self._get("/api/state", self.state.emit)

    def camera(self, callback: Callable[[dict], None]) -> None:
        self._get("/api/camera", callback)

    def set_camera(self, camera: dict, callback: Optional[Callable[[dict], None]] = None) -> None:
        self._send("PUT", "/api/camera", camera, callback)

    def orbit(self, heading_deg: float, pitch_deg: float) -> None:
        """Turns the scene camera about the ground drawn at the centre of
        the dock's view."""
        if self._view_id:
            gesture = {"orbit": {"headingDeg": heading_deg, "pitchDeg": pitch_deg}}
            self._send("POST", f"/api/views/{self._view_id}/navigate", gesture)

    def set_interactive(self, interactive: bool) -> None:
        """While the user drags a slider: smaller frames, sooner."""
        if self._view_id:
            self._send("PATCH", f"/api/views/{self._view_id}", {"interactive": interactive})

    def reload(self, source_ids: list[str], callback: Optional[Callable[[dict], None]] = None) -> None:
        self._send("POST", "/api/reload", {"sourceIds": source_ids}, callback)

    def elevation(self, lon_deg: float, lat_deg: float, callback: Callable[[Optional[float]], None]) -> None:
        """The height layer at a point (None over nodata or outside)."""

        def done(answer: dict) -> None:
            samples = answer.get("samples") or [{}]
            height = samples[0].get("heightM")
            callback(None if height is None else float(height))

        query = urlencode({"points": f"{lon_deg!r},{lat_deg!r}"})
        self._get("/api/elevation?" + query, done, on_error=lambda _: callback(None))

    # ------------------------------------------------------------ plumbing

    def _request(self, path: str) -> QNetworkRequest:
        request = self._credentials.apply(QNetworkRequest(QUrl(base_url(self._address) + path)))
        # An unreachable host fails in seconds, not the system's minutes.
        request.setTransferTimeout(REQUEST_TIMEOUT_MS)
        return request

    def _get(self, path: str, callback: Callable[[dict], None], on_error: Optional[Callable[[str], None]] = None) -> None:
        self._track(self._manager.get(self._request(path)), callback, on_error)

    def _send(self, verb: str, path: str, body: dict, callback: Optional[Callable[[dict], None]] = None) -> None:
        request = self._request(path)
        request.setHeader(QNetworkRequest.ContentTypeHeader, "application/json")
        data = QByteArray(json.dumps(body).encode("utf-8"))
        self._track(self._manager.sendCustomRequest(request, verb.encode("ascii"), data), callback, None)

    def _track(
        self,
        reply: QNetworkReply,
        callback: Optional[Callable[[dict], None]],
        on_error: Optional[Callable[[str], None]],
    ) -> None:
        # Held until it ends: PyQt would let the garbage collector take a
        # reply only its own slot refers to, and the request with it.
        self._pending.add(reply)
        epoch = self._epoch

        def finished() -> None:
            self._pending.discard(reply)
            reply.deleteLater()
            if epoch != self._epoch:
                return  # Asked before a restart: no longer ours.
            status = reply.attribute(QNetworkRequest.HttpStatusCodeAttribute)
            if reply.error() != QNetworkReply.NoError:
                if is_refusal(reply) == 401:
                    self.refused = 401
                why = error_text(reply)
                if on_error is not None:
                    on_error(why)
                elif not status:
                    self._down(why)  # Not answered: the daemon is down.
                else:
                    self.failed.emit(why)
                return
            try:
                answer = json.loads(bytes(reply.readAll()).decode("utf-8") or "{}")
            except ValueError as e:
                self.failed.emit(f"reliefd's answer could not be read: {e}")
                return
            if callback is not None:
                callback(answer)

        reply.finished.connect(finished)


def _keep_tls_errors(reply: QNetworkReply, errors: list) -> None:
    """Keeps Qt's reasons on the reply (the reply itself only says "SSL
    handshake failed"); the certificate stays refused."""
    reply.setProperty(TLS_ERRORS, "; ".join(e.errorString() for e in errors))


def _message(data: str) -> str:
    try:
        return str(json.loads(data)["message"])
    except (ValueError, KeyError, TypeError):
        return data

