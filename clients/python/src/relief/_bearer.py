"""The bearer token on every call: interceptors that add
`authorization: Bearer TOKEN` to each call's metadata, for grpc's blocking
channels and for grpc.aio's. (gRPC's call credentials would refuse a
plaintext channel; reliefd checks tokens over plaintext on loopback too.)"""

from __future__ import annotations

from typing import Any

import grpc
import grpc.aio

from relief._channel import metadata


class _CallDetails(grpc.ClientCallDetails):
    """A call's details with other metadata (grpc's class is abstract)."""

    def __init__(self, details: grpc.ClientCallDetails, extra: tuple[str, str]) -> None:
        self.method = details.method
        self.timeout = details.timeout
        self.metadata = (*(details.metadata or ()), extra)
        self.credentials = details.credentials
        self.wait_for_ready = getattr(details, "wait_for_ready", None)
        self.compression = getattr(details, "compression", None)


class Bearer(
    grpc.UnaryUnaryClientInterceptor,
    grpc.UnaryStreamClientInterceptor,
    grpc.StreamUnaryClientInterceptor,
    grpc.StreamStreamClientInterceptor,
):
    """Adds the token to every call of a blocking channel."""

    def __init__(self, token: str) -> None:
        self._metadata = metadata(token)

    def intercept_unary_unary(self, continuation: Any, client_call_details: Any, request: Any) -> Any:
        return continuation(_CallDetails(client_call_details, self._metadata), request)

    def intercept_unary_stream(self, continuation: Any, client_call_details: Any, request: Any) -> Any:
        return continuation(_CallDetails(client_call_details, self._metadata), request)

    def intercept_stream_unary(self, continuation: Any, client_call_details: Any, request_iterator: Any) -> Any:
        return continuation(_CallDetails(client_call_details, self._metadata), request_iterator)

    def intercept_stream_stream(self, continuation: Any, client_call_details: Any, request_iterator: Any) -> Any:
        return continuation(_CallDetails(client_call_details, self._metadata), request_iterator)


def _aio_details(details: grpc.aio.ClientCallDetails, extra: tuple[str, str]) -> grpc.aio.ClientCallDetails:
    entries = grpc.aio.Metadata(*(details.metadata or ()), extra)
    return grpc.aio.ClientCallDetails(
        details.method, details.timeout, entries, details.credentials, getattr(details, "wait_for_ready", None)
    )


class AioBearerUnaryUnary(grpc.aio.UnaryUnaryClientInterceptor):
    """Adds the token to every unary call of a grpc.aio channel."""

    def __init__(self, token: str) -> None:
        self._metadata = metadata(token)

    async def intercept_unary_unary(self, continuation: Any, client_call_details: Any, request: Any) -> Any:
        return await continuation(_aio_details(client_call_details, self._metadata), request)


class AioBearerUnaryStream(grpc.aio.UnaryStreamClientInterceptor):
    """Adds the token to every server-streaming call of a grpc.aio channel."""

    def __init__(self, token: str) -> None:
        self._metadata = metadata(token)

    async def intercept_unary_stream(self, continuation: Any, client_call_details: Any, request: Any) -> Any:
        return await continuation(_aio_details(client_call_details, self._metadata), request)


def aio_interceptors(token: str | None) -> list[grpc.aio.ClientInterceptor]:
    """The interceptors a grpc.aio channel takes for `token` (none without)."""
    if token is None:
        return []
    return [AioBearerUnaryUnary(token), AioBearerUnaryStream(token)]
