"""One Server-Sent Events request to reliefd (/api/frames, /api/events)
through Qt's network stack, parsed as its bytes arrive. Streams have no
transfer timeout (a quiet scene sends nothing for a while): the link's
heartbeat notices a daemon that hangs."""

from __future__ import annotations

from qgis.PyQt.QtCore import QObject, QUrl, pyqtSignal
from qgis.PyQt.QtNetwork import QNetworkAccessManager, QNetworkReply, QNetworkRequest

from .credentials import Credentials
from .replies import error_text, event_message, is_refusal
from .sse import SseParser


class EventStream(QObject):
    """One Server-Sent Events request; `received` for each event, `ended`
    (with the reason) once when it stops by itself."""

    received = pyqtSignal(str, str)
    ended = pyqtSignal(str)

    def __init__(self, manager: QNetworkAccessManager, base: str, path: str, credentials: Credentials, parent: QObject) -> None:
        super().__init__(parent)
        self._base = base
        request = credentials.apply(QNetworkRequest(QUrl(base + path)))
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
                self.error = event_message(data)
            self.received.emit(name, data)

    def _finished(self) -> None:
        if self._closing:
            return
        self._closing = True
        failed = self._reply.error() != QNetworkReply.NoError
        self.refused = is_refusal(self._reply)
        if self.error:
            self.ended.emit(f"it answered: {self.error}")
        elif failed:
            self.ended.emit(error_text(self._reply, self._base, 0.0))
        else:
            self.ended.emit("the daemon ended the stream")
        self._reply.deleteLater()

    def close(self) -> None:
        if not self._closing:
            self._closing = True
            self._reply.abort()
            self._reply.deleteLater()
        self.deleteLater()
