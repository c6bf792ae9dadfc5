"""Server-Sent Events, parsed as bytes arrive (the daemon's /api/frames and
/api/events streams). Plain Python: no Qt, so it is tested on its own."""

from __future__ import annotations


class SseParser:
    """Feeds on chunks of a text/event-stream body and returns the events
    each chunk completes, as (event name, data) pairs. Comments (the
    daemon's keep-alives) and fields other than `event` and `data` are
    skipped; an event without a name is called "message", as in browsers."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        #: Where the search for the next line end resumes (a frame is one
        #: long line that arrives in many chunks: never search it twice).
        self._scanned = 0
        self._name = ""
        self._data: list[str] = []

    def feed(self, chunk: bytes) -> list[tuple[str, str]]:
        self._buffer += chunk
        events: list[tuple[str, str]] = []
        start = 0
        while True:
            end = self._buffer.find(b"\n", max(start, self._scanned))
            if end < 0:
                break
            line = bytes(self._buffer[start:end]).rstrip(b"\r").decode("utf-8", errors="replace")
            start = end + 1
            self._line(line, events)
        del self._buffer[:start]
        self._scanned = len(self._buffer)
        return events

    def _line(self, line: str, events: list[tuple[str, str]]) -> None:
        if not line:
            if self._data:
                events.append((self._name or "message", "\n".join(self._data)))
            self._name, self._data = "", []
            return
        if line.startswith(":"):
            return
        field, _, value = line.partition(":")
        value = value[1:] if value.startswith(" ") else value
        if field == "event":
            self._name = value
        elif field == "data":
            self._data.append(value)
