"""The plugin's one connection to reliefd: its HTTP transport (the same calls
as gRPC, as JSON, streams as Server-Sent Events), through Qt's own network
stack. Nothing here blocks: every request answers through a signal or a
callback on the UI thread's event loop.

Two streams run while the daemon is up: /api/frames (a view opened to
follow the scene camera, pushed, PNG) and /api/events (the scene's generations and source
errors; each is followed by one GET /api/state), and a heartbeat
(GET /api/camera every second) that notices a daemon that hangs with its
streams open. When a stream ends or fails, or a heartbeat goes unanswered
for 3.5 s, the link reports the daemon down, stops everything and retries
GET /api/state with a growing delay until it answers (`retry_now` at once).
While the dock is hidden the frame stream is closed.

A reliefd serving with --token-file wants `Authorization: Bearer TOKEN` on
every request, the streams included (Qt sets headers on them, so the token
never goes in a URL); one refused (HTTP 401) is reported as such, with what
to do. An https:// address speaks TLS through Qt's own TLS, trusting the
system's CA certificates and, when given, those of a PEM file."""

from __future__ import annotations

import base64
import json
from typing import Callable, Optional
from urllib.parse import urlencode

from qgis.PyQt.QtCore import QByteArray, QObject, QTimer, QUrl, pyqtSignal
from qgis.PyQt.QtGui import QImage
from qgis.PyQt.QtNetwork import QNetworkAccessManager, QNetworkReply, QNetworkRequest

from . import proto_json as pj
from .address import DEFAULT_ADDRESS, parse_address
from .credentials import Credentials
from .replies import error_text, event_message, is_refusal, keep_tls_errors, not_relief
from .stream import EventStream

__all__ = ["DEFAULT_ADDRESS", "Backoff", "DaemonLink"]

#: How long the first GET /api/state and each heartbeat may go unanswered
#: before the daemon counts as hung (seconds). With a heartbeat every
#: HEARTBEAT_MS, a daemon that stops answering is seen within 4.5 s.
ANSWER_TIMEOUT_S = 3.5
#: Heartbeats while the daemon is up (GET /api/camera, a few bytes): its
#: streams cannot tell a hung daemon from a quiet scene (reliefd's SSE
#: keep-alive comments come every 15 s, axum's default).
HEARTBEAT_MS = 1000
#: How long other calls may take (a reload may read every source).
CALL_TIMEOUT_S = 30.0
#: How long a height lookup for Follow map may take.
ELEVATION_TIMEOUT_S = 5.0


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


class DaemonLink(QObject):
    """reliefd at one address. Signals carry decoded JSON (proto3 JSON
    mapping, read with proto_json: a missing field is its default)."""

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
        self._manager.sslErrors.connect(keep_tls_errors)
        self._address = address.strip()
        self._target = parse_address(self._address)
        self._credentials = Credentials(token, ca_file)
        #: 401 or 403 while the daemon refuses the token, else 0.
        self.refused = 0
        # Landscape, as the dock's frame is (it asks for its own size once laid out).
        self._size = (640, 360)
        self._max_fps = 10.0
        #: Whether frames are wanted (the dock is shown): hidden, the frame
        #: stream is closed and the rest (state, heartbeat) goes on.
        self._frames_wanted = True
        self._streams: dict[str, EventStream] = {}
        self._pending: set[QNetworkReply] = set()
        self._view_id = ""
        #: Bumped on every restart and stop: answers to requests made
        #: before are dropped (an old address's late failure must not tear
        #: down the new connection).
        self._epoch = 0
        self._running = False
        self._up: Optional[bool] = None
        #: GET /api/state probes sent so far (the first and each retry).
        self.probes = 0
        self.backoff = Backoff()
        self._retry = QTimer(self)
        self._retry.setSingleShot(True)
        self._retry.timeout.connect(self._probe)
        self._heartbeat = QTimer(self)
        self._heartbeat.setInterval(HEARTBEAT_MS)
        self._heartbeat.timeout.connect(self._beat)
        self._beating = False

    # ------------------------------------------------------------ settings

    @property
    def address(self) -> str:
        return self._address

    @property
    def url(self) -> str:
        """The URL the calls go to ("" while the address cannot be used)."""
        return self._target.url

    @property
    def address_note(self) -> str:
        """What was assumed of the address (a default port), or why it
        cannot be used; "" when neither."""
        return self._target.error or self._target.note

    @property
    def is_up(self) -> bool:
        return bool(self._up)

    @property
    def frame_size(self) -> tuple[int, int]:
        return self._size

    @property
    def streaming_frames(self) -> bool:
        """Whether the frame stream is open now."""
        return "frames" in self._streams

    def set_address(self, address: str) -> None:
        if address.strip() == self._address:
            return
        self._address = address.strip()
        self._target = parse_address(self._address)
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

    def set_frames_wanted(self, wanted: bool) -> None:
        """Frames only while someone looks: False closes the frame stream
        (the dock is hidden or closed), True opens it again."""
        if wanted == self._frames_wanted:
            return
        self._frames_wanted = wanted
        if not wanted:
            stream = self._streams.pop("frames", None)
            if stream is not None:
                stream.close()
        elif self._running and self._up and self._view_id:
            self._open_frames()

    # ------------------------------------------------------------ lifetime

    def start(self) -> None:
        self._running = True
        self._restart()

    def stop(self) -> None:
        self._running = False
        self._retry.stop()
        self._heartbeat.stop()
        self._forget_requests()
        self._close_streams()

    def retry_now(self) -> None:
        """Connects again at once, whatever the backoff's delay."""
        if self._running:
            self._restart()

    def _restart(self) -> None:
        self._forget_requests()
        self._close_streams()
        self._retry.stop()
        self._heartbeat.stop()
        self.backoff.reset()
        self._up = None
        self._probe()

    def _forget_requests(self) -> None:
        self._epoch += 1
        self._view_id = ""
        self._beating = False
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
        if self._target.error:
            # Nothing to retry until the address changes.
            self._up = False
            self.reachable.emit(False, f"reliefd: {self._target.error}")
            return
        if self._credentials.ca_error:
            self._down(self._credentials.ca_error)
            return
        refusal = self._credentials.refusal(self.url)
        if refusal:
            self._down(refusal)
            return
        self.probes += 1
        self._get("/api/state", self._probed, on_error=lambda why, _: self._down(why), timeout_s=ANSWER_TIMEOUT_S)

    def _probed(self, state: dict) -> None:
        if not self._running:
            return
        if not any(key in state for key in ("grid", "sources", "name", "generation")):
            # Something answered JSON, but not a scene state.
            self._down(not_relief(self.url, "its /api/state is not a relief scene state"))
            return
        self.refused = 0
        # The state first: what listens to `reachable` may read it.
        self.state.emit(state)
        self._set_up(True, "")
        # The dock's own view of the scene camera: its frames carry depth, so
        # the sliders turn the camera about the ground drawn at their centre.
        self._send("POST", "/api/views", {"followSceneCamera": True}, self._view_opened)
        self._open_events()
        self._heartbeat.start()

    def _view_opened(self, view: dict) -> None:
        self._view_id = pj.text(view, "viewId")
        if self._running and self._view_id and self._frames_wanted:
            self._open_frames()

    def _beat(self) -> None:
        """One heartbeat: a daemon that answers nothing for ANSWER_TIMEOUT_S
        is down (its streams stay open and silent when it hangs)."""
        if not self._running or not self._up or self._beating:
            return
        self._beating = True

        def answered(_: dict) -> None:
            self._beating = False

        def unanswered(why: str, status: int) -> None:
            self._beating = False
            if not status:  # An answer, even an error, is a daemon alive.
                self._down(why)

        self._get("/api/camera", answered, on_error=unanswered, timeout_s=ANSWER_TIMEOUT_S)

    def _down(self, why: str) -> None:
        self._close_streams()
        self._heartbeat.stop()
        if not self._running or (self._up is False and self._retry.isActive()):
            return  # Already waiting to try again.
        # A hung daemon keeps its requests open: drop them with the streams.
        self._forget_requests()
        delay = self.backoff.take()
        url = self.url
        if self.refused == 401:
            what = "the token is wrong" if self._credentials.token else "it wants a token"
            message = (
                f"reliefd at {url}: {why}; {what}: enter one of its token file in the dock's "
                f"Token field; trying again in {delay:g} s"
            )
        elif url and url in why:
            message = f"{why}; trying again in {delay:g} s"
        else:
            message = f"reliefd at {url}: not reachable or not drawing ({why}); trying again in {delay:g} s"
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
        stream = EventStream(self._manager, self.url, path, self._credentials, self)
        stream.received.connect(on_event)
        stream.ended.connect(lambda why, s=stream: self._ended(s, why))
        self._streams[name] = stream

    def _ended(self, stream: EventStream, why: str) -> None:
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
            self.failed.emit(event_message(data))
            return
        try:
            message = json.loads(data)
            image = QImage.fromData(QByteArray(base64.b64decode(pj.text(message, "image"))), "PNG")
        except (ValueError, TypeError) as e:
            self.failed.emit(f"a frame from reliefd could not be read: {e}")
            return
        if image.isNull():
            self.failed.emit("a frame from reliefd is not a PNG image")
            return
        self.backoff.reset()
        self.frame.emit(image, pj.integer(message, "generation"), pj.message(message, "camera"))

    def _on_scene_event(self, name: str, data: str) -> None:
        if name == "error":
            self.failed.emit(event_message(data))
            return
        try:
            message = json.loads(data)
        except ValueError:
            return
        snapshot = pj.message(message, "snapshot")
        if snapshot:
            self.state.emit(snapshot)
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

    def elevation(self, lon_deg: float, lat_deg: float, callback: Callable[[Optional[float], str], None]) -> None:
        """The height layer at a point: callback(height, "") when known;
        callback(None, why) over nodata, outside the scene, or when the
        lookup failed (an error or no answer in time)."""

        def done(answer: dict) -> None:
            samples = pj.items(answer, "samples")
            height = pj.optional_number(samples[0], "heightM") if samples else None
            callback(height, "" if height is not None else "the height layer has no data there")

        query = urlencode({"points": f"{lon_deg!r},{lat_deg!r}"})
        self._get(
            "/api/elevation?" + query, done, on_error=lambda why, _: callback(None, why), timeout_s=ELEVATION_TIMEOUT_S
        )

    # ------------------------------------------------------------ plumbing

    def _request(self, path: str, timeout_s: float) -> QNetworkRequest:
        request = self._credentials.apply(QNetworkRequest(QUrl(self.url + path)))
        # An unreachable or hung host fails in seconds, not the system's minutes.
        request.setTransferTimeout(int(timeout_s * 1000))
        return request

    def _get(
        self,
        path: str,
        callback: Callable[[dict], None],
        on_error: Optional[Callable[[str, int], None]] = None,
        timeout_s: float = CALL_TIMEOUT_S,
    ) -> None:
        self._track(self._manager.get(self._request(path, timeout_s)), timeout_s, callback, on_error)

    def _send(self, verb: str, path: str, body: dict, callback: Optional[Callable[[dict], None]] = None) -> None:
        request = self._request(path, CALL_TIMEOUT_S)
        request.setHeader(QNetworkRequest.ContentTypeHeader, "application/json")
        data = QByteArray(json.dumps(body).encode("utf-8"))
        reply = self._manager.sendCustomRequest(request, verb.encode("ascii"), data)
        self._track(reply, CALL_TIMEOUT_S, callback, None)

    def _track(
        self,
        reply: QNetworkReply,
        timeout_s: float,
        callback: Optional[Callable[[dict], None]],
        on_error: Optional[Callable[[str, int], None]],
    ) -> None:
        # Held until it ends: PyQt would let the garbage collector take a
        # reply only its own slot refers to, and the request with it.
        self._pending.add(reply)
        epoch, url = self._epoch, self.url

        def finished() -> None:
            self._pending.discard(reply)
            reply.deleteLater()
            if epoch != self._epoch:
                return  # Asked before a restart: no longer ours.
            status = reply.attribute(QNetworkRequest.HttpStatusCodeAttribute)
            if reply.error() != QNetworkReply.NoError:
                if is_refusal(reply) == 401:
                    self.refused = 401
                why = error_text(reply, url, timeout_s)
                if on_error is not None:
                    on_error(why, int(status or 0))
                elif not status:
                    self._down(why)  # Not answered: the daemon is down.
                else:
                    self.failed.emit(why)
                return
            try:
                answer = json.loads(bytes(reply.readAll()).decode("utf-8") or "{}")
            except (ValueError, UnicodeDecodeError):
                why = not_relief(url, "its answer is not JSON")
                if on_error is not None:
                    on_error(why, int(status or 200))
                else:
                    self.failed.emit(why)
                return
            if callback is not None:
                callback(answer if isinstance(answer, dict) else {})

        reply.finished.connect(finished)
