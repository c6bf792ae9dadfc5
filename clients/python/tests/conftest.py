"""Shared fixtures: one reliefd per module for the tests that only read
(the plugin's function-scoped `relief_client` serves those that change
the scene)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

import relief
from relief.testing import HillScene, Reliefd, write_hill_scene

#: The repository root (clients/python/tests -> ../../..).
REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(autouse=True)
def no_relief_env(monkeypatch: pytest.MonkeyPatch) -> None:
    """The caller's RELIEF_TOKEN and RELIEF_CA would change how every
    client here connects: the tests that want them set them."""
    monkeypatch.delenv("RELIEF_TOKEN", raising=False)
    monkeypatch.delenv("RELIEF_CA", raising=False)


@pytest.fixture(scope="module")
def shared_scene(tmp_path_factory: pytest.TempPathFactory) -> HillScene:
    return write_hill_scene(tmp_path_factory.mktemp("shared") / "scene", extra_manifest="[effects]\nlighting = {}\n")


@pytest.fixture(scope="module")
def shared_daemon(shared_scene: HillScene) -> Iterator[Reliefd]:
    with Reliefd(shared_scene.manifest) as daemon:
        yield daemon


@pytest.fixture(scope="module")
def shared_client(shared_daemon: Reliefd) -> Iterator[relief.Client]:
    with shared_daemon.connect() as client:
        yield client
