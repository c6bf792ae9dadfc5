#!/usr/bin/env python3
"""Builds the installable QGIS plugin zip: relief_qgis/ and its files,
as QGIS's "Install from ZIP" wants them. Prints the zip's path.

    python3 clients/qgis/scripts/package.py [OUT.zip]

(default: target/qgis/relief_qgis.zip in the repository)."""

from __future__ import annotations

import sys
import zipfile
from pathlib import Path

PLUGIN = "relief_qgis"
#: What goes in: the plugin's own files, never caches.
KINDS = {".py", ".txt", ".svg"}
#: Files without a suffix that go in too (the plugin repository wants the licence).
NAMES = {"LICENSE"}


def build(out: Path) -> Path:
    source = Path(__file__).resolve().parent.parent / PLUGIN
    out.parent.mkdir(parents=True, exist_ok=True)
    files = sorted(
        p
        for p in source.rglob("*")
        if p.is_file() and (p.suffix in KINDS or p.name in NAMES) and "__pycache__" not in p.parts
    )
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for path in files:
            z.write(path, f"{PLUGIN}/{path.relative_to(source).as_posix()}")
    return out


def main() -> None:
    repo = Path(__file__).resolve().parents[3]
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else repo / "target" / "qgis" / f"{PLUGIN}.zip"
    print(build(out.resolve()))


if __name__ == "__main__":
    main()
