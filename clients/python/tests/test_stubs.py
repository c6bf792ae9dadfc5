"""The vendored relief.v1 stubs are what proto/ and the pinned grpcio-tools
generate now: regenerate them into a temporary folder and compare bytes."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

PACKAGE = Path(__file__).resolve().parents[1]
SCRIPT = PACKAGE / "scripts" / "generate_stubs.py"
VENDORED = PACKAGE / "src" / "relief" / "_proto"
PROTO = PACKAGE.parents[1] / "proto"


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("generate_stubs", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("generate_stubs", module)
    spec.loader.exec_module(module)
    return module


def _files(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.suffix in {".py", ".pyi"} and "__pycache__" not in p.parts
    }


def test_the_vendored_stubs_match_proto(tmp_path: Path) -> None:
    try:
        import grpc_tools  # noqa: F401
    except ImportError:
        pytest.fail("grpcio-tools is not installed: pip install './clients/python[test]'")
    from importlib.metadata import version

    vendored_grpc = (VENDORED / "relief" / "v1" / "relief_pb2_grpc.py").read_text(encoding="utf-8")
    tools = version("grpcio-tools")
    assert f"GRPC_GENERATED_VERSION = '{tools}'" in vendored_grpc, (
        f"grpcio-tools {tools} is installed, but the stubs came from another version: install the one "
        "pinned in clients/python/pyproject.toml, or regenerate and re-pin"
    )
    fresh = tmp_path / "_proto"
    _script().generate(fresh, PROTO)
    want, have = _files(fresh), _files(VENDORED)
    stale = sorted(name for name in want.keys() | have.keys() if want.get(name) != have.get(name))
    assert not stale, (
        f"the vendored stubs are stale against {PROTO} ({', '.join(stale)}): run "
        "python clients/python/scripts/generate_stubs.py and commit the result"
    )
