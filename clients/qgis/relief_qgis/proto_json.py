"""Reading reliefd's JSON (the proto3 JSON mapping) the one way.

proto3 JSON leaves out every field that holds its default: a heading of 0,
a generation of 0, `active: false`, an empty error string, an empty list.
A missing field therefore means its default, never "unknown" or "no
change": a missing number reads as 0, a missing bool as false, a missing
string as "", a missing list as [] and a missing message as {}. 64-bit
integers arrive as strings ("3"). Only fields declared `optional` in the
proto (ElevationSample.height_m) keep their presence: `optional_number`
reads those, None when absent.

Every place in the plugin that reads JSON from reliefd goes through these."""

from __future__ import annotations

from typing import Any, Optional


def message(obj: Any, name: str) -> dict:
    """A sub-message ({} when missing or not an object)."""
    value = obj.get(name) if isinstance(obj, dict) else None
    return value if isinstance(value, dict) else {}


def items(obj: Any, name: str) -> list:
    """A repeated field ([] when missing)."""
    value = obj.get(name) if isinstance(obj, dict) else None
    return value if isinstance(value, list) else []


def number(obj: Any, name: str) -> float:
    """A double or float field (0.0 when missing, null or not a number)."""
    value = optional_number(obj, name)
    return 0.0 if value is None else value


def integer(obj: Any, name: str) -> int:
    """An integer field, 64-bit ones as strings (0 when missing)."""
    value = obj.get(name) if isinstance(obj, dict) else None
    try:
        return int(value) if value is not None and not isinstance(value, bool) else 0
    except (TypeError, ValueError):
        return 0


def flag(obj: Any, name: str) -> bool:
    """A bool field (false when missing)."""
    value = obj.get(name) if isinstance(obj, dict) else None
    return value is True


def text(obj: Any, name: str) -> str:
    """A string or enum field ("" when missing)."""
    value = obj.get(name) if isinstance(obj, dict) else None
    return "" if value is None else str(value)


def optional_number(obj: Any, name: str) -> Optional[float]:
    """A number whose absence means something (a proto3 `optional` field):
    None when missing; "NaN" and "Infinity" as the mapping writes them."""
    value = obj.get(name) if isinstance(obj, dict) else None
    if value is None or isinstance(value, bool):
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        return None
