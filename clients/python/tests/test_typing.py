"""`mypy --strict` over the package (the generated stubs excluded by the
configuration in pyproject.toml), its tests and the example users copy."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1]
EXAMPLES = PACKAGE.parents[1] / "examples" / "python"


def _cache_dir() -> str:
    # Keep mypy's cache out of the work tree: beside the venv, or in /tmp.
    prefix = Path(sys.prefix)
    if os.access(prefix, os.W_OK):
        return str(prefix / "mypy-cache")
    return str(Path(tempfile.gettempdir()) / "relief-mypy-cache")


def test_the_package_is_mypy_strict_clean() -> None:
    try:
        import mypy  # noqa: F401
    except ImportError:
        pytest.skip("mypy is not installed (pip install './clients/python[test]'): the typing check did not run")
    command = [
        sys.executable,
        "-m",
        "mypy",
        "--strict",
        "--config-file",
        str(PACKAGE / "pyproject.toml"),
        "--cache-dir",
        _cache_dir(),
        "src/relief",
        "tests",
        *(str(p) for p in sorted(EXAMPLES.glob("*.py"))),
    ]
    result = subprocess.run(command, cwd=PACKAGE, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, f"{' '.join(command)}\n{result.stdout}{result.stderr}"
