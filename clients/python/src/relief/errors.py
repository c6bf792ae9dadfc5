"""Errors: every gRPC status becomes a ReliefError, one subclass per code
the daemon answers, carrying the server's message (which names the field,
the source or the file)."""

from __future__ import annotations

import grpc


class ReliefError(Exception):
    """A call to reliefd failed. `code` is the gRPC status name (for example
    "INVALID_ARGUMENT"), `message` the server's own words, `method` the call."""

    code: str = "UNKNOWN"

    def __init__(self, message: str, *, method: str = "", code: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.method = method
        if code is not None:
            self.code = code

    def __str__(self) -> str:
        where = f" ({self.method})" if self.method else ""
        return f"{self.code}{where}: {self.message}"


class Cancelled(ReliefError):
    code = "CANCELLED"


class InvalidArgument(ReliefError):
    """A request field does not hold a usable value; the message names it."""

    code = "INVALID_ARGUMENT"


class DeadlineExceeded(ReliefError):
    """The call did not finish in time (WaitForGeneration's timeout, or the
    client's deadline)."""

    code = "DEADLINE_EXCEEDED"


class NotFound(ReliefError):
    """No source or view has the id given."""

    code = "NOT_FOUND"


class ResourceExhausted(ReliefError):
    """reliefd is busy: too many renders, views or frame memory."""

    code = "RESOURCE_EXHAUSTED"


class FailedPrecondition(ReliefError):
    """The scene cannot answer this now (a source with no data, a view with
    no frame yet)."""

    code = "FAILED_PRECONDITION"


class Unimplemented(ReliefError):
    code = "UNIMPLEMENTED"


class Internal(ReliefError):
    code = "INTERNAL"


class Unauthenticated(ReliefError):
    """reliefd wants a bearer token and got none, or one it does not accept
    (give `token=`, or set RELIEF_TOKEN)."""

    code = "UNAUTHENTICATED"


class PermissionDenied(ReliefError):
    """The token may only read: moving the scene camera, reloading and
    setting source parameters need a control token."""

    code = "PERMISSION_DENIED"


class Unavailable(ReliefError):
    """reliefd cannot be reached, is shutting down, or has no render device."""

    code = "UNAVAILABLE"


_BY_CODE: dict[grpc.StatusCode, type[ReliefError]] = {
    grpc.StatusCode.CANCELLED: Cancelled,
    grpc.StatusCode.INVALID_ARGUMENT: InvalidArgument,
    grpc.StatusCode.DEADLINE_EXCEEDED: DeadlineExceeded,
    grpc.StatusCode.NOT_FOUND: NotFound,
    grpc.StatusCode.RESOURCE_EXHAUSTED: ResourceExhausted,
    grpc.StatusCode.FAILED_PRECONDITION: FailedPrecondition,
    grpc.StatusCode.UNIMPLEMENTED: Unimplemented,
    grpc.StatusCode.INTERNAL: Internal,
    grpc.StatusCode.UNAVAILABLE: Unavailable,
    grpc.StatusCode.UNAUTHENTICATED: Unauthenticated,
    grpc.StatusCode.PERMISSION_DENIED: PermissionDenied,
}


def from_status(code: grpc.StatusCode, details: str | None, method: str = "") -> ReliefError:
    """The exception for a gRPC status."""
    cls = _BY_CODE.get(code, ReliefError)
    name = code.name if isinstance(code, grpc.StatusCode) else str(code)
    return cls(details or name.lower().replace("_", " "), method=method, code=name)


def from_rpc_error(error: grpc.RpcError, method: str = "") -> ReliefError:
    """The exception for a failed call (grpc.RpcError and grpc.aio.AioRpcError
    alike)."""
    code = getattr(error, "code", None)
    details = getattr(error, "details", None)
    status = code() if callable(code) else grpc.StatusCode.UNKNOWN
    text = details() if callable(details) else str(error)
    return from_status(status if isinstance(status, grpc.StatusCode) else grpc.StatusCode.UNKNOWN, text, method)
