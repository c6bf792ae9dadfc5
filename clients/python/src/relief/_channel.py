"""What the sync and asyncio clients share: the address, TLS and token,
the channel and the services' stubs on it, default timeouts and request
checks."""

from __future__ import annotations

import ipaddress
import math
import os
from dataclasses import dataclass
from types import ModuleType
from typing import Any, Generic, TypeVar

import grpc

from relief._proto.relief.v1 import relief_pb2_grpc as pb_grpc

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


#: The environment variables read when a client is given no token or CA.
TOKEN_ENV = "RELIEF_TOKEN"
CA_ENV = "RELIEF_CA"


@dataclass(frozen=True)
class Endpoint:
    """Where a client connects and how: the gRPC target ("HOST:PORT"),
    TLS or plaintext, the CA certificates to trust (None: the system's),
    and the bearer token to send (None: none)."""

    target: str
    tls: bool
    root_certificates: bytes | None
    token: str | None

    def __repr__(self) -> str:
        # Never the token itself: reprs end up in logs.
        token = "set" if self.token else "none"
        return f"Endpoint(target={self.target!r}, tls={self.tls}, token={token})"


def target(address: str | None) -> tuple[str, bool | None]:
    """A gRPC target from an address as users write it, and what its
    scheme says of TLS: "HOST:PORT" (None: not said), "http://HOST:PORT"
    or "grpc://HOST:PORT" (False), "https://HOST:PORT" (True). None is
    RELIEF_SERVER, as the CLI reads it, else 127.0.0.1:50051."""
    text = (address or os.environ.get("RELIEF_SERVER") or DEFAULT_ADDRESS).strip()
    tls: bool | None = None
    for scheme, secure in (("https://", True), ("http://", False), ("grpc://", False)):
        if text.lower().startswith(scheme):
            text, tls = text[len(scheme) :], secure
            break
    text = text.rstrip("/")
    if not text or "/" in text:
        raise ValueError(f"address {address!r} is not HOST:PORT or a URL of reliefd's port with no path")
    return text, tls


def read_ca(ca: str | os.PathLike[str] | bytes) -> bytes:
    """PEM certificates to trust: `ca` itself when bytes, else the file it
    names."""
    if isinstance(ca, bytes):
        pem, where = ca, "the CA certificate given"
    else:
        path = os.fspath(ca)
        try:
            with open(path, "rb") as f:
                pem = f.read()
        except OSError as e:
            raise ValueError(f"cannot read the CA certificate: {e.strerror or e}: {path}") from None
        where = f"the CA file {path}"
    if b"-----BEGIN CERTIFICATE-----" not in pem:
        raise ValueError(f"{where} holds no PEM certificate (-----BEGIN CERTIFICATE-----)")
    return pem


def check_token(token: str) -> str:
    """The token as sent: surrounding white space dropped (a token read
    from a file keeps its newline), anything else that cannot go in a
    header refused."""
    token = token.strip()
    if not token.isprintable() or not token.isascii() or any(c.isspace() for c in token):
        raise ValueError("the token holds white space or characters that cannot be sent in a header")
    return token


def is_loopback(target_: str) -> bool:
    """Whether "HOST:PORT" is this machine's (localhost, 127.0.0.0/8, ::1):
    nobody else is on the path to it."""
    host = target_.rsplit(":", 1)[0] if target_.count(":") == 1 or target_.startswith("[") else target_
    host = host.strip("[]")
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def endpoint(
    address: str | None,
    *,
    token: str | None = None,
    ca: str | os.PathLike[str] | bytes | None = None,
    tls: bool | None = None,
    insecure: bool = False,
) -> Endpoint:
    """How to reach reliefd at `address` (see `target`).

    TLS when the address is https://, when `tls` is True, or when a CA is
    given (`ca`, else the file RELIEF_CA names) to an address without a
    scheme; plaintext for http:// or grpc://, or when `tls` is False (the
    RELIEF_CA variable is then not read). `ca` is PEM bytes or a PEM file's
    path; TLS without one trusts the system's certificates.

    `token` is sent as `authorization: Bearer TOKEN` on every call; None
    reads RELIEF_TOKEN, "" sends none. A token never goes in plaintext to
    another machine (anyone on the path could read and use it): that is
    refused unless `insecure` is True."""
    where, said = target(address)
    if said is not None and tls is not None and said != tls:
        raise ValueError(f"address {address!r} says {'TLS' if said else 'plaintext'} but tls={tls} was asked")
    secure = said if said is not None else tls
    if ca is not None and secure is False:
        raise ValueError(f"a CA was given for the plaintext address {address!r}: use https://HOST:PORT")
    if ca is None and secure is not False:
        env_ca = os.environ.get(CA_ENV, "").strip()
        ca = env_ca or None
    if secure is None:
        secure = ca is not None
    if token is None:
        token = os.environ.get(TOKEN_ENV, "")
    token = check_token(token) if token.strip() else None
    if token is not None and not secure and not insecure and not is_loopback(where):
        raise ValueError(
            f"refusing to send the token over plaintext to {where}: anyone on the path could read it and use it; "
            "serve reliefd with TLS (--tls-cert, --tls-key) and use https://, or pass insecure=True to send it anyway"
        )
    return Endpoint(where, secure, read_ca(ca) if ca is not None else None, token)


def open_channel(endpoint: Endpoint, grpc_module: ModuleType, **extra: Any) -> Any:
    """A channel to `endpoint` made by `grpc_module`: `grpc` for a blocking
    channel, `grpc.aio` for an asyncio one (the two differ only in their
    constructors). Over TLS trusting the endpoint's CA (None: the system's
    certificates), else plaintext; with CHANNEL_OPTIONS. `extra` goes to the
    constructor as it is (grpc.aio's `interceptors`)."""
    if endpoint.tls:
        credentials = grpc.ssl_channel_credentials(root_certificates=endpoint.root_certificates)
        return grpc_module.secure_channel(endpoint.target, credentials, options=CHANNEL_OPTIONS, **extra)
    return grpc_module.insecure_channel(endpoint.target, options=CHANNEL_OPTIONS, **extra)


ChannelT = TypeVar("ChannelT")


class Connection(Generic[ChannelT]):
    """What a client is built on, blocking or asyncio: where it connects
    (`endpoint`, `address`), the default timeout of its calls, its channel
    and the stubs of the three services on it. Each client opens its
    channel in `_open` (through `open_channel`). The arguments are those of
    relief.Client, documented there."""

    def __init__(
        self,
        address: str | None = None,
        *,
        timeout: float = DEFAULT_TIMEOUT_S,
        token: str | None = None,
        ca: str | os.PathLike[str] | bytes | None = None,
        tls: bool | None = None,
        insecure: bool = False,
    ) -> None:
        self.endpoint = endpoint(address, token=token, ca=ca, tls=tls, insecure=insecure)
        self.address = self.endpoint.target
        self.timeout = timeout
        self._channel = self._open(self.endpoint)
        self._scene = pb_grpc.SceneServiceStub(self._channel)
        self._view = pb_grpc.ViewServiceStub(self._channel)
        self._tiles = pb_grpc.TileServiceStub(self._channel)

    def _open(self, to: Endpoint) -> ChannelT:
        """The channel to `to` that sends its bearer token, if any, on
        every call."""
        raise NotImplementedError


def unreachable(endpoint: Endpoint, timeout: float) -> str:
    """Why a connection did not come up within `timeout` seconds."""
    text = f"cannot reach reliefd at {endpoint.target} within {timeout:g} s"
    if endpoint.tls:
        trusted = "the CA given" if endpoint.root_certificates is not None else "the system's certificates"
        text += (
            f" over TLS (is it serving TLS, and is its certificate signed by {trusted} "
            f"for the host name '{endpoint.target.rsplit(':', 1)[0]}'?)"
        )
    return text


def metadata(token: str) -> tuple[str, str]:
    """The metadata entry that carries a bearer token."""
    return ("authorization", f"Bearer {token}")


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
