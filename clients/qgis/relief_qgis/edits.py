"""Edits made in QGIS, told to reliefd at once: when a layer whose file a
scene source reads is committed, the plugin asks for a reload of those
sources. reliefd's file watcher stays the source of truth (it would see
the save anyway); the reload only saves it the wait for the file to settle."""

from __future__ import annotations

import os
from typing import Iterable, Optional

from qgis.core import QgsMapLayer, QgsProviderRegistry

from . import proto_json as pj

#: Files that are one dataset with the .shp beside them.
SHAPEFILE_PARTS = {".shp", ".shx", ".dbf", ".prj", ".cpg", ".qix", ".sbn", ".sbx"}


def layer_file(layer: QgsMapLayer) -> Optional[str]:
    """The file a layer reads, as an absolute path; None for layers that
    are not files (a database, a web service, memory)."""
    parts = QgsProviderRegistry.instance().decodeUri(layer.providerType(), layer.source())
    path = parts.get("path") or ""
    return os.path.realpath(path) if path and os.path.isfile(path) else None


def _dataset(path: str) -> str:
    """One name for all the files of a dataset (a shapefile's parts)."""
    stem, ext = os.path.splitext(os.path.realpath(path))
    return stem + ".shp" if ext.lower() in SHAPEFILE_PARTS else os.path.realpath(path)


def sources_reading(state: dict, path: str) -> list[str]:
    """The ids of the scene's sources that read `path` (from GetState's
    `files`, as JSON), in the scene's order."""
    target = _dataset(path)
    found = []
    for source in pj.items(state, "sources"):
        files: Iterable[str] = pj.items(source, "files")
        if any(_dataset(str(f)) == target for f in files):
            found.append(pj.text(source, "id"))
    return found
