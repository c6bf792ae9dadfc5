"""What went wrong with a request to reliefd, in words: the daemon's own
message when it answered with one, "is not a relief daemon" when something
else answered (a web server's 404 page), "timed out" with the address and
the time when nothing answered in time, else Qt's reason."""

from __future__ import annotations

import json

from qgis.PyQt.QtNetwork import QNetworkReply, QNetworkRequest

from . import proto_json as pj

#: The reply property holding why Qt did not trust the daemon's certificate.
TLS_ERRORS = "relief_tls_errors"
#: Qt 5 reports a transfer timeout as a cancel; Qt 6 has its own code.
_TIMEOUTS = {QNetworkReply.OperationCanceledError, getattr(QNetworkReply, "TimeoutError", -1)}


def daemon_message(body: bytes) -> str:
    """The message of reliefd's JSON error body ("" when the body is not
    one: then something other than reliefd answered)."""
    try:
        answer = json.loads(body.decode("utf-8"))
    except (ValueError, UnicodeDecodeError):
        return ""
    return pj.text(answer, "message")


def not_relief(url: str, what: str) -> str:
    return f"{url} is not a relief daemon ({what}): check the address"


def error_text(reply: QNetworkReply, url: str, timeout_s: float) -> str:
    """Why `reply` (a request to the daemon at `url`, allowed `timeout_s`
    seconds) failed. Requests the plugin aborts itself are dropped before
    they get here, so a cancel is a timeout."""
    status = reply.attribute(QNetworkRequest.HttpStatusCodeAttribute)
    if status:
        message = daemon_message(bytes(reply.readAll()))
        reason = reply.attribute(QNetworkRequest.HttpReasonPhraseAttribute)
        if not message:
            return not_relief(url, f"HTTP {status}{' ' + str(reason) if reason else ''}")
        if status in (401, 403):
            return f"refused (HTTP {status}): {message}"
        return f"HTTP {status}: {message}"
    if reply.error() in _TIMEOUTS:
        return f"no answer from {url} within {timeout_s:g} s (timed out)"
    tls = reply.property(TLS_ERRORS)
    if tls:
        return f"{reply.errorString()}: {tls}"
    return reply.errorString()


def is_refusal(reply: QNetworkReply) -> int:
    """401 or 403 when the daemon refused the request's token, else 0."""
    status = reply.attribute(QNetworkRequest.HttpStatusCodeAttribute)
    return int(status) if status in (401, 403) else 0


def keep_tls_errors(reply: QNetworkReply, errors: list) -> None:
    """Keeps Qt's reasons on the reply (the reply itself only says "SSL
    handshake failed"); the certificate stays refused."""
    reply.setProperty(TLS_ERRORS, "; ".join(e.errorString() for e in errors))


def event_message(data: str) -> str:
    """The message of an `error` event on a stream (its data if not JSON)."""
    try:
        answer = json.loads(data)
    except ValueError:
        return data
    return pj.text(answer, "message") or data
