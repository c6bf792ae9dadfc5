"""A real reliefd process on 127.0.0.1 for tests: started on a free port,
its address read from the `listening on ADDR` line, its log kept, stopped
with SIGTERM."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import tempfile
import threading
from pathlib import Path
from types import TracebackType
from typing import IO

from relief.client import Client, connect

#: The environment variable naming the reliefd binary to use.
BIN_ENV = "RELIEF_BIN"

_LEVEL = re.compile(r"\b(WARN|ERROR)\b")


def _repo_candidates(start: Path) -> list[Path]:
    """target/{release,debug}/reliefd in the first folder, from `start` up,
    that has either."""
    for folder in [start, *start.parents]:
        found = [folder / "target" / kind / "reliefd" for kind in ("release", "debug")]
        found = [p for p in found if p.is_file() and os.access(p, os.X_OK)]
        if found:
            return found
    return []


def find_reliefd() -> Path:
    """The reliefd binary: $RELIEF_BIN, else `reliefd` on PATH, else
    target/release/reliefd or target/debug/reliefd up from this package
    (the repository it was installed from) or from the working directory;
    when both builds exist, the newer one (a stale release build must not
    stand in for the debug build a test script just made)."""
    named = os.environ.get(BIN_ENV)
    if named:
        path = Path(named)
        if not path.is_file():
            raise FileNotFoundError(f"{BIN_ENV}={named} is not a file")
        return path
    on_path = shutil.which("reliefd")
    if on_path:
        return Path(on_path)
    tried: list[str] = []
    for start in (Path(__file__).resolve().parent, Path.cwd().resolve()):
        found = _repo_candidates(start)
        if found:
            return max(found, key=lambda p: p.stat().st_mtime)
        tried.append(str(start))
    raise FileNotFoundError(
        f"cannot find reliefd: set {BIN_ENV}, put reliefd on PATH, or build it "
        f"(cargo build --release -p relief-daemon); searched target/{{release,debug}} up from {', '.join(tried)}"
    )


class Reliefd:
    """`reliefd serve MANIFEST --listen 127.0.0.1:0` (or `listen`), as a
    context manager.

        with Reliefd(manifest) as daemon, daemon.connect() as client:
            ...
    """

    def __init__(
        self,
        manifest: str | Path,
        *,
        binary: str | Path | None = None,
        args: tuple[str, ...] = (),
        env: dict[str, str] | None = None,
        start_timeout: float = 60.0,
        listen: str = "127.0.0.1:0",
    ) -> None:
        self.manifest = Path(manifest)
        self.binary = Path(binary) if binary is not None else find_reliefd()
        self.args = args
        #: Where it listens: port 0 takes a free one; give the `address` of
        #: a stopped daemon to start it again where its clients look.
        self.listen = listen
        self.start_timeout = start_timeout
        self._env = dict(os.environ if env is None else env)
        self._env.setdefault("RUST_LOG", os.environ.get("RELIEF_TEST_LOG", "info"))
        self._runtime_dir: tempfile.TemporaryDirectory[str] | None = None
        self._process: subprocess.Popen[str] | None = None
        self._log: list[str] = []
        self._stdout: list[str] = []
        self._lock = threading.Lock()
        self._ready = threading.Event()
        self._viewer_seen = threading.Event()
        self._threads: list[threading.Thread] = []
        self.address = ""
        self.viewer_url = ""

    # ------------------------------------------------------------ process

    def start(self) -> Reliefd:
        """Starts reliefd and waits for its `listening on` line."""
        if self._process is not None and self._process.poll() is None:
            raise RuntimeError("reliefd is already started")
        # Started again after stop(): a fresh process, the log goes on.
        self._ready.clear()
        self._viewer_seen.clear()
        self.address = ""
        self.viewer_url = ""
        if not self._env.get("XDG_RUNTIME_DIR"):
            # Mesa's lavapipe wants a private runtime folder.
            self._runtime_dir = tempfile.TemporaryDirectory(prefix="reliefd-xdg-")
            os.chmod(self._runtime_dir.name, 0o700)
            self._env["XDG_RUNTIME_DIR"] = self._runtime_dir.name
        command = [str(self.binary), "serve", str(self.manifest), "--listen", self.listen, *self.args]
        self._process = subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=self._env,
            text=True,
            encoding="utf-8",
            errors="replace",
        )
        assert self._process.stdout is not None and self._process.stderr is not None
        self._threads = [
            threading.Thread(target=self._read_stdout, args=(self._process.stdout,), name="reliefd-stdout", daemon=True),
            threading.Thread(target=self._read_stderr, args=(self._process.stderr,), name="reliefd-stderr", daemon=True),
        ]
        for t in self._threads:
            t.start()
        if not self._ready.wait(self.start_timeout) or not self.address:
            code = self._process.poll()
            self._kill()
            why = f"exited with {code}" if code is not None else f"said nothing in {self.start_timeout} s"
            raise RuntimeError(f"reliefd did not start ({why}): {' '.join(command)}\n{self.log_text()}")
        # The `viewer:` line follows at once; it says whether TLS is served.
        self._viewer_seen.wait(5.0)
        return self

    def _read_stdout(self, stream: IO[str]) -> None:
        for line in stream:
            line = line.rstrip("\n")
            with self._lock:
                self._stdout.append(line)
            if line.startswith("listening on "):
                self.address = line[len("listening on ") :].strip()
                self._ready.set()
            elif line.startswith("viewer: "):
                self.viewer_url = line[len("viewer: ") :].strip()
                self._viewer_seen.set()
        # Ended (exited before saying where it listens, or after): unblock start().
        self._ready.set()
        self._viewer_seen.set()

    def _read_stderr(self, stream: IO[str]) -> None:
        for line in stream:
            with self._lock:
                self._log.append(line.rstrip("\n"))

    @property
    def pid(self) -> int:
        if self._process is None:
            raise RuntimeError("reliefd is not started")
        return self._process.pid

    def is_running(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def stop(self, timeout: float = 15.0) -> int:
        """SIGTERM, then waits for the exit (SIGKILL after `timeout`);
        returns the exit status."""
        if self._process is None:
            return 0
        process = self._process
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(timeout)
            except subprocess.TimeoutExpired:
                self._kill()
                raise RuntimeError(f"reliefd did not stop within {timeout} s of SIGTERM; killed\n{self.log_text()}")
        for t in self._threads:
            t.join(5.0)
        for pipe in (process.stdout, process.stderr):
            if pipe is not None:
                pipe.close()
        if self._runtime_dir is not None:
            self._runtime_dir.cleanup()
            self._runtime_dir = None
            self._env.pop("XDG_RUNTIME_DIR", None)
        code = process.returncode
        return int(code) if code is not None else 0

    def _kill(self) -> None:
        if self._process is not None and self._process.poll() is None:
            self._process.kill()
            self._process.wait()

    def __enter__(self) -> Reliefd:
        if self._process is None:
            self.start()
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    # ------------------------------------------------------------ clients and logs

    @property
    def tls(self) -> bool:
        """Whether it serves TLS (its `viewer:` line says https)."""
        return self.viewer_url.startswith("https://")

    def connect(
        self, *, timeout: float = 30.0, token: str | None = None, ca: str | os.PathLike[str] | bytes | None = None
    ) -> Client:
        """A client connected to this reliefd, sending `token` (none when
        None: RELIEF_TOKEN is not read) and trusting `ca` when it serves TLS
        (RELIEF_CA is not read either)."""
        if not self.address:
            raise RuntimeError("reliefd is not started")
        if ca is not None and not self.tls:
            raise ValueError("a CA was given for a reliefd that does not serve TLS")
        if self.tls and ca is None:
            raise ValueError("this reliefd serves TLS: give the CA that signed its certificate (ca=...)")
        return connect(self.address, timeout=timeout, token=token or "", ca=ca, tls=self.tls)

    @property
    def log(self) -> list[str]:
        """What reliefd wrote on stderr so far."""
        with self._lock:
            return list(self._log)

    def log_text(self) -> str:
        return "\n".join(self.log)

    def problems(self) -> list[str]:
        """Log lines at WARN or ERROR."""
        return [line for line in self.log if _LEVEL.search(line)]
