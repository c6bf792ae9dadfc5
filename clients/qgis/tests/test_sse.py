"""The Server-Sent Events parser, fed as a socket would feed it."""

from __future__ import annotations

from conftest import PLUGIN  # noqa: F401 (the plugin's folder is on sys.path)
from relief_qgis.sse import SseParser

STREAM = (
    b": keep-alive\n\n"
    b"event: frame\ndata: {\"generation\":\"3\"}\n\n"
    b"event: error\r\ndata: {\"code\":\"NOT_FOUND\",\r\ndata: \"message\":\"x\"}\r\n\r\n"
    b"data: plain\n\n"
)
EXPECTED = [
    ("frame", '{"generation":"3"}'),
    ("error", '{"code":"NOT_FOUND",\n"message":"x"}'),
    ("message", "plain"),
]


def test_a_whole_stream() -> None:
    assert SseParser().feed(STREAM) == EXPECTED


def test_any_split_of_the_bytes_gives_the_same_events() -> None:
    for cut in range(1, len(STREAM)):
        parser = SseParser()
        assert parser.feed(STREAM[:cut]) + parser.feed(STREAM[cut:]) == EXPECTED, cut


def test_one_byte_at_a_time_and_utf8_split_across_chunks() -> None:
    parser = SseParser()
    data = "event: scene\ndata: Bialowieża ✓\n\n".encode("utf-8")
    events = [e for i in range(len(data)) for e in parser.feed(data[i : i + 1])]
    assert events == [("scene", "Bialowieża ✓")]


def test_an_unfinished_event_waits_for_its_blank_line() -> None:
    parser = SseParser()
    assert parser.feed(b"event: frame\ndata: 1\n") == []
    assert parser.feed(b"\n") == [("frame", "1")]


def test_a_frame_sized_event_in_small_chunks() -> None:
    # A 4 MB frame (one long base64 line) in 16 KB chunks, as a socket
    # gives it: the one event comes out whole (and in linear time).
    data = b"A" * (4 << 20)
    stream = b"event: frame\ndata: " + data + b"\n\n"
    parser = SseParser()
    events = [e for i in range(0, len(stream), 16384) for e in parser.feed(stream[i : i + 16384])]
    assert len(events) == 1 and events[0][0] == "frame" and len(events[0][1]) == len(data)
