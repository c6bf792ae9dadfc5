"""The pytest plugin (registered as `relief` under the pytest11 entry
point): fixtures that serve the hill scene with a real reliefd.

- `relief_scene`: the hill DEM and parcels written under tmp_path
  (a relief.testing.HillScene). Override it in a conftest.py to serve
  another scene: the other fixtures only read its `.manifest`.
- `reliefd_args`: extra arguments of `reliefd serve` (none). Override it
  to serve with tokens or TLS (relief.testing.write_token_file,
  make_certificates; their `.args`).
- `reliefd`: reliefd serving `relief_scene` on a free port (a
  relief.testing.Reliefd), stopped with SIGTERM afterwards.
- `relief_token`: the token `relief_client` sends (None: none). Override
  it along with `reliefd_args`.
- `relief_client`: a relief.Client connected to it.

The binary comes from --relief-bin, else $RELIEF_BIN, else `reliefd` on
PATH, else target/{release,debug}/reliefd of the repository (the newer).
GDAL's Python bindings (osgeo) are imported only when a fixture runs.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from relief.client import Client
from relief.testing.daemon import BIN_ENV, Reliefd
from relief.testing.scene import HillScene, write_hill_scene


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("relief")
    group.addoption(
        "--relief-bin",
        action="store",
        default=None,
        help=f"the reliefd binary the relief fixtures start (default: ${BIN_ENV}, PATH, then target/ of the repo)",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "relief: a test that talks to a real reliefd")
    binary = config.getoption("--relief-bin", default=None)
    if binary:
        os.environ[BIN_ENV] = str(Path(binary).resolve())


@pytest.fixture
def relief_scene(tmp_path: Path) -> HillScene:
    """The hill scene written under tmp_path/scene."""
    return write_hill_scene(tmp_path / "scene")


@pytest.fixture
def reliefd_args() -> tuple[str, ...]:
    """Extra arguments of `reliefd serve` (none)."""
    return ()


@pytest.fixture
def relief_token() -> str | None:
    """The token `relief_client` sends (none)."""
    return None


@pytest.fixture
def reliefd(relief_scene: HillScene, reliefd_args: tuple[str, ...]) -> Iterator[Reliefd]:
    """reliefd serving `relief_scene` on 127.0.0.1 (a free port), started
    with `reliefd_args`."""
    daemon = Reliefd(relief_scene.manifest, args=tuple(reliefd_args))
    daemon.start()
    try:
        yield daemon
    finally:
        code = daemon.stop()
        # Shown by pytest when the test fails.
        print(f"reliefd ({daemon.binary}) exited with {code}; its log:\n{daemon.log_text()}")


@pytest.fixture
def relief_client(reliefd: Reliefd, relief_token: str | None) -> Iterator[Client]:
    """A client connected to `reliefd`, sending `relief_token`."""
    with reliefd.connect(token=relief_token) as client:
        yield client
