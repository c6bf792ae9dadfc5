"""A reliefd that wants tokens and speaks TLS, for tests: a token file
(`reliefd serve --token-file`) and a certificate authority of the test's
own with a server certificate it signed for localhost and 127.0.0.1
(`--tls-cert`, `--tls-key`; clients trust `ca`).

    tokens = write_token_file(tmp_path)
    certs = make_certificates(tmp_path)
    with Reliefd(manifest, args=(*tokens.args, *certs.args)) as daemon:
        with daemon.connect(token=tokens.read, ca=certs.ca) as client:
            ...

The certificates are made by the `openssl` command (Debian's openssl
package), so the tests need no Python cryptography package."""

from __future__ import annotations

import ipaddress
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

#: Tokens of the file write_token_file writes by default (reliefd wants at
#: least 16 characters).
READ_TOKEN = "read-0123456789abcdef"
CONTROL_TOKEN = "control-0123456789abcdef"


@dataclass(frozen=True)
class TokenFile:
    """A token file and the tokens it lists."""

    path: Path
    read: str
    control: str

    @property
    def args(self) -> tuple[str, ...]:
        """reliefd's arguments that make it want these tokens."""
        return ("--token-file", str(self.path))


def write_token_file(folder: Path, *, read: str = READ_TOKEN, control: str = CONTROL_TOKEN) -> TokenFile:
    """`folder/tokens`, giving `read` the read scope and `control` the
    control scope."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "tokens"
    path.write_text(f"# who may call this reliefd\nread {read}\ncontrol {control}\n", encoding="utf-8")
    path.chmod(0o600)
    return TokenFile(path, read, control)


@dataclass(frozen=True)
class Certificates:
    """PEM files: the CA's certificate (what clients trust), and the
    server's certificate and key (what reliefd serves)."""

    ca: Path
    cert: Path
    key: Path

    @property
    def args(self) -> tuple[str, ...]:
        """reliefd's arguments that make it serve TLS with these."""
        return ("--tls-cert", str(self.cert), "--tls-key", str(self.key))


def make_certificates(folder: Path, *, names: tuple[str, ...] = ("localhost", "127.0.0.1"), days: int = 2) -> Certificates:
    """A CA and a server certificate it signed for `names` (host names and
    IP addresses), valid for `days`, with P-256 keys, under `folder`:
    ca.pem, ca.key, server.pem, server.key."""
    openssl = shutil.which("openssl")
    if openssl is None:
        raise RuntimeError("the test certificates need the openssl command: apt-get install openssl")
    folder.mkdir(parents=True, exist_ok=True)
    ca, ca_key = folder / "ca.pem", folder / "ca.key"
    cert, key, request = folder / "server.pem", folder / "server.key", folder / "server.csr"
    extensions = folder / "server.ext"
    alt = ",".join(f"IP:{n}" if _is_ip(n) else f"DNS:{n}" for n in names)
    extensions.write_text(
        f"subjectAltName={alt}\nbasicConstraints=critical,CA:FALSE\n"
        "keyUsage=critical,digitalSignature\nextendedKeyUsage=serverAuth\n",
        encoding="utf-8",
    )
    key_args = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes"]
    days_arg = ["-days", str(days)]
    _openssl(
        [openssl, "req", "-x509", *key_args, "-keyout", str(ca_key), "-out", str(ca), *days_arg,
         "-subj", "/CN=relief test CA",
         "-addext", "basicConstraints=critical,CA:TRUE", "-addext", "keyUsage=critical,keyCertSign,cRLSign"]
    )  # fmt: skip
    _openssl([openssl, "req", "-new", *key_args, "-keyout", str(key), "-out", str(request), "-subj", f"/CN={names[0]}"])
    _openssl(
        [openssl, "x509", "-req", "-in", str(request), "-CA", str(ca), "-CAkey", str(ca_key),
         "-CAcreateserial", "-CAserial", str(folder / "ca.srl"), "-out", str(cert), *days_arg,
         "-extfile", str(extensions)]
    )  # fmt: skip
    for private in (ca_key, key):
        private.chmod(0o600)
    return Certificates(ca, cert, key)


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def _openssl(command: list[str]) -> None:
    result = subprocess.run(command, capture_output=True, text=True, timeout=60, check=False)
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed ({result.returncode}):\n{result.stderr}")
