"""The daemon's address as the user types it (`host:port`, or a URL for
https://) and the URL the plugin calls. An address without a port gets
reliefd's own default port (`reliefd serve` listens on 127.0.0.1:50051),
never HTTP's 80, and the dock says so."""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass
from urllib.parse import urlsplit

#: The port `reliefd serve` listens on when given no --listen.
DEFAULT_PORT = 50051
#: Where a fresh install looks for reliefd (`reliefd serve`'s default).
DEFAULT_ADDRESS = f"127.0.0.1:{DEFAULT_PORT}"


@dataclass(frozen=True)
class Address:
    """What an address typed in the dock means: the URL the calls hang from
    (`scheme://host:port`, no trailing /), what was assumed to get it
    ("" when nothing was), or why it cannot be used ("" when it can)."""

    url: str
    note: str = ""
    error: str = ""


def parse_address(typed: str) -> Address:
    text = typed.strip().rstrip("/")
    if not text:
        return Address("", error="no address: enter reliefd's host:port (for example 127.0.0.1:50051)")
    url = text if "://" in text else f"http://{text}"
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError:
        return Address("", error=f"'{text}' is not an address: use host:port (for example 127.0.0.1:50051)")
    if parts.scheme not in ("http", "https"):
        return Address("", error=f"'{text}': reliefd speaks http:// or https://, not {parts.scheme}://")
    host = parts.hostname or ""
    if not host:
        return Address("", error=f"'{text}' names no host: use host:port (for example 127.0.0.1:50051)")
    note = ""
    if port is None:
        port = DEFAULT_PORT
        note = f"no port given in '{text}': using reliefd's default port {DEFAULT_PORT}"
    shown = f"[{host}]" if ":" in host else host
    return Address(f"{parts.scheme}://{shown}:{port}{parts.path}", note=note)


def base_url(address: str) -> str:
    """`host:port` or a URL, as the URL the calls hang from (no trailing /);
    an address that cannot be used gives ""."""
    return parse_address(address).url


def is_loopback(host: str) -> bool:
    """Whether `host` is this machine (localhost, 127.0.0.0/8, ::1)."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False
