"""What the sync and asyncio clients share: the address, channel options,
default timeouts and request checks."""

from __future__ import annotations

import math
import os

#: Where clients connect when given no address (as the `relief` CLI).
DEFAULT_ADDRESS = "127.0.0.1:50051"

#: Seconds a unary call may take unless told otherwise.
DEFAULT_TIMEOUT_S = 30.0
#: Renders on Mesa's lavapipe (a CPU) take seconds at 1280 x 720.
RENDER_TIMEOUT_S = 120.0
#: The longest WaitForGeneration reliefd honours (its timeout_ms is capped there).
MAX_WAIT_S = 600.0

#: A 4096 x 4096 RGBA8 frame is 64 MiB; the default 4 MiB would refuse it.
CHANNEL_OPTIONS: list[tuple[str, int]] = [
    ("grpc.max_receive_message_length", 256 * 1024 * 1024),
    ("grpc.max_send_message_length", 256 * 1024 * 1024),
]


def target(address: str | None) -> str:
    """A gRPC target from an address as users write it: "HOST:PORT", or a
    URL such as "http://127.0.0.1:50051" (RELIEF_SERVER, as the CLI reads it)."""
    text = (address or os.environ.get("RELIEF_SERVER") or DEFAULT_ADDRESS).strip()
    for scheme in ("http://", "grpc://"):
        if text.startswith(scheme):
            text = text[len(scheme) :]
    if text.startswith("https://"):
        raise ValueError(f"address {text!r}: reliefd speaks plaintext gRPC; give HOST:PORT")
    return text.rstrip("/")


def wait_request(generation: int, timeout: float) -> tuple[int, int]:
    """(min_generation, timeout_ms) for WaitForGeneration."""
    if generation < 0:
        raise ValueError(f"generation {generation} is negative")
    if not (math.isfinite(timeout) and timeout >= 0):
        raise ValueError(f"timeout {timeout} is not a number of seconds")
    ms = min(int(round(timeout * 1000.0)), int(MAX_WAIT_S * 1000))
    return generation, ms


def deadline_for_wait(timeout: float) -> float:
    """The client-side deadline of a WaitForGeneration: the server answers
    DEADLINE_EXCEEDED itself after `timeout`; this leaves it time to."""
    return min(timeout, MAX_WAIT_S) + 10.0
