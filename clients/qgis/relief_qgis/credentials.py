"""What every request to reliefd carries: the bearer token a reliefd
serving with --token-file wants, and for https:// the CA certificates to
trust besides the system's. A token never goes over plain http:// to
another machine."""

from __future__ import annotations

from typing import Optional

from qgis.PyQt.QtCore import QUrl
from qgis.PyQt.QtNetwork import QNetworkRequest, QSslCertificate, QSslConfiguration

from .address import is_loopback


class Credentials:
    """The bearer token (empty: none) and, for https://, the TLS settings
    with the CA certificates to trust."""

    def __init__(self, token: str = "", ca_file: str = "", insecure: bool = False) -> None:
        self.token = token.strip()
        self.ca_file = ca_file.strip()
        #: Send the token over plain http:// to another machine anyway.
        self.insecure = insecure
        #: Why the CA file cannot be used ("" when it can, or none is set).
        self.ca_error = ""
        self._ssl: Optional[QSslConfiguration] = None
        if self.ca_file:
            certificates = QSslCertificate.fromPath(self.ca_file)
            if not certificates:
                self.ca_error = f"the CA file holds no PEM certificate or cannot be read: {self.ca_file}"
            else:
                self._ssl = QSslConfiguration.defaultConfiguration()
                self._ssl.setCaCertificates(self._ssl.caCertificates() + certificates)

    def refusal(self, url: str) -> str:
        """Why no request may go to `url` with this token ("" when one may):
        over plain http:// to another machine anyone on the path could read
        the token and use it."""
        address = QUrl(url)
        host = address.host().strip("[]")
        if not self.token or self.insecure or address.scheme() != "http" or is_loopback(host):
            return ""
        return (
            f"refusing to send the token over plain http:// to {host}: anyone on the path could read it and use it; "
            "serve reliefd with TLS (--tls-cert, --tls-key) and connect to https://"
        )

    def apply(self, request: QNetworkRequest) -> QNetworkRequest:
        if self.token:
            request.setRawHeader(b"Authorization", b"Bearer " + self.token.encode("utf-8"))
        if self._ssl is not None and request.url().scheme() == "https":
            request.setSslConfiguration(self._ssl)
        return request
