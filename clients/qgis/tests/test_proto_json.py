"""proto3 JSON as reliefd writes it: a field at its default is left out,
so a missing number reads as 0, a bool as false, a string as "", a list as
[] and a message as {}; only `optional` fields keep their absence. And the
daemon's address as the dock reads it."""

from __future__ import annotations

import pytest
from conftest import PLUGIN  # noqa: F401 (the plugin's folder is on sys.path)
from relief_qgis import proto_json as pj
from relief_qgis.address import DEFAULT_PORT, parse_address

# A frame's camera looking north at the horizon, as proto3 JSON writes it.
CAMERA = {"lonDeg": 10.25, "latDeg": 45.1, "altitudeM": 9000, "verticalFovDeg": 50}


def test_missing_fields_read_as_their_defaults() -> None:
    assert pj.number(CAMERA, "headingDeg") == 0.0
    assert pj.number(CAMERA, "pitchDeg") == 0.0
    assert pj.number(CAMERA, "altitudeM") == 9000.0
    assert pj.integer({}, "generation") == 0
    assert pj.flag({"id": "dem"}, "active") is False
    assert pj.text({"id": "dem"}, "error") == ""
    assert pj.items({}, "sources") == []
    assert pj.message({}, "camera") == {}


def test_values_as_the_mapping_writes_them() -> None:
    assert pj.integer({"generation": "12"}, "generation") == 12  # 64-bit integers are strings
    assert pj.number({"x": "NaN"}, "x") != pj.number({"x": "NaN"}, "x")  # NaN
    assert pj.number({"x": "-Infinity"}, "x") == float("-inf")
    assert pj.flag({"active": True}, "active") is True
    assert pj.text({"status": "SOURCE_STATUS_READY"}, "status") == "SOURCE_STATUS_READY"
    assert pj.items({"files": ["a.tif"]}, "files") == ["a.tif"]


def test_wrong_kinds_read_as_defaults_rather_than_raise() -> None:
    assert pj.number({"x": "north"}, "x") == 0.0
    assert pj.number({"x": True}, "x") == 0.0
    assert pj.integer({"x": "many"}, "x") == 0
    assert pj.items({"x": "a"}, "x") == [] and pj.message({"x": [1]}, "x") == {}
    assert pj.number(None, "x") == 0.0 and pj.text([], "x") == ""


def test_an_optional_field_keeps_its_absence() -> None:
    assert pj.optional_number({}, "heightM") is None  # nodata
    assert pj.optional_number({"heightM": 0}, "heightM") == 0.0  # sea level, given
    assert pj.optional_number({"heightM": 512.5}, "heightM") == 512.5


@pytest.mark.parametrize(
    ("typed", "url"),
    [
        ("127.0.0.1:50051", "http://127.0.0.1:50051"),
        (" localhost:7000/ ", "http://localhost:7000"),
        ("https://relief.example.org:8443", "https://relief.example.org:8443"),
        ("[::1]:50051", "http://[::1]:50051"),
    ],
)
def test_an_address_with_a_port(typed: str, url: str) -> None:
    address = parse_address(typed)
    assert (address.url, address.note, address.error) == (url, "", "")


@pytest.mark.parametrize("typed", ["localhost", "http://localhost", "https://relief.example.org"])
def test_an_address_without_a_port_gets_reliefds_not_https(typed: str) -> None:
    address = parse_address(typed)
    assert address.url.endswith(f":{DEFAULT_PORT}") and not address.error
    assert f"using reliefd's default port {DEFAULT_PORT}" in address.note


@pytest.mark.parametrize(
    ("typed", "says"),
    [
        ("", "no address"),
        ("host:port", "is not an address"),
        ("ftp://host:21", "not ftp://"),
        (":50051", "names no host"),
    ],
)
def test_an_address_that_cannot_be_used_says_why(typed: str, says: str) -> None:
    address = parse_address(typed)
    assert address.url == "" and says in address.error, address
